//! What the tileset tests share: a street-like test cloud and a directory's files.

#![allow(dead_code)]

use std::path::Path;

use glam::{Quat, Vec3};
use splatbridge_scene::rng::Rng;
use splatbridge_scene::GaussianCloud;

/// Three clusters of small Gaussians along a street-like strip (x 0..40, thin in y and z),
/// SH degree 1: several leaves at budgets of a few hundred.
pub fn clusters_seeded(n: usize, seed: u64) -> GaussianCloud {
    let mut rng = Rng::new(seed);
    let mut c = GaussianCloud::new(1);
    let centres = [
        Vec3::new(2.0, -0.5, 3.0),
        Vec3::new(20.0, -1.0, 2.0),
        Vec3::new(38.0, 0.0, 4.0),
    ];
    for i in 0..n {
        let m = centres[i % 3] + 1.5 * Vec3::new(rng.normal(), 0.3 * rng.normal(), rng.normal());
        let s = Vec3::new(
            rng.range(0.03, 0.12),
            rng.range(0.03, 0.12),
            rng.range(0.01, 0.05),
        );
        let q = Quat::from_xyzw(rng.normal(), rng.normal(), rng.normal(), rng.normal()).normalize();
        let rgb = Vec3::new(rng.f32(), rng.f32(), rng.f32());
        c.push_activated(m, s, q, rng.range(0.3, 0.95), rgb);
    }
    c
}

/// Every file of a directory, by name.
pub fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().into_string().unwrap(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}
