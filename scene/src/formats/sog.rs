//! PlayCanvas SOG ("spatially ordered Gaussians"): a `meta.json` and lossless WebP images, one
//! pixel per Gaussian in row-major order, either bundled in a `.sog` zip or as files beside
//! the `meta.json`. Both published versions are read (see [`meta`] for what differs); the
//! layout follows PlayCanvas `splat-transform` (`read-sog.ts`, `write-sog.ts`) and the
//! engine's `GSplatSogData`:
//!
//! - `means_l`/`means_u`: low and high bytes of a 16-bit value per axis, a lerp between
//!   `means.mins`/`maxs` of `sign(x)·ln(|x|+1)`; the position is its inverse.
//! - `quats`: smallest-three quaternion: RGB are the three smaller components of the unit
//!   quaternion (w, x, y, z order, largest made positive) times √2 mapped to 0..255, A is
//!   252 + the index of the dropped largest component (other tags decode as identity, as in
//!   the reference).
//! - `scales`: log-scales per axis; `sh0`: the DC coefficients per channel and the opacity.
//! - `shN_labels`: a 16-bit palette index per Gaussian (R low, G high byte);
//!   `shN_centroids`: 64 palette entries per row, each `coeffs` pixels wide, RGB per pixel.
//!
//! Values land in the PLY's frame and conventions (SOG stores PLY space), kept as stored
//! (log-scales, opacity logits) so the cloud matches the reference decoder's columns.
//!
//! Safety against hostile files: `meta.json`'s count bounds every read (entry sizes declared
//! and real, image dimensions before decoding), and a count far beyond what the stored bytes
//! could hold is refused before anything count-sized is allocated.

mod container;
mod meta;

use std::io::Cursor;
use std::path::Path;

use glam::{Quat, Vec3};
use rayon::prelude::*;

use crate::error::{Result, SceneError};
use crate::gaussians::{sh_coeffs, GaussianCloud};
use container::{Container, META_CAP};
use meta::{Dequant, Meta, MAX_SIDE};

/// What a read found, for `info`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SogSummary {
    /// 1 (SOGS, per-channel ranges) or 2 (codebooks).
    pub version: u32,
    /// A `.sog` zip (rather than `meta.json` + files).
    pub bundled: bool,
    pub count: u64,
    pub sh_degree: u8,
}

/// At most this many Gaussians per stored image byte. Each Gaussian owns a pixel in six or
/// seven images that are mostly noise-like (positions, rotations), so real files store
/// several bytes per Gaussian (splat-transform's output measures 8–100); a file claiming
/// 64 per byte is a decompression bomb, refused before count-sized buffers exist.
const MAX_GAUSSIANS_PER_BYTE: u64 = 64;

/// Read a SOG: `path` is a `.sog` zip or an unbundled `meta.json`.
pub fn read_sog(path: &Path) -> Result<GaussianCloud> {
    read_sog_with_summary(path).map(|(c, _)| c)
}

/// [`read_sog`], also saying which version and container it read.
pub fn read_sog_with_summary(path: &Path) -> Result<(GaussianCloud, SogSummary)> {
    let (mut c, _len) = Container::open(path)?;
    let meta_bytes = match &c {
        Container::Zip(_) => c.read(path, "meta.json", META_CAP)?,
        Container::Dir(_) => super::read_file_capped(path, META_CAP)?,
    };
    let m = meta::parse(path, &meta_bytes, c.is_bundled())?;
    let mut names: Vec<&str> = vec![&m.means_files[0], &m.means_files[1], &m.quats_file];
    names.extend([m.scales_file.as_str(), m.sh0_file.as_str()]);
    if let Some(s) = &m.shn {
        names.extend([s.centroids.as_str(), s.labels.as_str()]);
    }
    let mut stored = 0u64;
    for n in &names {
        stored += c.stored_len(path, n)?;
    }
    if m.count > stored.saturating_mul(MAX_GAUSSIANS_PER_BYTE) {
        return Err(SceneError::format(
            path,
            format!(
                "meta.json claims {} Gaussians but the images hold only {stored} bytes \
                 (more than {MAX_GAUSSIANS_PER_BYTE} Gaussians per byte is a decompression bomb)",
                m.count
            ),
        ));
    }
    if m.count < ONE_THREAD_BELOW {
        // A pool of the calling thread alone: the parallel loops below run here, in order.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .use_current_thread()
            .build();
        // Building fails when this thread already works for a pool; then decode as usual.
        if let Ok(pool) = pool {
            return pool.install(|| decode_images(path, c, &m, &names));
        }
    }
    decode_images(path, c, &m, &names)
}

/// Clouds smaller than this decode on the calling thread alone. Their images decode in tens
/// of milliseconds, and each extra decoding thread costs resident memory of its own (its stack
/// and its malloc arena, about 2 MB in all with two threads: 1.73× a 113k-Gaussian SH-0
/// cloud's size at the peak, against 1.07× for what the decoder allocates).
const ONE_THREAD_BELOW: u64 = 1 << 18;

/// Decompress and decode the images `names` of container `c` and assemble the cloud.
fn decode_images(
    path: &Path,
    mut c: Container,
    m: &meta::Meta,
    names: &[&str],
) -> Result<(GaussianCloud, SogSummary)> {
    // One pixel per Gaussian plus a writer's padding (see `check_dims`); a lossless WebP of
    // incompressible RGBA stays under 8 bytes per pixel (4 channels of ≤ 15-bit Huffman
    // codes), plus headers.
    let pixel_cap = m.count + 4 * MAX_SIDE + 16;
    let image_cap = pixel_cap * 8 + (64 << 10);
    let mut raw = Vec::with_capacity(names.len());
    for (k, n) in names.iter().enumerate() {
        // The centroid image is sized by the palette, not the count: ≤ 65536 entries of
        // ≤ 15 pixels.
        let cap = if k == 5 {
            (1u64 << 16) * 15 * 8 + (64 << 10)
        } else {
            image_cap
        };
        raw.push(c.read(path, n, cap)?);
    }
    let bundled = c.is_bundled();
    drop(c);
    // Decode the images in parallel: WebP decoding is most of the time.
    // Each compressed image is dropped as soon as it is decoded.
    let images: Vec<Image> = raw
        .into_par_iter()
        .zip(names.par_iter())
        .enumerate()
        .map(|(k, (bytes, name))| {
            let expect = if k == 5 {
                Expect::Centroids
            } else {
                Expect::Count(m.count)
            };
            decode_webp(path, name, &bytes, expect)
        })
        .collect::<Result<_>>()?;
    let cloud = assemble(path, m, images)?;
    let summary = SogSummary {
        version: m.version,
        bundled,
        count: m.count,
        sh_degree: cloud.sh_degree,
    };
    Ok((cloud, summary))
}

/// A decoded image: `channels` bytes per pixel (3 when the WebP has no alpha; alpha reads
/// as 255 then, as WebP defines).
struct Image {
    width: u32,
    height: u32,
    channels: usize,
    data: Vec<u8>,
}

impl Image {
    fn empty() -> Image {
        Image {
            width: 0,
            height: 0,
            channels: 4,
            data: Vec::new(),
        }
    }

    #[inline]
    fn px(&self, i: usize) -> [u8; 4] {
        let o = i * self.channels;
        let d = &self.data[o..o + self.channels];
        [
            d[0],
            d[1],
            d[2],
            if self.channels == 4 { d[3] } else { 255 },
        ]
    }
}

enum Expect {
    /// One pixel per Gaussian.
    Count(u64),
    /// The SH palette: checked against meta after decoding (its size is small and bounded).
    Centroids,
}

/// Every per-Gaussian image must have at least `count` pixels and at most a writer's
/// padding more: splat-transform rounds the width up to a multiple of 4 and the height up to
/// a multiple of 4 rows (spare < 4·width); square layouts spare less than one row. Anything
/// larger disagrees with meta.json and would let a tiny count allocate a huge image.
fn check_dims(w: u64, h: u64, count: u64) -> bool {
    let px = w * h;
    px >= count && px - count < 4 * w.max(h) + 16
}

fn decode_webp(path: &Path, name: &str, bytes: &[u8], expect: Expect) -> Result<Image> {
    let bad = |what: String| SceneError::format(path, format!("{name}: {what}"));
    let mut dec = image_webp::WebPDecoder::new(Cursor::new(bytes))
        .map_err(|e| bad(format!("not a readable WebP image: {e}")))?;
    if dec.is_animated() {
        return Err(bad("an animated WebP is not a SOG image".into()));
    }
    let (w, h) = dec.dimensions();
    let (w64, h64) = (w as u64, h as u64);
    match expect {
        Expect::Count(count) => {
            if !check_dims(w64, h64, count) {
                return Err(bad(format!(
                    "image is {w}×{h} = {} pixels, which disagrees with meta.json's {count} \
                     Gaussians",
                    w64 * h64
                )));
            }
        }
        Expect::Centroids => {
            // 64 entries × at most 15 coefficients per row, at most 65536 entries.
            if w64 > 64 * 15 || h64 > (1 << 16) / 64 {
                return Err(bad(format!("SH palette image is {w}×{h}, beyond 960×1024")));
            }
        }
    }
    let size = dec
        .output_buffer_size()
        .ok_or_else(|| bad("image size overflows".into()))?;
    let channels = if dec.has_alpha() { 4 } else { 3 };
    let mut data = vec![0u8; size];
    dec.read_image(&mut data)
        .map_err(|e| bad(format!("WebP decoding failed: {e}")))?;
    Ok(Image {
        width: w,
        height: h,
        channels,
        data,
    })
}

/// Inverse of splat-transform's `logTransform(x) = sign(x)·ln(|x| + 1)`.
#[inline]
fn inv_log(v: f64) -> f64 {
    let e = v.abs().exp() - 1.0;
    if v < 0.0 {
        -e
    } else {
        e
    }
}

/// Smallest-three quaternion to (w, x, y, z) as the reference decodes it.
#[inline]
fn unpack_quat(p: [u8; 4]) -> Quat {
    const IDX: [[usize; 3]; 4] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];
    let tag = p[3];
    if !(252..=255).contains(&tag) {
        return Quat::IDENTITY;
    }
    let max = (tag - 252) as usize;
    let s2 = std::f64::consts::SQRT_2;
    let abc = [0, 1, 2].map(|k| (p[k] as f64 / 255.0 * 2.0 - 1.0) / s2);
    let mut q = [0f64; 4];
    for k in 0..3 {
        q[IDX[max][k]] = abc[k];
    }
    q[max] = (1.0 - (abc[0] * abc[0] + abc[1] * abc[1] + abc[2] * abc[2]))
        .max(0.0)
        .sqrt();
    Quat::from_xyzw(q[1] as f32, q[2] as f32, q[3] as f32, q[0] as f32)
}

/// `Range` lerp or `Codebook` lookup for channel `c`.
#[inline]
fn dequant(d: &Dequant, c: usize, b: u8) -> f32 {
    match d {
        Dequant::Range { mins, maxs } => {
            (mins[c] + (maxs[c] - mins[c]) * (b as f64 / 255.0)) as f32
        }
        Dequant::Codebook(cb) => cb[b as usize],
    }
}

/// v2 opacity: the sigmoid in 1/255 steps, clamped as the reference does before the logit.
#[inline]
fn opacity_logit(a: u8) -> f32 {
    let e = (a as f64 / 255.0).clamp(1e-6, 1.0 - 1e-6);
    (e / (1.0 - e)).ln() as f32
}

/// Build the cloud, freeing each image once its attributes are out (peak: the cloud plus the
/// images not yet used).
fn assemble(path: &Path, m: &Meta, mut img: Vec<Image>) -> Result<GaussianCloud> {
    let n = m.count as usize;
    let bad = |what: String| SceneError::format(path, what);
    // SH palette geometry and band count.
    let (degree, palette) = match &m.shn {
        None => (0u8, None),
        Some(s) => {
            let cen = &img[5];
            let degree = match s.bands {
                Some(b) => b,
                // v1: the band count is implied by the palette's width (64 entries per row).
                None => match cen.width {
                    192 => 1,
                    512 => 2,
                    960 => 3,
                    w => {
                        return Err(bad(format!(
                            "{}: SH palette width {w} is not 192, 512 or 960 (64 × 3/8/15)",
                            s.centroids
                        )))
                    }
                },
            };
            let coeffs = sh_coeffs(degree) - 1;
            if cen.width as usize != 64 * coeffs {
                return Err(bad(format!(
                    "{}: SH palette is {} pixels wide, degree {degree} needs {}",
                    s.centroids,
                    cen.width,
                    64 * coeffs
                )));
            }
            let rows_hold = cen.height as usize * 64;
            let entries = s.palette.map_or(rows_hold, |p| p as usize);
            if entries > rows_hold {
                return Err(bad(format!(
                    "{}: meta.json's shN.count {entries} needs {} palette rows, the image has {}",
                    s.centroids,
                    entries.div_ceil(64),
                    cen.height
                )));
            }
            (degree, Some((coeffs, entries)))
        }
    };
    let k = sh_coeffs(degree);
    let mut cloud = GaussianCloud::new(degree);
    let scale3 = |a: usize| {
        let span = m.means_maxs[a] - m.means_mins[a];
        // The reference uses `(max − min) || 1`: an empty range decodes with span 1.
        if span == 0.0 {
            1.0
        } else {
            span
        }
    };
    let spans = [scale3(0), scale3(1), scale3(2)];
    let (lo, hi) = (&img[0], &img[1]);
    cloud.means = (0..n)
        .into_par_iter()
        .map(|i| {
            let (l, h) = (lo.px(i), hi.px(i));
            let v = |a: usize| {
                let q = l[a] as u32 | (h[a] as u32) << 8;
                inv_log(m.means_mins[a] + spans[a] * (q as f64 / 65535.0)) as f32
            };
            Vec3::new(v(0), v(1), v(2))
        })
        .collect();
    img[0] = Image::empty();
    img[1] = Image::empty();
    cloud.rotations = (0..n)
        .into_par_iter()
        .map(|i| unpack_quat(img[2].px(i)))
        .collect();
    img[2] = Image::empty();
    cloud.log_scales = (0..n)
        .into_par_iter()
        .map(|i| {
            let p = img[3].px(i);
            Vec3::new(
                dequant(&m.scales, 0, p[0]),
                dequant(&m.scales, 1, p[1]),
                dequant(&m.scales, 2, p[2]),
            )
        })
        .collect();
    img[3] = Image::empty();
    let sh0 = &img[4];
    cloud.opacity_logits = (0..n)
        .into_par_iter()
        .map(|i| {
            let a = sh0.px(i)[3];
            match m.version {
                1 => dequant(&m.sh0, 3, a),
                _ => opacity_logit(a),
            }
        })
        .collect();
    let mut sh = vec![Vec3::ZERO; n * k];
    sh.par_chunks_mut(k)
        .enumerate()
        .try_for_each(|(i, out)| -> Result<()> {
            let p = sh0.px(i);
            out[0] = Vec3::new(
                dequant(&m.sh0, 0, p[0]),
                dequant(&m.sh0, 1, p[1]),
                dequant(&m.sh0, 2, p[2]),
            );
            if let (Some(s), Some((coeffs, entries))) = (&m.shn, palette) {
                let lp = img[6].px(i);
                let label = lp[0] as usize | (lp[1] as usize) << 8;
                if label >= entries {
                    return Err(bad(format!(
                        "{}: Gaussian {i} has palette label {label}, the palette has {entries}",
                        s.labels
                    )));
                }
                let cen = &img[5];
                let (row, col0) = (label / 64, (label % 64) * coeffs);
                for j in 0..coeffs {
                    let c = cen.px(row * cen.width as usize + col0 + j);
                    out[1 + j] = Vec3::new(
                        dequant(&s.dequant, 0, c[0]),
                        dequant(&s.dequant, 0, c[1]),
                        dequant(&s.dequant, 0, c[2]),
                    );
                }
            }
            Ok(())
        })?;
    cloud.sh = sh;
    Ok(cloud)
}
