//! Closed-form and invariance checks of the native renderer.

mod common;

use common::*;
use glam::{DVec3, Quat, Vec3};
use splatbridge_hybrid::{render, RenderOptions};
use splatbridge_scene::GaussianCloud;

/// One isotropic Gaussian on the optical axis: the image is `c·α + (1 − α)·bg` with
/// `α = min(0.99, o·exp(−r²/(2s²)))`, `s² = (f·σ/d)² + 0.3`, inside the tiles of the
/// `ceil(3·sqrt(s² + sqrt(0.1)))` square (mid² − det = 0, so λ = mid + sqrt(0.1)), and where
/// `α ≥ 1/255`; alpha is that α and depth is d.
#[test]
fn isotropic_gaussian_head_on_is_closed_form() {
    let (w, h) = (96u32, 80u32);
    let cam = front_camera(w, h);
    let (d, sigma, o) = (4.0f64, 0.2f64, 0.8f64);
    let rgb = Vec3::new(0.9, 0.4, 0.1);
    let bg = [0.1f32, 0.2, 0.3];
    let mut cloud = GaussianCloud::new(0);
    cloud.push_activated(
        Vec3::new(0.0, 0.0, d as f32),
        Vec3::splat(sigma as f32),
        Quat::IDENTITY,
        o as f32,
        rgb,
    );
    let opts = RenderOptions {
        background: bg,
        ..Default::default()
    };
    let (frame, stats) = render(&cloud, &cam, &opts).unwrap();
    assert_eq!(stats.projected, 1);

    let f = cam.fy;
    let s2 = (f * sigma / d).powi(2) + 0.3;
    let radius = (3.0 * (s2 + 0.1f64.sqrt()).sqrt()).ceil();
    let (cx, cy) = (w as f64 / 2.0 - 0.5, h as f64 / 2.0 - 0.5);
    let tiles = |c: f64, g: u32| {
        let lo = (((c - radius) / 16.0) as i64).clamp(0, g as i64);
        let hi = (((c + radius + 15.0) / 16.0) as i64).clamp(0, g as i64);
        (lo, hi)
    };
    let (tx0, tx1) = tiles(cx, w.div_ceil(16));
    let (ty0, ty1) = tiles(cy, h.div_ceil(16));
    // The colour the SH DC term encodes, through the f32 SH constant as the renderer uses it.
    let col = (cloud.sh_of(0)[0] * splatbridge_scene::sh::SH_C0 + Vec3::splat(0.5)).as_dvec3();
    let mut worst = 0.0f64;
    let mut covered = 0;
    for y in 0..h {
        for x in 0..w {
            let (tx, ty) = ((x / 16) as i64, (y / 16) as i64);
            let r2 = (x as f64 - cx).powi(2) + (y as f64 - cy).powi(2);
            let mut a = (o * (-r2 / (2.0 * s2)).exp()).min(0.99);
            if !(tx0..tx1).contains(&tx) || !(ty0..ty1).contains(&ty) || a < 1.0 / 255.0 {
                a = 0.0;
            }
            covered += (a > 0.0) as usize;
            let i = (y * w + x) as usize;
            for c in 0..3 {
                let want = col[c] * a + (1.0 - a) * bg[c] as f64;
                worst = worst.max((frame.rgb[3 * i + c] as f64 - want).abs());
            }
            worst = worst.max((frame.alpha[i] as f64 - a).abs());
            let want_depth = if a > 0.0 { d } else { 0.0 };
            worst = worst.max((frame.depth[i] as f64 - want_depth).abs() / d);
        }
    }
    assert!(
        covered > 50,
        "the Gaussian should cover a disc of pixels, covered {covered}"
    );
    // f32 conic and colour, and the polynomial exp (3.6e-7 relative): 1e-5 is 10× above.
    assert!(worst < 1e-5, "closed form differs by {worst}");
}

/// Opaque (logit +inf) at its centre: α is clamped to 0.99.
#[test]
fn fully_opaque_centre_is_clamped() {
    let cam = front_camera(32, 32);
    let mut cloud = GaussianCloud::new(0);
    // σ = 1 at z = 3 is ~9 px on screen: exp(power) > 0.997 half a pixel from the mean.
    cloud.push_activated(
        Vec3::new(0.0, 0.0, 3.0),
        Vec3::splat(1.0),
        Quat::IDENTITY,
        0.5,
        Vec3::ONE,
    );
    cloud.opacity_logits[0] = f32::INFINITY;
    let (frame, _) = render(&cloud, &cam, &RenderOptions::default()).unwrap();
    // Pixel (15.5, 15.5) is the projected mean; pixels 15 and 16 are 0.5 px away on both axes.
    let a = frame.alpha[15 * 32 + 15];
    assert!(frame.is_finite());
    assert_eq!(a, 0.99, "alpha {a}");
    let (f999, _) = render(
        &cloud,
        &cam,
        &RenderOptions {
            alpha_clamp: 0.999,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(f999.alpha[15 * 32 + 15] > 0.99);
}

fn base_scene() -> GaussianCloud {
    random_cloud(800, 11)
}

/// Gaussians that cannot contribute leave the image bit-identical.
#[test]
fn invisible_gaussians_change_nothing() {
    let cam = front_camera(80, 60);
    let base = base_scene();
    let (want, _) = render(&base, &cam, &RenderOptions::default()).unwrap();
    type Extra = Box<dyn Fn(&mut GaussianCloud)>;
    let extras: Vec<(&str, Extra)> = vec![
        (
            "opacity 0",
            Box::new(|c: &mut GaussianCloud| {
                c.push_activated(
                    Vec3::new(0.0, 0.0, 3.0),
                    Vec3::splat(0.5),
                    Quat::IDENTITY,
                    0.5,
                    Vec3::ONE,
                );
                *c.opacity_logits.last_mut().unwrap() = f32::NEG_INFINITY;
                c.push_activated(
                    Vec3::new(0.3, 0.1, 2.5),
                    Vec3::splat(0.3),
                    Quat::IDENTITY,
                    0.0,
                    Vec3::ONE,
                );
            }),
        ),
        (
            "behind the camera",
            Box::new(|c: &mut GaussianCloud| {
                c.push_activated(
                    Vec3::new(0.0, 0.0, -3.0),
                    Vec3::splat(0.5),
                    Quat::IDENTITY,
                    0.9,
                    Vec3::ONE,
                );
                c.push_activated(
                    Vec3::new(0.0, 0.0, -0.05),
                    Vec3::splat(2.0),
                    Quat::IDENTITY,
                    1.0,
                    Vec3::ONE,
                );
            }),
        ),
        (
            "off-screen",
            Box::new(|c: &mut GaussianCloud| {
                c.push_activated(
                    Vec3::new(50.0, 0.0, 3.0),
                    Vec3::splat(0.05),
                    Quat::IDENTITY,
                    0.9,
                    Vec3::ONE,
                );
                c.push_activated(
                    Vec3::new(0.0, -40.0, 3.0),
                    Vec3::splat(0.05),
                    Quat::IDENTITY,
                    0.9,
                    Vec3::ONE,
                );
            }),
        ),
    ];
    for (what, add) in extras {
        let mut c = base.clone();
        add(&mut c);
        let (got, stats) = render(&c, &cam, &RenderOptions::default()).unwrap();
        assert!(got == want, "{what}: the image changed");
        assert_eq!(stats.gaussians, base.len() + 2);
    }
}

/// Permuting the input, including Gaussians at exactly equal depths, gives the same bits.
#[test]
fn input_order_does_not_change_the_image() {
    let cam = front_camera(64, 48);
    let mut cloud = base_scene();
    // Exact depth ties: overlapping Gaussians at z = 3 with different colours.
    for k in 0..6 {
        let rgb = Vec3::new(k as f32 / 6.0, 1.0 - k as f32 / 6.0, 0.5);
        cloud.push_activated(
            Vec3::new(0.02 * k as f32, 0.0, 3.0),
            Vec3::splat(0.15),
            Quat::IDENTITY,
            0.7,
            rgb,
        );
    }
    let (want, _) = render(&cloud, &cam, &RenderOptions::default()).unwrap();
    let n = cloud.len();
    let mut rng = splatbridge_scene::rng::Rng::new(5);
    for round in 0..3 {
        let mut perm: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            perm.swap(i, rng.below(i as u64 + 1) as usize);
        }
        let mut p = GaussianCloud::new(cloud.sh_degree);
        for &i in &perm {
            p.push(
                cloud.means[i],
                cloud.log_scales[i],
                cloud.rotations[i],
                cloud.opacity_logits[i],
                cloud.sh_of(i),
            );
        }
        let (got, _) = render(&p, &cam, &RenderOptions::default()).unwrap();
        assert!(got == want, "permutation {round} changed the image");
    }
}

/// Identical bits with one and with two threads.
#[test]
fn thread_count_does_not_change_the_image() {
    let cam = front_camera(120, 90);
    let cloud = random_cloud(3000, 21);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| render(&cloud, &cam, &RenderOptions::default()).unwrap())
    };
    let (a, sa) = run(1);
    let (b, sb) = run(2);
    let (c, _) = run(3);
    assert!(a == b && b == c, "images differ between thread counts");
    assert_eq!((sa.tile_pairs, sa.blends), (sb.tile_pairs, sb.blends));
}

/// Translating scene and camera by 1e5 leaves the image bit-identical: the mean is made
/// camera-relative in f64 before any rounding. Positions are chosen representable at 1e5.
#[test]
fn far_from_origin_is_translation_invariant() {
    let offset = DVec3::new(1.0e5, -1.0e5, 1.0e5);
    let near_cloud = random_cloud(500, 3);
    let mut far = near_cloud.clone();
    let mut near = near_cloud.clone();
    for (i, m) in near_cloud.means.iter().enumerate() {
        let p = (m.as_dvec3() + offset).as_vec3();
        far.means[i] = p;
        // Exact: p and offset differ by a multiple of p's ulp, representable in f32.
        near.means[i] = (p.as_dvec3() - offset).as_vec3();
    }
    let cam_eye = DVec3::new(0.1, -0.05, 0.3);
    let cam0 = splatbridge_scene::Camera::look_at(
        cam_eye,
        DVec3::new(0.0, 0.0, 5.0),
        DVec3::NEG_Y,
        60.0,
        64,
        48,
    )
    .unwrap();
    let mut cam1 = cam0.clone();
    cam1.centre += offset;
    let (a, sa) = render(&near, &cam0, &RenderOptions::default()).unwrap();
    let (b, _) = render(&far, &cam1, &RenderOptions::default()).unwrap();
    assert!(sa.blends > 0);
    assert!(a == b, "image changed under translation by 1e5");
}

/// A renderer reused across scenes, sizes and cameras gives the bits of a fresh one.
#[test]
fn reused_renderer_matches_fresh_renders() {
    let mut r = splatbridge_hybrid::Renderer::new();
    for (seed, n, w, h) in [
        (1u64, 2000usize, 90u32, 60u32),
        (2, 300, 33, 47),
        (3, 1500, 64, 64),
    ] {
        let cloud = random_cloud(n, seed);
        let cam = front_camera(w, h);
        let (a, sa) = r.render(&cloud, &cam, &RenderOptions::default()).unwrap();
        let (b, sb) = render(&cloud, &cam, &RenderOptions::default()).unwrap();
        assert!(a == b, "seed {seed}: reused renderer differs");
        assert_eq!((sa.tile_pairs, sa.blends), (sb.tile_pairs, sb.blends));
    }
}
