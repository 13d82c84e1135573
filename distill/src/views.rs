//! Fitting and held-back views. The fitting orbit is the standard `orbit:N` rig; its held-back
//! views sit half-way between its cameras (the odd cameras of the 2N-camera rig), so no
//! held-back view is ever a fitting view.

use splatbridge_scene::camera::OrbitRig;
use splatbridge_scene::{Camera, GaussianCloud};

/// Cameras `i·step + offset` of the `n`-camera orbit around the robust bounds of `cloud`, at
/// `width`×`height` (the CLI's orbit: up −y, 50° field of view, 20° elevation).
pub fn orbit(
    cloud: &GaussianCloud,
    n: usize,
    pick: impl Iterator<Item = usize>,
    width: u32,
    height: u32,
) -> splatbridge_scene::Result<Vec<Camera>> {
    let rig = OrbitRig {
        width,
        height,
        ..OrbitRig::default()
    };
    let (lo, hi) = cloud.robust_bounds(rig.percentile).ok_or_else(|| {
        splatbridge_scene::SceneError::Invalid("cannot place an orbit around an empty scene".into())
    })?;
    pick.map(|i| rig.camera_around(lo.as_dvec3(), hi.as_dvec3(), n, i))
        .collect()
}

/// `m` held-back views of an `n`-camera fitting orbit: half-way between fitting cameras,
/// spread evenly over the orbit.
pub fn held_back(
    cloud: &GaussianCloud,
    n: usize,
    m: usize,
    width: u32,
    height: u32,
) -> splatbridge_scene::Result<Vec<Camera>> {
    let n = n.max(1);
    let m = m.clamp(1, n);
    orbit(
        cloud,
        2 * n,
        (0..m).map(|j| 2 * (j * n / m) + 1),
        width,
        height,
    )
}
