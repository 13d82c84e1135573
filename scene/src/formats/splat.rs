//! antimatter15 `.splat` files (the `splat` WebGL viewer's format, also written by
//! splat-transform, Luma and Polycam exports): no header, 32-byte little-endian records.
//!
//! | bytes | field | encoding |
//! |---|---|---|
//! | 0..12 | position x, y, z | f32 |
//! | 12..24 | scale x, y, z | f32, linear (`exp` of the PLY's log-scale) |
//! | 24..28 | R, G, B, A | u8: colour `0.5 + SH_C0·f_dc`, alpha `sigmoid(opacity)`, ×255 |
//! | 28..32 | rotation w, x, y, z | u8: `q·128 + 128` of the normalised quaternion |
//!
//! Only the DC colour survives (SH degree 0). The axis convention is the 3DGS PLY's (the
//! viewer loads `.splat` files converted from PLYs unchanged). Decoding inverts each step
//! exactly: alpha 255 becomes an opacity logit of +inf, which the cloud accepts.

use std::io::{Read, Write};
use std::path::Path;

use glam::{Quat, Vec3};

use super::regular_file_len;
use crate::error::{Result, SceneError};
use crate::gaussians::{logit, sigmoid};
use crate::sh::SH_C0;
use crate::GaussianCloud;

/// Bytes per record.
pub const RECORD: usize = 32;

/// The largest `.splat` file read: 2³² records (no format limit; this keeps sizes sane).
const MAX_FILE: u64 = (RECORD as u64) << 32;

/// Does a header-less buffer look like `.splat` records? The length must be a non-zero
/// multiple of 32 and the first records (up to 64 in `head`) must hold finite positions and
/// finite, non-negative scales of sane magnitude.
pub(crate) fn plausible(head: &[u8], file_len: u64) -> bool {
    if file_len == 0 || !file_len.is_multiple_of(RECORD as u64) {
        return false;
    }
    let records = head.chunks_exact(RECORD).take(64);
    let mut seen = 0;
    for r in records {
        let f = |k: usize| f32::from_le_bytes([r[4 * k], r[4 * k + 1], r[4 * k + 2], r[4 * k + 3]]);
        let pos_ok = (0..3).all(|k| f(k).is_finite() && f(k).abs() < 1e7);
        let scale_ok = (3..6).all(|k| f(k).is_finite() && f(k) >= 0.0 && f(k) < 1e7);
        if !(pos_ok && scale_ok) {
            return false;
        }
        seen += 1;
    }
    seen > 0
}

/// Decode `.splat` bytes (a whole number of records); `path` names the file in errors.
pub fn decode_splat(bytes: &[u8], path: &Path) -> Result<GaussianCloud> {
    check_len(bytes.len() as u64, path)?;
    let mut cloud = GaussianCloud::with_capacity(0, bytes.len() / RECORD);
    push_records(&mut cloud, bytes);
    Ok(cloud)
}

fn check_len(len: u64, path: &Path) -> Result<()> {
    if len == 0 {
        return Err(SceneError::format(
            path,
            ".splat file is empty (no records)",
        ));
    }
    if !len.is_multiple_of(RECORD as u64) {
        return Err(SceneError::format(
            path,
            format!(
                ".splat data is {len} bytes, not a whole number of {RECORD}-byte records ({} bytes left over)",
                len % RECORD as u64
            ),
        ));
    }
    if len > MAX_FILE {
        return Err(SceneError::format(
            path,
            format!(".splat file of {len} bytes is too large"),
        ));
    }
    Ok(())
}

fn push_records(cloud: &mut GaussianCloud, bytes: &[u8]) {
    for r in bytes.chunks_exact(RECORD) {
        let f = |k: usize| f32::from_le_bytes([r[4 * k], r[4 * k + 1], r[4 * k + 2], r[4 * k + 3]]);
        let scale = Vec3::new(f(3), f(4), f(5));
        let byte = |k: usize| r[24 + k] as f32;
        let rgb = Vec3::new(byte(0), byte(1), byte(2)) / 255.0;
        let q = |k: usize| (r[28 + k] as f32 - 128.0) / 128.0;
        cloud.means.push(Vec3::new(f(0), f(1), f(2)));
        cloud
            .log_scales
            .push(Vec3::new(scale.x.ln(), scale.y.ln(), scale.z.ln()));
        cloud
            .rotations
            .push(Quat::from_xyzw(q(1), q(2), q(3), q(0)));
        cloud.opacity_logits.push(logit(byte(3) / 255.0));
        cloud.sh.push((rgb - Vec3::splat(0.5)) / SH_C0);
    }
}

/// Read a `.splat` file, streaming 64 KiB of records at a time into the cloud (sized once
/// from the file's length), so the peak memory is the cloud plus one chunk.
pub fn read_splat(path: &Path) -> Result<GaussianCloud> {
    let len = regular_file_len(path)?;
    check_len(len, path)?;
    let n = (len / RECORD as u64) as usize;
    let file = std::fs::File::open(path).map_err(|e| SceneError::io(path, e))?;
    let mut r = file.take(len);
    let mut cloud = GaussianCloud::with_capacity(0, n);
    let mut buf = vec![0u8; 2048 * RECORD];
    let mut left = n;
    while left > 0 {
        let k = left.min(2048);
        r.read_exact(&mut buf[..k * RECORD]).map_err(|e| {
            SceneError::format(
                path,
                format!(".splat file shorter than its length says: {e}"),
            )
        })?;
        push_records(&mut cloud, &buf[..k * RECORD]);
        left -= k;
    }
    Ok(cloud)
}

fn to_u8(x: f32) -> u8 {
    // NaN maps to 0 (`as` saturates and sends NaN to 0).
    x.round().clamp(0.0, 255.0) as u8
}

/// Encode a cloud as `.splat` records (higher SH dropped). The cloud must be valid (finite
/// values, non-zero quaternions); opacity logits of ±inf encode as alpha 255/0.
pub fn encode_splat(cloud: &GaussianCloud) -> Result<Vec<u8>> {
    cloud.check_shape()?;
    let k = cloud.coeffs();
    let mut out = Vec::with_capacity(cloud.len() * RECORD);
    for i in 0..cloud.len() {
        let m = cloud.means[i];
        let s = cloud.scale(i);
        for v in [m.x, m.y, m.z, s.x, s.y, s.z] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        let dc = cloud.sh[i * k];
        let rgb = Vec3::splat(0.5) + dc * SH_C0;
        out.push(to_u8(rgb.x * 255.0));
        out.push(to_u8(rgb.y * 255.0));
        out.push(to_u8(rgb.z * 255.0));
        out.push(to_u8(sigmoid(cloud.opacity_logits[i]) * 255.0));
        let q = cloud.unit_rotation(i);
        for c in [q.w, q.x, q.y, q.z] {
            out.push(to_u8(c * 128.0 + 128.0));
        }
    }
    Ok(out)
}

/// Write a `.splat` file atomically.
pub fn write_splat(path: &Path, cloud: &GaussianCloud) -> Result<()> {
    let bytes =
        encode_splat(cloud).map_err(|e| SceneError::format(path, format!("cannot write: {e}")))?;
    crate::image_io::with_atomic_writer(path, |w| w.write_all(&bytes))
}
