//! PLY reader and writer for the standard 3DGS layout (graphdeco-inria `gaussian-splatting`,
//! `scene/gaussian_model.py`; facts in `../shared/reference/3dgs-conventions.md`).
//!
//! # Reading
//! - Encodings: `binary_little_endian`, `binary_big_endian` and `ascii`.
//! - Properties are found by name, in any order. Required: `x y z f_dc_0..2 opacity
//!   scale_0..2 rot_0..3`; `f_rest_0..K-1` optional with K ∈ {0, 9, 24, 45}, which gives the SH
//!   degree (any other count is an error). Normals `nx ny nz` may be present or not and are not
//!   used. Used properties may be `float`/`float32` or `double`/`float64` (converted to f32);
//!   integer types on a used property are an error naming it. Other properties, of any scalar
//!   type, are ignored: listed in [`ReadReport::ignored_properties`] with one warning. Elements
//!   after `vertex` (faces, say) are ignored with a warning; `vertex` must come first.
//! - `f_rest` is channel-major in the file and is reordered once, here, to the cloud's
//!   coefficient-major layout (and back by the writer).
//! - "Activations applied on read" is realised as validation at read plus activation by the
//!   cloud's accessors: the cloud keeps the stored values (log-scales, opacity logits, raw
//!   w,x,y,z quaternions, see [`GaussianCloud`]) and [`GaussianCloud::scale`],
//!   [`GaussianCloud::opacity`] and [`GaussianCloud::unit_rotation`] apply `exp`, the sigmoid
//!   and normalisation. That keeps write→read bit-exact, and the values real files contain are
//!   handled explicitly: `±inf` opacity logits are valid (sigmoid gives exactly 1 or 0),
//!   unnormalised quaternions are valid (normalised on use), log-scales such as −23 are valid;
//!   NaN anywhere, infinite positions/log-scales/SH/rotations and zero quaternions are invalid
//!   per [`GaussianCloud::invalid_reason`]. By default the first invalid Gaussian is an error
//!   naming the file, the vertex index and the property; with [`ReadOptions::drop_invalid`]
//!   invalid Gaussians are dropped, counted by reason in [`ReadReport::dropped`] with a warning.
//! - Before anything is allocated the header's vertex count is checked against the file size
//!   (binary: count × record size must fit; ASCII: every value needs at least two bytes), so a
//!   count of 2⁴⁰ is a clean error. Binary data is read in chunks of whole records (1/16 of the
//!   data, between 64 KiB and 4 MiB) straight into the cloud's arrays (sized exactly once), so
//!   the peak memory is the cloud plus one chunk. Measured with `splatbridge bench ply`.
//!
//! - Other layouts are read too (module `variant`): `red green blue` colours instead of
//!   `f_dc_*`, 2DGS surfels (`scale_0 scale_1` only), Mip-Splatting's `filter_3D` (folded
//!   into scales and opacities) and points without Gaussian parameters (3DGS's initial
//!   Gaussians: scales from the nearest neighbours). [`ReadReport::kind`] says which.
//!
//! # Writing
//! [`write_ply`] writes the standard layout atomically; see the `write` module for details.

mod ascii;
mod binary;
pub(crate) mod header;
mod point_defaults;
mod stream;
mod surfels2d;
mod variant;
mod write;

use std::io::BufReader;
use std::path::Path;

use glam::{Quat, Vec3};

use crate::error::{Result, SceneError};
use crate::GaussianCloud;
use header::{Encoding, SLOT_DC, SLOT_OPACITY, SLOT_REST, SLOT_ROT, SLOT_SCALE, SLOT_X};
pub use stream::PlyStream;
pub use surfels2d::{flatten_to_surfels, write_ply_2dgs};
pub use variant::{GaussianKind, POINT_OPACITY, SURFEL_THICKNESS};

/// Encoding of a written PLY.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum PlyFormat {
    #[default]
    BinaryLittleEndian,
    BinaryBigEndian,
    Ascii,
}

/// How the reader treats invalid Gaussians (NaN anywhere, zero quaternion, infinite values
/// other than opacity logits).
#[derive(Clone, Copy, Debug, Default)]
pub struct ReadOptions {
    /// Drop invalid Gaussians with a counted warning instead of failing.
    pub drop_invalid: bool,
}

/// What the reader noticed besides the Gaussians.
#[derive(Clone, Debug, Default)]
pub struct ReadReport {
    /// Gaussians dropped under `drop_invalid`, by reason (the reasons of
    /// [`GaussianCloud::invalid_reason`]), sorted by reason.
    pub dropped: Vec<(String, usize)>,
    /// Properties present in the file that the reader does not use (normals excepted).
    pub ignored_properties: Vec<String>,
    /// Human-readable warnings (one line each).
    pub warnings: Vec<String>,
    /// What the vertices were: 3D Gaussians, 2DGS surfels or points (see the module docs).
    pub kind: GaussianKind,
}

impl ReadReport {
    /// Total number of dropped Gaussians.
    pub fn dropped_total(&self) -> usize {
        self.dropped.iter().map(|(_, n)| n).sum()
    }
}

/// Read a 3DGS PLY file (see the module docs for the accepted layouts and the invalid-value
/// policy).
pub fn read_ply(path: &Path, opts: &ReadOptions) -> Result<(GaussianCloud, ReadReport)> {
    let (file, file_len) = crate::input::open_regular(path)?;
    let mut r = BufReader::with_capacity(64 << 10, file);
    let header = header::parse_header(&mut r, path)?;
    let layout = header::layout(&header, path)?;
    let data_len = file_len.saturating_sub(header.len);
    let count = header.vertex_count;
    let mut report = ReadReport::default();

    let n = match header.encoding {
        Encoding::BinaryLe | Encoding::BinaryBe => {
            let stride = header.stride as u64;
            let need = count.checked_mul(stride);
            match need {
                Some(need) if need <= data_len => {
                    if need < data_len && header.trailing_elements.is_empty() {
                        report.warnings.push(format!(
                            "{} bytes after the vertex data ignored",
                            data_len - need
                        ));
                    }
                }
                _ => {
                    return Err(SceneError::format(
                        path,
                        format!(
                            "header declares {count} vertices of {stride} bytes ({} bytes) but only {data_len} bytes follow the header (truncated file or wrong count)",
                            need.map_or_else(|| "more than 2^64".to_string(), |b| b.to_string())
                        ),
                    ))
                }
            }
            count as usize
        }
        Encoding::Ascii => {
            // Each value takes at least one character and one separator (space or newline).
            let min_per_vertex = 2 * header.properties.len() as u64;
            let capacity = (data_len + 1).checked_div(min_per_vertex).unwrap_or(0);
            if count > capacity {
                return Err(SceneError::format(
                    path,
                    format!(
                        "header declares {count} vertices of {} values but the {data_len} bytes after the header can hold at most {capacity}",
                        header.properties.len()
                    ),
                ));
            }
            count as usize
        }
    };

    let (mut cloud, suspect) = match header.encoding {
        Encoding::Ascii => ascii::read_ascii(&mut r, path, &header, &layout, n)?,
        _ => binary::read_binary(&mut r, path, &header, &layout, n)?,
    };

    if let Some(var) = &layout.variant {
        report.kind = var.kind;
        report.warnings.extend(var.notes.iter().cloned());
        if var.kind == GaussianKind::Points {
            point_defaults::neighbour_scales(&mut cloud);
        }
    }
    if !layout.ignored.is_empty() {
        report.warnings.push(format!(
            "ignored {} vertex properties not used by 3DGS: {}",
            layout.ignored.len(),
            layout.ignored.join(", ")
        ));
        report.ignored_properties = layout.ignored;
    }
    if !header.trailing_elements.is_empty() {
        let list: Vec<String> = header
            .trailing_elements
            .iter()
            .map(|(name, c)| format!("{name} ({c})"))
            .collect();
        report.warnings.push(format!(
            "ignored elements after 'vertex': {}",
            list.join(", ")
        ));
    }

    validate(&mut cloud, suspect, path, opts, &mut report)?;
    debug_assert!(cloud.check_shape().is_ok());
    Ok((cloud, report))
}

/// Apply the invalid-Gaussian policy. `suspect` is the decoder's conservative flag: when it is
/// false no Gaussian can be invalid and the per-Gaussian pass is skipped (debug builds run it
/// anyway and check that nothing was missed).
pub(crate) fn validate(
    cloud: &mut GaussianCloud,
    suspect: bool,
    path: &Path,
    opts: &ReadOptions,
    report: &mut ReadReport,
) -> Result<()> {
    if !suspect {
        debug_assert!(
            (0..cloud.len()).all(|i| cloud.invalid_reason(i).is_none()),
            "the decoder's validity screen missed an invalid Gaussian"
        );
        return Ok(());
    }
    let mut bad: Vec<(usize, &'static str)> = Vec::new();
    for i in 0..cloud.len() {
        if let Some(reason) = cloud.invalid_reason(i) {
            if !opts.drop_invalid {
                return Err(SceneError::format(
                    path,
                    format!(
                        "vertex {i}: {} ({reason}; drop invalid Gaussians with --drop-invalid)",
                        describe_invalid(cloud, i, reason)
                    ),
                ));
            }
            bad.push((i, reason));
        }
    }
    if bad.is_empty() {
        return Ok(());
    }
    let mut counts: Vec<(String, usize)> = Vec::new();
    for &(_, reason) in &bad {
        match counts.iter_mut().find(|(r, _)| r == reason) {
            Some((_, c)) => *c += 1,
            None => counts.push((reason.to_string(), 1)),
        }
    }
    counts.sort();
    let first = bad[0].0;
    let what = describe_invalid(cloud, first, bad[0].1);
    let mut flags = vec![false; cloud.len()];
    for &(i, _) in &bad {
        flags[i] = true;
    }
    cloud.retain_indices(|i| !flags[i]);
    let summary: Vec<String> = counts.iter().map(|(r, c)| format!("{c} {r}")).collect();
    report.warnings.push(format!(
        "dropped {} invalid Gaussians ({}); first: vertex {first}: {what}",
        bad.len(),
        summary.join(", ")
    ));
    report.dropped = counts;
    Ok(())
}

/// Name the property that makes Gaussian `i` invalid and its value.
fn describe_invalid(cloud: &GaussianCloud, i: usize, reason: &str) -> String {
    let prop = |slot: usize, v: f32| format!("property '{}' is {v}", header::slot_name(slot));
    let first_bad = |vals: &[f32], base: usize, nan_only: bool| {
        vals.iter()
            .position(|v| if nan_only { v.is_nan() } else { !v.is_finite() })
            .map(|j| prop(base + j, vals[j]))
    };
    let q = cloud.rotations[i];
    let found = match reason {
        "non-finite position" => first_bad(&cloud.means[i].to_array(), SLOT_X, false),
        "non-finite log-scale" => first_bad(&cloud.log_scales[i].to_array(), SLOT_SCALE, false),
        "NaN opacity" => first_bad(&[cloud.opacity_logits[i]], SLOT_OPACITY, true),
        "non-finite rotation" => first_bad(&[q.w, q.x, q.y, q.z], SLOT_ROT, false),
        "zero quaternion" => Some("rot_0..rot_3 are all zero".to_string()),
        "non-finite SH coefficient" => {
            let sh = cloud.sh_of(i);
            let kr = sh.len() - 1;
            (0..sh.len())
                .flat_map(|c| (0..3).map(move |ch| (c, ch)))
                .find_map(|(c, ch)| {
                    let v = sh[c][ch];
                    (!v.is_finite()).then(|| {
                        let slot = if c == 0 {
                            SLOT_DC + ch
                        } else {
                            SLOT_REST + ch * kr + c - 1
                        };
                        prop(slot, v)
                    })
                })
        }
        _ => None,
    };
    found.unwrap_or_else(|| reason.to_string())
}

/// One decoded record (values in canonical slot order, see `header`) as the cloud stores it,
/// `f_rest` reordered from channel-major to coefficient-major into `rest`. Returns the fixed
/// attributes and true when the record may be invalid: a conservative test (any non-finite
/// value other than the opacity, a NaN opacity, or a quaternion whose squared length is 0) done
/// while the values are in cache, so the full [`GaussianCloud::invalid_reason`] pass only runs
/// on files that need it.
#[inline(always)]
fn record_parts(
    v: &[f32; header::MAX_SLOTS],
    n_rest: usize,
    mut rest_out: impl FnMut(usize, Vec3),
) -> ((Vec3, Vec3, Quat, f32, Vec3), bool) {
    // x·0 is NaN exactly when x is ±inf or NaN (±0 otherwise). The opacity is left out of
    // the sum (its ±inf is valid) and tested for NaN on its own.
    let mut acc = 0.0f32;
    for &x in v[..SLOT_OPACITY]
        .iter()
        .chain(&v[SLOT_OPACITY + 1..SLOT_REST + n_rest])
    {
        acc += x * 0.0;
    }
    let opacity = v[SLOT_OPACITY];
    // rot_0 is w.
    let q = Quat::from_xyzw(
        v[SLOT_ROT + 1],
        v[SLOT_ROT + 2],
        v[SLOT_ROT + 3],
        v[SLOT_ROT],
    );
    let kr = n_rest / 3;
    let rest = &v[SLOT_REST..SLOT_REST + n_rest];
    for c in 0..kr {
        rest_out(c, Vec3::new(rest[c], rest[kr + c], rest[2 * kr + c]));
    }
    let parts = (
        Vec3::new(v[SLOT_X], v[SLOT_X + 1], v[SLOT_X + 2]),
        Vec3::new(v[SLOT_SCALE], v[SLOT_SCALE + 1], v[SLOT_SCALE + 2]),
        q,
        opacity,
        Vec3::new(v[SLOT_DC], v[SLOT_DC + 1], v[SLOT_DC + 2]),
    );
    (
        parts,
        acc.is_nan() || opacity.is_nan() || q.length_squared() == 0.0,
    )
}

/// Append one decoded record (values in canonical slot order, see `header`) to the cloud,
/// reordering channel-major `f_rest` to coefficient-major. Returns true when the record may be
/// invalid (see [`record_parts`]).
#[inline(always)]
fn push_slots(cloud: &mut GaussianCloud, v: &[f32; header::MAX_SLOTS], n_rest: usize) -> bool {
    let kr = n_rest / 3;
    let mut rest = [Vec3::ZERO; 15];
    let ((mean, scales, q, opacity, dc), suspect) = record_parts(v, n_rest, |c, x| rest[c] = x);
    cloud.means.push(mean);
    cloud.log_scales.push(scales);
    cloud.rotations.push(q);
    cloud.opacity_logits.push(opacity);
    cloud.sh.push(dc);
    cloud.sh.extend_from_slice(&rest[..kr]);
    suspect
}

/// Records per task of [`append_parallel`]: a few hundred kilobytes of records, so a 2 MB chunk
/// gives both cores several tasks and a small file stays on one.
const APPEND_TASK_RECORDS: usize = 512;

/// Append `m` records to `cloud` on all cores: record `j` (0-based within this call) is the
/// canonical slots `fill(j, &mut v)` writes, stored as [`push_slots`] stores it, in order, each
/// task writing its own range of the cloud's reserved capacity. Returns true when some record
/// may be invalid. The same cloud, bit for bit, as `push_slots` on each record in turn (tested
/// in `tests/ply_variants.rs` against the ASCII reader, which pushes record by record).
pub(crate) fn append_parallel(
    cloud: &mut GaussianCloud,
    m: usize,
    n_rest: usize,
    fill: impl Fn(usize, &mut [f32; header::MAX_SLOTS]) + Sync,
) -> bool {
    use rayon::prelude::*;
    use std::mem::MaybeUninit;
    let k = cloud.coeffs();
    debug_assert_eq!(k, 1 + n_rest / 3);
    cloud.means.reserve(m);
    cloud.log_scales.reserve(m);
    cloud.rotations.reserve(m);
    cloud.opacity_logits.reserve(m);
    cloud.sh.reserve(m * k);
    let t = APPEND_TASK_RECORDS;
    let suspect = (
        cloud.means.spare_capacity_mut()[..m].par_chunks_mut(t),
        cloud.log_scales.spare_capacity_mut()[..m].par_chunks_mut(t),
        cloud.rotations.spare_capacity_mut()[..m].par_chunks_mut(t),
        cloud.opacity_logits.spare_capacity_mut()[..m].par_chunks_mut(t),
        cloud.sh.spare_capacity_mut()[..m * k].par_chunks_mut(t * k),
    )
        .into_par_iter()
        .enumerate()
        .map(|(task, (means, scales, rots, opac, sh))| {
            let mut v = [0f32; header::MAX_SLOTS];
            let mut suspect = false;
            for j in 0..means.len() {
                fill(task * t + j, &mut v);
                let sh = &mut sh[j * k..(j + 1) * k];
                let ((mean, s, q, o, dc), bad) = record_parts(&v, n_rest, |c, x| {
                    sh[1 + c] = MaybeUninit::new(x);
                });
                means[j] = MaybeUninit::new(mean);
                scales[j] = MaybeUninit::new(s);
                rots[j] = MaybeUninit::new(q);
                opac[j] = MaybeUninit::new(o);
                sh[0] = MaybeUninit::new(dc);
                suspect |= bad;
            }
            suspect
        })
        .reduce(|| false, |a, b| a || b);
    // SAFETY: the five chunked slices are the first `m` (SH: `m·k`) spare slots of their
    // vectors, split into the same number of tasks (`t` records, `t·k` coefficients each; the
    // last task shorter by the same count in each). Each task writes every record of its
    // range: `means`, `log_scales`, `rotations`, `opacity_logits` at `j` and all `k`
    // coefficients `sh[j·k]` (DC) and `sh[j·k + 1..j·k + k]` (`record_parts` calls its sink
    // for each of the `k − 1 = n_rest/3` rest coefficients). A panic in a task propagates out
    // of the reduce above, before any length is changed.
    unsafe {
        cloud.means.set_len(cloud.means.len() + m);
        cloud.log_scales.set_len(cloud.log_scales.len() + m);
        cloud.rotations.set_len(cloud.rotations.len() + m);
        cloud.opacity_logits.set_len(cloud.opacity_logits.len() + m);
        cloud.sh.set_len(cloud.sh.len() + m * k);
    }
    suspect
}

/// Write a 3DGS PLY file (atomically: a temporary file renamed on success) in the standard
/// layout; see the `write` module docs.
pub fn write_ply(path: &Path, cloud: &GaussianCloud, format: PlyFormat) -> Result<()> {
    let mut set = crate::output::OutputSet::new();
    stage_ply(&mut set, path, cloud, format)?;
    set.commit()
}

/// [`write_ply`] into an output set (several files committed together).
pub fn stage_ply(
    set: &mut crate::output::OutputSet,
    path: &Path,
    cloud: &GaussianCloud,
    format: PlyFormat,
) -> Result<()> {
    cloud
        .check_shape()
        .map_err(|e| SceneError::format(path, format!("cannot write: {e}")))?;
    set.write_with(path, |w| write::write_cloud(w, cloud, format))
}
