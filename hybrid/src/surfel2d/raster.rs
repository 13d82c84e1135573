//! Per-tile front-to-back blending of set-up surfels, 2DGS's `renderCUDA` (see the parent
//! module): per pixel, the ray–splat intersection in the splat's `(u, v)` frame, the low-pass
//! minimum, the 0.99 clamp, the 1/255 skip and the 1e-4 stop. [`SurfelOrder::HitDepth`] is a
//! named departure for measurements: each pixel's surfels blended in the order of their
//! ray–plane hits, as a ray tracer of the surfels' fans composites them.

use std::cmp::Reverse;

use rayon::prelude::*;
use splatbridge_scene::Frame;

use super::project::{SurfelSplat, FILTER_INV_SQUARE};
use crate::bin::Bins;
use crate::project::TILE;

/// The order surfels are blended in at a pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SurfelOrder {
    /// 2DGS's: one global order by the view depth of each surfel's centre.
    #[default]
    CentreDepth,
    /// Per pixel, by the view depth where the pixel's ray meets each surfel's plane (ties in
    /// centre-depth order): not the reference, the order a ray tracer of the surfels' meshes
    /// composites in.
    HitDepth,
}

/// View depth of the point where the ray through pixel centre `(x, y)` meets the surfel's
/// plane (the `u·T_w,x + v·T_w,y + T_w,z` of [`surfel_alpha`] with the splat term).
fn plane_depth(s: &SurfelSplat, x: f64, y: f64) -> f64 {
    let k = -s.tu + x * s.tw;
    let l = -s.tv + y * s.tw;
    let inv = 1.0 / (k.x * l.y - k.y * l.x);
    let u = (l.z * k.y - k.z * l.y) * inv;
    let v = -(l.z * k.x - k.z * l.x) * inv;
    u * s.tw.x + v * s.tw.y + s.tw.z
}

/// What one surfel contributes at pixel centre `(x, y)`: `(α, depth)`, or `None` where the
/// reference skips it (`power > 0`, parallel planes, `α < 1/255`).
#[inline]
pub fn surfel_alpha(s: &SurfelSplat, x: f64, y: f64, alpha_clamp: f64) -> Option<(f64, f64)> {
    let k = -s.tu + x * s.tw;
    let l = -s.tv + y * s.tw;
    let den = k.x * l.y - k.y * l.x;
    if den == 0.0 {
        return None;
    }
    let inv = 1.0 / den;
    let u = (l.z * k.y - k.z * l.y) * inv;
    let v = -(l.z * k.x - k.z * l.x) * inv;
    let rho3d = u * u + v * v;
    let (dx, dy) = (s.centre[0] - x, s.centre[1] - y);
    let rho2d = FILTER_INV_SQUARE * (dx * dx + dy * dy);
    let rho = rho3d.min(rho2d);
    let depth = if rho3d <= rho2d {
        u * s.tw.x + v * s.tw.y + s.tw.z
    } else {
        s.tw.z
    };
    let power = -0.5 * rho;
    if !(power <= 0.0) {
        return None;
    }
    let alpha = (s.opacity as f64 * power.exp()).min(alpha_clamp);
    if !(alpha >= 1.0 / 255.0) {
        return None;
    }
    Some((alpha, depth))
}

/// One blended pixel of a tile: `(rgb, alpha, depth)`.
type TilePixel = ([f32; 3], f32, f32);

/// Blend one tile (top-left pixel `(px0, py0)`, `cols × rows` pixels) and write its pixels
/// into `out` (`(rgb, alpha, depth)` per tile pixel, row-major). Returns the blend count.
fn blend_tile(
    splats: &[SurfelSplat],
    list: &[u32],
    (px0, py0, cols, rows): (usize, usize, usize, usize),
    alpha_clamp: f64,
    background: [f32; 3],
    blend_order: SurfelOrder,
    out: &mut Vec<TilePixel>,
) -> u64 {
    let mut blends = 0u64;
    out.clear();
    // HitDepth: the pixel's contributions `(hit depth, α, depth, surfel)`, sorted.
    let mut hits: Vec<(f64, f64, f64, u32)> = Vec::new();
    for py in py0..py0 + rows {
        for px in px0..px0 + cols {
            let (x, y) = (px as f64 + 0.5, py as f64 + 0.5);
            let (pixel, n) = match blend_order {
                SurfelOrder::CentreDepth => blend_pixel(
                    splats,
                    list.iter().filter_map(|&k| {
                        surfel_alpha(&splats[k as usize], x, y, alpha_clamp).map(|(a, d)| (a, d, k))
                    }),
                    background,
                ),
                SurfelOrder::HitDepth => {
                    hits.clear();
                    hits.extend(list.iter().filter_map(|&k| {
                        let s = &splats[k as usize];
                        surfel_alpha(s, x, y, alpha_clamp)
                            .map(|(a, d)| (plane_depth(s, x, y), a, d, k))
                    }));
                    // Stable: equal hit depths keep the centre-depth order of the list.
                    hits.sort_by(|a, b| a.0.total_cmp(&b.0));
                    blend_pixel(
                        splats,
                        hits.iter().map(|&(_, a, d, k)| (a, d, k)),
                        background,
                    )
                }
            };
            blends += n;
            out.push(pixel);
        }
    }
    blends
}

/// Front-to-back blending of one pixel's contributions `(α, depth, surfel)` in the order given:
/// the pixel and its blend count.
#[inline(always)]
fn blend_pixel(
    splats: &[SurfelSplat],
    contributions: impl Iterator<Item = (f64, f64, u32)>,
    background: [f32; 3],
) -> (TilePixel, u64) {
    let mut t = 1.0f64;
    let mut c = [0.0f64; 3];
    let (mut dz, mut w) = (0.0f64, 0.0f64);
    let mut blends = 0;
    for (alpha, depth, k) in contributions {
        let s = &splats[k as usize];
        let test_t = t * (1.0 - alpha);
        if test_t < 1e-4 {
            break;
        }
        let wt = alpha * t;
        for ch in 0..3 {
            c[ch] += s.color[ch] as f64 * wt;
        }
        dz += depth * wt;
        w += wt;
        t = test_t;
        blends += 1;
    }
    let rgb = std::array::from_fn(|ch| (c[ch] + t * background[ch] as f64) as f32);
    let depth = if w > 0.0 { (dz / w) as f32 } else { 0.0 };
    ((rgb, (1.0 - t) as f32, depth), blends)
}

/// Blend every tile in parallel (largest lists first) into a frame; returns it and the blend
/// count.
pub fn rasterize(
    splats: &[SurfelSplat],
    bins: &Bins,
    width: u32,
    height: u32,
    alpha_clamp: f64,
    background: [f32; 3],
    blend_order: SurfelOrder,
) -> (Frame, u64) {
    let t = TILE as usize;
    let gx = width.div_ceil(TILE) as usize;
    let gy = height.div_ceil(TILE) as usize;
    let mut order: Vec<usize> = (0..gx * gy).collect();
    order.sort_by_key(|&k| Reverse(bins.tile(k).len()));
    let tiles: Vec<(usize, Vec<TilePixel>, u64)> = order
        .into_par_iter()
        .with_max_len(1)
        .map(|k| {
            let (px0, py0) = ((k % gx) * t, (k / gx) * t);
            let cols = (width as usize - px0).min(t);
            let rows = (height as usize - py0).min(t);
            let mut out = Vec::with_capacity(cols * rows);
            let n = blend_tile(
                splats,
                bins.tile(k),
                (px0, py0, cols, rows),
                alpha_clamp,
                background,
                blend_order,
                &mut out,
            );
            (k, out, n)
        })
        .collect();
    let mut frame = Frame::new(width, height);
    let mut blends = 0;
    for (k, out, n) in tiles {
        blends += n;
        let (px0, py0) = ((k % gx) * t, (k / gx) * t);
        let cols = (width as usize - px0).min(t);
        for (j, (rgb, a, d)) in out.into_iter().enumerate() {
            let p = (py0 + j / cols) * width as usize + px0 + j % cols;
            frame.rgb[3 * p..3 * p + 3].copy_from_slice(&rgb);
            frame.alpha[p] = a;
            frame.depth[p] = d;
        }
    }
    (frame, blends)
}
