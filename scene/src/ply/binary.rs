//! Binary (little- and big-endian) vertex data: read in chunks of whole records straight into
//! the cloud's arrays, so the file is never held in memory next to the cloud.

use std::io::Read;
use std::path::Path;

use super::header::{Encoding, Header, Layout, ScalarType, MAX_SLOTS};
use super::push_slots;
use crate::error::{Result, SceneError};
use crate::GaussianCloud;

/// Largest chunk read at once: big enough that the per-read cost vanishes.
const MAX_CHUNK_BYTES: usize = 4 << 20;
/// Smallest chunk, so tiny files are not read a few bytes at a time.
const MIN_CHUNK_BYTES: usize = 64 << 10;
/// The chunk is at most this fraction of the data, so the buffer stays small next to the
/// cloud (peak memory = cloud + one chunk) for small files too.
const CHUNKS_PER_FILE: usize = 16;

/// Decode `n` records (the size check against the file has been done by the caller). The flag
/// is true when some record may be invalid (see `push_slots`).
pub(crate) fn read_binary(
    r: &mut impl Read,
    path: &Path,
    header: &Header,
    layout: &Layout,
    n: usize,
) -> Result<(GaussianCloud, bool)> {
    let stride = header.stride;
    let mut cloud = GaussianCloud::with_capacity(layout.sh_degree, n);
    let chunk_bytes =
        (n.saturating_mul(stride) / CHUNKS_PER_FILE).clamp(MIN_CHUNK_BYTES, MAX_CHUNK_BYTES);
    let per_chunk = (chunk_bytes / stride).max(1).min(n.max(1));
    let mut buf = vec![0u8; per_chunk * stride];
    if let Some(var) = &layout.variant {
        return read_variant(r, path, header, var, layout.sh_degree, n, per_chunk, buf);
    }
    let slots: Vec<(usize, ScalarType)> =
        layout.slots.iter().map(|&(off, _, ty)| (off, ty)).collect();
    let all_f32 = slots.iter().all(|&(_, ty)| ty == ScalarType::F32);
    let n_rest = slots.len() - super::header::SLOT_REST;
    let mut done = 0;
    let mut suspect = false;
    while done < n {
        let m = per_chunk.min(n - done);
        let bytes = &mut buf[..m * stride];
        read_chunk(r, bytes, path, done, m)?;
        suspect |= match (header.encoding, all_f32) {
            (Encoding::BinaryLe, true) => {
                decode::<true, true>(bytes, stride, &slots, n_rest, &mut cloud)
            }
            (Encoding::BinaryLe, false) => {
                decode::<true, false>(bytes, stride, &slots, n_rest, &mut cloud)
            }
            (Encoding::BinaryBe, true) => {
                decode::<false, true>(bytes, stride, &slots, n_rest, &mut cloud)
            }
            (Encoding::BinaryBe, false) => {
                decode::<false, false>(bytes, stride, &slots, n_rest, &mut cloud)
            }
            (Encoding::Ascii, _) => unreachable!("ASCII data is read by the ascii module"),
        };
        done += m;
    }
    Ok((cloud, suspect))
}

#[inline(always)]
fn load_f32<const LE: bool>(rec: &[u8], off: usize) -> f32 {
    let b: [u8; 4] = rec[off..off + 4].try_into().expect("4 bytes");
    if LE {
        f32::from_le_bytes(b)
    } else {
        f32::from_be_bytes(b)
    }
}

#[inline(always)]
fn load_f64<const LE: bool>(rec: &[u8], off: usize) -> f64 {
    let b: [u8; 8] = rec[off..off + 8].try_into().expect("8 bytes");
    if LE {
        f64::from_le_bytes(b)
    } else {
        f64::from_be_bytes(b)
    }
}

/// Gather every record's slots and append them. `ALL_F32` is the fast path for files whose
/// used properties are all float32 (every trained 3DGS file): no per-value type dispatch.
fn decode<const LE: bool, const ALL_F32: bool>(
    bytes: &[u8],
    stride: usize,
    slots: &[(usize, ScalarType)],
    n_rest: usize,
    cloud: &mut GaussianCloud,
) -> bool {
    let mut suspect = false;
    let mut v = [0f32; MAX_SLOTS];
    for rec in bytes.chunks_exact(stride) {
        for (dst, &(off, ty)) in v.iter_mut().zip(slots) {
            *dst = if ALL_F32 || ty == ScalarType::F32 {
                load_f32::<LE>(rec, off)
            } else {
                // Layout validation admits only float and double for used slots.
                load_f64::<LE>(rec, off) as f32
            };
        }
        suspect |= push_slots(cloud, &v, n_rest);
    }
    suspect
}

fn read_chunk(
    r: &mut impl Read,
    bytes: &mut [u8],
    path: &Path,
    done: usize,
    m: usize,
) -> Result<()> {
    r.read_exact(bytes).map_err(|e| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            SceneError::format(
                path,
                format!(
                    "vertex data ends inside vertices {done}..{} (the file shrank while being read?)",
                    done + m
                ),
            )
        } else {
            SceneError::io(path, e)
        }
    })
}

/// One scalar of any PLY type, widened to f64.
#[inline]
fn load_any(rec: &[u8], off: usize, ty: ScalarType, le: bool) -> f64 {
    macro_rules! get {
        ($t:ty, $n:expr) => {{
            let b: [u8; $n] = rec[off..off + $n].try_into().expect("sized");
            if le {
                <$t>::from_le_bytes(b) as f64
            } else {
                <$t>::from_be_bytes(b) as f64
            }
        }};
    }
    match ty {
        ScalarType::I8 => rec[off] as i8 as f64,
        ScalarType::U8 => rec[off] as f64,
        ScalarType::I16 => get!(i16, 2),
        ScalarType::U16 => get!(u16, 2),
        ScalarType::I32 => get!(i32, 4),
        ScalarType::U32 => get!(u32, 4),
        ScalarType::F32 => get!(f32, 4),
        ScalarType::F64 => get!(f64, 8),
    }
}

/// The general path for non-standard layouts (see `super::variant`): every used property is
/// widened to f64 and the record assembled from them. Not the trained-3DGS hot path, so it
/// trades the fast path's specialisation for one loop that handles every layout.
#[allow(clippy::too_many_arguments)]
fn read_variant(
    r: &mut impl Read,
    path: &Path,
    header: &Header,
    var: &super::variant::Variant,
    sh_degree: u8,
    n: usize,
    per_chunk: usize,
    mut buf: Vec<u8>,
) -> Result<(GaussianCloud, bool)> {
    let stride = header.stride;
    let le = header.encoding == Encoding::BinaryLe;
    let mut cloud = GaussianCloud::with_capacity(sh_degree, n);
    let n_rest = var.slots.len() - super::header::SLOT_REST;
    let mut raw = vec![0f64; header.properties.len()];
    let mut v = [0f32; MAX_SLOTS];
    let mut done = 0;
    let mut suspect = false;
    while done < n {
        let m = per_chunk.min(n - done);
        let bytes = &mut buf[..m * stride];
        read_chunk(r, bytes, path, done, m)?;
        for rec in bytes.chunks_exact(stride) {
            for &(pi, off, ty) in &var.props {
                raw[pi] = load_any(rec, off, ty, le);
            }
            var.assemble(&raw, &mut v);
            suspect |= push_slots(&mut cloud, &v, n_rest);
        }
        done += m;
    }
    Ok((cloud, suspect))
}
