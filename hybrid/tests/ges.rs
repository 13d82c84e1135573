//! GES hybrid: surfel pass against a plain f64 z-buffer, the depth test of pass 2, the
//! documented composite on analytic cases, determinism and hard cases.

mod ges_common;

use ges_common::*;
use glam::{DVec3, Quat, Vec3};
use splatbridge_hybrid::ges::{render_ges, render_ges_with_ids, Blend, GesOptions};
use splatbridge_scene::surfels::{ges_mean_scale, SurfelCloud};
use splatbridge_scene::{Camera, Frame, GaussianCloud};

fn plain() -> GesOptions {
    GesOptions {
        blur: false,
        supersample: 1,
        background: [0.1, 0.2, 0.3],
        // These tests check GES's own formulas; the sorted blend has `ges_sorted.rs`.
        blend: Blend::Unsorted,
        ..Default::default()
    }
}

fn assert_bit_identical(a: &Frame, b: &Frame, what: &str) {
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert!(bits(&a.rgb) == bits(&b.rgb), "{what}: rgb differs");
    assert!(bits(&a.alpha) == bits(&b.alpha), "{what}: alpha differs");
    assert!(bits(&a.depth) == bits(&b.depth), "{what}: depth differs");
}

#[test]
fn surfel_only_scene_equals_plain_zbuffer() {
    let s = random_surfels(60, 7);
    let cam = camera(96, 72);
    let opts = plain();
    let (frame, stats, ids) = render_ges_with_ids(&s, &GaussianCloud::new(1), &cam, &opts).unwrap();
    assert_eq!(stats.blends, 0);
    let r = zbuffer_reference(&s, &cam, opts.near as f64, [0.0, 0.0]);
    let (mut covered, mut ambiguous) = (0, 0);
    for p in 0..(cam.width * cam.height) as usize {
        if r.ambiguous[p] {
            ambiguous += 1;
            continue;
        }
        let got = [frame.rgb[3 * p], frame.rgb[3 * p + 1], frame.rgb[3 * p + 2]];
        match r.winner[p] {
            Some(i) => {
                covered += 1;
                assert_eq!(ids[p], i as u32, "pixel {p}: winner");
                // The colour must be exactly the winner's (no Gaussians: (C_S + 0)/(1 + 0)).
                assert_eq!(
                    got,
                    surfel_color(&s, i, &cam).to_array(),
                    "pixel {p}: colour"
                );
                assert_eq!(frame.alpha[p], 1.0);
                // Depth: f32 intersection against f64, relative 1e-5 (a few f32 roundings of
                // terms ≤ 200× the result, see AMBIGUITY).
                assert!(
                    (frame.depth[p] as f64 - r.depth[p]).abs() <= 1e-5 * r.depth[p],
                    "pixel {p}: depth {} vs {}",
                    frame.depth[p],
                    r.depth[p]
                );
            }
            None => {
                assert_eq!(
                    ids[p],
                    u32::MAX,
                    "pixel {p}: covered but the reference is not"
                );
                assert_eq!(got, opts.background, "pixel {p}: background");
                assert_eq!(frame.alpha[p], 0.0);
            }
        }
    }
    // The scene must exercise both outcomes and leave almost every pixel unambiguous.
    assert!(covered > 1000, "only {covered} covered pixels");
    assert!(
        ambiguous * 100 < (cam.width * cam.height) as usize,
        "{ambiguous} ambiguous pixels"
    );
}

#[test]
fn supersampled_surfels_average_the_covered_samples() {
    let s = random_surfels(40, 11);
    let cam = camera(64, 48);
    let opts = GesOptions {
        supersample: 4,
        ..plain()
    };
    let (frame, _) = render_ges(&s, &GaussianCloud::new(1), &cam, &opts).unwrap();
    let offs = splatbridge_hybrid::ges::surfel_pass::OFFSETS_4;
    let refs: Vec<ZRef> = offs
        .iter()
        .map(|o| zbuffer_reference(&s, &cam, opts.near as f64, [o[0] as f64, o[1] as f64]))
        .collect();
    let mut checked = 0;
    for p in 0..(cam.width * cam.height) as usize {
        if refs.iter().any(|r| r.ambiguous[p]) {
            continue;
        }
        let hits: Vec<usize> = refs.iter().filter_map(|r| r.winner[p]).collect();
        let k = hits.len() as f64;
        let ws = k / 4.0;
        let cs = hits.iter().fold(DVec3::ZERO, |a, &i| {
            a + surfel_color(&s, i, &cam).as_dvec3()
        }) / k.max(1.0);
        let bg = DVec3::from_array(opts.background.map(|v| v as f64));
        // Partial coverage mixes the surfel rule and the background by coverage (no Gaussians).
        let want = if k > 0.0 {
            cs * ws + bg * (1.0 - ws)
        } else {
            bg
        };
        let got = DVec3::new(
            frame.rgb[3 * p] as f64,
            frame.rgb[3 * p + 1] as f64,
            frame.rgb[3 * p + 2] as f64,
        );
        // f32 mean of ≤ 4 colours ≤ ~2 and the mix: a few ulp of 2 (2.4e-7 each); 2e-6 bound.
        assert!(
            (got - want).abs().max_element() < 2e-6,
            "pixel {p}: {got} vs {want}"
        );
        assert!((frame.alpha[p] as f64 - ws).abs() < 1e-7);
        checked += 1;
    }
    assert!(checked * 100 > 95 * (cam.width * cam.height) as usize);
}

/// A wall surfel filling the view at z = 5 and a few Gaussians in front of it.
fn wall_scene() -> (SurfelCloud, GaussianCloud, Camera) {
    let cam = Camera::look_at(DVec3::ZERO, DVec3::Z, DVec3::NEG_Y, 50.0, 80, 64).unwrap();
    let mut s = SurfelCloud::new(0);
    let (su, sv) = (4.0f32, 4.0f32);
    s.push(
        Vec3::new(0.0, 0.0, 5.0),
        Vec3::X,
        Vec3::Y,
        [su, sv],
        ges_mean_scale(su, sv) * 0.01,
        &[Vec3::new(0.3, -0.2, 0.1)],
    );
    let mut g = GaussianCloud::new(0);
    g.push_activated(
        Vec3::new(0.2, 0.1, 3.0),
        Vec3::splat(0.2),
        Quat::IDENTITY,
        0.8,
        Vec3::new(1.0, 0.2, 0.1),
    );
    g.push_activated(
        Vec3::new(-0.4, -0.3, 4.0),
        Vec3::new(0.3, 0.1, 0.2),
        Quat::from_rotation_z(0.4),
        0.5,
        Vec3::new(0.1, 0.9, 0.3),
    );
    (s, g, cam)
}

#[test]
fn gaussians_behind_a_surfel_change_nothing() {
    let (s, g, cam) = wall_scene();
    let opts = plain();
    let (base, base_stats) = render_ges(&s, &g, &cam, &opts).unwrap();
    assert!(
        base.alpha.iter().all(|&a| a == 1.0),
        "the wall must cover the view"
    );
    // ε = 5·mean_scale = 5·0.01·0.35·8 = 0.14: Gaussians at z ≥ 6 are far beyond it.
    let mut behind = g.clone();
    let mut rng = splatbridge_scene::rng::Rng::new(3);
    for _ in 0..200 {
        let m = Vec3::new(
            rng.range(-3.0, 3.0),
            rng.range(-2.0, 2.0),
            rng.range(6.0, 9.0),
        );
        behind.push_activated(
            m,
            Vec3::splat(rng.range(0.05, 0.8)),
            Quat::IDENTITY,
            rng.range(0.1, 1.0),
            Vec3::new(rng.f32(), rng.f32(), rng.f32()),
        );
    }
    let (more, more_stats) = render_ges(&s, &behind, &cam, &opts).unwrap();
    assert_bit_identical(&base, &more, "Gaussians behind the wall");
    assert!(
        more_stats.culled_pairs > base_stats.culled_pairs,
        "the tile cull should drop them"
    );
    // Control: a Gaussian just behind the wall but within ε does count.
    let mut within = g.clone();
    within.push_activated(
        Vec3::new(0.0, 0.0, 5.1),
        Vec3::splat(0.3),
        Quat::IDENTITY,
        0.9,
        Vec3::ONE,
    );
    let (w, _) = render_ges(&s, &within, &cam, &opts).unwrap();
    assert!(w.max_rgb_diff(&base) > 0.05);
}

/// f64 projection of an isotropic Gaussian (scale σ, mean on the camera's axis-aligned plane
/// z) for a camera at the origin looking along +z: centre `(f·x/z + c')`, variance
/// `(f·σ/z)² + 0.3` per axis (the Jacobian is diagonal-plus-rank-one; for σ isotropic the 2D
/// covariance is `f²σ²/z²·(I + m·mᵀ/z²)`-free only at the axis, so the means are kept near it and
/// the full J·Σ·Jᵀ is formed here).
fn project_iso(cam: &Camera, m: DVec3, sigma: f64) -> (f64, f64, [f64; 3], f64) {
    let t = cam.world_to_cam * (m - cam.centre);
    let (fx, fy) = (cam.fx, cam.fy);
    let j0 = DVec3::new(fx / t.z, 0.0, -fx * t.x / (t.z * t.z));
    let j1 = DVec3::new(0.0, fy / t.z, -fy * t.y / (t.z * t.z));
    let s2 = sigma * sigma;
    let (a, b, c) = (
        s2 * j0.dot(j0) + 0.3,
        s2 * j0.dot(j1),
        s2 * j1.dot(j1) + 0.3,
    );
    let det = a * c - b * b;
    let x = fx * t.x / t.z + cam.cx - 0.5;
    let y = fy * t.y / t.z + cam.cy - 0.5;
    (x, y, [c / det, -b / det, a / det], t.z)
}

#[test]
fn no_surfels_pass_two_follows_the_documented_formula() {
    let cam = Camera::look_at(DVec3::ZERO, DVec3::Z, DVec3::NEG_Y, 40.0, 48, 40).unwrap();
    let g1 = (
        DVec3::new(0.1, 0.05, 4.0),
        0.15,
        0.7f64,
        DVec3::new(0.8, 0.4, 0.2),
    );
    let g2 = (
        DVec3::new(-0.1, 0.0, 5.0),
        0.2,
        0.5f64,
        DVec3::new(0.1, 0.5, 0.9),
    );
    let opts = plain();
    let bg = DVec3::from_array(opts.background.map(|v| v as f64));
    for two in [false, true] {
        let mut cloud = GaussianCloud::new(0);
        let gs = if two { vec![g1, g2] } else { vec![g1] };
        for g in &gs {
            cloud.push_activated(
                g.0.as_vec3(),
                Vec3::splat(g.1 as f32),
                Quat::IDENTITY,
                g.2 as f32,
                g.3.as_vec3(),
            );
        }
        let (frame, _) = render_ges(&SurfelCloud::new(0), &cloud, &cam, &opts).unwrap();
        let proj: Vec<_> = gs
            .iter()
            .map(|g| (project_iso(&cam, g.0, g.1), g.2, g.3))
            .collect();
        let mut lit = 0;
        for py in 0..cam.height as usize {
            for px in 0..cam.width as usize {
                let (mut cg, mut wg, mut t, mut dz) = (DVec3::ZERO, 0.0, 1.0, 0.0);
                let mut ambiguous = false;
                for ((x, y, q, z), o, col) in &proj {
                    let (dx, dy) = (x - px as f64, y - py as f64);
                    let a = o * (-0.5 * (q[0] * dx * dx + q[2] * dy * dy) - q[1] * dx * dy).exp();
                    // The 1/255 skip, f32 against f64: relative 1e-4 (see the native tests).
                    ambiguous |= (a * 255.0 - 1.0).abs() < 1e-4;
                    if a >= 1.0 / 255.0 {
                        cg += *col * a;
                        wg += a;
                        t *= 1.0 - a;
                        dz += a * z;
                    }
                }
                if ambiguous {
                    continue;
                }
                // The documented no-surfel rule: (C_G/W_G)(1 − T) + background·T.
                let want = if wg > 0.0 {
                    cg / wg * (1.0 - t) + bg * t
                } else {
                    bg
                };
                let p = py * cam.width as usize + px;
                let got = DVec3::new(
                    frame.rgb[3 * p] as f64,
                    frame.rgb[3 * p + 1] as f64,
                    frame.rgb[3 * p + 2] as f64,
                );
                // f32 projection and the polynomial exp (≤ 3.6e-7 relative) against f64: the
                // screen mean is rounded to ~2e-6 px, moving α by ≤ 2.4e-5 relative at the
                // footprint edge (see the native tests); 3e-5 absolute on values ≤ 1.
                assert!(
                    (got - want).abs().max_element() < 3e-5,
                    "two={two} pixel ({px},{py}): {got} vs {want}"
                );
                assert!((frame.alpha[p] as f64 - (1.0 - t)).abs() < 3e-5);
                let zd = if wg > 0.0 { dz / wg } else { 0.0 };
                assert!((frame.depth[p] as f64 - zd).abs() < 1e-5 * zd.max(1.0));
                lit += (wg > 0.0) as usize;
            }
        }
        assert!(lit > 100, "two={two}: only {lit} lit pixels");
        if !two {
            // One Gaussian: exactly the native over-composite α·c + (1 − α)·background.
            let (x, y) = (proj[0].0 .0.round() as usize, proj[0].0 .1.round() as usize);
            let p = y * cam.width as usize + x;
            assert!(frame.alpha[p] > 0.6);
        }
    }
}

#[test]
fn covered_pixels_follow_the_ges_formula() {
    let (s, g, cam) = wall_scene();
    let opts = plain();
    let (frame, _) = render_ges(&s, &g, &cam, &opts).unwrap();
    let cs = surfel_color(&s, 0, &cam).as_dvec3();
    let mut max_err = 0.0f64;
    for py in 0..cam.height as usize {
        for px in 0..cam.width as usize {
            let (mut cg, mut wg) = (DVec3::ZERO, 0.0);
            let mut ambiguous = false;
            for i in 0..g.len() {
                let (x, y, q, _) = project_aniso(&cam, &g, i);
                let (dx, dy) = (x - px as f64, y - py as f64);
                let a = g.opacity(i) as f64
                    * (-0.5 * (q[0] * dx * dx + q[2] * dy * dy) - q[1] * dx * dy).exp();
                ambiguous |= (a * 255.0 - 1.0).abs() < 1e-4;
                if a >= 1.0 / 255.0 {
                    let col = (g.sh_of(i)[0].as_dvec3() * 0.28209479177387814 + DVec3::splat(0.5))
                        .max(DVec3::ZERO);
                    cg += col * a;
                    wg += a;
                }
            }
            if ambiguous {
                continue;
            }
            let want = (cs + cg) / (1.0 + wg);
            let p = py * cam.width as usize + px;
            let got = DVec3::new(
                frame.rgb[3 * p] as f64,
                frame.rgb[3 * p + 1] as f64,
                frame.rgb[3 * p + 2] as f64,
            );
            max_err = max_err.max((got - want).abs().max_element());
        }
    }
    // As in the no-surfel case: 3e-5.
    assert!(max_err < 3e-5, "max error {max_err}");
}

#[test]
fn output_does_not_depend_on_the_thread_count() {
    let s = random_surfels(80, 21);
    let g = random_gaussians(3000, 22);
    let cam = camera(150, 110);
    let opts = GesOptions {
        supersample: 4,
        blur: true,
        ..plain()
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| render_ges(&s, &g, &cam, &opts).unwrap().0)
    };
    let one = run(1);
    assert!(one.is_finite());
    for n in [2, 3, 5] {
        assert_bit_identical(&one, &run(n), &format!("{n} threads"));
    }
}

#[test]
fn hard_cases_stay_finite() {
    let opts = GesOptions {
        supersample: 4,
        blur: true,
        ..plain()
    };
    let cam = Camera::look_at(DVec3::ZERO, DVec3::Z, DVec3::NEG_Y, 60.0, 64, 48).unwrap();
    let g = random_gaussians(200, 5);
    // Edge-on: the plane contains the camera centre (n·c = 0), and nearly so.
    let mut s = SurfelCloud::new(0);
    let c0 = [Vec3::ZERO];
    s.push(
        Vec3::new(0.0, 0.0, 3.0),
        Vec3::Z,
        Vec3::Y,
        [1.0, 1.0],
        0.7,
        &c0,
    );
    s.push(
        Vec3::new(0.5, 0.0, 3.0),
        Vec3::Z,
        Vec3::new(1e-7, 1.0, 0.0).normalize(),
        [1.0, 1.0],
        0.7,
        &c0,
    );
    // Camera inside: a surfel straddling the camera (the near plane cuts it), and one through it.
    s.push(
        Vec3::new(0.0, 0.1, 0.0),
        Vec3::X,
        Vec3::Z,
        [2.0, 2.0],
        1.4,
        &c0,
    );
    s.push(
        Vec3::new(0.0, 0.0, 0.1),
        Vec3::X,
        Vec3::Y,
        [5.0, 5.0],
        3.5,
        &c0,
    );
    // Degenerate scales.
    s.push(
        Vec3::new(0.0, 0.0, 2.0),
        Vec3::X,
        Vec3::Y,
        [0.0, 1.0],
        0.35,
        &c0,
    );
    s.push(
        Vec3::new(0.0, 0.0, 2.0),
        Vec3::X,
        Vec3::Y,
        [1e-30, 1e-30],
        1e-30,
        &c0,
    );
    let (f, _) = render_ges(&s, &g, &cam, &opts).unwrap();
    assert!(f.is_finite());
    // The straddling surfel fills the lower half of the view (its part at z > near).
    assert!(f.alpha.contains(&1.0));

    // 1e5 units from the origin: the same scene shifted with the camera gives the same image up
    // to f32 rounding of the stored positions (ulp of 1e5 is 0.0078; shifts of that size move
    // surfel edges by under a pixel here, so compare coverage counts and finiteness).
    let s0 = random_surfels(50, 9);
    let g0 = random_gaussians(500, 10);
    let cam0 = camera(64, 48);
    let off = Vec3::new(1e5, -1e5, 1e5);
    let mut s1 = s0.clone();
    s1.means.iter_mut().for_each(|m| *m += off);
    let mut g1 = g0.clone();
    g1.means.iter_mut().for_each(|m| *m += off);
    let mut cam1 = cam0.clone();
    cam1.centre += off.as_dvec3();
    let (a, _) = render_ges(&s0, &g0, &cam0, &opts).unwrap();
    let (b, _) = render_ges(&s1, &g1, &cam1, &opts).unwrap();
    assert!(a.is_finite() && b.is_finite());
    let cov = |f: &Frame| f.alpha.iter().filter(|&&v| v == 1.0).count() as f64;
    assert!(
        cov(&b) > 0.9 * cov(&a) && cov(&b) < 1.1 * cov(&a),
        "{} vs {}",
        cov(&a),
        cov(&b)
    );
}
