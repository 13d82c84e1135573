//! Eight-lane kernels of the tile path ([`super::tiles`]): a cell's list stored eight entries
//! at a time, field by field ([`Chunk`]), so that a ray tests eight entries' screen rectangles
//! and ellipses, and evaluates eight pixel-space responses ([`super::camera::PixelSplat::q`]),
//! without a branch per entry; and the colours of a ray's composited hits evaluated together
//! ([`colors_from_basis`]), their SH sums interleaved instead of one dependent chain per hit.
//!
//! Every lane performs the scalar code's float operations in the scalar code's order (no
//! fused multiply-add, no reassociation), so each lane's result has the scalar result's bits:
//! the tile path's images stay equal to the per-ray BVH path's and the brute-force
//! reference's bit for bit (`tile_tests`), and the kernels are checked lane by lane against
//! the scalar functions (`lane_tests`). The lanes are plain arrays, vectorized as far as the
//! compiler finds (no CPU feature is required); the cache hint of [`prefetch`] is
//! `crate::prefetch`'s.

use glam::Vec3;

use super::camera::PixelSplat;
use super::tiles::Entry;

/// Entries per [`Chunk`].
pub(super) const LANES: usize = 8;

/// Eight consecutive entries of a cell's list, field by field; lanes past the list's end are
/// [`Chunk::EMPTY`]'s, whose rectangle no ray is in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Chunk {
    /// The entries' rectangles `[u0, v0, u1, v1]` (see [`Entry`]).
    rect: [[f32; LANES]; 4],
    /// The screen ellipses: centre, `K` and `a_max` (see [`Entry`]).
    emu: [[f32; LANES]; 2],
    k: [[f32; LANES]; 3],
    amax: [f32; LANES],
    /// The mean's view depth (the key's numerator) and the proxy's index.
    pub(super) z: [f32; LANES],
    pub(super) p: [u32; LANES],
    /// The proxies' [`PixelSplat`] records (mode `on`; the default record otherwise).
    mu: [[f32; LANES]; 2],
    p0: [[f32; LANES]; 3],
    p1: [[f32; LANES]; 3],
    w: [[f32; LANES]; 3],
    pub(super) r2: [f32; LANES],
    pub(super) opacity: [f32; LANES],
    pub(super) ok: [bool; LANES],
}

impl Chunk {
    /// No entry: an empty rectangle.
    pub(super) const EMPTY: Chunk = Chunk {
        rect: [
            [f32::INFINITY; LANES],
            [f32::INFINITY; LANES],
            [f32::NEG_INFINITY; LANES],
            [f32::NEG_INFINITY; LANES],
        ],
        emu: [[0.0; LANES]; 2],
        k: [[0.0; LANES]; 3],
        amax: [f32::INFINITY; LANES],
        z: [0.0; LANES],
        p: [0; LANES],
        mu: [[0.0; LANES]; 2],
        p0: [[0.0; LANES]; 3],
        p1: [[0.0; LANES]; 3],
        w: [[0.0; LANES]; 3],
        r2: [0.0; LANES],
        opacity: [0.0; LANES],
        ok: [false; LANES],
    };

    /// Lane `l` set to entry `e` and its proxy's record `px`.
    pub(super) fn set(&mut self, l: usize, e: &Entry, px: &PixelSplat) {
        for c in 0..4 {
            self.rect[c][l] = e.rect[c];
        }
        for c in 0..2 {
            self.emu[c][l] = e.mu[c];
            self.mu[c][l] = px.mu[c];
        }
        for c in 0..3 {
            self.k[c][l] = e.k[c];
            self.p0[c][l] = px.p0[c];
            self.p1[c][l] = px.p1[c];
            self.w[c][l] = px.w[c];
        }
        self.amax[l] = e.amax;
        self.z[l] = e.z;
        self.p[l] = e.p;
        self.r2[l] = px.r2;
        self.opacity[l] = px.opacity;
        self.ok[l] = px.ok;
    }

    /// `list` in chunks, each entry with its proxy's record (`record(p)`): the reference
    /// [`super::tiles::Cells::build`] is checked against.
    #[cfg(test)]
    pub(super) fn pack(list: &[Entry], record: impl Fn(usize) -> PixelSplat, out: &mut Vec<Chunk>) {
        for group in list.chunks(LANES) {
            let mut c = Chunk::EMPTY;
            for (l, e) in group.iter().enumerate() {
                c.set(l, e, &record(e.p as usize));
            }
            out.push(c);
        }
    }

    /// Bit `l` set when the continuous pixel `(u, v)` is in lane `l`'s rectangle and its
    /// centred pixel `(cu, cv)` in the lane's screen ellipse: the tests of the scalar walk,
    /// `u ∈ [u0, u1]`, `v ∈ [v0, v1]` and `k0·x0·x0 + 2·k1·x0·x1 + k2·x1·x1 ≤ a_max`.
    #[inline(always)]
    pub(super) fn pass(&self, u: f32, v: f32, cu: f32, cv: f32) -> u32 {
        let mut m = 0u32;
        for l in 0..LANES {
            let inside = (u >= self.rect[0][l])
                & (u <= self.rect[2][l])
                & (v >= self.rect[1][l])
                & (v <= self.rect[3][l]);
            let (x0, x1) = (self.emu[0][l] - cu, self.emu[1][l] - cv);
            let e = self.k[0][l] * x0 * x0 + 2.0 * self.k[1][l] * x0 * x1 + self.k[2][l] * x1 * x1;
            m |= ((inside & (e <= self.amax[l])) as u32) << l;
        }
        m
    }

    /// [`Chunk::pass`] in AVX2 registers: the same compares and the same products and sums in
    /// the same order (`(k0·x0)·x0 + ((2·k1)·x0)·x1`, then `+ (k2·x1)·x1`; ordered compares,
    /// false for NaN as Rust's are), one mask by `movemask` instead of a bit a lane. The
    /// plain loop above stayed scalar in the AVX2 build (about 200 instructions a chunk,
    /// `cachegrind`).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) unsafe fn pass_avx2(&self, u: f32, v: f32, cu: f32, cv: f32) -> u32 {
        use std::arch::x86_64::*;
        // Closures would be compiled without AVX2: the loads are a macro.
        macro_rules! ld {
            ($a:expr) => {
                // SAFETY: `$a` is a `[f32; LANES]`, eight floats (32 bytes), read unaligned.
                unsafe { _mm256_loadu_ps($a.as_ptr()) }
            };
        }
        let (u8, v8) = (_mm256_set1_ps(u), _mm256_set1_ps(v));
        let inside = _mm256_and_ps(
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(u8, ld!(self.rect[0])),
                _mm256_cmp_ps::<_CMP_LE_OQ>(u8, ld!(self.rect[2])),
            ),
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(v8, ld!(self.rect[1])),
                _mm256_cmp_ps::<_CMP_LE_OQ>(v8, ld!(self.rect[3])),
            ),
        );
        let x0 = _mm256_sub_ps(ld!(self.emu[0]), _mm256_set1_ps(cu));
        let x1 = _mm256_sub_ps(ld!(self.emu[1]), _mm256_set1_ps(cv));
        let a = _mm256_mul_ps(_mm256_mul_ps(ld!(self.k[0]), x0), x0);
        let two_k1 = _mm256_mul_ps(_mm256_set1_ps(2.0), ld!(self.k[1]));
        let b = _mm256_mul_ps(_mm256_mul_ps(two_k1, x0), x1);
        let c = _mm256_mul_ps(_mm256_mul_ps(ld!(self.k[2]), x1), x1);
        let e = _mm256_add_ps(_mm256_add_ps(a, b), c);
        let ell = _mm256_cmp_ps::<_CMP_LE_OQ>(e, ld!(self.amax));
        _mm256_movemask_ps(_mm256_and_ps(inside, ell)) as u32
    }

    /// [`PixelSplat::q`] of every lane for the centred pixel `(u, v)` and a low-pass of `s`
    /// pixels² (`s2 = s²`): the lanes' `q` and a bit per lane whose determinant is a positive
    /// finite number (where the scalar function returns `Some(q)`).
    #[inline(always)]
    pub(super) fn q(&self, (u, v): (f32, f32), s: f32, s2: f32) -> ([f32; LANES], u32) {
        let mut q = [0.0f32; LANES];
        let mut ok = 0u32;
        for l in 0..LANES {
            let w = [self.w[0][l], self.w[1][l], self.w[2][l]];
            let b0 = [
                self.p0[0][l] - u * w[0],
                self.p0[1][l] - u * w[1],
                self.p0[2][l] - u * w[2],
            ];
            let b1 = [
                self.p1[0][l] - v * w[0],
                self.p1[1][l] - v * w[1],
                self.p1[2][l] - v * w[2],
            ];
            // glam's `dot` and `cross`, term for term.
            let dot = |a: [f32; 3], b: [f32; 3]| (a[0] * b[0]) + (a[1] * b[1]) + (a[2] * b[2]);
            let (m00, m01, m11) = (dot(b0, b0), dot(b0, b1), dot(b1, b1));
            let c = [
                b0[1] * b1[2] - b1[1] * b0[2],
                b0[2] * b1[0] - b1[2] * b0[0],
                b0[0] * b1[1] - b1[0] * b0[1],
            ];
            let det = dot(c, c) + s * (m00 + m11) + s2;
            let (x0, x1) = (self.mu[0][l] - u, self.mu[1][l] - v);
            q[l] = (x0 * x0 * (m11 + s) - 2.0 * x0 * x1 * m01 + x1 * x1 * (m00 + s)) / det;
            ok |= (((det > 0.0) & (det < f32::INFINITY)) as u32) << l;
        }
        (q, ok)
    }
}

/// Scratch space of [`colors_from_basis`]: each hit's products, and four floats of slack so
/// that the last coefficient's four-float add stays inside (their values never reach a
/// colour).
pub(super) struct Products([[f32; 52]; LANES]);

impl Default for Products {
    fn default() -> Self {
        Products([[0.0; 52]; LANES])
    }
}

/// Hint the cache to fetch `coeffs` (a hit's SH coefficients, read when its colour is
/// evaluated after the ray's walk).
#[inline(always)]
pub(super) fn prefetch(coeffs: &[Vec3]) {
    crate::prefetch::lines(coeffs);
}

/// [`super::tiles::color_from_basis`] of each of `coeffs` (at most [`LANES`] slices of equal
/// length, at most 16 coefficients) with the basis `b`, appended to `out`: the same products
/// and the same sums in the same order, so each colour has `color_from_basis`'s bits.
///
/// The products of a hit's 16 coefficients are taken as one flat array (its 48 floats times
/// the basis repeated per channel); each hit's three channel sums then advance together, one
/// four-float add a coefficient (the fourth lane is scratch), and the hits' chains are
/// interleaved, so no hit waits on another's sixteen dependent additions.
pub(super) fn colors_from_basis(
    coeffs: &[&[Vec3]],
    b: &[f32; 16],
    prod: &mut Products,
    out: &mut Vec<Vec3>,
) {
    debug_assert!(coeffs.len() <= LANES);
    let n = coeffs.len().min(LANES);
    if n == 0 {
        return;
    }
    let k = coeffs[0].len().min(16);
    // The basis per float of a coefficient array: b3[3j + c] = b[j].
    let mut b3 = [0.0f32; 48];
    for (j, bj) in b.iter().enumerate() {
        b3[3 * j..3 * j + 3].fill(*bj);
    }
    for (h, c) in coeffs.iter().enumerate().take(n) {
        let flat: &[f32] = bytemuck::cast_slice(&c[..k]);
        for ((p, x), b) in prod.0[h].iter_mut().zip(flat).zip(&b3) {
            *p = *x * *b;
        }
    }
    let prod = &prod.0;
    // All eight lanes (a lane past `n` sums a previous call's products, never read), so the
    // sums stay in registers.
    let mut sums = [[0.0f32; 4]; LANES];
    for j in 0..k {
        for (s, p) in sums.iter_mut().zip(prod) {
            let p = &p[3 * j..3 * j + 4];
            for c in 0..4 {
                s[c] += p[c];
            }
        }
    }
    for s in &sums[..n] {
        let v = Vec3::new(s[0], s[1], s[2]);
        out.push((v + Vec3::splat(0.5)).max(Vec3::ZERO));
    }
}

#[cfg(test)]
#[path = "lane_tests.rs"]
mod lane_tests;
