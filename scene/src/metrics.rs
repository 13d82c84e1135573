//! Image metrics against a reference: PSNR, SSIM, tile-SSIM, max absolute error, and a
//! difference heat-map.
//!
//! Every metric works on the RGB planes with values clamped to [0, 1] (NaN counted as 0, so a
//! broken render scores badly instead of poisoning the mean), data range 1, and needs both
//! frames to have the same size (otherwise an error).
//!
//! - **PSNR** = 10·log10(1 / MSE), MSE over all RGB values; identical images give
//!   `f64::INFINITY` (the limit as MSE → 0; callers printing it should say "identical").
//! - **SSIM** (Wang et al. 2004) with an 11×11 Gaussian window, σ = 1.5, K1 = 0.01, K2 = 0.03,
//!   computed per channel and averaged over channels and pixels, in f64. Two border
//!   conventions ([`SsimWindow`]): [`SsimWindow::ZeroPadded`] (the default of [`ssim`]) is the
//!   reference 3DGS code's `ssim()` (`utils/loss_utils.py`: `conv2d` with zero padding of 5,
//!   mean of the whole map), so numbers compare with the ones 3DGS papers report;
//!   [`SsimWindow::Valid`] averages only where the window lies inside the image (Wang et al.'s
//!   MATLAB `ssim_index` and scikit-image's cropping), free of padding effects.
//! - **Tile-SSIM** (the seed's Tile-SSIM loss, 1 − (1/Z)·Σ SSIM(tile_z)): the image is cut into
//!   `tile`×`tile` tiles from the top-left (edge tiles smaller), each tile's SSIM is computed as
//!   an image of its own (zero-padded convention), and the unweighted mean over tiles returned.
//! - **Heat-map**: per pixel the largest absolute channel difference, divided by a full-scale
//!   error ([`HEATMAP_FULL_SCALE`] unless given), clamped to 1 and coloured along an
//!   inferno-like ramp from black (no error) through purple and orange to pale yellow (≥ full
//!   scale).

use rayon::prelude::*;

use crate::error::{Result, SceneError};
use crate::image_io::Rgb8Image;
use crate::Frame;

/// SSIM window side length.
pub const SSIM_WINDOW: usize = 11;
/// SSIM Gaussian window standard deviation in pixels.
pub const SSIM_SIGMA: f64 = 1.5;
/// SSIM stabilising constants for data range 1: C1 = (0.01)², C2 = (0.03)².
pub const SSIM_C1: f64 = 0.01 * 0.01;
pub const SSIM_C2: f64 = 0.03 * 0.03;
/// Error shown at full intensity by [`heatmap`]: 0.1 is 25 of 255 levels, already plainly
/// visible, so everything from there on saturates and small differences keep their contrast.
pub const HEATMAP_FULL_SCALE: f32 = 0.1;

/// How SSIM treats the window where it overlaps the image border.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SsimWindow {
    /// Zero padding, mean over every pixel (reference 3DGS `ssim()`).
    #[default]
    ZeroPadded,
    /// Mean over the pixels whose window lies inside the image (needs ≥ 11×11 pixels).
    Valid,
}

#[inline]
fn clamp01(v: f32) -> f64 {
    if v.is_nan() {
        0.0
    } else {
        v.clamp(0.0, 1.0) as f64
    }
}

fn check_same_size(a: &Frame, b: &Frame) -> Result<()> {
    for f in [a, b] {
        if f.rgb.len() != 3 * f.pixels() {
            return Err(SceneError::Invalid(format!(
                "a {}×{} frame has {} RGB values instead of {}",
                f.width,
                f.height,
                f.rgb.len(),
                3 * f.pixels()
            )));
        }
    }
    if (a.width, a.height) != (b.width, b.height) {
        return Err(SceneError::Invalid(format!(
            "image sizes differ: {}×{} and {}×{}",
            a.width, a.height, b.width, b.height
        )));
    }
    if a.pixels() == 0 {
        return Err(SceneError::Invalid(
            "cannot compare empty (0-pixel) images".into(),
        ));
    }
    Ok(())
}

/// Values a parallel reduction sums in one piece (any fixed size keeps results independent of
/// the thread pool; this one is large enough that the partials cost nothing).
const SUM_CHUNK: usize = 1 << 14;

/// Mean squared error over all RGB values (clamped to [0, 1]).
pub fn mse(a: &Frame, b: &Frame) -> Result<f64> {
    check_same_size(a, b)?;
    // Partial sums over fixed chunks, added in order: a parallel `sum` associates its partials
    // as the pool happens to split the work, and the last bits of a PSNR then changed from
    // run to run of the same images.
    let partial: Vec<f64> = a
        .rgb
        .par_chunks(SUM_CHUNK)
        .zip(b.rgb.par_chunks(SUM_CHUNK))
        .map(|(xa, xb)| {
            xa.iter()
                .zip(xb)
                .map(|(&x, &y)| {
                    let d = clamp01(x) - clamp01(y);
                    d * d
                })
                .sum::<f64>()
        })
        .collect();
    Ok(partial.iter().sum::<f64>() / a.rgb.len() as f64)
}

/// PSNR in dB for data range 1; `f64::INFINITY` for identical (after clamping) images.
pub fn psnr(a: &Frame, b: &Frame) -> Result<f64> {
    let m = mse(a, b)?;
    Ok(if m == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * m.log10()
    })
}

/// Largest absolute RGB difference (values clamped to [0, 1]).
pub fn max_abs_error(a: &Frame, b: &Frame) -> Result<f32> {
    check_same_size(a, b)?;
    Ok(a.rgb
        .iter()
        .zip(&b.rgb)
        .map(|(&x, &y)| (clamp01(x) - clamp01(y)).abs())
        .fold(0.0f64, f64::max) as f32)
}

/// The normalised 1D Gaussian of the SSIM window (the 2D window is its outer product).
pub fn ssim_kernel() -> [f64; SSIM_WINDOW] {
    let mut g = [0.0; SSIM_WINDOW];
    let c = (SSIM_WINDOW / 2) as f64;
    for (i, v) in g.iter_mut().enumerate() {
        let d = i as f64 - c;
        *v = (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp();
    }
    let s: f64 = g.iter().sum();
    g.map(|v| v / s)
}

/// SSIM with the reference 3DGS convention ([`SsimWindow::ZeroPadded`]).
pub fn ssim(a: &Frame, b: &Frame) -> Result<f64> {
    ssim_with(a, b, SsimWindow::ZeroPadded)
}

/// SSIM with an explicit border convention.
pub fn ssim_with(a: &Frame, b: &Frame, window: SsimWindow) -> Result<f64> {
    check_same_size(a, b)?;
    let (w, h) = (a.width as usize, a.height as usize);
    if window == SsimWindow::Valid && (w < SSIM_WINDOW || h < SSIM_WINDOW) {
        return Err(SceneError::Invalid(format!(
            "a {w}×{h} image is smaller than the {SSIM_WINDOW}×{SSIM_WINDOW} SSIM window ('valid' convention)"
        )));
    }
    let mut total = 0.0;
    for c in 0..3 {
        let x: Vec<f64> = (0..w * h).map(|i| clamp01(a.rgb[3 * i + c])).collect();
        let y: Vec<f64> = (0..w * h).map(|i| clamp01(b.rgb[3 * i + c])).collect();
        total += ssim_plane(&x, &y, w, h, window);
    }
    Ok(total / 3.0)
}

/// Mean SSIM of one channel (row-major `w`×`h` planes).
fn ssim_plane(x: &[f64], y: &[f64], w: usize, h: usize, window: SsimWindow) -> f64 {
    let g = ssim_kernel();
    let r = SSIM_WINDOW / 2;
    // Horizontal pass of x, y, x², y², xy with zero padding; five interleaved maps.
    let mut hmaps = vec![[0.0f64; 5]; w * h];
    hmaps.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
        let base = row * w;
        for (col, o) in out.iter_mut().enumerate() {
            let lo = col.saturating_sub(r);
            let hi = (col + r).min(w - 1);
            let mut acc = [0.0; 5];
            for k in lo..=hi {
                let wt = g[k + r - col];
                let (xv, yv) = (x[base + k], y[base + k]);
                acc[0] += wt * xv;
                acc[1] += wt * yv;
                acc[2] += wt * xv * xv;
                acc[3] += wt * yv * yv;
                acc[4] += wt * xv * yv;
            }
            *o = acc;
        }
    });
    // Rows (and columns) whose window lies inside the image, for the 'valid' convention.
    let (rows, cols) = match window {
        SsimWindow::ZeroPadded => (0..h, 0..w),
        SsimWindow::Valid => (r..h - r, r..w - r),
    };
    let count = rows.len() * cols.len();
    let sum: f64 = rows
        .into_par_iter()
        .map(|row| {
            let lo = row.saturating_sub(r);
            let hi = (row + r).min(h - 1);
            let mut s = 0.0;
            for col in cols.clone() {
                let mut m = [0.0; 5];
                for k in lo..=hi {
                    let wt = g[k + r - row];
                    let v = &hmaps[k * w + col];
                    for j in 0..5 {
                        m[j] += wt * v[j];
                    }
                }
                s += ssim_value(m);
            }
            s
        })
        .collect::<Vec<f64>>()
        // Rows added in order, whatever the pool's split (as in `mse`).
        .iter()
        .sum();
    sum / count as f64
}

/// SSIM from windowed moments `[μx, μy, E[x²], E[y²], E[xy]]`.
#[inline]
fn ssim_value(m: [f64; 5]) -> f64 {
    let [mx, my, exx, eyy, exy] = m;
    let sxx = exx - mx * mx;
    let syy = eyy - my * my;
    let sxy = exy - mx * my;
    ((2.0 * mx * my + SSIM_C1) * (2.0 * sxy + SSIM_C2))
        / ((mx * mx + my * my + SSIM_C1) * (sxx + syy + SSIM_C2))
}

/// Copy the `tw`×`th` tile at (`x0`, `y0`) into a frame of its own (RGB only).
fn crop(f: &Frame, x0: u32, y0: u32, tw: u32, th: u32) -> Frame {
    let mut out = Frame::new(tw, th);
    for y in 0..th as usize {
        let src = 3 * ((y0 as usize + y) * f.width as usize + x0 as usize);
        out.rgb[3 * y * tw as usize..3 * (y + 1) * tw as usize]
            .copy_from_slice(&f.rgb[src..src + 3 * tw as usize]);
    }
    out
}

/// Tile-SSIM: mean over `tile`×`tile` tiles of each tile's own SSIM (zero-padded convention);
/// see the module docs.
pub fn tile_ssim(a: &Frame, b: &Frame, tile: u32) -> Result<f64> {
    check_same_size(a, b)?;
    if tile == 0 {
        return Err(SceneError::Invalid(
            "tile-SSIM needs a tile size of at least 1 pixel".into(),
        ));
    }
    let mut sum = 0.0;
    let mut z = 0usize;
    for y0 in (0..a.height).step_by(tile as usize) {
        for x0 in (0..a.width).step_by(tile as usize) {
            let tw = tile.min(a.width - x0);
            let th = tile.min(a.height - y0);
            sum += ssim(&crop(a, x0, y0, tw, th), &crop(b, x0, y0, tw, th))?;
            z += 1;
        }
    }
    Ok(sum / z as f64)
}

/// Inferno-like colour ramp stops (t, RGB).
const RAMP: [(f32, [f32; 3]); 5] = [
    (0.0, [0.0, 0.0, 4.0]),
    (0.25, [87.0, 16.0, 110.0]),
    (0.5, [188.0, 55.0, 84.0]),
    (0.75, [249.0, 142.0, 9.0]),
    (1.0, [252.0, 255.0, 164.0]),
];

/// The heat-map colour of `t` in [0, 1] (clamped; NaN as 1, the worst).
pub fn ramp(t: f32) -> [u8; 3] {
    let t = if t.is_nan() { 1.0 } else { t.clamp(0.0, 1.0) };
    let k = RAMP
        .iter()
        .position(|&(s, _)| s >= t)
        .unwrap_or(RAMP.len() - 1)
        .max(1);
    let (t0, c0) = RAMP[k - 1];
    let (t1, c1) = RAMP[k];
    let u = (t - t0) / (t1 - t0);
    [0, 1, 2].map(|j| (c0[j] + u * (c1[j] - c0[j])).round() as u8)
}

/// Difference heat-map with the default full scale [`HEATMAP_FULL_SCALE`].
pub fn heatmap(a: &Frame, b: &Frame) -> Result<Rgb8Image> {
    heatmap_scaled(a, b, HEATMAP_FULL_SCALE)
}

/// Difference heat-map: per pixel max |a − b| over RGB (clamped values) divided by
/// `full_scale`, through [`ramp`].
pub fn heatmap_scaled(a: &Frame, b: &Frame, full_scale: f32) -> Result<Rgb8Image> {
    check_same_size(a, b)?;
    if !(full_scale > 0.0 && full_scale.is_finite()) {
        return Err(SceneError::Invalid(format!(
            "heat-map full scale {full_scale} must be positive and finite"
        )));
    }
    let mut data = Vec::with_capacity(3 * a.pixels());
    for i in 0..a.pixels() {
        let e = (0..3)
            .map(|c| (clamp01(a.rgb[3 * i + c]) - clamp01(b.rgb[3 * i + c])).abs())
            .fold(0.0f64, f64::max) as f32;
        data.extend_from_slice(&ramp(e / full_scale));
    }
    Ok(Rgb8Image {
        width: a.width,
        height: a.height,
        data,
    })
}
