//! The SPZ-compressed variant of `KHR_gaussian_splatting`
//! (`KHR_gaussian_splatting_compression_spz_2`, Khronos glTF draft): the primitive's
//! `extensions.KHR_gaussian_splatting.extensions.<name>.bufferView` holds a whole SPZ stream
//! (gzip, SPZ v2 or v3), and the attribute accessors have no buffer views of their own.
//!
//! Axes: the extension requires packing and unpacking with SPZ's Left-Up-Front (LUF)
//! coordinate system, i.e. the glTF mesh's local frame is LUF while the SPZ stream stores RUB
//! (SPZ's internal convention). RUB → LUF negates x and z, a half turn about y, so positions,
//! quaternions (x and z parts) and every SH coefficient odd in x·z change sign.

use std::path::Path;

use glam::{Quat, Vec3};

use crate::error::Result;
use crate::formats::spz::{decode_spz_with, encode_spz, SpzAxes, SpzOptions};
use crate::gaussians::GaussianCloud;

/// Names of the extension, newest first; the older draft name is read the same way.
pub const SPZ_EXTENSIONS: [&str; 2] = [
    "KHR_gaussian_splatting_compression_spz_2",
    "KHR_gaussian_splatting_compression_spz",
];

/// Sign of each SH coefficient (coefficient-major, after DC) when x and z change sign: the
/// real SH basis of degrees 1–3 in the 3DGS order (y, z, x; xy, yz, 3z²−1, xz, x²−y²;
/// y(3x²−y²), xyz, y(5z²−1), z(5z²−3), x(5z²−1), z(x²−y²), x(x²−3y²)).
pub const SH_FLIP_XZ: [f32; 15] = [
    1.0, -1.0, -1.0, // degree 1
    -1.0, -1.0, 1.0, 1.0, 1.0, // degree 2
    1.0, 1.0, 1.0, -1.0, -1.0, -1.0, -1.0, // degree 3
];

/// Negate x and z of every Gaussian (its own inverse): RUB ↔ LUF.
pub fn flip_xz(c: &mut GaussianCloud) {
    for m in &mut c.means {
        *m *= Vec3::new(-1.0, 1.0, -1.0);
    }
    for q in &mut c.rotations {
        *q = Quat::from_xyzw(-q.x, q.y, -q.z, q.w);
    }
    let k = c.coeffs();
    if k > 1 {
        for g in c.sh.chunks_mut(k) {
            for (j, s) in g[1..].iter_mut().enumerate() {
                *s *= SH_FLIP_XZ[j];
            }
        }
    }
}

/// Decode the SPZ stream of a compressed primitive into the glTF mesh's local frame.
pub fn decode_khr_spz(bytes: &[u8], path: &Path) -> Result<GaussianCloud> {
    let mut c = decode_spz_with(bytes, path, SpzAxes::AsStored)?;
    flip_xz(&mut c);
    Ok(c)
}

/// Encode a cloud given in the glTF mesh's local frame as the extension's SPZ stream.
pub fn encode_khr_spz(cloud: &GaussianCloud, opts: &SpzOptions) -> Result<Vec<u8>> {
    let mut c = cloud.clone();
    flip_xz(&mut c);
    encode_spz(
        &c,
        &SpzOptions {
            axes: SpzAxes::AsStored,
            ..*opts
        },
    )
}
