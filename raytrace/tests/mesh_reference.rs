//! The mesh mode against the brute-force f64 reference (tests/common): same hit sets in the
//! same order and the same image (≤ 1e-5) on synthetic fan scenes, static and instanced, for
//! every compiled-in backend.

mod common;

use common::*;
use glam::{DQuat, DVec3, Vec3};
use splatbridge_raytrace::model::{Channel, ChannelPath, Interpolation, Node, TriScene};
use splatbridge_raytrace::RenderOptions;
use splatbridge_scene::Camera;

fn look(eye: DVec3, target: DVec3, w: u32, h: u32) -> Camera {
    Camera::look_at(eye, target, DVec3::NEG_Y, 50.0, w, h).unwrap()
}

#[test]
fn random_fans_match_reference() {
    let mesh = random_fans(1, 300, 1.0, Vec3::ZERO);
    let scene = TriScene::single(mesh, blend_materials(), vec![]);
    for b in backends() {
        for k in [1, 4, 16] {
            let opts = RenderOptions {
                k,
                ..Default::default()
            };
            compare(
                &scene,
                0.0,
                &look(DVec3::new(0.3, -0.5, -4.0), DVec3::ZERO, 48, 36),
                b,
                &opts,
            );
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
        compare(
            &scene,
            0.0,
            &look(c + DVec3::new(0.2, -0.4, -4.0), c, 40, 30),
            b,
            &RenderOptions::default(),
        );
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
            compare(
                &scene,
                t,
                &look(DVec3::new(0.5, -0.8, -4.0), DVec3::ZERO, 40, 30),
                b,
                &RenderOptions::default(),
            );
        }
    }
}
