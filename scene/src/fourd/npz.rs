//! Dynamic3DGaussians (Luiten et al., 3DV 2024) `params.npz`: per-time Gaussians with a fixed
//! count and order, as `helpers.py::save_params` writes them with `np.savez` — the arrays that
//! change with time stacked over timesteps, the others from the first timestep:
//!
//! | array | shape | use (`visualize.py::load_scene_data`) |
//! |---|---|---|
//! | `means3D` | T×N×3 | means at timestep t |
//! | `unnorm_rotations` | T×N×4 | `F.normalize(q[t])`, w,x,y,z |
//! | `rgb_colors` | T×N×3 (or N×3) | `colors_precomp`: the rendered RGB |
//! | `log_scales` | N×3 (or N×1, isotropic) | `exp` |
//! | `logit_opacities` | N×1 (or N) | `sigmoid` |
//! | `seg_colors` | N×3 | segmentation display only; not read |
//!
//! Timestep i is shown at `i/fps` (the viewer plays them at a fixed rate; `--fps`).
//!
//! NumPy's container is a zip of `.npy` files; entries are read through the workspace's `zip`
//! crate (the one the SOG reader uses) and the `.npy` header (magic, version, a Python dict
//! literal with `descr`, `fortran_order`, `shape`) is parsed here. The `npyz` and
//! `ndarray-npy` crates were considered: both bring a second `zip` major version (and
//! `ndarray`, or a Python-literal parser built on `pest`), and neither bounds an allocation by
//! the entry's size before making it (npyz allocates the header length a file declares), which
//! this reader must guarantee; the three dtypes used here (`f2`, `f4`, `f8`, either byte
//! order, C order) need a few dozen lines. Every declared size is checked: an entry's inflated
//! size against its stored size (deflate cannot exceed 1032:1) and the header's shape against
//! the bytes that follow it.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

use glam::{Quat, Vec3};

use crate::error::{Result, SceneError};
use crate::GaussianCloud;

/// Per-frame arrays of a `params.npz`, in memory.
#[derive(Clone, Debug, Default)]
pub struct FrameArrays {
    pub frames: usize,
    pub count: usize,
    /// `frames × count`, frame-major.
    pub means: Vec<Vec3>,
    /// `frames × count`, raw w,x,y,z.
    pub rotations: Vec<Quat>,
    /// RGB, `frames × count` (or `count` when constant).
    pub colors: Vec<Vec3>,
    pub log_scales: Vec<Vec3>,
    pub opacity_logits: Vec<f32>,
}

impl FrameArrays {
    /// Frame `i` (clamped) as a cloud.
    pub fn frame(&self, i: usize) -> GaussianCloud {
        let n = self.count;
        let i = i.min(self.frames.saturating_sub(1));
        let at = i * n;
        let mut c = GaussianCloud::with_capacity(0, n);
        c.means.extend_from_slice(&self.means[at..at + n]);
        c.rotations.extend_from_slice(&self.rotations[at..at + n]);
        let colors = if self.colors.len() == n {
            &self.colors[..]
        } else {
            &self.colors[at..at + n]
        };
        c.sh.extend(colors.iter().map(|&rgb| super::rgb_to_dc(rgb)));
        c.log_scales.extend_from_slice(&self.log_scales);
        c.opacity_logits.extend_from_slice(&self.opacity_logits);
        c
    }
}

/// Does a zip's first local header name a `.npy` entry (what `np.savez` writes)?
pub fn plausible(head: &[u8]) -> bool {
    if !head.starts_with(b"PK\x03\x04") || head.len() < 30 {
        return false;
    }
    let name_len = u16::from_le_bytes([head[26], head[27]]) as usize;
    head.get(30..30 + name_len)
        .is_some_and(|n| n.ends_with(b".npy"))
}

/// An array read from a `.npy` entry: shape and values as f32.
pub(crate) struct Array {
    pub shape: Vec<u64>,
    pub data: Vec<f32>,
}

/// Read a Dynamic3DGaussians `params.npz` whole (every timestep held: T×N×7 f32 and more).
/// [`super::load`] reads per frame instead ([`super::npz_frames::NpzFrames`]); this reader is
/// kept as the reference the per-frame reader is tested against.
pub fn read_params_npz(path: &Path) -> Result<FrameArrays> {
    let err = |what: String| SceneError::format(path, what);
    super::super::formats::regular_file_len(path)?;
    let file = File::open(path).map_err(|e| SceneError::io(path, e))?;
    let mut zip = zip::ZipArchive::new(BufReader::new(file))
        .map_err(|e| err(format!("not a readable .npz (zip): {e}")))?;
    let means = read_array(&mut zip, path, "means3D")?;
    let (t, n) = match means.shape[..] {
        [t, n, 3] => (t as usize, n as usize),
        _ => return Err(shape_err(path, "means3D", &means.shape, "T×N×3")),
    };
    if t == 0 {
        return Err(err("means3D has no timesteps".into()));
    }
    let rots = read_array(&mut zip, path, "unnorm_rotations")?;
    if rots.shape[..] != [t as u64, n as u64, 4] {
        return Err(shape_err(
            path,
            "unnorm_rotations",
            &rots.shape,
            &format!("{t}×{n}×4"),
        ));
    }
    let colors = read_array(&mut zip, path, "rgb_colors")?;
    let per_frame = match colors.shape[..] {
        [a, b, 3] if a == t as u64 && b == n as u64 => true,
        [b, 3] if b == n as u64 => false,
        _ => {
            return Err(shape_err(
                path,
                "rgb_colors",
                &colors.shape,
                &format!("{t}×{n}×3 or {n}×3"),
            ))
        }
    };
    let scales = read_array(&mut zip, path, "log_scales")?;
    let iso = match scales.shape[..] {
        [b, 3] if b == n as u64 => false,
        [b, 1] if b == n as u64 => true,
        _ => {
            return Err(shape_err(
                path,
                "log_scales",
                &scales.shape,
                &format!("{n}×3 or {n}×1"),
            ))
        }
    };
    let opac = read_array(&mut zip, path, "logit_opacities")?;
    if !(opac.shape[..] == [n as u64, 1] || opac.shape[..] == [n as u64]) {
        return Err(shape_err(
            path,
            "logit_opacities",
            &opac.shape,
            &format!("{n}×1"),
        ));
    }
    let finite = |name: &str, d: &[f32]| match d.iter().position(|v| !v.is_finite()) {
        Some(k) => Err(err(format!("{name}: value {k} is {} (not finite)", d[k]))),
        None => Ok(()),
    };
    finite("means3D", &means.data)?;
    finite("unnorm_rotations", &rots.data)?;
    finite("rgb_colors", &colors.data)?;
    finite("log_scales", &scales.data)?;
    // Opacity logits may be ±inf (fully transparent or opaque), not NaN.
    if let Some(k) = opac.data.iter().position(|v| v.is_nan()) {
        return Err(err(format!("logit_opacities: value {k} is NaN")));
    }
    let v3 = |d: &[f32]| -> Vec<Vec3> { d.chunks_exact(3).map(Vec3::from_slice).collect() };
    let rotations: Vec<Quat> = rots
        .data
        .chunks_exact(4)
        .map(|q| Quat::from_xyzw(q[1], q[2], q[3], q[0]))
        .collect();
    if let Some(k) = rotations.iter().position(|q| q.length_squared() == 0.0) {
        return Err(err(format!(
            "unnorm_rotations: quaternion {} of timestep {} is zero",
            k % n.max(1),
            k / n.max(1)
        )));
    }
    debug_assert!(per_frame == (colors.data.len() == 3 * t * n));
    Ok(FrameArrays {
        frames: t,
        count: n,
        means: v3(&means.data),
        rotations,
        colors: v3(&colors.data),
        log_scales: if iso {
            scales.data.iter().map(|&s| Vec3::splat(s)).collect()
        } else {
            v3(&scales.data)
        },
        opacity_logits: opac.data,
    })
}

pub(crate) fn shape_err(path: &Path, name: &str, shape: &[u64], want: &str) -> SceneError {
    let got: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    SceneError::format(
        path,
        format!("{name} has shape ({}), expected {want}", got.join(", ")),
    )
}

/// Deflate's largest expansion (a 258-byte match in about two bits): a declared inflated size
/// beyond this ratio to the stored size is a lie.
pub(crate) const DEFLATE_MAX_RATIO: u64 = 1032;

pub(crate) fn read_array(
    zip: &mut zip::ZipArchive<BufReader<File>>,
    path: &Path,
    name: &str,
) -> Result<Array> {
    let err = |what: String| SceneError::format(path, format!("{name}: {what}"));
    let entry_name = format!("{name}.npy");
    let entry = zip
        .by_name(&entry_name)
        .map_err(|e| err(format!("no entry {entry_name} in the .npz ({e})")))?;
    let stored = entry.compressed_size();
    let declared = entry.size();
    let cap = if entry.compression() == zip::CompressionMethod::Stored {
        stored
    } else {
        stored.saturating_mul(DEFLATE_MAX_RATIO)
    };
    if declared > cap {
        return Err(err(format!(
            "entry declares {declared} bytes from {stored} stored bytes (impossible)"
        )));
    }
    let mut bytes = Vec::with_capacity(declared as usize);
    entry
        .take(declared + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| err(format!("entry unreadable: {e}")))?;
    if bytes.len() as u64 != declared {
        return Err(err(format!(
            "entry holds {} bytes, its zip header says {declared}",
            bytes.len()
        )));
    }
    parse_npy(&bytes).map_err(err)
}

/// A `.npy` header: the shape, the value type and where the values start.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct NpyHeader {
    pub shape: Vec<u64>,
    pub dtype: Dtype,
    /// Bytes before the values (magic, version, length, dict).
    pub data_start: usize,
}

/// A float value type of a `.npy` (`f2`, `f4`, `f8`, either byte order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Dtype {
    pub size: u64,
    pub little: bool,
}

impl NpyHeader {
    /// Values in the array (the product of the shape; `None` on overflow).
    pub fn count(&self) -> Option<u64> {
        self.shape.iter().try_fold(1u64, |a, &d| a.checked_mul(d))
    }
}

/// The most header bytes a `.npy` can need before its values: version 1's 10-byte preamble
/// with a u16 length, or 12 bytes with a u32 length (versions 2–3). A header longer than
/// this is refused (NumPy's are a few hundred bytes; this bounds what a reader buffers).
pub(crate) const MAX_NPY_HEADER: usize = 1 << 16;

/// Parse a `.npy` header from the first bytes of an entry (`b` may hold more or, for a
/// streamed entry, only the first [`MAX_NPY_HEADER`] bytes).
pub(crate) fn parse_npy_header(b: &[u8]) -> std::result::Result<NpyHeader, String> {
    if b.len() < 10 || &b[..6] != b"\x93NUMPY" {
        return Err("not a .npy array (no \\x93NUMPY magic)".into());
    }
    let (hlen, start): (usize, usize) = match b[6] {
        1 => (u16::from_le_bytes([b[8], b[9]]) as usize, 10),
        2 | 3 if b.len() >= 12 => (u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize, 12),
        v => return Err(format!(".npy version {v} is not supported (1–3 are)")),
    };
    let header = b.get(start..start.saturating_add(hlen)).ok_or_else(|| {
        format!(
            ".npy header of {hlen} bytes runs past the entry's {} bytes",
            b.len()
        )
    })?;
    let header = std::str::from_utf8(header).map_err(|_| ".npy header is not text".to_string())?;
    let descr = dict_value(header, "descr").ok_or(".npy header has no 'descr'")?;
    let descr = descr.trim_matches(|c| c == '\'' || c == '"');
    let fortran =
        dict_value(header, "fortran_order").ok_or(".npy header has no 'fortran_order'")?;
    if fortran.trim() != "False" {
        return Err("Fortran-order arrays are not supported (np.savez writes C order)".into());
    }
    let shape = dict_value(header, "shape").ok_or(".npy header has no 'shape'")?;
    let shape: Vec<u64> = shape
        .trim()
        .trim_start_matches('(')
        .trim_end_matches(')')
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<u64>()
                .map_err(|_| format!("shape entry '{s}' is not a size"))
        })
        .collect::<std::result::Result<_, _>>()?;
    let (size, little) = match descr {
        "<f4" | "=f4" => (4, true),
        ">f4" => (4, false),
        "<f8" | "=f8" => (8, true),
        ">f8" => (8, false),
        "<f2" | "=f2" => (2, true),
        ">f2" => (2, false),
        other => return Err(format!("dtype '{other}' is not a float array")),
    };
    Ok(NpyHeader {
        shape,
        dtype: Dtype { size, little },
        data_start: start + hlen,
    })
}

/// The check every reader makes: the shape's values fill exactly the `data_len` bytes after
/// the header.
pub(crate) fn check_npy_len(h: &NpyHeader, data_len: u64) -> std::result::Result<(), String> {
    let count = h.count().ok_or("shape overflows")?;
    let size = h.dtype.size;
    if count.checked_mul(size) != Some(data_len) {
        return Err(format!(
            "shape {:?} of {size}-byte values needs {} bytes, the entry holds {data_len}",
            h.shape,
            count.saturating_mul(size),
        ));
    }
    Ok(())
}

/// Decode values of `dtype` to f32 (appended to `out`).
pub(crate) fn decode_values(data: &[u8], dtype: Dtype, out: &mut Vec<f32>) {
    match (dtype.size, dtype.little) {
        (4, true) => out.extend(
            data.chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap())),
        ),
        (4, false) => out.extend(
            data.chunks_exact(4)
                .map(|c| f32::from_be_bytes(c.try_into().unwrap())),
        ),
        (8, true) => out.extend(
            data.chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()) as f32),
        ),
        (8, false) => out.extend(
            data.chunks_exact(8)
                .map(|c| f64::from_be_bytes(c.try_into().unwrap()) as f32),
        ),
        (_, true) => out.extend(
            data.chunks_exact(2)
                .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32()),
        ),
        (_, false) => out.extend(
            data.chunks_exact(2)
                .map(|c| half::f16::from_be_bytes([c[0], c[1]]).to_f32()),
        ),
    }
}

/// Parse a whole `.npy` (header and data) into f32 values.
fn parse_npy(b: &[u8]) -> std::result::Result<Array, String> {
    let h = parse_npy_header(b)?;
    let data = &b[h.data_start..];
    check_npy_len(&h, data.len() as u64)?;
    let mut values = Vec::with_capacity(data.len() / h.dtype.size as usize);
    decode_values(data, h.dtype, &mut values);
    Ok(Array {
        shape: h.shape,
        data: values,
    })
}

/// The text of a key's value in the header's dict literal: up to the next top-level comma
/// (a tuple's commas are inside parentheses).
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let at = header
        .find(&format!("'{key}'"))
        .or_else(|| header.find(&format!("\"{key}\"")))?;
    let rest = &header[at + key.len() + 2..];
    let rest = rest.trim_start().strip_prefix(':')?.trim_start();
    let mut depth = 0i32;
    for (i, c) in rest.char_indices() {
        match c {
            '(' => depth += 1,
            ')' => {
                depth -= 1;
                if depth == 0 {
                    return Some(&rest[..=i]);
                }
            }
            ',' | '}' if depth == 0 => return Some(&rest[..i]),
            _ => {}
        }
    }
    None
}
