//! Hard cases of the mesh mode: rays exactly through fan centres and interior edges (counted
//! once), three orthogonal fans of one Gaussian (three hits), more than k hits at one distance
//! (ordered by Gaussian id, none lost), 10,000 stacked layers (transmittance underflow),
//! grazing rays along fan planes, a camera inside a fan's plane.

mod common;

use common::*;
use glam::{DVec3, Vec3};
use splatbridge_raytrace::kbuffer::KBuffer;
use splatbridge_raytrace::model::{Mesh, TriScene};
use splatbridge_raytrace::{BackendKind, BuildPreset, MeshTracer, RenderOptions};
use splatbridge_scene::Camera;

fn scene_of(mesh: Mesh) -> TriScene {
    TriScene::single(mesh, blend_materials(), vec![])
}

fn ids() -> Mesh {
    Mesh {
        has_gaussian_ids: true,
        ..Mesh::default()
    }
}

#[test]
fn rays_through_centres_and_interior_edges_count_once() {
    let mut m = ids();
    // Axis-aligned fans in z = 0 with exactly representable vertices (n = 4: rim on the axes).
    push_fan(&mut m, 5, Vec3::ZERO, Vec3::X, Vec3::Y, 4, Vec3::ONE, 0.5);
    push_fan(
        &mut m,
        6,
        Vec3::new(3.0, 0.0, 0.0),
        Vec3::X,
        Vec3::Y,
        8,
        Vec3::ONE,
        0.5,
    );
    let scene = scene_of(m);
    let reference = Reference::new(&scene, 0.0);
    for b in backends() {
        let tr = MeshTracer::new(scene.clone(), b, BuildPreset::Medium).unwrap();
        let insts = tr.prepare(0.0);
        let rays = [
            // Centre of fan 5 (a vertex of all four triangles), head-on and oblique.
            (DVec3::new(0.0, 0.0, -2.0), DVec3::Z),
            (
                DVec3::new(-1.0, -0.5, -2.0),
                DVec3::new(1.0, 0.5, 2.0).normalize(),
            ),
            // A spoke (interior edge shared by two triangles).
            (DVec3::new(0.5, 0.0, -2.0), DVec3::Z),
            (DVec3::new(0.0, 0.25, 2.0), -DVec3::Z),
            // Centre of fan 6.
            (DVec3::new(3.0, 0.0, -1.0), DVec3::Z),
        ];
        for (o, d) in rays {
            let hits = tr.all_hits(&insts, o, d, 16);
            let want = reference.trace(o, d);
            assert_eq!(
                hits.len(),
                1,
                "{b}: ray {o} {d} must hit exactly one fan once, got {hits:?}"
            );
            assert_eq!(want.hits.len(), 1);
            assert_eq!(hits[0].gaussian, want.hits[0].gaussian);
        }
    }
}

#[test]
fn three_orthogonal_fans_through_the_centre_are_three_hits() {
    let mut m = ids();
    push_fan(&mut m, 1, Vec3::ZERO, Vec3::X, Vec3::Y, 8, Vec3::ONE, 0.5);
    push_fan(&mut m, 1, Vec3::ZERO, Vec3::Y, Vec3::Z, 8, Vec3::ONE, 0.5);
    push_fan(&mut m, 1, Vec3::ZERO, Vec3::Z, Vec3::X, 8, Vec3::ONE, 0.5);
    for b in backends() {
        let tr = MeshTracer::new(scene_of(m.clone()), b, BuildPreset::Medium).unwrap();
        let insts = tr.prepare(0.0);
        let d = DVec3::new(1.0, 2.0, 3.0).normalize();
        let hits = tr.all_hits(&insts, -d * 3.0, d, 16);
        assert_eq!(hits.len(), 3, "{b}: {hits:?}");
        let groups: std::collections::HashSet<u32> = hits.iter().map(|h| h.group).collect();
        assert_eq!(groups.len(), 3);
    }
}

#[test]
fn more_than_k_hits_at_one_distance_keep_id_order() {
    // 40 coplanar fans (distinct Gaussians) over the same point, shuffled ids; k = 16.
    let mut m = ids();
    let mut r = Rng(9);
    let mut gids: Vec<u32> = (0..40).map(|i| i * 37 % 101).collect();
    for i in (1..gids.len()).rev() {
        let j = (r.next_u64() % (i as u64 + 1)) as usize;
        gids.swap(i, j);
    }
    for (i, &g) in gids.iter().enumerate() {
        let rgb = Vec3::new(i as f32 / 40.0, 1.0 - i as f32 / 40.0, 0.5);
        push_fan(
            &mut m,
            g,
            Vec3::ZERO,
            Vec3::X * (1.0 + i as f32 * 0.01),
            Vec3::Y,
            8,
            rgb,
            0.3,
        );
    }
    let scene = scene_of(m);
    let reference = Reference::new(&scene, 0.0);
    let opts = RenderOptions {
        k: 16,
        min_transmittance: 1e-9,
        ..Default::default()
    };
    for b in backends() {
        let tr = MeshTracer::new(scene.clone(), b, BuildPreset::Medium).unwrap();
        let insts = tr.prepare(0.0);
        let (o, d) = (DVec3::new(0.1, 0.05, -1.0), DVec3::Z);
        let hits = tr.all_hits(&insts, o, d, 16);
        let got: Vec<u32> = hits.iter().map(|h| h.gaussian).collect();
        let mut want = gids.clone();
        want.sort();
        assert_eq!(got, want, "{b}: all 40 hits, in Gaussian-id order");
        let mut buf = KBuffer::new(16);
        let px = tr.trace(&insts, o, d, &opts, &mut buf);
        let (rgb, alpha) = reference.composite(&reference.trace(o, d), &opts);
        assert!(
            (px.rgb.as_dvec3() - rgb).abs().max_element() <= 1e-5,
            "{b}: {} vs {rgb}",
            px.rgb
        );
        assert!((px.alpha as f64 - alpha).abs() <= 1e-5);
        assert_eq!(px.traversals, 3, "40 hits with k = 16 take three rounds");
    }
}

#[test]
fn ten_thousand_layers_stop_finite() {
    for (alpha, expect_stop) in [(1e-3f32, true), (0.9, true), (1e-5, false)] {
        let mut m = ids();
        for i in 0..10_000u32 {
            push_fan(
                &mut m,
                i,
                Vec3::new(0.0, 0.0, i as f32 * 1e-3),
                Vec3::X,
                Vec3::Y,
                4,
                Vec3::new(0.2, 0.5, 0.9),
                alpha / 0.2 * 0.2,
            );
        }
        // Uniform alpha over the fan: rim alpha = centre alpha.
        for c in m.colors.iter_mut() {
            c.w = alpha;
        }
        let scene = scene_of(m);
        let reference = Reference::new(&scene, 0.0);
        let tr = MeshTracer::new(scene, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
        let insts = tr.prepare(0.0);
        let opts = RenderOptions::default();
        let mut buf = KBuffer::new(16);
        let (o, d) = (DVec3::new(0.1, 0.2, -1.0), DVec3::Z);
        let px = tr.trace(&insts, o, d, &opts, &mut buf);
        assert!(px.rgb.is_finite() && px.alpha.is_finite() && px.depth.is_finite());
        let (rgb, a) = reference.composite(&reference.trace(o, d), &opts);
        // 10,000 f32 products of (1 − α): relative error ~1e4 · 6e-8 ≈ 6e-4 of T at worst.
        assert!(
            (px.rgb.as_dvec3() - rgb).abs().max_element() <= 1e-3,
            "α {alpha}: {} vs {rgb}",
            px.rgb
        );
        assert!((px.alpha as f64 - a).abs() <= 1e-3);
        if expect_stop {
            assert!(1.0 - px.alpha < 1e-4, "α {alpha}: stops once T < 1e-4");
            assert!((px.hits as usize) < 10_000);
        } else {
            assert_eq!(
                px.hits, 10_000,
                "α {alpha}: T never reaches 1e-4, every layer is composited"
            );
        }
    }
}

#[test]
fn grazing_rays_and_camera_in_a_fan_plane_are_finite_and_match() {
    let mut m = ids();
    push_fan(&mut m, 1, Vec3::ZERO, Vec3::X, Vec3::Y, 8, Vec3::ONE, 0.8);
    push_fan(
        &mut m,
        2,
        Vec3::new(0.0, 0.0, 0.5),
        Vec3::X,
        Vec3::Z,
        8,
        Vec3::new(1.0, 0.0, 0.0),
        0.6,
    );
    let scene = scene_of(m);
    let reference = Reference::new(&scene, 0.0);
    for b in backends() {
        let tr = MeshTracer::new(scene.clone(), b, BuildPreset::Medium).unwrap();
        let insts = tr.prepare(0.0);
        // Exactly in the plane z = 0 of fan 1: no hit on it (a zero-area crossing).
        let hits = tr.all_hits(&insts, DVec3::new(-3.0, 0.1, 0.0), DVec3::X, 16);
        assert!(hits.iter().all(|h| h.gaussian != 1), "{b}: {hits:?}");
        // Nearly grazing: one hit, like the reference.
        let d = DVec3::new(1.0, 0.0, 1e-4).normalize();
        let o = DVec3::new(-1000.0 * d.x, 0.1, -1000.0 * d.z + 1e-9);
        let got = tr.all_hits(&insts, o, d, 16);
        let want = reference.trace(o, d);
        assert_eq!(
            got.iter().map(|h| h.gaussian).collect::<Vec<_>>(),
            want.hits.iter().map(|h| h.gaussian).collect::<Vec<_>>()
        );
        // A camera in fan 1's plane looking along it: every pixel finite and like the reference.
        let cam = Camera::look_at(
            DVec3::new(-3.0, 0.0, 0.0),
            DVec3::ZERO,
            DVec3::NEG_Y,
            60.0,
            33,
            25,
        )
        .unwrap();
        let (f, _) = tr.render(&cam, 0.0, &RenderOptions::default()).unwrap();
        assert!(f.is_finite());
        for j in 0..cam.height {
            for i in 0..cam.width {
                let (o, d) = (cam.centre, cam.ray_dir(i as f64 + 0.5, j as f64 + 0.5));
                let want = reference.trace(o, d);
                if !want.ambiguous.is_empty() {
                    continue;
                }
                let (rgb, _) = reference.composite(&want, &RenderOptions::default());
                let px = f.rgb_at(i, j);
                for c in 0..3 {
                    assert!((px[c] as f64 - rgb[c]).abs() <= 1e-5, "{b}: ({i}, {j})");
                }
            }
        }
    }
}

#[test]
fn empty_scene_and_degenerate_triangles_render_background() {
    let mut m = ids();
    // A zero-area triangle and a fan collapsed to a line.
    m.positions = vec![Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
    m.colors = vec![glam::Vec4::ONE; 5];
    m.tris = vec![[0, 1, 2], [0, 3, 4]];
    m.tri_material = vec![0, 0].into();
    m.tri_gaussian = vec![0, 1];
    for scene in [scene_of(m), TriScene::default()] {
        let tr = MeshTracer::new(scene, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
        let cam = Camera::look_at(
            DVec3::new(0.0, 0.0, -3.0),
            DVec3::ZERO,
            DVec3::NEG_Y,
            60.0,
            16,
            12,
        )
        .unwrap();
        let opts = RenderOptions {
            background: Vec3::new(0.25, 0.5, 0.75),
            ..Default::default()
        };
        let (f, s) = tr.render(&cam, 0.0, &opts).unwrap();
        assert!(f.is_finite());
        assert_eq!(s.hits, 0);
        assert_eq!(f.rgb_at(3, 3), [0.25, 0.5, 0.75]);
    }
}

#[test]
fn axis_aligned_rays_with_negative_zero_components_hit() {
    // Direction components of −0.0 (e.g. −Z built as (−0, −0, −1)) and components far below
    // f32::EPSILON must not change what the BVH visits.
    let mut m = ids();
    push_fan(&mut m, 1, Vec3::ZERO, Vec3::X, Vec3::Y, 8, Vec3::ONE, 0.5);
    for b in backends() {
        let tr = MeshTracer::new(scene_of(m.clone()), b, BuildPreset::Medium).unwrap();
        let insts = tr.prepare(0.0);
        for d in [
            DVec3::new(-0.0, -0.0, -1.0),
            DVec3::new(0.0, 0.0, -1.0),
            DVec3::new(1e-12, -1e-12, -1.0).normalize(),
        ] {
            for o in [DVec3::new(0.1, 0.2, 2.0), DVec3::new(-0.3, 0.0, 2.0)] {
                assert_eq!(tr.all_hits(&insts, o, d, 16).len(), 1, "{b}: {o} {d}");
            }
        }
        // Nearly grazing with a component below f32::EPSILON, origin just off the plane: the
        // plane is reached after ~1000 units, still inside the fan.
        let d = DVec3::new(1.0, 0.0, 1e-9).normalize();
        let o = DVec3::new(-0.5 - 1e-6 / 1e-9 * d.x, 0.1, -1e-6);
        let reference = Reference::new(&scene_of(m.clone()), 0.0);
        let want = reference.trace(o, d).hits.len();
        assert_eq!(
            tr.all_hits(&insts, o, d, 16).len(),
            want,
            "{b}: nearly grazing"
        );
    }
}

#[test]
fn hits_right_at_the_origin_and_resumed_rounds_are_kept() {
    // obvhs skips nodes the ray leaves within 1e-4 of its origin; geometry 5e-5 ahead of the
    // ray (a camera touching a splat, a shadow ray leaving a surface) must still be hit, and
    // coplanar hits at a resumed round's start distance must not be lost.
    let mut m = ids();
    push_fan(&mut m, 1, Vec3::ZERO, Vec3::X, Vec3::Y, 8, Vec3::ONE, 0.5);
    for i in 0..40u32 {
        push_fan(
            &mut m,
            10 + i,
            Vec3::new(0.0, 0.0, 0.5),
            Vec3::X * (1.0 + i as f32 * 0.01),
            Vec3::Y,
            8,
            Vec3::ONE,
            0.1,
        );
    }
    for b in backends() {
        let tr = MeshTracer::new(scene_of(m.clone()), b, BuildPreset::Medium).unwrap();
        let insts = tr.prepare(0.0);
        for dz in [5e-5, 1e-6] {
            let hits = tr.all_hits(&insts, DVec3::new(0.1, 0.05, -dz), DVec3::Z, 4);
            assert_eq!(hits.len(), 41, "{b}: origin {dz} before the first fan");
            assert_eq!(hits[0].gaussian, 1);
        }
    }
}

#[test]
fn invisible_layers_change_nothing_and_take_no_k_buffer_slots() {
    // 12 visible fans stacked along z with an invisible one (α = 0 at every vertex, as the
    // texture profile's quad corners are) between each pair. Compositing keeps only α > 0 hits
    // in the k-buffer, so the scene renders bit-identically with and without the invisible
    // layers, in the same number of rounds, for any k (and the same image for every k);
    // enumeration still reports them.
    let (mut with, mut without) = (ids(), ids());
    for i in 0..12u32 {
        let z = i as f32 * 0.1;
        let rgb = Vec3::new(i as f32 / 12.0, 0.5, 1.0 - i as f32 / 12.0);
        for m in [&mut with, &mut without] {
            push_fan(
                m,
                2 * i,
                Vec3::new(0.0, 0.0, z),
                Vec3::X,
                Vec3::Y,
                8,
                rgb,
                0.3,
            );
        }
        push_fan(
            &mut with,
            2 * i + 1,
            Vec3::new(0.0, 0.0, z + 0.05),
            Vec3::X,
            Vec3::Y,
            8,
            Vec3::ONE,
            0.0,
        );
    }
    let cam = Camera::look_at(
        DVec3::new(0.1, 0.05, -2.0),
        DVec3::ZERO,
        DVec3::NEG_Y,
        40.0,
        12,
        9,
    )
    .unwrap();
    for b in backends() {
        let tw = MeshTracer::new(scene_of(with.clone()), b, BuildPreset::Medium).unwrap();
        let to = MeshTracer::new(scene_of(without.clone()), b, BuildPreset::Medium).unwrap();
        let mut first: Option<Vec<f32>> = None;
        for k in [1, 3, 16] {
            let opts = RenderOptions {
                k,
                ..Default::default()
            };
            let (fw, sw) = tw.render(&cam, 0.0, &opts).unwrap();
            let (fo, so) = to.render(&cam, 0.0, &opts).unwrap();
            // k changes the rounds, never the image (hits are composited in key order).
            assert_eq!(
                &fw.rgb,
                first.get_or_insert_with(|| fw.rgb.clone()),
                "{b}, k = {k}"
            );
            assert_eq!(fw.rgb, fo.rgb, "{b}, k = {k}");
            assert_eq!(fw.alpha, fo.alpha, "{b}, k = {k}");
            assert_eq!(
                sw.traversals, so.traversals,
                "{b}, k = {k}: invisible hits took slots"
            );
            assert!(so.hits > 0);
        }
        let insts = tw.prepare(0.0);
        let all = tw.all_hits(&insts, DVec3::new(0.1, 0.05, -2.0), DVec3::Z, 4);
        assert_eq!(all.len(), 24, "{b}: enumeration reports every crossing");
    }
}
