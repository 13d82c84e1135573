//! The mean-depth cull of the footprint BVHs ([`super::camera::Bucket`]) against the same
//! render with no cull at all (every proxy the ray enters is tested, the former behaviour):
//! the images must agree bit for bit, and the cull must actually skip work.

use glam::{DVec3, Quat, Vec3};
use splatbridge_scene::dynamic::{DynamicScene, PoseKey, SceneObject, TimeRange, Track};
use splatbridge_scene::rng::Rng;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use super::GaussianTracer;
use crate::backend::{BackendKind, BuildPreset};
use crate::footprint::{Footprint, HitOrder};
use crate::render::{RenderOptions, Stats};

/// An unnormalised random rotation (the tracer normalises, as readers of real files must) and
/// SH degree-1 coefficients with a strong DC term: shared by the tracer's random test scenes.
pub(super) fn random_rotation_and_sh(r: &mut Rng) -> (Quat, Vec<Vec3>) {
    let q = Quat::from_xyzw(
        r.range(-1.0, 1.0),
        r.range(-1.0, 1.0),
        r.range(-1.0, 1.0),
        r.range(-1.0, 1.0),
    );
    let sh = (0..4)
        .map(|k| {
            Vec3::new(r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0))
                * if k == 0 { 1.5 } else { 0.3 }
        })
        .collect();
    (q, sh)
}

/// A deep corridor of Gaussians (many per ray, so the k-buffer runs several rounds) whose
/// sizes span three decades (so a part splits into several buckets), with a few large ones.
pub(super) fn corridor(seed: u64, n: usize) -> GaussianCloud {
    // The project's SplitMix64, started at state `seed`.
    let mut r = Rng::new(seed ^ 0x9E37_79B9_7F4A_7C15);
    let mut c = GaussianCloud::new(1);
    for i in 0..n {
        let m = Vec3::new(r.range(-1.0, 1.0), r.range(-0.8, 0.8), r.range(0.5, 12.0));
        let size = if i % 97 == 0 {
            r.range(0.5, 1.5)
        } else {
            0.004 * 10f32.powf(r.range(0.0, 2.0))
        };
        let s = Vec3::new(size, size * r.range(0.2, 1.0), size * r.range(0.05, 1.0));
        let (q, sh) = random_rotation_and_sh(&mut r);
        let o = r.range(0.05, 0.6);
        c.push(
            m,
            Vec3::new(s.x.ln(), s.y.ln(), s.z.ln()),
            q,
            splatbridge_scene::gaussians::logit(o),
            &sh,
        );
    }
    c
}

pub(super) fn camera() -> Camera {
    Camera::look_at(
        DVec3::new(0.05, 0.02, -0.5),
        DVec3::new(0.0, 0.0, 6.0),
        DVec3::NEG_Y,
        60.0,
        40,
        30,
    )
    .unwrap()
}

/// [`GaussianTracer::render`], with the cull (`cull`) or with every bucket's reach unbounded
/// (no cull: the reference).
fn render(
    tracer: &GaussianTracer,
    cam: &Camera,
    opts: &RenderOptions,
    cull: bool,
) -> (Frame, Stats) {
    let variance = opts.sample_footprint.variance_px2(opts.spp);
    let mut padded = tracer.for_camera(cam, opts.footprint, variance).unwrap();
    if !cull {
        for b in padded
            .iter_mut()
            .flat_map(|p| p.accels.iter_mut().flatten())
        {
            b.reach = f32::INFINITY;
        }
    }
    tracer.render_padded(cam, opts, padded.as_ref()).unwrap()
}

/// Every channel of a frame as bits, for bit-for-bit comparisons.
pub(super) fn bits(f: &Frame) -> Vec<u32> {
    f.rgb
        .iter()
        .chain(&f.alpha)
        .chain(&f.depth)
        .map(|v| v.to_bits())
        .collect()
}

fn check(tracer: &GaussianTracer, cam: &Camera) {
    for k in [1, 4, 16] {
        let opts = RenderOptions {
            k,
            footprint: Footprint::On,
            order: HitOrder::MeanDepth,
            ..RenderOptions::default()
        };
        let (fast, fs) = render(tracer, cam, &opts, true);
        let (slow, ss) = render(tracer, cam, &opts, false);
        assert!(fs.hits > 0, "k {k}: nothing drawn");
        assert_eq!(bits(&fast), bits(&slow), "k {k}: images differ");
        assert_eq!(fs.hits, ss.hits, "k {k}");
        assert!(
            fs.candidates < ss.candidates,
            "k {k}: the cull skipped nothing ({} vs {} candidates)",
            fs.candidates,
            ss.candidates
        );
    }
}

#[test]
fn several_buckets_are_built() {
    let tracer =
        GaussianTracer::new(corridor(1, 1500), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let p = tracer.padded(&camera(), 0.3).unwrap();
    let sizes: Vec<(usize, f32)> = p.accels[0]
        .iter()
        .map(|b| (b.ids.as_ref().map_or(0, |i| i.len()), b.reach))
        .collect();
    assert!(sizes.len() >= 3, "buckets {sizes:?}");
    assert!(
        sizes.windows(2).all(|w| w[0].0 >= w[1].0),
        "buckets {sizes:?}"
    );
    let total: usize = sizes.iter().map(|s| s.0).sum();
    assert_eq!(total, 1500, "every proxy in one bucket");
}

#[test]
fn mean_depth_cull_matches_no_cull_static() {
    let tracer =
        GaussianTracer::new(corridor(2, 1500), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    check(&tracer, &camera());
}

/// A static corridor and two objects moving under tracks (rotating and translating).
pub(super) fn moving_scene() -> DynamicScene {
    let mut scene = DynamicScene::from_static(corridor(3, 900));
    scene.time = TimeRange {
        start: 0.0,
        end: 1.0,
        fps: 4.0,
    };
    for (k, seed) in [(0usize, 4u64), (1, 5)] {
        let keys = (0..3)
            .map(|i| {
                let s = i as f32 * 0.5;
                PoseKey::new(
                    s as f64,
                    Vec3::new(0.3 * s - 0.2 * k as f32, 0.1 * s, 0.5 + k as f32),
                    Quat::from_axis_angle(Vec3::Y, 0.4 * s + k as f32),
                )
            })
            .collect();
        scene.objects.push(SceneObject {
            name: format!("object{k}"),
            gaussians: corridor(seed, 300),
            track: Track::new(keys),
        });
    }
    scene.validate().unwrap();
    scene
}

/// Several parts (objects under tracks): a part traversed after the k-buffer filled must
/// start from the widened cull too.
#[test]
fn mean_depth_cull_matches_no_cull_dynamic() {
    let scene = moving_scene();
    let mut tracer =
        GaussianTracer::for_scene(&scene, 0.0, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    for t in [0.0, 0.7] {
        tracer.set_time(t);
        check(&tracer, &camera());
    }
}
