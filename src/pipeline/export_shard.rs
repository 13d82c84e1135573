//! Per-frame runs split into shards, whose result is files (no records to join):
//!
//! - `convert --frames --shard I/N`, one shard of a per-frame OBJ export. The work item of frame
//!   `i` at time `t` is (scene hash, t, "", `convert i`) (`crate::batch::shard`); the shard writes the
//!   OBJs of the frames it owns, the shared MTL, and a partial `report.json` beside them, all in
//!   one atomic output set (a re-run replaces the folder's outputs as a whole).
//! - `trace --lidar-all-frames --shard I/N`: the LiDAR scans of the frames the shard owns (work
//!   item (scene hash, t, "", `lidar i`), `pipeline::frame::lidar_key`), plus the traced image,
//!   which every shard writes identically; [`write_partial`] lists them.
//!
//! `splatbridge merge` copies the shards' files together: the unsharded run's files, bit for
//! bit (a file several shards wrote must have one size in all of them).

use std::path::{Path, PathBuf};

use splatbridge_convert::{ConvertOptions, ConvertReport};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::EffectCounters;
use splatbridge_scene::output::OutputSet;

use crate::batch::merge::{options_hash, scene_hash, PartialReport, PARTIAL_FORMAT, REPORT};
use crate::batch::shard::{Shard, WorkKey};

/// The work key of frame `index` at `time` of a per-frame export.
pub fn frame_key(scene_hash: &str, index: usize, time: f64) -> WorkKey {
    WorkKey {
        scene: scene_hash.to_string(),
        time,
        camera: String::new(),
        setting: format!("convert {index}"),
    }
}

/// Write shard `shard` of `scene`'s per-frame OBJ export to `output` (`OUT_NNNN.obj` beside
/// it) with its partial report; returns the converter's report (bytes of this shard's files)
/// and the effect counters.
pub fn export_obj_frames_shard(
    scene: &DynamicScene,
    input: &Path,
    output: &Path,
    opts: &ConvertOptions,
    shard: Shard,
) -> anyhow::Result<(ConvertReport, EffectCounters)> {
    let (weather, effects) = super::export::content(scene, input, true)?;
    let hash = scene_hash(scene);
    let mut set = OutputSet::new();
    let keep = |i: usize, t: f64| shard.owns(&frame_key(&hash, i, t));
    let (report, written) = splatbridge_convert::obj::write_into(
        &mut set,
        output,
        scene,
        weather.as_ref(),
        opts,
        true,
        &keep,
    )?;
    // Everything that shapes the files: the options and the output's name (frames are named
    // after it); not the folder, which differs per shard.
    let canonical = format!(
        "convert --frames\noptions={}\nout={:?}",
        serde_json::to_string(opts)?,
        output.file_name()
    );
    let dir = folder_of(output);
    let partial = partial_report("convert", hash, &canonical, shard, &written);
    set.write(
        &dir.join(REPORT),
        serde_json::to_string_pretty(&partial)?.as_bytes(),
    )?;
    set.commit()?;
    Ok((report, effects))
}

/// The folder a file is written in (`.` for a bare name).
pub fn folder_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A file-only shard's partial report: `files` are listed by name.
pub(crate) fn partial_report(
    command: &str,
    scene_hash: String,
    canonical: &str,
    shard: Shard,
    files: &[PathBuf],
) -> PartialReport {
    PartialReport {
        format: PARTIAL_FORMAT.into(),
        command: command.into(),
        version: env!("CARGO_PKG_VERSION").into(),
        scene_hash,
        options_hash: options_hash(canonical),
        shard,
        title: String::new(),
        preamble: String::new(),
        files: files
            .iter()
            .filter_map(|p| p.file_name())
            .map(|n| n.to_string_lossy().into_owned())
            .collect(),
        peak_memory_bytes: crate::measure::memory::peak_bytes().unwrap_or(0),
        records: Vec::new(),
    }
}

/// Write a file-only shard's partial report into `dir` (atomically): `command` names the
/// merge, `canonical` every option that shapes the files, `files` what the shard wrote in
/// `dir` (others are not listed: the merge copies one folder per shard).
pub fn write_partial(
    dir: &Path,
    command: &str,
    scene: &DynamicScene,
    canonical: &str,
    shard: Shard,
    files: &[PathBuf],
) -> anyhow::Result<()> {
    let here: Vec<PathBuf> = files
        .iter()
        .filter(|f| folder_of(f) == dir)
        .cloned()
        .collect();
    let partial = partial_report(command, scene_hash(scene), canonical, shard, &here);
    let mut set = OutputSet::new();
    set.write(
        &dir.join(REPORT),
        serde_json::to_string_pretty(&partial)?.as_bytes(),
    )?;
    set.commit()?;
    Ok(())
}
