//! What a distillation fits and how: the options and their validation.

use super::{DistillError, HitOrder, Loss, ParamMode, Result};

/// What to fit and how.
#[derive(Clone, Debug)]
pub struct DistillOptions {
    /// Scene time the views are fitted at (and the time [`Distiller::render`] traces).
    pub time: f64,
    /// Scene times for dynamic scenes, given to the views in turn (view i at
    /// `times[i % len]`); empty: every view at `time`.
    pub times: Vec<f64>,
    /// Adam steps (each over a batch of views).
    pub iterations: usize,
    /// Stop fitting once this many seconds have passed since the start (set-up included).
    pub max_seconds: Option<f64>,
    pub loss: Loss,
    /// Adam step sizes for the linear RGB and the alpha of a vertex.
    pub lr_colour: f32,
    pub lr_alpha: f32,
    /// The tracer's k-buffer size.
    pub k: usize,
    /// Bytes of hit lists kept between iterations; views beyond are re-traced each time
    /// (`--distill-memory`).
    pub hit_budget: u64,
    /// Hits are recorded until the transmittance falls below this.
    pub record_transmittance: f32,
    /// Per-vertex or per-Gaussian parameters ([`tied`]).
    pub params: ParamMode,
    /// The k-buffer size of hit recording: the order is the tracer's (hits sorted by the
    /// same keys), a larger buffer walks the BVH fewer times for a deep pixel (64 halved
    /// the set-up's wall time on `tile_lod1` against 16; docs/distill-time.md, "Where the time goes").
    pub record_k: usize,
    /// Views per Adam step: 0 for all of them (full batch), else that many in turn
    /// ([`Distiller::batch`]).
    pub batch: usize,
    /// Adam's ε in units of one pixel's loss: ε = eps_pixels / (W·H). A view's loss is a
    /// mean over its pixels, so a vertex's gradient is about (its pixel weight in a view) /
    /// (W·H) whatever the view count; 0.04 is the gradient of a vertex that sets one pixel
    /// with full weight in one view of 25. A vertex seen less than that takes steps smaller
    /// than the step size, so what the views barely constrain stays near the conversion
    /// instead of following noise at full step (Adam's usual 1e-8 lets it; on `fourth_st`
    /// held-back views peaked after 20 steps and then fell; docs/distill.md).
    pub eps_pixels: f32,
    /// Adam's ε, in the same units, after the guard first refuses a validation: the fit goes
    /// back to the best iteration the validation views accept, its moments start again, and
    /// it goes on with this ε ([`crate::guard`], "Backtracking"). Not larger than
    /// `eps_pixels`: never.
    pub eps_backtrack_pixels: f32,
    /// Make the fitted mesh from the Gaussians widened by native splatting's 0.3 px² low-pass
    /// at their depth in the fitting views ([`widen_for_fit`], `convert --footprint-for`'s
    /// widening sized by the fitting cameras), so the fans of Gaussians near or under a pixel
    /// cover what native splatting blurs them over. Applied by the callers that own the
    /// scene (`run::distill_export`, the accuracy sweep), which export the widened scene.
    pub footprint: bool,
    /// Which of the footprints of the views that see a Gaussian it is widened by, as a
    /// quantile of them: 0 the smallest (the most detailed view; no view blurred more than
    /// native blurs it), 1 the largest. One mesh serves every size, so a small view of a
    /// Gaussian under a pixel wants the widening a large view does not (docs/distill.md).
    pub footprint_quantile: f64,
    /// How far, in dB, a validation view may fall below its start before an iteration is
    /// refused ([`crate::guard`]): the default refuses any real loss; larger values trade
    /// the guarantee for the gains of the other views.
    pub guard_tolerance_db: f64,
    /// Check the kept result of a widened mesh against the export without distillation on
    /// the validation views, and write that export where the result is below it
    /// ([`crate::plain`]): what never lets distillation make a validation view worse than
    /// not distilling, at the cost of tracing the undistilled export from each validation
    /// view (4 s of 67 on `fourth_st`, docs/distill.md).
    pub floor: bool,
    /// Validations in a row ([`crate::guard::EVERY`] steps apart) without progress (no better
    /// admissible iteration, no refused one closer to admissible), after which the fit stops
    /// ([`crate::guard::PATIENCE`]). 0 runs every iteration.
    pub patience: usize,
    /// Highest SH degree of the native targets (3: all the scene has). Degree 0 makes the
    /// targets view-independent, so a fit to them measures what view-dependence costs a
    /// mesh (docs/distill.md, "Where the remaining error is").
    pub target_sh_degree: u8,
    /// Native splatting's near plane for every target and reference of the fit (fitting,
    /// validation and held-back views): Gaussians at view depth `z ≤ target_near` are
    /// dropped from them. The reference's 0.2 is in scene units; a mesh has no such cull
    /// (a viewer clips triangles at its camera's near plane, 0.01 in the cameras
    /// splatbridge writes), so where close views bring Gaussians within 0.2 of the camera
    /// the targets show holes the export cannot and should not have.
    pub target_near: f32,
    /// Highest SH degree of the fitting views' targets, when not `target_sh_degree`; the
    /// validation views and held-back references keep `target_sh_degree`.
    pub fit_sh_degree: Option<u8>,
    /// The order each pixel's hits are composited in, fitting and measuring alike: the
    /// tracer's (what viewers draw) or native splatting's, a measurement of what ray order
    /// costs ([`order`]).
    pub order: HitOrder,
    /// Fit vertex positions too ([`super::positions`]): every step re-traces its views with
    /// the moved mesh. Off by default; not for the texture profile.
    pub positions: bool,
    /// Adam's step for positions, in units of each Gaussian's size.
    pub lr_position: f32,
}

impl Default for DistillOptions {
    fn default() -> Self {
        DistillOptions {
            time: 0.0,
            times: Vec::new(),
            iterations: 60,
            max_seconds: None,
            loss: Loss::default(),
            lr_colour: 0.02,
            lr_alpha: 0.02,
            k: 16,
            // All 48 default views of a deep street capture (`fourth_st`: 113.7 M hits of 20
            // bytes, 2.29 GB) stay in memory: re-tracing the views beyond the budget took
            // half of each step (docs/distill-time.md).
            hit_budget: 3_000_000_000,
            // Native splatting stops blending a pixel where its transmittance falls below
            // 1e-4: hits behind that are not in the image the fit matches. Recording down to
            // 1e-6 kept 16–29 % more hits and took 22–47 % longer on `fourth_st` and `plant`
            // for a fit within 0.06 dB (docs/distill-time.md, "Recording depth").
            record_transmittance: 1e-4,
            params: ParamMode::Vertex,
            record_k: 64,
            batch: 16,
            eps_pixels: 0.04,
            // Measured on `fourth_st` (texture profile, `sphere:48`, the guard's eight views):
            // from the start at ε 0.4 a validation view still lost 0.02–0.12 dB at every
            // validation, at 4 it lost 0.04 after 10 steps and recovered, at 10 every
            // validation from step 20 on was admissible and the mean still rose at step 60
            // (+0.40 dB), at 40 the fit barely moved (+0.20 at step 60, one view at −0.0012).
            // docs/distill.md, "Backtracking".
            eps_backtrack_pixels: 10.0,
            footprint: true,
            // The smallest footprint, so no view is blurred more than native blurs it. The
            // median (0.5) gains more on `pc_short` (18 held-back views, 320×240 to 1080p:
            // worst +0.89 → +1.39 dB, median +5.24 → +6.11) but its widened start is below the
            // plain export at `fourth_st`'s 640×480 views by up to 0.45 dB, which the goal of
            // never ending below it forbids (docs/distill.md, "One mesh for every size").
            footprint_quantile: 0.0,
            guard_tolerance_db: crate::guard::TOLERANCE_DB,
            floor: true,
            patience: crate::guard::PATIENCE,
            target_sh_degree: 3,
            target_near: splatbridge_hybrid::native::NEAR_REFERENCE,
            fit_sh_degree: None,
            order: HitOrder::Ray,
            positions: false,
            lr_position: 0.01,
        }
    }
}

/// `near` where it is not the reference's near plane: what a fit's note and report say.
pub fn near_unless_reference(near: f32) -> Option<f32> {
    (near != splatbridge_hybrid::native::NEAR_REFERENCE).then_some(near)
}

impl DistillOptions {
    /// The scene time of each of `n` views: `times` in turn, or `time`.
    pub fn view_times(&self, n: usize) -> Vec<f64> {
        if self.times.is_empty() {
            vec![self.time; n]
        } else {
            (0..n).map(|i| self.times[i % self.times.len()]).collect()
        }
    }

    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(DistillError::Invalid(m));
        // (option, value, whether 0 is allowed): each a finite number, above 0 or at least 0.
        let numbers = [
            ("--distill-colour-step", self.lr_colour as f64, false),
            ("--distill-alpha-step", self.lr_alpha as f64, true),
            // No budget is a budget of 0: always valid.
            ("--distill-time", self.max_seconds.unwrap_or(0.0), true),
            ("--distill-position-step", self.lr_position as f64, true),
            (
                "--distill-eps-backtrack",
                self.eps_backtrack_pixels as f64,
                true,
            ),
            ("--distill-eps", self.eps_pixels as f64, true),
        ];
        for (name, x, zero) in numbers {
            let ok = x.is_finite() && (x > 0.0 || (zero && x == 0.0));
            if !ok {
                let bound = if zero { "≥ 0" } else { "> 0" };
                return bad(format!("{name} {x} must be a finite number {bound}"));
            }
        }
        if self.times.iter().any(|t| !t.is_finite()) {
            return bad("distillation times must be finite".into());
        }
        if !(1..=1024).contains(&self.k) {
            return bad(format!("k-buffer size {} is outside 1..=1024", self.k));
        }
        if !(1..=1024).contains(&self.record_k) {
            return bad(format!(
                "--distill-record-k {} is outside 1..=1024",
                self.record_k
            ));
        }
        if !(self.target_near > 0.0 && self.target_near.is_finite()) {
            return bad(format!(
                "--distill-near {} must be positive and finite",
                self.target_near
            ));
        }
        if !(self.record_transmittance > 0.0 && self.record_transmittance < 1.0) {
            return bad("record transmittance must be in (0, 1)".into());
        }
        if let Loss::L1Ssim(l) = self.loss {
            if !(0.0..=1.0).contains(&l) {
                return bad(format!("SSIM weight {l} is outside [0, 1]"));
            }
        }
        Ok(())
    }
}
