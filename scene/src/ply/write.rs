//! The writer: the standard 3DGS layout in any of the three encodings.
//!
//! Properties in the order of the reference `save_ply`: `x y z nx ny nz f_dc_0..2 f_rest_*
//! opacity scale_0..2 rot_0..3`, all float32, normals written as 0. `f_rest` is written
//! channel-major as the reference does. Stored values are written unchanged, so a write/read
//! round trip is bit-exact; ASCII prints each float with the shortest digits that read back to
//! the same bits (`inf`, `-inf` and `NaN` spelled as Rust prints them, which the reader parses).
//! Object ids are not part of the layout and are not written.
//!
//! Binary little endian (what every tool writes and the format converters emit) has a fast
//! path: records are laid out straight into one block buffer, blocks filled on all cores,
//! and written with one call each; it is checked byte for byte against the per-record path
//! ([`record`]), which the other encodings use. The same path writes 2DGS's layout (two
//! scales, [`Scales::Two`]) for `super::surfels2d`, checked there against its per-record writer.

use std::io::{self, Write};

use rayon::prelude::*;

use super::PlyFormat;
use crate::GaussianCloud;

/// Header lines for a cloud of `n` Gaussians with `n_rest` `f_rest` properties.
fn header(n: usize, n_rest: usize, format: PlyFormat) -> String {
    let enc = match format {
        PlyFormat::BinaryLittleEndian => "binary_little_endian",
        PlyFormat::BinaryBigEndian => "binary_big_endian",
        PlyFormat::Ascii => "ascii",
    };
    let mut h = format!("ply\nformat {enc} 1.0\nelement vertex {n}\n");
    let mut prop = |name: &str| {
        h.push_str("property float ");
        h.push_str(name);
        h.push('\n');
    };
    for name in [
        "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
    ] {
        prop(name);
    }
    for j in 0..n_rest {
        prop(&format!("f_rest_{j}"));
    }
    for name in [
        "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
    ] {
        prop(name);
    }
    h.push_str("end_header\n");
    h
}

/// The values of Gaussian `i` in file order.
fn record(cloud: &GaussianCloud, i: usize, out: &mut Vec<f32>) {
    out.clear();
    let m = cloud.means[i];
    out.extend_from_slice(&[m.x, m.y, m.z, 0.0, 0.0, 0.0]);
    let sh = cloud.sh_of(i);
    out.extend_from_slice(&sh[0].to_array());
    for ch in 0..3 {
        out.extend(sh[1..].iter().map(|c| c[ch]));
    }
    out.push(cloud.opacity_logits[i]);
    let s = cloud.log_scales[i];
    out.extend_from_slice(&[s.x, s.y, s.z]);
    let q = cloud.rotations[i];
    out.extend_from_slice(&[q.w, q.x, q.y, q.z]);
}

/// Shortest round-trip spelling: plain decimals for ordinary magnitudes, exponent notation
/// for the rest (Rust's `{}` never uses an exponent and would print 1e-38 with 38 zeros).
fn write_f32(w: &mut impl Write, v: f32) -> io::Result<()> {
    let a = v.abs();
    if a == 0.0 || !a.is_finite() || (1e-4..1e7).contains(&a) {
        write!(w, "{v}")
    } else {
        write!(w, "{v:e}")
    }
}

/// Output bytes per block of the fast path: enough to amortise the write call and the thread
/// hand-off, small next to a cloud (a 100k-Gaussian SH-0 cloud is 6 MB).
const BLOCK_BYTES: usize = 256 << 10;
/// Records per parallel task within a block.
pub(crate) const TASK_RECORDS: usize = 1 << 10;

/// Records per block for records of `rec` bytes: whole tasks, at least two of them.
pub(crate) fn block_records(rec: usize) -> usize {
    (BLOCK_BYTES / rec / TASK_RECORDS).max(2) * TASK_RECORDS
}

/// How many log-scales a record carries: 3DGS's three, or 2DGS's two (`scale_0 scale_1`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scales {
    Three,
    Two,
}

impl Scales {
    fn count(self) -> usize {
        match self {
            Scales::Three => 3,
            Scales::Two => 2,
        }
    }
}

/// Lay Gaussian `i` out as little-endian float32 in file order into `out` (exactly one
/// record's bytes); the same values in the same order as [`record`] (without `scale_2` for
/// [`Scales::Two`]).
fn record_le(cloud: &GaussianCloud, i: usize, scales: Scales, out: &mut [u8]) {
    let mut at = 0;
    let mut put = |v: f32| {
        out[at..at + 4].copy_from_slice(&v.to_le_bytes());
        at += 4;
    };
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
    for v in &[s.x, s.y, s.z][..scales.count()] {
        put(*v);
    }
    let q = cloud.rotations[i];
    for v in [q.w, q.x, q.y, q.z] {
        put(v);
    }
}

/// The binary little-endian records of the whole cloud, block by block.
pub(crate) fn write_records_le(
    w: &mut impl Write,
    cloud: &GaussianCloud,
    n_rest: usize,
    scales: Scales,
) -> io::Result<()> {
    let rec = 4 * (14 + scales.count() + n_rest);
    let n = cloud.len();
    let per_block = block_records(rec);
    let mut buf = vec![0u8; per_block.min(n) * rec];
    for start in (0..n).step_by(per_block) {
        let m = per_block.min(n - start);
        let block = &mut buf[..m * rec];
        block
            .par_chunks_mut(TASK_RECORDS * rec)
            .enumerate()
            .for_each(|(t, task)| {
                let first = start + t * TASK_RECORDS;
                for (j, out) in task.chunks_exact_mut(rec).enumerate() {
                    record_le(cloud, first + j, scales, out);
                }
            });
        w.write_all(block)?;
    }
    Ok(())
}

/// Write the whole file to `w`.
pub(crate) fn write_cloud(
    w: &mut impl Write,
    cloud: &GaussianCloud,
    format: PlyFormat,
) -> io::Result<()> {
    let n_rest = 3 * (cloud.coeffs() - 1);
    w.write_all(header(cloud.len(), n_rest, format).as_bytes())?;
    if let PlyFormat::BinaryLittleEndian = format {
        return write_records_le(w, cloud, n_rest, Scales::Three);
    }
    write_records(w, cloud, format, n_rest)
}

/// The per-record path: every encoding (the reference for the little-endian fast path).
fn write_records(
    w: &mut impl Write,
    cloud: &GaussianCloud,
    format: PlyFormat,
    n_rest: usize,
) -> io::Result<()> {
    let mut rec = Vec::with_capacity(17 + n_rest);
    let mut bytes = Vec::with_capacity(4 * (17 + n_rest));
    for i in 0..cloud.len() {
        record(cloud, i, &mut rec);
        match format {
            PlyFormat::BinaryLittleEndian => {
                bytes.clear();
                bytes.extend(rec.iter().flat_map(|v| v.to_le_bytes()));
                w.write_all(&bytes)?;
            }
            PlyFormat::BinaryBigEndian => {
                bytes.clear();
                bytes.extend(rec.iter().flat_map(|v| v.to_be_bytes()));
                w.write_all(&bytes)?;
            }
            PlyFormat::Ascii => {
                for (j, &v) in rec.iter().enumerate() {
                    if j > 0 {
                        w.write_all(b" ")?;
                    }
                    write_f32(w, v)?;
                }
                w.write_all(b"\n")?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::gaussians::sh_coeffs;
    use glam::{Quat, Vec3};

    /// A cloud whose every stored float is distinct (and some are ±inf, NaN, −0.0), so a
    /// value written to the wrong slot shows.
    pub(crate) fn distinct_cloud(n: usize, degree: u8) -> GaussianCloud {
        let mut c = GaussianCloud::new(degree);
        let k = c.coeffs();
        let mut x = 0.0f32;
        let mut next = || {
            x += 1.0;
            x * 0.37
        };
        for i in 0..n {
            let coeffs: Vec<Vec3> = (0..k).map(|_| Vec3::new(next(), next(), next())).collect();
            let opacity = match i % 5 {
                0 => f32::INFINITY,
                1 => f32::NAN,
                2 => -0.0,
                _ => next(),
            };
            c.push(
                Vec3::new(next(), -next(), next()),
                Vec3::new(next(), next(), -next()),
                Quat::from_xyzw(next(), next(), next(), next()),
                opacity,
                &coeffs,
            );
        }
        c
    }

    #[test]
    fn fast_little_endian_path_matches_the_per_record_path() {
        // Counts around the block and task sizes, every SH degree.
        for degree in 0..=3u8 {
            let per_block = block_records(4 * (17 + 3 * (sh_coeffs(degree) - 1)));
            for n in [0, 1, TASK_RECORDS + 3, per_block + TASK_RECORDS + 1] {
                let c = distinct_cloud(n, degree);
                let mut fast = Vec::new();
                write_cloud(&mut fast, &c, PlyFormat::BinaryLittleEndian).unwrap();
                let n_rest = 3 * (c.coeffs() - 1);
                let mut slow = header(n, n_rest, PlyFormat::BinaryLittleEndian).into_bytes();
                write_records(&mut slow, &c, PlyFormat::BinaryLittleEndian, n_rest).unwrap();
                assert!(fast == slow, "degree {degree}, {n} Gaussians");
            }
        }
    }
}
