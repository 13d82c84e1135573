//! The sRGB transfer function (IEC 61966-2-1, as glTF and every viewer apply it): the
//! reference encode and decode through `powf`, and a table-and-series encode for hot loops
//! (mesh distillation shades every recorded hit of every view in every step).
//!
//! [`encode_fast`] computes `1.055·x^(1/2.4) − 0.055` in f64 from the exponent of `x` (a
//! 10-entry table of `2^(5e/12)`), the top eight bits of its mantissa (a 256-entry table of
//! `m₀^(5/12)` at each interval's centre) and the binomial series of `(1 + t)^(5/12)` to its
//! third power (`|t| ≤ 1/512`, so the first term left out is below 1e-12 of the value), and
//! rounds once to f32: it is the correctly rounded encode except where the exact value lies
//! within about 1e-12 of a rounding boundary, while the f32 formula rounds three times.

/// sRGB encode (linear → display value) of a colour clamped to [0, 1], through `powf`.
#[inline]
pub fn encode(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB decode (display → linear).
#[inline]
pub fn decode(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

const A: f64 = 5.0 / 12.0;
// Binomial coefficients of (1 + t)^A.
const K2: f64 = A * (A - 1.0) / 2.0;
const K3: f64 = K2 * (A - 2.0) / 3.0;
/// The mantissa's intervals: the top eight bits of the mantissa.
const BITS: u32 = 8;
const INTERVALS: usize = 1 << BITS;

/// The tables of [`encode_fast`].
struct Tables {
    /// `2^(5e/12)` for the exponents e = −9…0 of (0.0031308, 1].
    pow2: [f64; 10],
    /// `[m₀^(5/12), 1/m₀]` at the centres `m₀ = 1 + (i + ½)/256` of the mantissa's intervals.
    centre: [[f64; 2]; INTERVALS],
}

static TABLES: std::sync::LazyLock<Tables> = std::sync::LazyLock::new(|| {
    let mut centre = [[0.0; 2]; INTERVALS];
    for (i, c) in centre.iter_mut().enumerate() {
        let m0 = 1.0 + (i as f64 + 0.5) / INTERVALS as f64;
        *c = [m0.powf(A), 1.0 / m0];
    }
    Tables {
        pow2: std::array::from_fn(|k| 2f64.powf(A * (k as f64 - 9.0))),
        centre,
    }
});

/// [`encode`] without `powf` on (0.0031308, 1], from tables filled on first use (the module
/// documentation says how); other values (the linear toe, anything above 1, NaN) as
/// [`encode`].
#[inline]
pub fn encode_fast(c: f32) -> f32 {
    if !(c > 0.003_130_8 && c <= 1.0) {
        return encode(c);
    }
    power(c)
}

/// [`encode_fast`] of a value already in [0, 1] (a clamped colour), bit for bit, without
/// branches: both the linear toe and the power are computed and one is selected, so a hot
/// loop over colours near black does not mispredict.
#[inline]
pub fn encode_unit(c: f32) -> f32 {
    let (toe, power) = (c * 12.92, power(c));
    if c <= 0.003_130_8 {
        toe
    } else {
        power
    }
}

/// `1.055·c^(1/2.4) − 0.055` from the tables, exact for c in (0.0031308, 1]; for other
/// values the exponent's index is clamped to the table, so the result is finite and unused.
#[inline]
fn power(c: f32) -> f32 {
    let t = &*TABLES;
    let bits = c.to_bits();
    // Biased exponents 118…127 are e = −9…0.
    let e = ((bits >> 23) as usize).clamp(118, 127) - 118;
    let i = ((bits >> (23 - BITS)) as usize) & (INTERVALS - 1);
    let m = f64::from(f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000));
    let [pow_m0, inv_m0] = t.centre[i];
    let x = m * inv_m0 - 1.0;
    let series = 1.0 + x * (A + x * (K2 + x * K3));
    (1.055 * (t.pow2[e] * pow_m0 * series) - 0.055) as f32
}

/// [`encode_unit`] of four values at once, compiled for AVX2: the exponent's and mantissa's
/// table entries gathered for the four lanes and the series in four f64 lanes. Every lane
/// performs [`encode_unit`]'s IEEE operations in its order (Rust never fuses a multiply and an
/// add), so each lane is [`encode_unit`] of its value to the bit, NaN and −0.0 included. The
/// indices are clamped to the tables whatever the lane holds, so any four floats may be given.
///
/// Hot loops that shade three channels a hit (mesh distillation's forward pass) run it in one
/// 128-bit register instead of three scalar encodes.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub unsafe fn encode_unit4_avx2(
    c: std::arch::x86_64::__m128,
    tables: &EncodeTables,
) -> std::arch::x86_64::__m128 {
    use std::arch::x86_64::*;
    let t = tables.0;
    let bits = _mm_castps_si128(c);
    // Biased exponents 118…127 are e = −9…0; the shift is logical, as `u32 >> 23`.
    let e = _mm_sub_epi32(
        _mm_min_epi32(
            _mm_max_epi32(_mm_srli_epi32::<23>(bits), _mm_set1_epi32(118)),
            _mm_set1_epi32(127),
        ),
        _mm_set1_epi32(118),
    );
    let i = _mm_and_si128(
        _mm_srli_epi32::<{ 23 - BITS as i32 }>(bits),
        _mm_set1_epi32(INTERVALS as i32 - 1),
    );
    let mant = _mm_or_si128(
        _mm_and_si128(bits, _mm_set1_epi32(0x007f_ffff)),
        _mm_set1_epi32(0x3f80_0000),
    );
    let m = _mm256_cvtps_pd(_mm_castsi128_ps(mant));
    let centre = t.centre.as_ptr() as *const f64;
    let i2 = _mm_slli_epi32::<1>(i);
    // SAFETY: `i2 = 2i` with i ≤ 255 and `e` in 0..=9 index within `centre` (256 pairs of
    // f64) and `pow2` (10 f64); the gathers read 8-byte elements at those offsets.
    let (pow_m0, inv_m0, pow2) = unsafe {
        (
            _mm256_i32gather_pd::<8>(centre, i2),
            _mm256_i32gather_pd::<8>(centre.add(1), i2),
            _mm256_i32gather_pd::<8>(t.pow2.as_ptr(), e),
        )
    };
    let one = _mm256_set1_pd(1.0);
    let x = _mm256_sub_pd(_mm256_mul_pd(m, inv_m0), one);
    let inner = _mm256_add_pd(_mm256_set1_pd(K2), _mm256_mul_pd(x, _mm256_set1_pd(K3)));
    let inner = _mm256_add_pd(_mm256_set1_pd(A), _mm256_mul_pd(x, inner));
    let series = _mm256_add_pd(one, _mm256_mul_pd(x, inner));
    let power = _mm256_sub_pd(
        _mm256_mul_pd(
            _mm256_set1_pd(1.055),
            _mm256_mul_pd(_mm256_mul_pd(pow2, pow_m0), series),
        ),
        _mm256_set1_pd(0.055),
    );
    let power = _mm256_cvtpd_ps(power);
    let toe = _mm_mul_ps(c, _mm_set1_ps(12.92));
    _mm_blendv_ps(power, toe, _mm_cmple_ps(c, _mm_set1_ps(0.003_130_8)))
}

/// The tables [`encode_unit4_avx2`] reads, taken once outside a hot loop (the first use fills
/// them).
#[derive(Clone, Copy)]
pub struct EncodeTables(&'static Tables);

impl EncodeTables {
    pub fn get() -> Self {
        EncodeTables(&TABLES)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The encode in f64 from `powf`, rounded once: the reference [`encode_fast`] approximates.
    fn rounded_once(c: f32) -> f32 {
        (1.055 * f64::from(c).powf(1.0 / 2.4) - 0.055) as f32
    }

    fn ulps(a: f32, b: f32) -> u32 {
        (a.to_bits() as i32 - b.to_bits() as i32).unsigned_abs()
    }

    #[test]
    fn fast_encode_matches_the_reference_on_every_float_of_its_range() {
        // Every f32 in (0.0031308, 1] (a stride of 7 keeps the debug build's test short
        // while visiting every mantissa interval and exponent): within one ulp of the value
        // rounded once, and within four of the f32 formula, which is itself up to three ulps
        // from the value rounded once (measured over all 70.4 M floats of the range).
        let lo = 0.003_130_8f32.to_bits() + 1;
        let hi = 1f32.to_bits();
        let (mut off_by_one, mut n) = (0u64, 0u64);
        for bits in (lo..=hi).step_by(7).chain([lo, hi]) {
            let c = f32::from_bits(bits);
            let fast = encode_fast(c);
            let once = ulps(fast, rounded_once(c));
            assert!(once <= 1, "{c:e}: {fast} against {}", rounded_once(c));
            assert!(
                ulps(fast, encode(c)) <= 4,
                "{c:e}: {fast} against {}",
                encode(c)
            );
            off_by_one += u64::from(once);
            n += 1;
        }
        // A one-ulp difference needs the exact value within ~1e-12 of a rounding boundary
        // (the series' and tables' error): measured over every float of the range, 32 of
        // 70.4 M. 1e-5 of them leaves room for the stride's sample and for the f64 `powf`
        // of the reference being one f64 ulp off on another libm.
        assert!(
            off_by_one * 100_000 <= n,
            "{off_by_one} of {n} off by one ulp"
        );
    }

    #[test]
    fn unit_encode_is_the_fast_encode_on_every_float_in_0_1() {
        for bits in (0..=1f32.to_bits()).step_by(5).chain([0, 1f32.to_bits()]) {
            let c = f32::from_bits(bits);
            assert_eq!(encode_unit(c).to_bits(), encode_fast(c).to_bits(), "{c:e}");
        }
        assert_eq!(encode_unit(-0.0).to_bits(), encode(-0.0).to_bits());
    }

    #[test]
    fn fast_encode_outside_the_powf_range_is_the_reference() {
        for c in [
            -1.0,
            0.0,
            1e-30,
            0.003_130_8,
            1.000_000_1,
            2.0,
            f32::INFINITY,
        ] {
            assert_eq!(encode_fast(c).to_bits(), encode(c).to_bits(), "{c}");
        }
        assert!(encode_fast(f32::NAN).is_nan());
        assert_eq!(encode_fast(1.0), 1.0);
    }

    /// The four-lane encode is [`encode_unit`] lane by lane, to the bit: every 3rd float of
    /// [0, 1] (each lane given a different one, so the gathers' indices differ across lanes),
    /// and values a shaded colour can hold after its clamp or not at all (−0.0, NaN, beyond 1,
    /// negative, subnormal, infinite), since the AVX2 shading passes any lane through it.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn four_lane_encode_is_the_unit_encode_lane_by_lane() {
        use std::arch::x86_64::*;
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("skipped: no AVX2 on this CPU");
            return;
        }
        let tables = EncodeTables::get();
        let check = |v: [f32; 4]| {
            let mut out = [0.0f32; 4];
            // SAFETY: AVX2 is present (checked above); the loads and store are of [f32; 4].
            unsafe {
                let r = encode_unit4_avx2(_mm_loadu_ps(v.as_ptr()), &tables);
                _mm_storeu_ps(out.as_mut_ptr(), r);
            }
            for (x, y) in v.iter().zip(out) {
                assert_eq!(y.to_bits(), encode_unit(*x).to_bits(), "{x:e}");
            }
        };
        let hi = 1f32.to_bits();
        let quarter = hi / 4;
        for b in (0..=quarter).step_by(3) {
            check([b, b + quarter, b + 2 * quarter, hi - b].map(f32::from_bits));
        }
        let special = [
            -0.0,
            f32::NAN,
            -f32::NAN,
            1.000_000_1,
            3.5,
            -0.25,
            f32::MIN_POSITIVE / 8.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.003_130_8,
            0.003_130_801,
            1.0,
        ];
        for w in special.chunks(4) {
            check([w[0], w[1], w[2], w[3]]);
        }
    }

    #[test]
    fn decode_inverts_encode() {
        for i in 0..=1000 {
            let x = i as f32 / 1000.0;
            // 4 f32 ulps at 1: two powf and the divisions between them.
            assert!((decode(encode(x)) - x).abs() <= 5e-7, "{x}");
        }
    }
}
