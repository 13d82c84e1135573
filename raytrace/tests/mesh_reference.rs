//! The mesh mode against the brute-force f64 reference (tests/common): same hit sets in the
//! same order and the same image (≤ 1e-5) on synthetic fan scenes, static and instanced, for
//! every compiled-in backend.

mod common;

use common::*;
use glam::{DQuat, DVec3, Vec3};
use splatbridge_raytrace::model::{Channel, ChannelPath, Interpolation, Node, TriScene};
use splatbridge_raytrace::{BackendKind, BuildPreset, MeshTracer, RenderOptions};
use splatbridge_scene::Camera;

pub fn backends() -> Vec<BackendKind> {
    let mut v = vec![BackendKind::Obvhs];
    if splatbridge_raytrace::backend::EMBREE_AVAILABLE {
        v.push(BackendKind::Embree);
    }
    v
}

/// Image tolerance: f32 barycentrics and f32 compositing against f64 carry ~1e-6 absolute
/// error per layer at these depths (measured max ≈ 1e-6); the bound is 1e-5.
const IMAGE_TOL: f64 = 1e-5;

/// Compare tracer and reference on every pixel of `cam`; returns the number of pixels skipped
/// as ambiguous (a group boundary within 1e-5 of the ray).
pub fn compare(scene: &TriScene, time: f64, cam: &Camera, backend: BackendKind, opts: &RenderOptions) -> usize {
    let tracer = MeshTracer::new(scene.clone(), backend, BuildPreset::Medium).unwrap();
    let reference = Reference::new(scene, time);
    let insts = tracer.prepare(time);
    let (frame, stats) = tracer.render(cam, time, opts).unwrap();
    assert!(frame.is_finite());
    assert_eq!(stats.rays, (cam.width * cam.height) as u64);
    let mut skipped = 0;
    let mut total_hits = 0;
    for j in 0..cam.height {
        for i in 0..cam.width {
            let (o, d) = (cam.centre, cam.ray_dir(i as f64 + 0.5, j as f64 + 0.5));
            let got = tracer.all_hits(&insts, o, d, opts.k);
            let want = reference.trace(o, d);
            total_hits += want.hits.len();
            let key = |g: u32, inst: u32, grp: u32| (g, inst, grp);
            let a: Vec<_> = got.iter().map(|h| key(h.gaussian, h.instance, h.group)).collect();
            let b: Vec<_> = want.hits.iter().map(|h| key(h.gaussian, h.instance, h.group)).collect();
            if a != b {
                // Only boundary-ambiguous groups may differ.
                let strip = |v: &[(u32, u32, u32)]| -> Vec<(u32, u32, u32)> {
                    v.iter().copied().filter(|k| !want.ambiguous.contains(&(k.1, k.2))).collect()
                };
                assert_eq!(strip(&a), strip(&b), "{backend}: hit sets differ at pixel ({i}, {j})");
                skipped += 1;
                continue;
            }
            for (g, w) in got.iter().zip(&want.hits) {
                // f32 distance from a camera-relative origin: relative error ~1e-6.
                assert!((g.t as f64 - w.t).abs() <= 1e-5 * w.t.max(1.0), "{backend}: t {} vs {} at ({i}, {j})", g.t, w.t);
            }
            let (rgb, alpha) = reference.composite(&want, opts);
            let px = frame.rgb_at(i, j);
            let k = (j * cam.width + i) as usize;
            for c in 0..3 {
                assert!(
                    (px[c] as f64 - rgb[c]).abs() <= IMAGE_TOL,
                    "{backend}: pixel ({i}, {j}) channel {c}: {} vs {}",
                    px[c],
                    rgb[c]
                );
            }
            assert!((frame.alpha[k] as f64 - alpha).abs() <= IMAGE_TOL);
        }
    }
    assert!(total_hits > 0, "the scene must be visible");
    // Ambiguity is a measure-zero event for random scenes: allow at most 0.5 % of pixels.
    assert!(skipped * 200 <= (cam.width * cam.height) as usize, "{skipped} ambiguous pixels");
    skipped
}

fn look(eye: DVec3, target: DVec3, w: u32, h: u32) -> Camera {
    Camera::look_at(eye, target, DVec3::NEG_Y, 50.0, w, h).unwrap()
}

#[test]
fn random_fans_match_reference() {
    let mesh = random_fans(1, 300, 1.0, Vec3::ZERO);
    let scene = TriScene::single(mesh, blend_materials(), vec![]);
    for b in backends() {
        for k in [1, 4, 16] {
            let opts = RenderOptions { k, ..Default::default() };
            compare(&scene, 0.0, &look(DVec3::new(0.3, -0.5, -4.0), DVec3::ZERO, 48, 36), b, &opts);
        }
    }
}

#[test]
fn far_from_origin_matches_reference() {
    // 1e5 units away: positions are f32 in the file, rays and anchors are f64.
    let off = Vec3::new(1e5, -1e5, 1e5);
    let mesh = random_fans(2, 200, 1.0, off);
    let scene = TriScene::single(mesh, blend_materials(), vec![]);
    let c = off.as_dvec3();
    for b in backends() {
        compare(&scene, 0.0, &look(c + DVec3::new(0.2, -0.4, -4.0), c, 40, 30), b, &RenderOptions::default());
    }
}

#[test]
fn animated_instances_match_reference() {
    let stat = random_fans(3, 120, 1.0, Vec3::ZERO);
    let moving = random_fans(4, 60, 0.4, Vec3::ZERO);
    let mut scene = TriScene {
        meshes: vec![stat, moving],
        materials: blend_materials(),
        ..TriScene::default()
    };
    scene.nodes = vec![
        Node {
            mesh: Some(0),
            ..Node::default()
        },
        Node {
            mesh: Some(1),
            parent: Some(2),
            ..Node::default()
        },
        // A parent with a scale, so the ray parameter must survive a non-rigid transform.
        Node {
            scale: DVec3::new(1.0, 1.5, 1.0),
            ..Node::default()
        },
    ];
    let q0 = DQuat::IDENTITY;
    let q1 = DQuat::from_rotation_y(2.0);
    scene.channels = vec![
        Channel {
            node: 1,
            path: ChannelPath::Translation,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 1.0],
            values: vec![[-1.0, 0.0, -0.5, 0.0], [1.0, 0.2, 0.5, 0.0]],
        },
        Channel {
            node: 1,
            path: ChannelPath::Rotation,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 1.0],
            values: vec![q0.to_array(), q1.to_array()],
        },
    ];
    for b in backends() {
        for t in [0.0, 0.37, 1.5] {
            compare(&scene, t, &look(DVec3::new(0.5, -0.8, -4.0), DVec3::ZERO, 40, 30), b, &RenderOptions::default());
        }
    }
}
