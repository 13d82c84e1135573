//! The GES composite and the surfel colour blur.
//!
//! **Where a surfel covers the pixel** (coverage `w_S = 1`): GES's
//! `C = (w_S·C_S + C_G)/(w_S + W_G)` with `C_G = Σ αᵢ·cᵢ`, `W_G = Σ αᵢ` over the Gaussians that
//! passed the depth test; alpha 1.
//!
//! **Where no surfel covers it** (`w_S = 0`) GES's formula would give `C_G/W_G` however faint the
//! Gaussians are, so a single α = 0.01 Gaussian would paint its full colour over the background.
//! Here the Gaussians are composited over the background as weighted blended order-independent
//! transparency does (McGuire & Bavoil 2013): colour `C_G/W_G` (the α-weighted mean, GES's own
//! colour rule) with opacity `a = 1 − T`, `T = Π(1 − αᵢ)`, the exact coverage of the set
//! (a product, so order-independent):
//!
//! `C = (C_G/W_G)·(1 − T) + background·T`, alpha `1 − T`.
//!
//! Empty pixels (`W_G = 0`, `T = 1`) are exactly the background; one Gaussian gives exactly the
//! native result `α·c + (1 − α)·background`; several give the native coverage and a weighted mean
//! colour instead of the front-to-back one, and fade smoothly to the background as `αᵢ → 0`.
//! `min(1, W_G)` would over-count overlaps (two α = 0.5 give 1, not 0.75) and `1 − exp(−W_G)`
//! under-counts a single Gaussian (0.39 for α = 0.5); the product is exact for coverage.
//!
//! **Partial coverage** (4× supersampling, `0 < w_S < 1`): the two rules mixed by coverage,
//! `C = w_S·(C_S + C_G)/(1 + W_G) + (1 − w_S)·[(C_G/W_G)(1 − T) + background·T]`, alpha
//! `w_S + (1 − w_S)(1 − T)`; which reduces to each rule at its end.
//!
//! Depth: the surfel depth (mean over covered samples) where any sample is covered, otherwise
//! the α-weighted Gaussian depth `Σ αᵢ zᵢ / Σ αᵢ` (0 where empty).
//!
//! **Blur**: GES box-blurs the surfel colour 3×3 (`ges_viewer/shader/blur_frag.glsl`, clamped at
//! the image border). Here the 3×3 mean is taken over covered neighbours only, weighted by their
//! coverage (so silhouettes are not darkened by the buffer's clear colour), and only at covered
//! pixels.

use rayon::prelude::*;

use super::surfel_pass::{N, P_B, P_G, P_R, P_W, SURFEL_PLANES, T};

/// Per-pixel Gaussian accumulators of pass 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GaussAcc {
    /// `C_G = Σ αᵢ·cᵢ`.
    pub c: [f32; 3],
    /// `W_G = Σ αᵢ`.
    pub w: f32,
    /// `T = Π(1 − αᵢ)`.
    pub t: f32,
    /// `Σ αᵢ·zᵢ`.
    pub dz: f32,
}

/// Composite one pixel (see the module docs): returns (rgb, alpha, depth).
#[inline]
pub fn composite_pixel(
    cs: [f32; 3],
    ws: f32,
    ds: f32,
    g: &GaussAcc,
    bg: [f32; 3],
) -> ([f32; 3], f32, f32) {
    let mut rgb = [0f32; 3];
    let inv_w = if g.w > 0.0 { 1.0 / g.w } else { 0.0 };
    let cov = 1.0 - g.t;
    if ws >= 1.0 {
        let k = 1.0 / (1.0 + g.w);
        for j in 0..3 {
            rgb[j] = (cs[j] + g.c[j]) * k;
        }
        return (rgb, 1.0, ds);
    }
    for j in 0..3 {
        let free = g.c[j] * inv_w * cov + bg[j] * g.t;
        rgb[j] = if ws > 0.0 {
            ws * (cs[j] + g.c[j]) / (1.0 + g.w) + (1.0 - ws) * free
        } else {
            free
        };
    }
    let alpha = ws + (1.0 - ws) * cov;
    let depth = if ws > 0.0 { ds } else { g.dz * inv_w };
    (rgb, alpha, depth)
}

/// Blur the surfel colour planes of a surfel buffer in place (see the module docs). `slot` maps
/// tiles to their planes (`u32::MAX`: no surfel, nothing covered).
pub fn blur_surfels(slot: &[u32], planes: &mut [f32], width: u32, height: u32, grid: [u32; 2]) {
    let (w, h, gx) = (width as usize, height as usize, grid[0] as usize);
    let base = |x: usize, y: usize| -> Option<usize> {
        let s = slot[(y / T) * gx + x / T];
        (s != u32::MAX).then(|| s as usize * SURFEL_PLANES * N + (y % T) * T + x % T)
    };
    let src: &[f32] = planes;
    let blurred: Vec<(usize, [f32; 3])> = (0..w * h)
        .into_par_iter()
        .filter_map(|i| {
            let (x, y) = (i % w, i / w);
            let b = base(x, y)?;
            if src[b + P_W * N] <= 0.0 {
                return None;
            }
            let mut acc = [0f32; 3];
            let mut wsum = 0f32;
            for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    let Some(q) = base(nx, ny) else { continue };
                    let wq = src[q + P_W * N];
                    if wq > 0.0 {
                        acc[0] += wq * src[q + P_R * N];
                        acc[1] += wq * src[q + P_G * N];
                        acc[2] += wq * src[q + P_B * N];
                        wsum += wq;
                    }
                }
            }
            Some((b, acc.map(|v| v / wsum)))
        })
        .collect();
    for (b, c) in blurred {
        planes[b + P_R * N] = c[0];
        planes[b + P_G * N] = c[1];
        planes[b + P_B * N] = c[2];
    }
}
