//! The writer: the standard 3DGS layout in any of the three encodings.
//!
//! Properties in the order of the reference `save_ply`: `x y z nx ny nz f_dc_0..2 f_rest_*
//! opacity scale_0..2 rot_0..3`, all float32, normals written as 0. `f_rest` is written
//! channel-major as the reference does. Stored values are written unchanged, so a write/read
//! round trip is bit-exact; ASCII prints each float with the shortest digits that read back to
//! the same bits (`inf`, `-inf` and `NaN` spelled as Rust prints them, which the reader parses).
//! Object ids are not part of the layout and are not written.

use std::io::{self, Write};

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

/// Write the whole file to `w`.
pub(crate) fn write_cloud(
    w: &mut impl Write,
    cloud: &GaussianCloud,
    format: PlyFormat,
) -> io::Result<()> {
    let n_rest = 3 * (cloud.coeffs() - 1);
    w.write_all(header(cloud.len(), n_rest, format).as_bytes())?;
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
