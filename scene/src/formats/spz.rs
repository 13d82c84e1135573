//! Niantic SPZ (nianticlabs/spz, `src/cc/load-spz.cc`): a gzip stream holding a 16-byte
//! header and the Gaussians attribute by attribute.
//!
//! Header (little endian): magic `0x5053474e` ("NGSP"), version u32, point count u32, SH
//! degree u8, fractional bits u8, flags u8 (1: antialiased, 2: extension records follow the
//! data), reserved u8. Then, each for all points in turn:
//!
//! | attribute | bytes/point | encoding |
//! |---|---|---|
//! | positions | 9 (v1: 6) | 24-bit signed fixed point, `fractional bits` after the point (v1: float16) |
//! | alphas | 1 | `sigmoid(opacity)·255` |
//! | colours | 3 | `f_dc·0.15·255 + 127.5` (a wider range than the display colour) |
//! | scales | 3 | `(log-scale + 10)·16` |
//! | rotations | 3 (v1, v2) / 4 (v3+) | v1/v2: x, y, z of the unit quaternion with w ≥ 0, `q·127.5 + 127.5`; v3: "smallest three", 2 bits for the largest component's index and 10 bits (sign + 9-bit magnitude / √½) for each other |
//! | SH | 3·((d+1)²−1) | coefficient-major RGB, `x·128 + 128`, rounded to 5 bits (degree 1) and 4 bits (higher) |
//!
//! Version 4 (nianticlabs/spz "SPZ 4", splat-transform 3.x's default) drops the gzip layer
//! for separate zstd streams per attribute plane: read and written by [`v4`].
//!
//! SPZ stores the RUB axis convention (x right, y up, z back; OpenGL, three.js),
//! the 3DGS PLY RDF (x right, y down, z forward): reading and writing flip y and z — positions,
//! the quaternion's y and z parts, and every SH coefficient odd in y·z ([`SH_FLIP`]) — so a
//! scene read from SPZ lines up with the PLY it came from. SH degree 4 (allowed by v3) is cut
//! to degree 3 with a warning.
//!
//! Decompression is bounded: the header is decompressed first, the payload size it implies is
//! checked against what the compressed size can hold (deflate expands at most 1032:1) before
//! anything is allocated, and the stream is read through `Read::take` with that size.

use std::io::{BufReader, Read, Write};
use std::path::Path;

use flate2::read::GzDecoder;
use flate2::write::GzEncoder;
use flate2::Compression;
use glam::{Quat, Vec3};

use super::prefetch::with_prefetch;
use super::regular_file_len;
use decode::{PlaneDecoder, PlaneError};

mod decode;
pub mod v4;

/// Said when a degree-4 file is read (the cloud keeps degrees 0–3).
const SH4_WARNING: &str = "SH degree 4 cut to degree 3 (the highest this tool renders)";
use crate::error::{Result, SceneError};
use crate::gaussians::{sh_coeffs, sigmoid};
use crate::GaussianCloud;

/// "NGSP", little endian.
pub const MAGIC: u32 = 0x5053_474e;
/// Bytes in the (pre-v4) header.
pub const HEADER: usize = 16;
/// Bytes in the version-4 header.
pub const HEADER_V4: usize = 32;
/// Version 4's bound on uncompressed/compressed size (load-spz.cc `kMaxCompressionRatio`):
/// a header claiming more data than this is refused before anything is allocated.
const MAX_ZSTD_RATIO: u64 = 1024;
/// The version [`encode_spz`] writes by default: 3, because every SPZ reader reads it —
/// readers of version 4 (nianticlabs/spz since "SPZ 4", splat-transform 3.x) read 1–3 as
/// well, while viewers built on earlier readers refuse version 4. Version 4 (zstd streams)
/// is one option away (`SpzOptions::version`, `convert --spz-version 4`) and buys little:
/// on `fourth_st` (131 k Gaussians, SH 3) 3 205 859 bytes against version 3's 3 209 111
/// (0.1 % smaller), decoded in 182 ms against 257 ms (`bench ply`, medians of 5, on a
/// machine loaded 11× its 2 cores).
pub const WRITE_VERSION: u32 = 3;
/// Deflate's largest expansion ratio (zlib technical notes: 1032:1), used to reject headers
/// that declare more data than the compressed stream could possibly hold.
const MAX_DEFLATE_RATIO: u64 = 1032;
/// Extension records after the data (flag 2) are skipped, up to this many bytes.
const MAX_EXTENSION_BYTES: u64 = 1 << 16;
/// DC colours are stored scaled by this instead of SH_C0 (load-spz.cc `colorScale`).
const COLOR_SCALE: f32 = 0.15;
const FLAG_EXTENSIONS: u8 = 2;

/// Sign of each SH coefficient (coefficient-major, after the DC term) when y and z change
/// sign: the real SH basis functions of degrees 1–3 in the 3DGS order (y, z, x; xy, yz,
/// 3z²−1, xz, x²−y²; y(3x²−y²), xyz, y(5z²−1), z(5z²−3), x(5z²−1), z(x²−y²), x(x²−3y²)).
pub const SH_FLIP: [f32; 15] = [
    -1.0, -1.0, 1.0, // degree 1
    -1.0, 1.0, 1.0, -1.0, 1.0, // degree 2
    -1.0, 1.0, -1.0, -1.0, 1.0, -1.0, 1.0, // degree 3
];

/// The axis convention of the SPZ data relative to the cloud.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpzAxes {
    /// The `.spz` file convention: RUB in the stream, the PLY's RDF in the cloud (y and z
    /// flipped on read and write).
    #[default]
    Rub,
    /// No conversion: the stream holds the cloud's own frame (`KHR_gaussian_splatting`'s SPZ
    /// variant, whose node transforms carry the axes).
    AsStored,
}

impl SpzAxes {
    fn flip(self) -> bool {
        self == SpzAxes::Rub
    }
}

/// Options for [`encode_spz`].
#[derive(Clone, Copy, Debug)]
pub struct SpzOptions {
    /// 2, 3 (the default, [`WRITE_VERSION`]) or 4 (zstd streams, [`v4`]).
    pub version: u32,
    /// Fixed-point fraction bits for positions; `None` picks 12 (1/4096 units, the reference
    /// encoder's choice) or fewer when the scene is too large for 24 bits at 12.
    pub fractional_bits: Option<u8>,
    /// Compression level 0–9: gzip's (versions 2, 3) or zstd's (version 4; 0 is zstd's
    /// default, 3).
    pub level: u32,
    /// Axis convention of the written stream.
    pub axes: SpzAxes,
}

impl Default for SpzOptions {
    fn default() -> Self {
        SpzOptions {
            version: WRITE_VERSION,
            fractional_bits: None,
            level: 6,
            axes: SpzAxes::Rub,
        }
    }
}

/// The parsed 16-byte header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpzHeader {
    pub version: u32,
    pub count: u32,
    pub sh_degree: u8,
    pub fractional_bits: u8,
    pub flags: u8,
}

impl SpzHeader {
    fn parse(b: &[u8; HEADER], path: &Path) -> Result<Self> {
        let u32_at = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        if u32_at(0) != MAGIC {
            return Err(SceneError::format(
                path,
                format!(
                    "SPZ magic is {:#010x}, expected {MAGIC:#010x} (\"NGSP\")",
                    u32_at(0)
                ),
            ));
        }
        let h = SpzHeader {
            version: u32_at(4),
            count: u32_at(8),
            sh_degree: b[12],
            fractional_bits: b[13],
            flags: b[14],
        };
        match h.version {
            1..=3 => {}
            4 => {
                return Err(SceneError::format(
                    path,
                    "SPZ version 4 inside a gzip stream (version 4 files are not gzipped)",
                ))
            }
            v => {
                return Err(SceneError::format(
                    path,
                    format!("SPZ version {v} is not one of 1, 2, 3"),
                ))
            }
        }
        if h.sh_degree > 4 {
            return Err(SceneError::format(
                path,
                format!("SPZ SH degree {} is above 4", h.sh_degree),
            ));
        }
        if h.fractional_bits > 23 {
            return Err(SceneError::format(
                path,
                format!(
                    "SPZ fractional bits {} leave no integer bits in a 24-bit position",
                    h.fractional_bits
                ),
            ));
        }
        Ok(h)
    }

    fn to_bytes(self) -> [u8; HEADER] {
        let mut b = [0u8; HEADER];
        b[0..4].copy_from_slice(&MAGIC.to_le_bytes());
        b[4..8].copy_from_slice(&self.version.to_le_bytes());
        b[8..12].copy_from_slice(&self.count.to_le_bytes());
        b[12] = self.sh_degree;
        b[13] = self.fractional_bits;
        b[14] = self.flags;
        b
    }

    fn position_bytes(&self) -> u64 {
        if self.version == 1 {
            6
        } else {
            9
        }
    }

    fn rotation_bytes(&self) -> u64 {
        if self.version >= 3 {
            4
        } else {
            3
        }
    }

    fn sh_bytes(&self) -> u64 {
        3 * (sh_coeffs(self.sh_degree) as u64 - 1)
    }

    /// Payload bytes after the header.
    pub fn payload_len(&self) -> u64 {
        let per = self.position_bytes() + 1 + 3 + 3 + self.rotation_bytes() + self.sh_bytes();
        self.count as u64 * per
    }
}

/// The version in a gzip-compressed SPZ file's header, from the first bytes of the file.
pub(crate) fn gzip_header_version(path: &Path, head: &[u8]) -> Result<u32> {
    let mut b = [0u8; 8];
    GzDecoder::new(head).read_exact(&mut b).map_err(|e| {
        SceneError::format(
            path,
            format!("gzip file whose start does not decompress: {e}"),
        )
    })?;
    let magic = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    if magic != MAGIC {
        return Err(SceneError::format(
            path,
            format!("gzip file that is not SPZ (magic {magic:#010x}, expected \"NGSP\")"),
        ));
    }
    Ok(u32::from_le_bytes([b[4], b[5], b[6], b[7]]))
}

/// Decode an SPZ stream (gzip-compressed bytes, the `.spz` file convention); `path` names the
/// source in errors.
pub fn decode_spz(bytes: &[u8], path: &Path) -> Result<GaussianCloud> {
    decode_spz_with(bytes, path, SpzAxes::Rub)
}

/// [`decode_spz`] with an explicit axis convention.
pub fn decode_spz_with(bytes: &[u8], path: &Path, axes: SpzAxes) -> Result<GaussianCloud> {
    if bytes.starts_with(&MAGIC.to_le_bytes()) {
        let len = bytes.len() as u64;
        return v4::decode_v4(std::io::Cursor::new(bytes), len, path, axes).map(|(c, _)| c);
    }
    decode_gzip(bytes, bytes.len() as u64, path, axes).map(|(c, _)| c)
}

/// Decode SPZ bytes without the gzip layer (header + attributes).
pub fn decode_spz_raw(bytes: &[u8], path: &Path) -> Result<GaussianCloud> {
    decode_spz_raw_with(bytes, path, SpzAxes::Rub)
}

/// [`decode_spz_raw`] with an explicit axis convention.
pub fn decode_spz_raw_with(bytes: &[u8], path: &Path, axes: SpzAxes) -> Result<GaussianCloud> {
    decode_stream(bytes, bytes.len() as u64, path, axes).map(|(c, _)| c)
}

/// Read an `.spz` file; also returns warnings (SH degree cut, extension records skipped).
pub fn read_spz(path: &Path) -> Result<(GaussianCloud, Vec<String>)> {
    let len = regular_file_len(path)?;
    let mut file = std::fs::File::open(path).map_err(|e| SceneError::io(path, e))?;
    let mut magic = [0u8; 4];
    let n = (&mut file)
        .take(4)
        .read(&mut magic)
        .map_err(|e| SceneError::io(path, e))?;
    if n == 4 && magic == MAGIC.to_le_bytes() {
        return v4::decode_v4(file, len, path, SpzAxes::Rub);
    }
    let file = std::fs::File::open(path).map_err(|e| SceneError::io(path, e))?;
    decode_gzip(
        BufReader::with_capacity(1 << 16, file.take(len)),
        len,
        path,
        SpzAxes::Rub,
    )
}

fn decode_gzip<R: Read + Send>(
    r: R,
    compressed_len: u64,
    path: &Path,
    axes: SpzAxes,
) -> Result<(GaussianCloud, Vec<String>)> {
    // Deflate cannot expand beyond MAX_DEFLATE_RATIO (plus the header's few bytes).
    let cap = compressed_len
        .saturating_mul(MAX_DEFLATE_RATIO)
        .saturating_add(64);
    // Inflate on one core while the planes are dequantised on the other.
    // The payload is not known before the header inside the stream; deflate typically
    // shrinks SPZ by 1.5–3×, so the compressed size decides.
    with_prefetch(GzDecoder::new(r), compressed_len, |p| {
        decode_stream(p, cap, path, axes)
    })
}

fn decode_stream<R: Read>(
    mut r: R,
    max_payload: u64,
    path: &Path,
    axes: SpzAxes,
) -> Result<(GaussianCloud, Vec<String>)> {
    let gz_err = |e: std::io::Error| -> SceneError {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            SceneError::format(
                path,
                "SPZ stream ends inside the 16-byte header (truncated)",
            )
        } else {
            SceneError::format(path, format!("SPZ stream does not decompress: {e}"))
        }
    };
    let mut hb = [0u8; HEADER];
    r.read_exact(&mut hb).map_err(gz_err)?;
    let h = SpzHeader::parse(&hb, path)?;
    let need = h.payload_len();
    if need > max_payload {
        return Err(SceneError::format(
            path,
            format!(
                "SPZ header declares {} Gaussians ({need} bytes of data) but the compressed stream can hold at most {max_payload} bytes",
                h.count
            ),
        ));
    }
    let mut dec = PlaneDecoder::new(&h, axes.flip()).map_err(|_| {
        SceneError::format(
            path,
            format!("cannot allocate the arrays of {} Gaussians", h.count),
        )
    })?;
    for p in 0..decode::PLANES {
        match dec.read_plane(p, &mut r) {
            Ok(()) => {}
            Err(PlaneError::Short) => {
                return Err(SceneError::format(
                    path,
                    format!(
                        "SPZ header declares {} Gaussians ({need} bytes of data) but the stream holds only {} (truncated, or the count is wrong)",
                        h.count, dec.got
                    ),
                ))
            }
            Err(PlaneError::Io(e)) => {
                return Err(SceneError::format(
                    path,
                    format!("SPZ stream does not decompress: {e}"),
                ))
            }
        }
    }
    // What follows the data: nothing, or extension records when flag 2 says so. Reading on
    // also makes the gzip layer check its CRC and length.
    let mut warnings = Vec::new();
    let allowed = if h.flags & FLAG_EXTENSIONS != 0 {
        MAX_EXTENSION_BYTES
    } else {
        0
    };
    let mut rest = Vec::new();
    (&mut r)
        .take(allowed + 1)
        .read_to_end(&mut rest)
        .map_err(|e| {
            SceneError::format(path, format!("SPZ stream is corrupt after the data: {e}"))
        })?;
    if rest.len() as u64 > allowed {
        return Err(SceneError::format(
            path,
            format!(
                "SPZ stream holds more data than the header's {} Gaussians need (the count disagrees with the data)",
                h.count
            ),
        ));
    }
    if !rest.is_empty() {
        warnings.push(format!(
            "{} bytes of SPZ extension records skipped",
            rest.len()
        ));
    }
    if h.sh_degree > 3 {
        warnings.push(SH4_WARNING.into());
    }
    Ok((dec.finish(), warnings))
}

/// float16 → f32 (SPZ v1 positions).
fn half_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as i32;
    let man = (h & 0x3ff) as f32;
    match exp {
        0 => sign * man * (2.0f32).powi(-24),
        31 if man == 0.0 => sign * f32::INFINITY,
        31 => f32::NAN,
        e => sign * (1.0 + man / 1024.0) * (2.0f32).powi(e - 15),
    }
}

/// Turn a cloud half a turn about x (y and z negated: positions, the quaternions' y and z
/// parts, the SH coefficients odd in y·z): the RUB ↔ RDF conversion applied on SPZ IO, for
/// comparing with tools that skip it (splat-transform reads and writes SPZ data unconverted).
pub fn flip_yz(cloud: &mut GaussianCloud) {
    let k = cloud.coeffs();
    for m in &mut cloud.means {
        *m = Vec3::new(m.x, -m.y, -m.z);
    }
    for q in &mut cloud.rotations {
        *q = Quat::from_xyzw(q.x, -q.y, -q.z, q.w);
    }
    for i in 0..cloud.len() {
        for (j, c) in cloud.sh[i * k + 1..(i + 1) * k].iter_mut().enumerate() {
            *c *= SH_FLIP[j];
        }
    }
}

/// Decode v3's "smallest three" quaternion to x, y, z, w.
fn unpack_smallest_three(mut comp: u32) -> [f32; 4] {
    const MASK: u32 = (1 << 9) - 1;
    let largest = (comp >> 30) as usize;
    let mut q = [0.0f32; 4];
    let mut sum = 0.0;
    for i in (0..4).rev() {
        if i == largest {
            continue;
        }
        let mag = comp & MASK;
        let neg = (comp >> 9) & 1;
        comp >>= 10;
        let v = std::f32::consts::FRAC_1_SQRT_2 * mag as f32 / MASK as f32;
        q[i] = if neg == 1 { -v } else { v };
        sum += q[i] * q[i];
    }
    q[largest] = (1.0 - sum).max(0.0).sqrt();
    q
}

/// Encode x, y, z, w (unit) as v3's "smallest three".
fn pack_smallest_three(q: [f32; 4]) -> u32 {
    let mut largest = 0;
    for i in 1..4 {
        if q[i].abs() > q[largest].abs() {
            largest = i;
        }
    }
    let negate = q[largest] < 0.0;
    let mut comp = largest as u32;
    for (i, &c) in q.iter().enumerate() {
        if i == largest {
            continue;
        }
        let neg = ((c < 0.0) ^ negate) as u32;
        let mag =
            (((1u32 << 9) - 1) as f32 * (c.abs() / std::f32::consts::FRAC_1_SQRT_2) + 0.5) as u32;
        comp = (comp << 10) | (neg << 9) | mag.min(511);
    }
    comp
}

fn to_u8(x: f32) -> u8 {
    x.round().clamp(0.0, 255.0) as u8
}

/// SH quantisation of load-spz.cc: 8 bits around 128, rounded to buckets of `bucket` steps.
fn quantize_sh(x: f32, bucket: i32) -> u8 {
    let q = (x * 128.0).round() as i32 + 128;
    let q = (q + bucket / 2) / bucket * bucket;
    q.clamp(0, 255) as u8
}

/// The fraction bits to use for a cloud's positions (see [`SpzOptions::fractional_bits`]).
fn pick_fractional_bits(cloud: &GaussianCloud, opts: &SpzOptions) -> Result<u8> {
    let max = cloud
        .means
        .iter()
        .map(|m| m.abs().max_element())
        .fold(0.0f32, f32::max);
    let limit = ((1 << 23) - 1) as f32;
    if let Some(fb) = opts.fractional_bits {
        if fb > 23 || max * (1u32 << fb) as f32 > limit {
            return Err(SceneError::Invalid(format!(
                "SPZ: positions up to {max} do not fit 24 bits with {fb} fraction bits"
            )));
        }
        return Ok(fb);
    }
    (0..=12u8)
        .rev()
        .find(|&fb| max * (1u32 << fb) as f32 <= limit)
        .ok_or_else(|| {
            SceneError::Invalid(format!(
                "SPZ: positions up to {max} are beyond the 24-bit fixed-point range (±8388607)"
            ))
        })
}

/// Encode a cloud as SPZ bytes without the gzip layer.
pub fn encode_spz_raw(cloud: &GaussianCloud, opts: &SpzOptions) -> Result<Vec<u8>> {
    cloud.check_shape()?;
    if !(2..=3).contains(&opts.version) {
        return Err(SceneError::Invalid(format!(
            "SPZ: the uncompressed stream of versions 2 and 3 is written, not version {} (version 4 is written by encode_spz)",
            opts.version
        )));
    }
    let n = u32::try_from(cloud.len())
        .map_err(|_| SceneError::Invalid("SPZ: more than 2^32 Gaussians".into()))?;
    let fb = pick_fractional_bits(cloud, opts)?;
    let h = SpzHeader {
        version: opts.version,
        count: n,
        sh_degree: cloud.sh_degree,
        fractional_bits: fb,
        flags: 0,
    };
    let n = cloud.len();
    let mut out = Vec::with_capacity(HEADER + h.payload_len() as usize);
    out.extend_from_slice(&h.to_bytes());
    let scale = (1u32 << fb) as f32;
    let flip = opts.axes.flip();
    let f = if flip { -1.0 } else { 1.0 };
    for m in &cloud.means {
        for v in [m.x, f * m.y, f * m.z] {
            let fixed = (v * scale).round() as i32;
            out.extend_from_slice(&fixed.to_le_bytes()[..3]);
        }
    }
    out.extend(
        cloud
            .opacity_logits
            .iter()
            .map(|&o| to_u8(sigmoid(o) * 255.0)),
    );
    let k = cloud.coeffs();
    for i in 0..n {
        let dc = cloud.sh[i * k];
        for c in [dc.x, dc.y, dc.z] {
            out.push(to_u8(c * (COLOR_SCALE * 255.0) + 0.5 * 255.0));
        }
    }
    for l in &cloud.log_scales {
        for c in [l.x, l.y, l.z] {
            out.push(to_u8((c + 10.0) * 16.0));
        }
    }
    for i in 0..n {
        let u = cloud.unit_rotation(i);
        // RDF → RUB, x, y, z, w order as in load-spz.cc.
        let q = [u.x, f * u.y, f * u.z, u.w];
        if opts.version >= 3 {
            out.extend_from_slice(&pack_smallest_three(q).to_le_bytes());
        } else {
            let s = if q[3] < 0.0 { -127.5 } else { 127.5 };
            for c in &q[..3] {
                out.push(to_u8(c * s + 127.5));
            }
        }
    }
    for i in 0..n {
        for (j, c) in cloud.sh[i * k + 1..(i + 1) * k].iter().enumerate() {
            // 5 bits for degree 1, 4 bits beyond (the reference encoder's defaults).
            let bucket = if j < 3 { 8 } else { 16 };
            let c = if flip { *c * SH_FLIP[j] } else { *c };
            for v in [c.x, c.y, c.z] {
                out.push(quantize_sh(v, bucket));
            }
        }
    }
    debug_assert_eq!(out.len() as u64, HEADER as u64 + h.payload_len());
    Ok(out)
}

/// Encode a cloud as an `.spz` file's bytes: a gzip-compressed stream (versions 2, 3) or
/// version 4's zstd streams.
pub fn encode_spz(cloud: &GaussianCloud, opts: &SpzOptions) -> Result<Vec<u8>> {
    if opts.version == 4 {
        return v4::encode_v4(cloud, opts);
    }
    let raw = encode_spz_raw(cloud, opts)?;
    let mut enc = GzEncoder::new(
        Vec::with_capacity(raw.len() / 3),
        Compression::new(opts.level.min(9)),
    );
    enc.write_all(&raw)
        .and_then(|_| enc.finish())
        .map_err(|e| SceneError::Invalid(format!("SPZ: gzip failed: {e}")))
}

/// Write an `.spz` file atomically.
pub fn write_spz(path: &Path, cloud: &GaussianCloud, opts: &SpzOptions) -> Result<()> {
    let bytes = encode_spz(cloud, opts)
        .map_err(|e| SceneError::format(path, format!("cannot write: {e}")))?;
    crate::image_io::with_atomic_writer(path, |w| w.write_all(&bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_floats_decode() {
        assert_eq!(half_to_f32(0x3c00), 1.0);
        assert_eq!(half_to_f32(0xc000), -2.0);
        assert_eq!(half_to_f32(0x3555), 0.333_251_95);
        assert_eq!(half_to_f32(0x0001), 2.0f32.powi(-24));
        assert_eq!(half_to_f32(0x7c00), f32::INFINITY);
    }

    #[test]
    fn smallest_three_round_trip_every_largest_index() {
        // The largest component in each position in turn, with mixed signs.
        for q in [
            [0.9f32, 0.3, -0.2, 0.1],
            [0.1, -0.8, 0.4, 0.2],
            [-0.3, 0.2, 0.85, -0.1],
            [0.2, -0.1, 0.3, -0.9],
        ] {
            let n = (q.iter().map(|c| c * c).sum::<f32>()).sqrt();
            let q = q.map(|c| c / n);
            let d = unpack_smallest_three(pack_smallest_three(q));
            // Same rotation up to sign; 9-bit magnitudes over [0, 1/√2] give steps of 1.4e-3.
            let s = if (0..4).map(|i| q[i] * d[i]).sum::<f32>() < 0.0 {
                -1.0
            } else {
                1.0
            };
            for i in 0..4 {
                assert!((q[i] - s * d[i]).abs() < 2e-3, "{q:?} -> {d:?}");
            }
        }
    }

    #[test]
    fn sh_bucket_rounding_matches_reference_examples() {
        // x·128 + 128, then to the nearest multiple of the bucket (half rounds up).
        assert_eq!(quantize_sh(0.5, 16), 192);
        assert_eq!(quantize_sh(3.0 / 128.0, 8), 128);
        assert_eq!(quantize_sh(4.0 / 128.0, 8), 136);
        assert_eq!(quantize_sh(-5.0, 16), 0);
        assert_eq!(quantize_sh(5.0, 16), 255);
    }
}
