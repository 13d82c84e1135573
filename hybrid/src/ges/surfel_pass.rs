//! Pass 1 of the GES hybrid: opaque surfels through a z-buffer, no sorting.
//!
//! Per pixel sample the camera ray `d = ((x − c'x)/fx, (y − c'y)/fy, 1)` (pixel `i` sampled at
//! `i`, as the native renderer) is intersected with each candidate surfel's plane: with the
//! camera-relative centre `c`, normal `n` and scaled axes `a_u/s_u`, `a_v/s_v`, the hit is at view
//! depth `t = (n·c)/(n·d)` and local coordinates `u = t·(a_u·d)/s_u − (a_u·c)/s_u` (likewise v).
//! The sample is covered when `t > near`, t is finite and `u² + v² ≤ 2·ln 255` (GES's
//! `−½|uv|² ≥ ln(1/255)`). The nearest covering surfel wins (strictly smaller t; equal depths
//! keep the lower surfel index, so the image does not depend on threads). Exact depth and coverage
//! per sample come for free from the intersection: no rasterised triangles, no depth bias.
//!
//! Each of `n·d`, `a_u·d`, `a_v·d` is linear in the pixel coordinates; the coefficients are formed
//! in f64 from the camera-relative surfel (so scenes far from the origin keep their precision) and
//! rounded to f32 once.
//!
//! The per-sample test runs on eight samples of a row at once (AVX2 where the CPU has it,
//! otherwise per lane); both perform the same f32 operations in the same order as
//! [`SurfelSplat::hit`], so the z-buffer is the same bit for bit (see the tests).
//!
//! Surfels are binned to tiles by the exact screen bounding box of their footprint ellipse (the
//! extremes of `x/z` over the ellipse's rim solve `P·sin θ + Q·cos θ = K`, see [`screen_box`]), in
//! index order, without sorting. A surfel whose footprint crosses the near plane gets the whole
//! screen (per-sample `t > near` clips it exactly).
//!
//! **Supersampling** (`supersample = 4`): four samples per pixel at the standard rotated-grid
//! offsets (±1/8, ±3/8). Per pixel: coverage `w_S = covered/4`, colour the mean over covered
//! samples, output depth the mean over covered samples, and the pass-2 depth limit the largest
//! `D_S + ε` over covered samples (a Gaussian counts if it lies in front of the limit of any
//! covered part of the pixel). With one sample the sample sits at the pixel's integer coordinate.

use std::mem::MaybeUninit;

use rayon::prelude::*;
use splatbridge_scene::surfels::SurfelCloud;

use crate::project::{ViewParams, TILE};

use super::tiles::bin_rects;

pub use super::surfel_project::{footprint_r2, project_surfel, screen_box, SurfelSplat};

pub(crate) const T: usize = TILE as usize;
pub(crate) const N: usize = T * T;

/// Planes of the surfel buffer, per tile (tile-major, `N` values per plane).
pub const P_R: usize = 0;
pub const P_G: usize = 1;
pub const P_B: usize = 2;
/// Coverage `w_S` in [0, 1].
pub const P_W: usize = 3;
/// Output depth (mean over covered samples; 0 where uncovered).
pub const P_DEPTH: usize = 4;
/// Pass-2 depth limit `D_S + ε` (+inf where uncovered).
pub const P_LIMIT: usize = 5;
pub const SURFEL_PLANES: usize = 6;

/// Sample offsets of the 4× pattern (the rotated grid of Direct3D's standard 4× MSAA).
pub const OFFSETS_4: [[f32; 2]; 4] = [
    [-0.125, -0.375],
    [0.375, -0.125],
    [-0.375, 0.125],
    [0.125, 0.375],
];

/// Result of pass 1. Only tiles that some surfel touches hold planes (see `P_*`, `N` values
/// each): `slot[t]` is tile t's index into `planes` in units of `SURFEL_PLANES·N`, `u32::MAX`
/// for a tile without surfels (nothing covered, limit +inf). `ids` holds, per pixel (row-major),
/// the index of the surfel that won the pixel's first sample (`u32::MAX` where none); it is empty
/// unless requested.
pub struct SurfelBuffer {
    pub slot: Vec<u32>,
    pub planes: Vec<f32>,
    /// Per slot, the largest pass-2 limit over the tile's pixels (+inf when any pixel of the
    /// tile, or any position outside the image, is uncovered).
    pub slot_max: Vec<f32>,
    pub ids: Vec<u32>,
    /// Surfels that reached at least one tile.
    pub drawn: usize,
    /// Surfel–tile pairs.
    pub pairs: usize,
}

impl SurfelBuffer {
    /// Largest pass-2 limit of tile t (+inf where a pixel is uncovered or there is no surfel):
    /// a Gaussian behind it is hidden at every pixel of the tile.
    pub fn tile_max(&self, t: usize) -> f32 {
        let s = self.slot[t];
        if s == u32::MAX {
            f32::INFINITY
        } else {
            self.slot_max[s as usize]
        }
    }

    /// Tile t's planes, if any surfel touches it.
    pub fn tile(&self, t: usize) -> Option<&[f32]> {
        let s = self.slot[t];
        (s != u32::MAX).then(|| {
            &self.planes[s as usize * SURFEL_PLANES * N..(s as usize + 1) * SURFEL_PLANES * N]
        })
    }
}

/// Sample offsets for a supersampling factor (1 or 4).
pub fn offsets(supersample: u32) -> &'static [[f32; 2]] {
    if supersample == 4 {
        &OFFSETS_4
    } else {
        &[[0.0, 0.0]]
    }
}

/// Fewest surfels projected per parallel job of [`surfel_pass`].
const PROJECT_CHUNK: usize = 8192;

/// Run pass 1 for `surfels` seen through `view`; the per-pixel winner ids only if `want_ids`
/// (otherwise `ids` is empty).
pub fn surfel_pass(
    surfels: &SurfelCloud,
    view: &ViewParams,
    eps_factor: f32,
    footprint: f32,
    sh_degree: u8,
    supersample: u32,
    max_pairs: usize,
    want_ids: bool,
) -> Result<SurfelBuffer, usize> {
    let degree = surfels.sh_degree.min(sh_degree);
    // One entry per surfel (index = surfel index), so no compaction; a culled surfel keeps an
    // empty tile rectangle and enters no tile list.
    let t = TILE as i32;
    let (proj, rects): (Vec<SurfelSplat>, Vec<[u32; 4]>) = (0..surfels.len())
        .into_par_iter()
        .with_min_len(PROJECT_CHUNK)
        .map(
            |i| match project_surfel(surfels, i, view, eps_factor, footprint, degree) {
                Some(p) => {
                    let b = p.bbox;
                    let r = [
                        (b[0] / t) as u32,
                        (b[1] / t) as u32,
                        (b[2] / t + 1) as u32,
                        (b[3] / t + 1) as u32,
                    ];
                    (p, r)
                }
                None => (SurfelSplat::culled(i), [0; 4]),
            },
        )
        .unzip();
    let bins = bin_rects(&rects, view.grid, max_pairs, |_, _| true)?;
    let (gx, gy) = (view.grid[0] as usize, view.grid[1] as usize);
    let offs = offsets(supersample);
    let near = view.near as f32;
    let mut slot = vec![u32::MAX; gx * gy];
    let mut tiles_used = Vec::new();
    for (t, sl) in slot.iter_mut().enumerate() {
        if !bins.tile(t).is_empty() {
            *sl = tiles_used.len() as u32;
            tiles_used.push(t);
        }
    }
    // Every value of every tile's planes is written by its job (`raster_tile`), so the buffer
    // is not zeroed first: that would be a serial pass over the whole buffer.
    let len = tiles_used.len() * SURFEL_PLANES * N;
    let mut planes: Vec<f32> = Vec::with_capacity(len);
    let mut tile_ids = vec![u32::MAX; if want_ids { tiles_used.len() * N } else { 0 }];
    let mut slot_max = vec![f32::INFINITY; tiles_used.len()];
    let tile_jobs = planes.spare_capacity_mut()[..len]
        .par_chunks_mut(SURFEL_PLANES * N)
        .zip(slot_max.par_iter_mut())
        .zip(tiles_used.par_iter());
    let job = |((out, m), &tile): ((&mut [MaybeUninit<f32>], &mut f32), &usize),
               ids: Option<&mut [u32]>| {
        let (px0, py0) = (((tile % gx) * T) as i32, ((tile / gx) * T) as i32);
        *m = raster_tile(&proj, bins.tile(tile), px0, py0, view, offs, near, out, ids);
    };
    if want_ids {
        tile_jobs
            .zip(tile_ids.par_chunks_mut(N))
            .with_max_len(1)
            .for_each(|(j, ids)| job(j, Some(ids)));
    } else {
        tile_jobs.with_max_len(1).for_each(|j| job(j, None));
    }
    // SAFETY: the chunks cover `..len` and `raster_tile` initialised every element of its chunk.
    unsafe { planes.set_len(len) };
    // Frame-level ids of the first sample.
    let (w, h) = (view.width as usize, view.height as usize);
    let mut ids = vec![u32::MAX; if want_ids { w * h } else { 0 }];
    ids.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, v) in row.iter_mut().enumerate() {
                let sl = slot[(y / T) * gx + x / T];
                if sl != u32::MAX {
                    let k = tile_ids[sl as usize * N + (y % T) * T + x % T];
                    if k != u32::MAX {
                        *v = proj[k as usize].index;
                    }
                }
            }
        });
    let _ = gy;
    Ok(SurfelBuffer {
        slot,
        planes,
        slot_max,
        ids,
        drawn: rects.iter().filter(|r| r[2] > r[0] && r[3] > r[1]).count(),
        pairs: bins.pairs(),
    })
}

/// Z-buffer one tile into `out` (`SURFEL_PLANES·N` values, every one written). `ids`, if given,
/// receives per tile pixel the index into `proj` that won sample 0.
/// Returns the largest pass-2 limit of the tile.
#[allow(clippy::too_many_arguments)]
fn raster_tile(
    proj: &[SurfelSplat],
    list: &[u32],
    px0: i32,
    py0: i32,
    view: &ViewParams,
    offs: &[[f32; 2]],
    near: f32,
    out: &mut [MaybeUninit<f32>],
    mut ids: Option<&mut [u32]>,
) -> f32 {
    assert_eq!(out.len(), SURFEL_PLANES * N);
    let ns = offs.len();
    let r2 = footprint_r2();
    let mut zbuf = [f32::INFINITY; 4 * N];
    let mut win = [u32::MAX; 4 * N];
    zbuffer(proj, list, px0, py0, offs, near, r2, &mut zbuf, &mut win);
    let (w, h) = (view.width as i32, view.height as i32);
    let mut tile_max = f32::NEG_INFINITY;
    for lp in 0..N {
        let (x, y) = (px0 + (lp % T) as i32, py0 + (lp / T) as i32);
        if let Some(ids) = ids.as_deref_mut() {
            ids[lp] = win[lp];
        }
        let mut k = 0u32;
        let (mut r, mut g, mut b, mut d) = (0f32, 0f32, 0f32, 0f32);
        let mut limit = f32::NEG_INFINITY;
        if x < w && y < h {
            for si in 0..ns {
                let wk = win[si * N + lp];
                if wk == u32::MAX {
                    continue;
                }
                let s = &proj[wk as usize];
                let z = zbuf[si * N + lp];
                k += 1;
                r += s.color[0];
                g += s.color[1];
                b += s.color[2];
                d += z;
                limit = limit.max(z + s.eps);
            }
        }
        // Uncovered (or outside the image): nothing, and no limit.
        let px = if k > 0 {
            let inv = 1.0 / k as f32;
            [
                r * inv,
                g * inv,
                b * inv,
                k as f32 / ns as f32,
                d * inv,
                limit,
            ]
        } else {
            [0.0, 0.0, 0.0, 0.0, 0.0, f32::INFINITY]
        };
        for (p, v) in px.into_iter().enumerate() {
            out[p * N + lp].write(v);
        }
        tile_max = tile_max.max(px[P_LIMIT]);
    }
    tile_max
}

/// How many list entries ahead the z-buffer loop prefetches.
const PREFETCH: usize = 8;

#[inline(always)]
fn prefetch(s: &SurfelSplat) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint without architectural effect; the address is a valid reference.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>((s as *const SurfelSplat).cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = s;
}

/// Eight adjacent samples of a row through surfel `s` (index `k`): tile positions
/// `base..base + 8` of the sample planes `zbuf`/`win`, the first at x = `xb + ox`, row
/// coordinate `y` (offset included); only lanes `lo..=hi` lie in the surfel's box. The portable
/// form: [`SurfelSplat::hit`] per lane.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn row8(
    s: &SurfelSplat,
    k: u32,
    xb: f32,
    ox: f32,
    y: f32,
    lanes: (usize, usize),
    near: f32,
    r2: f32,
    zbuf: &mut [f32; 8],
    win: &mut [u32; 8],
) {
    for l in lanes.0..=lanes.1 {
        let (t, covered) = s.hit(xb + l as f32 + ox, y, near, r2);
        if covered && t < zbuf[l] {
            zbuf[l] = t;
            win[l] = k;
        }
    }
}

/// [`row8`] on 256-bit vectors: the same f32 operations in the same order, so the same bits.
#[cfg(target_arch = "x86_64")]
mod avx {
    use std::arch::x86_64::*;

    use super::SurfelSplat;

    /// # Safety
    /// The CPU must support AVX2.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub unsafe fn row8(
        s: &SurfelSplat,
        k: u32,
        xb: f32,
        ox: f32,
        y: f32,
        lanes: (usize, usize),
        near: f32,
        r2: f32,
        zbuf: &mut [f32; 8],
        win: &mut [u32; 8],
    ) {
        // SAFETY: AVX2 is present (caller); the loads and stores touch exactly the 8 elements
        // of `zbuf` and `win`.
        unsafe {
            let v = |x: f32| _mm256_set1_ps(x);
            let idx = _mm256_set_epi32(7, 6, 5, 4, 3, 2, 1, 0);
            let in_box = _mm256_castsi256_ps(_mm256_and_si256(
                _mm256_cmpgt_epi32(idx, _mm256_set1_epi32(lanes.0 as i32 - 1)),
                _mm256_cmpgt_epi32(_mm256_set1_epi32(lanes.1 as i32 + 1), idx),
            ));
            // `x as f32 + o[0]` of the scalar loop: the integer pixel x is exact in f32.
            let x = _mm256_add_ps(
                _mm256_add_ps(v(xb), _mm256_set_ps(7.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0, 0.0)),
                v(ox),
            );
            let lin = |c: [f32; 3]| {
                _mm256_add_ps(
                    _mm256_add_ps(_mm256_mul_ps(v(c[0]), x), v(c[1] * y)),
                    v(c[2]),
                )
            };
            let t = _mm256_div_ps(v(s.nc), lin(s.n));
            let u = _mm256_sub_ps(_mm256_mul_ps(t, lin(s.u)), v(s.uc));
            let w = _mm256_sub_ps(_mm256_mul_ps(t, lin(s.v)), v(s.vc));
            let q = _mm256_add_ps(_mm256_mul_ps(u, u), _mm256_mul_ps(w, w));
            let covered = _mm256_and_ps(
                _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_GT_OQ>(t, v(near)),
                    _mm256_cmp_ps::<_CMP_LT_OQ>(t, v(f32::MAX)),
                ),
                _mm256_cmp_ps::<_CMP_LE_OQ>(q, v(r2)),
            );
            let zp = zbuf.as_mut_ptr();
            let wp = win.as_mut_ptr() as *mut __m256i;
            let z = _mm256_loadu_ps(zp);
            let take = _mm256_and_ps(
                _mm256_and_ps(covered, in_box),
                _mm256_cmp_ps::<_CMP_LT_OQ>(t, z),
            );
            _mm256_storeu_ps(zp, _mm256_blendv_ps(z, t, take));
            let old = _mm256_castsi256_ps(_mm256_loadu_si256(wp));
            let kk = _mm256_castsi256_ps(_mm256_set1_epi32(k as i32));
            _mm256_storeu_si256(wp, _mm256_castps_si256(_mm256_blendv_ps(old, kk, take)));
        }
    }
}

/// The z-buffer loop of a tile, with the 8-sample row kernel as a parameter: for every surfel
/// of `list` in order and every sample offset, the rows and 8-pixel groups its box reaches.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn zbuffer_with(
    proj: &[SurfelSplat],
    list: &[u32],
    px0: i32,
    py0: i32,
    offs: &[[f32; 2]],
    near: f32,
    r2: f32,
    zbuf: &mut [f32; 4 * N],
    win: &mut [u32; 4 * N],
    kernel: impl Fn(
        &SurfelSplat,
        u32,
        f32,
        f32,
        f32,
        (usize, usize),
        f32,
        f32,
        &mut [f32; 8],
        &mut [u32; 8],
    ),
) {
    let (tx1, ty1) = (px0 + T as i32 - 1, py0 + T as i32 - 1);
    for (i, &k) in list.iter().enumerate() {
        if let Some(&ahead) = list.get(i + PREFETCH) {
            prefetch(&proj[ahead as usize]);
        }
        let s = &proj[k as usize];
        let (x0, x1) = (s.bbox[0].max(px0), s.bbox[2].min(tx1));
        let (y0, y1) = (s.bbox[1].max(py0), s.bbox[3].min(ty1));
        if x0 > x1 || y0 > y1 {
            continue;
        }
        let (lx0, lx1) = ((x0 - px0) as usize, (x1 - px0) as usize);
        for (si, o) in offs.iter().enumerate() {
            for y in y0..=y1 {
                let row = si * N + (y - py0) as usize * T;
                let yf = y as f32 + o[1];
                for h in lx0 / 8..=lx1 / 8 {
                    let lanes = (lx0.max(8 * h) - 8 * h, lx1.min(8 * h + 7) - 8 * h);
                    let base = row + 8 * h;
                    let z: &mut [f32; 8] = (&mut zbuf[base..base + 8]).try_into().unwrap();
                    let w: &mut [u32; 8] = (&mut win[base..base + 8]).try_into().unwrap();
                    let xb = (px0 + 8 * h as i32) as f32;
                    kernel(s, k, xb, o[0], yf, lanes, near, r2, z, w);
                }
            }
        }
    }
}

/// [`zbuffer_with`] compiled for AVX2 with the 256-bit kernel.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn zbuffer_avx2(
    proj: &[SurfelSplat],
    list: &[u32],
    px0: i32,
    py0: i32,
    offs: &[[f32; 2]],
    near: f32,
    r2: f32,
    zbuf: &mut [f32; 4 * N],
    win: &mut [u32; 4 * N],
) {
    // SAFETY: this function only runs when AVX2 is present.
    let k8 =
        |s: &SurfelSplat,
         k: u32,
         xb: f32,
         ox: f32,
         y: f32,
         lanes: (usize, usize),
         near: f32,
         r2: f32,
         z: &mut [f32; 8],
         w: &mut [u32; 8]| unsafe { avx::row8(s, k, xb, ox, y, lanes, near, r2, z, w) };
    zbuffer_with(proj, list, px0, py0, offs, near, r2, zbuf, win, k8)
}

/// Z-buffer the surfels `list` into the sample planes of the tile at `(px0, py0)` with the
/// fastest kernel the CPU has (both give the same bits, see the tests).
#[allow(clippy::too_many_arguments)]
fn zbuffer(
    proj: &[SurfelSplat],
    list: &[u32],
    px0: i32,
    py0: i32,
    offs: &[[f32; 2]],
    near: f32,
    r2: f32,
    zbuf: &mut [f32; 4 * N],
    win: &mut [u32; 4 * N],
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present.
        return unsafe { zbuffer_avx2(proj, list, px0, py0, offs, near, r2, zbuf, win) };
    }
    zbuffer_with(proj, list, px0, py0, offs, near, r2, zbuf, win, row8)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ges::surfel_project::{ceil_in, clamp_box, floor_in};
    use glam::DVec3;
    use splatbridge_scene::rng::Rng;

    /// Random surfels around a 16×16 tile at (32, 48): planes tilted a little, ellipses of a
    /// few pixels centred near the tile, some in front of the near plane, boxes cut by the tile.
    fn random_surfels(rng: &mut Rng, n: usize) -> Vec<SurfelSplat> {
        (0..n)
            .map(|i| {
                let nrm = [
                    rng.range(-0.02, 0.02),
                    rng.range(-0.02, 0.02),
                    rng.range(0.5, 1.5),
                ];
                let (cx, cy) = (rng.range(26.0, 70.0), rng.range(42.0, 70.0));
                let nc = rng.range(0.0, 4.0);
                let t0 = nc / (nrm[0] * cx + nrm[1] * cy + nrm[2]);
                let mut axis = || {
                    let c = [
                        rng.range(-0.6, 0.6),
                        rng.range(-0.6, 0.6),
                        rng.range(-2.0, 2.0),
                    ];
                    let at = t0 * (c[0] * cx + c[1] * cy + c[2]);
                    (c, at)
                };
                let ((u, uc), (v, vc)) = (axis(), axis());
                let r = rng.range(1.0, 12.0);
                let (bx, by) = (cx.round() as i32, cy.round() as i32);
                let rr = r.ceil() as i32;
                SurfelSplat {
                    n: nrm,
                    u,
                    v,
                    nc,
                    uc,
                    vc,
                    color: [rng.f32(), rng.f32(), rng.f32()],
                    eps: rng.range(0.0, 0.5),
                    bbox: [bx - rr, by - rr, bx + rr, by + rr],
                    index: i as u32,
                }
            })
            .collect()
    }

    /// The integer floor and ceil of the box bounds equal `f64::floor`/`f64::ceil` on the
    /// clamped range they are used on: integers, their neighbours one ulp away, halves,
    /// negative fractions down to −1 and random values.
    #[test]
    fn integer_floor_and_ceil_match_libm() {
        let mut vals = vec![
            -1.0, -0.75, -0.5, -1e-300, -0.0, 0.0, 1e-300, 0.5, 1919.5, 16384.0,
        ];
        for k in -1..=2000 {
            let v = k as f64;
            vals.extend([v, v.next_up(), v.next_down(), v + 0.5]);
        }
        let mut rng = Rng::new(5);
        vals.extend((0..100_000).map(|_| rng.range(-1.0, 4000.0) as f64 * 1.000_123));
        for v in vals {
            let c = clamp_box(v, 3000);
            assert_eq!(floor_in(c), c.floor() as i64, "floor {v:e}");
            assert_eq!(ceil_in(c), c.ceil() as i64, "ceil {v:e}");
        }
        // The clamp commutes with floor/ceil at integer bounds, as the box computation assumes.
        for v in [-1e300, -7.5, -1.5, 2999.5, 3000.5, 1e300] {
            let c = clamp_box(v, 3000);
            assert_eq!(floor_in(c), (v.floor().max(-1.0) as i64).min(3000), "{v}");
            assert_eq!(ceil_in(c), (v.ceil().min(3000.0) as i64).max(-1), "{v}");
        }
    }

    /// The algebraic screen box equals the extremes of a dense sampling of the projected rim:
    /// it contains every sample and each of its edges is reached by one (to the sampling's
    /// resolution), for tilted ellipses in front of a camera.
    #[test]
    fn screen_box_matches_a_sampled_rim() {
        let cam =
            splatbridge_scene::Camera::look_at(DVec3::ZERO, DVec3::Z, DVec3::NEG_Y, 60.0, 640, 480)
                .unwrap();
        let view = ViewParams::new(&cam, 0.2);
        let mut rng = Rng::new(23);
        let mut r = |a: f64, b: f64| rng.range(a as f32, b as f32) as f64;
        for case in 0..500 {
            let c = DVec3::new(r(-3.0, 3.0), r(-2.0, 2.0), r(2.0, 8.0));
            let u = DVec3::new(r(-1.0, 1.0), r(-1.0, 1.0), r(-1.0, 1.0));
            let w = DVec3::new(r(-1.0, 1.0), r(-1.0, 1.0), r(-1.0, 1.0));
            let b = screen_box(&view, c, u, w);
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            const K: usize = 20_000;
            for j in 0..K {
                let th = j as f64 * std::f64::consts::TAU / K as f64;
                let p = c + th.cos() * u + th.sin() * w;
                let px = [
                    view.fx * p.x / p.z + view.px0,
                    view.fy * p.y / p.z + view.py0,
                ];
                for a in 0..2 {
                    lo[a] = lo[a].min(px[a]);
                    hi[a] = hi[a].max(px[a]);
                }
            }
            // Near an extreme the projection is flat in θ: the sampled extreme is within
            // R·(π/K)² of the true one, R the screen radius (below 1000 px here): < 1e-4 px.
            for a in 0..2 {
                assert!(
                    b[a] <= lo[a] + 1e-9 && lo[a] - b[a] < 1e-3,
                    "case {case}: {b:?} {lo:?}"
                );
                assert!(
                    b[a + 2] >= hi[a] - 1e-9 && b[a + 2] - hi[a] < 1e-3,
                    "case {case}: {b:?} {hi:?}"
                );
            }
        }
    }

    /// The z-buffer kernels (AVX2 where the CPU has it, and the portable one) give the bits of
    /// the per-sample loop: nearest covering surfel, ties to the lower index, per sample.
    #[test]
    fn zbuffer_kernels_match_the_per_sample_loop() {
        let mut rng = Rng::new(17);
        let proj = random_surfels(&mut rng, 400);
        let list: Vec<u32> = (0..proj.len() as u32).collect();
        let (px0, py0, near, r2) = (32, 48, 0.2f32, footprint_r2());
        for offs in [offsets(1), offsets(4)] {
            let mut want_z = [f32::INFINITY; 4 * N];
            let mut want_w = [u32::MAX; 4 * N];
            for &k in &list {
                let s = &proj[k as usize];
                for y in s.bbox[1].max(py0)..=s.bbox[3].min(py0 + T as i32 - 1) {
                    for x in s.bbox[0].max(px0)..=s.bbox[2].min(px0 + T as i32 - 1) {
                        let lp = (y - py0) as usize * T + (x - px0) as usize;
                        for (si, o) in offs.iter().enumerate() {
                            let (t, c) = s.hit(x as f32 + o[0], y as f32 + o[1], near, r2);
                            if c && t < want_z[si * N + lp] {
                                want_z[si * N + lp] = t;
                                want_w[si * N + lp] = k;
                            }
                        }
                    }
                }
            }
            let won = want_w[..offs.len() * N]
                .iter()
                .filter(|&&w| w != u32::MAX)
                .count();
            assert!(won > offs.len() * N / 2, "only {won} samples covered");
            let (mut z, mut w) = ([f32::INFINITY; 4 * N], [u32::MAX; 4 * N]);
            zbuffer_with(&proj, &list, px0, py0, offs, near, r2, &mut z, &mut w, row8);
            assert_eq!(z.map(f32::to_bits), want_z.map(f32::to_bits));
            assert_eq!(w, want_w);
            let (mut z, mut w) = ([f32::INFINITY; 4 * N], [u32::MAX; 4 * N]);
            zbuffer(&proj, &list, px0, py0, offs, near, r2, &mut z, &mut w);
            assert_eq!(z.map(f32::to_bits), want_z.map(f32::to_bits));
            assert_eq!(w, want_w);
        }
    }
}
