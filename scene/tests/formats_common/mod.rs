//! Helpers shared by the `formats_*` tests: a seeded random cloud with every attribute in
//! the ranges trained scenes hold, the real-data folder, and an attribute-wise comparison.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use glam::{Quat, Vec3};
use splatbridge_scene::formats::SplatFormat;
use splatbridge_scene::rng::Rng;
use splatbridge_scene::GaussianCloud;

/// `n` Gaussians of SH degree `degree`: positions in ±`extent`, log-scales in [−7, −1],
/// opacity logits in [−4, 4], random (non-unit) quaternions, DC in [−1.5, 1.5] and higher
/// SH in [−0.4, 0.4].
pub fn random_cloud(seed: u64, n: usize, degree: u8, extent: f32) -> GaussianCloud {
    let mut rng = Rng::new(seed);
    let mut c = GaussianCloud::with_capacity(degree, n);
    let k = c.coeffs();
    for _ in 0..n {
        let mean = Vec3::new(
            rng.range(-extent, extent),
            rng.range(-extent, extent),
            rng.range(-extent, extent),
        );
        let ls = Vec3::new(
            rng.range(-7.0, -1.0),
            rng.range(-7.0, -1.0),
            rng.range(-7.0, -1.0),
        );
        let q = Quat::from_xyzw(rng.normal(), rng.normal(), rng.normal(), rng.normal() + 0.1);
        let op = rng.range(-4.0, 4.0);
        let mut sh = vec![Vec3::new(
            rng.range(-1.5, 1.5),
            rng.range(-1.5, 1.5),
            rng.range(-1.5, 1.5),
        )];
        for _ in 1..k {
            sh.push(Vec3::new(
                rng.range(-0.4, 0.4),
                rng.range(-0.4, 0.4),
                rng.range(-0.4, 0.4),
            ));
        }
        c.push(mean, ls, q, op, &sh);
    }
    c
}

/// `../shared/data/real/NAME`. Tests that call this are ignored unless `build.rs` found the
/// folder (`cfg(real_data)`); a file missing from it is then a failure.
pub fn real_file(name: &str) -> PathBuf {
    let p = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/data/real"
    ))
    .join(name);
    assert!(p.is_file(), "real data file {} not found", p.display());
    p
}

/// The committed fixtures folder `fixtures/formats`.
pub fn fixtures() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/formats"))
}

/// Largest absolute differences between two clouds of equal length, per attribute:
/// positions, log-scales, rotation (|1 − |q·q'|| of the unit quaternions, sign-free),
/// opacity (after the sigmoid), DC colour (`SH_C0·f_dc`, display units) and higher SH.
#[derive(Debug, Default, Clone, Copy)]
pub struct MaxErr {
    pub pos: f32,
    pub log_scale: f32,
    pub rot_angle: f32,
    pub opacity: f32,
    pub colour: f32,
    pub sh_rest: f32,
}

pub fn max_err(a: &GaussianCloud, b: &GaussianCloud) -> MaxErr {
    assert_eq!(a.len(), b.len(), "counts differ");
    let mut e = MaxErr::default();
    let ka = a.coeffs();
    let kb = b.coeffs();
    for i in 0..a.len() {
        e.pos = e.pos.max((a.means[i] - b.means[i]).abs().max_element());
        e.log_scale = e
            .log_scale
            .max((a.log_scales[i] - b.log_scales[i]).abs().max_element());
        let d = a.unit_rotation(i).dot(b.unit_rotation(i)).abs().min(1.0);
        // Rotation angle between the two orientations, radians.
        e.rot_angle = e.rot_angle.max(2.0 * d.acos());
        e.opacity = e.opacity.max((a.opacity(i) - b.opacity(i)).abs());
        let dc = (a.sh[i * ka] - b.sh[i * kb]).abs().max_element() * splatbridge_scene::sh::SH_C0;
        e.colour = e.colour.max(dc);
        for c in 1..ka.min(kb) {
            e.sh_rest = e
                .sh_rest
                .max((a.sh[i * ka + c] - b.sh[i * kb + c]).abs().max_element());
        }
    }
    e
}

/// Write bytes to a fresh file in `dir` and return its path.
/// Two decodes of the same SPZ bytes (ours and splat-transform's reader) differ only by f32
/// rounding of the same formulas; splat-transform clamps alpha to [1/255, 254/255] before the
/// logit where we keep ±inf, so opacities may be 1/255 apart after the sigmoid.
pub fn assert_same_decode(e: &MaxErr) {
    assert!(e.pos <= 1e-6, "{e:?}");
    assert!(e.log_scale <= 1e-5, "{e:?}");
    assert!(e.rot_angle <= 1e-3, "{e:?}");
    assert!(e.colour <= 1e-5, "{e:?}");
    assert!(e.sh_rest <= 1e-5, "{e:?}");
    assert!(e.opacity <= 1.0 / 255.0 + 1e-6, "{e:?}");
}

pub fn put(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

pub fn is_spz(f: SplatFormat) -> bool {
    matches!(f, SplatFormat::Spz { .. })
}
