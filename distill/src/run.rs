//! Distillation for an export: resolve the views, fit, measure on held-back views, and hand
//! the fitted colours to the convert options (what `convert --distill` runs).

use std::sync::Arc;

use splatbridge_convert::ConvertOptions;
use splatbridge_scene::camera_spec::{
    parse_camera_list, CameraListItem, CameraRequest, CameraSource, CameraSpec,
};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::Camera;

use super::plain::{FloorCheck, Undistilled};
use super::{native_targets_sh, views, DistillOptions, DistillReport, Distiller, Result};

/// `n` times evenly over the scene's time range, start and end included (the start alone
/// for a static scene or `n` ≤ 1).
pub fn fitting_times(scene: &DynamicScene, n: usize) -> Vec<f64> {
    let (a, b) = (scene.time.start, scene.time.end);
    if !scene.is_dynamic() || n <= 1 || !(b > a) {
        return vec![a];
    }
    (0..n)
        .map(|i| a + (b - a) * i as f64 / (n - 1) as f64)
        .collect()
}

/// Which views to fit and at what size.
#[derive(Clone, Debug)]
pub struct ViewRequest {
    /// `auto` (the scene's own cameras, else `cameras` below, else `sphere:48`),
    /// `sphere:N` (N views over the view sphere, [`views::sphere`]), or a camera list:
    /// `orbit:N`, `scene`, `PATH.json`, single specs, comma-separated.
    pub spec: String,
    /// The fitting window: views larger than this are fitted through windows of this size
    /// ([`views::window_of`]).
    pub width: u32,
    pub height: u32,
    /// The sizes the export is made for (`--distill-for`, or the `--camera` views'); empty:
    /// [`views::DEFAULT_SIZES`], 320×240 to 1080p. Camera lists are resized to the first.
    pub sizes: Vec<(u32, u32)>,
    /// Cameras found beside the input (a 3DGS `cameras.json`), used by `auto` when the scene
    /// has none of its own.
    pub cameras: Vec<Camera>,
    /// Held-back views to measure before and after: one per class of
    /// [`views::HELD_BACK_CLASSES`] in turn (between the cameras for a single `orbit:N`).
    pub held_back: usize,
    /// Held-back image size; default 320×240 (the orbit's fitting size for `orbit:N`).
    pub held_size: Option<(u32, u32)>,
    /// Fitting views at the fine end of the distribution (its nearest distance and largest
    /// size, [`views::sphere_with_fine`]), after the `sphere:N` ones; only with `sphere:N`.
    pub fit_fine: usize,
    /// Validation views ([`super::guard`]), from the fitting distribution, never fitted.
    pub validation: usize,
    /// Validation views at the fine end of the fitting distribution (its nearest distance
    /// and largest size, [`views::fine_end_range`]), after the `validation` ones; only with
    /// `sphere:N` fitting views (user and scene cameras are the range themselves).
    pub validation_fine: usize,
    /// Scene times a dynamic scene is fitted at (evenly over its time range, start and end
    /// included), given to the views in turn; static scenes use their start.
    pub times: usize,
}

impl Default for ViewRequest {
    fn default() -> Self {
        ViewRequest {
            spec: "auto".into(),
            width: views::WINDOW.0,
            height: views::WINDOW.1,
            sizes: Vec::new(),
            cameras: Vec::new(),
            held_back: views::HELD_BACK_CLASSES.len(),
            held_size: None,
            fit_fine: DEFAULT_FIT_FINE,
            validation: 8,
            validation_fine: DEFAULT_VALIDATION_FINE,
            times: 4,
        }
    }
}

/// Fine-end fitting views by default ([`ViewRequest::fit_fine`]), beside the 48 of
/// `sphere:48`: measured on the shared scenes in `docs/distill-fine-end.md` ("Fitting the fine
/// end").
pub const DEFAULT_FIT_FINE: usize = 8;

/// Fine-end validation views by default ([`ViewRequest::validation_fine`]).
pub const DEFAULT_VALIDATION_FINE: usize = 2;

/// The views of a distillation.
#[derive(Clone, Debug, Default)]
pub struct ResolvedViews {
    /// What is fitted and the whole views they are windows of.
    pub fit: views::Windows,
    /// Validation windows ([`super::guard`]).
    pub validation: Vec<Camera>,
    /// Held-back views, with their class.
    pub held: Vec<views::HeldBack>,
    /// What `auto` chose, for the report, with the fine-end fitting views when there are
    /// any ("sphere:48 + 8 fine-end").
    pub spec: String,
}

/// The fitting, validation and held-back views of `req`.
pub fn resolve_views(scene: &DynamicScene, time: f64, req: &ViewRequest) -> Result<ResolvedViews> {
    let cloud = scene.composite(time);
    let window = (req.width, req.height);
    let sizes: Vec<(u32, u32)> = if req.sizes.is_empty() {
        views::DEFAULT_SIZES.to_vec()
    } else {
        req.sizes.clone()
    };
    let spec = match req.spec.trim() {
        "auto" if !scene.cameras.is_empty() => "scene".to_string(),
        "auto" if !req.cameras.is_empty() => "cameras.json".to_string(),
        "auto" => format!("sphere:{}", super::DEFAULT_VIEWS),
        s => s.to_string(),
    };
    let fit = if let Some(n) = spec.strip_prefix("sphere:") {
        let n: usize = n
            .parse()
            .ok()
            .filter(|&n| (1..=4096).contains(&n))
            .ok_or_else(|| {
                super::DistillError::Invalid(format!("'{spec}' is not sphere:N with N in 1..=4096"))
            })?;
        views::sphere_with_fine(&cloud, n, req.fit_fine, &sizes, window)?
    } else {
        let cams = if spec == "cameras.json" {
            req.cameras.clone()
        } else {
            let items = parse_camera_list(&spec)?;
            // Lists are fitted at the target size, else (named lists) at the window's, as
            // whole views; the scene's own cameras picked by `auto` keep their sizes.
            let mut request = CameraRequest::new(CameraSpec::Scene(0));
            let size = match req.sizes.first() {
                Some(&s) => Some(s),
                None if req.spec.trim() == "auto" => None,
                None => Some(window),
            };
            if let Some((w, h)) = size {
                request.width = Some(w);
                request.height = Some(h);
            }
            request.resolve_list(
                &items,
                CameraSource {
                    cloud: &cloud,
                    own: &scene.cameras,
                },
            )?
        };
        let cams: Vec<Camera> = match req.sizes.first() {
            Some(&(w, h)) if spec == "cameras.json" => {
                cams.iter().map(|c| c.resized(w, h)).collect()
            }
            _ => cams,
        };
        // About the default count of windows in all, at most four per view.
        let per = (super::DEFAULT_VIEWS / cams.len().max(1)).clamp(1, 4);
        views::windows_of(&cloud, &cams, per, window)
    };
    let n = fit.windows.len();
    let sphere = spec.starts_with("sphere:");
    let fine = if sphere { req.validation_fine } else { 0 };
    let validation = views::validation_views(&cloud, n, req.validation, fine, &sizes, window)?;
    let held = match parse_camera_list(&spec).ok().as_deref() {
        Some([CameraListItem::Orbit(k)]) if req.held_back > 0 => {
            let (w, h) = req.held_size.unwrap_or(window);
            views::held_back(&cloud, *k, req.held_back, w, h)?
                .into_iter()
                .map(|camera| views::HeldBack {
                    class: "between the orbit's cameras".into(),
                    camera,
                })
                .collect()
        }
        _ if req.held_back > 0 => {
            let avoid = [&fit.frames[..], &validation.frames];
            let size = req.held_size.unwrap_or((320, 240));
            let per = req.held_back.div_ceil(views::HELD_BACK_CLASSES.len());
            let all = views::held_back_classes(&cloud, &[size], per, &avoid)?;
            // One of each class before the second of any.
            let classes = views::HELD_BACK_CLASSES.len();
            let mut order: Vec<usize> = (0..all.len()).collect();
            order.sort_by_key(|&i| (i % per, i / per % classes));
            let mut taken: Vec<views::HeldBack> =
                order.into_iter().map(|i| all[i].clone()).collect();
            taken.truncate(req.held_back);
            taken
        }
        _ => Vec::new(),
    };
    let spec = if sphere && req.fit_fine > 0 {
        format!("{spec} + {} fine-end", req.fit_fine)
    } else {
        spec
    };
    Ok(ResolvedViews {
        fit,
        validation: validation.windows,
        held,
        spec,
    })
}

/// What a distillation for an export did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Outcome {
    pub report: DistillReport,
    /// Mean PSNR against native on the held-back views of the export without distillation
    /// ("before": `convert` without `--distill`) and of the export written.
    pub held_back: Option<(f64, f64)>,
    /// The held-back views' change in PSNR (dB): worst and median.
    pub held_back_change: Option<(f64, f64)>,
    pub held_back_views: usize,
    pub description: String,
    /// The refused validation of the highest mean, above the kept one ([`Distiller::best_refused`]).
    pub best_refused: Option<super::guard::Validation>,
    /// Every validation of the fit, in order (the guard's log).
    pub validations: Vec<super::guard::Validation>,
    /// The validation views' and the held-back views' names (where and how large).
    pub validation_names: Vec<String>,
    pub held_back_names: Vec<String>,
    /// Each held-back view's PSNR against native without distillation and as written, dB.
    pub held_back_before: Vec<f64>,
    pub held_back_after: Vec<f64>,
    /// The kept fit against the undistilled export on the validation views, where the
    /// mesh was widened ([`super::plain`]).
    pub undistilled: Option<FloorCheck>,
}

/// For `--views auto` on a scene without cameras of its own: the cameras of a 3DGS
/// `cameras.json` beside the input `input`, if there is one (none otherwise).
pub fn cameras_beside(
    views: &str,
    scene: &DynamicScene,
    input: &std::path::Path,
) -> Result<Vec<Camera>> {
    let beside = input.with_file_name("cameras.json");
    if views == "auto" && scene.cameras.is_empty() && beside.is_file() {
        splatbridge_scene::camera::load_cameras_json(&beside).map_err(|e| {
            super::DistillError::Invalid(format!("--views auto: {}: {e}", beside.display()))
        })
    } else {
        Ok(Vec::new())
    }
}

/// The worst (smallest) and the median of `x`.
pub fn worst_and_median(x: &[f64]) -> Option<(f64, f64)> {
    let mut v: Vec<f64> = x.iter().copied().filter(|a| !a.is_nan()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    let median = if v.len().is_multiple_of(2) {
        0.5 * (v[m - 1] + v[m])
    } else {
        v[m]
    };
    Some((v[0], median))
}

/// Fit `convert`'s mesh of `scene` and set its vertex colours (and the metadata's
/// description) in `convert`; `on_step` sees the progress. With `opts.footprint` the scene
/// is widened in place for the fitting views (the mesh to write is made from it).
pub fn distill_export(
    scene: &mut DynamicScene,
    convert: &mut ConvertOptions,
    req: &ViewRequest,
    opts: &DistillOptions,
    on_step: impl FnMut(&super::Progress),
) -> Result<Outcome> {
    let views = resolve_views(scene, opts.time, req)?;
    let mut opts = opts.clone();
    if opts.times.is_empty() {
        opts.times = fitting_times(scene, req.times);
    }
    let (fit, frames) = (&views.fit.windows, &views.fit.frames);
    let (mut d, widened) = Distiller::for_windows(scene, convert, fit, frames, &opts)?;
    let val_times = opts.view_times(views.validation.len());
    d.add_validation(scene, &views.validation, &val_times)?;
    // Held-back views take the fitting times in turn too, so a dynamic scene is measured
    // over the poses it was fitted for.
    let held: Vec<Camera> = views.held.iter().map(|h| h.camera.clone()).collect();
    let held_times = opts.view_times(held.len());
    let held_targets = native_targets_sh(
        scene,
        &held,
        &held_times,
        opts.target_sh_degree,
        opts.target_near,
    )?;
    // With a widened mesh, the export without distillation is measured as well: on the
    // held-back views (their "before"), and on the validation views, against which the
    // fit's result is checked once it is kept (`plain`). Its tracer is dropped before the
    // fit.
    let (before, undistilled_validation) = match &widened {
        Some(_) => {
            let undistilled = Undistilled::new(scene, convert, &opts)?;
            let before = undistilled.psnr_each(&held, &held_times, &held_targets)?;
            let validation = (opts.floor && d.report().validation_views > 0)
                .then(|| d.validation_psnr_of(&undistilled))
                .transpose()?;
            (before, validation)
        }
        None => (d.psnr_each(&held, &held_times, &held_targets)?, None),
    };
    d.run(on_step)?;
    let r = d.report();
    // Where the kept result is below the undistilled export at a validation view, that
    // export is written (`plain`): its held-back images are the ones of `before`.
    let floor = undistilled_validation.map(|u| d.check_floor(u));
    let to_undistilled = floor.as_ref().is_some_and(|c| c.kept_undistilled);
    // Where no step ran, or the guard went back to the start (its iteration-0 snapshot, the
    // colours just measured) of a mesh that was not widened, the held-back images are the
    // ones of `before` too, bit for bit: the same colours on the same mesh (moved positions
    // change the mesh).
    let at_start = widened.is_none()
        && !opts.positions
        && (r.iterations == 0 || (r.validation_views > 0 && r.kept_iteration == 0));
    let after = if to_undistilled || at_start {
        before.clone()
    } else {
        d.psnr_each(&held, &held_times, &held_targets)?
    };
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len().max(1) as f64;
    let change: Vec<f64> = after.iter().zip(&before).map(|(a, b)| a - b).collect();
    let colours = d.vertex_colours()?;
    if let (Some(w), false) = (widened, to_undistilled) {
        *scene = w;
    }
    let report = d.report();
    // The measurement-only and optional parts of the fit, said after the loss.
    // A near plane other than the reference's is said with the targets it changed.
    let near = super::near_unless_reference(opts.target_near)
        .map(|z| format!(" against native with its near plane at {z}"));
    let what_else = [
        opts.positions.then(|| " with positions".to_string()),
        (opts.order == super::HitOrder::Splat).then(|| {
            " composited in splat order (a measurement: viewers draw ray order)".to_string()
        }),
        near,
    ]
    .into_iter()
    .flatten()
    .collect::<Vec<_>>()
    .join(",");
    let description = format!(
        "{} views '{}' through {}×{} windows ({}){}{}, {} iterations of Adam on {}{} in {:.1} s{}",
        report.views,
        views.spec,
        report.width,
        report.height,
        sizes_text(frames),
        if opts.footprint {
            format!(
                ", Gaussians widened by the low-pass of the views that see them (quantile {})",
                opts.footprint_quantile
            )
        } else {
            String::new()
        },
        if opts.times.len() > 1 {
            format!(" over {} scene times", opts.times.len())
        } else {
            String::new()
        },
        report.iterations,
        report.loss,
        what_else,
        report.seconds,
        if report.validation_views > 0 {
            format!(
                ", iteration {} kept by {} validation views",
                report.kept_iteration, report.validation_views
            )
        } else {
            String::new()
        }
    );
    let description = match floor.as_ref().and_then(FloorCheck::worst) {
        Some((view, change)) if to_undistilled => format!(
            "{description}; the undistilled export written (validation view {} {:.3} dB below it)",
            view + 1,
            -change
        ),
        _ => description,
    };
    if !to_undistilled {
        convert.vertex_colours = Some(Arc::new(colours));
    }
    convert.distilled = Some(description.clone());
    Ok(Outcome {
        report,
        held_back: (!held.is_empty()).then(|| (mean(&before), mean(&after))),
        held_back_change: worst_and_median(&change),
        held_back_views: held.len(),
        description,
        best_refused: d.best_refused().cloned(),
        validations: d.validation_log().to_vec(),
        validation_names: views.validation.iter().map(|c| c.name.clone()).collect(),
        held_back_names: held.iter().map(|c| c.name.clone()).collect(),
        held_back_before: before,
        held_back_after: after,
        undistilled: floor,
    })
}

/// The whole views' sizes, distinct, in order ("320×240, 1920×1080").
fn sizes_text(frames: &[Camera]) -> String {
    let mut seen: Vec<(u32, u32)> = Vec::new();
    for c in frames {
        if !seen.contains(&(c.width, c.height)) {
            seen.push((c.width, c.height));
        }
    }
    seen.iter()
        .map(|(w, h)| format!("{w}×{h}"))
        .collect::<Vec<_>>()
        .join(", ")
}
