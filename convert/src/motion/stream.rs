//! The decomposition of [`super::decompose`] reading the frames one at a time, for sequences
//! too long to hold: what is kept is per-Gaussian running sums (O(N)), the trajectories of the
//! Gaussians that move (O(moving × frames)), and frame 0.
//!
//! Passes over the [`FrameSource`]:
//! 1. every frame: checks, the running sums (positions, squared distance from frame 0), whether
//!    opacity or scales change, and the second differences of the noise sample (three frames of
//!    it at a time);
//! 2. every frame: the moving Gaussians' positions, which the search and the refinement of
//!    [`super::decompose`] then run on unchanged (indices mapped back);
//! 3. ([`StreamedDecomposition::to_scene`]) every frame again for the per-frame content.
//!
//! Every sum runs in the same order as in [`super::decompose`] (frame by frame), and the
//! moving Gaussians keep their order, so the labels, groups and poses are the same; the tests
//! check this against the in-memory decomposition.

use std::borrow::Cow;

use glam::DVec3;
use rayon::prelude::*;
use splatbridge_scene::dynamic::{DynamicScene, FrameContent};
use splatbridge_scene::GaussianCloud;

use super::cluster::{self, Search, Trajectories};
use super::{refine, subset, DecomposeOptions, Decomposition, Label, APPEARANCE_TOLERANCE};
use crate::{ConvertError, Result};

/// Frames read one at a time (and read again by later passes).
pub trait FrameSource: Sync {
    /// Number of frames.
    fn len(&self) -> usize;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Frame `f`.
    fn frame(&self, f: usize) -> Result<Cow<'_, GaussianCloud>>;
}

impl FrameSource for [GaussianCloud] {
    fn len(&self) -> usize {
        <[GaussianCloud]>::len(self)
    }
    fn frame(&self, f: usize) -> Result<Cow<'_, GaussianCloud>> {
        Ok(Cow::Borrowed(&self[f]))
    }
}

/// A decomposition made from streamed frames, with what building its scene needs besides a
/// last pass over the frames.
pub struct StreamedDecomposition {
    pub decomposition: Decomposition,
    /// Frame 0 (objects and static Gaussians take its values).
    pub first: GaussianCloud,
    /// Per Gaussian, the sum of its positions over the frames (static means).
    sum: Vec<DVec3>,
}

/// Frame `f` has frame 0's `n` Gaussians, a consistent shape and finite means (the checks
/// both the in-memory and the streamed decomposition make).
pub(super) fn check_frame(c: &GaussianCloud, f: usize, n: usize) -> Result<()> {
    if c.len() != n {
        return Err(ConvertError::Invalid(format!(
            "frame {f} has {} Gaussians, frame 0 has {n}: decomposition needs the same \
             Gaussians in every frame",
            c.len()
        )));
    }
    c.check_shape()
        .map_err(|e| ConvertError::Invalid(format!("frame {f}: {e}")))?;
    if let Some(i) = c.means.iter().position(|m| !m.is_finite()) {
        return Err(ConvertError::Invalid(format!(
            "frame {f}: Gaussian {i} has a non-finite mean"
        )));
    }
    Ok(())
}

/// [`super::decompose`] over frames read one at a time.
pub fn decompose_streamed(
    src: &(impl FrameSource + ?Sized),
    times: &[f64],
    opts: &DecomposeOptions,
) -> Result<StreamedDecomposition> {
    let nf = src.len();
    if nf == 0 {
        return Err(ConvertError::Invalid("no frames to decompose".into()));
    }
    if nf != times.len() {
        return Err(ConvertError::Invalid(format!(
            "{nf} frames but {} times",
            times.len()
        )));
    }
    if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| !(w[1] > w[0])) {
        return Err(ConvertError::Invalid(
            "frame times must be finite and strictly increasing".into(),
        ));
    }
    // Pass 1.
    let first = src.frame(0)?.into_owned();
    let n = first.len();
    check_frame(&first, 0, n)?;
    let p0: Vec<DVec3> = first.means.iter().map(|m| m.as_dvec3()).collect();
    let mut sum = vec![DVec3::ZERO; n];
    let mut sq = vec![0f64; n];
    let mut changes = vec![false; n];
    // The noise sample of `estimate_noise`: every `step`-th Gaussian, its last two positions.
    let step = n.div_ceil(20_000).max(1);
    let sample: Vec<usize> = (0..n).step_by(step).collect();
    let mut prev: Vec<[DVec3; 2]> = Vec::new();
    let mut second = vec![0f64; sample.len()];
    for f in 0..nf {
        let c = src.frame(f)?;
        check_frame(&c, f, n)?;
        sum.par_iter_mut()
            .zip(sq.par_iter_mut())
            .zip(changes.par_iter_mut())
            .enumerate()
            .for_each(|(i, ((s, q), ch))| {
                let p = c.means[i].as_dvec3();
                *s += p;
                *q += (p - p0[i]).length_squared();
                if f > 0 && !*ch {
                    *ch = (c.opacity(i) - first.opacity(i)).abs() > APPEARANCE_TOLERANCE
                        || (c.log_scales[i] - first.log_scales[i]).abs().max_element()
                            > APPEARANCE_TOLERANCE;
                }
            });
        let now: Vec<DVec3> = sample.iter().map(|&i| c.means[i].as_dvec3()).collect();
        if f >= 2 {
            for (k, s) in second.iter_mut().enumerate() {
                *s += (now[k] - 2.0 * prev[k][1] + prev[k][0]).length_squared();
            }
        }
        prev = if f == 0 {
            now.iter().map(|&p| [p, p]).collect()
        } else {
            prev.iter().zip(&now).map(|(pp, &p)| [pp[1], p]).collect()
        };
    }
    let noise = if nf < 3 || n == 0 {
        0.0
    } else {
        let mut v: Vec<f64> = second
            .iter()
            .map(|s| (s / (nf - 2) as f64).sqrt())
            .collect();
        let mid = v.len() / 2;
        v.select_nth_unstable_by(mid, f64::total_cmp);
        v[mid] / 18f64.sqrt()
    };
    let diag = first
        .bounds()
        .map(|(lo, hi)| (hi - lo).as_dvec3().length())
        .unwrap_or(0.0);
    let tolerance = opts
        .tolerance
        .unwrap_or_else(|| (10.0 * noise).max(1e-5 * diag).max(f64::MIN_POSITIVE));
    let tol2 = tolerance * tolerance;
    let mut labels: Vec<Label> = (0..n)
        .map(|i| {
            if !changes[i] && sq[i] <= tol2 * nf as f64 {
                Label::Static
            } else {
                Label::PerFrame
            }
        })
        .collect();
    // Pass 2 and the search.
    let mut groups = Vec::new();
    if opts.objects {
        let moving: Vec<u32> = (0..n as u32)
            .filter(|&i| labels[i as usize] == Label::PerFrame && !changes[i as usize])
            .collect();
        let mut pos = Vec::with_capacity(nf);
        for f in 0..nf {
            let c = src.frame(f)?;
            check_frame(&c, f, n)?;
            pos.push(
                moving
                    .iter()
                    .map(|&i| c.means[i as usize].as_dvec3())
                    .collect::<Vec<_>>(),
            );
        }
        let tr = Trajectories { pos };
        let local: Vec<u32> = (0..moving.len() as u32).collect();
        let search = Search {
            tolerance,
            min_group: opts.min_group,
            max_groups: opts.max_groups,
            hypotheses: opts.hypotheses.max(1),
            seed: opts.seed,
        };
        let (found, _rest) = cluster::find_groups(&tr, &local, &search);
        for (k, mut g) in found.into_iter().enumerate() {
            g.members.sort_unstable();
            let mut group = refine(&tr, g.members, g.motions);
            for m in &mut group.members {
                *m = moving[*m as usize];
                labels[*m as usize] = Label::Group(k as u32);
            }
            groups.push(group);
        }
    }
    let statics: Vec<usize> = (0..n).filter(|&i| labels[i] == Label::Static).collect();
    // Σ|p − mean|² = Σ|p − p0|² − nf·|mean − p0|² (distances from frame 0 are small for a
    // static Gaussian, so the difference loses no precision that matters for a report).
    let static_sq: f64 = statics
        .iter()
        .map(|&i| {
            let mean = sum[i] / nf as f64;
            (sq[i] - nf as f64 * (mean - p0[i]).length_squared()).max(0.0)
        })
        .sum();
    let per_frame_idx: Vec<usize> = (0..n).filter(|&i| labels[i] == Label::PerFrame).collect();
    let per_frame_sq: f64 = per_frame_idx.iter().map(|&i| sq[i]).sum();
    Ok(StreamedDecomposition {
        decomposition: Decomposition {
            static_count: statics.len(),
            static_rms: (static_sq / (statics.len() * nf).max(1) as f64).sqrt(),
            per_frame: per_frame_idx.len(),
            per_frame_appearance: per_frame_idx.iter().filter(|&&i| changes[i]).count(),
            per_frame_motion_rms: (per_frame_sq / (per_frame_idx.len() * nf).max(1) as f64).sqrt(),
            labels,
            groups,
            noise,
            tolerance,
        },
        first,
        sum,
    })
}

impl StreamedDecomposition {
    /// The scene of [`Decomposition::to_scene`], reading the frames once more for the per-frame
    /// content. `visit(f, frame)` sees every frame as it is read (the report measures the
    /// groups' fits on a few of them).
    pub fn to_scene(
        &self,
        src: &(impl FrameSource + ?Sized),
        times: &[f64],
        fps: f64,
        mut visit: impl FnMut(usize, &GaussianCloud),
    ) -> Result<DynamicScene> {
        let d = &self.decomposition;
        let nf = src.len();
        let n = self.first.len();
        let static_means = (0..n)
            .filter(|&i| d.labels[i] == Label::Static)
            .map(|i| (self.sum[i] / nf as f64).as_vec3())
            .collect();
        let mut content = Vec::new();
        for (f, &t) in times.iter().enumerate().take(nf) {
            let c = src.frame(f)?;
            check_frame(&c, f, n)?;
            visit(f, &c);
            if d.per_frame > 0 {
                content.push(FrameContent {
                    t,
                    gaussians: subset(&c, |i| d.labels[i] == Label::PerFrame),
                });
            }
        }
        d.scene_from(&self.first, static_means, content, times, fps)
    }
}
