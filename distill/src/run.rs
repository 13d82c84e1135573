//! Distillation for an export: resolve the views, fit, measure on held-back views, and hand
//! the fitted colours to the convert options (what `convert --distill` runs).

use std::sync::Arc;

use splatbridge_convert::ConvertOptions;
use splatbridge_scene::camera_spec::{
    parse_camera_list, CameraListItem, CameraRequest, CameraSource, CameraSpec,
};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::Camera;

use super::{
    mean_psnr_at, native_targets_sh, views, DistillOptions, DistillReport, Distiller, Result,
};

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
    /// A camera list: `orbit:N`, `scene`, `PATH.json`, single specs, comma-separated.
    pub spec: String,
    pub width: u32,
    pub height: u32,
    /// Held-back views to measure before and after (fitting by `orbit:N` only).
    pub held_back: usize,
    /// Held-back image size when it is not the fitting size (so fits at different sizes
    /// are measured on the same images).
    pub held_size: Option<(u32, u32)>,
    /// Scene times a dynamic scene is fitted at (evenly over its time range, start and end
    /// included), given to the views in turn; static scenes use their start.
    pub times: usize,
}

impl Default for ViewRequest {
    fn default() -> Self {
        ViewRequest {
            spec: format!("orbit:{}", super::DEFAULT_VIEWS),
            width: 240,
            height: 180,
            held_back: 4,
            held_size: None,
            times: 4,
        }
    }
}

/// The fitting cameras and, for a single `orbit:N`, the held-back cameras between them.
pub fn resolve_views(
    scene: &DynamicScene,
    time: f64,
    req: &ViewRequest,
) -> Result<(Vec<Camera>, Vec<Camera>)> {
    let items = parse_camera_list(&req.spec)?;
    let cloud = scene.composite(time);
    let mut request = CameraRequest::new(CameraSpec::Scene(0));
    request.width = Some(req.width);
    request.height = Some(req.height);
    let cams = request.resolve_list(
        &items,
        CameraSource {
            cloud: &cloud,
            own: &scene.cameras,
        },
    )?;
    let held = match items[..] {
        [CameraListItem::Orbit(n)] if req.held_back > 0 => {
            let (w, h) = req.held_size.unwrap_or((req.width, req.height));
            views::held_back(&cloud, n, req.held_back, w, h)?
        }
        _ => Vec::new(),
    };
    Ok((cams, held))
}

/// What a distillation for an export did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Outcome {
    pub report: DistillReport,
    /// Mean PSNR against native on the held-back views before and after fitting.
    pub held_back: Option<(f64, f64)>,
    pub held_back_views: usize,
    pub description: String,
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
    let (cams, held) = resolve_views(scene, opts.time, req)?;
    let mut opts = opts.clone();
    if opts.times.is_empty() {
        opts.times = fitting_times(scene, req.times);
    }
    let (mut d, widened) = Distiller::for_export(scene, convert, &cams, &opts)?;
    // Held-back views take the fitting times in turn too, so a dynamic scene is measured
    // over the poses it was fitted for.
    let held_times = opts.view_times(held.len());
    let held_targets = native_targets_sh(scene, &held, &held_times, opts.target_sh_degree)?;
    let before = if held.is_empty() {
        None
    } else {
        Some(mean_psnr_at(&mut d, &held, &held_times, &held_targets)?)
    };
    d.run(on_step)?;
    let after = match before {
        Some(_) => Some(mean_psnr_at(&mut d, &held, &held_times, &held_targets)?),
        None => None,
    };
    let colours = d.vertex_colours()?;
    if let Some(w) = widened {
        *scene = w;
    }
    let report = d.report();
    // The measurement-only and optional parts of the fit, said after the loss.
    let what_else = [
        opts.positions.then_some(" with positions"),
        (opts.order == super::HitOrder::Splat)
            .then_some(" composited in splat order (a measurement: viewers draw ray order)"),
    ]
    .into_iter()
    .flatten()
    .collect::<Vec<_>>()
    .join(",");
    let description = format!(
        "{} views '{}' at {}×{}{}{}, {} iterations of Adam on {}{} in {:.1} s",
        report.views,
        req.spec,
        report.width,
        report.height,
        if opts.footprint {
            ", Gaussians widened by the low-pass of those views"
        } else {
            ""
        },
        if opts.times.len() > 1 {
            format!(" over {} scene times", opts.times.len())
        } else {
            String::new()
        },
        report.iterations,
        report.loss,
        what_else,
        report.seconds
    );
    convert.vertex_colours = Some(Arc::new(colours));
    convert.distilled = Some(description.clone());
    Ok(Outcome {
        report,
        held_back: before.zip(after),
        held_back_views: held.len(),
        description,
    })
}
