//! The blending kernel: one Gaussian into four horizontally adjacent pixels of a tile.
//!
//! On x86_64 it is written with SSE2 intrinsics (part of the x86_64 baseline, so no runtime
//! detection); elsewhere a scalar twin performs the same f32 operations in the same order, so
//! both give identical bits. Masked lanes add `+0.0`, which leaves the (non-negative)
//! accumulators bit-identical, so the result equals the per-pixel loop of the reference.
//!
//! `power = −½·((c0·dx)·dx + (c2·dy)·dy) − dx·(c1·dy)`: the reference's expression with the
//! per-row products hoisted (the same value up to f32 rounding).

/// Pixels per tile row and per tile.
pub const T: usize = crate::project::TILE as usize;
pub const N: usize = T * T;

/// Per-pixel accumulators of one tile.
pub struct TileState {
    pub t: [f32; N],
    pub r: [f32; N],
    pub g: [f32; N],
    pub b: [f32; N],
    /// Σ w·z and Σ w (w = α·T) for the blended depth.
    pub dz: [f32; N],
    pub w: [f32; N],
    /// All ones once the pixel stopped (or lies outside the image).
    pub done: [u32; N],
}

impl TileState {
    /// Fresh state for a tile of which `cols × rows` pixels lie inside the image.
    pub fn new(cols: usize, rows: usize) -> Self {
        let mut done = [u32::MAX; N];
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
}

/// One Gaussian's constants for one pixel row.
#[derive(Clone, Copy, Debug)]
pub struct SplatRow {
    pub sx: f32,
    pub c0: f32,
    /// `c1·dy`
    pub c1dy: f32,
    /// `(c2·dy)·dy`
    pub c2dy2: f32,
    pub opacity: f32,
    pub clamp: f32,
    pub color: [f32; 3],
    pub depth: f32,
}

const LOG2E: f32 = std::f32::consts::LOG2_E;
const C1: f32 = 0.693_359_4;
const C2: f32 = -2.121_944_4e-4;
/// 1.5·2²³: adding and subtracting it rounds to an integer.
const ROUND: f32 = 12_582_912.0;
const P: [f32; 6] = [
    1.987_569_1e-4,
    1.398_199_9e-3,
    8.333_452e-3,
    4.166_579_6e-2,
    1.666_666_5e-1,
    0.5,
];
const MIN_ALPHA: f32 = 1.0 / 255.0;
const MIN_T: f32 = 1e-4;

/// `exp(x)` for `x ≤ 0` (larger inputs are treated as 0, smaller than −87 as −87, where the
/// result is below any α threshold). Cephes `expf`: range reduction by ln 2 split in two
/// constants, degree-5 polynomial, exponent assembled from bits.
#[inline(always)]
pub fn exp_nonpos(x: f32) -> f32 {
    // max/min rather than clamp: no NaN panic path, and it matches maxps/minps.
    #[allow(clippy::manual_clamp)]
    let x = x.max(-87.0).min(0.0);
    let n = (x * LOG2E + ROUND) - ROUND;
    let r = (x - n * C1) - n * C2;
    let mut p = P[0];
    for c in &P[1..] {
        p = p * r + c;
    }
    let y = (p * r) * r + r + 1.0;
    y * f32::from_bits(((n as i32 + 127) as u32) << 23)
}

/// Blend into pixels `base..base + 4` (pixel x of the first is `x0`). Returns (blends, stops).
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
pub fn blend4(st: &mut TileState, base: usize, x0: f32, k: &SplatRow) -> (u32, u32) {
    let (mut blends, mut stops) = (0, 0);
    for l in 0..4 {
        let i = base + l;
        let dx = k.sx - (x0 + l as f32);
        let q = k.c0 * dx * dx + k.c2dy2;
        let power = -0.5 * q - dx * k.c1dy;
        let a = (k.opacity * exp_nonpos(power)).min(k.clamp);
        let t = st.t[i];
        let test_t = t * (1.0 - a);
        let live = st.done[i] == 0 && power <= 0.0 && a >= MIN_ALPHA;
        let stop = live && test_t < MIN_T;
        let add = live && !stop;
        let w = a * t;
        let m = |v: f32| if add { v } else { 0.0 };
        st.r[i] += m(k.color[0] * w);
        st.g[i] += m(k.color[1] * w);
        st.b[i] += m(k.color[2] * w);
        st.dz[i] += m(k.depth * w);
        st.w[i] += m(w);
        if add {
            st.t[i] = test_t;
        }
        if stop {
            st.done[i] = u32::MAX;
        }
        blends += add as u32;
        stops += stop as u32;
    }
    (blends, stops)
}

#[cfg(target_arch = "x86_64")]
mod sse {
    use std::arch::x86_64::*;

    use super::*;

    // SAFETY (all intrinsics below): SSE and SSE2 are part of the x86_64 baseline, so the
    // instructions exist on every x86_64 target; the only memory accesses are the unaligned
    // 4-lane loads/stores noted at their pointers.

    #[inline(always)]
    fn exp4(x: __m128) -> __m128 {
        unsafe {
            let s = |v: f32| _mm_set1_ps(v);
            let x = _mm_min_ps(_mm_max_ps(x, s(-87.0)), s(0.0));
            let n = _mm_sub_ps(_mm_add_ps(_mm_mul_ps(x, s(LOG2E)), s(ROUND)), s(ROUND));
            let r = _mm_sub_ps(_mm_sub_ps(x, _mm_mul_ps(n, s(C1))), _mm_mul_ps(n, s(C2)));
            let mut p = s(P[0]);
            for c in &P[1..] {
                p = _mm_add_ps(_mm_mul_ps(p, r), s(*c));
            }
            let y = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_mul_ps(p, r), r), r), s(1.0));
            let e = _mm_slli_epi32::<23>(_mm_add_epi32(_mm_cvttps_epi32(n), _mm_set1_epi32(127)));
            _mm_mul_ps(y, _mm_castsi128_ps(e))
        }
    }

    /// Blend into pixels `base..base + 4` (pixel x of the first is `x0`). Returns (blends, stops).
    #[inline(always)]
    pub fn blend4(st: &mut TileState, base: usize, x0: f32, k: &SplatRow) -> (u32, u32) {
        // SAFETY: each pointer comes from a bounds-checked 4-element subslice of a tile plane,
        // and every load/store below touches exactly those 4 lanes; SSE2 is x86_64 baseline.
        let lanes = |a: &mut [f32; N]| -> *mut f32 { a[base..base + 4].as_mut_ptr() };
        let tp = lanes(&mut st.t);
        let rp = lanes(&mut st.r);
        let gp = lanes(&mut st.g);
        let bp = lanes(&mut st.b);
        let zp = lanes(&mut st.dz);
        let wp = lanes(&mut st.w);
        let dp = st.done[base..base + 4].as_mut_ptr() as *mut __m128i;
        unsafe {
            let s = |v: f32| _mm_set1_ps(v);
            let dx = _mm_sub_ps(s(k.sx), _mm_add_ps(s(x0), _mm_set_ps(3.0, 2.0, 1.0, 0.0)));
            let q = _mm_add_ps(_mm_mul_ps(_mm_mul_ps(s(k.c0), dx), dx), s(k.c2dy2));
            let power = _mm_sub_ps(_mm_mul_ps(s(-0.5), q), _mm_mul_ps(dx, s(k.c1dy)));
            let a = _mm_min_ps(_mm_mul_ps(s(k.opacity), exp4(power)), s(k.clamp));
            let t = _mm_loadu_ps(tp);
            let done = _mm_castsi128_ps(_mm_loadu_si128(dp));
            let test_t = _mm_mul_ps(t, _mm_sub_ps(s(1.0), a));
            let ok = _mm_and_ps(_mm_cmple_ps(power, s(0.0)), _mm_cmpge_ps(a, s(MIN_ALPHA)));
            let live = _mm_andnot_ps(done, ok);
            let stop = _mm_and_ps(live, _mm_cmplt_ps(test_t, s(MIN_T)));
            let add = _mm_andnot_ps(stop, live);
            let w = _mm_mul_ps(a, t);
            let acc = |p: *mut f32, v: __m128| {
                _mm_storeu_ps(p, _mm_add_ps(_mm_loadu_ps(p), _mm_and_ps(add, v)))
            };
            acc(rp, _mm_mul_ps(s(k.color[0]), w));
            acc(gp, _mm_mul_ps(s(k.color[1]), w));
            acc(bp, _mm_mul_ps(s(k.color[2]), w));
            acc(zp, _mm_mul_ps(s(k.depth), w));
            acc(wp, w);
            _mm_storeu_ps(
                tp,
                _mm_or_ps(_mm_and_ps(add, test_t), _mm_andnot_ps(add, t)),
            );
            _mm_storeu_si128(dp, _mm_castps_si128(_mm_or_ps(done, stop)));
            (
                (_mm_movemask_ps(add) as u32).count_ones(),
                (_mm_movemask_ps(stop) as u32).count_ones(),
            )
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub use sse::blend4;

/// Eight adjacent pixels at once: the same lane arithmetic as [`blend4`] on 256-bit vectors.
/// Only meaningful inside a function compiled with AVX2 (see `raster::blend_tile`); elsewhere
/// it is two [`blend4`] calls, which give the same bits.
#[cfg(target_arch = "x86_64")]
pub mod avx {
    use std::arch::x86_64::*;

    use super::*;

    // SAFETY (all intrinsics below): callers run these only inside a function compiled with
    // `target_feature(enable = "avx2")` after `is_x86_feature_detected!("avx2")`; memory
    // accesses are the unaligned 8-lane loads/stores noted at their pointers.

    /// [`super::exp_nonpos`] on eight lanes (its constants and operation order; `n` is an
    /// integer in [−126, 0], so truncation equals Rust's saturating cast). Shared with the GES
    /// accumulation kernel.
    #[inline(always)]
    pub(crate) fn exp8(x: __m256) -> __m256 {
        // SAFETY: register-only AVX2 intrinsics (no memory access), run only where AVX2 is
        // present (see the note above).
        unsafe {
            let s = |v: f32| _mm256_set1_ps(v);
            let x = _mm256_min_ps(_mm256_max_ps(x, s(-87.0)), s(0.0));
            let n = _mm256_sub_ps(
                _mm256_add_ps(_mm256_mul_ps(x, s(LOG2E)), s(ROUND)),
                s(ROUND),
            );
            let r = _mm256_sub_ps(
                _mm256_sub_ps(x, _mm256_mul_ps(n, s(C1))),
                _mm256_mul_ps(n, s(C2)),
            );
            let mut p = s(P[0]);
            for c in &P[1..] {
                p = _mm256_add_ps(_mm256_mul_ps(p, r), s(*c));
            }
            let y = _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(p, r), r), r),
                s(1.0),
            );
            let e = _mm256_slli_epi32::<23>(_mm256_add_epi32(
                _mm256_cvttps_epi32(n),
                _mm256_set1_epi32(127),
            ));
            _mm256_mul_ps(y, _mm256_castsi256_ps(e))
        }
    }

    /// Blend into pixels `base..base + 8` (pixel x of the first is `x0`). Returns (blends, stops).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline(always)]
    pub unsafe fn blend8(st: &mut TileState, base: usize, x0: f32, k: &SplatRow) -> (u32, u32) {
        // SAFETY: each pointer comes from a bounds-checked 8-element subslice of a tile plane,
        // and every load/store below touches exactly those 8 lanes; AVX2 is present (the
        // caller's contract).
        let lanes = |a: &mut [f32; N]| -> *mut f32 { a[base..base + 8].as_mut_ptr() };
        let tp = lanes(&mut st.t);
        let rp = lanes(&mut st.r);
        let gp = lanes(&mut st.g);
        let bp = lanes(&mut st.b);
        let zp = lanes(&mut st.dz);
        let wp = lanes(&mut st.w);
        let dp = st.done[base..base + 8].as_mut_ptr() as *mut __m256i;
        unsafe {
            let s = |v: f32| _mm256_set1_ps(v);
            let xs = _mm256_add_ps(s(x0), _mm256_set_ps(7.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0, 0.0));
            let dx = _mm256_sub_ps(s(k.sx), xs);
            let q = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(s(k.c0), dx), dx), s(k.c2dy2));
            let power = _mm256_sub_ps(_mm256_mul_ps(s(-0.5), q), _mm256_mul_ps(dx, s(k.c1dy)));
            let a = _mm256_min_ps(_mm256_mul_ps(s(k.opacity), exp8(power)), s(k.clamp));
            let t = _mm256_loadu_ps(tp);
            let done = _mm256_castsi256_ps(_mm256_loadu_si256(dp));
            let test_t = _mm256_mul_ps(t, _mm256_sub_ps(s(1.0), a));
            let ok = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_LE_OQ>(power, s(0.0)),
                _mm256_cmp_ps::<_CMP_GE_OQ>(a, s(MIN_ALPHA)),
            );
            let live = _mm256_andnot_ps(done, ok);
            let stop = _mm256_and_ps(live, _mm256_cmp_ps::<_CMP_LT_OQ>(test_t, s(MIN_T)));
            let add = _mm256_andnot_ps(stop, live);
            let w = _mm256_mul_ps(a, t);
            let acc = |p: *mut f32, v: __m256| {
                _mm256_storeu_ps(p, _mm256_add_ps(_mm256_loadu_ps(p), _mm256_and_ps(add, v)))
            };
            acc(rp, _mm256_mul_ps(s(k.color[0]), w));
            acc(gp, _mm256_mul_ps(s(k.color[1]), w));
            acc(bp, _mm256_mul_ps(s(k.color[2]), w));
            acc(zp, _mm256_mul_ps(s(k.depth), w));
            acc(wp, w);
            _mm256_storeu_ps(
                tp,
                _mm256_or_ps(_mm256_and_ps(add, test_t), _mm256_andnot_ps(add, t)),
            );
            _mm256_storeu_si256(dp, _mm256_castps_si256(_mm256_or_ps(done, stop)));
            (
                (_mm256_movemask_ps(add) as u32).count_ones(),
                (_mm256_movemask_ps(stop) as u32).count_ones(),
            )
        }
    }
}

/// Eight adjacent pixels as two [`blend4`] calls (the portable path; the same bits as
/// [`avx::blend8`]).
#[inline(always)]
pub fn blend8_pair(st: &mut TileState, base: usize, x0: f32, k: &SplatRow) -> (u32, u32) {
    let (b0, s0) = blend4(st, base, x0, k);
    let (b1, s1) = blend4(st, base + 4, x0 + 4.0, k);
    (b0 + b1, s0 + s1)
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

    /// The 8-lane AVX2 kernel gives the bits of two 4-lane calls.
    #[cfg(target_arch = "x86_64")]
    #[test]
    #[cfg_attr(not(host_avx2), ignore = "the CPU has no AVX2")]
    fn avx_kernel_matches_sse_kernel() {
        // Built where the CPU has it (build.rs); running it elsewhere would be undefined.
        assert!(std::arch::is_x86_feature_detected!("avx2"));
        let mut rng = splatbridge_scene::rng::Rng::new(8);
        let mut a = TileState::new(16, 13);
        let mut b = TileState::new(16, 13);
        for round in 0..4000 {
            let k = SplatRow {
                sx: rng.range(-4.0, 20.0),
                c0: rng.range(0.0, 3.0),
                c1dy: rng.range(-3.0, 3.0),
                c2dy2: rng.range(0.0, 10.0),
                opacity: rng.range(0.0, 1.0),
                clamp: 0.999,
                color: [rng.range(0.0, 2.0), rng.f32(), rng.f32()],
                depth: rng.range(0.2, 9.0),
            };
            let base = 8 * (round % 32);
            let x0 = (base % T) as f32;
            // SAFETY: AVX2 was detected above.
            let got = unsafe { avx::blend8(&mut a, base, x0, &k) };
            assert_eq!(got, blend8_pair(&mut b, base, x0, &k));
        }
        assert_eq!(a.t.map(f32::to_bits), b.t.map(f32::to_bits));
        assert_eq!(a.g.map(f32::to_bits), b.g.map(f32::to_bits));
        assert_eq!(a.w.map(f32::to_bits), b.w.map(f32::to_bits));
        assert_eq!(a.done, b.done);
    }

    /// The SIMD kernel (on x86_64) gives the bits of the plain per-lane arithmetic.
    #[test]
    fn kernel_matches_scalar_arithmetic() {
        let mut rng = splatbridge_scene::rng::Rng::new(3);
        let mut st = TileState::new(16, 16);
        let mut want = TileState::new(16, 16);
        for round in 0..2000 {
            let k = SplatRow {
                sx: rng.range(-4.0, 20.0),
                c0: rng.range(0.0, 3.0),
                c1dy: rng.range(-3.0, 3.0),
                c2dy2: rng.range(0.0, 10.0),
                opacity: rng.range(0.0, 1.0),
                clamp: 0.99,
                color: [rng.range(0.0, 2.0), rng.f32(), rng.f32()],
                depth: rng.range(0.2, 9.0),
            };
            let base = 4 * (round % 64);
            let x0 = (base % T) as f32;
            let got = blend4(&mut st, base, x0, &k);
            let (mut nb, mut ns) = (0, 0);
            for l in 0..4 {
                let i = base + l;
                let dx = k.sx - (x0 + l as f32);
                let power = -0.5 * (k.c0 * dx * dx + k.c2dy2) - dx * k.c1dy;
                let a = (k.opacity * exp_nonpos(power)).min(k.clamp);
                if want.done[i] != 0 || power > 0.0 || a < MIN_ALPHA {
                    continue;
                }
                let test_t = want.t[i] * (1.0 - a);
                if test_t < MIN_T {
                    want.done[i] = u32::MAX;
                    ns += 1;
                    continue;
                }
                let w = a * want.t[i];
                want.r[i] += k.color[0] * w;
                want.g[i] += k.color[1] * w;
                want.b[i] += k.color[2] * w;
                want.dz[i] += k.depth * w;
                want.w[i] += w;
                want.t[i] = test_t;
                nb += 1;
            }
            assert_eq!(got, (nb, ns));
        }
        assert_eq!(st.t.map(f32::to_bits), want.t.map(f32::to_bits));
        assert_eq!(st.r.map(f32::to_bits), want.r.map(f32::to_bits));
        assert_eq!(st.dz.map(f32::to_bits), want.dz.map(f32::to_bits));
        assert_eq!(st.done, want.done);
    }
}
