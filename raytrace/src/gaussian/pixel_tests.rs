//! The pixel-space widened response ([`super::camera::PixelSplat`], the fast path of
//! `--footprint on`) against the 3-D form it replaces ([`super::Part::widened_q_3d`], the
//! obviously-correct reference: the footprint module's derivation step by step), per ray and
//! Gaussian and as images; and the tile path's per-ray SH basis against `sh::eval_color`.

use glam::Vec3;
use splatbridge_scene::rng::Rng;
use splatbridge_scene::{metrics, sh, Camera, Frame};

use super::camera::LocalFootprint;
use super::cull_tests::{bits, camera, corridor, moving_scene, random_rotation_and_sh};
use super::tiles::color_from_basis;
use super::GaussianTracer;
use crate::backend::{BackendKind, BuildPreset};
use crate::footprint::{Footprint, HitOrder, RayFootprint};
use crate::render::RenderOptions;

/// Largest relative gap `|q_px − q_3d| / max(q_3d, 1)` between the two forms, over every
/// proxy and every pixel centre of `cam`, for each part; and how many pairs were compared.
fn q_gap(tracer: &GaussianTracer, cam: &Camera, variance: f64) -> (f64, usize) {
    let pad = tracer.padded(cam, variance).unwrap();
    let mut worst = 0.0f64;
    let mut n = 0;
    for j in 0..cam.height {
        for i in 0..cam.width {
            let d = cam.ray_dir(i as f64 + 0.5, j as f64 + 0.5);
            let f = RayFootprint::pinhole(cam, d, variance).unwrap();
            for (pi, part) in tracer.parts.iter().enumerate() {
                let ro = tracer.local_point(pi, cam.centre);
                let local = LocalFootprint::new(tracer, pi, &f, &pad);
                for (p, px) in pad.pixels[pi].iter().enumerate() {
                    assert!(px.ok, "part {pi} proxy {p}: no pixel record");
                    let q3 = part.widened_q_3d(p, ro, &local);
                    let qp = px.q(&local);
                    let (Some(q3), Some(qp)) = (q3, qp) else {
                        assert_eq!(q3.is_some(), qp.is_some(), "part {pi} proxy {p}");
                        continue;
                    };
                    // Only where the cut at r² can be decided by it.
                    if q3.min(qp) > 4.0 * px.r2 {
                        continue;
                    }
                    let gap = (qp as f64 - q3 as f64).abs() / (q3 as f64).max(1.0);
                    worst = worst.max(gap);
                    n += 1;
                }
            }
        }
    }
    (worst, n)
}

/// A static corridor (seed `seed`) and the moving scene posed at t = 0.7: the two kinds of
/// record (no part rotation, and a part's rotation).
fn static_and_moving(seed: u64) -> (GaussianTracer, GaussianTracer) {
    let stat = GaussianTracer::new(
        corridor(seed, 1200),
        BackendKind::Obvhs,
        BuildPreset::Medium,
    )
    .unwrap();
    let mut moving = GaussianTracer::for_scene(
        &moving_scene(),
        0.0,
        BackendKind::Obvhs,
        BuildPreset::Medium,
    )
    .unwrap();
    moving.set_time(0.7);
    (stat, moving)
}

/// The two forms are one number up to f32 rounding, for a static cloud and for moving parts
/// (whose records carry the part's rotation).
#[test]
fn pixel_form_matches_3d_form() {
    let (stat, moving) = static_and_moving(21);
    for (what, tracer) in [("static", &stat), ("moving", &moving)] {
        for variance in [0.3, 0.3 / 4.0] {
            let (gap, n) = q_gap(tracer, &camera(), variance);
            assert!(n > 10_000, "{what}: only {n} pairs near the cut");
            // Both forms are ~60 f32 operations on inputs rounded to f32 (1.2e-7 each); the
            // largest gap measured on these scenes is printed. 1e-4 is a few hundred ulps: a
            // formula error (a wrong Jacobian, a missing z², a sign) gives gaps of order 1.
            println!("{what} s = {variance}: largest relative gap {gap:.2e} over {n} pairs");
            assert!(gap < 1e-4, "{what} s = {variance}: gap {gap:e}");
        }
    }
}

/// Images through the pixel records and through the 3-D form (every record disabled, so the
/// fallback runs) agree to within a few hits crossing the α or T cut by one rounding.
#[test]
fn pixel_form_images_match_3d_form() {
    let tracer =
        GaussianTracer::new(corridor(22, 1500), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let cam = camera();
    for order in [HitOrder::MeanDepth, HitOrder::Hit] {
        let opts = RenderOptions {
            footprint: Footprint::On,
            order,
            ..RenderOptions::default()
        };
        let fast = tracer.padded(&cam, 0.3).unwrap();
        let mut slow = tracer.padded(&cam, 0.3).unwrap();
        for px in slow.pixels.iter_mut().flatten() {
            px.ok = false;
        }
        let a: Frame = tracer.render_padded(&cam, &opts, Some(&fast)).unwrap().0;
        let b: Frame = tracer.render_padded(&cam, &opts, Some(&slow)).unwrap().0;
        let same = bits(&a)
            .iter()
            .zip(bits(&b))
            .filter(|(x, y)| **x == *y)
            .count();
        let psnr = metrics::psnr(&a, &b).unwrap();
        println!(
            "{order:?}: {psnr:.1} dB, {same} of {} values equal",
            bits(&a).len()
        );
        // 60 dB: the bar images must meet where the order of float operations changes.
        assert!(psnr >= 60.0, "{order:?}: {psnr} dB");
        // The records are used: the fast render is not the fallback's.
        assert!(a.rgb.iter().any(|v| *v > 0.0));
    }
}

/// The tile path's colour with the ray's SH basis computed once is `sh::eval_color` bit for
/// bit, at every degree.
#[test]
fn basis_once_is_eval_color() {
    let mut r = Rng::new(5);
    for degree in 0..=3u8 {
        let k = (degree as usize + 1).pow(2);
        for _ in 0..2000 {
            let d = Vec3::new(r.normal(), r.normal(), r.normal()).normalize();
            let (_, base) = random_rotation_and_sh(&mut r);
            let coeffs: Vec<Vec3> = (0..k).map(|j| base[j % 4] * (1.0 + j as f32)).collect();
            let b = sh::basis(degree, d);
            let fast = color_from_basis(&coeffs, &b);
            let slow = sh::eval_color(degree, &coeffs, d);
            assert_eq!(
                fast.to_array().map(f32::to_bits),
                slow.to_array().map(f32::to_bits)
            );
        }
    }
}

/// The screen ellipse the tile path tests before `q` ([`super::camera::PixelSplat::bound`])
/// holds every ray whose `q` passes the cut, at every pixel centre and at sub-pixel samples,
/// and it is a real bound: most Gaussians get one, and it rejects rays.
#[test]
fn screen_ellipse_holds_every_accepted_ray() {
    let (stat, moving) = static_and_moving(23);
    let cam = camera();
    for (what, tracer) in [("static", &stat), ("moving", &moving)] {
        for variance in [0.3, 0.3 / 4.0] {
            let pad = tracer.padded(&cam, variance).unwrap();
            let (mut bounded, mut records, mut accepted, mut rejected) = (0, 0, 0, 0);
            for (pi, pixels) in pad.pixels.iter().enumerate() {
                let bounds: Vec<_> = pixels.iter().map(|px| px.bound(variance)).collect();
                records += bounds.len();
                bounded += bounds.iter().filter(|b| b.is_some()).count();
                for j in 0..cam.height * 3 {
                    for i in 0..cam.width * 3 {
                        let (u, v) = ((i as f64 + 0.5) / 3.0, (j as f64 + 0.5) / 3.0);
                        let f = RayFootprint::pinhole(&cam, cam.ray_dir(u, v), variance).unwrap();
                        let local = LocalFootprint::new(tracer, pi, &f, &pad);
                        let (cu, cv) = local.centred;
                        for (p, px) in pixels.iter().enumerate() {
                            let Some((mu, k, amax, half)) = bounds[p] else {
                                continue;
                            };
                            let (x0, x1) = (mu[0] - cu, mu[1] - cv);
                            let inside =
                                k[0] * x0 * x0 + 2.0 * k[1] * x0 * x1 + k[2] * x1 * x1 <= amax;
                            let in_box = ((x0 as f64).abs() <= half[0] + 0.05)
                                && ((x1 as f64).abs() <= half[1] + 0.05);
                            let passes = px.q(&local).is_some_and(|q| q <= px.r2);
                            if passes {
                                accepted += 1;
                                assert!(
                                    inside && in_box,
                                    "{what} s {variance}: proxy {p} at {u},{v}"
                                );
                            } else if !inside {
                                rejected += 1;
                            }
                        }
                    }
                }
            }
            println!("{what} s {variance}: {bounded} of {records} bounded, {accepted} accepted, {rejected} rejected");
            assert!(
                bounded * 10 > records * 9,
                "{what}: {bounded} of {records} bounded"
            );
            assert!(accepted > 1000 && rejected > accepted, "{what}");
        }
    }
}
