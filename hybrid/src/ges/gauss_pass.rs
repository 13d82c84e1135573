//! Pass 2 of the GES hybrid: the residual Gaussians, unsorted, additively accumulated.
//!
//! Per pixel, Gaussian i (projected by the native renderer's [`crate::project::project_one`])
//! counts when its view depth `zᵢ ≤ D_S + ε` (the pass-1 limit, +inf where no surfel covers the
//! pixel), `power ≤ 0` and `αᵢ = opacityᵢ·exp(power) ≥ 1/255`: no 0.99 clamp, no transmittance
//! order, no early stop (GES's Gaussian pass). It adds `αᵢ·cᵢ` to `C_G`, `αᵢ` to `W_G`, `αᵢ·zᵢ` to
//! the depth sum and multiplies `T` by `1 − αᵢ` (see [`super::composite`] for what T is for).
//!
//! Gaussians are visited per tile in input order, each pixel by one task, so the sums are formed
//! in a fixed order and the image is the same for any thread count. The tile lists themselves
//! already omit Gaussians behind every surfel of the tile (see [`super::tiles`]); inside a tile,
//! a Gaussian skips each 8-pixel row group whose largest limit it lies behind. The loop is the
//! native renderer's 8-lane branch-free form, with its vectorisable `exp`: written with AVX2
//! intrinsics where the CPU has them, otherwise as plain per-lane arithmetic that the compiler
//! vectorises; both perform the same f32 operations in the same order (the tests compare bits).
//! Finished tiles are composited straight into the frame.

use splatbridge_scene::Frame;

use crate::kernel::exp_nonpos;
use crate::project::Splat;
use crate::raster::{prefetch, PREFETCH};

use super::composite::{composite_pixel, GaussAcc};
use super::surfel_pass::{N, P_B, P_DEPTH, P_G, P_LIMIT, P_R, P_W, T};

/// Per-pixel sums of one tile.
struct Acc {
    r: [f32; N],
    g: [f32; N],
    b: [f32; N],
    w: [f32; N],
    t: [f32; N],
    dz: [f32; N],
}

impl Acc {
    fn new() -> Self {
        Acc {
            r: [0.0; N],
            g: [0.0; N],
            b: [0.0; N],
            w: [0.0; N],
            t: [1.0; N],
            dz: [0.0; N],
        }
    }
}

/// One Gaussian's constants for one pixel row: `power = (m0·dx)·dx + k1·dx + k0` with
/// `dx = x − xb`… as written out in [`lanes8`].
#[derive(Clone, Copy, Debug)]
struct RowK {
    sx: f32,
    /// `−½·c0`
    m0: f32,
    /// `−c1·dy`
    k1: f32,
    /// `−½·c2·dy·dy`
    k0: f32,
    opacity: f32,
    depth: f32,
    color: [f32; 3],
}

/// Eight pixels of a row (`base..base + 8`, the first at pixel x `xb`): the portable form,
/// branch-free on fixed-size arrays so that the compiler vectorises it. Returns the additions.
#[inline(always)]
fn lanes8(acc: &mut Acc, base: usize, limit: &[f32; 8], xb: f32, k: &RowK) -> u32 {
    let r: &mut [f32; 8] = (&mut acc.r[base..base + 8]).try_into().unwrap();
    let g: &mut [f32; 8] = (&mut acc.g[base..base + 8]).try_into().unwrap();
    let b: &mut [f32; 8] = (&mut acc.b[base..base + 8]).try_into().unwrap();
    let w: &mut [f32; 8] = (&mut acc.w[base..base + 8]).try_into().unwrap();
    let t: &mut [f32; 8] = (&mut acc.t[base..base + 8]).try_into().unwrap();
    let dz: &mut [f32; 8] = (&mut acc.dz[base..base + 8]).try_into().unwrap();
    let mut n = 0u32;
    for l in 0..8 {
        let dx = k.sx - (xb + l as f32);
        let power = k.m0 * dx * dx + k.k1 * dx + k.k0;
        let a = k.opacity * exp_nonpos(power);
        let add = (power <= 0.0) & (a >= 1.0 / 255.0) & (k.depth <= limit[l]);
        let a = if add { a } else { 0.0 };
        r[l] += k.color[0] * a;
        g[l] += k.color[1] * a;
        b[l] += k.color[2] * a;
        w[l] += a;
        dz[l] += k.depth * a;
        t[l] *= 1.0 - a;
        n += add as u32;
    }
    n
}

/// [`lanes8`] on 256-bit vectors: the same operations in the same order, so the same bits.
#[cfg(target_arch = "x86_64")]
mod avx {
    use std::arch::x86_64::*;

    use super::{Acc, RowK, N};
    use crate::kernel::avx::exp8;

    // SAFETY (all intrinsics below): callers run these only inside a function compiled with
    // `target_feature(enable = "avx2")` after `is_x86_feature_detected!("avx2")`; the memory
    // accesses are the unaligned 8-lane loads/stores noted at their pointers.

    /// # Safety
    /// The CPU must support AVX2.
    #[inline(always)]
    pub unsafe fn lanes8(acc: &mut Acc, base: usize, limit: &[f32; 8], xb: f32, k: &RowK) -> u32 {
        // SAFETY: each pointer comes from a bounds-checked 8-element subslice of a tile plane,
        // and every load/store below touches exactly those 8 lanes; AVX2 is present (the
        // caller's contract).
        let lanes = |a: &mut [f32; N]| -> *mut f32 { a[base..base + 8].as_mut_ptr() };
        let rp = lanes(&mut acc.r);
        let gp = lanes(&mut acc.g);
        let bp = lanes(&mut acc.b);
        let wp = lanes(&mut acc.w);
        let tp = lanes(&mut acc.t);
        let zp = lanes(&mut acc.dz);
        unsafe {
            let s = |v: f32| _mm256_set1_ps(v);
            let xs = _mm256_add_ps(s(xb), _mm256_set_ps(7.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0, 0.0));
            let dx = _mm256_sub_ps(s(k.sx), xs);
            let power = _mm256_add_ps(
                _mm256_add_ps(
                    _mm256_mul_ps(_mm256_mul_ps(s(k.m0), dx), dx),
                    _mm256_mul_ps(s(k.k1), dx),
                ),
                s(k.k0),
            );
            let a = _mm256_mul_ps(s(k.opacity), exp8(power));
            let add = _mm256_and_ps(
                _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_LE_OQ>(power, s(0.0)),
                    _mm256_cmp_ps::<_CMP_GE_OQ>(a, s(1.0 / 255.0)),
                ),
                _mm256_cmp_ps::<_CMP_LE_OQ>(s(k.depth), _mm256_loadu_ps(limit.as_ptr())),
            );
            let a = _mm256_and_ps(add, a);
            let acc =
                |p: *mut f32, v: __m256| _mm256_storeu_ps(p, _mm256_add_ps(_mm256_loadu_ps(p), v));
            acc(rp, _mm256_mul_ps(s(k.color[0]), a));
            acc(gp, _mm256_mul_ps(s(k.color[1]), a));
            acc(bp, _mm256_mul_ps(s(k.color[2]), a));
            acc(wp, a);
            acc(zp, _mm256_mul_ps(s(k.depth), a));
            _mm256_storeu_ps(
                tp,
                _mm256_mul_ps(_mm256_loadu_ps(tp), _mm256_sub_ps(s(1.0), a)),
            );
            (_mm256_movemask_ps(add) as u32).count_ones()
        }
    }
}

/// Accumulate the Gaussians `list` into the tile whose top-left pixel is `(px0, py0)`, with the
/// kernel for eight adjacent pixels as a parameter. Returns the blend count.
#[inline(always)]
fn accumulate_with(
    splats: &[Splat],
    list: &[u32],
    px0: i32,
    py0: i32,
    limit: &[f32; N],
    acc: &mut Acc,
    kernel: impl Fn(&mut Acc, usize, &[f32; 8], f32, &RowK) -> u32,
) -> u64 {
    // Largest limit of each 8-pixel half row.
    let mut group_max = [f32::NEG_INFINITY; N / 8];
    for (gi, m) in group_max.iter_mut().enumerate() {
        *m = limit[gi * 8..gi * 8 + 8]
            .iter()
            .cloned()
            .fold(f32::NEG_INFINITY, f32::max);
    }
    let (tx1, ty1) = (px0 + T as i32 - 1, py0 + T as i32 - 1);
    let mut blends = 0u64;
    for (i, &k) in list.iter().enumerate() {
        // Tile lists are sparse in the splat array: fetch a few entries ahead so the loads
        // overlap instead of each costing a full memory round trip.
        if let Some(&ahead) = list.get(i + PREFETCH) {
            prefetch(&splats[ahead as usize]);
        }
        let s = &splats[k as usize];
        let [bx0, by0, bx1, by1] = s.bbox;
        let (x0, x1) = (bx0.max(px0), bx1.min(tx1));
        let (y0, y1) = (by0.max(py0), by1.min(ty1));
        if x0 > x1 || y0 > y1 {
            continue;
        }
        let (h0, h1) = (((x0 - px0) / 8) as usize, ((x1 - px0) / 8) as usize);
        let [c0, c1, c2] = s.conic;
        for y in y0..=y1 {
            let ly = (y - py0) as usize;
            let dy = s.y - y as f32;
            let row = RowK {
                sx: s.x,
                m0: -0.5 * c0,
                k1: -c1 * dy,
                k0: -0.5 * c2 * dy * dy,
                opacity: s.opacity,
                depth: s.depth,
                color: s.color,
            };
            for h in h0..=h1 {
                let base = ly * T + h * 8;
                if s.depth > group_max[base / 8] {
                    continue;
                }
                let xb = (px0 + 8 * h as i32) as f32;
                let lim: &[f32; 8] = limit[base..base + 8].try_into().unwrap();
                blends += kernel(acc, base, lim, xb, &row) as u64;
            }
        }
    }
    blends
}

/// [`accumulate_with`] compiled for AVX2 with the 256-bit kernel.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_avx2(
    splats: &[Splat],
    list: &[u32],
    px0: i32,
    py0: i32,
    limit: &[f32; N],
    acc: &mut Acc,
) -> u64 {
    // SAFETY: this function only runs when AVX2 is present.
    let k8 = |acc: &mut Acc, base: usize, lim: &[f32; 8], xb: f32, k: &RowK| unsafe {
        avx::lanes8(acc, base, lim, xb, k)
    };
    accumulate_with(splats, list, px0, py0, limit, acc, k8)
}

/// Accumulate with the fastest kernel the CPU has.
fn accumulate(
    splats: &[Splat],
    list: &[u32],
    px0: i32,
    py0: i32,
    limit: &[f32; N],
    acc: &mut Acc,
) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 is present.
        return unsafe { accumulate_avx2(splats, list, px0, py0, limit, acc) };
    }
    accumulate_with(splats, list, px0, py0, limit, acc, lanes8)
}

/// The frame's planes as raw pointers, so tiles running in parallel each write their own
/// pixels without a tile-major intermediate copy.
pub struct FrameOut {
    rgb: *mut f32,
    alpha: *mut f32,
    depth: *mut f32,
    width: usize,
    height: usize,
}

// SAFETY: the pointers are only written through `gauss_tile`, whose callers pass each tile once
// (each tile writes its own 16×16 block) while the frame is borrowed mutably by `FrameOut::new`.
unsafe impl Sync for FrameOut {}

impl FrameOut {
    /// Writes into `frame`, which must outlive every use and not be touched otherwise meanwhile.
    pub fn new(frame: &mut Frame) -> Self {
        FrameOut {
            rgb: frame.rgb.as_mut_ptr(),
            alpha: frame.alpha.as_mut_ptr(),
            depth: frame.depth.as_mut_ptr(),
            width: frame.width as usize,
            height: frame.height as usize,
        }
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Write pixel `p` (row-major).
    ///
    /// # Safety
    /// `p < width·height`; the frame must be alive and no one else may access pixel `p`
    /// meanwhile.
    #[inline]
    pub unsafe fn write(&self, p: usize, rgb: [f32; 3], alpha: f32, depth: f32) {
        // SAFETY: the planes hold 3·, 1·, 1·(width·height) values and p is in range (the
        // caller's contract).
        unsafe {
            self.rgb.add(3 * p).write(rgb[0]);
            self.rgb.add(3 * p + 1).write(rgb[1]);
            self.rgb.add(3 * p + 2).write(rgb[2]);
            self.alpha.add(p).write(alpha);
            self.depth.add(p).write(depth);
        }
    }
}

/// Accumulate and composite one tile whose top-left pixel is `(px0, py0)` into `out`. `surf` is
/// the tile's surfel planes (None: no surfel touches the tile). Returns the blend count.
///
/// # Safety
/// `out` must come from a frame that is still alive and that no one else reads or writes
/// meanwhile, and no other call may write the same tile concurrently.
pub unsafe fn gauss_tile(
    splats: &[Splat],
    list: &[u32],
    px0: i32,
    py0: i32,
    surf: Option<&[f32]>,
    bg: [f32; 3],
    out: &FrameOut,
) -> u64 {
    let mut acc = Acc::new();
    const INF: [f32; N] = [f32::INFINITY; N];
    let limit: &[f32; N] = match surf {
        Some(p) => p[P_LIMIT * N..(P_LIMIT + 1) * N].try_into().unwrap(),
        None => &INF,
    };
    let blends = accumulate(splats, list, px0, py0, limit, &mut acc);
    let (px0, py0) = (px0 as usize, py0 as usize);
    let cols = out.width.saturating_sub(px0).min(T);
    let rows = out.height.saturating_sub(py0).min(T);
    for y in 0..rows {
        for x in 0..cols {
            let i = y * T + x;
            let g = GaussAcc {
                c: [acc.r[i], acc.g[i], acc.b[i]],
                w: acc.w[i],
                t: acc.t[i],
                dz: acc.dz[i],
            };
            let (cs, ws, ds) = match surf {
                Some(p) => (
                    [p[P_R * N + i], p[P_G * N + i], p[P_B * N + i]],
                    p[P_W * N + i],
                    p[P_DEPTH * N + i],
                ),
                None => ([0.0; 3], 0.0, 0.0),
            };
            let (rgb, alpha, depth) = composite_pixel(cs, ws, ds, &g, bg);
            let p = (py0 + y) * out.width + px0 + x;
            // SAFETY: p < width·height (x < cols, y < rows) and the planes hold 3·, 1·, 1·that;
            // the caller guarantees the frame is alive and this tile is written only here.
            unsafe {
                out.rgb.add(3 * p).write(rgb[0]);
                out.rgb.add(3 * p + 1).write(rgb[1]);
                out.rgb.add(3 * p + 2).write(rgb[2]);
                out.alpha.add(p).write(alpha);
                out.depth.add(p).write(depth);
            }
        }
    }
    blends
}

#[cfg(test)]
mod tests {
    use super::*;
    use splatbridge_scene::rng::Rng;

    fn random_splats(rng: &mut Rng, n: usize) -> Vec<Splat> {
        (0..n)
            .map(|_| {
                let (x, y) = (rng.range(-6.0, 22.0), rng.range(-6.0, 22.0));
                let (sa, sb) = (rng.range(0.3, 6.0), rng.range(0.3, 6.0));
                let rho = rng.range(-0.9, 0.9);
                let (a, c, b) = (sa * sa, sb * sb, rho * sa * sb);
                let det = a * c - b * b;
                let r = (3.4 * sa.max(sb)).ceil() as i32;
                let (xi, yi) = (x.round() as i32, y.round() as i32);
                Splat {
                    x,
                    y,
                    conic: [c / det, -b / det, a / det],
                    opacity: rng.range(0.0, 1.0),
                    color: [rng.range(0.0, 2.0), rng.f32(), rng.f32()],
                    depth: rng.range(0.2, 9.0),
                    bbox: [xi - r, yi - r, xi + r, yi + r],
                }
            })
            .collect()
    }

    /// The AVX2 tile loop gives the bits of the portable one (and of the plain per-lane
    /// arithmetic, which `lanes8` is), with and without per-pixel depth limits.
    #[cfg(target_arch = "x86_64")]
    #[test]
    #[cfg_attr(not(host_avx2), ignore = "the CPU has no AVX2")]
    fn avx_accumulation_matches_portable() {
        // Built where the CPU has it (build.rs); running it elsewhere would be undefined.
        assert!(std::arch::is_x86_feature_detected!("avx2"));
        let mut rng = Rng::new(61);
        let splats = random_splats(&mut rng, 3000);
        let list: Vec<u32> = (0..splats.len() as u32).collect();
        let mut limit = [f32::INFINITY; N];
        for round in 0..2 {
            let mut a = Acc::new();
            let mut b = Acc::new();
            // SAFETY: AVX2 was detected above.
            let na = unsafe { accumulate_avx2(&splats, &list, 0, 0, &limit, &mut a) };
            let nb = accumulate_with(&splats, &list, 0, 0, &limit, &mut b, lanes8);
            assert!(nb > 10_000, "round {round}: only {nb} blends exercised");
            assert_eq!(na, nb, "round {round}");
            for (pa, pb) in [
                (&a.r, &b.r),
                (&a.g, &b.g),
                (&a.b, &b.b),
                (&a.w, &b.w),
                (&a.t, &b.t),
                (&a.dz, &b.dz),
            ] {
                assert_eq!(pa.map(f32::to_bits), pb.map(f32::to_bits), "round {round}");
            }
            for l in limit.iter_mut() {
                *l = rng.range(0.0, 10.0);
            }
        }
    }
}
