//! Numbers as text for the OBJ writer, exactly as Rust's `Display` prints them, from faster
//! algorithms.
//!
//! `Display` for `f32` prints the shortest digits that read back as the same float, the ones
//! nearest the value among those, without an exponent (`0.000001`, `100000000000000000000`,
//! `-0`, `1`). `zmij` (a Schubfach/yy port) finds the shortest nearest digits too but lays
//! them out its own way (`1.0`, `1e-7`); [`push_f32`] re-lays them in `Display`'s form. The
//! two differ only where a choice is a tie: two shortest candidates equally near (std rounds
//! the half up, zmij to even: `2⁻¹²` is `0.00024414063` in std, `…062` in zmij), or an end of
//! the rounding interval that is itself a short decimal. Both need the value or an interval
//! end to be a decimal of at most ten significant digits ([`may_tie`], a few integer
//! operations), which is rare in a mesh's coordinates and colours; those go through
//! `format!`. So files are byte for byte what `format!("{x}")` wrote, at a fraction of the
//! time: std's Grisu and the `fmt` machinery around it were half the time of writing a
//! `rings` OBJ of a real capture (`docs/meshes.md`, "OBJ text, written and read").

/// Append `x` as `format!("{x}")` prints it.
#[inline]
pub fn push_f32(out: &mut Vec<u8>, x: f32) {
    if !x.is_finite() {
        // Display's own words for these.
        out.extend_from_slice(if x.is_nan() {
            b"NaN"
        } else if x > 0.0 {
            b"inf"
        } else {
            b"-inf"
        });
        return;
    }
    if may_tie(x) {
        out.extend_from_slice(format!("{x}").as_bytes());
        return;
    }
    let mut buf = zmij::Buffer::new();
    let s = buf.format_finite(x).as_bytes();
    if !s.contains(&b'e') {
        // zmij's fixed layout (decimal exponents −6 to 12 for `f32`) is Display's, but for
        // the `.0` it gives whole numbers.
        out.extend_from_slice(s.strip_suffix(b".0").unwrap_or(s));
        return;
    }
    let (neg, s) = match s.split_first() {
        Some((b'-', rest)) => (true, rest),
        _ => (false, s),
    };
    // The exponential layout: mantissa, `e`, exponent (found above).
    let i = s.iter().position(|&c| c == b'e').unwrap_or(s.len());
    let (mant, exp) = (&s[..i], s.get(i + 1..).and_then(parse_exp));
    // The significant digits and where the point falls among them (digits before it).
    let mut digits = [0u8; 64];
    let mut n = 0usize;
    let mut point = None;
    let mut regular = exp.is_some();
    for &c in mant {
        match c {
            b'.' if point.is_none() => point = Some(n),
            b'0'..=b'9' if n < digits.len() => {
                digits[n] = c;
                n += 1;
            }
            _ => regular = false,
        }
    }
    if !regular {
        // Not a layout this function knows: the slow path says what Display says.
        out.extend_from_slice(format!("{x}").as_bytes());
        return;
    }
    let mut p = point.unwrap_or(n) as i64 + exp.unwrap_or(0);
    let mut start = 0;
    while start < n && digits[start] == b'0' {
        start += 1;
        p -= 1;
    }
    let mut end = n;
    while end > start && digits[end - 1] == b'0' {
        end -= 1;
    }
    if neg {
        out.push(b'-');
    }
    let d = &digits[start..end];
    if d.is_empty() {
        out.push(b'0');
        return;
    }
    let len = d.len() as i64;
    let zeros = |out: &mut Vec<u8>, k: i64| out.extend(std::iter::repeat_n(b'0', k as usize));
    if p <= 0 {
        out.extend_from_slice(b"0.");
        zeros(out, -p);
        out.extend_from_slice(d);
    } else if p >= len {
        out.extend_from_slice(d);
        zeros(out, p - len);
    } else {
        let p = p as usize;
        out.extend_from_slice(&d[..p]);
        out.push(b'.');
        out.extend_from_slice(&d[p..]);
    }
}

/// Whether `x` (finite) or an end of its rounding interval (half an ulp either side, a
/// quarter below a power of two) is a decimal of at most ten significant digits: only then
/// can two shortest candidates be equally near, or an interval end be a candidate, where
/// std's and zmij's rules may choose differently. Shortest digits are at most nine for
/// `f32`, and a tie's midpoint has one digit more.
fn may_tie(x: f32) -> bool {
    let bits = x.to_bits() & 0x7fff_ffff;
    if bits == 0 {
        return true;
    }
    let (exp, frac) = (bits >> 23, (bits & 0x7f_ffff) as u128);
    let (m, e) = if exp == 0 {
        (frac, -149)
    } else {
        (frac | 1 << 23, exp as i32 - 150)
    };
    short(m, e) || short(2 * m + 1, e - 1) || short(2 * m - 1, e - 1) || short(4 * m - 1, e - 2)
}

/// Whether `n·2^k` (n > 0) has at most ten significant decimal digits; true also where the
/// value is too large to check in `u128` (the slow path is always right).
fn short(mut n: u128, mut k: i32) -> bool {
    while n.is_multiple_of(2) && k < 0 {
        n /= 2;
        k += 1;
    }
    let mut v = if k < 0 {
        // n odd: n·5^|k| ends in 5 (no trailing zeros) and has more than ten digits once
        // 5^|k| alone does.
        if k < -14 {
            return false;
        }
        n * 5u128.pow((-k) as u32)
    } else {
        match n.checked_shl(k as u32).filter(|v| v >> k == n) {
            Some(v) => v,
            None => return true,
        }
    };
    while v.is_multiple_of(10) {
        v /= 10;
    }
    v < 10_000_000_000
}

/// The exponent after an `e`: an optional sign and at most four digits.
fn parse_exp(s: &[u8]) -> Option<i64> {
    let (sign, digits) = match s.split_first() {
        Some((b'-', r)) => (-1, r),
        Some((b'+', r)) => (1, r),
        _ => (1, s),
    };
    if digits.is_empty() || digits.len() > 4 || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    Some(sign * digits.iter().fold(0i64, |v, &c| v * 10 + (c - b'0') as i64))
}

/// Append `v` as `format!("{v}")` prints it.
#[inline]
pub fn push_u64(out: &mut Vec<u8>, v: u64) {
    out.extend_from_slice(itoa::Buffer::new().format(v).as_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(x: f32) {
        let mut got = Vec::new();
        push_f32(&mut got, x);
        let want = format!("{x}");
        assert_eq!(
            std::str::from_utf8(&got).unwrap(),
            want,
            "bits {:#010x}",
            x.to_bits()
        );
    }

    /// Display is the reference: every special value, the ends of each range, every power
    /// of ten and two (the ties and short interval ends of `may_tie`), two million random bit
    /// patterns (normal and subnormal, both signs) and every 4099th bit pattern.
    #[test]
    fn f32_text_is_displays() {
        for x in [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            0.1,
            0.5,
            1.5,
            123456.79,
            f32::MIN_POSITIVE,
            f32::MAX,
            f32::MIN,
            f32::EPSILON,
            f32::from_bits(1),
            f32::from_bits(0x007f_ffff),
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ] {
            check(x);
        }
        for e in -45..=38 {
            let p = 10f32.powi(e);
            for x in [
                p,
                -p,
                p * 1.5,
                p * 9.999_999,
                f32::from_bits(p.to_bits() + 1),
            ] {
                check(x);
            }
        }
        for e in -149..=127 {
            check(2f32.powi(e));
        }
        let mut draw = splatbridge_scene::rng::Rng::new(0x0b1);
        for _ in 0..2_000_000 {
            check(f32::from_bits(draw.next_u64() as u32));
        }
        for b in (0..=u32::MAX).step_by(4099) {
            check(f32::from_bits(b));
        }
        // Short decimals with a tie: the slow path is what keeps them equal.
        for x in [0.000_244_140_63f32, 0.040_039_063, 0.5, 0.125, 1024.5] {
            assert!(may_tie(x), "{x}");
            check(x);
        }
        // A full 24-bit mantissa at a small exponent cannot tie.
        assert!(!may_tie(0.1) && !may_tie(0.7) && !may_tie(-123.456));
    }

    #[test]
    fn integers_are_displays() {
        let mut out = Vec::new();
        for v in [0u64, 1, 9, 10, 99, 100, 4_294_967_295, u64::MAX] {
            out.clear();
            push_u64(&mut out, v);
            assert_eq!(out, v.to_string().as_bytes());
        }
    }
}
