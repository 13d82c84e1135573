//! SPZ version 4 (nianticlabs/spz "SPZ 4"; what splat-transform 3.x writes by default):
//! an uncompressed 32-byte header (the version-3 fields, then u8 stream count, u32 offset of
//! the table of contents, 12 reserved bytes), optional extension records, the table of
//! contents (per stream: compressed and uncompressed size, u64 each) and the version-3
//! attribute planes (positions, alphas, colours, scales, smallest-three rotations, SH) as
//! separate zstd frames, empty planes (SH at degree 0) left out. The layout was checked
//! against splat-transform 3.7.0's output byte for byte in the header and table (see the
//! tests of `scene/tests/formats_spz_v4.rs`).
//!
//! Reading uses the reference C `libzstd` and streams each plane into the cloud; writing
//! quantises exactly as version 3 does and compresses the six planes in parallel.

use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use rayon::prelude::*;

use super::decode::{self, PlaneDecoder, PlaneError};
use super::{
    encode_spz_raw, SpzAxes, SpzHeader, SpzOptions, HEADER, HEADER_V4, MAGIC, MAX_ZSTD_RATIO,
    SH4_WARNING,
};
use crate::error::{Result, SceneError};
use crate::formats::prefetch::with_prefetch;
use crate::GaussianCloud;

/// Decode a version-4 file (uncompressed header, zstd attribute streams) of `file_len`
/// bytes from `src`: the header and table of contents are read, then each stream straight
/// from its place into the cloud, so the compressed file is never held whole.
pub(super) fn decode_v4<R: Read + Seek + Send>(
    mut src: R,
    file_len: u64,
    path: &Path,
    axes: SpzAxes,
) -> Result<(GaussianCloud, Vec<String>)> {
    let bad = |what: String| SceneError::format(path, what);
    let io_err = |e: std::io::Error| SceneError::io(path, e);
    if file_len < HEADER_V4 as u64 {
        return Err(bad(format!(
            "SPZ file of {file_len} bytes ends inside the {HEADER_V4}-byte version-4 header"
        )));
    }
    let mut bytes = [0u8; HEADER_V4];
    src.seek(SeekFrom::Start(0))
        .and_then(|_| src.read_exact(&mut bytes))
        .map_err(io_err)?;
    let version = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]);
    if version != 4 {
        return Err(bad(format!(
            "uncompressed SPZ header says version {version}; only version 4 is stored without gzip"
        )));
    }
    // The shared fields mean what they mean in version 3: parse them with its rules.
    let mut legacy = [0u8; HEADER];
    legacy.copy_from_slice(&bytes[..HEADER]);
    legacy[4..8].copy_from_slice(&3u32.to_le_bytes());
    legacy[15] = 0;
    let mut h = SpzHeader::parse(&legacy, path)?;
    h.version = 4;
    let streams = bytes[15] as usize;
    let toc = u32::from_le_bytes([bytes[16], bytes[17], bytes[18], bytes[19]]) as u64;
    let n = h.count as u64;
    let planes = [9 * n, n, 3 * n, 3 * n, 4 * n, h.sh_bytes() * n];
    let expected: Vec<u64> = planes.iter().copied().filter(|&s| s > 0).collect();
    if streams != expected.len() {
        return Err(bad(format!(
            "SPZ v4 header declares {streams} streams; {} Gaussians of SH degree {} need {}",
            h.count,
            h.sh_degree,
            expected.len()
        )));
    }
    let need = h.payload_len();
    if need > file_len.saturating_mul(MAX_ZSTD_RATIO) {
        return Err(bad(format!(
            "SPZ header declares {} Gaussians ({need} bytes of data), more than a {file_len}-byte file can hold",
            h.count
        )));
    }
    let toc_end = toc.saturating_add(16 * streams as u64);
    if toc < HEADER_V4 as u64 || toc_end > file_len {
        return Err(bad(format!(
            "SPZ v4 table of contents at byte {toc} ({streams} entries) is outside the {file_len}-byte file"
        )));
    }
    let mut warnings = Vec::new();
    if toc > HEADER_V4 as u64 {
        warnings.push(format!(
            "{} bytes of SPZ extension records skipped",
            toc - HEADER_V4 as u64
        ));
    }
    // At most 255 entries of 16 bytes.
    let mut table = vec![0u8; 16 * streams];
    src.seek(SeekFrom::Start(toc))
        .and_then(|_| src.read_exact(&mut table))
        .map_err(io_err)?;
    let u64_at = |o: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&table[o..o + 8]);
        u64::from_le_bytes(b)
    };
    let mut dec = PlaneDecoder::new(&h, axes.flip()).map_err(|_| {
        bad(format!(
            "cannot allocate the arrays of {} Gaussians",
            h.count
        ))
    })?;
    let mut at = toc_end;
    let mut k = 0;
    for p in 0..decode::PLANES {
        let want = dec.stride(p) as u64 * n;
        if want == 0 {
            continue;
        }
        let (csize, usize_) = (u64_at(16 * k), u64_at(16 * k + 8));
        if usize_ != want {
            return Err(bad(format!(
                "SPZ v4 stream {k} declares {usize_} bytes; {} Gaussians need {want}",
                h.count
            )));
        }
        let end = at
            .checked_add(csize)
            .filter(|&v| v <= file_len)
            .ok_or_else(|| {
                bad(format!(
                    "SPZ v4 stream {k} ({csize} bytes at {at}) runs past the end of the {file_len}-byte file (truncated)"
                ))
            })?;
        src.seek(SeekFrom::Start(at)).map_err(io_err)?;
        let mut stream = BufReader::with_capacity(1 << 16, (&mut src).take(csize));
        // Checked here rather than left to the decoder, whose error for a wrong magic is a
        // bare "Unknown frame descriptor".
        if !stream.fill_buf().map_err(io_err)?.starts_with(&ZSTD_MAGIC) {
            return Err(bad(format!(
                "SPZ v4 stream {k} is not zstd (no zstd frame magic)"
            )));
        }
        let mut dec_z = zstd::stream::read::Decoder::with_buffer(stream)
            .map_err(|e| bad(format!("SPZ v4 stream {k}: zstd decoder: {e}")))?;
        // A frame may declare a window of up to 2 GiB, which the decoder would allocate
        // before producing a byte (a cheap bomb). No window need exceed the plane itself.
        dec_z
            .window_log_max(window_log_for(want))
            .map_err(|e| bad(format!("SPZ v4 stream {k}: zstd decoder: {e}")))?;
        let before = dec.got;
        let short = |got: u64| {
            bad(format!(
                "SPZ v4 stream {k} decompresses to {got} bytes; {} Gaussians need {want}",
                h.count
            ))
        };
        // Decompress on one core while the plane is dequantised on the other.
        with_prefetch(dec_z, want, |z| -> Result<()> {
            match dec.read_plane(p, z) {
                Ok(()) => {}
                Err(PlaneError::Short) => return Err(short(dec.got - before)),
                Err(PlaneError::Io(e)) => {
                    return Err(bad(format!("SPZ v4 stream {k} does not decompress: {e}")))
                }
            }
            // One byte beyond the declared size is enough to tell a lying stream (a bomb).
            let mut extra = [0u8; 1];
            let more = z
                .read(&mut extra)
                .map_err(|e| bad(format!("SPZ v4 stream {k} does not decompress: {e}")))?;
            if more > 0 {
                return Err(bad(format!(
                    "SPZ v4 stream {k} decompresses to more than {want} bytes; {} Gaussians need {want}",
                    h.count
                )));
            }
            Ok(())
        })?;
        at = end;
        k += 1;
    }
    if at != file_len {
        return Err(bad(format!(
            "{} bytes after the last SPZ v4 stream",
            file_len - at
        )));
    }
    if h.sh_degree > 3 {
        warnings.push(SH4_WARNING.into());
    }
    Ok((dec.finish(), warnings))
}

/// The zstd frame magic number (RFC 8878, section 3.1.1), little-endian.
const ZSTD_MAGIC: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];

/// The largest zstd window (as log₂ bytes) accepted for a stream of `want` decompressed
/// bytes. A window never has to exceed the content, but an encoder that streams without
/// knowing the size declares its level's window (2²³ up to level 19), so that is the floor;
/// 2²⁷ (libzstd's own default limit) is the ceiling, so no file can ask for more.
fn window_log_for(want: u64) -> u32 {
    let bits = 64 - want.max(1).saturating_sub(1).leading_zeros();
    bits.clamp(23, 27)
}

/// Encode a cloud as an SPZ version-4 file's bytes. `opts.level` is the zstd level (0 is
/// zstd's default, 3; 1–9 as zstd numbers them).
pub(super) fn encode_v4(cloud: &GaussianCloud, opts: &SpzOptions) -> Result<Vec<u8>> {
    let raw = encode_spz_raw(
        cloud,
        &SpzOptions {
            version: 3,
            ..*opts
        },
    )?;
    let mut hb = [0u8; HEADER];
    hb.copy_from_slice(&raw[..HEADER]);
    let h = SpzHeader::parse(&hb, Path::new("(output)"))?;
    let n = h.count as usize;
    let sizes = [9 * n, n, 3 * n, 3 * n, 4 * n, h.sh_bytes() as usize * n];
    let mut planes = Vec::with_capacity(sizes.len());
    let mut at = HEADER;
    for s in sizes {
        if s > 0 {
            planes.push(&raw[at..at + s]);
        }
        at += s;
    }
    debug_assert_eq!(at, raw.len());
    let level = opts.level.min(9) as i32;
    let compressed = planes
        .par_iter()
        .map(|p| zstd::bulk::compress(p, level))
        .collect::<std::io::Result<Vec<Vec<u8>>>>()
        .map_err(|e| SceneError::Invalid(format!("SPZ: zstd failed: {e}")))?;
    let total: usize = compressed.iter().map(Vec::len).sum();
    let mut out = Vec::with_capacity(HEADER_V4 + 16 * planes.len() + total);
    out.extend_from_slice(&MAGIC.to_le_bytes());
    out.extend_from_slice(&4u32.to_le_bytes());
    out.extend_from_slice(&h.count.to_le_bytes());
    out.extend_from_slice(&[h.sh_degree, h.fractional_bits, h.flags, planes.len() as u8]);
    out.extend_from_slice(&(HEADER_V4 as u32).to_le_bytes());
    out.extend_from_slice(&[0u8; 12]);
    for (c, p) in compressed.iter().zip(&planes) {
        out.extend_from_slice(&(c.len() as u64).to_le_bytes());
        out.extend_from_slice(&(p.len() as u64).to_le_bytes());
    }
    for c in &compressed {
        out.extend_from_slice(c);
    }
    Ok(out)
}
