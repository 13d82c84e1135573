//! What a fit is measured against: native splatting's targets (SH capped at a degree for the
//! view-dependence measurement), the footprint-widened scene the mesh is made from, and the
//! mean PSNR of a fitted mesh on held-back views.

use splatbridge_convert::ConvertOptions;
use splatbridge_hybrid::native::RenderOptions as NativeOptions;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::{Camera, Frame};

use rayon::prelude::*;

use super::{DistillOptions, Distiller, Result};

/// The scene the mesh is made from for `cameras` (whole views, not windows): `scene` widened
/// by native splatting's low-pass at each Gaussian's depth, the smallest over the views whose
/// image holds it, when `opts.footprint`, else None (the scene as it is). The widening is a property of the export, so callers write this scene. Gaussians
/// the converter makes flat keep their smallest scale, so every Gaussian keeps its class and
/// the mesh its triangle count (widening all three scales turned 46 % more of `donut`'s
/// triangles volumetric: 1.40 M → 2.05 M).
pub fn widen_for_fit(
    scene: &DynamicScene,
    cameras: &[Camera],
    opts: &DistillOptions,
    convert: &ConvertOptions,
) -> Option<DynamicScene> {
    use splatbridge_convert::classify::{classify, Kind};
    let three = convert.volumetric == splatbridge_convert::VolumetricMode::ThreeFans;
    let ratio = convert.flat_ratio;
    opts.footprint.then(|| {
        let mut s = scene.clone();
        crate::footprint::widen_scene_seen(&mut s, cameras, opts.footprint_quantile, |c, i| {
            classify(c, i, ratio, three, false) != Kind::Volumetric
        });
        s
    })
}

/// Mean PSNR of the fitted mesh against `targets` from `cameras` (at the options' time).
pub fn mean_psnr(d: &mut Distiller, cameras: &[Camera], targets: &[Frame]) -> Result<f64> {
    let t = d.opts.time;
    let times = vec![t; cameras.len()];
    mean_psnr_at(d, cameras, &times, targets)
}

/// Mean PSNR of the fitted mesh against `targets` from `cameras`, camera i at `times[i]`.
pub fn mean_psnr_at(
    d: &mut Distiller,
    cameras: &[Camera],
    times: &[f64],
    targets: &[Frame],
) -> Result<f64> {
    let each = d.psnr_each(cameras, times, targets)?;
    Ok(each.iter().sum::<f64>() / cameras.len().max(1) as f64)
}

/// PSNR against native of `render`'s image from each of `cameras` (at `times`, against
/// `targets`), a view at a time per thread: a small image's tiles do not keep two cores busy.
pub(crate) fn psnr_views(
    cameras: &[Camera],
    times: &[f64],
    targets: &[Frame],
    render: impl Fn(&Camera, f64) -> Result<Frame> + Sync,
) -> Result<Vec<f64>> {
    cameras
        .par_iter()
        .zip(times)
        .zip(targets)
        .map(|((c, &time), t)| Ok(splatbridge_scene::metrics::psnr(&render(c, time)?, t)?))
        .collect()
}

/// Native targets of `scene` from `cameras`, camera i at scene time `times[i]`.
pub fn native_targets_at(
    scene: &DynamicScene,
    cameras: &[Camera],
    times: &[f64],
) -> Result<Vec<Frame>> {
    let native = NativeOptions::default();
    native_targets_sh(scene, cameras, times, native.sh_degree_cap, native.near)
}

/// [`native_targets_at`] with SH up to degree `sh_degree` and Gaussians at view depth
/// `z ≤ near` dropped.
pub fn native_targets_sh(
    scene: &DynamicScene,
    cameras: &[Camera],
    times: &[f64],
    sh_degree: u8,
    near: f32,
) -> Result<Vec<Frame>> {
    let native = native_options(sh_degree, near);
    let mut r = splatbridge_hybrid::native::Renderer::new();
    let mut out = Vec::with_capacity(cameras.len());
    let mut cached: Option<(f64, splatbridge_scene::GaussianCloud)> = None;
    for (c, &t) in cameras.iter().zip(times) {
        if cached.as_ref().is_none_or(|(ct, _)| *ct != t) {
            cached = Some((t, scene.composite(t)));
        }
        if let Some((_, cloud)) = &cached {
            out.push(render_native(&mut r, cloud, c, &native)?);
        }
    }
    Ok(out)
}

/// Native splatting's reference settings with SH up to degree `sh_degree` and the near plane
/// `near`.
pub(crate) fn native_options(sh_degree: u8, near: f32) -> NativeOptions {
    NativeOptions {
        sh_degree_cap: sh_degree,
        near,
        ..NativeOptions::default()
    }
}

/// Native targets (reference settings) of `scene` at `time` from `cameras`.
pub fn native_targets(scene: &DynamicScene, time: f64, cameras: &[Camera]) -> Result<Vec<Frame>> {
    let cloud = scene.composite(time);
    let mut r = splatbridge_hybrid::native::Renderer::new();
    cameras
        .iter()
        .map(|c| render_native(&mut r, &cloud, c, &NativeOptions::default()))
        .collect()
}

/// Native splatting of `cam`, a whole view or a window of one: a window is rendered through
/// its centred frame ([`crate::views::frame_of`]) and cut, so its pixels are the frame's.
pub fn render_native(
    r: &mut splatbridge_hybrid::native::Renderer,
    cloud: &splatbridge_scene::GaussianCloud,
    cam: &Camera,
    native: &NativeOptions,
) -> Result<Frame> {
    let (frame, x0, y0) = crate::views::frame_of(cam);
    if (x0, y0, frame.width, frame.height) == (0, 0, cam.width, cam.height) {
        return Ok(r.render(cloud, &frame, native)?.0);
    }
    // Only the window's tiles: the frame's pixels there, bit for bit (a 240×180 window of a
    // 1080p view is 2 % of it).
    Ok(
        r.render_window(cloud, &frame, native, [x0, y0, cam.width, cam.height])?
            .0,
    )
}
