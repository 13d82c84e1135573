//! Per-tile front-to-back blending, the reference's `renderCUDA` (`forward.cu`) on a CPU.
//!
//! Per pixel, in depth order: `power = −½(c0·dx² + c2·dy²) − c1·dx·dy` with `d = mean − pixel`
//! (pixel `i` sampled at `i`); skip if `power > 0`; `α = min(clamp, opacity·exp(power))`; skip if
//! `α < 1/255`; if `T·(1 − α) < 1e-4` the pixel stops without adding this Gaussian; otherwise
//! `C += colour·α·T`, `T ·= 1 − α`. Output `C + T·background`, alpha `1 − T` and the blended
//! expected depth `Σ wᵢ·zᵢ / Σ wᵢ` (wᵢ = αᵢ·Tᵢ, 0 where nothing was added).
//!
//! The loop runs Gaussian by Gaussian over a tile held in small planes, four pixels of a row at
//! a time ([`crate::kernel`], SIMD); a pixel that stopped is masked, which gives exactly the
//! per-pixel loop's result. Each Gaussian visits only the rows and 4-pixel groups its footprint
//! box can reach ([`crate::project::footprint_box`]): outside it `α < 1/255` for certain, so
//! skipping is exact. A tile ends as soon as all its pixels stopped.
//!
//! `exp` is a Cephes-style polynomial (below 2 ulp relative error, see the kernel tests) so the
//! loop vectorises; the reference uses the GPU's `expf`.

use std::cmp::Reverse;

use rayon::prelude::*;
use splatbridge_scene::Frame;

use crate::bin::Bins;
#[cfg(target_arch = "x86_64")]
use crate::kernel::avx;
use crate::kernel::{blend4, blend8_pair, SplatRow, TileState, T};
use crate::project::{Splat, TILE};

/// Blending knobs.
#[derive(Clone, Copy, Debug)]
pub struct BlendParams {
    pub alpha_clamp: f32,
    pub background: [f32; 3],
    /// Visit every pixel of every touched tile instead of each Gaussian's footprint box. The
    /// image is bit-identical; only slower. Kept so tests can check the box is exact.
    pub exhaustive: bool,
}

/// How many list entries ahead [`blend_tile`] (and the GES accumulation) prefetches.
pub(crate) const PREFETCH: usize = 8;

/// Hint the cache to fetch a splat a tile loop will read soon.
#[inline(always)]
pub(crate) fn prefetch(s: &Splat) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint without architectural effect; the address is a valid reference.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>((s as *const Splat).cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = s;
}

/// Blend the Gaussians `list` (front to back) into the tile whose top-left pixel is
/// `(px0, py0)`; `st` holds the tile's accumulators ([`TileState::new`] marks the pixels outside
/// the image). Returns the number of pixel–Gaussian blends. Uses 8-lane AVX2 where the CPU has
/// it (the same bits as the 4-lane path, see the kernel tests).
pub fn blend_tile(
    splats: &[Splat],
    list: &[u32],
    px0: i32,
    py0: i32,
    params: &BlendParams,
    st: &mut TileState,
) -> u64 {
    blend_tile_cut(splats, list, px0, py0, params, st, &[])
}

/// [`blend_tile`] with a per-pixel depth limit: `cut` holds `(limit, pixel)` pairs (pixel the
/// index in the tile, each at most once) sorted by ascending limit. A pixel stops, like a pixel
/// whose transmittance ran out, before the first Gaussian deeper than its limit. The list being
/// front to back, that is exactly "blend only the Gaussians with `depth ≤ limit`"; pixels not in
/// `cut` have no limit. With an empty `cut` this is [`blend_tile`].
pub fn blend_tile_cut(
    splats: &[Splat],
    list: &[u32],
    px0: i32,
    py0: i32,
    params: &BlendParams,
    st: &mut TileState,
    cut: &[(f32, u16)],
) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present.
        return unsafe { blend_tile_avx2(splats, list, px0, py0, params, st, cut) };
    }
    blend_tile_with(splats, list, px0, py0, params, st, cut, blend8_pair)
}

/// [`blend_tile_with`] compiled for AVX2 with the 256-bit kernel.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn blend_tile_avx2(
    splats: &[Splat],
    list: &[u32],
    px0: i32,
    py0: i32,
    params: &BlendParams,
    st: &mut TileState,
    cut: &[(f32, u16)],
) -> u64 {
    // SAFETY: this function only runs when AVX2 is present.
    let k8 = |st: &mut TileState, base: usize, x0: f32, k: &SplatRow| unsafe {
        avx::blend8(st, base, x0, k)
    };
    blend_tile_with(splats, list, px0, py0, params, st, cut, k8)
}

/// The tile loop, with the per-pixel depth cut (see [`blend_tile_cut`]) and the kernel for
/// eight adjacent pixels as parameters.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn blend_tile_with(
    splats: &[Splat],
    list: &[u32],
    px0: i32,
    py0: i32,
    params: &BlendParams,
    st: &mut TileState,
    cut: &[(f32, u16)],
    blend8: impl Fn(&mut TileState, usize, f32, &SplatRow) -> (u32, u32),
) -> u64 {
    let active = st.done.iter().filter(|&&d| d == 0).count() as u32;
    let mut finished = 0u32;
    let mut blends = 0u64;
    let mut next_cut = 0usize;
    let (tx1, ty1) = (px0 + T as i32 - 1, py0 + T as i32 - 1);
    for (i, &k) in list.iter().enumerate() {
        // Tile lists are sparse in the splat array: fetch a few entries ahead so the loads
        // overlap instead of each costing a full memory round trip.
        if let Some(&ahead) = list.get(i + PREFETCH) {
            prefetch(&splats[ahead as usize]);
        }
        let s = &splats[k as usize];
        while let Some(&(limit, p)) = cut.get(next_cut) {
            if s.depth <= limit {
                break;
            }
            let d = &mut st.done[p as usize];
            if *d == 0 {
                *d = u32::MAX;
                finished += 1;
            }
            next_cut += 1;
        }
        if finished == active {
            break;
        }
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
        // 4-pixel groups q0..=q1 of each row; pairs of groups go through the 8-lane kernel.
        let (q0, q1) = (((x0 - px0) / 4) as usize, ((x1 - px0) / 4) as usize);
        let [c0, c1, c2] = s.conic;
        for y in y0..=y1 {
            let ly = (y - py0) as usize;
            let dy = s.y - y as f32;
            let k = SplatRow {
                sx: s.x,
                c0,
                c1dy: c1 * dy,
                c2dy2: c2 * dy * dy,
                opacity: s.opacity,
                clamp: params.alpha_clamp,
                color: s.color,
                depth: s.depth,
            };
            let mut q = q0;
            while q <= q1 {
                let x = (px0 + 4 * q as i32) as f32;
                let (nb, ns) = if q < q1 {
                    blend8(st, ly * T + q * 4, x, &k)
                } else {
                    blend4(st, ly * T + q * 4, x, &k)
                };
                q += if q < q1 { 2 } else { 1 };
                blends += nb as u64;
                finished += ns;
            }
        }
        if finished == active {
            break;
        }
    }
    blends
}

/// Final values of tile pixel `i`: (rgb `C + T·background`, alpha `1 − T`, depth `Σw·z / Σw`).
#[inline]
pub fn resolve(st: &TileState, i: usize, background: [f32; 3]) -> ([f32; 3], f32, f32) {
    let t = st.t[i];
    let rgb = [
        st.r[i] + t * background[0],
        st.g[i] + t * background[1],
        st.b[i] + t * background[2],
    ];
    let depth = if st.w[i] > 0.0 {
        st.dz[i] / st.w[i]
    } else {
        0.0
    };
    (rgb, 1.0 - t, depth)
}

/// The frame's planes as raw pointers, so tiles running in parallel can each write their own
/// pixels without a tile-major intermediate copy.
struct FramePlanes {
    rgb: *mut f32,
    alpha: *mut f32,
    depth: *mut f32,
    width: usize,
    height: usize,
}

// SAFETY: the pointers are only written through `write_tile`, whose callers write disjoint
// pixel sets (each tile its own 16×16 block) while the frame is borrowed mutably by `rasterize`.
unsafe impl Sync for FramePlanes {}

impl FramePlanes {
    /// Write tile `st` whose top-left pixel is `(px0, py0)`, clipped to the image.
    ///
    /// # Safety
    /// No other thread may write the same pixels concurrently, and the frame the pointers
    /// come from must outlive the call.
    unsafe fn write_tile(&self, px0: usize, py0: usize, st: &TileState, background: [f32; 3]) {
        let cols = (self.width - px0).min(T);
        let rows = (self.height - py0).min(T);
        for y in 0..rows {
            for x in 0..cols {
                let (rgb, a, d) = resolve(st, y * T + x, background);
                let p = (py0 + y) * self.width + px0 + x;
                // SAFETY: p < width·height (x < cols, y < rows), planes hold 3·, 1·, 1·that.
                unsafe {
                    self.rgb.add(3 * p).write(rgb[0]);
                    self.rgb.add(3 * p + 1).write(rgb[1]);
                    self.rgb.add(3 * p + 2).write(rgb[2]);
                    self.alpha.add(p).write(a);
                    self.depth.add(p).write(d);
                }
            }
        }
    }
}

/// Blend every tile (in parallel, largest lists first, one tile per task so heavy tiles never
/// serialise the frame) straight into the frame. Returns the frame and the blend count.
pub fn rasterize(
    splats: &[Splat],
    bins: &Bins,
    width: u32,
    height: u32,
    params: &BlendParams,
) -> (Frame, u64) {
    let tiles = [0, 0, width.div_ceil(TILE), height.div_ceil(TILE)];
    rasterize_region(splats, bins, width, height, tiles, params)
}

/// [`rasterize`] of the tiles `[x0, y0, x1, y1)` of a `width`×`height` frame only: the frame
/// returned holds their pixels (from pixel `(16·x0, 16·y0)`, clipped to the frame), each
/// blended exactly as the whole frame's.
pub fn rasterize_region(
    splats: &[Splat],
    bins: &Bins,
    width: u32,
    height: u32,
    tiles: [u32; 4],
    params: &BlendParams,
) -> (Frame, u64) {
    let gx = width.div_ceil(TILE) as usize;
    let [tx0, ty0, tx1, ty1] = tiles.map(|t| t as usize);
    let (ox, oy) = (tx0 * T, ty0 * T);
    let fw = (tx1 * T).min(width as usize).saturating_sub(ox);
    let fh = (ty1 * T).min(height as usize).saturating_sub(oy);
    let mut order: Vec<usize> = (ty0..ty1)
        .flat_map(|ty| (tx0..tx1).map(move |tx| ty * gx + tx))
        .collect();
    order.sort_by_key(|&t| Reverse(bins.tile(t).len()));
    let mut frame = Frame::new(fw as u32, fh as u32);
    let planes = FramePlanes {
        rgb: frame.rgb.as_mut_ptr(),
        alpha: frame.alpha.as_mut_ptr(),
        depth: frame.depth.as_mut_ptr(),
        width: fw,
        height: fh,
    };
    let blends: u64 = order
        .into_par_iter()
        .with_max_len(1)
        .map(|t| {
            let (px0, py0) = ((t % gx) * T, (t / gx) * T);
            let mut st = TileState::new(
                (width as usize - px0).min(T),
                (height as usize - py0).min(T),
            );
            let n = blend_tile(
                splats,
                bins.tile(t),
                px0 as i32,
                py0 as i32,
                params,
                &mut st,
            );
            // SAFETY: each tile index appears once in `order`, so each pixel is written once;
            // the tile lies in the region, so its pixels lie in `frame` (clipped as the whole
            // frame clips them); `frame` lives until after the parallel loop.
            unsafe { planes.write_tile(px0 - ox, py0 - oy, &st, params.background) };
            n
        })
        .sum();
    (frame, blends)
}
