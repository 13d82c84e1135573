//! The mesh tracer's structure over runs of triangles (`MeshTracer::with_boxes`, what obvhs
//! builds by default to bound its build memory) against the structure over single triangles,
//! the reference: the same hits, bit for bit, in the same order, and the same image, for run
//! lengths that do and do not divide the triangle count, static and instanced.

mod common;

use common::*;
use glam::{DVec3, Vec3};
use splatbridge_raytrace::model::{Node, TriScene};
use splatbridge_raytrace::{BackendKind, BuildPreset, MeshTracer, RenderOptions};
use splatbridge_scene::Camera;

fn look(eye: DVec3, target: DVec3, w: u32, h: u32) -> Camera {
    Camera::look_at(eye, target, DVec3::NEG_Y, 50.0, w, h).unwrap()
}

/// Every hit of every pixel, as bits, and the image's bits.
fn trace_all(tracer: &MeshTracer, cam: &Camera, opts: &RenderOptions) -> (Vec<u64>, Vec<u32>) {
    let insts = tracer.prepare(0.0);
    let mut hits = Vec::new();
    for j in 0..cam.height {
        for i in 0..cam.width {
            let (o, d) = (cam.centre, cam.ray_dir(i as f64 + 0.5, j as f64 + 0.5));
            for h in tracer.all_hits(&insts, o, d, opts.k) {
                hits.push(
                    (u64::from(h.t.to_bits()) << 32)
                        ^ (u64::from(h.gaussian) << 16)
                        ^ u64::from(h.payload.tri),
                );
                hits.extend(h.payload.bary.map(|b| u64::from(b.to_bits())));
                hits.push(u64::from(h.group) << 8 | u64::from(h.instance));
            }
            hits.push(u64::MAX);
        }
    }
    let (frame, _) = tracer.render(cam, 0.0, opts).unwrap();
    let mut px: Vec<u32> = frame.rgb.iter().map(|v| v.to_bits()).collect();
    px.extend(frame.alpha.iter().map(|v| v.to_bits()));
    px.extend(frame.depth.iter().map(|v| v.to_bits()));
    (hits, px)
}

fn check(scene: &TriScene, cam: &Camera) {
    let opts = RenderOptions {
        k: 4,
        ..Default::default()
    };
    let single = MeshTracer::with_boxes(
        scene.clone(),
        BackendKind::Obvhs,
        BuildPreset::Medium,
        Some(1),
    )
    .unwrap();
    let (want_hits, want_px) = trace_all(&single, cam, &opts);
    // A test that can fail: the scene must actually be hit, several times per ray on average
    // (five words per hit, one per pixel).
    let pixels = (cam.width * cam.height) as usize;
    let hits = (want_hits.len() - pixels) / 5;
    assert!(hits > 2 * pixels, "too few hits ({hits}) to compare");
    for per_box in [2, 3, 8, 64] {
        let runs = MeshTracer::with_boxes(
            scene.clone(),
            BackendKind::Obvhs,
            BuildPreset::Medium,
            Some(per_box),
        )
        .unwrap();
        let (hits, px) = trace_all(&runs, cam, &opts);
        assert!(hits == want_hits, "{per_box} per box: hits differ");
        assert!(px == want_px, "{per_box} per box: image differs");
    }
    // The default constructor is one of the above.
    let default = MeshTracer::new(scene.clone(), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    assert!(trace_all(&default, cam, &opts) == (want_hits, want_px));
}

#[test]
fn runs_of_triangles_hit_what_single_triangles_hit() {
    // 3001 fans: the triangle count is not a multiple of any run length above.
    let mesh = random_fans(7, 3001, 1.0, Vec3::ZERO);
    let scene = TriScene::single(mesh, blend_materials(), vec![]);
    check(
        &scene,
        &look(DVec3::new(0.3, -0.5, -4.0), DVec3::ZERO, 24, 18),
    );
}

#[test]
fn runs_of_triangles_in_instances_hit_what_single_triangles_hit() {
    let a = random_fans(8, 1500, 1.0, Vec3::ZERO);
    let b = random_fans(9, 700, 0.5, Vec3::new(0.2, 0.1, 0.0));
    let mut scene = TriScene {
        meshes: vec![a, b],
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
            scale: DVec3::new(1.0, 1.5, 1.0),
            translation: DVec3::new(0.1, 0.0, -0.3),
            ..Node::default()
        },
    ];
    check(
        &scene,
        &look(DVec3::new(-0.2, 0.4, -4.0), DVec3::ZERO, 24, 18),
    );
}

/// Runs lengthen only on meshes past a million boxes' worth of triangles, and never past the
/// cap; the lengths themselves are checked for identical hits above.
#[test]
fn run_length_grows_only_on_very_large_meshes() {
    use splatbridge_raytrace::mesh_tracer::{
        run_length, BOXES_PER_MESH, MAX_TRIANGLES_PER_BOX, TRIANGLES_PER_BOX,
    };
    assert_eq!(run_length(0), TRIANGLES_PER_BOX);
    assert_eq!(run_length(1000), TRIANGLES_PER_BOX);
    assert_eq!(
        run_length(TRIANGLES_PER_BOX * BOXES_PER_MESH),
        TRIANGLES_PER_BOX
    );
    assert_eq!(
        run_length(TRIANGLES_PER_BOX * BOXES_PER_MESH + 1),
        TRIANGLES_PER_BOX + 1
    );
    // The 37 M-triangle rings export the constant was measured on: runs of 36.
    assert_eq!(run_length(36_856_560), 36);
    assert_eq!(run_length(usize::MAX / 2), MAX_TRIANGLES_PER_BOX);
}
