//! The tile path's skipping of instances the camera cannot see (`mesh_tiles::box_unseen`)
//! against binning every instance's triangles: the same records, bit for bit and in the same
//! order, on many small nodes scattered around and behind the camera and placed on the image's
//! edges to within a fraction of a pixel (where the rectangle margins decide), seen through
//! whole views, windows of a larger view (the principal point moved off the image, as
//! distillation records them) and a camera inside the scene; and images through the skipping
//! equal to the brute-force reference's. Also the records binning drops because no sample of
//! the image can pass their pre-test (`mesh_bin::Samples`): none of them is crossed by a
//! sample's ray, and images over sub-pixel triangles equal the brute-force reference's.

use glam::{DQuat, DVec3, Vec3};
use splatbridge_scene::Camera;

use super::footprint::sample_offsets;
use super::mesh_bin::TileLists;
use super::mesh_tile_tests::{
    assert_image_is_reference, bits, blend, random_mesh, reference_image, tracer, Rng,
};
use super::mesh_tiles::local_ray;
use super::model::{Node, TriScene};
use super::render::RenderOptions;

/// A 64×48 camera at the origin looking down +z with a 60° vertical field of view.
fn main_camera() -> Camera {
    Camera::look_at(DVec3::ZERO, DVec3::Z, DVec3::NEG_Y, 60.0, 64, 48).unwrap()
}

/// Three small meshes (half-sizes 0.3, 0.15 and 0.02) under `n` nodes: a third scattered in a
/// box around the camera (many behind it or beside it), the rest placed so that their centre
/// projects near the main camera's image edges (within three pixels either side), at depths
/// 1–20, some rotated and scaled.
fn scattered(seed: u64, n: usize) -> TriScene {
    let mut r = Rng(seed);
    let meshes = vec![
        random_mesh(seed, 12, 0.3, Vec3::ZERO, true),
        random_mesh(seed ^ 0x55, 8, 0.15, Vec3::ZERO, false),
        random_mesh(seed ^ 0xAA, 6, 0.02, Vec3::ZERO, true),
    ];
    let cam = main_camera();
    let (w, h) = (cam.width as f32, cam.height as f32);
    let mut nodes = Vec::with_capacity(n);
    for k in 0..n {
        let translation = if k % 3 == 0 {
            DVec3::new(
                r.range(-12.0, 12.0) as f64,
                r.range(-9.0, 9.0) as f64,
                r.range(-8.0, 14.0) as f64,
            )
        } else {
            // A pixel near an edge: one coordinate within 3 px of 0 or of the side.
            let (mut u, mut v) = (r.range(-3.0, w + 3.0), r.range(-3.0, h + 3.0));
            match k % 4 {
                0 => u = r.range(-3.0, 3.0),
                1 => u = w + r.range(-3.0, 3.0),
                2 => v = r.range(-3.0, 3.0),
                _ => v = h + r.range(-3.0, 3.0),
            }
            let z = r.range(1.0, 20.0) as f64;
            DVec3::new(
                (u as f64 - cam.cx) / cam.fx * z,
                (v as f64 - cam.cy) / cam.fy * z,
                z,
            )
        };
        let (rotation, scale) = if k % 5 == 0 {
            (
                DQuat::from_euler(
                    glam::EulerRot::XYZ,
                    r.range(-3.0, 3.0) as f64,
                    r.range(-3.0, 3.0) as f64,
                    0.3,
                ),
                DVec3::new(1.0, r.range(0.5, 2.0) as f64, 0.7),
            )
        } else {
            (DQuat::IDENTITY, DVec3::ONE)
        };
        nodes.push(Node {
            mesh: Some(k % meshes.len()),
            translation,
            rotation,
            scale,
            ..Node::default()
        });
    }
    TriScene {
        meshes,
        materials: blend(),
        nodes,
        colors_linear: true,
        ..TriScene::default()
    }
}

/// The main camera, 24×20 windows of it (its rays, the principal point shifted by whole
/// pixels, one corner window and one beyond the right edge's content), a narrow view, and a
/// camera inside the scattered box looking back.
fn cameras() -> Vec<Camera> {
    let main = main_camera();
    let window = |x0: f64, y0: f64| Camera {
        width: 24,
        height: 20,
        cx: main.cx - x0,
        cy: main.cy - y0,
        name: format!("window at {x0},{y0}"),
        ..main.clone()
    };
    vec![
        main.clone(),
        window(0.0, 0.0),
        window(40.0, 28.0),
        window(20.0, 10.0),
        Camera::look_at(
            DVec3::ZERO,
            DVec3::new(0.3, 0.1, 1.0),
            DVec3::NEG_Y,
            10.0,
            40,
            30,
        )
        .unwrap(),
        Camera::look_at(
            DVec3::new(2.0, 1.0, 6.0),
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::NEG_Y,
            80.0,
            33,
            21,
        )
        .unwrap(),
    ]
}

#[test]
fn unseen_instances_skip_only_triangles_never_binned() {
    let mut skipped = 0;
    let mut instances = 0;
    for seed in [3u64, 17, 40] {
        let tracer = tracer(scattered(seed, 150));
        let insts = tracer.prepare_list(0.0);
        for cam in cameras() {
            let fast = TileLists::build(&tracer, &insts, &cam, &sample_offsets(1));
            let all = TileLists::build_with(&tracer, &insts, &cam, &sample_offsets(1), false);
            assert_eq!(all.skipped, 0);
            let (a, b) = (fast.records(), all.records());
            let first = a.iter().zip(&b).position(|(x, y)| x != y);
            assert!(
                a.len() == b.len() && first.is_none(),
                "seed {seed}, {}: {} records against {}, first difference at {first:?}",
                cam.name,
                a.len(),
                b.len()
            );
            skipped += fast.skipped;
            instances += insts.len();
        }
    }
    // The skipping must do something on these scenes, or the equality above shows nothing:
    // most nodes lie off every window and a third off the main view.
    assert!(skipped * 3 > instances, "{skipped} of {instances} skipped");
}

#[test]
fn windows_through_skipping_equal_brute_force() {
    let opts = RenderOptions::default();
    let tracer = tracer(scattered(5, 90));
    for cam in cameras() {
        let (img, _) = tracer.render(&cam, 0.0, &opts).unwrap();
        let want = reference_image(&tracer, &cam, &opts);
        assert_eq!(bits(&img), bits(&want), "{}", cam.name);
    }
}

/// Twelve nodes of one mesh of small fans (40 fans of 6 triangles each way, spread over ±0.5,
/// sized 0.02–0.16 of it), at depths 2–10 across the main view: most triangles are under a
/// pixel on screen, many between the pixel centres.
fn dust(seed: u64) -> TriScene {
    let mut r = Rng(seed);
    let cam = main_camera();
    let nodes = (0..12)
        .map(|_| {
            let (u, v, z) = (
                r.range(8.0, 56.0) as f64,
                r.range(6.0, 42.0) as f64,
                r.range(2.0, 10.0) as f64,
            );
            Node {
                mesh: Some(0),
                translation: DVec3::new((u - cam.cx) / cam.fx * z, (v - cam.cy) / cam.fy * z, z),
                ..Node::default()
            }
        })
        .collect();
    TriScene {
        meshes: vec![random_mesh(seed, 40, 0.5, Vec3::ZERO, true)],
        materials: blend(),
        nodes,
        colors_linear: true,
        ..TriScene::default()
    }
}

/// The records binning drops for want of a sample are crossed by no sample's ray (the
/// watertight test over every sample of every pixel, for one and four samples a pixel), a
/// fair share is dropped (else the check shows nothing), and images at 1 and 4 samples a pixel
/// equal the brute-force reference's.
#[test]
fn triangles_between_the_samples_are_never_crossed() {
    let cam = main_camera();
    let (mut dropped, mut total) = (0usize, 0usize);
    for seed in [4u64, 9] {
        let tracer = tracer(dust(seed));
        let insts = tracer.prepare_list(0.0);
        // Sixteen samples a pixel take four offsets an axis: no record is dropped for them.
        let all = TileLists::build(&tracer, &insts, &cam, &sample_offsets(16)).records();
        for spp in [1, 4] {
            let offsets = sample_offsets(spp);
            let kept = TileLists::build(&tracer, &insts, &cam, &offsets).records();
            let kept: std::collections::HashSet<(u32, u32)> =
                kept.iter().map(|r| (r[5], r[6])).collect();
            for rec in all.iter().filter(|r| !kept.contains(&(r[5], r[6]))) {
                dropped += 1;
                let inst = &insts[rec[5] as usize];
                let (mesh, blas) = (&tracer.scene.meshes[inst.mesh], &tracer.blas[inst.mesh]);
                let verts = blas.triangle(&mesh.positions, mesh.tris[rec[6] as usize]);
                // The pixels whose samples lie within 2 px of its rectangle (the walk's
                // pre-test, whose soundness the brute-force tile tests check, admits none
                // beyond it).
                let r = [rec[1], rec[2], rec[3], rec[4]].map(f32::from_bits);
                let span = |lo: f32, hi: f32, n: u32| {
                    let lo = (lo as f64 - 2.0).floor().max(0.0) as u32;
                    lo.min(n)..((hi as f64 + 2.0).ceil().max(0.0) as u32).min(n)
                };
                for j in span(r[1], r[3], cam.height) {
                    for i in span(r[0], r[2], cam.width) {
                        for &(du, dv) in &offsets {
                            let (o, d) =
                                crate::render::camera_ray(&cam, i as f64 + du, j as f64 + dv);
                            if let Some(r) = local_ray(&tracer, inst, o, d) {
                                assert!(
                                    r.wray.cover(verts[0], verts[1], verts[2]).is_err(),
                                    "seed {seed}, {spp} spp: triangle {} of instance {} dropped, \
                                     but the ray of pixel ({i}, {j}) + ({du}, {dv}) crosses it",
                                    rec[6],
                                    rec[5]
                                );
                            }
                        }
                    }
                }
            }
            total += all.len();
            assert_image_is_reference(&tracer, &cam, spp, &format!("seed {seed}"));
        }
    }
    // Measured: 9,116 of 13,216 records (69 %) over both scenes and sample counts; a fifth is
    // far below it.
    assert!(dropped * 5 > total, "{dropped} of {total} records dropped");
}
