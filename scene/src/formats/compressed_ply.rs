//! SuperSplat / PlayCanvas compressed PLY (`*.compressed.ply`, written by SuperSplat and
//! splat-transform; decoder: splat-transform `src/readers/decompress-ply.ts`).
//!
//! A binary little-endian PLY with the elements
//! - `chunk` (one per 256 Gaussians, float): `min_x min_y min_z max_x max_y max_z`,
//!   `min_scale_x.. max_scale_z` (log-scales) and, optionally, `min_r min_g min_b max_r max_g
//!   max_b` (display colour; [0, 1] when absent, as in early SuperSplat files);
//! - `vertex` (uint32): `packed_position` (11-10-11 bits, lerp between the chunk's bounds),
//!   `packed_rotation` (2 bits index of the largest component, then three 10-bit components in
//!   [−1/√2, 1/√2], in PLY order w, x, y, z), `packed_scale` (11-10-11 between the chunk's
//!   log-scale bounds), `packed_color` (8-8-8-8: colour between the chunk's bounds, then
//!   `sigmoid(opacity)`);
//! - optional `sh` (uint8) `f_rest_0..K−1`, K ∈ {9, 24, 45}, channel-major like the PLY:
//!   `n = 0 | 1 | (v + 0.5)/256` for v = 0 | 255 | otherwise, `f_rest = (n − 0.5)·8`.
//!
//! Same axis convention as the 3DGS PLY. Sizes are checked against the file before
//! allocating; chunk bounds must be finite.

use std::io::Write;
use std::path::Path;

use glam::{Quat, Vec3};
use rayon::prelude::*;

use super::read_file_capped;
use crate::error::{Result, SceneError};
use crate::gaussians::logit;
use crate::sh::SH_C0;
use crate::GaussianCloud;

/// Gaussians per chunk.
pub const CHUNK: usize = 256;
/// Header bytes searched for `end_header`.
const MAX_HEADER: usize = 64 << 10;

const CHUNK_REQUIRED: [&str; 12] = [
    "min_x",
    "min_y",
    "min_z",
    "max_x",
    "max_y",
    "max_z",
    "min_scale_x",
    "min_scale_y",
    "min_scale_z",
    "max_scale_x",
    "max_scale_y",
    "max_scale_z",
];
const CHUNK_COLOUR: [&str; 6] = ["min_r", "min_g", "min_b", "max_r", "max_g", "max_b"];
const PACKED: [&str; 4] = [
    "packed_position",
    "packed_rotation",
    "packed_scale",
    "packed_color",
];

/// Does a PLY header (the first bytes of the file) describe a compressed PLY?
pub(crate) fn looks_compressed(head: &[u8]) -> bool {
    let text = String::from_utf8_lossy(head);
    let header = text.split("end_header").next().unwrap_or("");
    header.contains("element chunk") && header.contains("packed_position")
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    /// (name, size in bytes, kind: "f32", "u32", "u8", "f64" or "int")
    props: Vec<(String, usize, &'static str)>,
}

impl Element {
    fn stride(&self) -> usize {
        self.props.iter().map(|p| p.1).sum()
    }
    fn offset(&self, name: &str) -> Option<(usize, &'static str)> {
        let mut off = 0;
        for (n, size, ty) in &self.props {
            if n == name {
                return Some((off, ty));
            }
            off += size;
        }
        None
    }
}

fn scalar(ty: &str) -> Option<(usize, &'static str)> {
    Some(match ty {
        "char" | "int8" => (1, "int"),
        "uchar" | "uint8" => (1, "u8"),
        "short" | "int16" => (2, "int"),
        "ushort" | "uint16" => (2, "int"),
        "int" | "int32" => (4, "int"),
        "uint" | "uint32" => (4, "u32"),
        "float" | "float32" => (4, "f32"),
        "double" | "float64" => (8, "f64"),
        _ => return None,
    })
}

/// Parse the header; returns the elements and the header's length in bytes.
fn parse_header(bytes: &[u8], path: &Path) -> Result<(Vec<Element>, usize)> {
    let bad = |what: String| SceneError::format(path, what);
    let search = &bytes[..bytes.len().min(MAX_HEADER)];
    let end = search
        .windows(11)
        .position(|w| w == b"end_header\n")
        .map(|p| p + 11)
        .or_else(|| {
            search
                .windows(12)
                .position(|w| w == b"end_header\r\n")
                .map(|p| p + 12)
        })
        .ok_or_else(|| bad("compressed PLY header has no end_header in its first 64 KiB".into()))?;
    let text = std::str::from_utf8(&bytes[..end])
        .map_err(|_| bad("compressed PLY header is not text".into()))?;
    let mut elements: Vec<Element> = Vec::new();
    let mut format_ok = false;
    for (ln, line) in text.lines().enumerate().skip(1) {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["format", "binary_little_endian", _] => format_ok = true,
            ["format", f, _] => {
                return Err(bad(format!(
                    "compressed PLY must be binary_little_endian, not {f}"
                )))
            }
            ["comment", ..] | ["obj_info", ..] | [] | ["end_header"] => {}
            ["element", name, count] => {
                let count = count.parse::<u64>().map_err(|_| {
                    bad(format!(
                        "header line {}: element count '{count}' is not a number",
                        ln + 1
                    ))
                })?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            ["property", "list", ..] => {
                return Err(bad(format!(
                    "header line {}: list properties are not part of a compressed PLY",
                    ln + 1
                )))
            }
            ["property", ty, name] => {
                let (size, kind) = scalar(ty).ok_or_else(|| {
                    bad(format!(
                        "header line {}: unknown property type '{ty}'",
                        ln + 1
                    ))
                })?;
                let el = elements.last_mut().ok_or_else(|| {
                    bad(format!(
                        "header line {}: property before any element",
                        ln + 1
                    ))
                })?;
                el.props.push((name.to_string(), size, kind));
            }
            _ => {
                return Err(bad(format!(
                    "header line {}: cannot parse '{line}'",
                    ln + 1
                )))
            }
        }
    }
    if !format_ok {
        return Err(bad("compressed PLY header has no format line".into()));
    }
    Ok((elements, end))
}

/// Read a compressed PLY file. The flag is the decoder's validity screen (see
/// [`decode_screened`]): false when no Gaussian can be invalid.
pub fn read_compressed_ply(path: &Path) -> Result<(GaussianCloud, bool)> {
    // 2^32 Gaussians of 16 bytes plus their chunks and SH bound any real file.
    let bytes = read_file_capped(path, 1 << 40)?;
    decode_screened(&bytes, path)
}

fn f32_at(b: &[u8], o: usize) -> f32 {
    f32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}
fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}

fn unorm(v: u32, bits: u32) -> f32 {
    let t = (1u32 << bits) - 1;
    (v & t) as f32 / t as f32
}

fn unpack_111011(v: u32) -> Vec3 {
    Vec3::new(unorm(v >> 21, 11), unorm(v >> 11, 10), unorm(v, 11))
}

/// 2-10-10-10 smallest three, to a quaternion (PLY order w, x, y, z → glam).
fn unpack_rot(v: u32) -> Quat {
    let norm = std::f32::consts::SQRT_2;
    let a = (unorm(v >> 20, 10) - 0.5) * norm;
    let b = (unorm(v >> 10, 10) - 0.5) * norm;
    let c = (unorm(v, 10) - 0.5) * norm;
    let m = (1.0 - (a * a + b * b + c * c)).max(0.0).sqrt();
    let [w, x, y, z] = match v >> 30 {
        0 => [m, a, b, c],
        1 => [a, m, b, c],
        2 => [a, b, m, c],
        _ => [a, b, c, m],
    };
    Quat::from_xyzw(x, y, z, w)
}

fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a * (1.0 - t) + b * t
}

/// Decode a compressed PLY held in memory.
pub fn decode_compressed_ply(bytes: &[u8], path: &Path) -> Result<GaussianCloud> {
    decode_screened(bytes, path).map(|(cloud, _)| cloud)
}

/// Chunk bounds at most this large in magnitude cannot overflow when interpolated: a convex
/// combination stays within its ends, up to the last bit's rounding, which only matters
/// within an ulp of `f32::MAX`.
const SAFE_BOUND: f32 = f32::MAX / 2.0;

/// Clouds whose decoded arrays reach this size decode on every core (see `decode_screened`).
pub const PARALLEL_FROM_BYTES: usize = 16 << 20;

/// [`decode_compressed_ply`], with a conservative validity flag that saves the loader a
/// pass over the decoded cloud: every value is interpolated between finite chunk bounds
/// (checked below), SH come from bytes, and a smallest-three quaternion never has zero
/// length (its largest component is √(1 − the others' squares) when they sum below one).
/// So only bounds near `f32::MAX`, whose interpolation could round to ±∞, make a Gaussian
/// suspect. Debug builds check the claim against the per-Gaussian rule on every load.
pub fn decode_screened(bytes: &[u8], path: &Path) -> Result<(GaussianCloud, bool)> {
    decode_with(bytes, path, PARALLEL_FROM_BYTES)
}

/// [`decode_screened`] with the size from which decoding runs on every core.
fn decode_with(
    bytes: &[u8],
    path: &Path,
    parallel_from_bytes: usize,
) -> Result<(GaussianCloud, bool)> {
    let bad = |what: String| SceneError::format(path, what);
    let (elements, header_len) = parse_header(bytes, path)?;
    let find = |name: &str| elements.iter().position(|e| e.name == name);
    let ci = find("chunk").ok_or_else(|| bad("compressed PLY has no 'chunk' element".into()))?;
    let vi = find("vertex").ok_or_else(|| bad("compressed PLY has no 'vertex' element".into()))?;
    let si = find("sh");
    if let Some(e) = elements
        .iter()
        .find(|e| !["chunk", "vertex", "sh"].contains(&e.name.as_str()))
    {
        return Err(bad(format!(
            "compressed PLY has an unexpected element '{}'",
            e.name
        )));
    }
    // Element data sizes against the file, before anything is allocated.
    let data_len = (bytes.len() - header_len) as u64;
    let mut offsets = Vec::with_capacity(elements.len());
    let mut at = 0u64;
    for e in &elements {
        offsets.push(at as usize);
        let size = e.count.checked_mul(e.stride() as u64);
        at = match size.and_then(|s| at.checked_add(s)) {
            Some(v) if v <= data_len => v,
            _ => {
                return Err(bad(format!(
                    "element '{}' declares {} rows of {} bytes but only {} bytes of data follow the header (truncated file or wrong count)",
                    e.name,
                    e.count,
                    e.stride(),
                    data_len.saturating_sub(at)
                )))
            }
        };
    }
    let data = &bytes[header_len..];
    let chunk = &elements[ci];
    let vertex = &elements[vi];
    let n = vertex.count as usize;
    let need_chunks = n.div_ceil(CHUNK) as u64;
    if chunk.count < need_chunks {
        return Err(bad(format!(
            "{n} vertices need {need_chunks} chunks of {CHUNK} but the file has {}",
            chunk.count
        )));
    }
    let prop = |e: &Element, name: &str, ty: &str| -> Result<usize> {
        match e.offset(name) {
            Some((off, t)) if t == ty => Ok(off),
            Some((_, t)) => Err(bad(format!("{}.{name} is {t}, expected {ty}", e.name))),
            None => Err(bad(format!(
                "element '{}' has no property '{name}'",
                e.name
            ))),
        }
    };
    let chunk_offs: Vec<usize> = CHUNK_REQUIRED
        .iter()
        .map(|n| prop(chunk, n, "f32"))
        .collect::<Result<_>>()?;
    let colour_offs: Option<Vec<usize>> = if chunk.offset("min_r").is_some() {
        Some(
            CHUNK_COLOUR
                .iter()
                .map(|n| prop(chunk, n, "f32"))
                .collect::<Result<_>>()?,
        )
    } else {
        None
    };
    let packed_offs: Vec<usize> = PACKED
        .iter()
        .map(|n| prop(vertex, n, "u32"))
        .collect::<Result<_>>()?;
    let (sh_degree, sh_offs) = match si {
        None => (0u8, Vec::new()),
        Some(si) => {
            let e = &elements[si];
            if e.count != vertex.count {
                return Err(bad(format!(
                    "element 'sh' has {} rows but 'vertex' has {}",
                    e.count, vertex.count
                )));
            }
            let k = e.props.len();
            let degree = match k {
                9 => 1,
                24 => 2,
                45 => 3,
                _ => {
                    return Err(bad(format!(
                        "element 'sh' has {k} properties; 9, 24 or 45 f_rest values expected"
                    )))
                }
            };
            let offs = (0..k)
                .map(|j| prop(e, &format!("f_rest_{j}"), "u8").map(|o| offsets[si] + o))
                .collect::<Result<Vec<_>>>()?;
            (degree, offs)
        }
    };

    // Chunk bounds: read and check once per chunk.
    let mut suspect = false;
    let cstride = chunk.stride();
    let mut bounds: Vec<[f32; 18]> = Vec::with_capacity(need_chunks as usize);
    for c in 0..need_chunks as usize {
        let base = offsets[ci] + c * cstride;
        let mut b = [0.0f32; 18];
        for (j, &o) in chunk_offs.iter().enumerate() {
            b[j] = f32_at(data, base + o);
        }
        match &colour_offs {
            Some(co) => {
                for (j, &o) in co.iter().enumerate() {
                    b[12 + j] = f32_at(data, base + o);
                }
            }
            None => b[12..].copy_from_slice(&[0.0, 0.0, 0.0, 1.0, 1.0, 1.0]),
        }
        if let Some(j) = b.iter().position(|v| !v.is_finite()) {
            let name = if j < 12 {
                CHUNK_REQUIRED[j]
            } else {
                CHUNK_COLOUR[j - 12]
            };
            return Err(bad(format!(
                "chunk {c}: {name} is {} (bounds must be finite)",
                b[j]
            )));
        }
        suspect |= b.iter().any(|v| v.abs() > SAFE_BOUND);
        bounds.push(b);
    }

    let k = crate::gaussians::sh_coeffs(sh_degree);
    let kr = k - 1;
    let mut cloud = GaussianCloud::new(sh_degree);
    cloud.means = vec![Vec3::ZERO; n];
    cloud.log_scales = vec![Vec3::ZERO; n];
    cloud.rotations = vec![Quat::IDENTITY; n];
    cloud.opacity_logits = vec![0.0; n];
    cloud.sh = vec![Vec3::ZERO; n * k];
    let vstride = vertex.stride();
    let sstride = si.map_or(0, |si| elements[si].stride());
    // One task per chunk of 256 (the format's own unit: one set of bounds). Each task writes
    // only its own slices of the preallocated arrays, so the result does not depend on the
    // thread count and no worker allocates. Small clouds decode on the calling thread: a
    // second thread's stack and arena cost more resident memory than its overlap saves time
    // (plant, 6.4 MB of arrays: 1.55× the cloud resident on two threads, 1.42× on one).
    let decode_chunk = |ch: usize,
                        means: &mut [Vec3],
                        scales: &mut [Vec3],
                        rots: &mut [Quat],
                        opacities: &mut [f32],
                        sh: &mut [Vec3]| {
        let b = &bounds[ch];
        for j in 0..means.len() {
            let i = ch * CHUNK + j;
            let base = offsets[vi] + i * vstride;
            let p = unpack_111011(u32_at(data, base + packed_offs[0]));
            let r = u32_at(data, base + packed_offs[1]);
            let s = unpack_111011(u32_at(data, base + packed_offs[2]));
            let c = u32_at(data, base + packed_offs[3]);
            means[j] = Vec3::new(
                lerp(b[0], b[3], p.x),
                lerp(b[1], b[4], p.y),
                lerp(b[2], b[5], p.z),
            );
            scales[j] = Vec3::new(
                lerp(b[6], b[9], s.x),
                lerp(b[7], b[10], s.y),
                lerp(b[8], b[11], s.z),
            );
            rots[j] = unpack_rot(r);
            let rgb = Vec3::new(
                lerp(b[12], b[15], unorm(c >> 24, 8)),
                lerp(b[13], b[16], unorm(c >> 16, 8)),
                lerp(b[14], b[17], unorm(c >> 8, 8)),
            );
            let coeffs = &mut sh[j * k..(j + 1) * k];
            coeffs[0] = (rgb - Vec3::splat(0.5)) / SH_C0;
            opacities[j] = logit(unorm(c, 8));
            if kr > 0 {
                let sb = i * sstride;
                let v = |j: usize| {
                    let q = data[sb + sh_offs[j]];
                    let t = match q {
                        0 => 0.0,
                        255 => 1.0,
                        q => (q as f32 + 0.5) / 256.0,
                    };
                    (t - 0.5) * 8.0
                };
                // Channel-major in the file (all R, then G, then B) → coefficient-major.
                for (c, out) in coeffs[1..].iter_mut().enumerate() {
                    *out = Vec3::new(v(c), v(kr + c), v(2 * kr + c));
                }
            }
        }
    };
    let cloud_bytes = n * (4 * (3 + 3 + 4 + 1) + 12 * k);
    if cloud_bytes < parallel_from_bytes {
        for (ch, ((((means, scales), rots), opacities), sh)) in cloud
            .means
            .chunks_mut(CHUNK)
            .zip(cloud.log_scales.chunks_mut(CHUNK))
            .zip(cloud.rotations.chunks_mut(CHUNK))
            .zip(cloud.opacity_logits.chunks_mut(CHUNK))
            .zip(cloud.sh.chunks_mut(CHUNK * k))
            .enumerate()
        {
            decode_chunk(ch, means, scales, rots, opacities, sh);
        }
    } else {
        (
            cloud.means.par_chunks_mut(CHUNK),
            cloud.log_scales.par_chunks_mut(CHUNK),
            cloud.rotations.par_chunks_mut(CHUNK),
            cloud.opacity_logits.par_chunks_mut(CHUNK),
            cloud.sh.par_chunks_mut(CHUNK * k),
        )
            .into_par_iter()
            .enumerate()
            .for_each(|(ch, (means, scales, rots, opacities, sh))| {
                decode_chunk(ch, means, scales, rots, opacities, sh)
            });
    }
    Ok((cloud, suspect))
}

fn pack_unorm(v: f32, bits: u32) -> u32 {
    let t = ((1u32 << bits) - 1) as f32;
    (v.clamp(0.0, 1.0) * t + 0.5).floor() as u32
}

fn norm01(v: f32, lo: f32, hi: f32) -> f32 {
    if hi > lo {
        (v - lo) / (hi - lo)
    } else {
        0.0
    }
}

/// Encode a cloud as a compressed PLY (the layout splat-transform writes: chunk bounds
/// including colour, log-scales clamped to [−20, 20] like SuperSplat).
pub fn encode_compressed_ply(cloud: &GaussianCloud) -> Result<Vec<u8>> {
    cloud.check_shape()?;
    let n = cloud.len();
    let chunks = n.div_ceil(CHUNK);
    let k = cloud.coeffs();
    let kr = k - 1;
    let mut out = Vec::with_capacity(1024 + chunks * 72 + n * (16 + 3 * kr));
    let mut h =
        String::from("ply\nformat binary_little_endian 1.0\ncomment splatbridge compressed PLY\n");
    h += &format!("element chunk {chunks}\n");
    for name in CHUNK_REQUIRED.iter().chain(CHUNK_COLOUR.iter()) {
        h += &format!("property float {name}\n");
    }
    h += &format!("element vertex {n}\n");
    for name in PACKED {
        h += &format!("property uint {name}\n");
    }
    if kr > 0 {
        h += &format!("element sh {n}\n");
        for j in 0..3 * kr {
            h += &format!("property uchar f_rest_{j}\n");
        }
    }
    h += "end_header\n";
    out.extend_from_slice(h.as_bytes());
    let colour = |i: usize| Vec3::splat(0.5) + cloud.sh[i * k] * SH_C0;
    let clamp_scale = |l: Vec3| l.clamp(Vec3::splat(-20.0), Vec3::splat(20.0));
    let mut all_bounds = Vec::with_capacity(chunks);
    for c in 0..chunks {
        let range = c * CHUNK..((c + 1) * CHUNK).min(n);
        let (mut pmin, mut pmax) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let (mut smin, mut smax) = (pmin, pmax);
        let (mut cmin, mut cmax) = (pmin, pmax);
        for i in range {
            pmin = pmin.min(cloud.means[i]);
            pmax = pmax.max(cloud.means[i]);
            let l = clamp_scale(cloud.log_scales[i]);
            smin = smin.min(l);
            smax = smax.max(l);
            cmin = cmin.min(colour(i));
            cmax = cmax.max(colour(i));
        }
        for v in [pmin, pmax, smin, smax, cmin, cmax] {
            if !v.is_finite() {
                return Err(SceneError::Invalid(format!(
                    "compressed PLY: chunk {c} has non-finite values"
                )));
            }
        }
        for v in [
            pmin.x, pmin.y, pmin.z, pmax.x, pmax.y, pmax.z, smin.x, smin.y, smin.z,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in [
            smax.x, smax.y, smax.z, cmin.x, cmin.y, cmin.z, cmax.x, cmax.y, cmax.z,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        all_bounds.push([pmin, pmax, smin, smax, cmin, cmax]);
    }
    for i in 0..n {
        let [pmin, pmax, smin, smax, cmin, cmax] = all_bounds[i / CHUNK];
        let p = cloud.means[i];
        let pos = pack_unorm(norm01(p.x, pmin.x, pmax.x), 11) << 21
            | pack_unorm(norm01(p.y, pmin.y, pmax.y), 10) << 11
            | pack_unorm(norm01(p.z, pmin.z, pmax.z), 11);
        let q = cloud.unit_rotation(i);
        let wxyz = [q.w, q.x, q.y, q.z];
        let mut largest = 0;
        for j in 1..4 {
            if wxyz[j].abs() > wxyz[largest].abs() {
                largest = j;
            }
        }
        let sign = if wxyz[largest] < 0.0 { -1.0 } else { 1.0 };
        let mut rot = largest as u32;
        for (j, &v) in wxyz.iter().enumerate() {
            if j != largest {
                let t = v * sign * std::f32::consts::FRAC_1_SQRT_2 + 0.5;
                rot = rot << 10 | pack_unorm(t, 10);
            }
        }
        let l = clamp_scale(cloud.log_scales[i]);
        let scl = pack_unorm(norm01(l.x, smin.x, smax.x), 11) << 21
            | pack_unorm(norm01(l.y, smin.y, smax.y), 10) << 11
            | pack_unorm(norm01(l.z, smin.z, smax.z), 11);
        let rgb = colour(i);
        let col = pack_unorm(norm01(rgb.x, cmin.x, cmax.x), 8) << 24
            | pack_unorm(norm01(rgb.y, cmin.y, cmax.y), 8) << 16
            | pack_unorm(norm01(rgb.z, cmin.z, cmax.z), 8) << 8
            | pack_unorm(cloud.opacity(i), 8);
        for v in [pos, rot, scl, col] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for i in 0..n {
        let sh = &cloud.sh[i * k + 1..(i + 1) * k];
        for ch in 0..3 {
            for c in sh {
                let t = c[ch] / 8.0 + 0.5;
                out.push((t * 256.0).floor().clamp(0.0, 255.0) as u8);
            }
        }
    }
    Ok(out)
}

/// Write a compressed PLY atomically.
pub fn write_compressed_ply(path: &Path, cloud: &GaussianCloud) -> Result<()> {
    let bytes = encode_compressed_ply(cloud)
        .map_err(|e| SceneError::format(path, format!("cannot write: {e}")))?;
    crate::image_io::with_atomic_writer(path, |w| w.write_all(&bytes))
}

#[cfg(test)]
mod parallel_tests {
    use super::*;

    /// The parallel chunk decode against the one-thread path, bit for bit, on a cloud that
    /// spans several chunks and a partial last one, with every SH degree.
    #[test]
    fn parallel_decode_equals_the_one_thread_decode() {
        for degree in 0..=3u8 {
            let mut c = GaussianCloud::new(degree);
            let k = c.coeffs();
            for i in 0..(3 * CHUNK + 17) {
                let f = i as f32;
                let coeffs: Vec<Vec3> = (0..k)
                    .map(|j| Vec3::new((f * 0.01).sin(), (j as f32 * 0.3).cos(), 0.2))
                    .collect();
                c.push(
                    Vec3::new(f.sin() * 3.0, f.cos(), f * 0.001),
                    Vec3::new(-3.0 - (f * 0.1).sin(), -4.0, -2.5),
                    Quat::from_xyzw(f.sin(), 0.3, f.cos(), 1.0).normalize(),
                    (f * 0.05).sin() * 3.0,
                    &coeffs,
                );
            }
            let bytes = encode_compressed_ply(&c).unwrap();
            let p = Path::new("t.compressed.ply");
            let (one, s1) = decode_with(&bytes, p, usize::MAX).unwrap();
            let (all, s2) = decode_with(&bytes, p, 0).unwrap();
            assert_eq!(s1, s2);
            let bits = |c: &GaussianCloud| {
                let mut v: Vec<u32> = Vec::new();
                for a in [&c.means, &c.log_scales, &c.sh] {
                    v.extend(a.iter().flat_map(|x| x.to_array().map(f32::to_bits)));
                }
                v.extend(
                    c.rotations
                        .iter()
                        .flat_map(|q| q.to_array().map(f32::to_bits)),
                );
                v.extend(c.opacity_logits.iter().map(|x| x.to_bits()));
                v
            };
            assert!(bits(&one) == bits(&all), "SH degree {degree}");
        }
    }
}
