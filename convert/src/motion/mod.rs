//! Finding what moves in a sequence of Gaussian frames: a static background, rigidly moving
//! groups with one SE(3) pose per frame, and per-frame content for what moves but not rigidly
//! — the decomposition dynamic street-scene methods (Street Gaussians, DrivingGaussian) start
//! from, recovered here from trajectories alone.
//!
//! Input: frames of the same Gaussians (same count and order) with their times, as 4D readers
//! give them. Steps:
//! 1. Noise and tolerance: the noise σ is estimated from second differences of the
//!    trajectories (a static or smoothly moving mean has none; noise σ per axis gives an RMS of
//!    √18·σ), the median over Gaussians; the tolerance is 10σ (at least 10⁻⁵ of the scene's
//!    diagonal), or [`DecomposeOptions::tolerance`].
//! 2. Static: a Gaussian whose RMS distance over the frames from its first position is within
//!    the tolerance, and whose opacity and scales do not change ([`APPEARANCE_TOLERANCE`]).
//! 3. Rigid groups among the rest by sequential RANSAC over whole trajectories
//!    ([`cluster`]), each refined by alternating fits: motions from the references, then the
//!    references as the mean of each Gaussian's positions carried back by the motions (which
//!    averages the noise of one frame out of the local shape).
//! 4. What fits no group (or changes opacity or scale) is per-frame content.
//!
//! [`Decomposition::to_scene`] makes the `splatbridge-scene/1` scene: the static cloud (means
//! averaged over frames), one object per group in its local frame (centred, rotations and SH
//! carried back by the first pose) with a track keyed at every frame, and the per-frame
//! content.

mod cluster;
pub mod rigid;
pub mod score;
pub mod stream;

use glam::{DQuat, DVec3, Quat, Vec3};
use rayon::prelude::*;
use splatbridge_scene::dynamic::{
    DynamicScene, FrameContent, Pose, PoseKey, SceneObject, TimeRange, Track,
};
use splatbridge_scene::sh_rotate::ShRotation;
use splatbridge_scene::GaussianCloud;

use crate::{ConvertError, Result};
use cluster::{Search, Trajectories};
pub use rigid::Rigid;

/// Largest change of activated opacity (or of a log-scale) over the frames for a Gaussian to
/// count as the same rigid body part: 0.02 is 5 of 255 display levels of alpha; a Gaussian
/// that fades in or out more is per-frame content.
pub const APPEARANCE_TOLERANCE: f32 = 0.02;

/// How to decompose.
#[derive(Clone, Copy, Debug)]
pub struct DecomposeOptions {
    /// Look for rigid groups (`--objects auto`); `false` keeps everything that moves as
    /// per-frame content (`--objects none`).
    pub objects: bool,
    /// Largest RMS distance (world units) between a Gaussian's positions and its group's
    /// motion; `None`: 10 σ of the estimated noise.
    pub tolerance: Option<f64>,
    /// Fewest Gaussians of a group; smaller clusters stay per-frame content.
    pub min_group: usize,
    /// Most groups.
    pub max_groups: usize,
    /// RANSAC hypotheses per group.
    pub hypotheses: usize,
    /// Seed of the sampling (the result is deterministic for a seed).
    pub seed: u64,
}

impl Default for DecomposeOptions {
    fn default() -> Self {
        DecomposeOptions {
            objects: true,
            tolerance: None,
            min_group: 32,
            max_groups: 64,
            hypotheses: 128,
            seed: 1,
        }
    }
}

/// What a Gaussian became.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Label {
    Static,
    Group(u32),
    PerFrame,
}

impl Label {
    /// A number per part for comparing labelings: 0 static, k+1 group k, `u32::MAX` per-frame.
    pub fn code(self) -> u32 {
        match self {
            Label::Static => 0,
            Label::Group(k) => k + 1,
            Label::PerFrame => u32::MAX,
        }
    }
}

/// One rigid group.
#[derive(Clone, Debug)]
pub struct Group {
    /// Indices of its Gaussians, increasing.
    pub members: Vec<u32>,
    /// Local frame to world, one pose per frame (local = centred reference shape).
    pub poses: Vec<Rigid>,
    /// Each member's position in the local frame.
    pub local: Vec<DVec3>,
    /// RMS over members and frames of the fit's error, world units.
    pub rms: f64,
    /// Largest error of a member at a frame.
    pub max: f64,
}

/// The decomposition of a sequence.
#[derive(Clone, Debug)]
pub struct Decomposition {
    pub labels: Vec<Label>,
    pub groups: Vec<Group>,
    /// Estimated noise σ per axis (world units).
    pub noise: f64,
    /// The tolerance used.
    pub tolerance: f64,
    /// Static Gaussians and the RMS of their distance to their mean position.
    pub static_count: usize,
    pub static_rms: f64,
    /// Gaussians kept per frame, and how many of them because their opacity or scales
    /// change (the rest move but fit no group).
    pub per_frame: usize,
    pub per_frame_appearance: usize,
    /// RMS over the per-frame Gaussians and the frames of their distance from their first
    /// position (world units): how much the content left per frame moves.
    pub per_frame_motion_rms: f64,
}

fn check(frames: &[GaussianCloud], times: &[f64]) -> Result<()> {
    if frames.is_empty() {
        return Err(ConvertError::Invalid("no frames to decompose".into()));
    }
    if frames.len() != times.len() {
        return Err(ConvertError::Invalid(format!(
            "{} frames but {} times",
            frames.len(),
            times.len()
        )));
    }
    if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| !(w[1] > w[0])) {
        return Err(ConvertError::Invalid(
            "frame times must be finite and strictly increasing".into(),
        ));
    }
    let n = frames[0].len();
    for (f, c) in frames.iter().enumerate() {
        stream::check_frame(c, f, n)?;
    }
    Ok(())
}

/// Noise σ per axis from second differences (median over up to 20 000 Gaussians spread over
/// the index range); 0 with fewer than three frames.
fn estimate_noise(tr: &Trajectories) -> f64 {
    let nf = tr.frames();
    let n = tr.pos[0].len();
    if nf < 3 || n == 0 {
        return 0.0;
    }
    let step = n.div_ceil(20_000).max(1);
    let mut v: Vec<f64> = (0..n)
        .step_by(step)
        .map(|i| {
            let s: f64 = (1..nf - 1)
                .map(|f| {
                    (tr.pos[f + 1][i] - 2.0 * tr.pos[f][i] + tr.pos[f - 1][i]).length_squared()
                })
                .sum();
            (s / (nf - 2) as f64).sqrt()
        })
        .collect();
    let mid = v.len() / 2;
    v.select_nth_unstable_by(mid, f64::total_cmp);
    v[mid] / 18f64.sqrt()
}

fn appearance_changes(frames: &[GaussianCloud], i: usize) -> bool {
    let a0 = frames[0].opacity(i);
    let s0 = frames[0].log_scales[i];
    frames[1..].iter().any(|c| {
        (c.opacity(i) - a0).abs() > APPEARANCE_TOLERANCE
            || (c.log_scales[i] - s0).abs().max_element() > APPEARANCE_TOLERANCE
    })
}

/// Split `frames` (the same Gaussians at `times`) into static, rigid groups and per-frame
/// content. Errors: no frames, counts that differ, times not increasing, non-finite means.
pub fn decompose(
    frames: &[GaussianCloud],
    times: &[f64],
    opts: &DecomposeOptions,
) -> Result<Decomposition> {
    check(frames, times)?;
    let n = frames[0].len();
    let tr = Trajectories {
        pos: frames
            .iter()
            .map(|c| c.means.iter().map(|m| m.as_dvec3()).collect())
            .collect(),
    };
    let nf = tr.frames();
    let noise = estimate_noise(&tr);
    let diag = frames[0]
        .bounds()
        .map(|(lo, hi)| (hi - lo).as_dvec3().length())
        .unwrap_or(0.0);
    let tolerance = opts
        .tolerance
        .unwrap_or_else(|| (10.0 * noise).max(1e-5 * diag).max(f64::MIN_POSITIVE));
    let tol2 = tolerance * tolerance;
    let identity = vec![Rigid::IDENTITY; nf];
    let all: Vec<usize> = (0..nf).collect();
    let changes: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|i| appearance_changes(frames, i))
        .collect();
    let mut labels: Vec<Label> = (0..n)
        .into_par_iter()
        .map(|i| {
            if changes[i] {
                Label::PerFrame
            } else if tr.msd(&identity, &all, tr.pos[0][i], i, tol2) <= tol2 {
                Label::Static
            } else {
                Label::PerFrame
            }
        })
        .collect();
    let mut groups = Vec::new();
    if opts.objects {
        let moving: Vec<u32> = (0..n as u32)
            .filter(|&i| labels[i as usize] == Label::PerFrame && !changes[i as usize])
            .collect();
        let search = Search {
            tolerance,
            min_group: opts.min_group,
            max_groups: opts.max_groups,
            hypotheses: opts.hypotheses.max(1),
            seed: opts.seed,
        };
        let (found, _rest) = cluster::find_groups(&tr, &moving, &search);
        for (k, mut g) in found.into_iter().enumerate() {
            // Index order: the object's cloud keeps the input's order (`to_scene`).
            g.members.sort_unstable();
            for &i in &g.members {
                labels[i as usize] = Label::Group(k as u32);
            }
            groups.push(refine(&tr, g.members, g.motions));
        }
    }
    let statics: Vec<usize> = (0..n).filter(|&i| labels[i] == Label::Static).collect();
    let static_sq: f64 = statics
        .par_iter()
        .map(|&i| {
            let mean = all.iter().map(|&f| tr.pos[f][i]).sum::<DVec3>() / nf as f64;
            all.iter()
                .map(|&f| (tr.pos[f][i] - mean).length_squared())
                .sum::<f64>()
        })
        .collect::<Vec<f64>>()
        // Added in order: a parallel `sum` would associate as the pool splits the work, and
        // the report's RMS would change in its last bits from run to run.
        .iter()
        .sum();
    let per_frame_idx: Vec<usize> = (0..n).filter(|&i| labels[i] == Label::PerFrame).collect();
    let per_frame_sq: f64 = per_frame_idx
        .par_iter()
        .map(|&i| {
            all.iter()
                .map(|&f| (tr.pos[f][i] - tr.pos[0][i]).length_squared())
                .sum::<f64>()
        })
        .collect::<Vec<f64>>()
        .iter()
        .sum();
    Ok(Decomposition {
        per_frame: per_frame_idx.len(),
        per_frame_appearance: per_frame_idx.iter().filter(|&&i| changes[i]).count(),
        per_frame_motion_rms: (per_frame_sq / (per_frame_idx.len() * nf).max(1) as f64).sqrt(),
        static_count: statics.len(),
        static_rms: (static_sq / (statics.len() * nf).max(1) as f64).sqrt(),
        labels,
        groups,
        noise,
        tolerance,
    })
}

/// Alternate motions and reference shape (three rounds), then centre the shape: the local
/// frame's origin is the members' centroid.
fn refine(tr: &Trajectories, members: Vec<u32>, motions: Vec<Rigid>) -> Group {
    let nf = tr.frames();
    let mut motions = motions;
    let mut refs: Vec<DVec3> = members.iter().map(|&i| tr.pos[0][i as usize]).collect();
    for _ in 0..3 {
        let inv: Vec<Rigid> = motions.iter().map(Rigid::inverse).collect();
        refs = members
            .par_iter()
            .map(|&i| {
                (0..nf)
                    .map(|f| inv[f].apply(tr.pos[f][i as usize]))
                    .sum::<DVec3>()
                    / nf as f64
            })
            .collect();
        motions = tr.fit_motions(&members, &refs);
    }
    let c = refs.iter().sum::<DVec3>() / refs.len().max(1) as f64;
    let local: Vec<DVec3> = refs.iter().map(|&r| r - c).collect();
    let poses: Vec<Rigid> = motions
        .iter()
        .map(|m| Rigid {
            rotation: m.rotation,
            translation: m.apply(c),
        })
        .collect();
    let (sq, max) = members
        .par_iter()
        .zip(&local)
        .map(|(&i, &l)| {
            (0..nf).fold((0.0f64, 0.0f64), |(s, m), f| {
                let e = (poses[f].apply(l) - tr.pos[f][i as usize]).length();
                (s + e * e, m.max(e))
            })
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1.max(b.1)));
    Group {
        rms: (sq / (members.len() * nf).max(1) as f64).sqrt(),
        max,
        members,
        poses,
        local,
    }
}

/// Rotation quaternions of a track flipped onto one hemisphere, frame to frame (the same
/// rotations; viewers that interpolate components linearly then take the short way).
fn continuous(poses: &[Rigid]) -> Vec<DQuat> {
    let mut out: Vec<DQuat> = Vec::with_capacity(poses.len());
    for p in poses {
        let q = match out.last() {
            Some(prev) if prev.dot(p.rotation) < 0.0 => -p.rotation,
            _ => p.rotation,
        };
        out.push(q);
    }
    out
}

impl Decomposition {
    /// The dynamic scene: static Gaussians (frame 0's values, means averaged over the frames),
    /// objects `object_K` (frame 0's values carried into the local frame) with a key per
    /// frame, and per-frame content (each frame's own values of the Gaussians no group took).
    /// `fps` is the scene's frame rate (the manifest's `time.fps`).
    pub fn to_scene(
        &self,
        frames: &[GaussianCloud],
        times: &[f64],
        fps: f64,
    ) -> Result<DynamicScene> {
        check(frames, times)?;
        let first = &frames[0];
        let nf = frames.len();
        let statics: Vec<usize> = (0..first.len())
            .filter(|&i| self.labels[i] == Label::Static)
            .collect();
        let static_means = statics
            .par_iter()
            .map(|&i| {
                (frames.iter().map(|c| c.means[i].as_dvec3()).sum::<DVec3>() / nf as f64).as_vec3()
            })
            .collect();
        let frame_content = if self.per_frame == 0 {
            Vec::new()
        } else {
            frames
                .iter()
                .zip(times)
                .map(|(c, &t)| FrameContent {
                    t,
                    gaussians: subset(c, |i| self.labels[i] == Label::PerFrame),
                })
                .collect()
        };
        self.scene_from(first, static_means, frame_content, times, fps)
    }

    /// The scene from frame 0, the static Gaussians' mean positions and the per-frame content.
    fn scene_from(
        &self,
        first: &GaussianCloud,
        static_means: Vec<Vec3>,
        frame_content: Vec<FrameContent>,
        times: &[f64],
        fps: f64,
    ) -> Result<DynamicScene> {
        let nf = times.len();
        let mut static_gaussians = subset(first, |i| self.labels[i] == Label::Static);
        static_gaussians.means = static_means;
        let mut objects = Vec::with_capacity(self.groups.len());
        for (k, g) in self.groups.iter().enumerate() {
            let mut cloud = subset(first, |i| self.labels[i] == Label::Group(k as u32));
            let back = g.poses[0].rotation.conjugate().as_quat();
            cloud.means = g.local.iter().map(|l| l.as_vec3()).collect();
            for q in &mut cloud.rotations {
                *q = back * splatbridge_scene::dynamic::normalize_or_identity(*q);
            }
            let shr = ShRotation::from_quat(back);
            let kc = cloud.coeffs();
            if cloud.sh_degree > 0 && !shr.identity {
                let degree = cloud.sh_degree;
                cloud.sh.chunks_mut(kc).for_each(|c| shr.apply(degree, c));
            }
            let keys = continuous(&g.poses)
                .into_iter()
                .zip(&g.poses)
                .zip(times)
                .map(|((q, p), &t)| PoseKey {
                    t,
                    pose: Pose::new(p.translation.as_vec3(), q.as_quat()),
                })
                .collect();
            objects.push(SceneObject {
                name: format!("object_{k}"),
                gaussians: cloud,
                track: Track::new(keys),
            });
        }
        let scene = DynamicScene {
            four_d: None,
            time: TimeRange {
                start: times[0],
                end: times[nf - 1],
                fps,
            },
            static_gaussians,
            objects,
            frames: frame_content,
            cameras: Vec::new(),
            effects: serde_json::Map::new(),
        };
        scene.validate()?;
        Ok(scene)
    }
}

/// The Gaussians of `c` with `keep(i)`, in order, without object ids.
pub fn subset(c: &GaussianCloud, keep: impl Fn(usize) -> bool) -> GaussianCloud {
    let idx: Vec<usize> = (0..c.len()).filter(|&i| keep(i)).collect();
    let k = c.coeffs();
    let mut out = GaussianCloud::with_capacity(c.sh_degree, idx.len());
    for &i in &idx {
        out.means.push(c.means[i]);
        out.log_scales.push(c.log_scales[i]);
        out.rotations.push(c.rotations[i]);
        out.opacity_logits.push(c.opacity_logits[i]);
        out.sh.extend_from_slice(&c.sh[i * k..(i + 1) * k]);
    }
    out
}

/// A pose as the scene stores it.
pub fn pose_of(r: &Rigid) -> Pose {
    Pose::new(r.translation.as_vec3(), r.rotation.as_quat())
}

/// Degrees between two rotations.
pub fn angle_deg(a: Quat, b: Quat) -> f64 {
    let d = a
        .as_dquat()
        .normalize()
        .dot(b.as_dquat().normalize())
        .abs()
        .min(1.0);
    (2.0 * d.acos()).to_degrees()
}

/// World position of a local point under a pose, for comparisons in tests and reports.
pub fn world(p: &Pose, local: Vec3) -> DVec3 {
    p.transform_point_f64(local.as_dvec3())
}
