//! A tiny deterministic generator for the unit tests (PCG's 64-bit LCG step, the top 24 bits
//! as a fraction), so the tests need no dependency and draw the same numbers on every run.

/// Uniform draws in [0, 1) from `seed`.
pub(crate) fn unit(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 40) as f64 / (1u64 << 24) as f64
    }
}
