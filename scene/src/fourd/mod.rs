//! 4D Gaussian models: Gaussians whose values depend on time, read from the files that
//! dynamic-scene methods and viewers write, and evaluated at any time exactly as the
//! reference implementation of each does.
//!
//! | form | module | time | reference followed |
//! |---|---|---|---|
//! | SpacetimeGaussians "lite" PLY | [`spacetime`] | continuous, [0, 1] | oppo-us-research/SpacetimeGaussians `scene/ourslite.py`, `renderer/__init__.py::train_ours_lite` |
//! | `.splatv` | [`splatv`] | continuous, [0, 1] | antimatter15/splaTV `hybrid.js` (reader, vertex shader) |
//! | Dynamic3DGaussians `params.npz` | [`npz`] | frame i at i/fps | JonathonLuiten/Dynamic3DGaussians `visualize.py::load_scene_data`, `helpers.py::save_params` |
//! | numbered per-frame files | [`sequence`] | frame i at i/fps | (frames in name order) |
//!
//! A model becomes a [`crate::dynamic::DynamicScene`] whose [`DynamicScene::composite`]
//! samples it ([`FourD::sample`]), so every command that takes a time takes these files. Code
//! that needs every frame (decomposition, per-frame export) walks [`FourD::frame_times`] and
//! calls [`FourD::sample`] per time: a numbered sequence reads one frame file per call and keeps
//! only the last frame read, and a `params.npz` reads that timestep's slice of its arrays
//! ([`npz_frames`]), so a long sequence is streamed, never held whole.
//!
//! Sampled clouds keep the crate's stored-value convention: log-scales, opacity logits
//! (`logit(0) = −∞` for a Gaussian the model hides at that time), raw w,x,y,z quaternions, and
//! colours as SH degree-0 coefficients (`dc = (rgb − 0.5)/C0` for models that store RGB).
//!
//! [`DynamicScene::composite`]: crate::dynamic::DynamicScene::composite

pub mod npz;
pub mod npz_frames;
pub mod sequence;
pub mod spacetime;
pub mod splatv;

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;

use crate::dynamic::{DynamicScene, TimeRange};
use crate::error::{Result, SceneError};
use crate::GaussianCloud;

pub use sequence::{is_sequence_spec, Sequence};
pub use spacetime::SpacetimeModel;

/// Frame rate of frame-based models when none is given (`--fps`).
pub const DEFAULT_FPS: f64 = 30.0;

/// The frame rate [`crate::formats::load`] gives 4D models, as f64 bits; 0 means unset.
static FRAME_RATE: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Set the frame rate every later load gives 4D models (the CLI's global `--fps`).
pub fn set_frame_rate(fps: f64) -> std::result::Result<(), String> {
    let fps = check_fps(fps)?;
    FRAME_RATE.store(fps.to_bits(), std::sync::atomic::Ordering::Relaxed);
    Ok(())
}

/// The frame rate loads use: the one set by [`set_frame_rate`], else [`DEFAULT_FPS`].
pub fn frame_rate() -> f64 {
    match FRAME_RATE.load(std::sync::atomic::Ordering::Relaxed) {
        0 => DEFAULT_FPS,
        bits => f64::from_bits(bits),
    }
}

/// Which 4D form a model was read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FourDForm {
    SpacetimeLite,
    Splatv,
    Npz,
    Sequence,
}

impl FourDForm {
    pub fn name(self) -> &'static str {
        match self {
            FourDForm::SpacetimeLite => "SpacetimeGaussians lite PLY",
            FourDForm::Splatv => ".splatv (splaTV)",
            FourDForm::Npz => "Dynamic3DGaussians params.npz",
            FourDForm::Sequence => "numbered frame sequence",
        }
    }
}

/// The time-dependent part of a model.
#[derive(Debug)]
pub enum Motion {
    /// Continuous time: polynomial motion, rotation velocity, temporal RBF opacity.
    Spacetime(SpacetimeModel),
    /// Per-frame arrays read per frame from a `params.npz` (stored members at their offsets,
    /// deflated ones decompressed in order).
    Frames(Box<npz_frames::NpzFrames>),
    /// One file per frame, read when sampled.
    Sequence(Sequence),
}

/// A 4D model and its time axis.
#[derive(Debug)]
pub struct FourD {
    pub form: FourDForm,
    pub motion: Motion,
    /// Frame rate: the spacing of frame-based models, the sampling rate of continuous ones.
    pub fps: f64,
}

impl FourD {
    /// Number of frames of a frame-based model; for a continuous model, the samples at `fps`
    /// over its range.
    pub fn frame_count(&self) -> usize {
        match &self.motion {
            Motion::Spacetime(_) => self.time_range().frame_count(),
            Motion::Frames(f) => f.frames,
            Motion::Sequence(s) => s.len(),
        }
    }

    /// The time range: [0, 1] for the continuous models (their training time axis), frame 0 to
    /// frame n−1 at `fps` for frame-based ones.
    pub fn time_range(&self) -> TimeRange {
        let end = match &self.motion {
            Motion::Spacetime(_) => 1.0,
            Motion::Frames(f) => (f.frames.max(1) - 1) as f64 / self.fps,
            Motion::Sequence(s) => (s.len().max(1) - 1) as f64 / self.fps,
        };
        TimeRange {
            start: 0.0,
            end,
            fps: self.fps,
        }
    }

    /// The frame times (`i/fps`), for a continuous model its samples at `fps` over [0, 1].
    pub fn frame_times(&self) -> Vec<f64> {
        let r = self.time_range();
        (0..self.frame_count()).map(|i| r.frame_time(i)).collect()
    }

    /// The frame shown at time `t` by a frame-based model: the last frame at or before `t`
    /// (frames are held until the next one), clamped to the sequence. `None` for continuous
    /// models.
    pub fn frame_at(&self, t: f64) -> Option<usize> {
        let n = match &self.motion {
            Motion::Spacetime(_) => return None,
            Motion::Frames(f) => f.frames,
            Motion::Sequence(s) => s.len(),
        };
        Some(frame_index(t, self.fps, n))
    }

    /// Most Gaussians at any time (the capacity a sampled cloud needs).
    pub fn max_count(&self) -> usize {
        match &self.motion {
            Motion::Spacetime(m) => m.len(),
            Motion::Frames(f) => f.count,
            Motion::Sequence(s) => s.max_count(),
        }
    }

    /// True when every frame has the same Gaussians in the same order (always, except for a
    /// sequence whose frames differ in count).
    pub fn same_count(&self) -> bool {
        match &self.motion {
            Motion::Sequence(s) => s.same_count(),
            _ => true,
        }
    }

    /// The Gaussians at time `t`, evaluated as the model's reference implementation does.
    pub fn sample(&self, t: f64) -> Result<GaussianCloud> {
        match &self.motion {
            Motion::Spacetime(m) => Ok(m.sample(t as f32)),
            Motion::Frames(f) => f.frame(frame_index(t, self.fps, f.frames)),
            Motion::Sequence(s) => s
                .frame(frame_index(t, self.fps, s.len()))
                .map(|c| (*c).clone()),
        }
    }

    /// How far the Gaussians move over the model's frames: per-Gaussian largest displacement
    /// from their position at the start, summarised (needs the same count in every frame;
    /// `None` otherwise). Streams frame by frame.
    pub fn displacement(&self) -> Result<Option<Displacement>> {
        if !self.same_count() {
            return Ok(None);
        }
        let times = self.frame_times();
        let Some(&t0) = times.first() else {
            return Ok(None);
        };
        let first = self.sample(t0)?;
        let mut max_d = vec![0f32; first.len()];
        for &t in &times[1..] {
            let c = self.sample(t)?;
            if c.len() != first.len() {
                return Ok(None);
            }
            for (d, (a, b)) in max_d.iter_mut().zip(first.means.iter().zip(&c.means)) {
                let dist = a.distance(*b);
                if dist.is_finite() && dist > *d {
                    *d = dist;
                }
            }
        }
        let extent = first
            .robust_bounds(0.02)
            .map_or(0.0, |(lo, hi)| (hi - lo).max_element());
        Ok(Some(Displacement::from(max_d, extent)))
    }
}

/// Summary of how far Gaussians travel over a model's frames.
#[derive(Clone, Debug, PartialEq)]
pub struct Displacement {
    /// Median, 95th percentile and largest per-Gaussian displacement (world units).
    pub median: f32,
    pub p95: f32,
    pub max: f32,
    /// Fraction of Gaussians that move more than 1 % of the scene's extent.
    pub moving_fraction: f32,
    /// The scene's extent (largest side of the robust bounds at the start).
    pub extent: f32,
}

impl Displacement {
    fn from(mut d: Vec<f32>, extent: f32) -> Self {
        if d.is_empty() {
            return Displacement {
                median: 0.0,
                p95: 0.0,
                max: 0.0,
                moving_fraction: 0.0,
                extent,
            };
        }
        d.sort_by(f32::total_cmp);
        let at = |q: f64| d[((d.len() - 1) as f64 * q).round() as usize];
        let threshold = 0.01 * extent;
        let moving = d.iter().filter(|&&x| x > threshold).count();
        Displacement {
            median: at(0.5),
            p95: at(0.95),
            max: d[d.len() - 1],
            moving_fraction: moving as f32 / d.len() as f32,
            extent,
        }
    }
}

/// The frame shown at `t`: `floor(t·fps)` with a nanosecond of slack (so `i/fps` computed in
/// f64 lands on frame i), clamped to `[0, n−1]`; a NaN time is frame 0.
pub fn frame_index(t: f64, fps: f64, n: usize) -> usize {
    if n == 0 || t.is_nan() || t <= 0.0 || fps.is_nan() || fps <= 0.0 {
        return 0;
    }
    let f = (t * fps + 1e-6).floor();
    if f.is_finite() && f >= 0.0 {
        (f as usize).min(n - 1)
    } else {
        n - 1
    }
}

/// Check an `--fps` value: finite and positive.
pub fn check_fps(fps: f64) -> std::result::Result<f64, String> {
    if fps.is_finite() && fps > 0.0 && fps <= 1e6 {
        Ok(fps)
    } else {
        Err(format!(
            "--fps {fps} must be a positive frame rate (at most 1e6)"
        ))
    }
}

/// A colour as the renderer's SH degree-0 coefficient: `dc = (rgb − 0.5)/C0`, so the 3DGS
/// evaluation `0.5 + C0·dc` gives `rgb` back (to f32 rounding).
pub(crate) fn rgb_to_dc(rgb: Vec3) -> Vec3 {
    (rgb - Vec3::splat(0.5)) / crate::sh::SH_C0
}

/// Wrap a model as a scene: the model sampled at its start is the static cloud (what code that
/// reads `static_gaussians` directly sees) and [`DynamicScene::composite`] samples the model.
pub fn into_scene(model: FourD) -> Result<DynamicScene> {
    let range = model.time_range();
    let first = model.sample(range.start)?;
    let mut scene = DynamicScene::from_static(first);
    scene.time = range;
    scene.four_d = Some(Arc::new(model));
    Ok(scene)
}

/// Load a 4D model of a known form.
pub fn load(path: &Path, form: FourDForm, fps: f64) -> Result<FourD> {
    let fps = check_fps(fps).map_err(|e| SceneError::format(path, e))?;
    let motion = match form {
        FourDForm::SpacetimeLite => Motion::Spacetime(spacetime::read_spacetime_ply(path)?),
        FourDForm::Splatv => Motion::Spacetime(splatv::read_splatv(path)?),
        FourDForm::Npz => Motion::Frames(Box::new(npz_frames::NpzFrames::open(path)?)),
        FourDForm::Sequence => Motion::Sequence(Sequence::open(path)?),
    };
    Ok(FourD { form, motion, fps })
}
