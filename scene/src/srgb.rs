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

    #[test]
    fn decode_inverts_encode() {
        for i in 0..=1000 {
            let x = i as f32 / 1000.0;
            // 4 f32 ulps at 1: two powf and the divisions between them.
            assert!((decode(encode(x)) - x).abs() <= 5e-7, "{x}");
        }
    }
}
