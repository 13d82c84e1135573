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
//!
//! 2DGS surfels have another filter ([`LowPass::Surfel2d`]): 2D Gaussian Splatting's
//! rasterizer (`diff-surfel-rasterization`, `forward.cu`) takes `G = max(G(u, v), G(√2·d))`,
//! `d` the pixel's distance to the projected centre, so a surfel is drawn as the larger of
//! itself and a screen-space Gaussian of variance ½ px² about its centre, at its full opacity.
//! Seen face-on, that envelope is the surfel with each in-plane σ raised to the filter's
//! `√½·d/f` (a maximum, not a sum of variances), which is what its fan gets; the third axis
//! stays the derived thickness. An oblique surfel's filter is still round on screen while its
//! fan is foreshortened, and an edge-on one's blob no fan in its plane can show: the rule is
//! the face-on one, the same for every view, as the 3DGS widening is.

use glam::{DVec3, Vec3};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::ply::SURFEL_THICKNESS;
use splatbridge_scene::{Camera, GaussianCloud};

/// Native splatting's screen-space low-pass variance, in pixels² (3DGS `+0.3` on the 2-D
/// covariance's diagonal).
pub const LOW_PASS_PX2: f64 = 0.3;

/// 2D Gaussian Splatting's screen-space filter variance, in pixels²: `forward.cu` compares
/// `FilterInvSquare · |d|²` with `FilterInvSquare = 2` (a σ of `FilterSize = √2/2` px).
pub const SURFEL_LOW_PASS_PX2: f64 = 0.5;

/// Which renderer's screen-space low-pass a mesh is made to stand in for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LowPass {
    /// 3DGS splatting: `+0.3 px²` on the projected covariance, so every σ becomes
    /// `√(σ² + s²)`.
    #[default]
    Splat3d,
    /// 2DGS's rasterizer: the larger of the surfel and a `½ px²` screen Gaussian, so each
    /// in-plane σ becomes `max(σ, s)` and the thickness is derived again.
    Surfel2d,
}

impl LowPass {
    /// The filter's variance in pixels².
    pub fn px2(self) -> f64 {
        match self {
            LowPass::Splat3d => LOW_PASS_PX2,
            LowPass::Surfel2d => SURFEL_LOW_PASS_PX2,
        }
    }

    /// A short description for reports.
    pub fn name(self) -> &'static str {
        match self {
            LowPass::Splat3d => "3DGS's 0.3 px² low-pass",
            LowPass::Surfel2d => "2DGS's ½ px² filter, the larger of surfel and filter",
        }
    }
}

/// What widening did, for the report.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Widened {
    /// The filter the Gaussians were widened by.
    pub low_pass: LowPass,
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
    low_pass_variance(p, cameras, LOW_PASS_PX2)
}

/// As [`footprint_variance`], for a filter of `px2` pixels².
pub fn low_pass_variance(p: DVec3, cameras: &[Camera], px2: f64) -> Option<f64> {
    cameras
        .iter()
        .filter_map(|c| {
            let z = c.to_camera(p).z;
            // A camera's near plane is not part of the model; anything in front counts.
            (z > 0.0 && z.is_finite()).then(|| {
                let f = c.fx.min(c.fy);
                px2 * (z / f) * (z / f)
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
    widen_cloud_by(cloud, to_world, flat, LowPass::Splat3d, |p| {
        footprint_variance(p, cameras)
    })
}

/// Widen every Gaussian of `cloud` by the variance `variance` gives at its world position
/// (None: left as it is), by the rule of `low_pass`; `flat` as in [`widen_cloud_keeping`]
/// (a surfel's thin axis is kept by [`LowPass::Surfel2d`] whatever it says).
pub fn widen_cloud_by(
    cloud: &mut GaussianCloud,
    to_world: impl Fn(Vec3) -> Vec3,
    flat: impl Fn(&GaussianCloud, usize) -> bool,
    low_pass: LowPass,
    variance: impl Fn(DVec3) -> Option<f64>,
) -> Widened {
    let mut out = Widened {
        low_pass,
        ..Widened::default()
    };
    for i in 0..cloud.len() {
        let keep_smallest = flat(cloud, i);
        let p = to_world(cloud.means[i]).as_dvec3();
        let Some(s2) = variance(p) else {
            out.unseen += 1;
            continue;
        };
        out.widened += 1;
        out.max_sigma = out.max_sigma.max(s2.sqrt());
        if low_pass == LowPass::Surfel2d {
            cloud.log_scales[i] = surfel_widened(cloud.log_scales[i], s2);
            continue;
        }
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
    }
    out
}

/// A 2DGS surfel's log-scales raised to the filter's σ = √`s2` on its two in-plane axes
/// (`max` in log space is `max` of the scales), its thickness derived from them as the reader
/// derives it (`scene::ply::SURFEL_THICKNESS`). A non-finite log-scale stays as it is.
fn surfel_widened(ls: Vec3, s2: f64) -> Vec3 {
    let filter = (0.5 * s2.ln()) as f32;
    let raise = |l: f32| if l.is_finite() { l.max(filter) } else { l };
    let (a, b) = (raise(ls.x), raise(ls.y));
    Vec3::new(a, b, a.min(b) + SURFEL_THICKNESS.ln())
}

/// Widen a whole scene for `cameras` resized to `width`×`height` (each keeps its field of
/// view). Errors when there is no camera to size the footprint by.
pub fn widen_scene_for(
    scene: &mut DynamicScene,
    width: u32,
    height: u32,
    low_pass: LowPass,
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
    let px2 = low_pass.px2();
    Ok(widen_scene_by(
        scene,
        |_, _| false,
        low_pass,
        |p| low_pass_variance(p, &cameras, px2),
    ))
}

/// Widen a whole scene for `cameras` as they are (objects at their pose at the clip's start);
/// `flat` as in [`widen_cloud_keeping`].
pub fn widen_scene_with(
    scene: &mut DynamicScene,
    cameras: &[Camera],
    flat: impl Fn(&GaussianCloud, usize) -> bool + Copy,
) -> Widened {
    widen_scene_by(scene, flat, LowPass::Splat3d, |p| {
        footprint_variance(p, cameras)
    })
}

/// As [`widen_scene_with`], each Gaussian by the views that see it
/// ([`footprint_variance_seen`]).
pub fn widen_scene_seen(
    scene: &mut DynamicScene,
    cameras: &[Camera],
    quantile: f64,
    flat: impl Fn(&GaussianCloud, usize) -> bool + Copy,
) -> Widened {
    widen_scene_by(scene, flat, LowPass::Splat3d, |p| {
        footprint_variance_seen(p, cameras, quantile)
    })
}

fn widen_scene_by(
    scene: &mut DynamicScene,
    flat: impl Fn(&GaussianCloud, usize) -> bool + Copy,
    low_pass: LowPass,
    variance: impl Fn(DVec3) -> Option<f64> + Copy,
) -> Widened {
    let mut total = widen_cloud_by(&mut scene.static_gaussians, |p| p, flat, low_pass, variance);
    let t0 = scene.time.start;
    for o in &mut scene.objects {
        let pose = o.track.sample(t0);
        let w = widen_cloud_by(
            &mut o.gaussians,
            |p| pose.transform_point(p),
            flat,
            low_pass,
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

    /// 2DGS's rule in closed form: each in-plane σ becomes max(σ, √½·d/f), the thickness is
    /// derived from the new in-plane pair, and nothing else changes; 3DGS's rule on the same
    /// surfel adds 0.3 (d/f)² instead.
    #[test]
    fn surfels_are_raised_to_the_2dgs_filter() {
        let cam = camera(64, 48);
        let d = 5.0;
        let filter = (SURFEL_LOW_PASS_PX2 * (d / cam.fy.min(cam.fx)).powi(2)).sqrt();
        let mut c = GaussianCloud::new(0);
        // One axis below the filter's σ, one above; the thickness as the 2DGS reader derives it.
        let (a, b) = ((0.2 * filter).ln() as f32, (3.0 * filter).ln() as f32);
        for (la, lb) in [(a, b), (b, b), (a, a), (f32::NAN, a)] {
            c.push(
                Vec3::new(0.0, 0.0, d as f32),
                Vec3::new(la, lb, la.min(lb) + SURFEL_THICKNESS.ln()),
                Quat::from_rotation_y(0.4),
                0.3,
                &[Vec3::ONE],
            );
        }
        let before = c.clone();
        let mut scene = DynamicScene::from_static(c);
        scene.cameras = vec![cam.clone()];
        let w = widen_scene_for(&mut scene, 64, 48, LowPass::Surfel2d).unwrap();
        assert_eq!((w.widened, w.unseen, w.low_pass), (4, 0, LowPass::Surfel2d));
        let c = scene.static_gaussians;
        let lf = filter.ln() as f32;
        // f32 log-scales of f64 values: 1e-6 absolute.
        let near = |x: f32, y: f32| (x - y).abs() < 1e-6;
        let ls = &c.log_scales;
        assert!(near(ls[0].x, lf) && ls[0].y == b, "{}", ls[0]);
        assert_eq!(ls[1], before.log_scales[1], "both axes above: unchanged");
        assert!(near(ls[2].x, lf) && near(ls[2].y, lf), "{}", ls[2]);
        assert!(
            ls[3].x.is_nan() && near(ls[3].y, lf),
            "a NaN axis stays NaN"
        );
        for (i, l) in ls.iter().enumerate().take(3) {
            assert_eq!(l.z, l.x.min(l.y) + SURFEL_THICKNESS.ln(), "surfel {i}");
        }
        assert_eq!(c.rotations, before.rotations);
        assert_eq!(c.opacity_logits, before.opacity_logits);
        assert_eq!(c.means, before.means);
        // 3DGS's rule on the first surfel: the sum of variances at 0.3 px², on every axis.
        let mut s3 = DynamicScene::from_static(before.clone());
        s3.cameras = vec![cam];
        widen_scene_for(&mut s3, 64, 48, LowPass::Splat3d).unwrap();
        let want = ((0.2 * filter).powi(2) + filter * filter * LOW_PASS_PX2 / SURFEL_LOW_PASS_PX2)
            .sqrt()
            .ln();
        assert!((s3.static_gaussians.log_scales[0].x as f64 - want).abs() < 1e-6);
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
