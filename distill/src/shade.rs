//! A recorded hit shaded as the mesh tracer shades it (`raytrace::model::Mesh::shade` and the
//! compositor's display encode), with the slopes the backward pass needs: the interpolated
//! linear colour clamped to [0, 1] and sRGB-encoded per channel (`scene::srgb::encode_unit`),
//! and α from the interpolated vertex alpha times the hit's material and texture factor.
//!
//! The three channels' clamp, encode and slope are the forward pass's hottest work (every hit
//! of 16 views a step: about 29 M on `fourth_st`, two thirds of the pass in the encode's
//! series). [`Lanes::Avx2`] does them in four lanes at once, the encode's series in four f64
//! lanes (`scene::srgb::encode_unit4_avx2`); every lane performs the scalar code's IEEE
//! operations in its order, so both give the same bits (tested against each other on values
//! at and beyond the clamps, NaN included).

use glam::Vec3;
use splatbridge_scene::srgb;

use crate::composite::Rec;

/// How the hit colours are encoded for blending.
#[derive(Clone, Copy, Debug)]
pub struct Shading {
    /// Vertex colours are linear and each hit is sRGB-encoded before blending.
    pub encode: bool,
    pub background: Vec3,
}

/// One shaded hit: display colour, its slope per channel (∂c/∂x, 0 where clamped), α, and
/// the unclamped α's slope `∂α/∂(Σ b·A)` (0 where clamped).
#[derive(Clone, Copy, Debug, Default)]
pub struct Shaded {
    pub(crate) c: Vec3,
    pub(crate) dc: Vec3,
    pub(crate) a: f32,
    pub(crate) da: f32,
}

/// Which code shades a pass's hits: the scalar code, or the same operations four lanes at a
/// time where the CPU has AVX2 (the tables taken once for the pass).
#[derive(Clone, Copy)]
pub(crate) enum Lanes {
    Scalar,
    #[cfg(target_arch = "x86_64")]
    Avx2(srgb::EncodeTables),
}

impl Lanes {
    /// AVX2 where the CPU has it, else scalar.
    pub(crate) fn best() -> Self {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            return Lanes::Avx2(srgb::EncodeTables::get());
        }
        Lanes::Scalar
    }
}

/// Shade one hit whose triangle's vertices are `verts` (scalar).
#[inline(always)]
pub(crate) fn shade(h: &Rec, verts: [u32; 3], params: &[[f32; 4]], s: &Shading) -> Shaded {
    shade_with(h, verts, params, s, channels)
}

/// [`shade`] with the channels' clamp, encode and slope done by `channels` (one of the two
/// builds of the same operations).
#[inline(always)]
pub(crate) fn shade_with(
    h: &Rec,
    verts: [u32; 3],
    params: &[[f32; 4]],
    s: &Shading,
    channels: impl Fn([f32; 4], bool) -> ([f32; 4], [f32; 4]),
) -> Shaded {
    let mut x = [0.0f32; 4];
    for (&v, &b) in verts.iter().zip(&h.bary) {
        for (xc, pc) in x.iter_mut().zip(&params[v as usize]) {
            *xc += b * pc;
        }
    }
    let (c, dc) = channels(x, s.encode);
    let a = h.fa * x[3];
    Shaded {
        c: Vec3::new(c[0], c[1], c[2]),
        dc: Vec3::new(dc[0], dc[1], dc[2]),
        a: a.clamp(0.0, 1.0),
        da: if (0.0..=1.0).contains(&a) { h.fa } else { 0.0 },
    }
}

/// The display colour and its slope of the first three lanes of `x` (the fourth is unused):
/// clamped to [0, 1], encoded when `encode`, the slope 0 where clamped.
#[inline(always)]
pub(crate) fn channels(x: [f32; 4], encode: bool) -> ([f32; 4], [f32; 4]) {
    let mut c = [0.0f32; 4];
    let mut dc = [0.0f32; 4];
    for ((&v, cc), dd) in x[..3].iter().zip(c.iter_mut()).zip(dc.iter_mut()) {
        let inside = (0.0..=1.0).contains(&v);
        let v = v.clamp(0.0, 1.0);
        // Each branch's value is computed and one selected: colours near black and at the
        // clamps would mispredict branches in this loop over every hit of every view.
        let (enc, slope) = if encode {
            // Within one ulp of the encode rounded once (`scene::srgb` tests it on every
            // float), at a fraction of `powf`'s cost. The slope from the encoded value: above
            // the linear toe, d/dx (1.055·x^(1/2.4) − 0.055) = (c + 0.055) / (2.4·x), without
            // a second powf.
            let enc = srgb::encode_unit(v);
            let power = (enc + 0.055) / (2.4 * v);
            (enc, if v <= 0.003_130_8 { 12.92 } else { power })
        } else {
            (v, 1.0)
        };
        *cc = enc;
        *dd = if inside { slope } else { 0.0 };
    }
    (c, dc)
}

/// [`channels`] in four lanes (the fourth computed and unused), compiled for AVX2: the same
/// comparisons, the clamp as `f32::clamp` takes it (a NaN and −0.0 pass through), the encode
/// of `scene::srgb::encode_unit4_avx2` and the slope's division in one instruction for the
/// three channels.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) unsafe fn channels_avx2(
    x: [f32; 4],
    encode: bool,
    tables: &srgb::EncodeTables,
) -> ([f32; 4], [f32; 4]) {
    use std::arch::x86_64::*;
    // SAFETY: loads and stores of [f32; 4] values on the stack.
    let x = unsafe { _mm_loadu_ps(x.as_ptr()) };
    let (zero, one) = (_mm_setzero_ps(), _mm_set1_ps(1.0));
    let inside = _mm_and_ps(_mm_cmple_ps(zero, x), _mm_cmple_ps(x, one));
    // `f32::clamp`: below the minimum takes it, then above the maximum takes that.
    let v = _mm_blendv_ps(x, zero, _mm_cmplt_ps(x, zero));
    let v = _mm_blendv_ps(v, one, _mm_cmpgt_ps(v, one));
    let (enc, slope) = if encode {
        // SAFETY: AVX2 is present (this function's contract).
        let enc = unsafe { srgb::encode_unit4_avx2(v, tables) };
        let power = _mm_div_ps(
            _mm_add_ps(enc, _mm_set1_ps(0.055)),
            _mm_mul_ps(_mm_set1_ps(2.4), v),
        );
        let toe = _mm_cmple_ps(v, _mm_set1_ps(0.003_130_8));
        (enc, _mm_blendv_ps(power, _mm_set1_ps(12.92), toe))
    } else {
        (v, one)
    };
    let dc = _mm_and_ps(inside, slope);
    let (mut c_out, mut dc_out) = ([0.0f32; 4], [0.0f32; 4]);
    // SAFETY: as above.
    unsafe {
        _mm_storeu_ps(c_out.as_mut_ptr(), enc);
        _mm_storeu_ps(dc_out.as_mut_ptr(), dc);
    }
    (c_out, dc_out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The AVX2 channels are the scalar ones to the bit on values inside, at and beyond the
    /// clamps, at the encode's toe, and on NaN, ±∞ and −0.0, with and without the encode.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_channels_are_the_scalar_channels() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            eprintln!("skipped: no AVX2 on this CPU");
            return;
        }
        let t = srgb::EncodeTables::get();
        let mut values = vec![
            -0.0,
            0.0,
            1.0,
            -1e-9,
            1.000_000_1,
            0.003_130_8,
            0.003_130_799,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e-42,
            7.5,
        ];
        let mut state = 9u64;
        values.extend((0..20_000).map(|_| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 40) as f32 / (1u64 << 24) as f32) * 1.4 - 0.2
        }));
        let mut checked = 0;
        for w in values.windows(4) {
            let x = [w[0], w[1], w[2], w[3]];
            for encode in [true, false] {
                let (c, dc) = channels(x, encode);
                // SAFETY: AVX2 is present (checked above).
                let (c2, dc2) = unsafe { channels_avx2(x, encode, &t) };
                for k in 0..3 {
                    assert_eq!(c[k].to_bits(), c2[k].to_bits(), "{x:?} {encode} c{k}");
                    assert_eq!(dc[k].to_bits(), dc2[k].to_bits(), "{x:?} {encode} dc{k}");
                    checked += 1;
                }
            }
        }
        assert!(checked > 100_000);
    }
}
