//! Per-tile front-to-back blending, the reference's `renderCUDA` (`forward.cu`) on a CPU.
//!
//! Per pixel, in depth order: `power = −½(c0·dx² + c2·dy²) − c1·dx·dy` with `d = mean − pixel`
//! (pixel `i` sampled at `i`); skip if `power > 0`; `α = min(clamp, opacity·exp(power))`; skip if
//! `α < 1/255`; if `T·(1 − α) < 1e-4` the pixel stops without adding this Gaussian; otherwise
//! `C += colour·α·T`, `T ·= 1 − α`. Output `C + T·background`, alpha `1 − T` and the blended
//! expected depth `Σ wᵢ·zᵢ / Σ wᵢ` (wᵢ = αᵢ·Tᵢ, 0 where nothing was added).
//!
//! The loop runs Gaussian by Gaussian over a tile held in registers-sized planes, eight pixels of
//! a row at a time (branch-free, so the compiler vectorises it); a pixel that stopped is masked,
//! which gives exactly the per-pixel loop's result. Each Gaussian visits only the rows and
//! 8-pixel halves its footprint box can reach ([`crate::project::footprint_box`]): outside it
//! `α < 1/255` for certain, so skipping is exact. A tile ends as soon as all its pixels stopped.
//!
//! `exp` is a Cephes-style polynomial (below 2 ulp relative error, see the tests) so the loop
//! vectorises; the reference uses the GPU's `expf`.

use std::cmp::Reverse;

use rayon::prelude::*;
use splatbridge_scene::Frame;

use crate::bin::Bins;
use crate::project::{Splat, TILE};

const T: usize = TILE as usize;
const N: usize = T * T;
/// Output planes per tile: r, g, b, alpha, depth.
const PLANES: usize = 5;

/// Blending knobs.
#[derive(Clone, Copy, Debug)]
pub struct BlendParams {
    pub alpha_clamp: f32,
    pub background: [f32; 3],
    /// Visit every pixel of every touched tile instead of each Gaussian's footprint box. The
    /// image is bit-identical; only slower. Kept so tests can check the box is exact.
    pub exhaustive: bool,
}

/// `exp(x)` for `x ≤ 0` (larger inputs are treated as 0, smaller than −87 as −87, where the
/// result is below any α threshold). Cephes `expf`: range reduction by ln 2 split in two
/// constants, degree-5 polynomial, exponent assembled from bits.
#[inline(always)]
pub fn exp_nonpos(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const C1: f32 = 0.693_359_4;
    const C2: f32 = -2.121_944_4e-4;
    const ROUND: f32 = 12_582_912.0; // 1.5·2²³: adding and subtracting rounds to an integer
    let x = x.max(-87.0).min(0.0);
    let n = (x * LOG2E + ROUND) - ROUND;
    let r = x - n * C1 - n * C2;
    let mut p = 1.987_569_1e-4f32;
    p = p * r + 1.398_199_9e-3;
    p = p * r + 8.333_452e-3;
    p = p * r + 4.166_579_6e-2;
    p = p * r + 1.666_666_5e-1;
    p = p * r + 5.000_000_1e-1;
    let y = p * r * r + r + 1.0;
    y * f32::from_bits(((n as i32 + 127) as u32) << 23)
}

/// Per-pixel accumulators of one tile.
struct TileState {
    t: [f32; N],
    r: [f32; N],
    g: [f32; N],
    b: [f32; N],
    dz: [f32; N],
    w: [f32; N],
    done: [u32; N],
}

impl TileState {
    fn new(cols: usize, rows: usize) -> Self {
        let mut done = [1u32; N];
        for y in 0..rows {
            done[y * T..y * T + cols].fill(0);
        }
        TileState {
            t: [1.0; N],
            r: [0.0; N],
            g: [0.0; N],
            b: [0.0; N],
            dz: [0.0; N],
            w: [0.0; N],
            done,
        }
    }

    /// Blend splat `s` into the eight pixels starting at `base` (pixel x coordinate `x0`,
    /// `dy = s.y − pixel y`). Returns (blends, pixels that stopped).
    #[inline(always)]
    fn blend8(&mut self, base: usize, x0: f32, dy: f32, s: &Splat, clamp: f32) -> (u32, u32) {
        let t: &mut [f32; 8] = (&mut self.t[base..base + 8]).try_into().unwrap();
        let r: &mut [f32; 8] = (&mut self.r[base..base + 8]).try_into().unwrap();
        let g: &mut [f32; 8] = (&mut self.g[base..base + 8]).try_into().unwrap();
        let b: &mut [f32; 8] = (&mut self.b[base..base + 8]).try_into().unwrap();
        let dz: &mut [f32; 8] = (&mut self.dz[base..base + 8]).try_into().unwrap();
        let w: &mut [f32; 8] = (&mut self.w[base..base + 8]).try_into().unwrap();
        let done: &mut [u32; 8] = (&mut self.done[base..base + 8]).try_into().unwrap();
        let [c0, c1, c2] = s.conic;
        let [cr, cg, cb] = s.color;
        let mut blends = 0u32;
        let mut stops = 0u32;
        for l in 0..8 {
            let dx = s.x - (x0 + l as f32);
            let power = -0.5 * (c0 * dx * dx + c2 * dy * dy) - c1 * dx * dy;
            let a = (s.opacity * exp_nonpos(power)).min(clamp);
            let tl = t[l];
            let test_t = tl * (1.0 - a);
            let live = (done[l] == 0) & (power <= 0.0) & (a >= 1.0 / 255.0);
            let stop = live & (test_t < 1e-4);
            let add = live & !stop;
            let wl = a * tl;
            r[l] = if add { r[l] + cr * wl } else { r[l] };
            g[l] = if add { g[l] + cg * wl } else { g[l] };
            b[l] = if add { b[l] + cb * wl } else { b[l] };
            dz[l] = if add { dz[l] + s.depth * wl } else { dz[l] };
            w[l] = if add { w[l] + wl } else { w[l] };
            t[l] = if add { test_t } else { tl };
            done[l] |= stop as u32;
            blends += add as u32;
            stops += stop as u32;
        }
        (blends, stops)
    }
}

/// Blend one tile whose top-left pixel is `(px0, py0)` and of which `cols × rows` pixels lie
/// inside the image; writes the planes r, g, b, alpha, depth (each `N`, row-major in the tile)
/// to `out`. Returns the number of pixel–Gaussian blends.
pub fn blend_tile(
    splats: &[Splat],
    list: &[u32],
    px0: i32,
    py0: i32,
    cols: usize,
    rows: usize,
    params: &BlendParams,
    out: &mut [f32],
) -> u64 {
    let mut st = TileState::new(cols, rows);
    let active = (cols * rows) as u32;
    let mut finished = 0u32;
    let mut blends = 0u64;
    let (tx1, ty1) = (px0 + T as i32 - 1, py0 + T as i32 - 1);
    for &k in list {
        if finished == active {
            break;
        }
        let s = &splats[k as usize];
        let [bx0, by0, bx1, by1] = if params.exhaustive {
            [px0, py0, tx1, ty1]
        } else {
            s.bbox
        };
        let (x0, x1) = (bx0.max(px0), bx1.min(tx1));
        let (y0, y1) = (by0.max(py0), by1.min(ty1));
        if x0 > x1 || y0 > y1 {
            continue;
        }
        let (h0, h1) = (((x0 - px0) / 8) as usize, ((x1 - px0) / 8) as usize);
        for y in y0..=y1 {
            let ly = (y - py0) as usize;
            let dy = s.y - y as f32;
            for h in h0..=h1 {
                let (nb, ns) = st.blend8(
                    ly * T + h * 8,
                    (px0 + 8 * h as i32) as f32,
                    dy,
                    s,
                    params.alpha_clamp,
                );
                blends += nb as u64;
                finished += ns;
            }
        }
    }
    let [br, bg, bb] = params.background;
    let (o_r, rest) = out.split_at_mut(N);
    let (o_g, rest) = rest.split_at_mut(N);
    let (o_b, rest) = rest.split_at_mut(N);
    let (o_a, o_d) = rest.split_at_mut(N);
    for i in 0..N {
        let t = st.t[i];
        o_r[i] = st.r[i] + t * br;
        o_g[i] = st.g[i] + t * bg;
        o_b[i] = st.b[i] + t * bb;
        o_a[i] = 1.0 - t;
        o_d[i] = if st.w[i] > 0.0 {
            st.dz[i] / st.w[i]
        } else {
            0.0
        };
    }
    blends
}

/// Blend every tile (in parallel, largest lists first, one tile per task so heavy tiles never
/// serialise the frame) and assemble the frame. Returns the frame and the blend count.
pub fn rasterize(
    splats: &[Splat],
    bins: &Bins,
    width: u32,
    height: u32,
    params: &BlendParams,
) -> (Frame, u64) {
    let gx = width.div_ceil(TILE) as usize;
    let gy = height.div_ceil(TILE) as usize;
    let mut buf = vec![0f32; gx * gy * PLANES * N];
    let mut jobs: Vec<(usize, &mut [f32])> = buf.chunks_mut(PLANES * N).enumerate().collect();
    jobs.sort_by_key(|(t, _)| Reverse(bins.tile(*t).len()));
    let blends: u64 = jobs
        .into_par_iter()
        .with_max_len(1)
        .map(|(t, out)| {
            let (tx, ty) = (t % gx, t / gx);
            let (px0, py0) = (tx * T, ty * T);
            let cols = (width as usize - px0).min(T);
            let rows = (height as usize - py0).min(T);
            blend_tile(
                splats,
                bins.tile(t),
                px0 as i32,
                py0 as i32,
                cols,
                rows,
                params,
                out,
            )
        })
        .sum();

    let mut frame = Frame::new(width, height);
    let w = width as usize;
    frame
        .rgb
        .par_chunks_mut(3 * w)
        .zip(frame.alpha.par_chunks_mut(w))
        .zip(frame.depth.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, ((rgb, alpha), depth))| {
            let (ty, ly) = (y / T, y % T);
            for x in 0..w {
                let tile = &buf[(ty * gx + x / T) * PLANES * N..][..PLANES * N];
                let i = ly * T + x % T;
                rgb[3 * x] = tile[i];
                rgb[3 * x + 1] = tile[N + i];
                rgb[3 * x + 2] = tile[2 * N + i];
                alpha[x] = tile[3 * N + i];
                depth[x] = tile[4 * N + i];
            }
        });
    (frame, blends)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polynomial_exp_matches_f64_exp() {
        // Cephes quotes ≤ 2 ulp for its expf on this range; allow 3 ulp-ish relative (3.6e-7).
        let mut worst = 0.0f64;
        let mut x = 0.0f32;
        while x > -87.0 {
            let e = exp_nonpos(x) as f64;
            let r = (x as f64).exp();
            worst = worst.max(((e - r) / r).abs());
            x -= 0.000_731;
        }
        assert!(worst < 3.6e-7, "worst relative error {worst}");
        assert_eq!(exp_nonpos(0.0), 1.0);
        assert_eq!(exp_nonpos(5.0), 1.0);
        assert!(exp_nonpos(-1e30) >= 0.0 && exp_nonpos(-1e30) < 1e-37);
    }
}
