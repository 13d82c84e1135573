//! Scenes shared by the distillation tests.

use splatbridge_scene::GaussianCloud;

/// `n` Gaussians of random orientation, flat and volumetric, packed in a unit cube at sizes
/// around a tenth of it, so their fans cut through each other (a splitmix64 stream, fixed).
pub fn crossing_cloud(n: usize) -> GaussianCloud {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f32 / (1u64 << 53) as f32
    };
    let mut c = GaussianCloud::with_capacity(0, n);
    for i in 0..n {
        let p = glam::Vec3::new(next(), next(), next()) - 0.5;
        let flat = if i % 2 == 0 { 0.05 } else { 1.0 };
        let s = glam::Vec3::new(0.05 + 0.1 * next(), 0.05 + 0.1 * next(), 0.1 * flat);
        let q = glam::Quat::from_xyzw(next() - 0.5, next() - 0.5, next() - 0.5, next() - 0.5)
            .normalize();
        let rgb = glam::Vec3::new(next(), next(), next());
        c.push_activated(p, s, q, 0.5 + 0.45 * next(), rgb);
    }
    c
}
