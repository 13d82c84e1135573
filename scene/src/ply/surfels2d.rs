//! 2DGS surfel files (`hbb1/2d-gaussian-splatting`, `scene/gaussian_model.py`: `save_ply` writes
//! `x y z nx ny nz f_dc_0..2 f_rest_* opacity scale_0 scale_1 rot_0..3`) and the flattening of
//! 3D Gaussians into surfels.
//!
//! A cloud read from a 2DGS file keeps its two scales and rotation bit for bit; its third
//! log-scale is derived on read (`SURFEL_THICKNESS`) and [`write_ply_2dgs`] drops it again, so
//! a 2DGS file survives read → write unchanged.

use std::io::{self, Write};
use std::path::Path;

use glam::{Mat3, Quat, Vec3};

use super::variant::SURFEL_THICKNESS;
use super::write::{write_records_le, Scales};
use crate::error::{Result, SceneError};
use crate::GaussianCloud;

/// Header of a binary little-endian 2DGS PLY of `n` surfels with `n_rest` `f_rest` values.
fn header(n: usize, n_rest: usize) -> String {
    let mut h = format!("ply\nformat binary_little_endian 1.0\nelement vertex {n}\n");
    let names = [
        "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
    ]
    .into_iter()
    .map(String::from)
    .chain((0..n_rest).map(|j| format!("f_rest_{j}")))
    .chain(
        [
            "opacity", "scale_0", "scale_1", "rot_0", "rot_1", "rot_2", "rot_3",
        ]
        .into_iter()
        .map(String::from),
    );
    for name in names {
        h.push_str("property float ");
        h.push_str(&name);
        h.push('\n');
    }
    h.push_str("end_header\n");
    h
}

/// The whole file: the writer's block-parallel little-endian path with two scales.
fn write_all(w: &mut impl Write, cloud: &GaussianCloud) -> io::Result<()> {
    let n_rest = 3 * (cloud.coeffs() - 1);
    w.write_all(header(cloud.len(), n_rest).as_bytes())?;
    write_records_le(w, cloud, n_rest, Scales::Two)
}

/// The per-record writer: the reference [`write_all`] is checked against.
#[cfg(test)]
fn write_all_per_record(w: &mut impl Write, cloud: &GaussianCloud) -> io::Result<()> {
    let n_rest = 3 * (cloud.coeffs() - 1);
    w.write_all(header(cloud.len(), n_rest).as_bytes())?;
    let mut rec: Vec<u8> = Vec::with_capacity(4 * (16 + n_rest));
    for i in 0..cloud.len() {
        rec.clear();
        let mut put = |v: f32| rec.extend_from_slice(&v.to_le_bytes());
        let m = cloud.means[i];
        for v in [m.x, m.y, m.z, 0.0, 0.0, 0.0] {
            put(v);
        }
        let sh = cloud.sh_of(i);
        for v in sh[0].to_array() {
            put(v);
        }
        for ch in 0..3 {
            for c in &sh[1..] {
                put(c[ch]);
            }
        }
        put(cloud.opacity_logits[i]);
        let s = cloud.log_scales[i];
        put(s.x);
        put(s.y);
        let q = cloud.rotations[i];
        for v in [q.w, q.x, q.y, q.z] {
            put(v);
        }
        w.write_all(&rec)?;
    }
    Ok(())
}

/// Write `cloud` as a 2DGS PLY (binary little endian): the first two scales and the rotation as
/// stored, no third scale; written atomically.
pub fn write_ply_2dgs(path: &Path, cloud: &GaussianCloud) -> Result<()> {
    cloud
        .check_shape()
        .map_err(|e| SceneError::format(path, format!("cannot write: {e}")))?;
    let mut set = crate::output::OutputSet::new();
    set.write_with(path, |w| write_all(w, cloud))?;
    set.commit()
}

/// Flatten 3D Gaussians into 2DGS surfels: each keeps its two largest axes as the surfel's
/// tangent axes (rotation columns 0 and 1, in that order of size), its smallest axis becomes the
/// normal (column 2, sign chosen so the frame stays right-handed), and its third log-scale is
/// set as a 2DGS file's is on read. Mean, opacity and SH are kept. Rotations are stored unit.
pub fn flatten_to_surfels(cloud: &GaussianCloud) -> GaussianCloud {
    let mut out = cloud.clone();
    for i in 0..cloud.len() {
        let l = cloud.log_scales[i];
        let r = Mat3::from_quat(cloud.unit_rotation(i));
        let cols = [r.x_axis, r.y_axis, r.z_axis];
        let ls = l.to_array();
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&a, &b| ls[b].total_cmp(&ls[a]));
        let (a, b) = (cols[idx[0]], cols[idx[1]]);
        let n = a.cross(b);
        let q = Quat::from_mat3(&Mat3::from_cols(a, b, n)).normalize();
        let (la, lb) = (ls[idx[0]], ls[idx[1]]);
        out.log_scales[i] = Vec3::new(la, lb, la.min(lb) + SURFEL_THICKNESS.ln());
        out.rotations[i] = q;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ply::write::{block_records, tests::distinct_cloud, TASK_RECORDS};

    #[test]
    fn block_writer_matches_the_per_record_writer() {
        // Counts around the block and task sizes, every SH degree; every stored float distinct
        // (some ±inf, NaN, −0.0), so a value in the wrong slot or a stray `scale_2` shows.
        for degree in 0..=3u8 {
            let rec = 4 * (16 + 3 * (crate::gaussians::sh_coeffs(degree) - 1));
            let per_block = block_records(rec);
            for n in [0, 1, TASK_RECORDS + 3, per_block + TASK_RECORDS + 1] {
                let c = distinct_cloud(n, degree);
                let (mut fast, mut slow) = (Vec::new(), Vec::new());
                write_all(&mut fast, &c).unwrap();
                write_all_per_record(&mut slow, &c).unwrap();
                assert_eq!(fast.len(), slow.len(), "degree {degree}, {n} surfels");
                assert!(fast == slow, "degree {degree}, {n} surfels");
            }
        }
    }
}
