//! Sequences of Gaussian frames (4D captures) to scenes: what `convert --objects` and
//! `convert --frames` run on a sequence. [`decompose_scene`] finds what moves
//! (`splatbridge_convert::motion`: static background, rigid objects with tracks, per-frame
//! content) and [`frames_scene`] keeps every frame whole (in memory; [`export_frames`] writes
//! every frame whole one frame at a time); both give a `DynamicScene`, so a
//! manifest, a glTF export (objects as animated nodes, per-frame content as nodes switched
//! by stepped scale keys) and every other command take the result.
//!
//! The report ([`MotionReport`]) gives, per rigid group, its Gaussians and the residual of the
//! rigid fit twice: as distances in world units, and as the PSNR of native splatting of the
//! group as fitted (its local cloud placed by its track) against the group's true Gaussians of
//! that frame, at [`FIT_TIMES`] sampled frames, through a camera framed on the group — what the
//! residual costs in an image, where a distance alone does not say whether it shows.
//!
//! [`read_frames`] samples any 4D input the scene crate reads (SpacetimeGaussians PLY,
//! `.splatv`, `params.npz`, numbered frames) at its frame times and gives the
//! `(frames, times)` these functions take.

use std::borrow::Cow;
use std::path::Path;

use anyhow::bail;
use serde::Serialize;
use splatbridge_convert::frames_gltf::{
    write_frames_dir, write_frames_file, FramesIndex, FramesLimits,
};
use splatbridge_convert::frames_morph::write_frames_morph;
use splatbridge_convert::motion::stream::{decompose_streamed, FrameSource};
use splatbridge_convert::motion::{subset, DecomposeOptions, Decomposition};
use splatbridge_convert::{ConvertOptions, ConvertReport};
use splatbridge_hybrid::native::{render, RenderOptions};
use splatbridge_scene::camera::OrbitRig;
use splatbridge_scene::dynamic::{DynamicScene, FrameContent, TimeRange};
use splatbridge_scene::formats::SplatFormat;
use splatbridge_scene::fourd::{FourD, Motion};
use splatbridge_scene::metrics::psnr;
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
    let (model, times) = open_model(path, fps, same_count)?;
    let frames = times
        .iter()
        .map(|&t| model.sample(t))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((frames, times))
}

/// The 4D model at `path` and its frame times, checked as [`read_frames`] checks them, without
/// reading any frame.
pub fn open_model(path: &Path, fps: f64, same_count: bool) -> anyhow::Result<(FourD, Vec<f64>)> {
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
    Ok((model, times))
}

/// A 4D model's frames read one at a time: frame `f` is the model sampled at `times[f]` (a
/// numbered sequence reads that frame's file; nothing else is kept).
pub struct ModelFrames<'a> {
    pub model: &'a FourD,
    pub times: &'a [f64],
}

impl FrameSource for ModelFrames<'_> {
    fn len(&self) -> usize {
        self.times.len()
    }
    fn frame(&self, f: usize) -> splatbridge_convert::Result<Cow<'_, GaussianCloud>> {
        Ok(Cow::Owned(self.model.sample(self.times[f])?))
    }
}

/// What `convert --frames` wrote.
pub enum FramesWritten {
    /// One animated glTF (`.glb`, or `.gltf` + `.bin`).
    File(ConvertReport),
    /// One GLB per frame and the index (`DIR/frames.json`); the report sums the frames.
    Dir(FramesIndex, ConvertReport),
}

/// Gaussians over every frame of a model, from what it knows without reading the frames.
pub fn total_gaussians(model: &FourD, frames: usize) -> u64 {
    match &model.motion {
        Motion::Sequence(s) => s.counts.iter().map(|&c| c as u64).sum(),
        _ => frames as u64 * model.max_count() as u64,
    }
}

/// How one animated glTF of `convert --frames` holds the frames (measured in docs/motion.md,
/// "Per-frame nodes or morph targets").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FramesEncoding {
    /// A node per frame switched by stepped scale keys (`frames_gltf`): takes every 4D input
    /// and every layout.
    #[default]
    Nodes,
    /// One mesh, frame 0 as its base and a morph target per later frame, STEP weights
    /// (`frames_morph`): only frames that mesh to frame 0's topology, in the input layout.
    Morph,
}

/// `convert --frames`: every frame of `model` (at `times`) meshed whole with `opts`, one frame
/// in memory at a time, into one animated glTF at `output` encoded as `encoding` or, with
/// `dir`, one GLB per frame in the folder `output` (`splatbridge_convert::frames_gltf`).
/// Surfels and a triangle budget split or budget every frame together, so with those the
/// frames are held and the in-memory writer writes the file (per-frame nodes only). Morph
/// targets are refused for a folder, and by their writer for options they cannot carry and
/// for frames whose topology differs from frame 0's (naming the first).
#[allow(clippy::too_many_arguments)]
pub fn export_frames(
    model: &FourD,
    times: &[f64],
    fps: f64,
    output: &Path,
    opts: &ConvertOptions,
    dir: bool,
    encoding: FramesEncoding,
) -> anyhow::Result<FramesWritten> {
    let src = ModelFrames { model, times };
    let limits = FramesLimits {
        total_gaussians: Some(total_gaussians(model, times.len())),
        ..FramesLimits::default()
    };
    if encoding == FramesEncoding::Morph {
        if dir {
            bail!(
                "{}: morph targets are written to one .glb or .gltf, not one GLB per frame",
                output.display()
            );
        }
        let report = write_frames_morph(output, &src, times, opts, &limits, &[])?;
        return Ok(FramesWritten::File(report));
    }
    if dir {
        let (index, report) = write_frames_dir(output, &src, times, fps, opts)?;
        return Ok(FramesWritten::Dir(index, report));
    }
    if opts.surfels.is_some() || opts.max_triangles.is_some() {
        let frames = times
            .iter()
            .map(|&t| model.sample(t))
            .collect::<Result<Vec<_>, _>>()?;
        let scene = frames_scene(frames, times, fps)?;
        let report = splatbridge_convert::convert_to_file(output, &scene, None, opts, true)?;
        return Ok(FramesWritten::File(report));
    }
    Ok(FramesWritten::File(write_frames_file(
        output, &src, times, opts, &limits,
    )?))
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

/// Frames at which each group's fit is rendered (evenly spread, first and last included).
pub const FIT_TIMES: usize = 4;
/// Size of the images the fit is measured in: enough pixels for a framed object's detail at a
/// cost of milliseconds a render.
pub const FIT_IMAGE: (u32, u32) = (128, 96);
/// PSNR reported for identical images (∞; JSON has no infinity): above any measured figure.
pub const PSNR_IDENTICAL: f64 = 100.0;

/// PSNR of a group's fit at one time.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct FitPsnr {
    pub t: f64,
    pub psnr: f64,
}

/// One group of a decomposition, as reported.
#[derive(Clone, Debug, Serialize)]
pub struct GroupReport {
    pub name: String,
    pub gaussians: usize,
    /// RMS and largest distance between the Gaussians and their rigid fit, world units.
    pub rms: f64,
    pub max: f64,
    /// Native splatting of the fitted group against its true Gaussians at sampled times
    /// (camera framed on the group at each); empty when not measured.
    pub psnr: Vec<FitPsnr>,
}

impl GroupReport {
    /// The lowest PSNR over the sampled times.
    pub fn psnr_min(&self) -> Option<f64> {
        self.psnr.iter().map(|p| p.psnr).reduce(f64::min)
    }
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
    /// Of those, the ones whose opacity or scales change.
    pub per_frame_appearance: usize,
    /// RMS distance of the per-frame Gaussians from their first position, world units.
    pub per_frame_motion_rms: f64,
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
                    psnr: Vec::new(),
                })
                .collect(),
            per_frame_gaussians: d.per_frame,
            per_frame_appearance: d.per_frame_appearance,
            per_frame_motion_rms: d.per_frame_motion_rms,
            seconds,
        }
    }
}

/// The frames a group's fit is measured at: [`FIT_TIMES`] evenly spread, first and last
/// included, without repeats.
pub fn fit_frames(n: usize) -> Vec<usize> {
    let mut f: Vec<usize> = (0..FIT_TIMES)
        .map(|k| k * n.saturating_sub(1) / (FIT_TIMES - 1))
        .collect();
    f.dedup();
    f
}

/// PSNR of object `k` of `scene` (the fitted group: its local cloud placed by its track) against
/// the group's true Gaussians `truths` (time, cloud) of sampled frames, both splatted natively
/// through a camera framed on the true group in that frame.
pub fn fit_psnr(
    scene: &DynamicScene,
    k: usize,
    truths: &[(f64, GaussianCloud)],
) -> anyhow::Result<Vec<FitPsnr>> {
    let object = &scene.objects[k];
    let alone = DynamicScene {
        four_d: None,
        time: scene.time,
        static_gaussians: GaussianCloud::new(object.gaussians.sh_degree),
        objects: vec![object.clone()],
        frames: Vec::new(),
        cameras: Vec::new(),
        effects: serde_json::Map::new(),
    };
    let rig = OrbitRig {
        width: FIT_IMAGE.0,
        height: FIT_IMAGE.1,
        ..OrbitRig::default()
    };
    let ropts = RenderOptions::default();
    let mut out = Vec::with_capacity(truths.len());
    for (t, truth) in truths {
        let fitted = alone.composite(*t);
        let cam = rig.camera(truth, 4, 1)?;
        let (a, _) = render(truth, &cam, &ropts)?;
        let (b, _) = render(&fitted, &cam, &ropts)?;
        let db = psnr(&a, &b)?;
        out.push(FitPsnr {
            t: *t,
            psnr: if db.is_finite() { db } else { PSNR_IDENTICAL },
        });
    }
    Ok(out)
}

/// Decompose `frames` (at `times`) and make the scene, with its report (each group's fit
/// measured as PSNR at [`fit_frames`]). The frames are read through [`FrameSource`]: three
/// passes, one frame at a time ([`splatbridge_convert::motion::stream`]).
pub fn decompose_frames(
    src: &(impl FrameSource + ?Sized),
    times: &[f64],
    fps: f64,
    opts: &DecomposeOptions,
) -> anyhow::Result<(DynamicScene, MotionReport)> {
    let t0 = std::time::Instant::now();
    let sd = decompose_streamed(src, times, opts)?;
    let d = &sd.decomposition;
    let at = fit_frames(src.len());
    // truths[k]: group k's true Gaussians at each sampled frame.
    let mut truths: Vec<Vec<(f64, GaussianCloud)>> = vec![Vec::new(); d.groups.len()];
    let scene = sd.to_scene(src, times, fps, |f, c| {
        if at.contains(&f) {
            for (k, g) in d.groups.iter().enumerate() {
                let truth = subset(c, |i| g.members.binary_search(&(i as u32)).is_ok());
                truths[k].push((times[f], truth));
            }
        }
    })?;
    let mut report = MotionReport::of(d, src.len(), 0.0);
    for (k, tk) in truths.iter().enumerate() {
        report.groups[k].psnr = fit_psnr(&scene, k, tk)?;
    }
    report.seconds = t0.elapsed().as_secs_f64();
    Ok((scene, report))
}

/// [`decompose_frames`] on frames held in memory.
pub fn decompose_scene(
    frames: &[GaussianCloud],
    times: &[f64],
    fps: f64,
    opts: &DecomposeOptions,
) -> anyhow::Result<(DynamicScene, MotionReport)> {
    decompose_frames(frames, times, fps, opts)
}

/// [`decompose_frames`] on the 4D model at `path`, streamed: a numbered sequence is read one
/// frame file at a time (three times over), never held whole.
pub fn decompose_path(
    path: &Path,
    fps: f64,
    opts: &DecomposeOptions,
) -> anyhow::Result<(DynamicScene, MotionReport)> {
    let (model, times) = open_model(path, fps, true)?;
    decompose_frames(
        &ModelFrames {
            model: &model,
            times: &times,
        },
        &times,
        fps,
        opts,
    )
}
