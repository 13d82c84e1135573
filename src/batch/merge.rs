//! Sharded runs and their merge. A run given `--shard I/N` does the work items shard I owns
//! ([`crate::batch::shard`]) and writes, beside its images, a partial `report.json`
//! ([`PartialReport`]): the command, the tool's version, the scene hash, the options hash, the
//! shard id, the files it wrote and its records with their places in the unsharded report.
//! [`merge`] checks that the shards are one run's complete, disjoint set and writes what the
//! unsharded run writes: the same files, the same records in the same order (timings and
//! memory figures are each shard's own).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::input::Cap;
use splatbridge_scene::output::OutputSet;
use thiserror::Error;

use crate::batch::shard::{Fnv1a, Shard};
use crate::measure::parity::Placed;
use crate::measure::report::Record;

/// The `format` field of a partial report.
pub const PARTIAL_FORMAT: &str = "splatbridge-shard/1";

/// The partial report's file name in a shard's folder (the unsharded report's name).
pub const REPORT: &str = "report.json";

/// What a shard wrote, in its folder's `report.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PartialReport {
    pub format: String,
    /// `compare` or `accuracy`.
    pub command: String,
    /// The tool's version (`CARGO_PKG_VERSION`); shards of different versions do not merge.
    pub version: String,
    /// [`scene_hash`] of the input.
    pub scene_hash: String,
    /// [`options_hash`] of every option that changes the outputs (not `--shard`, not `--out`).
    pub options_hash: String,
    pub shard: Shard,
    /// The report's title and the text under it (`report.md`, `accuracy.md`).
    pub title: String,
    pub preamble: String,
    /// Files this shard wrote besides `report.json`, by name in its folder.
    pub files: Vec<String>,
    /// The shard's peak resident memory (bytes; 0 where not measured).
    pub peak_memory_bytes: u64,
    #[serde(with = "exact")]
    pub records: Vec<Placed>,
}

/// Records with their floating-point fields also stored as IEEE-754 bits: serde_json's
/// default float parser can be one unit in the last place off, and a merged report must hold
/// the values the shard measured, bit for bit.
mod exact {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use crate::measure::parity::Placed;
    use crate::measure::report::Record;

    #[derive(Serialize, Deserialize)]
    struct Wire {
        #[serde(flatten)]
        placed: Placed,
        /// time, psnr, ssim, tile_ssim, max_error, milliseconds.
        bits: [u64; 6],
    }

    fn fields(r: &mut Record) -> [&mut f64; 6] {
        [
            &mut r.time,
            &mut r.psnr,
            &mut r.ssim,
            &mut r.tile_ssim,
            &mut r.max_error,
            &mut r.milliseconds,
        ]
    }

    pub fn serialize<S: Serializer>(v: &[Placed], s: S) -> Result<S::Ok, S::Error> {
        let wire: Vec<Wire> = v
            .iter()
            .map(|p| {
                let mut p = p.clone();
                let bits = fields(&mut p.record).map(|f| f.to_bits());
                Wire { placed: p, bits }
            })
            .collect();
        wire.serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Placed>, D::Error> {
        let wire = Vec::<Wire>::deserialize(d)?;
        Ok(wire
            .into_iter()
            .map(|mut w| {
                for (f, b) in fields(&mut w.placed.record).into_iter().zip(w.bits) {
                    *f = f64::from_bits(b);
                }
                w.placed
            })
            .collect())
    }
}

#[derive(Debug, Error)]
pub enum MergeError {
    #[error("{0}: {1}")]
    Shard(PathBuf, String),
    #[error("no shard folders given")]
    Empty,
    #[error("{0}: missing shard(s) {1} of {2}")]
    Missing(String, String, u32),
    #[error("{0}: {1}")]
    Output(PathBuf, String),
}

/// Hex of a 64-bit hash, as written in reports.
fn hex(h: u64) -> String {
    format!("{h:016x}")
}

/// FNV-1a over the scene's Gaussians (static cloud then each object's, every attribute as
/// stored), its objects' tracks and its cameras: equal for the same input read anywhere.
pub fn scene_hash(scene: &DynamicScene) -> String {
    let mut h = Fnv1a::new();
    let mut cloud = |c: &splatbridge_scene::GaussianCloud| {
        h.write(&(c.len() as u64).to_le_bytes());
        h.write(&[c.sh_degree]);
        for m in &c.means {
            h.write_f32s(&m.to_array());
        }
        for s in &c.log_scales {
            h.write_f32s(&s.to_array());
        }
        for r in &c.rotations {
            h.write_f32s(&r.to_array());
        }
        h.write_f32s(&c.opacity_logits);
        for s in &c.sh {
            h.write_f32s(&s.to_array());
        }
    };
    cloud(&scene.static_gaussians);
    for o in &scene.objects {
        cloud(&o.gaussians);
    }
    let mut rest = Fnv1a::new();
    for o in &scene.objects {
        rest.write(format!("{:?}", o.track).as_bytes());
    }
    rest.write(format!("{:?}", scene.cameras).as_bytes());
    rest.write(format!("{:?}", scene.time).as_bytes());
    let mut all = h;
    all.write(&rest.finish().to_le_bytes());
    hex(all.finish())
}

/// FNV-1a of the options' canonical text (callers list every option that changes an output).
pub fn options_hash(canonical: &str) -> String {
    let mut h = Fnv1a::new();
    h.write(canonical.as_bytes());
    hex(h.finish())
}

/// Write a shard's partial report and commit its folder. `stage` is the staging folder of
/// `set` holding the shard's images and exports; their names are listed in the report.
pub fn commit_shard(set: OutputSet, stage: &Path, mut report: PartialReport) -> anyhow::Result<()> {
    let mut files = Vec::new();
    for e in std::fs::read_dir(stage)? {
        let name = e?.file_name().to_string_lossy().into_owned();
        if name != REPORT {
            files.push(name);
        }
    }
    files.sort();
    report.files = files;
    report.peak_memory_bytes = crate::measure::memory::peak_bytes().unwrap_or(0);
    let json = serde_json::to_string_pretty(&report)?;
    std::fs::write(stage.join(REPORT), json)?;
    set.commit()?;
    Ok(())
}

/// Read and check one shard folder's partial report.
fn read_partial(dir: &Path) -> Result<PartialReport, MergeError> {
    let path = dir.join(REPORT);
    let bad = |why: String| MergeError::Shard(path.clone(), why);
    // A partial report is JSON of a few hundred bytes per image: the text cap (64 MiB, see
    // `scene::input`) refuses a wrong file (a scene, an export, a FIFO) before reading it.
    let text = splatbridge_scene::input::read_bounded(&path, Cap::Text).map_err(|e| {
        MergeError::Shard(
            path.clone(),
            format!("no partial report ({e}); was this folder written with --shard I/N?"),
        )
    })?;
    let report: PartialReport = serde_json::from_slice(&text).map_err(|e| {
        bad(format!(
            "not a shard's partial report (written by a run with --shard I/N): {e}"
        ))
    })?;
    if report.format != PARTIAL_FORMAT {
        return Err(bad(format!(
            "format '{}', expected '{PARTIAL_FORMAT}'",
            report.format
        )));
    }
    for f in &report.files {
        if f.is_empty() || f.contains('/') || f.contains('\\') || f == "." || f == ".." {
            return Err(bad(format!("lists a file outside its folder: '{f}'")));
        }
    }
    Ok(report)
}

/// The merged result, before it is written.
pub struct Merged {
    pub first: PartialReport,
    /// Every file to copy: name → the shard folder holding it.
    pub files: BTreeMap<String, PathBuf>,
    pub records: Vec<Placed>,
    /// Each shard's peak memory, by shard index.
    pub peaks: Vec<u64>,
}

/// Check that `dirs` are the complete set of one run's shards and gather them.
pub fn gather(dirs: &[PathBuf]) -> Result<Merged, MergeError> {
    if dirs.is_empty() {
        return Err(MergeError::Empty);
    }
    let mut parts: Vec<(PathBuf, PartialReport)> = Vec::new();
    for d in dirs {
        parts.push((d.clone(), read_partial(d)?));
    }
    let (d0, p0) = &parts[0];
    let mut by_index: BTreeMap<u32, PathBuf> = BTreeMap::new();
    for (d, p) in &parts {
        let mismatch = |what: &str, a: &str, b: &str| {
            MergeError::Shard(
                d.join(REPORT),
                format!(
                    "{what} '{b}' differs from '{a}' of {}: shards of different runs",
                    d0.display()
                ),
            )
        };
        if p.command != p0.command {
            return Err(mismatch("command", &p0.command, &p.command));
        }
        if p.version != p0.version {
            return Err(mismatch("tool version", &p0.version, &p.version));
        }
        if p.scene_hash != p0.scene_hash {
            return Err(mismatch("scene hash", &p0.scene_hash, &p.scene_hash));
        }
        if p.options_hash != p0.options_hash {
            return Err(mismatch("options hash", &p0.options_hash, &p.options_hash));
        }
        if p.shard.count != p0.shard.count {
            return Err(mismatch(
                "shard count",
                &p0.shard.count.to_string(),
                &p.shard.count.to_string(),
            ));
        }
        if p.shard.index >= p.shard.count {
            return Err(MergeError::Shard(
                d.join(REPORT),
                format!("shard {} is not below its count", p.shard),
            ));
        }
        if let Some(other) = by_index.insert(p.shard.index, d.clone()) {
            return Err(MergeError::Shard(
                d.join(REPORT),
                format!(
                    "duplicate shard {}: {} holds it too",
                    p.shard,
                    other.display()
                ),
            ));
        }
    }
    let count = p0.shard.count;
    let missing: Vec<String> = (0..count)
        .filter(|i| !by_index.contains_key(i))
        .map(|i| i.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(MergeError::Missing(
            d0.display().to_string(),
            missing.join(", "),
            count,
        ));
    }
    let mut files: BTreeMap<String, PathBuf> = BTreeMap::new();
    let mut records = Vec::new();
    let mut peaks = vec![0; count as usize];
    let mut orders = std::collections::HashSet::new();
    for (d, p) in &parts {
        for f in &p.files {
            let src = d.join(f);
            let len = std::fs::metadata(&src)
                .map_err(|e| MergeError::Shard(src.clone(), format!("listed but unreadable: {e}")))?
                .len();
            // Exports are written by every shard that traced them, identically (the converter
            // is deterministic); a different size means the folders do not belong together.
            if let Some(prev) = files.get(f) {
                let prev_len = std::fs::metadata(prev.join(f))
                    .map(|m| m.len())
                    .unwrap_or(0);
                if prev_len != len {
                    return Err(MergeError::Shard(
                        src,
                        format!("{len} bytes, but {} has {prev_len}", prev.join(f).display()),
                    ));
                }
                continue;
            }
            files.insert(f.clone(), d.clone());
        }
        for r in &p.records {
            if !r.skipped && !orders.insert(r.order) {
                return Err(MergeError::Shard(
                    d.join(REPORT),
                    format!("record {:?} is also in another shard", r.order),
                ));
            }
        }
        records.extend(p.records.iter().cloned());
        peaks[p.shard.index as usize] = p.peak_memory_bytes;
    }
    Ok(Merged {
        first: parts.swap_remove(0).1,
        files,
        records,
        peaks,
    })
}

/// Copy every shard's files into a staging folder of `out`, then write the merged reports with
/// `write_reports(stage, merged)` and commit: `out` gets everything or nothing.
pub fn write_merged(
    merged: &Merged,
    out: &Path,
    write_reports: &dyn Fn(&Path, &Merged) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let mut set = OutputSet::new();
    let stage = set.stage_dir(out)?;
    for (name, dir) in &merged.files {
        let src = dir.join(name);
        std::fs::copy(&src, stage.join(name)).map_err(|e| {
            MergeError::Output(
                src.clone(),
                format!("cannot copy into {}: {e}", out.display()),
            )
        })?;
    }
    write_reports(&stage, merged)?;
    set.commit()?;
    Ok(())
}

/// The merged records in report order (measured by place, then one note per skipped client).
pub fn records(merged: &Merged) -> Vec<Record> {
    crate::measure::parity::report_order(merged.records.clone())
}

/// Write the merged run into `out` (files and reports, committed together); returns the main
/// report's name.
pub fn write_report(merged: &Merged, out: &Path) -> anyhow::Result<&'static str> {
    match merged.first.command.as_str() {
        "compare" => {
            write_merged(merged, out, &|stage, m| {
                crate::measure::parity::write_reports(
                    stage,
                    &m.first.title,
                    &m.first.preamble,
                    &records(m),
                )
            })?;
            Ok("report.md")
        }
        "accuracy" => {
            write_merged(merged, out, &|stage, m| {
                crate::measure::accuracy::write_staged(stage, &m.first.preamble, &records(m))
            })?;
            Ok("accuracy.md")
        }
        // Frames (rendered images, per-frame OBJs): the files are the result; there is no
        // report to join.
        "render" | "convert" | "trace" => {
            write_merged(merged, out, &|_, _| Ok(()))?;
            Ok("")
        }
        other => Err(MergeError::Shard(
            PathBuf::from(REPORT),
            format!("command '{other}' has no merge (compare, accuracy, render, convert, trace)"),
        )
        .into()),
    }
}
