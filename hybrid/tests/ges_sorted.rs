//! The hybrid's sorted blend (`Blend::Sorted`): with no surfels it is the native renderer bit
//! for bit; with a surfel wall it follows an f64 front-to-back reference in which the surfel is
//! an opaque layer at its depth limit `D_S + ε`.

mod ges_common;

use ges_common::*;
use glam::{DVec3, Quat, Vec3};
use splatbridge_hybrid::ges::{render_ges, Blend, GesOptions};
use splatbridge_hybrid::{render, Extent, RenderOptions};
use splatbridge_scene::surfels::{ges_mean_scale, SurfelCloud};
use splatbridge_scene::{Camera, Frame, GaussianCloud};

fn sorted() -> GesOptions {
    GesOptions {
        background: [0.1, 0.2, 0.3],
        blend: Blend::Sorted,
        ..Default::default()
    }
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn assert_bit_identical(a: &Frame, b: &Frame, what: &str) {
    assert!(bits(&a.rgb) == bits(&b.rgb), "{what}: rgb differs");
    assert!(bits(&a.alpha) == bits(&b.alpha), "{what}: alpha differs");
    assert!(bits(&a.depth) == bits(&b.depth), "{what}: depth differs");
}

/// With no surfels the sorted hybrid is the native renderer (same extent and background), bit
/// for bit, including exact depth ties (duplicated means with different colours, listed in
/// both orders) and a camera inside the cloud.
#[test]
fn no_surfels_sorted_blend_is_native() {
    let mut cloud = random_gaussians(3000, 21);
    // Exact ties: same mean (so the same depth), different colours and opacities.
    for k in 0..40 {
        let m = Vec3::new(0.05 * k as f32 - 1.0, 0.3, 0.2);
        let (a, b) = (Vec3::new(1.0, 0.1, 0.1), Vec3::new(0.1, 0.1, 1.0));
        let (first, second) = if k % 2 == 0 { (a, b) } else { (b, a) };
        cloud.push_activated(m, Vec3::splat(0.15), Quat::IDENTITY, 0.6, first);
        cloud.push_activated(m, Vec3::splat(0.15), Quat::IDENTITY, 0.7, second);
    }
    let opts = sorted();
    let native = RenderOptions {
        extent: Extent::Alpha,
        background: opts.background,
        ..Default::default()
    };
    let inside = Camera::look_at(
        DVec3::new(0.2, 0.1, -0.5),
        DVec3::new(0.0, 0.0, 3.0),
        DVec3::NEG_Y,
        70.0,
        90,
        70,
    )
    .unwrap();
    for (what, cam) in [("outside", camera(120, 90)), ("inside", inside)] {
        let (h, stats) = render_ges(&SurfelCloud::new(1), &cloud, &cam, &opts).unwrap();
        let (n, nstats) = render(&cloud, &cam, &native).unwrap();
        assert!(
            stats.blends > 10_000,
            "{what}: only {} blends",
            stats.blends
        );
        assert_eq!(stats.blends, nstats.blends, "{what}: blends");
        assert_bit_identical(&h, &n, what);
    }
    // Control: the unsorted blend is not native on this cloud, so the comparison can fail.
    let cam = camera(120, 90);
    let unsorted = GesOptions {
        blend: Blend::Unsorted,
        ..opts
    };
    let (u, _) = render_ges(&SurfelCloud::new(1), &cloud, &cam, &unsorted).unwrap();
    let (n, _) = render(&cloud, &cam, &native).unwrap();
    assert!(u.max_rgb_diff(&n) > 0.05, "{}", u.max_rgb_diff(&n));
}

/// One surfel wall at z = 5 filling the view, Gaussians in front of it, within ε behind its
/// plane, and far behind it.
fn wall_scene() -> (SurfelCloud, GaussianCloud, Camera, f64) {
    let cam = Camera::look_at(DVec3::ZERO, DVec3::Z, DVec3::NEG_Y, 50.0, 80, 64).unwrap();
    let mut s = SurfelCloud::new(0);
    let (su, sv) = (4.0f32, 4.0f32);
    let mean_scale = ges_mean_scale(su, sv) * 0.01;
    s.push(
        Vec3::new(0.0, 0.0, 5.0),
        Vec3::X,
        Vec3::Y,
        [su, sv],
        mean_scale,
        &[Vec3::new(0.3, -0.2, 0.1)],
    );
    let mut g = GaussianCloud::new(0);
    let mut rng = splatbridge_scene::rng::Rng::new(8);
    for k in 0..60 {
        // Depths: most in front (2–4.9), some within ε (5–5.1), some far behind (6–8).
        let z = match k % 6 {
            0 => rng.range(5.0, 5.1),
            1 => rng.range(6.0, 8.0),
            _ => rng.range(2.0, 4.9),
        };
        let m = Vec3::new(
            rng.range(-0.8, 0.8) * z / 3.0,
            rng.range(-0.6, 0.6) * z / 3.0,
            z,
        );
        g.push_activated(
            m,
            Vec3::new(
                rng.range(0.03, 0.3),
                rng.range(0.03, 0.3),
                rng.range(0.03, 0.3),
            ),
            random_rotation(&mut rng),
            rng.range(0.1, 1.0),
            Vec3::new(rng.f32(), rng.f32(), rng.f32()),
        );
    }
    let eps = sorted().epsilon_factor as f64 * mean_scale as f64;
    (s, g, cam, 5.0 + eps)
}

/// [`screen_cov`] as the renderer uses it: centre, conic, view depth, and the reference's tile
/// rectangle `[x0, y0, x1, y1)` (its `getRect` of the `α ≥ 1/255` radius: tiles from
/// `⌊(c − r)/16⌋` to `⌊(c + r + 15)/16⌋` exclusive, which can leave out the last pixel row or
/// column the radius reaches; native splatting inherits that, so the reference must too).
fn project(cam: &Camera, g: &GaussianCloud, i: usize) -> (f64, f64, [f64; 3], f64, [i64; 4]) {
    let (x, y, [a, b, c], depth) = screen_cov(cam, g, i);
    let det = a * c - b * b;
    let mid = 0.5 * (a + c);
    let lambda = mid + (mid * mid - det).max(0.1).sqrt();
    let r = ((2.0 * (255.0 * g.opacity(i) as f64).ln()).sqrt() * lambda.sqrt()).ceil();
    let rect = [
        ((x - r) / 16.0) as i64,
        ((y - r) / 16.0) as i64,
        ((x + r + 15.0) / 16.0) as i64,
        ((y + r + 15.0) / 16.0) as i64,
    ];
    (x, y, [c / det, -b / det, a / det], depth, rect)
}

/// Every pixel against the f64 front-to-back reference: the Gaussians with depth ≤ `D_S + ε` in
/// depth order with native's rules (α clamp 0.99, 1/255 skip, stop before `T < 1e-4`), then the
/// surfel colour times the remaining transmittance.
#[test]
fn surfel_wall_is_an_opaque_layer_behind_sorted_gaussians() {
    let (s, g, cam, limit) = wall_scene();
    let opts = sorted();
    let (frame, _) = render_ges(&s, &g, &cam, &opts).unwrap();
    let cs = surfel_color(&s, 0, &cam).as_dvec3();
    let mut order: Vec<usize> = (0..g.len()).collect();
    let proj: Vec<_> = (0..g.len()).map(|i| project(&cam, &g, i)).collect();
    order.sort_by(|&a, &b| proj[a].3.total_cmp(&proj[b].3));
    let (mut max_err, mut checked, mut behind_lit) = (0.0f64, 0, 0);
    for py in 0..cam.height as usize {
        for px in 0..cam.width as usize {
            let (mut c, mut t) = (DVec3::ZERO, 1.0f64);
            let mut ambiguous = false;
            let (tx, ty) = ((px / 16) as i64, (py / 16) as i64);
            for &i in &order {
                let (x, y, q, z, rect) = proj[i];
                if !(rect[0] <= tx && tx < rect[2] && rect[1] <= ty && ty < rect[3]) {
                    continue;
                }
                let (dx, dy) = (x - px as f64, y - py as f64);
                let a = g.opacity(i) as f64
                    * (-0.5 * (q[0] * dx * dx + q[2] * dy * dy) - q[1] * dx * dy).exp();
                // The 1/255 skip and the early stop, f32 against f64: relative 1e-4 (see the
                // native tests).
                ambiguous |= (a * 255.0 - 1.0).abs() < 1e-4;
                if z > limit {
                    behind_lit += (a >= 1.0 / 255.0) as usize;
                    continue;
                }
                let a = a.min(0.99);
                if a < 1.0 / 255.0 {
                    continue;
                }
                let next = t * (1.0 - a);
                ambiguous |= (next / 1e-4 - 1.0).abs() < 1e-3;
                if next < 1e-4 {
                    break;
                }
                let col = (g.sh_of(i)[0].as_dvec3() * 0.28209479177387814 + DVec3::splat(0.5))
                    .max(DVec3::ZERO);
                c += col * a * t;
                t = next;
            }
            if ambiguous {
                continue;
            }
            let want = c + cs * t;
            let p = py * cam.width as usize + px;
            let got = DVec3::new(
                frame.rgb[3 * p] as f64,
                frame.rgb[3 * p + 1] as f64,
                frame.rgb[3 * p + 2] as f64,
            );
            max_err = max_err.max((got - want).abs().max_element());
            assert_eq!(frame.alpha[p], 1.0, "pixel ({px},{py}) alpha");
            checked += 1;
        }
    }
    // The scene must exercise the cut: Gaussians behind the limit that would otherwise show.
    assert!(
        behind_lit > 200,
        "only {behind_lit} pixels with a hidden Gaussian"
    );
    assert!(checked > 4000, "only {checked} pixels checked");
    // As the unsorted pass's formula tests: f32 projection and the polynomial exp against f64,
    // 3e-5 absolute on values ≤ 1.
    assert!(max_err < 3e-5, "max error {max_err}");
}

/// The sorted pass is the same image for any thread count.
#[test]
fn sorted_blend_does_not_depend_on_the_thread_count() {
    let s = random_surfels(80, 3);
    let g = random_gaussians(2000, 4);
    let cam = camera(100, 80);
    let opts = sorted();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| render_ges(&s, &g, &cam, &opts).unwrap().0);
    let many = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap()
        .install(|| render_ges(&s, &g, &cam, &opts).unwrap().0);
    assert_bit_identical(&one, &many, "threads");
}
