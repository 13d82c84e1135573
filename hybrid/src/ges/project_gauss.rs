//! Gaussian projection for pass 2 with the hierarchical depth test folded in.
//!
//! [`project_unhidden`] performs the native renderer's [`crate::project::project_one`] operation
//! for operation (same f64 quantities, same roundings, so the same [`Splat`] and tile rectangle
//! bit for bit; the tests compare them), but stops once the tile rectangle is known when the
//! Gaussian lies behind the largest pass-1 limit of every tile of that rectangle. Such a Gaussian
//! would enter no tile list in binning (whose filter is the same `depth ≤ tile_max` test), so it
//! adds nothing anywhere and the image is unchanged; it only skips the SH colour, the footprint
//! box and its place in the splat array. In a scene whose surfels hide much of the cloud that is
//! most of the projection work.

use splatbridge_scene::{sh, GaussianCloud};

use crate::project::{covariance_2d, covariance_3d, get_rect, Extent, Splat, ViewParams};

/// What [`project_unhidden`] made of a Gaussian.
#[derive(Clone, Copy, Debug)]
pub enum Projection {
    /// `project_one`'s splat and tile rectangle.
    Visible(Splat, [u32; 4]),
    /// Projected, but behind every tile of this rectangle.
    Hidden([u32; 4]),
    /// Culled by `project_one`.
    Culled,
}

/// Project Gaussian `i` as [`crate::project::project_one`] does. The Gaussian is
/// [`Projection::Hidden`] where its view depth (as f32) exceeds `tile_max[t]` (per tile,
/// row-major on the view's grid) for every tile `t` of its rectangle.
#[inline(always)]
pub fn project_unhidden(
    cloud: &GaussianCloud,
    i: usize,
    view: &ViewParams,
    extent: Extent,
    sh_degree: u8,
    tile_max: &[f32],
) -> Projection {
    let rel = cloud.means[i].as_dvec3() - view.centre;
    let t = view.world_to_cam * rel;
    if !t.is_finite() || t.z <= view.near {
        return Projection::Culled;
    }
    let opacity = cloud.opacity(i);
    if !(opacity >= 1.0 / 255.0) {
        return Projection::Culled;
    }
    let sigma = covariance_3d(cloud, i);
    let [a, b, c] = covariance_2d(view, t, &sigma);
    let det = a * c - b * b;
    if !(det > 0.0) || !det.is_finite() {
        return Projection::Culled;
    }
    let conic = [c / det, -b / det, a / det];
    let mid = 0.5 * (a + c);
    let lambda = mid + (mid * mid - det).max(0.1).sqrt();
    let level = (255.0 * opacity as f64).ln();
    let sigmas = match extent {
        Extent::Sigma3 => 3.0,
        Extent::Alpha => (2.0 * level).sqrt(),
    };
    let radius_f = (sigmas * lambda.sqrt()).ceil();
    let x = view.fx * t.x / t.z + view.px0;
    let y = view.fy * t.y / t.z + view.py0;
    if !(radius_f.is_finite() && x.is_finite() && y.is_finite()) {
        return Projection::Culled;
    }
    let radius = radius_f.min(i32::MAX as f64) as i32;
    let rect = get_rect(x, y, radius, view.grid);
    if rect[2] <= rect[0] || rect[3] <= rect[1] {
        return Projection::Culled;
    }
    let depth = t.z as f32;
    let gx = view.grid[0] as usize;
    let seen = (rect[1] as usize..rect[3] as usize).any(|ty| {
        tile_max[ty * gx + rect[0] as usize..ty * gx + rect[2] as usize]
            .iter()
            .any(|&m| depth <= m)
    });
    if !seen {
        return Projection::Hidden(rect);
    }
    let dir = rel.normalize();
    let color = sh::eval_color(sh_degree, cloud.sh_of(i), dir.as_vec3());
    let (xf, yf) = (x as f32, y as f32);
    let splat = Splat {
        x: xf,
        y: yf,
        conic: conic.map(|v| v as f32),
        opacity,
        color: color.to_array(),
        depth,
        bbox: footprint_box_inline(xf as f64, yf as f64, [a, b, c], conic, level),
    };
    Projection::Visible(splat, rect)
}

/// [`crate::project::footprint_box`]'s operations, inlined into the caller so that, in the SSE4.1 projection
/// loop (`super::project_all`), its floor and ceil are single instructions instead of calls (the
/// same IEEE roundings; the tests compare it with `footprint_box` and the projection with
/// `project_one`).
#[inline(always)]
pub(crate) fn footprint_box_inline(
    x: f64,
    y: f64,
    cov: [f64; 3],
    conic: [f64; 3],
    level: f64,
) -> [i32; 4] {
    let half = |l: f64| ((2.0 * l * cov[0]).sqrt(), (2.0 * l * cov[2]).sqrt());
    let (hx, hy) = half(level);
    let b = conic[0].abs() * hx * hx + conic[2].abs() * hy * hy + 2.0 * conic[1].abs() * hx * hy;
    let widened = level * (1.0 + 1e-5) + 1e-5 + 1e-6 * b;
    let (hx, hy) = half(widened);
    let lo = |c: f64, h: f64| (c - h - 0.01).ceil().clamp(-1.0e9, 1.0e9) as i32;
    let hi = |c: f64, h: f64| (c + h + 0.01).floor().clamp(-1.0e9, 1.0e9) as i32;
    [lo(x, hx), lo(y, hy), hi(x, hx), hi(y, hy)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::project::{footprint_box, project_one};
    use glam::DVec3;
    use splatbridge_scene::rng::Rng;
    use splatbridge_scene::Camera;

    /// Every field of a splat, floats as bits.
    fn bits(s: &Splat) -> Vec<u32> {
        let mut v = vec![
            s.x.to_bits(),
            s.y.to_bits(),
            s.opacity.to_bits(),
            s.depth.to_bits(),
        ];
        v.extend(s.conic.map(f32::to_bits));
        v.extend(s.color.map(f32::to_bits));
        v.extend(s.bbox.map(|b| b as u32));
        v
    }

    /// The inlined footprint box is [`footprint_box`], for random covariances, levels and centres
    /// (including centres far off-screen, where the clamp applies).
    #[test]
    fn inlined_footprint_box_matches() {
        let mut rng = Rng::new(77);
        for _ in 0..200_000 {
            let (sa, sb) = (rng.range(0.05, 400.0) as f64, rng.range(0.05, 400.0) as f64);
            let rho = rng.range(-0.99, 0.99) as f64;
            let (a, c, b) = (sa * sa, sb * sb, rho * sa * sb);
            let det = a * c - b * b;
            let conic = [c / det, -b / det, a / det];
            let level = rng.range(0.0, 5.6) as f64;
            let scale = if rng.f32() < 0.1 { 1e10 } else { 3000.0 };
            let (x, y) = (
                rng.range(-1.0, 1.0) as f64 * scale,
                rng.range(-1.0, 1.0) as f64 * scale,
            );
            assert_eq!(
                footprint_box_inline(x, y, [a, b, c], conic, level),
                footprint_box(x, y, [a, b, c], conic, level)
            );
        }
    }

    /// The large fixture seen from inside its region (Gaussians behind the camera, crossing the
    /// near plane, off-screen, faint and opaque), on a small image.
    fn scene() -> (GaussianCloud, ViewParams) {
        let cloud = splatbridge_scene::fixtures::large(20_000, 3);
        let cam = Camera::look_at(
            DVec3::new(3.0, -2.0, -12.0),
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::NEG_Y,
            60.0,
            200,
            120,
        )
        .unwrap();
        (cloud, ViewParams::new(&cam, 0.2))
    }

    /// With no tile limit the result is `project_one`'s, bit for bit, for both extents; with
    /// random tile limits a Gaussian is dropped exactly when every tile of its rectangle hides it.
    #[test]
    fn matches_project_one_and_drops_only_hidden_gaussians() {
        let (cloud, view) = scene();
        let ntiles = (view.grid[0] * view.grid[1]) as usize;
        let open = vec![f32::INFINITY; ntiles];
        let mut rng = Rng::new(9);
        let limits: Vec<f32> = (0..ntiles).map(|_| rng.range(0.0, 30.0)).collect();
        let gx = view.grid[0] as usize;
        for extent in [Extent::Alpha, Extent::Sigma3] {
            let (mut kept, mut hidden) = (0, 0);
            for i in 0..cloud.len() {
                let want = project_one(&cloud, i, &view, extent, 3).ok();
                let got = project_unhidden(&cloud, i, &view, extent, 3, &open);
                match (&want, got) {
                    (Some(p), Projection::Visible(s, r)) => {
                        assert_eq!((bits(&p.splat), p.rect), (bits(&s), r), "Gaussian {i}");
                    }
                    (None, Projection::Culled) => {}
                    _ => panic!("Gaussian {i}: project_one {want:?}, here {got:?}"),
                }
                let got = project_unhidden(&cloud, i, &view, extent, 3, &limits);
                match (want, got) {
                    (Some(p), got) => {
                        let r = p.rect;
                        let visible = (r[1]..r[3]).any(|ty| {
                            (r[0]..r[2])
                                .any(|tx| p.splat.depth <= limits[ty as usize * gx + tx as usize])
                        });
                        match got {
                            Projection::Visible(s, r) if visible => {
                                assert_eq!((bits(&s), r), (bits(&p.splat), p.rect), "Gaussian {i}");
                                kept += 1;
                            }
                            Projection::Hidden(r) if !visible => {
                                assert_eq!(r, p.rect, "Gaussian {i}");
                                hidden += 1;
                            }
                            _ => panic!("Gaussian {i}: visible {visible}, here {got:?}"),
                        }
                    }
                    (None, Projection::Culled) => {}
                    (None, got) => panic!("Gaussian {i}: culled by project_one, here {got:?}"),
                }
            }
            assert!(kept > 1000 && hidden > 1000, "kept {kept}, hidden {hidden}");
        }
    }
}
