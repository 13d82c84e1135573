//! Pixel footprints of primary rays, and stratified sub-pixel samples.
//!
//! Native 3DGS splatting (Kerbl et al. 2023, `preprocessCUDA`) filters every splat: it adds
//! `0.3 px²` to both diagonal entries of the projected covariance `Σ' = J·W·Σ·Wᵀ·Jᵀ` and keeps
//! the opacity as it is. A single ray per pixel instead point-samples the 3-D Gaussian, so small
//! Gaussians alias. This module gives each primary ray the 3-D widening that reproduces the
//! 2-D low-pass.
//!
//! Derivation. The ray tracer's response of a Gaussian to the ray `o + t·d` is its maximum along
//! the ray, `exp(−½·xᵀ·C⁻¹·x)`, where `x` is the mean's offset projected onto the plane ⊥ d and
//! `C = P·Σ·Pᵀ` the covariance projected (orthographically) onto that plane: the marginal of the
//! Gaussian along `d`. Near the ray the perspective camera maps that plane to pixels by the
//! Jacobian `J` restricted to it, `A = J|⊥d` (`J·d = 0`: moving along the ray does not move the
//! pixel), and `A` at view depth `z` is `A₁/z` with `A₁` its value at unit depth. Native's
//! low-pass `Σ'_2D + s·I` (s = 0.3 px²) pulled back through `A` is the perpendicular covariance
//! `Δ = s·(AᵀA)⁻¹ = s·z²·(A₁ᵀA₁)⁻¹`: adding `Δ` to `C` gives, through `A`, exactly
//! `A·C·Aᵀ + s·I`. Any 3-D covariance whose projection onto the plane ⊥ d is `Δ` does the same
//! (the component along the ray is integrated out by the max-along-the-ray response).
//! On the optical axis `Δ = s·z²/f²·I`, an isotropic ray cone of `√s` pixels; off axis the
//! radial direction is narrower by `cos θ` (the image plane is oblique there), which the exact
//! `A₁` carries.
//!
//! Depth: `z` is the view depth of the Gaussian's mean, where native evaluates `J`, not the hit
//! distance along the ray; the two differ by the Gaussian's own extent. This makes the widened
//! Gaussian one fixed Gaussian per camera, as native's splat is, and lets the BVH proxies be
//! padded exactly (see [`pad_for`]).
//!
//! Opacity: native 3DGS does not rescale the opacity by `sqrt(det Σ'/det(Σ' + s·I))` (the
//! hybrid's `project.rs` adds `DILATION` and keeps `opacity`; Mip-Splatting's compensation is not
//! the reference), so the widened Gaussian here keeps its peak opacity `o` too: a sub-pixel
//! Gaussian grows to about a pixel and gains energy, exactly as in native.
//!
//! What native does that this does not: its `J` is clamped at `1.3·tan(fov/2)` for means far
//! outside the view, and the whole Gaussian shares the `J` of its mean (the affine EWA
//! approximation), whereas the tracer's `A` follows each ray. Secondary rays (shadows, LiDAR)
//! carry no footprint: they are not pixels of the rendered image and keep today's exact
//! point-sampled response.
//!
//! Sub-pixel samples: `spp` samples per pixel on a fixed stratified pattern (a `k×k` grid of
//! cell centres when `spp = k²`, otherwise the Hammersley set of `spp` points), averaged with a
//! box filter. With `spp > 1` a sample's footprint is by default that of its sub-pixel
//! (`s/spp`, [`SampleFootprint::Subpixel`]), or the whole pixel's (`s`,
//! [`SampleFootprint::Pixel`]).

use glam::{DMat2, DVec2, DVec3};
use splatbridge_scene::Camera;

/// Native's low-pass variance in pixels² (`project::DILATION` of the hybrid crate, the
/// reference's `+0.3` in `computeCov2D`).
pub const LOW_PASS_PX2: f64 = 0.3;

/// Whether primary rays in mode `gaussian` carry their pixel footprint.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Footprint {
    /// Point-sampled response (3DGRT's): the exact 3-D Gaussian along the ray.
    #[default]
    Off,
    /// Each Gaussian widened by the ray's pixel footprint at its depth (native's low-pass).
    On,
    /// Each Gaussian evaluated as native's projection does: the EWA 2-D conic with the
    /// low-pass at the ray's pixel (pinhole primary rays; see `gaussian::camera`).
    Projected,
}

/// Order of a primary ray's hits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum HitOrder {
    /// By the distance of maximum response along the ray, `t*` (3DGRT's).
    #[default]
    Hit,
    /// By the view depth of the Gaussian's mean, as native splatting's global sort.
    MeanDepth,
}

/// Direction a primary ray's hit evaluates the Gaussian's SH in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ShDirection {
    /// The ray's direction (3DGRT's).
    #[default]
    Ray,
    /// From the camera centre toward the Gaussian's mean, as native splatting.
    Mean,
}

impl ShDirection {
    /// `trace`'s default: native's direction whenever a footprint is on (the parity mode,
    /// which takes native's hit order too; it also lets a frame evaluate each Gaussian's
    /// colour once instead of once per hit), the ray's with the footprint off (3DGRT's model).
    pub fn for_footprint(footprint: Footprint) -> Self {
        match footprint {
            Footprint::Off => ShDirection::Ray,
            Footprint::On | Footprint::Projected => ShDirection::Mean,
        }
    }
}

/// Which footprint a sub-pixel sample carries when `spp > 1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SampleFootprint {
    /// The sub-pixel's: `0.3/spp` px² (the ray cone of the sub-pixel).
    #[default]
    Subpixel,
    /// The whole pixel's `0.3` px² on every sample (the box filter then blurs on top).
    Pixel,
}

impl SampleFootprint {
    /// Low-pass variance in pixels² of one of `spp` samples.
    pub fn variance_px2(self, spp: u32) -> f64 {
        match self {
            SampleFootprint::Subpixel => LOW_PASS_PX2 / spp.max(1) as f64,
            SampleFootprint::Pixel => LOW_PASS_PX2,
        }
    }
}

/// A primary ray's footprint: the widening covariance `Δ/z²` in the basis `(e1, e2)` of the
/// plane ⊥ d (world frame), and the camera's forward axis to take the view depth `z` of a mean.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayFootprint {
    pub forward: DVec3,
    pub e1: DVec3,
    pub e2: DVec3,
    /// `(a, b, c)` of the symmetric `s·(A₁ᵀA₁)⁻¹` (world units² per unit depth²).
    pub cov: [f64; 3],
    /// The ray's continuous pixel position `(u, v)` (pixel `i` spans `[i, i + 1)`).
    pub pixel: (f64, f64),
}

impl RayFootprint {
    /// Footprint of the pinhole ray with unit direction `d` of `cam`, for a low-pass of
    /// `variance_px2` pixels². None when `d` does not point in front of the camera.
    pub fn pinhole(cam: &Camera, d: DVec3, variance_px2: f64) -> Option<Self> {
        let w = cam.world_to_cam;
        let (forward, pc) = unit_depth_point(cam, d)?;
        // Rows of J at unit depth, carried to world: Wᵀ·j.
        let m0 = w.transpose() * DVec3::new(cam.fx, 0.0, -cam.fx * pc.x);
        let m1 = w.transpose() * DVec3::new(0.0, cam.fy, -cam.fy * pc.y);
        let (e1, e2) = d.any_orthonormal_pair();
        let a = DMat2::from_cols(
            DVec2::new(m0.dot(e1), m1.dot(e1)),
            DVec2::new(m0.dot(e2), m1.dot(e2)),
        );
        let g = a.transpose() * a;
        if !(g.determinant() > 0.0) {
            return None;
        }
        let inv = g.inverse() * variance_px2;
        let cov = [inv.x_axis.x, inv.y_axis.x, inv.y_axis.y];
        let pixel = pixel_of(cam, pc);
        cov.iter().all(|v| v.is_finite()).then_some(RayFootprint {
            forward,
            e1,
            e2,
            cov,
            pixel,
        })
    }
}

/// The camera's forward axis and the camera coordinates `(x, y, 1)` of the point at unit view
/// depth on the ray of unit direction `d`; None when `d` does not point in front of the camera.
fn unit_depth_point(cam: &Camera, d: DVec3) -> Option<(DVec3, DVec3)> {
    let w = cam.world_to_cam;
    let forward = w.row(2);
    let dz = d.dot(forward);
    if !(dz > 0.0) {
        return None;
    }
    Some((forward, w * (d / dz)))
}

/// The continuous pixel of the camera point `pc` at unit depth.
fn pixel_of(cam: &Camera, pc: DVec3) -> (f64, f64) {
    (cam.fx * pc.x + cam.cx, cam.fy * pc.y + cam.cy)
}

/// The pixel position [`RayFootprint::pinhole`] gives the ray of unit direction `d` (the same
/// numbers), without the rest of its footprint; None where `pinhole` is None for that reason.
pub fn pinhole_pixel(cam: &Camera, d: DVec3) -> Option<(f64, f64)> {
    unit_depth_point(cam, d).map(|(_, pc)| pixel_of(cam, pc))
}

/// Whether [`RayFootprint::pinhole`] gives a footprint to every ray of `cam` through its image
/// `[0, width] × [0, height]`, so that a renderer may take [`pinhole_pixel`] alone and work out
/// the rest only for the rays that need it.
///
/// Why a check of the frame suffices: `pinhole` is None only when the ray is not in front, or
/// when `g = AᵀA` has no positive determinant or `s·g⁻¹` is not finite. For a pinhole ray
/// `d ∝ Wᵀ(x, y, 1)`, `det A = ±fx·fy/|(x, y, 1)|`, so `det g = (fx·fy·cos θ)²`, with `θ` the
/// ray's angle to the optical axis, and g's condition number is at most
/// `(max(fx, fy)/min(fx, fy))²/cos²θ`. Over the image, `cos θ` is smallest at a corner (the
/// farthest point from the principal point). With focal lengths within 1e-30…1e30 and a
/// ratio of at most 1e3, corners at `cos θ ≥ 1e-3` and a finite variance, the condition number
/// is below 1e12, so f64 rounding (relative 1e-16 per operation) leaves `det g` positive by
/// ten orders of magnitude, and `g`, its inverse and `cov` far from overflow. The corners'
/// own footprints are checked as well.
pub fn covers_frame(cam: &Camera, variance_px2: f64) -> bool {
    let focal = |f: f64| (1e-30..=1e30).contains(&f);
    let ratio = cam.fx / cam.fy;
    if !(focal(cam.fx) && focal(cam.fy) && (1e-3..=1e3).contains(&ratio))
        || !(variance_px2.is_finite() && variance_px2 >= 0.0)
        || !(cam.cx.is_finite() && cam.cy.is_finite())
    {
        return false;
    }
    let (w, h) = (cam.width as f64, cam.height as f64);
    [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
        .iter()
        .all(|&(u, v)| {
            let d = cam.ray_dir(u, v);
            d.dot(cam.world_to_cam.row(2)) >= 1e-3
                && RayFootprint::pinhole(cam, d, variance_px2).is_some()
        })
}

/// Half-width to add on every axis to the box of a Gaussian whose mean is at view depth `z`, so
/// that the box holds the widened Gaussian's `r`-σ ellipsoid for every ray of `cam`: the
/// widened ellipsoid lies in the original one plus a ball of radius `r·σ` with `σ² ≥` the
/// largest eigenvalue of `Δ`, which is at most `s·z²/min(fx, fy)²` (the smallest singular value
/// of `A₁` is at least `min(fx, fy)`: `f` across the ray and `f/cos θ` along its radius).
pub fn pad_for(cam: &Camera, variance_px2: f64, z: f64, r: f64) -> f64 {
    if !(z > 0.0) {
        return 0.0;
    }
    r * variance_px2.sqrt() * z / cam.fx.min(cam.fy)
}

/// Sub-pixel offsets in `[0, 1)²` of `spp` samples: the centres of a `k×k` grid when
/// `spp = k²` (so `spp = 1` is the pixel centre, today's sample), else the Hammersley set
/// `((i + ½)/spp, radical_inverse₂(i) + ½/spp)`. Fixed: no random numbers, independent of
/// threads.
pub fn sample_offsets(spp: u32) -> Vec<(f64, f64)> {
    let n = spp.max(1);
    let k = (n as f64).sqrt().round() as u32;
    if k * k == n {
        let mut v = Vec::with_capacity(n as usize);
        for j in 0..k {
            for i in 0..k {
                v.push(((i as f64 + 0.5) / k as f64, (j as f64 + 0.5) / k as f64));
            }
        }
        return v;
    }
    (0..n)
        .map(|i| {
            let r = (i.reverse_bits() as f64) / 4_294_967_296.0;
            ((i as f64 + 0.5) / n as f64, (r + 0.5 / n as f64).fract())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(w: u32, h: u32, fov_y: f64) -> Camera {
        Camera::look_at(
            DVec3::ZERO,
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(0.0, -1.0, 0.0),
            fov_y,
            w,
            h,
        )
        .unwrap()
    }

    /// `pinhole_pixel` is `pinhole`'s pixel bit for bit, and `covers_frame` holds exactly
    /// where it should: ordinary views of any aspect and principal point, not views whose
    /// corners reach 89.9° off axis, focal lengths out of range or a huge aspect of pixels.
    #[test]
    fn pixel_alone_and_frames_covered() {
        let eye = DVec3::new(0.3, -0.2, 0.1);
        let target = DVec3::new(-0.4, 0.5, 3.0);
        for (fov, w, h) in [(50.0, 64, 48), (120.0, 30, 90), (5.0, 200, 10)] {
            let mut c = Camera::look_at(eye, target, DVec3::NEG_Y, fov, w, h).unwrap();
            c.cx += 7.25;
            assert!(covers_frame(&c, 0.3), "{fov}° {w}×{h}");
            for j in 0..=h {
                for i in 0..=w {
                    let d = c.ray_dir(i as f64 * 0.999, j as f64 * 0.999);
                    let f = RayFootprint::pinhole(&c, d, 0.3).unwrap();
                    let p = pinhole_pixel(&c, d).unwrap();
                    assert_eq!(
                        (p.0.to_bits(), p.1.to_bits()),
                        (f.pixel.0.to_bits(), f.pixel.1.to_bits())
                    );
                }
            }
            assert!(pinhole_pixel(&c, -c.world_to_cam.row(2)).is_none());
        }
        let c = Camera::look_at(eye, target, DVec3::NEG_Y, 179.9, 64, 48).unwrap();
        assert!(!covers_frame(&c, 0.3), "corners 89.9° off axis");
        let base = Camera::look_at(eye, target, DVec3::NEG_Y, 50.0, 64, 48).unwrap();
        for (fx, fy) in [(1e-31, 1e-31), (1e31, 1e31), (1e4, 1.0)] {
            let c = Camera {
                fx,
                fy,
                ..base.clone()
            };
            assert!(!covers_frame(&c, 0.3), "fx {fx} fy {fy}");
        }
        assert!(!covers_frame(&base, f64::NAN));
    }

    #[test]
    fn on_axis_footprint_is_the_isotropic_pixel_cone() {
        let c = cam(101, 101, 50.0);
        let d = c.ray_dir(c.cx, c.cy);
        let fp = RayFootprint::pinhole(&c, d, 0.3).unwrap();
        // s/f² exactly on the axis; 1e-12 relative is f64 rounding of a few products.
        let want = 0.3 / (c.fx * c.fx);
        assert!((fp.cov[0] - want).abs() < 1e-12 * want);
        assert!((fp.cov[2] - want).abs() < 1e-12 * want);
        assert!(fp.cov[1].abs() < 1e-12 * want);
    }

    #[test]
    fn footprint_pulls_back_to_the_screen_low_pass() {
        // Off axis: A·Δ·Aᵀ must be s·I for the finite-difference Jacobian of the projection.
        let c = cam(200, 100, 70.0);
        let d = c.ray_dir(180.0, 10.0);
        let fp = RayFootprint::pinhole(&c, d, 0.3).unwrap();
        let z = 3.0;
        let p = c.centre + d * (z / d.dot(fp.forward));
        let proj = |q: DVec3| {
            let v = c.world_to_cam * (q - c.centre);
            DVec2::new(c.fx * v.x / v.z, c.fy * v.y / v.z)
        };
        let h = 1e-6;
        let col = |e: DVec3| (proj(p + e * h) - proj(p - e * h)) / (2.0 * h);
        let a = DMat2::from_cols(col(fp.e1), col(fp.e2));
        let delta = DMat2::from_cols(
            DVec2::new(fp.cov[0], fp.cov[1]),
            DVec2::new(fp.cov[1], fp.cov[2]),
        ) * (z * z);
        let s = a * delta * a.transpose();
        // Central differences with h = 1e-6 at depth 3 are good to about 1e-7 relative.
        assert!((s.x_axis.x - 0.3).abs() < 1e-5, "{s:?}");
        assert!((s.y_axis.y - 0.3).abs() < 1e-5, "{s:?}");
        assert!(s.x_axis.y.abs() < 1e-5, "{s:?}");
        // And the padding bound holds: the largest eigenvalue of Δ is below pad²/r².
        let tr = delta.x_axis.x + delta.y_axis.y;
        let det = delta.determinant();
        let lmax = 0.5 * tr + (0.25 * tr * tr - det).max(0.0).sqrt();
        let pad = pad_for(&c, 0.3, z, 1.0);
        assert!(lmax <= pad * pad * (1.0 + 1e-12));
    }

    #[test]
    fn offsets_are_stratified_and_fixed() {
        assert_eq!(sample_offsets(1), vec![(0.5, 0.5)]);
        let g = sample_offsets(4);
        assert_eq!(
            g,
            vec![(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]
        );
        for n in [2u32, 3, 5, 8] {
            let s = sample_offsets(n);
            assert_eq!(s.len(), n as usize);
            // One sample per column stratum 1/n wide.
            for (i, (x, y)) in s.iter().enumerate() {
                assert!((*x * n as f64).floor() as usize == i);
                assert!((0.0..1.0).contains(y));
            }
        }
    }
}
