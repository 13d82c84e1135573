//! `expf` of eight lanes at once, with the bits of the platform's scalar `f32::exp`, for the
//! tile walk's α (`alpha_of`'s `exp(−q/2)`): the scalar call, once a candidate, was 11 % of a
//! 1080p frame of mode `gaussian` (`docs/trace-speed.md`, "The α's exponential in lanes, and
//! the walk's per-hit bookkeeping").
//!
//! The algorithm is glibc's `expf` (since 2.28; ARM's optimized-routines, Szabolcs Nagy):
//! `x·N/ln 2` rounded to an integer `k` by the 1.5·2⁵² shift, the rest `r` evaluated by a
//! degree-3 polynomial in f64, scaled by `2^(k/N)` from a table of `N = 32` entries with the
//! exponent added to its bits, and rounded once to f32. On x86-64, glibc runs its FMA build
//! (`__expf_fma`) where the CPU has FMA: the rest `r = x·N/ln 2 − k` and the three polynomial
//! steps are fused multiply-adds. [`exp_lanes`] performs those operations, lane by lane, in
//! that order; over every f32 of [−87, 88] (2.24·10⁹ inputs) it returned `f32::exp`'s bits
//! for each (checked exhaustively on this project's build machine; without the fused `r`, 2
//! differ). The tests check a strided sample of that range on every run.
//!
//! A platform whose `f32::exp` is another algorithm (another libm, glibc's non-FMA build)
//! would see different last bits; [`matches_platform`] checks a sample once a process and the
//! tile walk uses these lanes only where it holds, so images never depend on which path ran.

use std::sync::OnceLock;

use super::lanes::LANES;

/// Table entries (`EXP2F_TABLE_BITS = 5`).
const N: u64 = 32;

/// `asuint64(2^(i/N)) − (i << 52)/N`: glibc's `__exp2f_data.tab`.
const TAB: [u64; N as usize] = [
    0x3ff0000000000000,
    0x3fefd9b0d3158574,
    0x3fefb5586cf9890f,
    0x3fef9301d0125b51,
    0x3fef72b83c7d517b,
    0x3fef54873168b9aa,
    0x3fef387a6e756238,
    0x3fef1e9df51fdee1,
    0x3fef06fe0a31b715,
    0x3feef1a7373aa9cb,
    0x3feedea64c123422,
    0x3feece086061892d,
    0x3feebfdad5362a27,
    0x3feeb42b569d4f82,
    0x3feeab07dd485429,
    0x3feea47eb03a5585,
    0x3feea09e667f3bcd,
    0x3fee9f75e8ec5f74,
    0x3feea11473eb0187,
    0x3feea589994cce13,
    0x3feeace5422aa0db,
    0x3feeb737b0cdc5e5,
    0x3feec49182a3f090,
    0x3feed503b23e255d,
    0x3feee89f995ad3ad,
    0x3feeff76f2fb5e47,
    0x3fef199bdd85529c,
    0x3fef3720dcef9069,
    0x3fef5818dcfba487,
    0x3fef7c97337b9b5f,
    0x3fefa4afa2a490da,
    0x3fefd0765b6e4540,
];

/// `N / ln 2` (`0x1.71547652b82fep+0 · N`).
const INV_LN2_N: f64 = f64::from_bits(0x3ff71547652b82fe) * N as f64;
/// `0x1.8p+52`: adding it rounds to an integer held in the low bits.
const SHIFT: f64 = f64::from_bits(0x4338000000000000);
/// The polynomial's coefficients, scaled for `r` in units of `1/N` (`__exp2f_data.poly_scaled`).
const C: [f64; 3] = [
    f64::from_bits(0x3fac6af84b912394) / (N * N * N) as f64,
    f64::from_bits(0x3fcebfce50fac4f3) / (N * N) as f64,
    f64::from_bits(0x3fe62e42ff0c52d6) / N as f64,
];

/// Inputs whose lanes hold `f32::exp`'s bits (the range checked above); outside it, glibc
/// takes its special cases (overflow, underflow, NaN), which the caller takes from the scalar
/// `exp`. The tile walk's arguments `−q/2` with `q ≤ r²` lie in [−6, 0] in practice.
pub(super) const RANGE: (f32, f32) = (-87.0, 88.0);

/// `exp(x[l])` for each lane, glibc's FMA build's operations (module documentation). Inline
/// into a function compiled with FMA: elsewhere `mul_add` is a library call (the same exact
/// result, slowly). A lane outside [`RANGE`] holds an unspecified finite or infinite value.
#[inline(always)]
pub(super) fn exp_lanes(x: [f32; LANES]) -> [f32; LANES] {
    let mut out = [0.0f32; LANES];
    for l in 0..LANES {
        let xd = x[l] as f64;
        let kd = INV_LN2_N * xd + SHIFT;
        let ki = kd.to_bits();
        let kd = kd - SHIFT;
        let r = INV_LN2_N.mul_add(xd, -kd);
        let t = TAB[(ki % N) as usize].wrapping_add(ki << (52 - 5));
        let s = f64::from_bits(t);
        let z = C[0].mul_add(r, C[1]);
        let r2 = r * r;
        let y = C[2].mul_add(r, 1.0);
        let y = z.mul_add(r2, y);
        out[l] = (y * s) as f32;
    }
    out
}

/// Whether [`exp_lanes`] returns `f32::exp`'s bits on this platform, by a sample of [`RANGE`]
/// (every 65,536th float, 34,000 inputs, about a millisecond), checked once a process.
pub(super) fn matches_platform() -> bool {
    static MATCHES: OnceLock<bool> = OnceLock::new();
    *MATCHES.get_or_init(|| differences(65_536) == 0)
}

/// How many floats of [`RANGE`], every `stride`-th by bit pattern, [`exp_lanes`] gives other
/// bits than `f32::exp` for.
pub(super) fn differences(stride: u32) -> u64 {
    let mut diff = 0;
    let mut check = |xs: &[f32]| {
        let mut lanes = [0.0f32; LANES];
        lanes[..xs.len()].copy_from_slice(xs);
        let e = exp_lanes(lanes);
        for (x, e) in xs.iter().zip(e) {
            diff += u64::from(x.exp().to_bits() != e.to_bits());
        }
    };
    let mut batch = Vec::with_capacity(LANES);
    // Negative floats' bits ascend away from zero, positive ones' towards +∞: both halves.
    let halves = [
        ((-0.0f32).to_bits(), RANGE.0.to_bits()),
        (0.0f32.to_bits(), RANGE.1.to_bits()),
    ];
    for (lo, hi) in halves {
        let mut b = lo;
        while b <= hi {
            batch.push(f32::from_bits(b));
            if batch.len() == LANES {
                check(&batch);
                batch.clear();
            }
            b = match b.checked_add(stride) {
                Some(n) => n,
                None => break,
            };
        }
    }
    check(&batch);
    diff
}

/// The tests pin glibc's x86-64 build, the platform the lanes were checked against.
#[cfg(all(test, target_arch = "x86_64", target_os = "linux", target_env = "gnu"))]
mod tests {
    use super::*;

    /// Every 997th float of the range, about 2.2 million inputs: all of `f32::exp`'s bits.
    /// (glibc x86-64 with FMA, the platform the tile walk's lanes are meant for; elsewhere
    /// the walk takes the scalar `exp` and this reports which platform differs.)
    #[test]
    fn lanes_have_the_platform_expf_bits() {
        if !super::super::tiles::vector_exp_supported() {
            eprintln!("skipped: the CPU lacks AVX2 and FMA, where the lanes are not used");
            return;
        }
        assert_eq!(differences(997), 0, "exp_lanes differs from f32::exp");
        assert!(matches_platform());
    }

    /// The rest `r` rounded on its own (glibc's non-FMA build) differs from the lanes, and from
    /// the platform's FMA build, at two inputs of the range (found by the exhaustive run the
    /// module documentation describes): the lanes keep the fused operation where it matters.
    #[test]
    fn the_fused_rest_decides_two_inputs() {
        if !super::super::tiles::vector_exp_supported() {
            eprintln!("skipped: the CPU lacks AVX2 and FMA, where the lanes are not used");
            return;
        }
        let unfused = |x: f32| {
            let xd = x as f64;
            let z = INV_LN2_N * xd;
            let kd = z + SHIFT;
            let ki = kd.to_bits();
            let r = z - (kd - SHIFT);
            let s = f64::from_bits(TAB[(ki % N) as usize].wrapping_add(ki << (52 - 5)));
            let y = (C[0] * r + C[1]) * (r * r) + (C[2] * r + 1.0);
            (y * s) as f32
        };
        for (bits, want) in [
            (0x4202_422f_u32, 0x56fc_9f1c_u32),
            (0xc27c_65d9, 0x11fa_2993),
        ] {
            // Opaque to the optimiser: `exp` of a constant may be folded at compile time by
            // the compiler's own arithmetic (`exp` in f64, rounded once), not the platform's.
            let x = std::hint::black_box(f32::from_bits(bits));
            assert_eq!(x.exp().to_bits(), want, "the platform's expf at {x}");
            assert_eq!(exp_lanes([x; LANES])[0].to_bits(), want, "the lanes at {x}");
            assert_eq!(unfused(x).to_bits(), want - 1, "the unfused rest at {x}");
        }
    }
}
