//! Distillation for an export: resolve the views, fit, measure on held-back views, and hand
//! the fitted colours to the convert options (what `convert --distill` runs).

use std::sync::Arc;

use splatbridge_convert::ConvertOptions;
use splatbridge_scene::camera_spec::{
    parse_camera_list, CameraListItem, CameraRequest, CameraSource, CameraSpec,
};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::Camera;

use super::{mean_psnr, native_targets, views, DistillOptions, DistillReport, Distiller, Result};

/// Which views to fit and at what size.
#[derive(Clone, Debug)]
pub struct ViewRequest {
    /// A camera list: `orbit:N`, `scene`, `PATH.json`, single specs, comma-separated.
    pub spec: String,
    pub width: u32,
    pub height: u32,
    /// Held-back views to measure before and after (fitting by `orbit:N` only).
    pub held_back: usize,
}

impl Default for ViewRequest {
    fn default() -> Self {
        ViewRequest {
            spec: "orbit:16".into(),
            width: 240,
            height: 180,
            held_back: 4,
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
            views::held_back(&cloud, n, req.held_back, req.width, req.height)?
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
/// description) in `convert`; `on_step` sees the progress.
pub fn distill_export(
    scene: &DynamicScene,
    convert: &mut ConvertOptions,
    req: &ViewRequest,
    opts: &DistillOptions,
    on_step: impl FnMut(&super::Progress),
) -> Result<Outcome> {
    let (cams, held) = resolve_views(scene, opts.time, req)?;
    let mut d = Distiller::new(scene, convert, &cams, opts)?;
    let held_targets = native_targets(scene, opts.time, &held)?;
    let before = if held.is_empty() {
        None
    } else {
        Some(mean_psnr(&mut d, &held, &held_targets)?)
    };
    d.run(on_step)?;
    let after = match before {
        Some(_) => Some(mean_psnr(&mut d, &held, &held_targets)?),
        None => None,
    };
    let colours = d.vertex_colours()?;
    let report = d.report();
    let description = format!(
        "{} views '{}' at {}×{}, {} iterations of Adam on {} in {:.1} s",
        report.views,
        req.spec,
        report.width,
        report.height,
        report.iterations,
        report.loss,
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
