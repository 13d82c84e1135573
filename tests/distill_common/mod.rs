//! Scenes and helpers shared by the distillation tests.

// Each test crate that includes this module uses a subset of it.
#![allow(dead_code)]

use splatbridge::distill::run::{resolve_views, ViewRequest};
use splatbridge::distill::{DistillOptions, Distiller};
use splatbridge_convert::{ConvertOptions, Profile};
use splatbridge_raytrace::{BackendKind, BuildPreset, MeshTracer};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

/// The converter's defaults with `profile`.
pub fn opts(profile: Profile) -> ConvertOptions {
    ConvertOptions {
        profile,
        ..ConvertOptions::default()
    }
}

/// The largest absolute difference between two images' values.
pub fn worst_difference(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max)
}

/// The largest magnitude among the first `lanes` components of a gradient.
pub fn grad_scale(grad: &[[f32; 4]], lanes: usize) -> f64 {
    grad.iter()
        .flat_map(|g| g[..lanes].iter())
        .fold(0.0f64, |m, &x| m.max(x.abs() as f64))
}

/// The `n` (vertex, lane) components of largest magnitude among the first `lanes` lanes
/// that `keep` accepts, largest first: the ones a finite-difference check is worth making on.
pub fn largest(
    grad: &[[f32; 4]],
    lanes: usize,
    keep: impl Fn(usize, usize) -> bool,
    n: usize,
) -> Vec<(usize, usize)> {
    let mut idx: Vec<(usize, usize)> = (0..grad.len())
        .flat_map(|v| (0..lanes).map(move |c| (v, c)))
        .filter(|&(v, c)| keep(v, c))
        .collect();
    idx.sort_by(|a, b| grad[b.0][b.1].abs().total_cmp(&grad[a.0][a.1].abs()));
    idx.truncate(n);
    idx
}

/// `n` Gaussians of random orientation, flat and volumetric, packed in a unit cube at sizes
/// around a tenth of it, so their fans cut through each other (a splitmix64 stream, fixed).
pub fn crossing_cloud(n: usize) -> GaussianCloud {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f32 / (1u64 << 53) as f32
    };
    let mut c = GaussianCloud::with_capacity(0, n);
    for i in 0..n {
        let p = glam::Vec3::new(next(), next(), next()) - 0.5;
        let flat = if i % 2 == 0 { 0.05 } else { 1.0 };
        let s = glam::Vec3::new(0.05 + 0.1 * next(), 0.05 + 0.1 * next(), 0.1 * flat);
        let q = glam::Quat::from_xyzw(next() - 0.5, next() - 0.5, next() - 0.5, next() - 0.5)
            .normalize();
        let rgb = glam::Vec3::new(next(), next(), next());
        c.push_activated(p, s, q, 0.5 + 0.45 * next(), rgb);
    }
    c
}

/// The small fit of the export tests: `orbit:4` at 40×30, one view held back, one time.
pub fn small_request() -> ViewRequest {
    ViewRequest {
        spec: "orbit:4".into(),
        width: 40,
        height: 30,
        held_back: 1,
        // `refit` runs the fit again without validation views, to the last iteration.
        validation: 0,
        times: 1,
        ..ViewRequest::default()
    }
}

/// The fit `distill_export` made, made again in memory: targets of `original`, the mesh of
/// `scene` (the widened scene it exported) with `convert`'s options but their fitted colours.
pub fn refit(
    original: &DynamicScene,
    scene: &DynamicScene,
    convert: &ConvertOptions,
    req: &ViewRequest,
    d_opts: &DistillOptions,
) -> (Distiller, Vec<Camera>) {
    let fit_cams = resolve_views(scene, 0.0, req).unwrap().fit.windows;
    let mut plain = convert.clone();
    plain.vertex_colours = None;
    let mut d = Distiller::with_mesh_scene(original, scene, &plain, &fit_cams, d_opts).unwrap();
    d.run(|_| {}).unwrap();
    (d, fit_cams)
}

/// The tracer over `convert`'s GLB of `scene`, read back from its bytes as a viewer would.
pub fn trace_export(scene: &DynamicScene, convert: &ConvertOptions) -> (MeshTracer, Vec<u8>) {
    let (bytes, _) = splatbridge_convert::glb_bytes(scene, None, convert).unwrap();
    let mut tri =
        splatbridge_raytrace::scene_load::load_glb_bytes(&bytes, "distilled.glb".as_ref()).unwrap();
    tri.to_capture_frame();
    let tracer = MeshTracer::new(tri, BackendKind::default(), BuildPreset::default()).unwrap();
    (tracer, bytes)
}

/// A cloud of `large(300, 7)` with SH degree 1: its DC terms and a strong first band, so
/// that renders at degree 0 and at the full degree differ.
pub fn view_dependent_cloud() -> GaussianCloud {
    let mut cloud = splatbridge_scene::fixtures::large(300, 7);
    let n = cloud.len();
    let k = cloud.sh.len() / n.max(1);
    let dc: Vec<glam::Vec3> = (0..n).map(|i| cloud.sh[i * k]).collect();
    cloud.sh_degree = 1;
    cloud.sh = dc
        .iter()
        .flat_map(|&c| {
            [
                c,
                glam::Vec3::splat(0.5),
                glam::Vec3::new(-0.4, 0.3, 0.2),
                glam::Vec3::splat(-0.3),
            ]
        })
        .collect();
    cloud
}

/// The street fixture (3,000 Gaussians, objects in their pose at t = 0), 8 fitting orbit views
/// and 4 held-back views between them at 64×48, and native's images at the held-back views.
pub fn street_fit_and_held_back() -> (DynamicScene, Vec<Camera>, Vec<Camera>, Vec<Frame>) {
    let scene = splatbridge_scene::fixtures::street_with(
        &splatbridge_scene::fixtures::StreetParams::new(3, 3000),
    );
    let cloud = scene.composite(0.0);
    let fit = splatbridge::distill::views::orbit(&cloud, 8, 0..8, 64, 48).unwrap();
    let held = splatbridge::distill::views::held_back(&cloud, 8, 4, 64, 48).unwrap();
    let targets = splatbridge::distill::native_targets(&scene, 0.0, &held).unwrap();
    (scene, fit, held, targets)
}
