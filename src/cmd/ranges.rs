//! Value parsers that check an option's range while the command line is parsed, before any
//! file is read or written or anything is allocated from the value, so a bad value is
//! `error: invalid value 'V' for '--option <…>': …` with exit status 2. The ranges are the
//! libraries' own (each cites where its bound is defined).

/// `--k`: the k-buffer size, 1..=4096 (`splatbridge_raytrace::RenderOptions::validate`).
pub fn k_buffer(s: &str) -> Result<usize, String> {
    in_range(s, 1, 4096)
}

/// `--segments` of a meshing profile, 3..=64 (`splatbridge_convert::ConvertOptions`).
pub fn segments(s: &str) -> Result<usize, String> {
    in_range(s, 3, 64)
}

/// `--rings` of the `rings` profile, 1..=16 (`splatbridge_convert::ConvertOptions`).
pub fn rings(s: &str) -> Result<usize, String> {
    in_range(s, 1, 16)
}

/// `--surfel-segments`, 3..=64 (`splatbridge_convert::surfels`).
pub fn surfel_segments(s: &str) -> Result<usize, String> {
    in_range(s, 3, 64)
}

/// `--time`: a finite scene time within ±`MAX_TIME_SECONDS`
/// (`splatbridge_scene::manifest`), the range every scene time is held to.
pub fn time(s: &str) -> Result<f64, String> {
    use splatbridge_scene::manifest::MAX_TIME_SECONDS;
    let t: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number"))?;
    if !(t.abs() <= MAX_TIME_SECONDS) {
        return Err(format!(
            "a time must be finite and within ±{MAX_TIME_SECONDS} s"
        ));
    }
    Ok(t)
}

/// `--spp`: samples per pixel, 1..=`MAX_SPP` (`splatbridge_raytrace::render::MAX_SPP`).
pub fn spp(s: &str) -> Result<u32, String> {
    in_range(s, 1, splatbridge_raytrace::render::MAX_SPP as usize).map(|v| v as u32)
}

fn in_range(s: &str, lo: usize, hi: usize) -> Result<usize, String> {
    let v: usize = s
        .trim()
        .parse()
        .map_err(|_| format!("expected a whole number in {lo}..={hi}"))?;
    if !(lo..=hi).contains(&v) {
        return Err(format!("{v} is outside {lo}..={hi}"));
    }
    Ok(v)
}

/// `--alpha-clamp`: 0.99 (reference) or 0.999 (gsplat).
pub fn alpha_clamp(s: &str) -> Result<f32, String> {
    match s.trim() {
        "0.99" => Ok(0.99),
        "0.999" => Ok(0.999),
        _ => Err(format!(
            "'{s}': alpha clamp is 0.99 (reference) or 0.999 (gsplat)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alpha_clamp_accepts_only_the_named_values() {
        assert_eq!(alpha_clamp("0.99"), Ok(0.99));
        assert_eq!(alpha_clamp("0.999"), Ok(0.999));
        assert!(alpha_clamp("0.9").is_err());
        assert!(alpha_clamp("1").is_err());
    }

    #[test]
    fn ranges_accept_their_bounds_and_refuse_beyond() {
        assert_eq!(k_buffer("1"), Ok(1));
        assert_eq!(k_buffer("4096"), Ok(4096));
        assert!(k_buffer("0").is_err());
        assert!(k_buffer("4097").is_err());
        assert!(segments("2").is_err());
        assert_eq!(segments("64"), Ok(64));
        assert!(segments("100000000").is_err());
        assert!(rings("0").is_err());
        assert!(time("nan").is_err());
        assert!(time("inf").is_err());
        assert!(time("1e300").is_err());
        assert_eq!(time("-2.5"), Ok(-2.5));
    }
}
