//! Sequences of Gaussian frames (4D captures) to scenes: what `convert --objects` and
//! `convert --frames` run on a sequence. [`decompose_scene`] finds what moves
//! (`splatbridge_convert::motion`: static background, rigid objects with tracks, per-frame
//! content) and [`frames_scene`] keeps every frame whole; both give a `DynamicScene`, so a
//! manifest, a glTF export (objects as animated nodes, per-frame content as nodes switched
//! by stepped scale keys) and every other command take the result.
//!
//! [`read_frames`] samples any 4D input the scene crate reads (SpacetimeGaussians PLY,
//! `.splatv`, `params.npz`, numbered frames) at its frame times and gives the
//! `(frames, times)` these functions take.

use std::path::Path;

use anyhow::bail;
use serde::Serialize;
use splatbridge_convert::motion::{decompose, DecomposeOptions, Decomposition};
use splatbridge_scene::dynamic::{DynamicScene, FrameContent, TimeRange};
use splatbridge_scene::formats::SplatFormat;
use splatbridge_scene::fourd::Motion;
use splatbridge_scene::GaussianCloud;

/// Most frames a decomposition holds in memory at once: it fits every frame's Gaussians
/// together, so their count bounds what it allocates.
pub const MAX_FRAMES: usize = 100_000;

/// The frames of any 4D input (SpacetimeGaussians PLY, `.splatv`, `params.npz`, a numbered
/// frame sequence as a folder or a pattern) and their times: each model sampled at its frame
/// times (`i/fps`, continuous models at `fps` over their own range), as its reader evaluates
/// it (`splatbridge_scene::fourd`). `same_count` asks every frame to hold the same Gaussians
/// in the same order (what finding rigid motion needs); a sequence whose counts differ is
/// then refused naming the first frame that differs.
pub fn read_frames(
    path: &Path,
    fps: f64,
    same_count: bool,
) -> anyhow::Result<(Vec<GaussianCloud>, Vec<f64>)> {
    let form = match splatbridge_scene::formats::detect(path)? {
        SplatFormat::FourD(form) => form,
        other => bail!(
            "{}: {other} holds no motion: --objects and --frames read a 4D model (SpacetimeGaussians PLY, .splatv, params.npz, numbered frames)",
            path.display()
        ),
    };
    let model = splatbridge_scene::fourd::load(path, form, fps)?;
    if same_count {
        if let Motion::Sequence(seq) = &model.motion {
            if let Some(i) = (1..seq.counts.len()).find(|&i| seq.counts[i] != seq.counts[0]) {
                bail!(
                    "{}: {} Gaussians, the first frame ({}) has {}: finding what moves needs the same Gaussians in every frame",
                    seq.files[i].display(),
                    seq.counts[i],
                    seq.files[0].display(),
                    seq.counts[0]
                );
            }
        }
    }
    let times = model.frame_times();
    if times.len() > MAX_FRAMES {
        bail!(
            "{}: {} frames, more than the {MAX_FRAMES} a decomposition holds",
            path.display(),
            times.len()
        );
    }
    let frames = times
        .iter()
        .map(|&t| model.sample(t))
        .collect::<Result<Vec<_>, _>>()?;
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
