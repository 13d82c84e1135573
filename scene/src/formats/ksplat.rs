//! `.ksplat`: GaussianSplats3D's format (mkkellogg/GaussianSplats3D, `src/loaders/SplatBuffer.js`
//! and `SplatBufferGenerator`; read by three.js's `KSPLATLoader` and splat-transform's
//! `readKsplat`). Little endian throughout.
//!
//! - **Header**, 4096 bytes: u8 major version 0, u8 minor ≥ 1, u32 at 4 the section count
//!   (`maxSectionCount`), u32 at 8 the loaded sections, u32 at 12 the Gaussian count
//!   (`maxSplatCount`), u32 at 16 the loaded count, u16 at 20 the compression level (0–2),
//!   f32×3 at 24 the scene centre, f32 at 36 and 40 the range of 8-bit SH (0 means ±1.5).
//! - **Section headers**, 1024 bytes each: u32 loaded and u32 total Gaussians, u32 bucket size
//!   (Gaussians per full bucket), u32 bucket count, f32 bucket block size, u16 at 20 bytes per
//!   bucket (12), u32 at 24 the position quantisation range (0 means 32767), u32 at 28 the
//!   section's bytes, u32 at 32 full buckets, u32 at 36 partially filled buckets, u16 at 40 the
//!   SH degree.
//! - **Section data**, one after another: u32 length of each partially filled bucket, the
//!   bucket centres (f32×3 each), then the Gaussians, in bucket order (full buckets, then the
//!   partially filled ones), `total` records of:
//!
//! | level | position | scale (linear) | rotation w,x,y,z | colour | SH (per band, channel-major) |
//! |---|---|---|---|---|---|
//! | 0 | f32×3 | f32×3 | f32×4 | u8 RGBA | f32 |
//! | 1 | u16×3 in the bucket | f16×3 | f16×4 | u8 RGBA | f16 |
//! | 2 | u16×3 in the bucket | f16×3 | f16×4 | u8 RGBA | u8 in the header's range |
//!
//! A quantised position is `(q − R)·(B/2)/R + bucket centre` for range R and block size B.
//! Colour is the display colour `(0.5 + C0·f_dc)·255` and alpha `sigmoid(opacity)·255`. SH
//! are stored band by band (degree 1: 3 coefficients of R, then G, then B; degree 2: 5 of
//! each; degree 3: 7 of each, as splat-transform reads them; GaussianSplats3D itself renders
//! up to degree 2). Values are in the 3DGS PLY's frame (the generator converts PLYs without
//! turning them).
//!
//! Hostile input: every section's size is computed with checked arithmetic and must lie inside
//! the file before anything is allocated; a Gaussian beyond its section's buckets is an error;
//! a zero or negative stored scale (a half float underflows below 6·10⁻⁸) reads as the
//! smallest positive half float (2⁻²⁴), the format's own resolution, rather than −∞.

use std::io::Write;
use std::path::Path;

use glam::{Quat, Vec3};
use half::f16;

use crate::error::{Result, SceneError};
use crate::gaussians::{logit, sh_coeffs, sigmoid, GaussianCloud};

/// Main header bytes.
pub const HEADER: usize = 4096;
/// Bytes per section header.
pub const SECTION_HEADER: usize = 1024;
/// Bytes per bucket centre.
const BUCKET_BYTES: usize = 12;
/// GaussianSplats3D's defaults: block size, Gaussians per bucket, position range, SH range.
pub const DEFAULT_BLOCK_SIZE: f32 = 5.0;
pub const DEFAULT_BUCKET_SIZE: u32 = 256;
const DEFAULT_RANGE: u32 = 32767;
const DEFAULT_SH_HALF_RANGE: f32 = 1.5;
/// 3DGS's degree-0 SH constant, as GaussianSplats3D writes it.
const C0: f32 = 0.282_094_8;
/// The smallest positive half float: a stored scale of zero reads as this.
const MIN_SCALE: f32 = 5.960_464_5e-8;

/// Options for [`encode_ksplat`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KsplatOptions {
    /// 0 (float32), 1 (half floats, positions in buckets; the default) or 2 (level 1 with
    /// 8-bit SH).
    pub level: u8,
    /// Edge of a position bucket's cube (GaussianSplats3D: 5).
    pub block_size: f32,
    /// Gaussians per full bucket (GaussianSplats3D: 256).
    pub bucket_size: u32,
}

impl Default for KsplatOptions {
    fn default() -> Self {
        KsplatOptions {
            level: 1,
            block_size: DEFAULT_BLOCK_SIZE,
            bucket_size: DEFAULT_BUCKET_SIZE,
        }
    }
}

/// Bytes of one record at a level and SH degree.
pub fn record_bytes(level: u8, degree: u8) -> usize {
    let sh = 3 * (sh_coeffs(degree) - 1);
    match level {
        0 => 44 + 4 * sh,
        1 => 24 + 2 * sh,
        _ => 24 + sh,
    }
}

/// Does the start of a file look like a `.ksplat` header? (version 0.1+, a level 0–2, at
/// least one section, the unused bytes zero, and the file at least a header long).
pub(crate) fn plausible(head: &[u8], file_len: u64) -> bool {
    if head.len() < 48 || file_len < (HEADER + SECTION_HEADER) as u64 {
        return false;
    }
    let u32_at = |i: usize| u32::from_le_bytes([head[i], head[i + 1], head[i + 2], head[i + 3]]);
    head[0] == 0
        && head[1] >= 1
        && head[2] == 0
        && head[3] == 0
        && u32_at(4) >= 1
        && u32_at(8) <= u32_at(4)
        && u32_at(16) <= u32_at(12)
        && u16::from_le_bytes([head[20], head[21]]) <= 2
        && head[22] == 0
        && head[23] == 0
}

/// One parsed section header, with the byte ranges it implies.
struct Section {
    count: usize,
    bucket_size: usize,
    full: usize,
    partial: usize,
    buckets: usize,
    block: f32,
    range: f32,
    degree: u8,
    /// Start of the section's data in the file.
    base: usize,
    /// Bytes of the section's data.
    len: usize,
}

fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

fn u16_at(b: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([b[i], b[i + 1]])
}

fn f32_at(b: &[u8], i: usize) -> f32 {
    f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

fn half_at(b: &[u8], i: usize) -> f32 {
    f16::from_bits(u16_at(b, i)).to_f32()
}

/// Read a `.ksplat` file.
pub fn read_ksplat(path: &Path) -> Result<GaussianCloud> {
    let len = super::regular_file_len(path)?;
    // The whole file is the format's unit (its sections point anywhere in it); reading it
    // costs its own size, which the file justifies.
    let bytes = super::read_file_capped(path, len)?;
    decode_ksplat(&bytes, path)
}

/// Decode `.ksplat` bytes; `path` names the source in errors.
pub fn decode_ksplat(b: &[u8], path: &Path) -> Result<GaussianCloud> {
    let bad = |what: String| SceneError::format(path, what);
    if b.len() < HEADER {
        return Err(bad(format!(
            ".ksplat file of {} bytes ends inside its {HEADER}-byte header",
            b.len()
        )));
    }
    if b[0] != 0 || b[1] < 1 {
        return Err(bad(format!(
            ".ksplat version {}.{} is not one GaussianSplats3D writes (0.1 and later 0.x)",
            b[0], b[1]
        )));
    }
    let sections = u32_at(b, 4) as usize;
    let level = u16_at(b, 20);
    if level > 2 {
        return Err(bad(format!(
            ".ksplat compression level {level} is not 0, 1 or 2"
        )));
    }
    let level = level as u8;
    let sh_min = match f32_at(b, 36) {
        0.0 => -DEFAULT_SH_HALF_RANGE,
        v => v,
    };
    let sh_max = match f32_at(b, 40) {
        0.0 => DEFAULT_SH_HALF_RANGE,
        v => v,
    };
    if level == 2 && !(sh_min.is_finite() && sh_max.is_finite()) {
        return Err(bad(format!(
            ".ksplat 8-bit SH range [{sh_min}, {sh_max}] is not finite"
        )));
    }
    let data_start = sections
        .checked_mul(SECTION_HEADER)
        .and_then(|s| s.checked_add(HEADER))
        .filter(|&e| e <= b.len())
        .ok_or_else(|| {
            bad(format!(
                ".ksplat header declares {sections} sections, whose 1024-byte headers run past the end of the {}-byte file",
                b.len()
            ))
        })?;
    let mut parsed = Vec::with_capacity(sections);
    let mut base = data_start;
    let mut degree = 0u8;
    let mut n_total = 0usize;
    for s in 0..sections {
        let h = &b[HEADER + s * SECTION_HEADER..][..SECTION_HEADER];
        let sec = parse_section(h, s, level, base, b.len()).map_err(bad)?;
        base = sec.base + sec.len;
        degree = degree.max(sec.degree);
        n_total += sec.count;
        parsed.push(sec);
    }
    let declared = u32_at(b, 16) as usize;
    if declared != n_total {
        return Err(bad(format!(
            ".ksplat header declares {declared} Gaussians but its sections hold {n_total}"
        )));
    }
    let mut cloud = GaussianCloud::with_capacity(degree, n_total);
    for (s, sec) in parsed.iter().enumerate() {
        decode_section(b, sec, level, degree, (sh_min, sh_max), &mut cloud)
            .map_err(|what| bad(format!("section {s}: {what}")))?;
    }
    Ok(cloud)
}

fn parse_section(
    h: &[u8],
    s: usize,
    level: u8,
    base: usize,
    file_len: usize,
) -> std::result::Result<Section, String> {
    let count = u32_at(h, 0) as usize;
    let total = u32_at(h, 4) as usize;
    let degree = u16_at(h, 40);
    if degree > 3 {
        return Err(format!("section {s}: SH degree {degree} is above 3"));
    }
    if count > total {
        return Err(format!(
            "section {s}: {count} Gaussians loaded of a section of {total}"
        ));
    }
    let degree = degree as u8;
    let (bucket_size, buckets, full, partial) = (
        u32_at(h, 8) as usize,
        u32_at(h, 12) as usize,
        u32_at(h, 32) as usize,
        u32_at(h, 36) as usize,
    );
    let block = f32_at(h, 16);
    let bucket_bytes = u16_at(h, 20) as usize;
    let range = match u32_at(h, 24) {
        0 => DEFAULT_RANGE,
        r => r,
    } as f32;
    let bucket_len = if level == 0 {
        0
    } else {
        if buckets > 0 && bucket_bytes != BUCKET_BYTES {
            return Err(format!(
                "section {s}: buckets of {bucket_bytes} bytes; the format's are {BUCKET_BYTES}"
            ));
        }
        if full.checked_add(partial) != Some(buckets) {
            return Err(format!(
                "section {s}: {full} full and {partial} partially filled buckets, but {buckets} buckets"
            ));
        }
        if count > 0 && !(block.is_finite() && block > 0.0) {
            return Err(format!("section {s}: bucket block size {block}"));
        }
        buckets
            .checked_mul(BUCKET_BYTES)
            .and_then(|x| x.checked_add(partial.checked_mul(4)?))
            .ok_or_else(|| format!("section {s}: {buckets} buckets overflow"))?
    };
    let len = total
        .checked_mul(record_bytes(level, degree))
        .and_then(|d| d.checked_add(bucket_len))
        .filter(|&l| base.checked_add(l).is_some_and(|e| e <= file_len))
        .ok_or_else(|| {
            format!(
                "section {s} ({total} Gaussians, {buckets} buckets) runs past the end of the {file_len}-byte file (truncated, or a wrong count)"
            )
        })?;
    Ok(Section {
        count,
        bucket_size,
        full,
        partial,
        buckets,
        block,
        range,
        degree,
        base,
        len,
    })
}

/// Append a section's Gaussians, in stored order.
fn decode_section(
    b: &[u8],
    sec: &Section,
    level: u8,
    degree: u8,
    (sh_min, sh_max): (f32, f32),
    cloud: &mut GaussianCloud,
) -> std::result::Result<(), String> {
    let bucketed = level > 0;
    let (lengths_at, centres_at) = (sec.base, sec.base + 4 * sec.partial);
    let data_at = if bucketed {
        centres_at + BUCKET_BYTES * sec.buckets
    } else {
        sec.base
    };
    // Which bucket each Gaussian falls in: full buckets of `bucket_size`, then the partially
    // filled ones with their own lengths.
    let mut bucket_of = Vec::new();
    if bucketed {
        let in_full = sec.full.saturating_mul(sec.bucket_size).min(sec.count);
        bucket_of.reserve(sec.count);
        bucket_of.extend((0..in_full).map(|i| i / sec.bucket_size.max(1)));
        for p in 0..sec.partial {
            if bucket_of.len() >= sec.count {
                break;
            }
            let l = u32_at(b, lengths_at + 4 * p) as usize;
            let room = sec.count - bucket_of.len();
            bucket_of.extend(std::iter::repeat_n(sec.full + p, l.min(room)));
        }
        if bucket_of.len() < sec.count {
            return Err(format!(
                "its buckets hold {} of its {} Gaussians",
                bucket_of.len(),
                sec.count
            ));
        }
    }
    let rec = record_bytes(level, sec.degree);
    let k_in = sh_coeffs(sec.degree) - 1;
    let k_out = sh_coeffs(degree);
    let scale_q = (sec.block * 0.5) / sec.range;
    let sh_step = (sh_max - sh_min) / 255.0;
    let mut sh = vec![Vec3::ZERO; k_out];
    for i in 0..sec.count {
        let r = &b[data_at + i * rec..][..rec];
        let (mean, scale, rot, sh_at) = if level == 0 {
            (
                Vec3::new(f32_at(r, 0), f32_at(r, 4), f32_at(r, 8)),
                Vec3::new(f32_at(r, 12), f32_at(r, 16), f32_at(r, 20)),
                Quat::from_xyzw(f32_at(r, 28), f32_at(r, 32), f32_at(r, 36), f32_at(r, 24)),
                44,
            )
        } else {
            let c = centres_at + BUCKET_BYTES * bucket_of[i];
            let centre = Vec3::new(f32_at(b, c), f32_at(b, c + 4), f32_at(b, c + 8));
            let q = |o: usize| (u16_at(r, o) as f32 - sec.range) * scale_q;
            (
                Vec3::new(q(0), q(2), q(4)) + centre,
                Vec3::new(half_at(r, 6), half_at(r, 8), half_at(r, 10)),
                Quat::from_xyzw(
                    half_at(r, 14),
                    half_at(r, 16),
                    half_at(r, 18),
                    half_at(r, 12),
                ),
                24,
            )
        };
        let col = if level == 0 { 40 } else { 20 };
        let rgba = &r[col..col + 4];
        sh[0] = Vec3::new(rgba[0] as f32, rgba[1] as f32, rgba[2] as f32) / 255.0;
        sh[0] = (sh[0] - Vec3::splat(0.5)) / C0;
        for v in &mut sh[1..] {
            *v = Vec3::ZERO;
        }
        // Band by band, channel-major inside a band.
        let mut at = 0;
        for band in 1..=sec.degree as usize {
            let m = 2 * band + 1;
            let first = band * band - 1;
            for ch in 0..3 {
                for c in 0..m {
                    let j = at + ch * m + c;
                    let v = match level {
                        0 => f32_at(r, sh_at + 4 * j),
                        1 => half_at(r, sh_at + 2 * j),
                        _ => sh_min + r[sh_at + j] as f32 * sh_step,
                    };
                    if first + c < k_out - 1 {
                        sh[1 + first + c][ch] = v;
                    }
                }
            }
            at += 3 * m;
        }
        debug_assert_eq!(at, 3 * k_in);
        let log = |s: f32| {
            let s = s.abs();
            if s > 0.0 {
                s.ln()
            } else if s == 0.0 {
                MIN_SCALE.ln()
            } else {
                s // NaN stays NaN, for the invalid-Gaussian policy to name
            }
        };
        cloud.push(
            mean,
            Vec3::new(log(scale.x), log(scale.y), log(scale.z)),
            rot,
            logit(rgba[3] as f32 / 255.0),
            &sh,
        );
    }
    Ok(())
}

/// The order the Gaussians are stored in at levels 1 and 2: grouped by position block (cubes
/// of `block_size` from the bounds' minimum corner, as GaussianSplats3D's
/// `computeBucketsForUncompressedSplatArray`), each block cut into buckets of `bucket_size`;
/// all full buckets first, then the partially filled ones. Returns the order, each bucket's
/// centre and the partial buckets' lengths, and the number of full buckets.
pub fn bucket_order(
    cloud: &GaussianCloud,
    opts: &KsplatOptions,
) -> (Vec<usize>, Vec<Vec3>, Vec<u32>, usize) {
    let Some((lo, _)) = cloud.bounds() else {
        return (Vec::new(), Vec::new(), Vec::new(), 0);
    };
    let bs = opts.block_size;
    let block = |p: Vec3| ((p - lo) / bs).floor();
    let mut keyed: Vec<((i64, i64, i64), usize)> = cloud
        .means
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            let k = block(p);
            ((k.x as i64, k.y as i64, k.z as i64), i)
        })
        .collect();
    // Stable: a block's Gaussians keep their file order, as in the reference.
    keyed.sort_by_key(|&(k, _)| k);
    let cap = opts.bucket_size.max(1) as usize;
    let (mut full, mut partial) = (Vec::new(), Vec::new());
    let mut start = 0;
    while start < keyed.len() {
        let key = keyed[start].0;
        let end = start + keyed[start..].iter().take_while(|(k, _)| *k == key).count();
        let centre = lo + (Vec3::new(key.0 as f32, key.1 as f32, key.2 as f32) + 0.5) * bs;
        for chunk in keyed[start..end].chunks(cap) {
            let ids: Vec<usize> = chunk.iter().map(|&(_, i)| i).collect();
            if ids.len() == cap {
                full.push((centre, ids));
            } else {
                partial.push((centre, ids));
            }
        }
        start = end;
    }
    let n_full = full.len();
    let lengths = partial.iter().map(|(_, ids)| ids.len() as u32).collect();
    let mut order = Vec::with_capacity(cloud.len());
    let mut centres = Vec::with_capacity(full.len() + partial.len());
    for (c, ids) in full.into_iter().chain(partial) {
        centres.push(c);
        order.extend(ids);
    }
    (order, centres, lengths, n_full)
}

/// Encode a cloud as `.ksplat` bytes (one section). At levels 1 and 2 the Gaussians are
/// reordered into buckets ([`bucket_order`]); values round to nearest (GaussianSplats3D's
/// generator truncates colours and 8-bit SH; its reader decodes either the same way).
pub fn encode_ksplat(cloud: &GaussianCloud, opts: &KsplatOptions) -> Result<Vec<u8>> {
    cloud.check_shape()?;
    let level = opts.level;
    if level > 2 {
        return Err(SceneError::Invalid(format!(
            ".ksplat: compression level {level} is not 0, 1 or 2"
        )));
    }
    if !(opts.block_size.is_finite() && opts.block_size > 0.0) || opts.bucket_size == 0 {
        return Err(SceneError::Invalid(format!(
            ".ksplat: block size {} and bucket size {} must be positive",
            opts.block_size, opts.bucket_size
        )));
    }
    let n = u32::try_from(cloud.len())
        .map_err(|_| SceneError::Invalid(".ksplat: more than 2^32 Gaussians".into()))?;
    let degree = cloud.sh_degree;
    let k = cloud.coeffs();
    let rec = record_bytes(level, degree);
    let (order, centres, lengths, n_full) = if level == 0 {
        ((0..cloud.len()).collect(), Vec::new(), Vec::new(), 0)
    } else {
        bucket_order(cloud, opts)
    };
    // The 8-bit SH range: the coefficients' own extent (GaussianSplats3D's generator does the
    // same), or the default when there are none.
    let (mut sh_min, mut sh_max) = (f32::INFINITY, f32::NEG_INFINITY);
    if degree > 0 {
        for (i, v) in cloud.sh.iter().enumerate() {
            if i % k != 0 {
                for x in v.to_array() {
                    sh_min = sh_min.min(x);
                    sh_max = sh_max.max(x);
                }
            }
        }
    }
    if !(sh_min.is_finite() && sh_max.is_finite() && sh_max > sh_min)
        || sh_min == 0.0
        || sh_max == 0.0
    {
        // 0 in the header means "the default", so a range touching 0 is widened to it.
        sh_min = sh_min.min(-DEFAULT_SH_HALF_RANGE);
        sh_max = sh_max.max(DEFAULT_SH_HALF_RANGE);
        if !(sh_min.is_finite() && sh_max.is_finite()) {
            sh_min = -DEFAULT_SH_HALF_RANGE;
            sh_max = DEFAULT_SH_HALF_RANGE;
        }
    }
    let bucket_len = if level == 0 {
        0
    } else {
        lengths.len() * 4 + centres.len() * BUCKET_BYTES
    };
    let section_len = bucket_len + rec * cloud.len();
    let section_u32 = u32::try_from(section_len).map_err(|_| {
        SceneError::Invalid(format!(
            ".ksplat: a section of {section_len} bytes exceeds the format's 32-bit size field"
        ))
    })?;
    let mut out = vec![0u8; HEADER + SECTION_HEADER];
    out.reserve(section_len);
    out[0] = 0;
    out[1] = 1;
    let put32 =
        |o: &mut Vec<u8>, at: usize, v: u32| o[at..at + 4].copy_from_slice(&v.to_le_bytes());
    let putf = |o: &mut Vec<u8>, at: usize, v: f32| o[at..at + 4].copy_from_slice(&v.to_le_bytes());
    put32(&mut out, 4, 1);
    put32(&mut out, 8, 1);
    put32(&mut out, 12, n);
    put32(&mut out, 16, n);
    out[20..22].copy_from_slice(&(level as u16).to_le_bytes());
    let centre = cloud
        .bounds()
        .map_or(Vec3::ZERO, |(lo, hi)| (lo + hi) * 0.5);
    for (j, v) in centre.to_array().into_iter().enumerate() {
        putf(&mut out, 24 + 4 * j, v);
    }
    putf(&mut out, 36, sh_min);
    putf(&mut out, 40, sh_max);
    let s = HEADER;
    put32(&mut out, s, n);
    put32(&mut out, s + 4, n);
    if level > 0 {
        put32(&mut out, s + 8, opts.bucket_size);
        put32(&mut out, s + 12, centres.len() as u32);
        putf(&mut out, s + 16, opts.block_size);
        out[s + 20..s + 22].copy_from_slice(&(BUCKET_BYTES as u16).to_le_bytes());
        put32(&mut out, s + 24, DEFAULT_RANGE);
        put32(&mut out, s + 32, n_full as u32);
        put32(&mut out, s + 36, lengths.len() as u32);
    }
    put32(&mut out, s + 28, section_u32);
    out[s + 40..s + 42].copy_from_slice(&(degree as u16).to_le_bytes());
    for l in &lengths {
        out.extend_from_slice(&l.to_le_bytes());
    }
    if level > 0 {
        for c in &centres {
            for v in c.to_array() {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    let range = DEFAULT_RANGE as f32;
    let to_q = range / (opts.block_size * 0.5);
    let h =
        |o: &mut Vec<u8>, v: f32| o.extend_from_slice(&f16::from_f32(v).to_bits().to_le_bytes());
    let mut bucket = 0;
    let mut left_in_bucket = 0usize;
    let mut partial_seen = 0;
    for &i in &order {
        if level > 0 {
            while left_in_bucket == 0 {
                left_in_bucket = if bucket < n_full {
                    opts.bucket_size as usize
                } else {
                    let l = lengths[partial_seen] as usize;
                    partial_seen += 1;
                    l
                };
                bucket += 1;
            }
            left_in_bucket -= 1;
        }
        let m = cloud.means[i];
        let s3 = cloud.scale(i);
        let q = cloud.unit_rotation(i);
        if level == 0 {
            for v in m
                .to_array()
                .into_iter()
                .chain(s3.to_array())
                .chain([q.w, q.x, q.y, q.z])
            {
                out.extend_from_slice(&v.to_le_bytes());
            }
        } else {
            let d = m - centres[bucket - 1];
            for v in d.to_array() {
                let qv = ((v * to_q).round() + range).clamp(0.0, 2.0 * range + 1.0) as u16;
                out.extend_from_slice(&qv.to_le_bytes());
            }
            for v in s3.to_array().into_iter().chain([q.w, q.x, q.y, q.z]) {
                h(&mut out, v);
            }
        }
        let dc = cloud.sh[i * k];
        for c in dc.to_array() {
            out.push(((0.5 + C0 * c) * 255.0).round().clamp(0.0, 255.0) as u8);
        }
        out.push(
            (sigmoid(cloud.opacity_logits[i]) * 255.0)
                .round()
                .clamp(0.0, 255.0) as u8,
        );
        let sh = &cloud.sh[i * k + 1..(i + 1) * k];
        for band in 1..=degree as usize {
            let m = 2 * band + 1;
            let first = band * band - 1;
            for ch in 0..3 {
                for c in 0..m {
                    let v = sh[first + c][ch];
                    match level {
                        0 => out.extend_from_slice(&v.to_le_bytes()),
                        1 => h(&mut out, v),
                        _ => out.push(
                            ((v - sh_min) / (sh_max - sh_min) * 255.0)
                                .round()
                                .clamp(0.0, 255.0) as u8,
                        ),
                    }
                }
            }
        }
    }
    debug_assert_eq!(out.len(), HEADER + SECTION_HEADER + section_len);
    Ok(out)
}

/// Write a `.ksplat` file atomically.
pub fn write_ksplat(path: &Path, cloud: &GaussianCloud, opts: &KsplatOptions) -> Result<()> {
    let bytes = encode_ksplat(cloud, opts)
        .map_err(|e| SceneError::format(path, format!("cannot write: {e}")))?;
    crate::image_io::with_atomic_writer(path, |w| w.write_all(&bytes))
}
