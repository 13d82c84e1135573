//! Image metrics against independently computed values: hand-derived PSNR, closed-form SSIM of
//! constant images, and a brute-force f64 SSIM (direct 2D window sums, no separability) on
//! small random images.

use splatbridge_scene::metrics::{
    heatmap, heatmap_scaled, max_abs_error, mse, psnr, ramp, ssim, ssim_with, tile_ssim,
    SsimWindow, SSIM_C1, SSIM_C2,
};
use splatbridge_scene::rng::Rng;
use splatbridge_scene::Frame;

fn constant(w: u32, h: u32, v: [f32; 3]) -> Frame {
    let mut f = Frame::new(w, h);
    for p in f.rgb.chunks_exact_mut(3) {
        p.copy_from_slice(&v);
    }
    f
}

fn random(w: u32, h: u32, seed: u64) -> Frame {
    let mut rng = Rng::new(seed);
    let mut f = Frame::new(w, h);
    for v in &mut f.rgb {
        *v = rng.f32();
    }
    f
}

/// Brute-force SSIM: for every pixel, sum the 11×11 window directly (zero outside the image),
/// the window built from its own formula; mean over the chosen pixels and channels.
fn ssim_brute(a: &Frame, b: &Frame, valid: bool) -> f64 {
    let (w, h) = (a.width as i64, a.height as i64);
    let mut win = [[0.0f64; 11]; 11];
    let mut total = 0.0;
    for (i, row) in win.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let (di, dj) = (i as f64 - 5.0, j as f64 - 5.0);
            *v = (-(di * di + dj * dj) / (2.0 * 1.5 * 1.5)).exp();
            total += *v;
        }
    }
    let px = |f: &Frame, x: i64, y: i64, c: usize| -> f64 {
        if x < 0 || y < 0 || x >= w || y >= h {
            0.0
        } else {
            (f.rgb[3 * (y * w + x) as usize + c] as f64).clamp(0.0, 1.0)
        }
    };
    let mut sum = 0.0;
    let mut count = 0usize;
    for c in 0..3 {
        for y in 0..h {
            for x in 0..w {
                if valid && (x < 5 || y < 5 || x >= w - 5 || y >= h - 5) {
                    continue;
                }
                let (mut mx, mut my, mut xx, mut yy, mut xy) = (0.0, 0.0, 0.0, 0.0, 0.0);
                for i in 0..11i64 {
                    for j in 0..11i64 {
                        let g = win[i as usize][j as usize] / total;
                        let (p, q) = (
                            px(a, x + j - 5, y + i - 5, c),
                            px(b, x + j - 5, y + i - 5, c),
                        );
                        mx += g * p;
                        my += g * q;
                        xx += g * p * p;
                        yy += g * q * q;
                        xy += g * p * q;
                    }
                }
                let (sx, sy, sxy) = (xx - mx * mx, yy - my * my, xy - mx * my);
                sum += ((2.0 * mx * my + SSIM_C1) * (2.0 * sxy + SSIM_C2))
                    / ((mx * mx + my * my + SSIM_C1) * (sx + sy + SSIM_C2));
                count += 1;
            }
        }
    }
    sum / count as f64
}

#[test]
fn psnr_of_a_constant_offset_of_a_tenth_is_20_db() {
    let a = constant(16, 9, [0.3, 0.3, 0.3]);
    let b = constant(16, 9, [0.4, 0.4, 0.4]);
    // MSE = 0.01 → 10·log10(100) = 20 dB. In f32, 0.4 − 0.3 = 0.099999994 (6e-8 relative
    // below 0.1), which moves the PSNR by 10·log10(1 + 1.2e-7) ≈ 5.2e-7 dB.
    assert!((psnr(&a, &b).unwrap() - 20.0).abs() < 1e-6);
    // The exact value for the f32 inputs, derived in f64 (error ~1e-16 relative).
    let d = 0.4f32 as f64 - 0.3f32 as f64;
    assert!((mse(&a, &b).unwrap() - d * d).abs() < 1e-17);
    assert!((psnr(&a, &b).unwrap() + 10.0 * (d * d).log10()).abs() < 1e-12);
}

#[test]
fn psnr_of_half_the_pixels_off_by_a_half() {
    // Left half differs by 0.5 in every channel: MSE = 0.25 / 2, PSNR = 10·log10(8).
    let a = constant(8, 4, [0.25, 0.25, 0.25]);
    let mut b = a.clone();
    for y in 0..4 {
        for x in 0..4 {
            let i = 3 * (y * 8 + x);
            b.rgb[i..i + 3].copy_from_slice(&[0.75; 3]);
        }
    }
    let expected = 10.0 * 8f64.log10();
    assert!(
        (psnr(&a, &b).unwrap() - expected).abs() < 1e-12,
        "{}",
        psnr(&a, &b).unwrap()
    );
    assert_eq!(max_abs_error(&a, &b).unwrap(), 0.5);
}

#[test]
fn identical_images_give_infinite_psnr_after_clamping() {
    let a = random(7, 5, 1);
    assert_eq!(psnr(&a, &a).unwrap(), f64::INFINITY);
    let hi = constant(4, 4, [1.0, 2.0, 0.0]);
    let hi2 = constant(4, 4, [1.5, 1.0, -3.0]);
    assert_eq!(psnr(&hi, &hi2).unwrap(), f64::INFINITY);
    assert_eq!(max_abs_error(&hi, &hi2).unwrap(), 0.0);
    // NaN counts as 0: against black it is identical, against white the worst.
    let nan = constant(4, 4, [f32::NAN; 3]);
    assert_eq!(
        psnr(&nan, &constant(4, 4, [0.0; 3])).unwrap(),
        f64::INFINITY
    );
    assert_eq!(psnr(&nan, &constant(4, 4, [1.0; 3])).unwrap(), 0.0);
}

#[test]
fn ssim_of_identical_images_is_one() {
    for (w, h) in [(32, 24), (5, 3)] {
        let a = random(w, h, 7);
        assert!((ssim(&a, &a).unwrap() - 1.0).abs() < 1e-12);
    }
    let a = random(32, 24, 8);
    assert!((ssim_with(&a, &a, SsimWindow::Valid).unwrap() - 1.0).abs() < 1e-12);
}

#[test]
fn ssim_of_constant_images_is_the_luminance_term() {
    // With the window inside the image, σ = 0 and SSIM = (2μxμy + C1)/(μx² + μy² + C1);
    // the residual from window weights summing to 1 ± 1e-16 is ~1e-13 in the contrast term.
    let (mx, my) = (0.3f32, 0.5f32);
    let a = constant(40, 30, [mx; 3]);
    let b = constant(40, 30, [my; 3]);
    let (mx, my) = (mx as f64, my as f64);
    let expected = (2.0 * mx * my + SSIM_C1) / (mx * mx + my * my + SSIM_C1);
    let got = ssim_with(&a, &b, SsimWindow::Valid).unwrap();
    assert!((got - expected).abs() < 1e-10, "{got} vs {expected}");
    // Zero padding darkens the borders of both images, which changes the value.
    let padded = ssim(&a, &b).unwrap();
    assert!(
        (padded - expected).abs() > 1e-4,
        "zero padding should differ at the border"
    );
}

#[test]
fn ssim_matches_a_brute_force_double_loop() {
    // Brute force and the separable implementation differ only in f64 summation order:
    // ~1e-15 per value, far below the 1e-12 allowed.
    for (w, h, seed) in [(23, 17, 1), (11, 11, 2), (6, 4, 3), (31, 12, 4)] {
        let a = random(w, h, seed);
        let mut b = a.clone();
        let mut rng = Rng::new(seed + 100);
        for v in &mut b.rgb {
            *v += 0.2 * (rng.f32() - 0.5);
        }
        let got = ssim(&a, &b).unwrap();
        let want = ssim_brute(&a, &b, false);
        assert!((got - want).abs() < 1e-12, "{w}×{h}: {got} vs {want}");
        assert!(got < 0.999, "noise must lower SSIM: {got}");
        if w >= 11 && h >= 11 {
            let got = ssim_with(&a, &b, SsimWindow::Valid).unwrap();
            let want = ssim_brute(&a, &b, true);
            assert!((got - want).abs() < 1e-12, "{w}×{h} valid: {got} vs {want}");
        }
    }
}

#[test]
fn valid_ssim_rejects_images_smaller_than_the_window() {
    let a = random(10, 20, 1);
    assert!(ssim_with(&a, &a, SsimWindow::Valid).is_err());
}

#[test]
fn tile_ssim_is_the_mean_of_per_tile_ssim() {
    let a = random(20, 13, 5);
    let mut b = a.clone();
    for (i, v) in b.rgb.iter_mut().enumerate() {
        *v += if i % 7 == 0 { 0.3 } else { 0.0 };
    }
    // Tiles of 8: columns 0..8, 8..16, 16..20; rows 0..8, 8..13 → six tiles.
    let crop = |f: &Frame, x0: u32, y0: u32, tw: u32, th: u32| {
        let mut o = Frame::new(tw, th);
        for y in 0..th {
            for x in 0..tw {
                for c in 0..3 {
                    o.rgb[(3 * (y * tw + x) + c) as usize] =
                        f.rgb[(3 * ((y0 + y) * f.width + x0 + x) + c) as usize];
                }
            }
        }
        o
    };
    let mut sum = 0.0;
    for (x0, tw) in [(0, 8), (8, 8), (16, 4)] {
        for (y0, th) in [(0, 8), (8, 5)] {
            sum += ssim_brute(&crop(&a, x0, y0, tw, th), &crop(&b, x0, y0, tw, th), false);
        }
    }
    let got = tile_ssim(&a, &b, 8).unwrap();
    assert!((got - sum / 6.0).abs() < 1e-12, "{got} vs {}", sum / 6.0);
    // One tile covering everything is plain SSIM.
    assert!((tile_ssim(&a, &b, 64).unwrap() - ssim(&a, &b).unwrap()).abs() < 1e-15);
    assert!(tile_ssim(&a, &b, 0).is_err());
}

#[test]
fn heatmap_maps_errors_through_the_ramp() {
    let a = constant(3, 1, [0.5; 3]);
    let mut b = a.clone();
    b.rgb[3] = 0.55; // pixel 1: error 0.05 = half of full scale
    b.rgb[8] = 0.0; // pixel 2: error 0.5 ≥ full scale
    let img = heatmap(&a, &b).unwrap();
    assert_eq!((img.width, img.height), (3, 1));
    assert_eq!(&img.data[0..3], &[0, 0, 4]);
    // 0.55f32 − 0.5 is 0.05 to ~1e-8, i.e. t = 0.5 ± 1e-7: ramp(0.5) is a stop, colour exact.
    assert_eq!(&img.data[3..6], &ramp(0.5));
    assert_eq!(ramp(0.5), [188, 55, 84]);
    assert_eq!(&img.data[6..9], &[252, 255, 164]);
    // A larger full scale dims the same error.
    let dim = heatmap_scaled(&a, &b, 1.0).unwrap();
    assert_eq!(&dim.data[6..9], &ramp(0.5));
    assert!(heatmap_scaled(&a, &b, 0.0).is_err());
}

#[test]
fn ramp_is_monotone_in_brightness_and_handles_nan() {
    let lum = |c: [u8; 3]| c[0] as u32 * 3 + c[1] as u32 * 6 + c[2] as u32;
    let mut last = 0;
    for i in 0..=100 {
        let l = lum(ramp(i as f32 / 100.0));
        assert!(l >= last, "ramp darkens at {i}");
        last = l;
    }
    assert_eq!(ramp(f32::NAN), ramp(1.0));
    assert_eq!(ramp(-1.0), ramp(0.0));
}

#[test]
fn mismatched_sizes_are_an_error_not_a_panic() {
    let a = Frame::new(4, 4);
    let b = Frame::new(4, 5);
    for r in [psnr(&a, &b), ssim(&a, &b), tile_ssim(&a, &b, 2)] {
        let e = r.unwrap_err().to_string();
        assert!(e.contains("4×4") && e.contains("4×5"), "{e}");
    }
    assert!(max_abs_error(&a, &b).is_err());
    assert!(heatmap(&a, &b).is_err());
    assert!(psnr(&Frame::new(0, 0), &Frame::new(0, 0)).is_err());
}

/// MSE and SSIM are the same bits whatever the thread pool: a run that traces the same images
/// (sharded, or on another machine) reports the same figures. A parallel `sum` associated its
/// partials as the pool split the work, and a merged run's PSNR then differed from the
/// unsharded run's in its last bits.
#[test]
fn mse_and_ssim_do_not_depend_on_the_thread_count() {
    // 1920×1080 values: many chunks, so each pool splits the work its own way.
    let (a, b) = (random(1920, 1080, 11), random(1920, 1080, 12));
    let (small_a, small_b) = (random(200, 150, 13), random(200, 150, 14));
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                (
                    mse(&a, &b).unwrap().to_bits(),
                    ssim(&small_a, &small_b).unwrap().to_bits(),
                )
            })
    };
    let one = run(1);
    for threads in [2, 3, 4, 7] {
        for _ in 0..3 {
            assert_eq!(run(threads), one, "{threads} threads");
        }
    }
    // And the chunked sum is the mean of squares: a sequential f64 sum of n non-negative
    // terms is within n·ε of the exact sum (relative; the chunked one is tighter), so the two
    // agree to n·ε (6.2 M terms: 1.4e-9).
    let seq: f64 = a
        .rgb
        .iter()
        .zip(&b.rgb)
        .map(|(&x, &y)| ((x as f64) - (y as f64)).powi(2))
        .sum::<f64>()
        / a.rgb.len() as f64;
    let got = f64::from_bits(one.0);
    let n = a.rgb.len() as f64;
    assert!(
        (got - seq).abs() <= n * f64::EPSILON * seq,
        "{got} vs {seq}"
    );
}
