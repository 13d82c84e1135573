//! Sequences of Gaussian frames (4D captures) to scenes: what `convert --objects` and
//! `convert --frames` run on a sequence. [`decompose_scene`] finds what moves
//! (`splatbridge_convert::motion`: static background, rigid objects with tracks, per-frame
//! content) and [`frames_scene`] keeps every frame whole; both give a `DynamicScene`, so a
//! manifest, a glTF export (objects as animated nodes, per-frame content as nodes switched
//! by stepped scale keys) and every other command take the result.
//!
//! [`read_frame_folder`] reads a folder of numbered frames (`name_0000.ply`, …: any splat
//! file the loader recognises, numbered in name order) with frame i at i/fps seconds. Other
//! 4D forms give the same `(frames, times)` to these functions.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use serde::Serialize;
use splatbridge_convert::motion::{decompose, DecomposeOptions, Decomposition};
use splatbridge_scene::dynamic::{DynamicScene, FrameContent, TimeRange};
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::GaussianCloud;

/// Most frames a folder may hold (the scene's own frame limit is far above what memory holds).
pub const MAX_FOLDER_FRAMES: usize = 100_000;

/// The frame files of a folder in frame order: regular files with a splat extension
/// (`.ply`, `.splat`, `.spz`), ordered by the number at the end of their stem, then by name.
pub fn frame_files(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let rd = std::fs::read_dir(dir).with_context(|| dir.display().to_string())?;
    let mut files: Vec<(u64, String, PathBuf)> = Vec::new();
    for e in rd {
        let p = e.with_context(|| dir.display().to_string())?.path();
        let ext = p
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        if !p.is_file() || !matches!(ext.as_str(), "ply" | "splat" | "spz") {
            continue;
        }
        let stem = p
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let digits: String = stem
            .chars()
            .rev()
            .take_while(|c| c.is_ascii_digit())
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect();
        let n = digits.parse::<u64>().unwrap_or(u64::MAX);
        files.push((n, stem, p));
        if files.len() > MAX_FOLDER_FRAMES {
            bail!(
                "{}: more than {MAX_FOLDER_FRAMES} frame files",
                dir.display()
            );
        }
    }
    if files.is_empty() {
        bail!(
            "{}: no frame files (.ply, .splat or .spz) in this folder",
            dir.display()
        );
    }
    files.sort();
    Ok(files.into_iter().map(|(_, _, p)| p).collect())
}

/// Read a folder of numbered frames: the frames and their times (i/fps).
pub fn read_frame_folder(dir: &Path, fps: f64) -> anyhow::Result<(Vec<GaussianCloud>, Vec<f64>)> {
    if !(fps > 0.0 && fps.is_finite()) {
        bail!("--fps: {fps} is not a positive frame rate");
    }
    let files = frame_files(dir)?;
    let mut frames = Vec::with_capacity(files.len());
    for p in &files {
        let (cloud, _) = splatbridge_scene::formats::load_cloud(p, &ReadOptions::default())?;
        if let Some(first) = frames.first() {
            let first: &GaussianCloud = first;
            if cloud.len() != first.len() {
                bail!(
                    "{}: {} Gaussians, the first frame ({}) has {}: finding what moves needs the same Gaussians in every frame",
                    p.display(),
                    cloud.len(),
                    files[0].display(),
                    first.len()
                );
            }
        }
        frames.push(cloud);
    }
    let times = (0..frames.len()).map(|i| i as f64 / fps).collect();
    Ok((frames, times))
}

/// Every frame whole, as per-frame content (no static part, no objects).
pub fn frames_scene(
    frames: Vec<GaussianCloud>,
    times: &[f64],
    fps: f64,
) -> anyhow::Result<DynamicScene> {
    let Some((&start, &end)) = times.first().zip(times.last()) else {
        bail!("no frames");
    };
    let scene = DynamicScene {
        four_d: None,
        time: TimeRange { start, end, fps },
        static_gaussians: GaussianCloud::new(0),
        objects: Vec::new(),
        frames: frames
            .into_iter()
            .zip(times)
            .map(|(gaussians, &t)| FrameContent { t, gaussians })
            .collect(),
        cameras: Vec::new(),
        effects: serde_json::Map::new(),
    };
    scene.validate()?;
    Ok(scene)
}

/// One group of a decomposition, as reported.
#[derive(Clone, Debug, Serialize)]
pub struct GroupReport {
    pub name: String,
    pub gaussians: usize,
    /// RMS and largest distance between the Gaussians and their rigid fit, world units.
    pub rms: f64,
    pub max: f64,
}

/// What a decomposition found.
#[derive(Clone, Debug, Serialize)]
pub struct MotionReport {
    pub frames: usize,
    pub gaussians: usize,
    pub noise: f64,
    pub tolerance: f64,
    pub static_gaussians: usize,
    /// RMS distance of the static Gaussians from their mean position, world units.
    pub static_rms: f64,
    pub groups: Vec<GroupReport>,
    /// Gaussians kept per frame (moving without a rigid fit, or changing opacity or scale).
    pub per_frame_gaussians: usize,
    pub seconds: f64,
}

impl MotionReport {
    pub fn of(d: &Decomposition, frames: usize, seconds: f64) -> Self {
        MotionReport {
            frames,
            gaussians: d.labels.len(),
            noise: d.noise,
            tolerance: d.tolerance,
            static_gaussians: d.static_count,
            static_rms: d.static_rms,
            groups: d
                .groups
                .iter()
                .enumerate()
                .map(|(k, g)| GroupReport {
                    name: format!("object_{k}"),
                    gaussians: g.members.len(),
                    rms: g.rms,
                    max: g.max,
                })
                .collect(),
            per_frame_gaussians: d.per_frame,
            seconds,
        }
    }
}

/// Decompose `frames` (at `times`) and make the scene, with its report.
pub fn decompose_scene(
    frames: &[GaussianCloud],
    times: &[f64],
    fps: f64,
    opts: &DecomposeOptions,
) -> anyhow::Result<(DynamicScene, MotionReport)> {
    let t0 = std::time::Instant::now();
    let d = decompose(frames, times, opts)?;
    let scene = d.to_scene(frames, times, fps)?;
    Ok((
        scene,
        MotionReport::of(&d, frames.len(), t0.elapsed().as_secs_f64()),
    ))
}
