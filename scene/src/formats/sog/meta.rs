//! `meta.json` of a SOG, both published versions, checked field by field.
//!
//! Version 1 (no `version` key; PlayCanvas SOGS, early 2025): `means.shape[0]` is the count;
//! `scales` and `sh0` carry per-channel `mins`/`maxs` (sh0's fourth channel is the opacity
//! logit); `shN` carries scalar `mins`/`maxs` and its band count is implied by the centroid
//! image's width (192/512/960 = 64 × 3/8/15).
//! Version 2 (`"version": 2`, splat-transform ≥ 1.0): `count`; `scales`, `sh0` and `shN`
//! carry 256-entry `codebook`s indexed by the image bytes; sh0's alpha is the sigmoid opacity
//! in 1/255 steps; `shN` has `count` (palette entries) and `bands`.

use std::path::Path;

use serde_json::Value;

use crate::error::{Result, SceneError};

/// How one group's bytes turn into values.
#[derive(Clone, Debug)]
pub(super) enum Dequant {
    /// v1: `min[c] + (max[c] − min[c]) · byte/255`, per channel.
    Range { mins: Vec<f64>, maxs: Vec<f64> },
    /// v2: `codebook[byte]`, 256 entries.
    Codebook(Vec<f32>),
}

/// The SH palette (`shN`).
#[derive(Clone, Debug)]
pub(super) struct ShN {
    /// v2: the band count from meta; v1: `None` (implied by the centroid image width).
    pub bands: Option<u8>,
    /// v2: palette entries; v1: `None` (implied by the centroid image height).
    pub palette: Option<u32>,
    /// Scalar range (v1) or codebook (v2) for every centroid byte.
    pub dequant: Dequant,
    pub centroids: String,
    pub labels: String,
}

/// A parsed `meta.json`.
#[derive(Clone, Debug)]
pub(super) struct Meta {
    pub version: u32,
    pub count: u64,
    pub means_mins: [f64; 3],
    pub means_maxs: [f64; 3],
    pub means_files: [String; 2],
    pub quats_file: String,
    pub scales: Dequant,
    pub scales_file: String,
    pub sh0: Dequant,
    pub sh0_file: String,
    pub shn: Option<ShN>,
}

/// The WebP dimension ceiling (14-bit width and height), hence the most Gaussians a SOG holds.
pub(super) const MAX_SIDE: u64 = 16383;

/// Parse a `meta.json`. `bundled`: it came out of the `.sog` zip `path`, so messages name the
/// entry after the zip (`scene.sog: meta.json: …`); an unbundled `meta.json` is `path` itself
/// and is named once (`meta.json: …`).
pub(super) fn parse(path: &Path, bytes: &[u8], bundled: bool) -> Result<Meta> {
    let entry = if bundled { "meta.json: " } else { "" };
    let bad = |what: String| SceneError::format(path, format!("{entry}{what}"));
    let v: Value = serde_json::from_slice(bytes).map_err(|e| {
        // JavaScript's JSON.stringify writes NaN and ±Infinity as `null`, but hand-made or
        // Python-written files carry the bare tokens; name them rather than a parse position.
        let text = String::from_utf8_lossy(bytes);
        if text.contains("NaN") || text.contains("Infinity") {
            bad(format!(
                "holds NaN or Infinity, which no range may be ({e})"
            ))
        } else {
            bad(format!("not JSON: {e}"))
        }
    })?;
    if !v.is_object() {
        return Err(bad("not a JSON object".into()));
    }
    let version = match &v["version"] {
        Value::Null => 1,
        x => match x.as_u64() {
            Some(2) => 2,
            _ => {
                return Err(bad(format!(
                    "version {x} is not a SOG version this reads (1, 2)"
                )))
            }
        },
    };
    let count = if version == 1 {
        v["means"]["shape"][0]
            .as_u64()
            .ok_or_else(|| bad("means.shape[0] (the Gaussian count) is missing".into()))?
    } else {
        v["count"]
            .as_u64()
            .ok_or_else(|| bad("count is missing or not an integer".into()))?
    };
    if count > MAX_SIDE * MAX_SIDE {
        return Err(bad(format!(
            "count {count} exceeds what {MAX_SIDE}×{MAX_SIDE} WebP images can hold"
        )));
    }
    let means_mins = fixed3(&bad, &v["means"]["mins"], "means.mins")?;
    let means_maxs = fixed3(&bad, &v["means"]["maxs"], "means.maxs")?;
    let means = files(&bad, &v["means"], "means", 2)?;
    let quats = files(&bad, &v["quats"], "quats", 1)?;
    let scales_files = files(&bad, &v["scales"], "scales", 1)?;
    let sh0_files = files(&bad, &v["sh0"], "sh0", 1)?;
    let (scales, sh0) = if version == 1 {
        (
            range(&bad, &v["scales"], "scales", 3)?,
            range(&bad, &v["sh0"], "sh0", 4)?,
        )
    } else {
        (
            codebook(&bad, &v["scales"], "scales")?,
            codebook(&bad, &v["sh0"], "sh0")?,
        )
    };
    let shn = match &v["shN"] {
        Value::Null => None,
        s => {
            let f = files(&bad, s, "shN", 2)?;
            let [centroids, labels] = [f[0].clone(), f[1].clone()];
            if version == 1 {
                let lo = number(&bad, &s["mins"], "shN.mins")?;
                let hi = number(&bad, &s["maxs"], "shN.maxs")?;
                Some(ShN {
                    bands: None,
                    palette: None,
                    dequant: Dequant::Range {
                        mins: vec![lo],
                        maxs: vec![hi],
                    },
                    centroids,
                    labels,
                })
            } else {
                let bands = s["bands"]
                    .as_u64()
                    .filter(|b| *b <= 3)
                    .ok_or_else(|| bad("shN.bands is missing or not 0–3".into()))?;
                let palette = s["count"]
                    .as_u64()
                    .filter(|c| *c <= 1 << 16)
                    .ok_or_else(|| {
                        bad("shN.count is missing or beyond 65536 (16-bit labels)".into())
                    })?;
                if bands == 0 {
                    None
                } else {
                    Some(ShN {
                        bands: Some(bands as u8),
                        palette: Some(palette as u32),
                        dequant: codebook(&bad, s, "shN")?,
                        centroids,
                        labels,
                    })
                }
            }
        }
    };
    let [m0, m1] = [means[0].clone(), means[1].clone()];
    Ok(Meta {
        version,
        count,
        means_mins,
        means_maxs,
        means_files: [m0, m1],
        quats_file: quats[0].clone(),
        scales,
        scales_file: scales_files[0].clone(),
        sh0,
        sh0_file: sh0_files[0].clone(),
        shn,
    })
}

fn number(bad: &dyn Fn(String) -> SceneError, v: &Value, what: &str) -> Result<f64> {
    let x = v
        .as_f64()
        .ok_or_else(|| bad(format!("{what} is missing or not a number")))?;
    // serde_json cannot hold NaN or infinity, but a number beyond f32 becomes inf in use.
    if !x.is_finite() || x.abs() > f32::MAX as f64 {
        return Err(bad(format!("{what} is {x}, not a finite f32")));
    }
    Ok(x)
}

fn numbers(bad: &dyn Fn(String) -> SceneError, v: &Value, what: &str) -> Result<Vec<f64>> {
    let a = v
        .as_array()
        .ok_or_else(|| bad(format!("{what} is missing or not an array")))?;
    a.iter()
        .enumerate()
        .map(|(i, x)| number(bad, x, &format!("{what}[{i}]")))
        .collect()
}

fn fixed3(bad: &dyn Fn(String) -> SceneError, v: &Value, what: &str) -> Result<[f64; 3]> {
    let a = numbers(bad, v, what)?;
    <[f64; 3]>::try_from(a.as_slice())
        .map_err(|_| bad(format!("{what} has {} entries, not 3", a.len())))
}

fn range(bad: &dyn Fn(String) -> SceneError, g: &Value, name: &str, n: usize) -> Result<Dequant> {
    let mins = numbers(bad, &g["mins"], &format!("{name}.mins"))?;
    let maxs = numbers(bad, &g["maxs"], &format!("{name}.maxs"))?;
    if mins.len() != n || maxs.len() != n {
        return Err(bad(format!(
            "{name}.mins/maxs have {}/{} entries, not {n}",
            mins.len(),
            maxs.len()
        )));
    }
    Ok(Dequant::Range { mins, maxs })
}

fn codebook(bad: &dyn Fn(String) -> SceneError, g: &Value, name: &str) -> Result<Dequant> {
    let c = numbers(bad, &g["codebook"], &format!("{name}.codebook"))?;
    if c.len() != 256 {
        return Err(bad(format!(
            "{name}.codebook has {} entries; byte indices need 256",
            c.len()
        )));
    }
    Ok(Dequant::Codebook(c.into_iter().map(|x| x as f32).collect()))
}

fn files(
    bad: &dyn Fn(String) -> SceneError,
    g: &Value,
    name: &str,
    n: usize,
) -> Result<Vec<String>> {
    let a = g["files"]
        .as_array()
        .ok_or_else(|| bad(format!("{name}.files is missing")))?;
    if a.len() < n {
        return Err(bad(format!(
            "{name}.files lists {} files, needs {n}",
            a.len()
        )));
    }
    a.iter()
        .take(n)
        .map(|f| {
            f.as_str()
                .map(str::to_string)
                .ok_or_else(|| bad(format!("{name}.files holds a non-string")))
        })
        .collect()
}
