//! The undistilled export as the floor of what distillation writes.
//!
//! Distillation changes two things: the mesh, made from Gaussians widened by the fitting
//! views' low-pass ([`crate::widen_for_fit`]), and its colours (the fit). The guard
//! ([`crate::guard`]) judges the fit's iterations against the widened start; this module
//! judges what the guard kept against the export `convert` writes without `--distill`, on
//! the same validation views and by the same measure: each view as the tracer draws the
//! file (what its recorded hits composite to, bit for bit) and its PSNR against native,
//! capped at [`crate::guard::CAP_DB`]. Where the kept result is below the undistilled
//! export at a validation view by more than the guard's tolerance, the undistilled export
//! is written instead, so a distilled export is never below the plain one at a validation
//! view. The widening alone can be: it sizes each Gaussian for the most detailed fitting
//! view that sees it, and a close-up between the fitting views sees it larger still
//! (`docs/distill.md`, "The undistilled export as the floor").

use rayon::prelude::*;
use splatbridge_convert::ConvertOptions;
use splatbridge_raytrace::{BackendKind, BuildPreset, MeshTracer, RenderOptions};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::{Camera, Frame};

use crate::mesh::export_mesh;
use crate::targets::psnr_views;
use crate::{guard, DistillOptions, Distiller, Result};

/// The export of a scene without distillation, traced as the fit's views are.
pub struct Undistilled {
    tracer: MeshTracer,
    k: usize,
}

impl Undistilled {
    /// The export `convert` makes of `scene` (not widened, its own colours), traced with the
    /// fit's k-buffer (`opts.k`), as [`Distiller::render_at`] traces the fitted mesh.
    pub fn new(
        scene: &DynamicScene,
        convert: &ConvertOptions,
        opts: &DistillOptions,
    ) -> Result<Self> {
        let tri = export_mesh(scene, convert)?;
        Ok(Undistilled {
            tracer: MeshTracer::new(tri, BackendKind::default(), BuildPreset::default())?,
            k: opts.k,
        })
    }

    /// PSNR against native of the export traced from each of `cameras` (at `times`, against
    /// `targets`), a view at a time per thread.
    pub fn psnr_each(
        &self,
        cameras: &[Camera],
        times: &[f64],
        targets: &[Frame],
    ) -> Result<Vec<f64>> {
        psnr_views(cameras, times, targets, |c, time| self.render_at(c, time))
    }

    /// The export traced from `cam` at scene time `time`.
    pub fn render_at(&self, cam: &Camera, time: f64) -> Result<Frame> {
        let opts = RenderOptions {
            k: self.k,
            ..RenderOptions::default()
        };
        Ok(self.tracer.render(cam, time, &opts)?.0)
    }
}

/// What the kept fit scored against the undistilled export on the validation views.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FloorCheck {
    /// Each validation view's PSNR for the undistilled export, dB (capped as the guard's).
    pub undistilled: Vec<f64>,
    /// Each validation view's PSNR for the kept fit less the undistilled export's, dB.
    pub change: Vec<f64>,
    /// Whether the undistilled export is written instead of the fit's: some view's change
    /// is below minus the guard's tolerance.
    pub kept_undistilled: bool,
}

impl FloorCheck {
    /// The kept fit's validation PSNRs `kept` against the undistilled export's
    /// `undistilled` (the same views, in order), with the guard's tolerance in dB.
    pub fn new(kept: &[f64], undistilled: Vec<f64>, tolerance_db: f64) -> Self {
        let change: Vec<f64> = kept.iter().zip(&undistilled).map(|(k, p)| k - p).collect();
        FloorCheck {
            kept_undistilled: change.iter().any(|&c| c < -tolerance_db.max(0.0)),
            undistilled,
            change,
        }
    }

    /// The view of the largest loss (the first of equals) and its change; None without
    /// views.
    pub fn worst(&self) -> Option<(usize, f64)> {
        self.change
            .iter()
            .copied()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }
}

impl Distiller {
    /// Each validation view's PSNR for `undistilled`'s images, measured as
    /// [`Distiller::validation_psnr`] measures the fit's.
    pub fn validation_psnr_of(&self, undistilled: &Undistilled) -> Result<Vec<f64>> {
        // A view at a time per thread, as the fit records its views: a 240×180 window's
        // tiles do not keep two cores busy.
        self.guard
            .views()
            .par_iter()
            .map(|v| {
                let img = undistilled.render_at(&v.camera, v.time)?;
                Ok(guard::capped_psnr(&img.rgb, &v.target))
            })
            .collect()
    }

    /// The kept colours against the undistilled export's validation PSNRs `undistilled`
    /// ([`Distiller::validation_psnr_of`]).
    pub fn check_floor(&self, undistilled: Vec<f64>) -> FloorCheck {
        FloorCheck::new(
            &self.validation_psnr(),
            undistilled,
            self.opts.guard_tolerance_db,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rule: the undistilled export is written exactly when some view's change is below
    /// minus the tolerance (a loss of the tolerance itself is kept, as the guard keeps it),
    /// and a negative tolerance counts as 0.
    #[test]
    fn the_undistilled_export_is_kept_below_the_tolerance_only() {
        let und = vec![30.0, 20.0, 25.0];
        let check = |kept: [f64; 3], tol: f64| FloorCheck::new(&kept, und.clone(), tol);
        // Binary fractions, so the differences are exact.
        let at = check([30.5, 19.75, 25.0], 0.25);
        assert!(!at.kept_undistilled, "{at:?}");
        assert_eq!(at.worst().map(|w| w.0), Some(1));
        let below = check([30.5, 19.5, 25.0], 0.25);
        assert!(below.kept_undistilled, "{below:?}");
        assert!(!check([30.0, 20.0, 25.0], -1.0).kept_undistilled);
        assert!(check([30.0, 20.0, 24.999_999], -1.0).kept_undistilled);
        let c = check([31.0, 21.0, 26.0], 0.0);
        assert_eq!(c.change, vec![1.0, 1.0, 1.0]);
        assert_eq!(c.undistilled, und);
        assert_eq!(FloorCheck::new(&[], Vec::new(), 0.0).worst(), None);
    }
}
