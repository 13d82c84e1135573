//! Decoded glTF textures and their sampling as a viewer's texture unit does it: texel centres
//! at `(i + ½)/size`, bilinear (or nearest, for a NEAREST sampler) filtering, and the
//! sampler's wrap mode per axis (glTF 2.0 §5.26: REPEAT, CLAMP_TO_EDGE, MIRRORED_REPEAT).

use glam::{Vec2, Vec3, Vec4};

use crate::geom::floor;
use crate::model::srgb_to_linear;

/// Texture coordinate wrap mode (glTF sampler).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    Clamp,
    Mirror,
}

/// A decoded texture: RGB decoded from sRGB to linear (glTF base-colour textures are sRGB
/// encoded), alpha linear as stored; row 0 is the top of the image (UV v = 0).
#[derive(Clone, Debug)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    texels: Texels,
    pub wrap: [Wrap; 2],
    /// Nearest-neighbour magnification/minification (sampler filter NEAREST); bilinear otherwise.
    pub nearest: bool,
    /// Per texel `(x, y)`, row-major: every texel of the 4×4 block `x − 1 ..= x + 2`,
    /// `y − 1 ..= y + 2` lies inside the image and has alpha exactly 0 (see
    /// [`Texture::alpha_zero_near`]).
    alpha_zero: Vec<bool>,
}

/// How texels are kept: an 8-bit image as its bytes (a quarter of the memory, so a sample's
/// four texels come from cache: the falloff texture of every texture export is 256 KB instead
/// of 1 MB), decoded on read through tables of the very conversion a float texel gets, so both
/// give the same numbers.
#[derive(Clone, Debug)]
enum Texels {
    Float(Vec<Vec4>),
    Byte(Vec<[u8; 4]>, &'static ByteDecode),
    /// An 8-bit image whose RGB bytes are the same in every texel (the falloff texture of
    /// every texture export is white): its alphas, and the one colour decoded. A texel reads
    /// one byte and one table entry instead of four of each, and the image is a quarter the
    /// size again; the values are the [`Texels::Byte`] ones.
    Alpha(Vec<u8>, Vec3, &'static ByteDecode),
}

/// The one decode table every byte texture reads.
static BYTE_DECODE: std::sync::LazyLock<ByteDecode> = std::sync::LazyLock::new(ByteDecode::new);

/// The decoded value of each byte: RGB through the sRGB decode, alpha as stored.
#[derive(Clone, Debug)]
struct ByteDecode {
    rgb: [f32; 256],
    alpha: [f32; 256],
}

impl ByteDecode {
    fn new() -> Self {
        let unorm = |i: usize| i as f32 / 255.0;
        ByteDecode {
            rgb: std::array::from_fn(|i| srgb_to_linear(unorm(i))),
            alpha: std::array::from_fn(unorm),
        }
    }

    #[inline(always)]
    fn get(&self, b: [u8; 4]) -> Vec4 {
        Vec4::new(
            self.rgb[b[0] as usize],
            self.rgb[b[1] as usize],
            self.rgb[b[2] as usize],
            self.alpha[b[3] as usize],
        )
    }
}

impl Texture {
    /// A texture of decoded texels, row-major.
    pub fn from_texels(
        width: u32,
        height: u32,
        texels: Vec<Vec4>,
        wrap: [Wrap; 2],
        nearest: bool,
    ) -> Self {
        Self::of(width, height, Texels::Float(texels), wrap, nearest)
    }

    /// A texture of 8-bit texels as stored (RGB sRGB-encoded, alpha linear), row-major: it
    /// samples as [`Texture::from_texels`] of `srgb_to_linear(byte / 255)` (RGB) and
    /// `byte / 255` (alpha) does, bit for bit.
    pub fn from_bytes(
        width: u32,
        height: u32,
        texels: Vec<[u8; 4]>,
        wrap: [Wrap; 2],
        nearest: bool,
    ) -> Self {
        let d = &*BYTE_DECODE;
        let texels = match texels.first() {
            Some(&[r, g, b, _]) if texels.iter().all(|t| t[..3] == [r, g, b]) => {
                let rgb = Vec3::new(d.rgb[r as usize], d.rgb[g as usize], d.rgb[b as usize]);
                Texels::Alpha(texels.iter().map(|t| t[3]).collect(), rgb, d)
            }
            _ => Texels::Byte(texels, d),
        };
        Self::of(width, height, texels, wrap, nearest)
    }

    fn of(width: u32, height: u32, texels: Texels, wrap: [Wrap; 2], nearest: bool) -> Self {
        let mut t = Texture {
            width,
            height,
            texels,
            wrap,
            nearest,
            alpha_zero: Vec::new(),
        };
        t.alpha_zero = t.zero_blocks();
        t
    }

    /// [`Texture::alpha_zero`]'s blocks: whether each texel's alpha is 0, then a sliding
    /// 4-wide "all" along rows and along columns (the block of `(x, y)` starts one texel
    /// before it on each axis).
    fn zero_blocks(&self) -> Vec<bool> {
        let (w, h) = (self.width as usize, self.height as usize);
        if w * h != self.len() || w < 4 || h < 4 {
            return vec![false; self.len()];
        }
        let zero: Vec<bool> = self.texels().map(|t| t.w == 0.0).collect();
        let block = |get: &dyn Fn(usize, usize) -> bool, x: usize, y: usize, n: usize| {
            // Texels x − 1 ..= x + 2 along an axis of n texels.
            x >= 1 && x + 2 < n && (x - 1..=x + 2).all(|i| get(i, y))
        };
        let rows: Vec<bool> = (0..w * h)
            .map(|i| block(&|x, y| zero[y * w + x], i % w, i / w, w))
            .collect();
        (0..w * h)
            .map(|i| block(&|y, x| rows[y * w + x], i / w, i % w, h))
            .collect()
    }

    /// Whether the alpha [`Texture::sample`] gives is exactly 0 at every texture coordinate
    /// less than one texel from `uv` along each axis: the bilinear (or nearest) texels of any
    /// such coordinate lie in the all-zero block around `uv`'s first texel, inside the image
    /// where no wrap mode moves them, and a weighted sum of zeros is zero. Lets a caller that
    /// found α = 0 at `uv` know it for a coordinate computed from the same barycentrics in
    /// another order (`mesh_hit`: a triangle's other winding).
    pub fn alpha_zero_near(&self, uv: Vec2) -> bool {
        if self.alpha_zero.is_empty() || !uv.is_finite() {
            return false;
        }
        let (x, y) = self.texel_coords(uv);
        let (x, y) = (floor(x), floor(y));
        let (w, h) = (self.width as f64, self.height as f64);
        if !(x >= 0.0 && x < w && y >= 0.0 && y < h) {
            return false;
        }
        self.alpha_zero[y as usize * self.width as usize + x as usize]
    }

    /// Number of texels.
    pub fn len(&self) -> usize {
        match &self.texels {
            Texels::Float(t) => t.len(),
            Texels::Byte(t, _) => t.len(),
            Texels::Alpha(t, _, _) => t.len(),
        }
    }

    /// Whether the texture has no texel.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Texel `i` (row-major), decoded.
    #[inline(always)]
    pub fn texel_at(&self, i: usize) -> Vec4 {
        match &self.texels {
            Texels::Float(t) => t[i],
            Texels::Byte(t, d) => d.get(t[i]),
            Texels::Alpha(t, rgb, d) => rgb.extend(d.alpha[t[i] as usize]),
        }
    }

    /// Every texel, decoded, row-major.
    pub fn texels(&self) -> impl Iterator<Item = Vec4> + '_ {
        (0..self.len()).map(|i| self.texel_at(i))
    }

    fn texel(&self, x: i64, y: i64) -> Vec4 {
        let wrap = |i: i64, n: u32, m: Wrap| -> usize {
            let n = n as i64;
            (match m {
                Wrap::Clamp => i.clamp(0, n - 1),
                Wrap::Repeat => i.rem_euclid(n),
                Wrap::Mirror => {
                    let p = i.rem_euclid(2 * n);
                    if p < n {
                        p
                    } else {
                        2 * n - 1 - p
                    }
                }
            }) as usize
        };
        let xi = wrap(x, self.width, self.wrap[0]);
        let yi = wrap(y, self.height, self.wrap[1]);
        self.texel_at(yi * self.width as usize + xi)
    }

    /// Texture coordinate `uv` in texels, texel centres at integers: what [`Texture::sample`]
    /// filters and [`Texture::alpha_zero_near`] looks up, the same numbers for both.
    #[inline(always)]
    fn texel_coords(&self, uv: Vec2) -> (f64, f64) {
        (
            uv.x as f64 * self.width as f64 - 0.5,
            uv.y as f64 * self.height as f64 - 0.5,
        )
    }

    /// Sample at texture coordinate `uv` (texel centres at (i + 0.5)/size).
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        if self.is_empty() || !uv.is_finite() {
            return Vec4::ONE;
        }
        let (x, y) = self.texel_coords(uv);
        if self.nearest {
            return self.texel(x.round() as i64, y.round() as i64);
        }
        let (x0, y0) = (floor(x), floor(y));
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let (w, h) = (self.width as i64, self.height as i64);
        let (a0, a1, b0, b1) = if (0..w - 1).contains(&x0) && (0..h - 1).contains(&y0) {
            // All four texels inside: no wrap mode moves them (the tests check this path
            // against `texel` on every mode).
            let i = (y0 * w + x0) as usize;
            let row = w as usize;
            (
                self.texel_at(i),
                self.texel_at(i + 1),
                self.texel_at(i + row),
                self.texel_at(i + row + 1),
            )
        } else {
            // Saturating: a coordinate beyond i64's texels (an f32 UV of 1e30) stays at the
            // last one instead of wrapping to the first.
            let (x1, y1) = (x0.saturating_add(1), y0.saturating_add(1));
            (
                self.texel(x0, y0),
                self.texel(x1, y0),
                self.texel(x0, y1),
                self.texel(x1, y1),
            )
        };
        a0.lerp(a1, fx).lerp(b0.lerp(b1, fx), fy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn same_bits(a: Vec4, b: Vec4) -> bool {
        a.to_array()
            .iter()
            .zip(b.to_array())
            .all(|(p, q)| p.to_bits() == q.to_bits())
    }

    /// Bilinear filtering as written in the definition: four texels through `texel` (which
    /// applies the wrap mode to each), weights from `f64::floor`.
    fn sample_reference(t: &Texture, uv: Vec2) -> Vec4 {
        let x = uv.x as f64 * t.width as f64 - 0.5;
        let y = uv.y as f64 * t.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let (x1, y1) = (x0.saturating_add(1), y0.saturating_add(1));
        let a = t.texel(x0, y0).lerp(t.texel(x1, y0), fx);
        let b = t.texel(x0, y1).lerp(t.texel(x1, y1), fx);
        a.lerp(b, fy)
    }

    /// The interior path and the inline floor give the definition's samples bit for bit: on
    /// every wrap mode, at random coordinates inside and outside [0, 1], on texel centres and
    /// edges (integer and half-integer x), at −0 and at huge coordinates, on textures of one
    /// texel row or column too.
    #[test]
    fn sampling_equals_the_definition() {
        let mut draw = crate::test_rng::unit(7);
        let mut next = move || draw() as f32;
        for (w, h) in [(5u32, 4u32), (1, 6), (7, 1), (16, 16)] {
            let texels: Vec<Vec4> = (0..w * h)
                .map(|_| Vec4::new(next(), next(), next(), next()))
                .collect();
            for wrap in [Wrap::Clamp, Wrap::Repeat, Wrap::Mirror] {
                let t = Texture::from_texels(w, h, texels.clone(), [wrap, Wrap::Clamp], false);
                let mut uvs: Vec<Vec2> = (0..2000)
                    .map(|_| Vec2::new(next() * 3.0 - 1.0, next() * 3.0 - 1.0))
                    .collect();
                for i in -3..=(2 * w as i32 + 3) {
                    for j in -3..=(2 * h as i32 + 3) {
                        // Texel centres and edges: x = i/2 + ½ texel.
                        uvs.push(Vec2::new(
                            (i as f32 * 0.5 + 0.5) / w as f32,
                            (j as f32 * 0.5 + 0.5) / h as f32,
                        ));
                    }
                }
                uvs.extend([
                    Vec2::new(-0.0, 0.5),
                    Vec2::new(0.5 / w as f32, -0.0),
                    Vec2::new(1e30, 0.5),
                    Vec2::new(-1e30, 3e20),
                ]);
                for uv in uvs {
                    let (a, b) = (t.sample(uv), sample_reference(&t, uv));
                    assert!(same_bits(a, b), "{w}×{h} {wrap:?} at {uv}: {a} vs {b}");
                }
            }
        }
    }
    /// An 8-bit texture samples as the float texture of the same decode does, bit for bit: every
    /// byte value, every wrap mode, bilinear and nearest, inside and across the edges; also
    /// where every texel has the same colour bytes (kept as alphas and one colour).
    #[test]
    fn byte_texels_sample_as_their_decoded_floats() {
        let (w, h) = (16u32, 16u32);
        // Every byte value appears in every channel (16·16 texels, four channels rotated).
        let rotated: Vec<[u8; 4]> = (0..w * h)
            .map(|i| {
                let b = i as u8;
                [
                    b,
                    b.wrapping_mul(7),
                    b.wrapping_add(91),
                    b.wrapping_mul(13).wrapping_add(5),
                ]
            })
            .collect();
        let one_colour = |rgb: [u8; 3]| -> Vec<[u8; 4]> {
            rotated
                .iter()
                .map(|t| [rgb[0], rgb[1], rgb[2], t[3]])
                .collect()
        };
        for (bytes, alpha_only) in [
            (rotated.clone(), false),
            (one_colour([255, 255, 255]), true),
            (one_colour([17, 200, 3]), true),
        ] {
            let t = Texture::from_bytes(w, h, bytes.clone(), [Wrap::Clamp; 2], false);
            assert_eq!(matches!(t.texels, Texels::Alpha(..)), alpha_only);
            byte_texels_sample_as(&bytes, w, h);
        }
    }

    fn byte_texels_sample_as(bytes: &[[u8; 4]], w: u32, h: u32) {
        let unorm = |b: u8| b as f32 / 255.0;
        let floats: Vec<Vec4> = bytes
            .iter()
            .map(|b| {
                Vec4::new(
                    srgb_to_linear(unorm(b[0])),
                    srgb_to_linear(unorm(b[1])),
                    srgb_to_linear(unorm(b[2])),
                    unorm(b[3]),
                )
            })
            .collect();
        let mut draw = crate::test_rng::unit(3);
        let mut next = move || draw() as f32;
        for wrap in [Wrap::Clamp, Wrap::Repeat, Wrap::Mirror] {
            for nearest in [false, true] {
                let f = Texture::from_texels(w, h, floats.clone(), [wrap, wrap], nearest);
                let b = Texture::from_bytes(w, h, bytes.to_vec(), [wrap, wrap], nearest);
                assert_eq!(b.len(), f.len());
                assert!(b.texels().zip(f.texels()).all(|(p, q)| p == q));
                for _ in 0..3000 {
                    let uv = Vec2::new(next() * 3.0 - 1.0, next() * 3.0 - 1.0);
                    let (p, q) = (b.sample(uv), f.sample(uv));
                    assert!(
                        same_bits(p, q),
                        "{wrap:?} nearest {nearest} at {uv}: {p} vs {q}"
                    );
                }
            }
        }
    }
}
