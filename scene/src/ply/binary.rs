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
    let chunk_bytes =
        (n.saturating_mul(stride) / CHUNKS_PER_FILE).clamp(MIN_CHUNK_BYTES, MAX_CHUNK_BYTES);
    let per_chunk = (chunk_bytes / stride).max(1).min(n.max(1));
    let mut buf = vec![0u8; per_chunk * stride];
    if let Some(var) = &layout.variant {
        // Before the cloud is reserved here: the variant path reserves its own, and two
        // reservations held at once doubled its peak heap (2.07x the cloud, measured).
        return read_variant(r, path, header, var, layout.sh_degree, n, per_chunk, buf);
    }
    let mut cloud = GaussianCloud::with_capacity(layout.sh_degree, n);
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

/// Where canonical slots of a non-standard layout come from, resolved to the record's bytes:
/// the per-record form of `super::variant::Source`.
#[derive(Clone, Copy)]
enum Op {
    /// `len` float32 properties taken as is (`mul` 1, `add` 0: the standard path's load) into
    /// the consecutive slots from `slot`, from consecutive bytes at `off` (a run of the file's
    /// properties in slot order, as `f_rest_*` are).
    F32Run {
        slot: usize,
        off: usize,
        len: usize,
    },
    /// Any scalar at this offset, `raw · mul + add` in f64.
    Any {
        slot: usize,
        off: usize,
        ty: ScalarType,
        mul: f64,
        add: f64,
    },
    Const {
        slot: usize,
        value: f32,
    },
}

/// Non-standard layouts (see `super::variant`): each slot's source resolved once to an [`Op`]
/// on the record's bytes, then every record gathered without going through a table of all
/// its properties. [`super::variant::Variant::assemble`] (the ASCII reader's path) is the
/// reference: the tests check both give the same bits.
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
    let ops = variant_ops(header, var);
    let filter = var
        .filter_3d
        .map(|pi| (header.properties[pi].offset, header.properties[pi].ty));
    let mut cloud = GaussianCloud::with_capacity(sh_degree, n);
    let n_rest = var.slots.len() - super::header::SLOT_REST;
    let mut done = 0;
    let mut suspect = false;
    while done < n {
        let m = per_chunk.min(n - done);
        let bytes = &mut buf[..m * stride];
        read_chunk(r, bytes, path, done, m)?;
        suspect |= if le {
            decode_variant::<true>(bytes, stride, &ops, var, filter, n_rest, &mut cloud)
        } else {
            decode_variant::<false>(bytes, stride, &ops, var, filter, n_rest, &mut cloud)
        };
        done += m;
    }
    Ok((cloud, suspect))
}

/// The [`Op`]s that fill every slot, consecutive float32 loads merged into runs.
fn variant_ops(header: &Header, var: &super::variant::Variant) -> Vec<Op> {
    use super::variant::Source;
    let mut ops: Vec<Op> = Vec::new();
    for (slot, s) in var.slots.iter().enumerate() {
        let op = match *s {
            Source::Prop { pi, mul, add } => {
                let (off, ty) = (header.properties[pi].offset, header.properties[pi].ty);
                if ty == ScalarType::F32 && mul == 1.0 && add == 0.0 {
                    if let Some(Op::F32Run {
                        slot: s0,
                        off: o0,
                        len,
                    }) = ops.last_mut()
                    {
                        if *s0 + *len == slot && *o0 + 4 * *len == off {
                            *len += 1;
                            continue;
                        }
                    }
                    Op::F32Run { slot, off, len: 1 }
                } else {
                    Op::Any {
                        slot,
                        off,
                        ty,
                        mul,
                        add,
                    }
                }
            }
            Source::Const(value) => Op::Const { slot, value },
            // Derived after the other slots (`finish`).
            Source::ThinAxis => Op::Const { slot, value: 0.0 },
        };
        ops.push(op);
    }
    ops
}

/// Decode one chunk of records on all cores ([`super::append_parallel`]; the per-record work of
/// the filter fold and the widening loads is what dominates these layouts).
#[allow(clippy::too_many_arguments)]
fn decode_variant<const LE: bool>(
    bytes: &[u8],
    stride: usize,
    ops: &[Op],
    var: &super::variant::Variant,
    filter: Option<(usize, ScalarType)>,
    n_rest: usize,
    cloud: &mut GaussianCloud,
) -> bool {
    let m = bytes.len() / stride;
    super::append_parallel(cloud, m, n_rest, |j, v| {
        let rec = &bytes[j * stride..(j + 1) * stride];
        for op in ops {
            match *op {
                Op::F32Run { slot, off, len } => {
                    let src = rec[off..off + 4 * len].chunks_exact(4);
                    for (dst, b) in v[slot..slot + len].iter_mut().zip(src) {
                        let b: [u8; 4] = b.try_into().expect("4 bytes");
                        *dst = if LE {
                            f32::from_le_bytes(b)
                        } else {
                            f32::from_be_bytes(b)
                        };
                    }
                }
                Op::Any {
                    slot,
                    off,
                    ty,
                    mul,
                    add,
                } => v[slot] = (load_any(rec, off, ty, LE) * mul + add) as f32,
                Op::Const { slot, value } => v[slot] = value,
            }
        }
        var.finish(v, filter.map(|(off, ty)| load_any(rec, off, ty, LE)));
    })
}
