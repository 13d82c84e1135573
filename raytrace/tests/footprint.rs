//! Mode `gaussian` with pixel footprints and sub-pixel samples: a head-on Gaussian against the
//! closed form of the widened Gaussian, the footprint → 0 and spp = 1 limits against today's
//! point-sampled image, supersampling against a slow per-sample loop, and independence from the
//! thread count.

mod common;

use common::Rng;
use glam::{DVec3, Quat, Vec3};
use splatbridge_raytrace::footprint::{sample_offsets, RayFootprint};
use splatbridge_raytrace::kbuffer::KBuffer;
use splatbridge_raytrace::render::camera_ray;
use splatbridge_raytrace::{
    BackendKind, BuildPreset, Footprint, GaussianTracer, RenderOptions, SampleFootprint,
};
use splatbridge_scene::gaussians::logit;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

fn look(eye: DVec3, target: DVec3, fov: f64, w: u32, h: u32) -> Camera {
    Camera::look_at(eye, target, DVec3::NEG_Y, fov, w, h).unwrap()
}

fn random_cloud(seed: u64, n: usize) -> GaussianCloud {
    let mut r = Rng(seed);
    let mut c = GaussianCloud::new(1);
    for _ in 0..n {
        let m = Vec3::new(r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0));
        // Many sub-pixel Gaussians at 32×32 (a pixel is ~0.08 units at the cloud's depth), the
        // case the footprint exists for, and some larger ones.
        let s = Vec3::new(
            r.range(0.005, 0.1),
            r.range(0.005, 0.1),
            r.range(0.002, 0.1),
        );
        let q = Quat::from_xyzw(
            r.range(-1.0, 1.0),
            r.range(-1.0, 1.0),
            r.range(-1.0, 1.0),
            r.range(-1.0, 1.0),
        );
        let sh: Vec<Vec3> = (0..4)
            .map(|k| {
                Vec3::new(r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0))
                    * if k == 0 { 1.5 } else { 0.3 }
            })
            .collect();
        c.push(
            m,
            Vec3::new(s.x.ln(), s.y.ln(), s.z.ln()),
            q,
            logit(r.range(0.05, 1.0)),
            &sh,
        );
    }
    c
}

fn opts(footprint: Footprint, spp: u32) -> RenderOptions {
    RenderOptions {
        footprint,
        spp,
        ..RenderOptions::default()
    }
}

fn max_diff(a: &Frame, b: &Frame) -> f32 {
    a.rgb
        .iter()
        .zip(&b.rgb)
        .chain(a.alpha.iter().zip(&b.alpha))
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// An isotropic Gaussian (σ) on the optical axis at depth Z, seen by pixel rays along the image
/// row and column through the centre. The widened response along a ray at angle θ from the axis
/// is `o·exp(−½·(Z sin θ)² / (σ² + s·Z²·cos²θ/f²))`: the mean's offset from the ray is radial,
/// and the footprint's radial variance at view depth Z is `s·Z²·cos²θ/f²` (derivation in
/// `footprint.rs`). Off, it is the same with s = 0.
#[test]
fn head_on_gaussian_matches_the_closed_form() {
    let (z, sigma, o) = (4.0f64, 0.01f64, 0.8f64);
    let mut cloud = GaussianCloud::new(0);
    cloud.push(
        Vec3::new(0.0, 0.0, z as f32),
        Vec3::splat((sigma as f32).ln()),
        Quat::IDENTITY,
        logit(o as f32),
        &[Vec3::ZERO],
    );
    // 41×41, 40° field of view: f ≈ 56 px, σ·f/Z ≈ 0.14 px, a sub-pixel Gaussian.
    let cam = look(DVec3::ZERO, DVec3::Z, 40.0, 41, 41);
    for b in common::backends() {
        let tracer = GaussianTracer::new(cloud.clone(), b, BuildPreset::default()).unwrap();
        for (fp, s) in [(Footprint::On, 0.3), (Footprint::Off, 0.0)] {
            let (frame, _) = tracer.render(&cam, &opts(fp, 1)).unwrap();
            let mut lit = 0;
            for k in 0..41u32 {
                for (i, j) in [(k, 20u32), (20u32, k)] {
                    let d = cam.ray_dir(i as f64 + 0.5, j as f64 + 0.5);
                    let cos = d.dot(DVec3::Z);
                    let sin2 = 1.0 - cos * cos;
                    let f = cam.fx;
                    let q = z * z * sin2 / (sigma * sigma + s * z * z * cos * cos / (f * f));
                    let mut want = (o * (-0.5 * q).exp()).min(0.99);
                    if want < 1.0 / 255.0 {
                        want = 0.0;
                    }
                    let got = frame.alpha[(j * 41 + i) as usize] as f64;
                    // f32 evaluation of q (relative ~1e-6) and of the exponential: 1e-5 absolute
                    // is 100× the error seen and far below the footprint's own effect (≥ 0.1
                    // at the neighbours of the centre pixel).
                    assert!(
                        (got - want).abs() < 1e-5,
                        "{b:?} {fp:?} pixel ({i}, {j}): {got} vs closed form {want}"
                    );
                    lit += (want > 0.0) as usize;
                }
            }
            // On: the centre pixel and its four neighbours (1 px away, q ≈ 3.1, α ≈ 0.17; two
            // pixels away α ≈ 0.0015 is cut), the centre counted once per line; off: the centre
            // only (its neighbours are 7σ away). The closed form itself, so the check above
            // covers both covered and cut pixels.
            let want_lit = if fp == Footprint::On { 6 } else { 2 };
            assert_eq!(lit, want_lit, "{fp:?}: lit samples");
        }
    }
}

/// Footprint → 0 reproduces the point-sampled image: the widened response with a vanishing
/// footprint is the same function evaluated in another form (2-D marginal instead of the
/// whitened cross product).
#[test]
fn vanishing_footprint_is_todays_image() {
    let cloud = random_cloud(7, 300);
    let cam = look(DVec3::new(0.3, -0.2, -4.0), DVec3::ZERO, 50.0, 32, 32);
    let tracer = GaussianTracer::new(cloud, BackendKind::Obvhs, BuildPreset::default()).unwrap();
    let o = RenderOptions::default();
    let (today, _) = tracer.render(&cam, &o).unwrap();
    let tiny = 1e-12;
    let padded = tracer.padded(&cam, tiny).unwrap();
    let forward = cam.world_to_cam.row(2);
    let mut worst = 0.0f32;
    let mut differ = 0;
    for j in 0..32u32 {
        for i in 0..32u32 {
            let (org, d) = camera_ray(&cam, i as f64 + 0.5, j as f64 + 0.5);
            let fp = RayFootprint::pinhole(&cam, d, tiny).unwrap();
            let px = tracer.trace_fp(
                org,
                d,
                Some(forward),
                Some((&fp, &padded)),
                &o,
                &mut KBuffer::new(o.k),
            );
            let k = (j * 32 + i) as usize;
            let e = (0..3)
                .map(|c| (px.rgb[c] - today.rgb[3 * k + c]).abs())
                .fold((px.alpha - today.alpha[k]).abs(), f32::max);
            worst = worst.max(e);
            differ += (e > 1e-5) as usize;
        }
    }
    // The two forms of the response agree to f32 rounding (~1e-6 relative); 1e-4 allows the
    // compositing of ~20 hits to accumulate it. A Gaussian whose α sits within rounding of the
    // 1/255 cut could flip and move a pixel by up to ~1/255·colour, which would show here.
    assert!(
        worst < 1e-4,
        "worst {worst}, {differ} pixels differ by > 1e-5"
    );
}

/// `spp = 1` is today's image bit for bit, with the footprint off; and the footprint changes it.
#[test]
fn spp_one_is_todays_image() {
    let cloud = random_cloud(11, 300);
    let cam = look(DVec3::new(-0.5, 0.4, -3.5), DVec3::ZERO, 55.0, 24, 20);
    let tracer = GaussianTracer::new(cloud, BackendKind::Obvhs, BuildPreset::default()).unwrap();
    let o = RenderOptions::default();
    let (img, _) = tracer.render(&cam, &o).unwrap();
    let forward = cam.world_to_cam.row(2);
    for j in 0..20u32 {
        for i in 0..24u32 {
            let (org, d) = camera_ray(&cam, i as f64 + 0.5, j as f64 + 0.5);
            let px = tracer.trace(org, d, Some(forward), &o, &mut KBuffer::new(o.k));
            let k = (j * 24 + i) as usize;
            assert_eq!(img.rgb[3 * k..3 * k + 3], px.rgb.to_array());
            assert_eq!(img.alpha[k], px.alpha);
        }
    }
    let (on, _) = tracer.render(&cam, &opts(Footprint::On, 1)).unwrap();
    assert!(max_diff(&on, &img) > 0.01, "the footprint changes nothing");
}

/// Supersampling equals the mean of the per-sample traces at the fixed offsets (the slow
/// reference), with and without the footprint; and it does not depend on the thread count.
#[test]
fn spp_is_the_mean_of_its_samples_and_thread_independent() {
    let cloud = random_cloud(23, 250);
    let cam = look(DVec3::new(0.2, 0.1, -3.8), DVec3::ZERO, 50.0, 16, 12);
    let tracer = GaussianTracer::new(cloud, BackendKind::Obvhs, BuildPreset::default()).unwrap();
    let forward = cam.world_to_cam.row(2);
    for (fp, spp, sf) in [
        (Footprint::Off, 4, SampleFootprint::Subpixel),
        (Footprint::On, 4, SampleFootprint::Subpixel),
        (Footprint::On, 3, SampleFootprint::Pixel),
    ] {
        let o = RenderOptions {
            sample_footprint: sf,
            ..opts(fp, spp)
        };
        let (img, stats) = tracer.render(&cam, &o).unwrap();
        assert_eq!(stats.rays, 16 * 12 * spp as u64);
        let var = sf.variance_px2(spp);
        let padded = tracer.padded(&cam, var).unwrap();
        for j in 0..12u32 {
            for i in 0..16u32 {
                let mut sum = [0.0f32; 4];
                for (du, dv) in sample_offsets(spp) {
                    let (org, d) = camera_ray(&cam, i as f64 + du, j as f64 + dv);
                    let f = RayFootprint::pinhole(&cam, d, var).unwrap();
                    let with = (fp == Footprint::On).then_some((&f, &padded));
                    let px =
                        tracer.trace_fp(org, d, Some(forward), with, &o, &mut KBuffer::new(o.k));
                    for (acc, v) in sum
                        .iter_mut()
                        .zip(px.rgb.to_array().into_iter().chain([px.alpha]))
                    {
                        *acc += v;
                    }
                }
                let k = (j * 16 + i) as usize;
                // Same sums in the same order, then one multiplication by 1/spp.
                let got = [
                    img.rgb[3 * k],
                    img.rgb[3 * k + 1],
                    img.rgb[3 * k + 2],
                    img.alpha[k],
                ];
                assert_eq!(got, sum.map(|v| v * (1.0 / spp as f32)));
            }
        }
        let in_pool = |n: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap()
                .install(|| tracer.render(&cam, &o).unwrap().0)
        };
        let (a, b) = (in_pool(1), in_pool(3));
        assert_eq!(a.rgb, img.rgb);
        assert_eq!(b.rgb, img.rgb);
        assert_eq!(a.alpha, b.alpha);
    }
}

/// Options out of range are refused, not clamped.
#[test]
fn bad_spp_is_refused() {
    let tracer = GaussianTracer::new(
        random_cloud(3, 10),
        BackendKind::Obvhs,
        BuildPreset::default(),
    )
    .unwrap();
    let cam = look(DVec3::new(0.0, 0.0, -4.0), DVec3::ZERO, 50.0, 8, 8);
    for spp in [0, 1025] {
        assert!(tracer.render(&cam, &opts(Footprint::On, spp)).is_err());
    }
}
