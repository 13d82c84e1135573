//! The top-level BVH over a scene's instances (`instances::Instances`) against the
//! brute-force f64 reference (tests/common: every triangle of every instance tested, hits
//! sorted) and against visiting every instance in order: same hit sets, and images equal bit
//! for bit to the one-by-one traversal, on many overlapping and disjoint nodes (static, scaled
//! and moving), for every compiled-in backend and at 1, 2 and 3 threads.

mod common;

use common::*;
use glam::{DQuat, DVec3, Vec3};
use splatbridge_raytrace::kbuffer::KBuffer;
use splatbridge_raytrace::mesh_tracer::Instances;
use splatbridge_raytrace::model::{Channel, ChannelPath, Interpolation, Node, TriScene};
use splatbridge_raytrace::{BackendKind, BuildPreset, MeshTracer, RenderOptions};
use splatbridge_scene::Camera;

fn look(eye: DVec3, target: DVec3, w: u32, h: u32) -> Camera {
    Camera::look_at(eye, target, DVec3::NEG_Y, 50.0, w, h).unwrap()
}

/// A 4×3 grid of chunks (as the viewer layout writes them), two of them sharing one mesh,
/// one chunk placed twice on top of another (exact ties between instances), a scaled parent,
/// and a moving node.
fn chunked_scene() -> TriScene {
    let mut meshes = Vec::new();
    let mut nodes = Vec::new();
    for c in 0..12u64 {
        meshes.push(random_fans(10 + c, 40, 0.6, Vec3::ZERO));
        let (x, y) = ((c % 4) as f64 - 1.5, (c / 4) as f64 - 1.0);
        nodes.push(Node {
            mesh: Some(c as usize),
            translation: DVec3::new(x * 1.1, y * 1.1, 0.2 * (c % 3) as f64),
            ..Node::default()
        });
    }
    // The same mesh at the same place twice: every hit ties with its twin but the instance.
    nodes.push(Node {
        mesh: Some(5),
        translation: nodes[5].translation,
        ..Node::default()
    });
    // A chunk under a scaled parent.
    nodes.push(Node {
        mesh: Some(3),
        parent: Some(nodes.len() + 1),
        translation: DVec3::new(0.1, 0.0, -0.3),
        ..Node::default()
    });
    nodes.push(Node {
        scale: DVec3::new(1.0, 1.4, 0.8),
        ..Node::default()
    });
    // A moving chunk.
    meshes.push(random_fans(99, 30, 0.4, Vec3::ZERO));
    let moving = nodes.len();
    nodes.push(Node {
        mesh: Some(meshes.len() - 1),
        ..Node::default()
    });
    let channels = vec![
        Channel {
            node: moving,
            path: ChannelPath::Translation,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 1.0],
            values: vec![[-1.5, 0.0, -0.5, 0.0], [1.5, 0.3, 0.5, 0.0]],
        },
        Channel {
            node: moving,
            path: ChannelPath::Rotation,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 1.0],
            values: vec![
                DQuat::IDENTITY.to_array(),
                DQuat::from_rotation_y(2.0).to_array(),
            ],
        },
    ];
    TriScene {
        meshes,
        nodes,
        channels,
        materials: blend_materials(),
        ..TriScene::default()
    }
}

/// Every pixel through `insts`, one ray at a time.
fn render_with(tracer: &MeshTracer, insts: &Instances, cam: &Camera, k: usize) -> Vec<u32> {
    let opts = RenderOptions {
        k,
        ..Default::default()
    };
    let mut buf = KBuffer::new(k);
    let mut out = Vec::new();
    for j in 0..cam.height {
        for i in 0..cam.width {
            let (o, d) = (cam.centre, cam.ray_dir(i as f64 + 0.5, j as f64 + 0.5));
            let p = tracer.trace(insts, o, d, &opts, &mut buf);
            out.extend([p.rgb.x, p.rgb.y, p.rgb.z, p.alpha, p.depth].map(f32::to_bits));
        }
    }
    out
}

#[test]
fn top_level_matches_reference() {
    let scene = chunked_scene();
    let cam = look(DVec3::new(0.4, -0.7, -5.0), DVec3::ZERO, 48, 36);
    for b in backends() {
        for t in [0.0, 0.6] {
            for k in [1, 16] {
                let opts = RenderOptions {
                    k,
                    ..Default::default()
                };
                compare(&scene, t, &cam, b, &opts);
            }
        }
    }
}

#[test]
fn top_level_matches_every_instance_in_order() {
    let scene = chunked_scene();
    for b in backends() {
        let tracer = MeshTracer::new(scene.clone(), b, BuildPreset::Medium).unwrap();
        for (t, eye) in [
            (0.0, DVec3::new(0.4, -0.7, -5.0)),
            (0.6, DVec3::new(-2.0, 0.5, 3.0)),
            // Inside the grid: instances behind the camera and around it.
            (0.3, DVec3::new(0.0, 0.0, 0.1)),
        ] {
            let cam = look(eye, DVec3::new(0.2, 0.1, 0.0), 40, 30);
            let top = tracer.prepare(t);
            assert!(top.has_top_level(), "{} instances", top.len());
            let linear = Instances::linear(tracer.prepare_list(t));
            for k in [1, 3, 16] {
                let a = render_with(&tracer, &top, &cam, k);
                let b2 = render_with(&tracer, &linear, &cam, k);
                assert_eq!(a, b2, "{b}: t {t}, k {k}: images differ");
                assert!(a.iter().any(|&v| v != 0), "nothing drawn");
            }
        }
    }
}

#[test]
fn images_do_not_depend_on_threads() {
    let scene = chunked_scene();
    let tracer = MeshTracer::new(scene, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let cam = look(DVec3::new(0.4, -0.7, -5.0), DVec3::ZERO, 64, 48);
    let frames: Vec<Vec<u32>> = [1, 2, 3]
        .iter()
        .map(|&n| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap();
            pool.install(|| {
                bits(
                    &tracer
                        .render(&cam, 0.6, &RenderOptions::default())
                        .unwrap()
                        .0,
                )
            })
        })
        .collect();
    assert_eq!(frames[0], frames[1]);
    assert_eq!(frames[0], frames[2]);
}
