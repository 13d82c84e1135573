//! Synthetic scenes built in memory for the converter's tests.
#![allow(dead_code)]

use glam::{DVec3, Quat, Vec3};
use splatbridge_scene::dynamic::{DynamicScene, Pose, PoseKey, SceneObject, TimeRange, Track};
use splatbridge_scene::rng::Rng;
use splatbridge_scene::{Camera, GaussianCloud};

/// A deterministic cloud: `n` Gaussians in a box, mixed flat and volumetric shapes,
/// opacities from 0.001 to 1 (some below 1/255), SH degree `deg` with random rest terms.
pub fn cloud(n: usize, deg: u8, seed: u64) -> GaussianCloud {
    let mut rng = Rng::new(seed);
    let mut c = GaussianCloud::with_capacity(deg, n);
    for i in 0..n {
        let mean = Vec3::new(
            rng.f32() * 4.0 - 2.0,
            rng.f32() * 2.0 - 1.0,
            rng.f32() * 4.0 - 2.0,
        );
        let flat = i % 3 != 0;
        let s0 = 0.02 + 0.1 * rng.f32();
        let s1 = s0 * (0.4 + 0.6 * rng.f32());
        let s2 = if flat {
            s1 * 0.05
        } else {
            s1 * (0.5 + 0.5 * rng.f32())
        };
        let q = Quat::from_xyzw(
            rng.f32() - 0.5,
            rng.f32() - 0.5,
            rng.f32() - 0.5,
            rng.f32() - 0.5,
        );
        let o = if i % 17 == 0 {
            0.002
        } else {
            0.05 + 0.95 * rng.f32()
        };
        let rgb = Vec3::new(rng.f32(), rng.f32(), rng.f32());
        c.push_activated(mean, Vec3::new(s0, s1, s2), q, o, rgb);
        let k = c.coeffs();
        for j in 1..k {
            c.sh[i * k + j] = Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5) * 0.2;
        }
    }
    c
}

/// Static Gaussians, two animated objects (one moving and turning, one with keys inside
/// the time range only), two cameras; time 0..2 s at 10 fps; COLMAP-style y-down world.
pub fn street(n_static: usize) -> DynamicScene {
    let mut s = DynamicScene::from_static(cloud(n_static, 3, 1));
    s.time = TimeRange {
        start: 0.0,
        end: 2.0,
        fps: 10.0,
    };
    let key = |t: f64, x: f32, yaw: f32| PoseKey {
        t,
        pose: Pose {
            translation: Vec3::new(x, 0.0, 1.0),
            rotation: Quat::from_rotation_y(yaw),
        },
    };
    s.objects.push(SceneObject {
        name: "car".into(),
        gaussians: cloud(200, 3, 2),
        track: Track {
            keys: vec![key(0.0, -2.0, 0.0), key(1.0, 0.0, 1.5), key(2.0, 2.0, 3.0)],
        },
    });
    s.objects.push(SceneObject {
        name: "cyclist".into(),
        gaussians: cloud(100, 3, 3),
        track: Track {
            keys: vec![key(0.5, 1.0, -0.5), key(1.5, -1.0, 2.9)],
        },
    });
    for (i, eye) in [DVec3::new(0.0, -1.0, -6.0), DVec3::new(5.0, -2.0, -3.0)]
        .iter()
        .enumerate()
    {
        let mut c = Camera::look_at(*eye, DVec3::ZERO, DVec3::NEG_Y, 50.0, 320, 240).unwrap();
        c.name = format!("cam{i}");
        s.cameras.push(c);
    }
    s
}

/// The shared tools folder.
pub fn tools() -> std::path::PathBuf {
    // Tests that call this are ignored unless `build.rs` found the wrapper, node and npm
    // (`cfg(gltf_tools)`).
    std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/tools")).to_path_buf()
}

pub fn real(name: &str) -> std::path::PathBuf {
    // Tests that call this are ignored unless `build.rs` found the folder (`cfg(real_data)`).
    std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/data/real"
    ))
    .join(name)
}
