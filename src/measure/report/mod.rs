//! Parity and accuracy reports: one record per renderer × profile × camera × time (or per knob
//! setting), written as `report.json` and as a markdown table with thumbnails, plus plots.

pub mod plot;
pub mod summary;

use std::fmt::Write as _;

use serde::{Deserialize, Deserializer, Serialize};

/// One measured image against the native-splatting reference.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct Record {
    /// native, hybrid, trace-gaussian, trace-mesh.
    pub renderer: String,
    /// Converter profile for mesh traces (meshsplats, rings, texture), else empty.
    pub profile: String,
    /// File the mesh was read back from (glb, obj), else empty.
    pub format: String,
    /// For accuracy sweeps: the knob and its value.
    pub knob: String,
    pub value: String,
    pub camera: String,
    pub time: f64,
    /// dB; +inf for an image identical to the reference (JSON: null).
    #[serde(deserialize_with = "null_is_infinite")]
    pub psnr: f64,
    pub ssim: f64,
    pub tile_ssim: f64,
    pub max_error: f64,
    pub milliseconds: f64,
    pub triangles: u64,
    pub bytes: u64,
    /// Image and heat-map paths relative to the report.
    pub image: String,
    pub heatmap: String,
    /// Why a row has no measurement (a viewer client that is not installed); empty otherwise.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub note: String,
    /// The process's peak resident memory (bytes, `VmHWM`) when this record was measured: like
    /// `milliseconds`, a cost of the run, not part of the result (0: not recorded).
    #[serde(skip_serializing_if = "is_zero")]
    pub peak_memory_bytes: u64,
    /// The stage's estimated peak memory (bytes, `budget.rs`), which `--max-memory` is held
    /// against: Gaussian-trace and mesh records (0: not estimated). Deterministic, unlike
    /// `peak_memory_bytes`.
    #[serde(skip_serializing_if = "is_zero")]
    pub memory_estimate_bytes: u64,
}

fn is_zero(v: &u64) -> bool {
    *v == 0
}

/// JSON has no infinity: serde_json writes +inf as null, read back here as +inf.
fn null_is_infinite<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
}

fn fmt_psnr(p: f64) -> String {
    if p.is_infinite() {
        "∞".into()
    } else {
        format!("{p:.2}")
    }
}

/// A markdown table of records; `thumbs` adds image and heat-map columns.
pub fn markdown_table(records: &[Record], thumbs: bool) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "| renderer | profile | file | knob | setting | camera | t | PSNR dB | SSIM | tile-SSIM | max err | ms | triangles | bytes |"
    );
    if thumbs {
        s.push_str(" image | difference |");
    }
    s.push('\n');
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    if thumbs {
        s.push_str("---|---|");
    }
    s.push('\n');
    for r in records {
        let _ = write!(
            s,
            "| {} | {} | {} | {} | {} | {} | {:.2} | {} | {:.4} | {:.4} | {:.3} | {:.1} | {} | {} |",
            r.renderer,
            r.profile,
            r.format,
            r.knob,
            r.value,
            r.camera,
            r.time,
            fmt_psnr(r.psnr),
            r.ssim,
            r.tile_ssim,
            r.max_error,
            r.milliseconds,
            r.triangles,
            r.bytes
        );
        if thumbs {
            let img = |p: &str| {
                if p.is_empty() {
                    String::new()
                } else {
                    format!("<img src=\"{p}\" width=\"160\">")
                }
            };
            let _ = write!(s, " {} | {} |", img(&r.image), img(&r.heatmap));
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_through_json_with_infinite_psnr() {
        let r = Record {
            renderer: "native".into(),
            psnr: f64::INFINITY,
            ssim: 1.0,
            ..Record::default()
        };
        let json = serde_json::to_string(&vec![r.clone()]).unwrap();
        assert!(json.contains("\"psnr\":null"));
        let back: Vec<Record> = serde_json::from_str(&json).unwrap();
        assert_eq!(back[0].psnr, f64::INFINITY);
        assert_eq!(back[0].renderer, "native");
    }
}
