//! The fit's safeguard: validation views that are never fitted pick the iteration kept.
//!
//! A fit to some views can make others worse (an export fitted on one orbit lost up to 5 dB
//! off it). Validation views are drawn from the fitting distribution but never fitted; every
//! [`EVERY`] steps, and at the end, each is composited from its recorded hits with the
//! current colours (quantised as the file stores them) and its PSNR against native is taken.
//! An iteration is admissible when no validation view is below its PSNR at the start (the
//! mesh as converted) by more than a tolerance (`--distill-guard-tolerance`, 1e-3 dB); the
//! admissible iteration with the best mean is kept, the start itself when none is. Fitted
//! positions change the hits every step, so they are not validated.
//!
//! Backtracking: the first refused validation sends the fit back to the best admissible
//! iteration (its parameters; Adam's moments start again) and the fit goes on with a larger
//! ε ([`DistillOptions::eps_backtrack_pixels`](crate::DistillOptions), 10 pixels' loss
//! against 0.04). Adam moves every parameter whose gradient is above ε by about the full
//! step whatever the gradient's size, and those below it in proportion to the gradient: a
//! larger ε makes the fit move only what many pixels of the batch agree on at full speed.
//! The fit whose every validation passes is unchanged (bit for bit); one that makes some
//! view worse, as a fit from a few dozen windows does to the views between them where
//! colours depend on the direction, starts again with the damping that view needs, instead
//! of keeping the start.

use rayon::prelude::*;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::Camera;

use super::{composite, mesh::quantise, targets, Distiller, Result, View};

/// Validation PSNRs are capped here, in dB: above it a view is as good as identical on an
/// 8-bit display (one quantisation step's RMS is 59 dB), and a window of empty background
/// (hundreds of dB) would otherwise outweigh every other view in the mean and refuse every
/// step for a change no one can see.
pub const CAP_DB: f64 = 60.0;

/// Steps between validations.
pub const EVERY: usize = 10;

/// A view may fall this far below its start before the iteration is refused, in dB: the
/// PSNR of a 240×180 window moves by about 1e-4 dB from colour quantisation alone, so
/// anything above that is a real loss.
pub const TOLERANCE_DB: f64 = 1e-3;

/// Validations in a row without progress before the fit stops
/// ([`DistillOptions::patience`](crate::DistillOptions)): two, 20 steps. A validation makes
/// progress when it finds a better admissible iteration, or when it is refused with a worst
/// view closer to its start than every refused validation before it (a fit whose first steps
/// overshoot and recover keeps going). Measured at the defaults on the five shared scenes
/// (docs/distill-time.md, "Stopping early"): the same iteration kept by all five, `fourth_st` and
/// `donut` stopped after 40 and 30 of 60 steps.
pub const PATIENCE: usize = 2;

/// A validation view's PSNR of `img` against `target` (interleaved RGB, each clamped to
/// [0, 1]), capped at [`CAP_DB`].
pub(crate) fn capped_psnr(img: &[f32], target: &[f32]) -> f64 {
    let n = img.len().max(1) as f64;
    let mse: f64 = img
        .iter()
        .zip(target)
        .map(|(&a, &b)| {
            let d = (a.clamp(0.0, 1.0) - b.clamp(0.0, 1.0)) as f64;
            d * d
        })
        .sum::<f64>()
        / n;
    (-10.0 * mse.max(1e-20).log10()).min(CAP_DB)
}

/// The parameters of an admissible iteration.
struct Snapshot {
    iteration: usize,
    mean: f64,
    params: Vec<[f32; 4]>,
    /// The per-Gaussian parameters, when the fit moves those.
    theta: Option<Vec<[f32; 4]>>,
}

/// Validation views and what they have seen.
#[derive(Default)]
pub struct Guard {
    views: Vec<View>,
    /// PSNR of each view at the start.
    start: Vec<f64>,
    /// The best admissible iteration.
    best: Option<Snapshot>,
    /// The iteration last validated.
    last: Option<usize>,
    /// Validations since the last that made progress ([`PATIENCE`]).
    since_progress: usize,
    /// The largest worst change of a refused validation so far.
    closest_refused: Option<f64>,
    /// Every validation, in order.
    pub log: Vec<Validation>,
}

/// One validation of the fit.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Validation {
    pub iteration: usize,
    /// Mean PSNR over the validation views, dB (each capped at [`CAP_DB`]).
    pub mean: f64,
    /// Each view's PSNR, dB (capped).
    pub psnr: Vec<f64>,
    /// Each view's change from the start, dB.
    pub change: Vec<f64>,
    /// Whether no view is below its start by more than the fit's tolerance
    /// ([`DistillOptions::guard_tolerance_db`](crate::DistillOptions), default [`TOLERANCE_DB`]).
    pub admissible: bool,
}

impl Guard {
    /// The validation views.
    pub(crate) fn views(&self) -> &[View] {
        &self.views
    }
}

impl Validation {
    /// The largest loss from the start (negative), or the smallest gain.
    pub fn worst(&self) -> f64 {
        self.worst_view().1
    }

    /// The view of [`Validation::worst`] (the first of equals) and its change; `(0, ∞)`
    /// without views.
    pub fn worst_view(&self) -> (usize, f64) {
        self.change.iter().enumerate().fold(
            (0, f64::INFINITY),
            |m, (i, &c)| if c < m.1 { (i, c) } else { m },
        )
    }
}

impl Distiller {
    /// Add validation views (targets rendered from `scene`, view i at `times[i]`), before the
    /// fit runs. No-op when positions are fitted.
    pub fn add_validation(
        &mut self,
        scene: &DynamicScene,
        cameras: &[Camera],
        times: &[f64],
    ) -> Result<()> {
        if self.opts.positions || cameras.is_empty() {
            return Ok(());
        }
        let native = targets::native_options(self.opts.target_sh_degree, self.opts.target_near);
        let mut r = splatbridge_hybrid::native::Renderer::new();
        let mut frames = Vec::with_capacity(cameras.len());
        for (cam, &t) in cameras.iter().zip(times) {
            let cloud = scene.composite(t);
            frames.push(targets::render_native(&mut r, &cloud, cam, &native)?.rgb);
        }
        // Every validation view is kept: recorded side by side, as the fitting views are.
        let this = &*self;
        let hits: Vec<Result<composite::ViewHits>> = cameras
            .par_iter()
            .zip(times)
            .map(|(cam, &t)| this.record(cam, t))
            .collect();
        for (((cam, &t), target), hits) in cameras.iter().zip(times).zip(frames).zip(hits) {
            self.guard.views.push(View {
                camera: cam.clone(),
                time: t,
                target,
                hits: Some(hits?),
            });
        }
        self.report.validation_views = self.guard.views.len();
        Ok(())
    }

    /// PSNR of every validation view with the current colours.
    pub fn validation_psnr(&self) -> Vec<f64> {
        let q: Vec<[f32; 4]> = self.params.iter().map(|&p| quantise(p)).collect();
        self.guard
            .views
            .iter()
            .filter_map(|v| {
                let hits = v.hits.as_ref()?;
                Some(capped_psnr(
                    &composite::render(hits, &q, &self.shading),
                    &v.target,
                ))
            })
            .collect()
    }

    /// Measure the validation views now; remember this iteration when it is admissible and
    /// the best so far.
    pub fn validate(&mut self) -> Result<()> {
        let it = self.history.len();
        if self.guard.views.is_empty() || self.guard.last == Some(it) {
            return Ok(());
        }
        self.guard.last = Some(it);
        let now = self.validation_psnr();
        if self.guard.start.is_empty() {
            self.guard.start = now.clone();
        }
        let mean = now.iter().sum::<f64>() / now.len().max(1) as f64;
        let change: Vec<f64> = now
            .iter()
            .zip(&self.guard.start)
            .map(|(a, b)| a - b)
            .collect();
        let mut v = Validation {
            iteration: it,
            mean,
            psnr: now.clone(),
            change,
            admissible: false,
        };
        v.admissible = v.worst() >= -self.opts.guard_tolerance_db.max(0.0);
        let (admissible, worst) = (v.admissible, v.worst());
        self.guard.log.push(v);
        if it == 0 {
            self.report.validation_start = mean;
        }
        let better = self.guard.best.as_ref().is_none_or(|b| mean > b.mean);
        let closer = !admissible && self.guard.closest_refused.is_none_or(|c| worst > c);
        if closer {
            self.guard.closest_refused = Some(worst);
        }
        self.guard.since_progress = if (admissible && better) || closer {
            0
        } else {
            self.guard.since_progress + 1
        };
        if admissible && better {
            self.guard.best = Some(Snapshot {
                iteration: it,
                mean,
                params: self.params.clone(),
                theta: self.tied.as_ref().map(|t| t.theta.clone()),
            });
        }
        Ok(())
    }

    /// Whether the last [`DistillOptions::patience`](crate::DistillOptions) validations made
    /// no progress ([`PATIENCE`] says what counts); never with a patience of 0 or without
    /// validation views.
    pub fn patience_spent(&self) -> bool {
        let p = self.opts.patience;
        p > 0 && !self.guard.views.is_empty() && self.guard.since_progress >= p
    }

    /// The validation after every [`EVERY`]-th step: measure, backtrack where the
    /// validation calls for it; true when the patience is spent (the fit should stop).
    pub fn validate_step(&mut self) -> Result<bool> {
        self.validate()?;
        if self.backtrack_due() {
            self.backtrack();
            return Ok(false);
        }
        Ok(self.patience_spent())
    }

    /// Whether the last validation calls for a backtrack: it was refused, the fit has not
    /// backtracked yet, and the backtrack's ε is larger than the fit's (see the module
    /// documentation, "Backtracking").
    pub fn backtrack_due(&self) -> bool {
        let refused = self.guard.log.last().is_some_and(|v| !v.admissible);
        refused
            && self.report.backtracked.is_none()
            && self.guard.best.is_some()
            && self.opts.eps_backtrack_pixels > self.opts.eps_pixels
            && self.positions.is_none()
    }

    /// Go back to the best admissible iteration's parameters, start Adam's moments again
    /// and go on with [`DistillOptions::eps_backtrack_pixels`](crate::DistillOptions). A
    /// backtrack is progress for the patience: the fit after it is another fit.
    pub fn backtrack(&mut self) {
        let Some(best) = &self.guard.best else {
            return;
        };
        self.params.clone_from(&best.params);
        if let (Some(t), Some(theta)) = (self.tied.as_mut(), &best.theta) {
            t.theta.clone_from(theta);
        }
        self.m.iter_mut().for_each(|m| *m = [0.0; 4]);
        self.v.iter_mut().for_each(|v| *v = [0.0; 4]);
        // From this step on Adam counts its steps afresh and takes the backtrack's ε
        // (`Distiller::eps`).
        self.report.backtracked = Some((self.history.len(), best.iteration));
        self.guard.since_progress = 0;
        self.guard.closest_refused = None;
    }

    /// Go back to the best admissible iteration (no-op without validation views).
    pub fn keep_best(&mut self) {
        let Some(best) = self.guard.best.take() else {
            return;
        };
        self.params = best.params;
        if let (Some(t), Some(theta)) = (self.tied.as_mut(), best.theta) {
            t.theta = theta;
        }
        self.report.kept_iteration = best.iteration;
        self.report.validation_kept = best.mean;
    }

    /// Every validation so far.
    pub fn validation_log(&self) -> &[Validation] {
        &self.guard.log
    }

    /// The refused validation of the highest mean, when it is above the kept one's: what a
    /// tolerance of its largest loss (`-worst()`) would have kept instead.
    pub fn best_refused(&self) -> Option<&Validation> {
        let log = &self.guard.log;
        let kept = log
            .iter()
            .filter(|v| v.admissible)
            .map(|v| v.mean)
            .fold(f64::NEG_INFINITY, f64::max);
        log.iter()
            .filter(|v| !v.admissible && v.mean > kept)
            .max_by(|a, b| a.mean.total_cmp(&b.mean))
    }
}
