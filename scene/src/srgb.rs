//! The sRGB transfer function (IEC 61966-2-1, as glTF and every viewer apply it): the
//! reference encode and decode through `powf`, and a table-and-series encode for hot loops
//! (mesh distillation shades every recorded hit of every view in every step).
//!
//! [`encode_fast`] computes `1.055·x^(1/2.4) − 0.055` in f64 from the exponent of `x` (a
//! 10-entry table of `2^(5e/12)`), the top five bits of its mantissa (a 32-entry table of
//! `m₀^(5/12)` at each interval's centre) and the binomial series of `(1 + t)^(5/12)` to its
//! fifth power (`|t| ≤ 1/64`, so the first term left out is below 4e-13 of the value), and
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
const K4: f64 = K3 * (A - 3.0) / 4.0;
const K5: f64 = K4 * (A - 4.0) / 5.0;

/// `2^(5e/12)` for the exponents e = −9…0 of (0.0031308, 1].
const POW2: [f64; 10] = [
    0.07432544468767006,
    0.09921256574801246,
    0.13243288679491189,
    0.1767766952966369,
    0.23596857817042335,
    0.3149802624737183,
    0.42044820762685725,
    0.5612310241546865,
    0.7491535384383408,
    1.0,
];
/// `m₀^(5/12)` and `1/m₀` at the centres `m₀ = 1 + (i + ½)/32` of the mantissa's intervals.
const POW_M0: [f64; 32] = [
    1.0064809890307198,
    1.0192706338676127,
    1.031839459215272,
    1.0441975169368105,
    1.0563541331336523,
    1.068317978861026,
    1.0800971322629307,
    1.091699133362278,
    1.10313103253733,
    1.1143994335490568,
    1.1255105318477538,
    1.1364701487751478,
    1.1472837621855314,
    1.157956533932488,
    1.1684933346035296,
    1.1788987658311623,
    1.1891771804636182,
    1.1993327008402617,
    1.209369235384271,
    1.2192904936976316,
    1.229100000319943,
    1.2388011072924026,
    1.2483970056510154,
    1.2578907359581755,
    1.2672851979688762,
    1.2765831595166506,
    1.2857872646946402,
    1.2949000413987521,
    1.303923908292482,
    1.3128611812465345,
    1.3217140793007052,
    1.3304847301905132,
];
const INV_M0: [f64; 32] = [
    0.9846153846153847,
    0.9552238805970149,
    0.927536231884058,
    0.9014084507042254,
    0.8767123287671232,
    0.8533333333333334,
    0.8311688311688312,
    0.810126582278481,
    0.7901234567901234,
    0.7710843373493976,
    0.7529411764705882,
    0.735632183908046,
    0.7191011235955056,
    0.7032967032967034,
    0.6881720430107527,
    0.6736842105263158,
    0.6597938144329897,
    0.6464646464646465,
    0.6336633663366337,
    0.6213592233009708,
    0.6095238095238096,
    0.5981308411214953,
    0.5871559633027523,
    0.5765765765765766,
    0.5663716814159292,
    0.5565217391304348,
    0.5470085470085471,
    0.5378151260504201,
    0.5289256198347108,
    0.5203252032520326,
    0.512,
    0.5039370078740157,
];

/// [`encode`] without `powf` on (0.0031308, 1] (the module documentation says how); other
/// values (the linear toe, anything above 1, NaN) as [`encode`].
#[inline]
pub fn encode_fast(c: f32) -> f32 {
    if !(c > 0.003_130_8 && c <= 1.0) {
        return encode(c);
    }
    let bits = c.to_bits();
    // c is normal here: its biased exponent is 118…127 (e = −9…0).
    let e = (bits >> 23) as usize - 118;
    let i = ((bits >> 18) & 31) as usize;
    let m = f64::from(f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000));
    let t = m * INV_M0[i] - 1.0;
    let series = 1.0 + t * (A + t * (K2 + t * (K3 + t * (K4 + t * K5))));
    (1.055 * (POW2[e] * POW_M0[i] * series) - 0.055) as f32
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
    fn tables_are_their_formulas() {
        // Two f64 ulps: the tables were printed from another libm's pow.
        for (k, &p) in POW2.iter().enumerate() {
            let want = 2f64.powf(A * (k as f64 - 9.0));
            assert!((p - want).abs() <= 2.0 * f64::EPSILON * want, "POW2[{k}]");
        }
        for i in 0..32 {
            let m0 = 1.0 + (i as f64 + 0.5) / 32.0;
            assert!(
                (POW_M0[i] - m0.powf(A)).abs() <= 2.0 * f64::EPSILON * m0,
                "POW_M0[{i}]"
            );
            assert!((INV_M0[i] - 1.0 / m0).abs() <= f64::EPSILON, "INV_M0[{i}]");
        }
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
        // (the series' and tables' error): measured over every float of the range, 8 of
        // 70.4 M. 1e-5 of them leaves room for the stride's sample and for the f64 `powf`
        // of the reference being one f64 ulp off on another libm.
        assert!(
            off_by_one * 100_000 <= n,
            "{off_by_one} of {n} off by one ulp"
        );
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

    #[test]
    fn decode_inverts_encode() {
        for i in 0..=1000 {
            let x = i as f32 / 1000.0;
            // 4 f32 ulps at 1: two powf and the divisions between them.
            assert!((decode(encode(x)) - x).abs() <= 5e-7, "{x}");
        }
    }
}
