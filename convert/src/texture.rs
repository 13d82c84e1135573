//! The shared radial falloff texture of the `texture` profile.
//!
//! One RGBA8 PNG for the whole file: RGB white, alpha `exp(−r²/2)` with `r` in σ units,
//! `r = R·|2·uv − 1|` and `R = sqrt(2·ln 255)` (the 1/255 radius of a fully opaque Gaussian);
//! zero outside that disc. Clients must multiply texture alpha by vertex alpha (the vertex
//! alpha carries the opacity): glTF's `baseColorTexture × COLOR_0` does exactly that.
//! The sampler is LINEAR/CLAMP_TO_EDGE without mipmaps; the outermost texels are zero, so
//! coordinates beyond [0, 1] read zero.

use crate::profile::texture_radius;

/// Texture edge length in texels. 256 resolves the profile to ≤ 1/255 between texels
/// (the steepest slope of exp(−r²/2) is 0.61 per σ; one texel spans 2·3.33/256 = 0.026σ,
/// so bilinear error ≤ 0.61·0.026²·… is far below the 8-bit step).
pub const SIZE: u32 = 256;

/// The texture's alpha at texture coordinate (u, v) before quantisation.
pub fn falloff(u: f64, v: f64) -> f64 {
    let r_edge = texture_radius() as f64;
    let (x, y) = ((2.0 * u - 1.0) * r_edge, (2.0 * v - 1.0) * r_edge);
    let r2 = x * x + y * y;
    if r2 > r_edge * r_edge {
        0.0
    } else {
        (-0.5 * r2).exp()
    }
}

/// RGBA8 texels, row-major.
pub fn texels() -> Vec<u8> {
    let mut px = Vec::with_capacity((SIZE * SIZE * 4) as usize);
    for j in 0..SIZE {
        for i in 0..SIZE {
            let u = (i as f64 + 0.5) / SIZE as f64;
            let v = (j as f64 + 0.5) / SIZE as f64;
            let a = (falloff(u, v) * 255.0).round().clamp(0.0, 255.0) as u8;
            px.extend_from_slice(&[255, 255, 255, a]);
        }
    }
    px
}

/// The PNG-encoded texture.
pub fn png() -> Vec<u8> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&texels(), SIZE, SIZE, image::ExtendedColorType::Rgba8)
        .expect("encoding a PNG into memory cannot fail");
    out
}
