//! Mesh exports made for a target resolution (`convert --footprint-for WxH`).
//!
//! Native splatting low-pass filters every splat: it adds 0.3 px² to the projected 2-D
//! covariance (Kerbl et al. 2023, the EWA "dilation"), so at a low resolution small Gaussians
//! blur into their neighbours. A triangle mesh has no such filter: its fans keep their exact
//! size, and at low resolution the tracer (or any rasteriser) aliases where native blurs
//! (`docs/footprint.md`). This module bakes the filter into the Gaussians before they are
//! triangulated, for a given set of cameras at a given size.
//!
//! A pixel at depth `d` in front of a camera with focal length `f` pixels spans `d / f` world
//! units, so the 0.3 px² screen variance is `0.3 (d / f)²` world units² across the view
//! direction. Adding that isotropic variance `s²` to the 3-D covariance, `Σ' = Σ + s² I`, keeps
//! its eigenvectors (the rotation) and adds `s²` to every eigenvalue, so each scale becomes
//! `√(σ² + s²)`. It also adds `s²` along the view direction, which projects to nothing under
//! the pinhole's affine approximation at the mean. As in native splatting (and `hybrid`), the
//! opacity is not rescaled by the determinant ratio.
//!
//! With several cameras a Gaussian takes the smallest footprint of the cameras that see it in
//! front (the most detailed view), so no view is blurred more than native blurs it there; the
//! views farther away then alias a little less than before, never more. Objects of a dynamic
//! scene are widened at their pose at the clip's start.

use glam::{DVec3, Vec3};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::{Camera, GaussianCloud};

/// Native splatting's screen-space low-pass variance, in pixels² (3DGS `+0.3` on the 2-D
/// covariance's diagonal).
pub const LOW_PASS_PX2: f64 = 0.3;

/// What widening did, for the report.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Widened {
    /// Gaussians in front of at least one camera (the ones widened).
    pub widened: usize,
    /// Gaussians behind every camera (left as they are).
    pub unseen: usize,
    /// The largest footprint added, as a standard deviation in world units.
    pub max_sigma: f64,
}

/// The world-space variance the low-pass adds at world point `p`: the smallest over the
/// cameras that have `p` in front of them, or None when none does.
pub fn footprint_variance(p: DVec3, cameras: &[Camera]) -> Option<f64> {
    cameras
        .iter()
        .filter_map(|c| {
            let z = c.to_camera(p).z;
            // A camera's near plane is not part of the model; anything in front counts.
            (z > 0.0 && z.is_finite()).then(|| {
                let f = c.fx.min(c.fy);
                LOW_PASS_PX2 * (z / f) * (z / f)
            })
        })
        .min_by(f64::total_cmp)
}

/// As [`footprint_variance`], over the cameras whose image holds `p` (a tenth of the image's
/// size of margin, for the Gaussian's own extent): each view sizes the footprint only of what
/// it sees, so a close-up does not thin Gaussians it never shows. `quantile` picks among
/// those views' footprints: 0 the smallest, 1 the largest, between them the nearest rank.
pub fn footprint_variance_seen(p: DVec3, cameras: &[Camera], quantile: f64) -> Option<f64> {
    let mut v: Vec<f64> = cameras
        .iter()
        .filter(|c| crate::views::sees(c, p, 0.1))
        .map(|c| {
            let z = c.to_camera(p).z;
            let f = c.fx.min(c.fy);
            LOW_PASS_PX2 * (z / f) * (z / f)
        })
        .collect();
    if v.is_empty() {
        return None;
    }
    let q = if quantile.is_finite() {
        quantile.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let rank = ((v.len() - 1) as f64 * q).round() as usize;
    Some(*v.select_nth_unstable_by(rank, f64::total_cmp).1)
}

/// Widen every Gaussian of `cloud` (its means mapped to the world by `to_world`) by the
/// low-pass footprint of `cameras`.
pub fn widen_cloud(
    cloud: &mut GaussianCloud,
    cameras: &[Camera],
    to_world: impl Fn(Vec3) -> Vec3,
) -> Widened {
    widen_cloud_keeping(cloud, cameras, to_world, |_, _| false)
}

/// As [`widen_cloud`], but a Gaussian for which `flat(cloud, i)` holds keeps its smallest
/// scale: its two largest axes (the plane of its fan) widen and the third does not, so a
/// flat Gaussian stays flat, and a volumetric one, all of whose scales move towards each
/// other, stays volumetric: the converter's classification and triangle count are unchanged.
pub fn widen_cloud_keeping(
    cloud: &mut GaussianCloud,
    cameras: &[Camera],
    to_world: impl Fn(Vec3) -> Vec3,
    flat: impl Fn(&GaussianCloud, usize) -> bool,
) -> Widened {
    widen_cloud_by(cloud, to_world, flat, |p| footprint_variance(p, cameras))
}

/// Widen every Gaussian of `cloud` by the variance `variance` gives at its world position
/// (None: left as it is); `flat` as in [`widen_cloud_keeping`].
pub fn widen_cloud_by(
    cloud: &mut GaussianCloud,
    to_world: impl Fn(Vec3) -> Vec3,
    flat: impl Fn(&GaussianCloud, usize) -> bool,
    variance: impl Fn(DVec3) -> Option<f64>,
) -> Widened {
    let mut out = Widened::default();
    for i in 0..cloud.len() {
        let keep_smallest = flat(cloud, i);
        let p = to_world(cloud.means[i]).as_dvec3();
        let Some(s2) = variance(p) else {
            out.unseen += 1;
            continue;
        };
        let ls = cloud.log_scales[i].as_dvec3();
        // σ' = √(σ² + s²), in log space: ½ ln(e^{2 ln σ} + s²). A non-finite log-scale
        // (an invalid Gaussian the loader kept with --drop-invalid off) stays as it is.
        let widen = |l: f64| {
            if l.is_finite() {
                0.5 * ((2.0 * l).exp() + s2).ln()
            } else {
                l
            }
        };
        let mut w = [widen(ls.x), widen(ls.y), widen(ls.z)];
        if keep_smallest {
            let smallest = (0..3).min_by(|&a, &b| ls[a].total_cmp(&ls[b])).unwrap_or(2);
            w[smallest] = ls[smallest];
        }
        cloud.log_scales[i] = DVec3::from_array(w).as_vec3();
        out.widened += 1;
        out.max_sigma = out.max_sigma.max(s2.sqrt());
    }
    out
}

/// Widen a whole scene for `cameras` resized to `width`×`height` (each keeps its field of
/// view). Errors when there is no camera to size the footprint by.
pub fn widen_scene_for(
    scene: &mut DynamicScene,
    width: u32,
    height: u32,
) -> Result<Widened, String> {
    if scene.cameras.is_empty() {
        return Err(
            "needs cameras to size the footprint by: give --camera, or a scene with cameras".into(),
        );
    }
    let cameras: Vec<Camera> = scene
        .cameras
        .iter()
        .map(|c| c.resized(width, height))
        .collect();
    Ok(widen_scene_with(scene, &cameras, |_, _| false))
}

/// Widen a whole scene for `cameras` as they are (objects at their pose at the clip's start);
/// `flat` as in [`widen_cloud_keeping`].
pub fn widen_scene_with(
    scene: &mut DynamicScene,
    cameras: &[Camera],
    flat: impl Fn(&GaussianCloud, usize) -> bool + Copy,
) -> Widened {
    widen_scene_by(scene, flat, |p| footprint_variance(p, cameras))
}

/// As [`widen_scene_with`], each Gaussian by the views that see it
/// ([`footprint_variance_seen`]).
pub fn widen_scene_seen(
    scene: &mut DynamicScene,
    cameras: &[Camera],
    quantile: f64,
    flat: impl Fn(&GaussianCloud, usize) -> bool + Copy,
) -> Widened {
    widen_scene_by(scene, flat, |p| {
        footprint_variance_seen(p, cameras, quantile)
    })
}

fn widen_scene_by(
    scene: &mut DynamicScene,
    flat: impl Fn(&GaussianCloud, usize) -> bool + Copy,
    variance: impl Fn(DVec3) -> Option<f64> + Copy,
) -> Widened {
    let mut total = widen_cloud_by(&mut scene.static_gaussians, |p| p, flat, variance);
    let t0 = scene.time.start;
    for o in &mut scene.objects {
        let pose = o.track.sample(t0);
        let w = widen_cloud_by(
            &mut o.gaussians,
            |p| pose.transform_point(p),
            flat,
            variance,
        );
        total.widened += w.widened;
        total.unseen += w.unseen;
        total.max_sigma = total.max_sigma.max(w.max_sigma);
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    fn camera(w: u32, h: u32) -> Camera {
        Camera::look_at(DVec3::ZERO, DVec3::Z, DVec3::NEG_Y, 50.0, w, h).unwrap()
    }

    /// The closed form: a Gaussian at depth d gains 0.3 (d/f)² of variance on every axis.
    #[test]
    fn widening_adds_the_low_pass_variance_at_the_gaussians_depth() {
        let cam = camera(64, 48);
        let mut c = GaussianCloud::new(0);
        c.push_activated(
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::new(0.01, 0.02, 0.5),
            Quat::from_rotation_y(0.3),
            0.7,
            Vec3::ONE,
        );
        let before = c.clone();
        let w = widen_cloud(&mut c, std::slice::from_ref(&cam), |p| p);
        assert_eq!(w.widened, 1);
        let s2 = 0.3 * (5.0 / cam.fy.min(cam.fx)).powi(2);
        for (a, b) in [
            (before.log_scales[0].x, c.log_scales[0].x),
            (before.log_scales[0].y, c.log_scales[0].y),
            (before.log_scales[0].z, c.log_scales[0].z),
        ] {
            let want = ((a as f64).exp().powi(2) + s2).sqrt();
            // f32 storage of the log-scale: relative 1e-6 of the scale.
            assert!(
                ((b as f64).exp() - want).abs() < 1e-6 * want,
                "{b} vs {want}"
            );
        }
        assert_eq!(c.rotations[0], before.rotations[0]);
        assert_eq!(c.opacity_logits[0], before.opacity_logits[0]);
    }

    /// The quantile picks among the footprints of the views that see the point (nearest
    /// rank), and views that do not see it take no part.
    #[test]
    fn the_quantile_picks_among_the_views_that_see_the_point() {
        let p = DVec3::new(0.0, 0.0, 4.0);
        // One view at each of five sizes: footprints 1, 1/4, 1/9, 1/16, 1/25 of the smallest
        // size's, all looking at p.
        let cams: Vec<Camera> = [5u32, 4, 3, 2, 1]
            .iter()
            .map(|&k| camera(100 * k, 75 * k))
            .collect();
        let each: Vec<f64> = cams
            .iter()
            .map(|c| footprint_variance(p, std::slice::from_ref(c)).unwrap())
            .collect();
        let seen = |q| footprint_variance_seen(p, &cams, q).unwrap();
        assert_eq!(seen(0.0), each[0]);
        assert_eq!(seen(1.0), each[4]);
        assert_eq!(seen(0.5), each[2]);
        assert_eq!(seen(0.25), each[1]);
        assert_eq!(seen(f64::NAN), each[0]);
        // A view looking away adds nothing, whatever the quantile.
        let away = Camera::look_at(DVec3::ZERO, DVec3::NEG_Z, DVec3::NEG_Y, 50.0, 100, 75).unwrap();
        let mut with_away = cams.clone();
        with_away.push(away.clone());
        assert_eq!(
            footprint_variance_seen(p, &with_away, 1.0).unwrap(),
            each[4]
        );
        assert!(footprint_variance_seen(p, &[away], 0.5).is_none());
    }

    /// Metamorphic: a camera at four times the resolution adds a sixteenth of the variance,
    /// and the nearest camera in front decides; behind every camera nothing changes.
    #[test]
    fn footprint_follows_resolution_and_the_nearest_view() {
        let p = DVec3::new(0.0, 0.0, 4.0);
        let lo = footprint_variance(p, &[camera(100, 75)]).unwrap();
        let hi = footprint_variance(p, &[camera(400, 300)]).unwrap();
        assert!((lo / hi - 16.0).abs() < 1e-9);
        let far = Camera::look_at(
            DVec3::new(0.0, 0.0, -6.0),
            DVec3::Z,
            DVec3::NEG_Y,
            50.0,
            100,
            75,
        )
        .unwrap();
        let both = footprint_variance(p, &[far.clone(), camera(100, 75)]).unwrap();
        assert_eq!(both, lo);
        assert!(footprint_variance(DVec3::new(0.0, 0.0, -1.0), &[camera(100, 75)]).is_none());
    }
}
