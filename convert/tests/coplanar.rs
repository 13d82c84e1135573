//! Coplanar separation (classify.rs): exactly coplanar Gaussians get fans in distinct
//! parallel planes, a few f32 ulps apart and never more than 1.2e-4 of their coordinates
//! away, with the in-plane geometry untouched; a tracer that continues from its last hit and
//! ignores hits at t ≈ 0 (what Cycles does) then sees every layer instead of one.

use glam::{DVec3, Quat, Vec3};
use splatbridge_convert::classify::{coplanar_offset, COPLANAR_STEP};
use splatbridge_convert::{mesh_cloud, ConvertOptions, MeshSoup, Profile};
use splatbridge_scene::GaussianCloud;

/// `n` flat Gaussians in the plane z = 5 (normal ±z), centres spread within 0.3 of (7, −3),
/// all covering (7, −3, 5): a road-like stack far enough from the origin that f32 spacing
/// matters (ulp(7) ≈ 4.8e-7).
fn stack(n: usize) -> GaussianCloud {
    let mut c = GaussianCloud::new(0);
    for i in 0..n {
        let a = i as f32 * 2.399;
        let r = 0.3 * (i as f32 / n as f32).sqrt();
        let mean = Vec3::new(7.0 + r * a.cos(), -3.0 + r * a.sin(), 5.0);
        let q = Quat::from_rotation_z(a);
        c.push_activated(
            mean,
            Vec3::new(0.5, 0.4, 0.001),
            q,
            0.5,
            Vec3::new(0.2, 0.5, 0.8),
        );
    }
    c
}

fn opts(on: bool) -> ConvertOptions {
    ConvertOptions {
        profile: Profile::MeshSplats,
        coplanar_offset: on,
        ..Default::default()
    }
}

/// Plane height (z) of each Gaussian's fan (9 vertices per flat MeshSplats fan).
fn planes(m: &MeshSoup) -> Vec<f32> {
    m.positions.chunks(9).map(|f| f[0][2]).collect()
}

#[test]
fn coplanar_gaussians_get_distinct_bounded_planes() {
    let c = stack(200);
    let (off, _) = mesh_cloud(&c, &opts(false)).unwrap();
    let (on, _) = mesh_cloud(&c, &opts(true)).unwrap();
    assert!(off.positions.iter().all(|p| p[2] == 5.0));
    let z = planes(&on);
    // Every fan stays planar, parallel to z = 5 (the shift is along the normal only).
    for f in on.positions.chunks(9) {
        assert!(f.iter().all(|p| p[2] == f[0][2]));
    }
    // In-plane geometry unchanged: x, y exactly as without the separation.
    for (a, b) in on.positions.iter().zip(&off.positions) {
        assert_eq!((a[0], a[1]), (b[0], b[1]));
    }
    // Bounded: |Δz| ≤ 128 steps of 2^-20 of the coordinate bound (|mean|∞ + 4σ_max ≤ 9.3)
    // rounded up to a power of two (16).
    let bound = 128.0 * COPLANAR_STEP as f64 * 16.0;
    assert!(z.iter().all(|&h| (h as f64 - 5.0).abs() <= bound * 1.0001));
    // Distinct: pairs on one level are hash collisions, 1/256 of pairs on average (≈ 78 of
    // 19900 here); 2 % (398) leaves room for the hash's variance and fails if levels collapse.
    let mut same = 0;
    let mut close = 0;
    for i in 0..z.len() {
        for j in i + 1..z.len() {
            let d = (z[i] - z[j]).abs();
            if d == 0.0 {
                same += 1;
            } else if (d as f64) < 16.0 * COPLANAR_STEP as f64 * 0.999 {
                // Distinct levels are at least one step (2^-20·16, 16 ulps of 8…16) apart.
                close += 1;
            }
        }
    }
    assert!(same <= 398, "{same} coplanar pairs left");
    assert_eq!(close, 0);
    // Deterministic.
    assert_eq!(mesh_cloud(&c, &opts(true)).unwrap().0, on);
}

#[test]
fn offsets_are_finite_and_within_the_documented_spread() {
    for id in [0u32, 1, 2, 77, u32::MAX] {
        for reach in [0.0f32, 1e-3, 1.0, 1e4, 1e30] {
            let d = coplanar_offset(id, reach);
            assert!(d.is_finite());
            // R ≤ 2·reach.
            assert!(d.abs() <= 2.0 * 128.0 * COPLANAR_STEP * reach);
        }
        assert_eq!(coplanar_offset(id, f32::INFINITY), 0.0);
    }
}

/// Composite along +z through (7, −3) as a tracer that continues from its last hit does:
/// the next hit is the nearest triangle with t > τ (τ: 4 ulps of the hit point's magnitude,
/// the rounding of a continuation ray that starts on the last surface) other than the last
/// triangle. Returns the number of layers composited and the final transmittance.
fn continue_from_last_hit(m: &MeshSoup) -> (usize, f64) {
    let d = DVec3::Z;
    let mut o = DVec3::new(7.0, -3.0, 0.0);
    let mut last = usize::MAX;
    let (mut layers, mut trans) = (0, 1.0);
    loop {
        let tau = 4.0 * 7.0 * f32::EPSILON as f64;
        let mut best: Option<(f64, usize, f64)> = None;
        for (k, t) in m.indices.chunks_exact(3).enumerate() {
            let t: [u32; 3] = t.try_into().unwrap();
            if k == last {
                continue;
            }
            let p = t.map(|i| DVec3::from_array(m.positions[i as usize].map(|x| x as f64)));
            // Möller–Trumbore in f64.
            let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
            let h = d.cross(e2);
            let det = e1.dot(h);
            if det.abs() < 1e-15 {
                continue;
            }
            let s = o - p[0];
            let u = s.dot(h) / det;
            let q = s.cross(e1);
            let v = d.dot(q) / det;
            let tt = e2.dot(q) / det;
            if u < 0.0 || v < 0.0 || u + v > 1.0 || tt <= tau {
                continue;
            }
            if best.is_none_or(|b| tt < b.0) {
                let a = t.map(|i| m.colors[i as usize][3] as f64);
                let alpha = (1.0 - u - v) * a[0] + u * a[1] + v * a[2];
                best = Some((tt, k, alpha));
            }
        }
        let Some((t, k, alpha)) = best else { break };
        // One Gaussian's fan is crossed once: skip the rest of its triangles at this plane.
        trans *= 1.0 - alpha;
        layers += 1;
        // The continuation starts on the hit, rounded to f32 as a renderer stores it.
        o = (o + d * t).as_vec3().as_dvec3();
        last = k;
    }
    (layers, trans)
}

#[test]
fn a_continuation_tracer_sees_every_coplanar_layer() {
    let n = 12;
    let c = stack(n);
    let (off, _) = mesh_cloud(&c, &opts(false)).unwrap();
    let (on, _) = mesh_cloud(&c, &opts(true)).unwrap();
    let (l_off, _) = continue_from_last_hit(&off);
    let (l_on, t_on) = continue_from_last_hit(&on);
    // Exactly coplanar: the first hit hides every other layer.
    assert_eq!(l_off, 1);
    // Separated: one layer per distinct plane (hash collisions merge layers).
    let mut z = planes(&on);
    z.sort_by(f32::total_cmp);
    z.dedup();
    assert_eq!(l_on, z.len());
    assert!(l_on >= n - 2, "{l_on} of {n} layers");
    // Transmittance against every Gaussian composited once (order does not matter for it):
    // each fan's own alpha at (7, −3), traced alone.
    if l_on == n {
        let reference: f64 = on
            .indices
            .chunks(3 * 8)
            .map(|f| {
                let one = MeshSoup {
                    indices: f.to_vec(),
                    ..on.clone()
                };
                continue_from_last_hit(&one).1
            })
            .product();
        // f32 vertex alphas and positions: 1e-6 relative.
        assert!((t_on - reference).abs() < 1e-6, "{t_on} vs {reference}");
    }
}
