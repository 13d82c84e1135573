//! Helpers of the GES hybrid tests: random surfel scenes and an f64 plain z-buffer reference of
//! surfels, written independently of the renderer's code (direct ray–plane intersection in f64).
#![allow(dead_code)]

use glam::{DVec3, Mat3, Quat, Vec3};
use splatbridge_scene::rng::Rng;
use splatbridge_scene::surfels::{ges_mean_scale, SurfelCloud};
use splatbridge_scene::{sh, Camera, GaussianCloud};

/// Relative band around a decision (coverage `u² + v²` against `2·ln 255`, or two depths) within
/// which the f32 renderer may legitimately decide the other way. The renderer forms the linear
/// forms of the pixel coordinates in f32 (relative error ~1e-7 each, a few terms) and the local
/// coordinates from a difference of terms at most ~|c|/s ≈ 200 times larger than the result in
/// these scenes (distance ≤ 10, scale ≥ 0.05), so the error is below 200·4·6e-8 ≈ 5e-5; 2e-4
/// leaves a factor of four.
pub const AMBIGUITY: f64 = 2e-4;

pub fn random_rotation(rng: &mut Rng) -> Quat {
    Quat::from_xyzw(rng.normal(), rng.normal(), rng.normal(), rng.normal()).normalize()
}

/// `n` surfels around the origin (within ±2 on each axis), random orientation, scales
/// 0.05–0.4, SH degree 1 colours.
pub fn random_surfels(n: usize, seed: u64) -> SurfelCloud {
    let mut rng = Rng::new(seed);
    let mut s = SurfelCloud::new(1);
    for _ in 0..n {
        let m = Vec3::new(
            rng.range(-2.0, 2.0),
            rng.range(-2.0, 2.0),
            rng.range(-2.0, 2.0),
        );
        let r = Mat3::from_quat(random_rotation(&mut rng));
        let (su, sv) = (rng.range(0.05, 0.4), rng.range(0.05, 0.4));
        let shc: Vec<Vec3> = (0..4)
            .map(|_| {
                Vec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                ) * 0.5
            })
            .collect();
        s.push(
            m,
            r.col(0),
            r.col(1),
            [su, sv],
            ges_mean_scale(su, sv),
            &shc,
        );
    }
    s
}

/// `n` random 3D Gaussians (degree 1) within ±2, scales 0.02–0.3, opacity 0.05–0.95.
pub fn random_gaussians(n: usize, seed: u64) -> GaussianCloud {
    let mut rng = Rng::new(seed);
    let mut c = GaussianCloud::new(1);
    for _ in 0..n {
        let m = Vec3::new(
            rng.range(-2.0, 2.0),
            rng.range(-2.0, 2.0),
            rng.range(-2.0, 2.0),
        );
        let s = Vec3::new(
            rng.range(0.02, 0.3),
            rng.range(0.02, 0.3),
            rng.range(0.02, 0.3),
        );
        let rgb = Vec3::new(rng.f32(), rng.f32(), rng.f32());
        c.push_activated(m, s, random_rotation(&mut rng), rng.range(0.05, 0.95), rgb);
    }
    c
}

pub fn camera(w: u32, h: u32) -> Camera {
    Camera::look_at(
        DVec3::new(0.3, -1.0, -7.0),
        DVec3::ZERO,
        DVec3::NEG_Y,
        50.0,
        w,
        h,
    )
    .unwrap()
}

/// Per-pixel result of the f64 z-buffer.
pub struct ZRef {
    /// Winning surfel per pixel (None = background).
    pub winner: Vec<Option<usize>>,
    pub depth: Vec<f64>,
    /// Decisions within [`AMBIGUITY`] of their threshold.
    pub ambiguous: Vec<bool>,
}

/// Plain z-buffer in f64: per pixel (sampled at its integer coordinate plus `offset`), every
/// surfel, nearest covering one (ties: lower index).
pub fn zbuffer_reference(s: &SurfelCloud, cam: &Camera, near: f64, offset: [f64; 2]) -> ZRef {
    let r2 = 2.0 * 255f64.ln();
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut out = ZRef {
        winner: vec![None; w * h],
        depth: vec![0.0; w * h],
        ambiguous: vec![false; w * h],
    };
    let surf: Vec<(DVec3, DVec3, DVec3, DVec3, f64, f64)> = (0..s.len())
        .map(|i| {
            let c = cam.world_to_cam * (s.means[i].as_dvec3() - cam.centre);
            let au = cam.world_to_cam * s.axes_u[i].as_dvec3();
            let av = cam.world_to_cam * s.axes_v[i].as_dvec3();
            (
                c,
                au,
                av,
                au.cross(av),
                s.scales[i][0] as f64,
                s.scales[i][1] as f64,
            )
        })
        .collect();
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            // Pixel i sampled at continuous coordinate i + 0.5 (the native convention).
            let d = DVec3::new(
                (x as f64 + offset[0] + 0.5 - cam.cx) / cam.fx,
                (y as f64 + offset[1] + 0.5 - cam.cy) / cam.fy,
                1.0,
            );
            let mut best: Option<(f64, usize)> = None;
            let mut second = f64::INFINITY;
            for (i, &(c, au, av, n, su, sv)) in surf.iter().enumerate() {
                let t = n.dot(c) / n.dot(d);
                if !(t.is_finite() && t > near) {
                    continue;
                }
                let hit = d * t - c;
                let (u, v) = (au.dot(hit) / su, av.dot(hit) / sv);
                let q = u * u + v * v;
                if (q - r2).abs() <= AMBIGUITY * r2 {
                    out.ambiguous[p] = true;
                }
                if q <= r2 {
                    match best {
                        Some((bt, _)) if t >= bt => second = second.min(t),
                        Some((bt, _)) => {
                            second = bt;
                            best = Some((t, i));
                        }
                        None => best = Some((t, i)),
                    }
                }
            }
            if let Some((t, i)) = best {
                if (second - t).abs() <= AMBIGUITY * t {
                    out.ambiguous[p] = true;
                }
                out.winner[p] = Some(i);
                out.depth[p] = t;
            }
        }
    }
    out
}

/// The surfel colour the renderer uses: SH toward the camera, as a Gaussian's.
pub fn surfel_color(s: &SurfelCloud, i: usize, cam: &Camera) -> Vec3 {
    let dir = (s.means[i].as_dvec3() - cam.centre).normalize();
    sh::eval_color(s.sh_degree, s.sh_of(i), dir.as_vec3())
}

/// f64 screen projection of Gaussian `i` of `g` (any rotation), camera at the origin: pixel
/// centre, the 2D covariance `[a, b, c]` with native's 0.3 px² low-pass, view depth.
pub fn screen_cov(cam: &Camera, g: &GaussianCloud, i: usize) -> (f64, f64, [f64; 3], f64) {
    let t = cam.world_to_cam * (g.means[i].as_dvec3() - cam.centre);
    let r = glam::DMat3::from_quat(g.unit_rotation(i).as_dquat());
    let s = glam::DMat3::from_diagonal(g.scale(i).as_dvec3());
    let m = cam.world_to_cam * r * s;
    let sigma = m * m.transpose();
    let (fx, fy) = (cam.fx, cam.fy);
    let j0 = DVec3::new(fx / t.z, 0.0, -fx * t.x / (t.z * t.z));
    let j1 = DVec3::new(0.0, fy / t.z, -fy * t.y / (t.z * t.z));
    let cov = [
        j0.dot(sigma * j0) + 0.3,
        j0.dot(sigma * j1),
        j1.dot(sigma * j1) + 0.3,
    ];
    (
        fx * t.x / t.z + cam.cx - 0.5,
        fy * t.y / t.z + cam.cy - 0.5,
        cov,
        t.z,
    )
}

/// [`screen_cov`] with the conic (the inverse 2D covariance) in place of the covariance.
pub fn project_aniso(cam: &Camera, g: &GaussianCloud, i: usize) -> (f64, f64, [f64; 3], f64) {
    let (x, y, [a, b, c], depth) = screen_cov(cam, g, i);
    let det = a * c - b * b;
    (x, y, [c / det, -b / det, a / det], depth)
}
