//! obvhs and Embree produce the same images (≤ 1e-5) in both modes, and Embree's edge rule
//! (which may give a shared-edge hit to the other triangle of the pair) never loses or doubles
//! a fan. Needs `--features embree` (after scripts/get-embree.sh).
#![cfg(feature = "embree")]

mod common;

use common::*;
use glam::{DVec3, Quat, Vec3};
use splatbridge_raytrace::{
    BackendKind, BuildPreset, GaussianTracer, MeshTracer, RenderOptions, TriScene,
};
use splatbridge_scene::{Camera, GaussianCloud};

/// Both backends composite identical hit lists with identical arithmetic, so the only source
/// of difference is a ray within f32 rounding of an outer fan edge; the bound is 1e-5.
const TOL: f32 = 1e-5;

#[test]
fn mesh_images_agree() {
    let scene = TriScene::single(
        random_fans(21, 2000, 1.0, Vec3::ZERO),
        blend_materials(),
        vec![],
    );
    let cam = Camera::look_at(
        DVec3::new(0.4, -0.6, -3.5),
        DVec3::ZERO,
        DVec3::NEG_Y,
        60.0,
        96,
        72,
    )
    .unwrap();
    let a = MeshTracer::new(scene.clone(), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let b = MeshTracer::new(scene, BackendKind::Embree, BuildPreset::Medium).unwrap();
    for k in [4, 16] {
        let opts = RenderOptions {
            k,
            ..Default::default()
        };
        let (fa, sa) = a.render(&cam, 0.0, &opts).unwrap();
        let (fb, sb) = b.render(&cam, 0.0, &opts).unwrap();
        let bad = fa
            .rgb
            .iter()
            .zip(&fb.rgb)
            .filter(|(x, y)| (*x - *y).abs() > TOL)
            .count();
        // Outer-edge ambiguity is measure-zero; allow a handful of channel values.
        assert!(
            bad <= 3,
            "k {k}: {bad} values differ by more than {TOL}; max {}",
            fa.max_rgb_diff(&fb)
        );
        assert!(sa.hits > 0 && sa.hits.abs_diff(sb.hits) <= 3);
    }
}

#[test]
fn gaussian_images_agree() {
    let mut r = Rng(5);
    let mut c = GaussianCloud::new(1);
    for _ in 0..3000 {
        let m = Vec3::new(r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0));
        let s = Vec3::new(r.range(0.01, 0.1), r.range(0.01, 0.1), r.range(0.005, 0.1));
        let q = Quat::from_xyzw(
            r.range(-1.0, 1.0),
            r.range(-1.0, 1.0),
            r.range(-1.0, 1.0),
            r.range(-1.0, 1.0),
        );
        c.push_activated(m, s, q, r.range(0.0, 1.0), Vec3::new(r.f(), r.f(), r.f()));
    }
    let cam = Camera::look_at(
        DVec3::new(0.4, -0.6, -3.5),
        DVec3::ZERO,
        DVec3::NEG_Y,
        60.0,
        96,
        72,
    )
    .unwrap();
    let a = GaussianTracer::new(c.clone(), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let b = GaussianTracer::new(c, BackendKind::Embree, BuildPreset::Medium).unwrap();
    let (fa, _) = a.render(&cam, &RenderOptions::default()).unwrap();
    let (fb, _) = b.render(&cam, &RenderOptions::default()).unwrap();
    // Identical candidates and arithmetic: bit-identical images.
    assert_eq!(fa.rgb, fb.rgb);
}

#[test]
fn rays_along_spokes_count_each_fan_once() {
    let c = Vec3::new(0.6, 0.1, 0.3);
    let (a0, a1) = (Vec3::X * 0.4, Vec3::new(0.0, 0.6, 0.6));
    let mut m = splatbridge_raytrace::model::Mesh {
        has_gaussian_ids: true,
        ..Default::default()
    };
    push_fan(&mut m, 3, c, a0, a1, 8, Vec3::ONE, 0.5);
    let scene = TriScene::single(m, blend_materials(), vec![]);
    let reference = Reference::new(&scene, 0.0);
    for b in [BackendKind::Obvhs, BackendKind::Embree] {
        let tr = MeshTracer::new(scene.clone(), b, BuildPreset::Medium).unwrap();
        let insts = tr.prepare(0.0);
        let mut compared = 0;
        for i in 0..120 {
            for j in 0..120 {
                // A grid whose lines i = 60, j = 60 and i = j pass along spokes of the fan.
                let target = c + a0 * (i as f32 / 60.0 - 1.0) + a1 * (j as f32 / 60.0 - 1.0);
                let o = DVec3::new(-1.0, -1.0, -3.0);
                let d = (target.as_dvec3() - o).normalize();
                let want = reference.trace(o, d);
                if !want.ambiguous.is_empty() {
                    continue;
                }
                compared += 1;
                assert_eq!(
                    tr.all_hits(&insts, o, d, 16).len(),
                    want.hits.len(),
                    "{b}: ({i}, {j})"
                );
            }
        }
        assert!(compared > 10_000);
    }
}
