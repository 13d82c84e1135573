//! Fitting, validation and held-back views.
//!
//! A distilled export is looked at from anywhere, at any size, so the default fitting set
//! covers the view sphere ([`sphere`]): elevations from below the horizon to high above
//! ([`FIT_ELEVATIONS`]), distances from close-ups to beyond the orbit's ([`FIT_DISTANCES`]),
//! and several image sizes up to 1080p ([`DEFAULT_SIZES`]). The views are a
//! low-discrepancy (R-sequence, Roberts 2018) sample of that space, so any count covers it
//! evenly. A view larger than the fitting window is fitted through a window of it
//! ([`window_of`]): the same focal length and principal point, a smaller pixel grid. Its
//! pixels are the big view's pixels exactly, so a 1080p view's footprint is fitted at the
//! cost of a 240×180 image. Each window is placed over the view's content
//! ([`content_point`]): its centre is a projected Gaussian drawn by opacity × area on
//! screen, so on a small object the windows of the large sizes fit the object, not the
//! background around it.
//!
//! Held-back views ([`held_back_classes`]) are drawn apart from the fitting ones: other
//! elevations and distances, named by class, at the measured sizes, each nudged in azimuth
//! until it is at least [`MIN_APART_DEG`] from every fitting and validation view's direction.
//! The `orbit:N` rig keeps its own held-back views half-way between its cameras ([`held_back`]).

use glam::DVec3;
use splatbridge_scene::camera::OrbitRig;
use splatbridge_scene::{Camera, GaussianCloud, SceneError};

type SResult<T> = splatbridge_scene::Result<T>;

/// Elevations of the fitting views, degrees above the scene centre's horizontal plane.
pub const FIT_ELEVATIONS: (f64, f64) = (-15.0, 70.0);
/// Distances of the fitting views, in units of the orbit rig's distance.
pub const FIT_DISTANCES: (f64, f64) = (0.5, 1.2);
/// Image sizes fitted when no target size is named: from a small preview to 1080p.
pub const DEFAULT_SIZES: [(u32, u32); 4] = [(320, 240), (640, 480), (1280, 720), (1920, 1080)];
/// The fitting window: views larger than this are fitted through a window of this size.
pub const WINDOW: (u32, u32) = (240, 180);
/// No held-back view's direction is closer than this to a fitting or validation view's.
pub const MIN_APART_DEG: f64 = 5.0;

/// The orbit rig's frame around a cloud: centre, distance (the rig's), up and two horizontal
/// axes, as [`OrbitRig::camera_around`] places its cameras.
#[derive(Clone, Debug)]
pub struct Frame {
    pub centre: DVec3,
    pub distance: f64,
    up: DVec3,
    e1: DVec3,
    e2: DVec3,
    fov_y_deg: f64,
}

impl Frame {
    /// The frame of the default orbit rig around `cloud` (its bounds: [`OrbitRig::bounds`]).
    pub fn around(cloud: &GaussianCloud) -> SResult<Frame> {
        let rig = OrbitRig::default();
        let (lo, hi) = rig
            .bounds(cloud)
            .map_err(|_| SceneError::Invalid("cannot place views around an empty scene".into()))?;
        let p = rig.placement(lo, hi);
        Ok(Frame {
            centre: p.centre,
            distance: p.distance,
            up: p.up,
            e1: p.e1,
            e2: p.e2,
            fov_y_deg: rig.fov_y_deg,
        })
    }

    /// Unit direction from the centre at `elevation_deg` and azimuth `azimuth_deg` (the
    /// orbit's: azimuth 0 is its camera 0).
    pub fn direction(&self, elevation_deg: f64, azimuth_deg: f64) -> DVec3 {
        let (el, az) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
        (self.e1 * az.cos() + self.e2 * az.sin()) * el.cos() + self.up * el.sin()
    }

    /// A camera looking at the centre from `direction` at `factor` times the orbit's
    /// distance, the rig's field of view, `width`×`height`.
    pub fn camera(
        &self,
        direction: DVec3,
        factor: f64,
        width: u32,
        height: u32,
    ) -> SResult<Camera> {
        Camera::look_at(
            self.centre + direction * self.distance * factor,
            self.centre,
            self.up,
            self.fov_y_deg,
            width,
            height,
        )
    }

    /// The angle in degrees between the directions from the centre to two camera centres.
    pub fn angle_deg(&self, a: &Camera, b: &Camera) -> f64 {
        let (u, v) = (a.centre - self.centre, b.centre - self.centre);
        let c = u.dot(v) / (u.length() * v.length()).max(1e-300);
        c.clamp(-1.0, 1.0).acos().to_degrees()
    }
}

/// Point `i` of the d-dimensional R-sequence (Roberts 2018): `frac(0.5 + i·αₖ)` with
/// `αₖ = φ_d^−k`, `φ_d` the root of `x^(d+1) = x + 1`. Successive points fill the unit cube
/// evenly for any count.
fn r_sequence<const D: usize>(i: usize) -> [f64; D] {
    let mut phi = 2.0f64;
    for _ in 0..30 {
        phi = (1.0 + phi).powf(1.0 / (D as f64 + 1.0));
    }
    let mut out = [0.0; D];
    for (k, o) in out.iter_mut().enumerate() {
        let a = phi.powi(-(k as i32 + 1));
        *o = (0.5 + a * i as f64).fract();
    }
    out
}

/// Point `i` of the fitting distribution: a camera at an elevation in [`FIT_ELEVATIONS`]
/// (uniform in sin, so uniform in area over the band), any azimuth, a distance in
/// [`FIT_DISTANCES`], the size `sizes[i mod len]`, seen through a `window`-sized window over
/// the view's content ([`content_window`], the sequence's fourth and fifth coordinates
/// pick the place). Returns the window and the whole view. `fine`: the view at the range's
/// fine end instead, the nearest distance and the largest size (by pixels) of `sizes`.
fn sphere_view(
    cloud: &GaussianCloud,
    f: &Frame,
    i: usize,
    sizes: &[(u32, u32)],
    window: (u32, u32),
    fine: bool,
) -> SResult<(Camera, Camera)> {
    let [a, b, c, u, v] = r_sequence::<5>(i);
    let (s0, s1) = (
        FIT_ELEVATIONS.0.to_radians().sin(),
        FIT_ELEVATIONS.1.to_radians().sin(),
    );
    let el = (s0 + (s1 - s0) * a).asin().to_degrees();
    let (factor, (w, h)) = if fine {
        let largest = sizes
            .iter()
            .copied()
            .max_by_key(|&(w, h)| u64::from(w) * u64::from(h));
        (FIT_DISTANCES.0, largest.unwrap_or(sizes[0]))
    } else {
        (
            FIT_DISTANCES.0 + (FIT_DISTANCES.1 - FIT_DISTANCES.0) * c,
            sizes[i % sizes.len()],
        )
    };
    let mut cam = f.camera(f.direction(el, 360.0 * b), factor, w, h)?;
    cam.name = format!("sphere {i}: {el:.0}°, {factor:.2}×, {w}×{h}");
    Ok((content_window(cloud, &cam, window, u, v), cam))
}

/// Fitting views and the whole views they are windows of.
#[derive(Clone, Debug, Default)]
pub struct Windows {
    /// What is fitted: each at most the window's size.
    pub windows: Vec<Camera>,
    /// The whole view of each window (the footprint is sized by these).
    pub frames: Vec<Camera>,
}

/// `n` fitting views over the view sphere around `cloud` ([`sphere_view`], points 0..n).
pub fn sphere(
    cloud: &GaussianCloud,
    n: usize,
    sizes: &[(u32, u32)],
    window: (u32, u32),
) -> SResult<Windows> {
    sphere_range(cloud, 0..n, sizes, window)
}

/// `n` fitting views over the view sphere ([`sphere`]) and `fine` more at the distribution's
/// fine end ([`fine_end_range`], the points after them): the nearest distance at the largest
/// size, which a fit through small windows of mostly small or far views otherwise sees
/// rarely, and makes worse (`docs/distill-fine-end.md`). Validation views take the points
/// after these.
pub fn sphere_with_fine(
    cloud: &GaussianCloud,
    n: usize,
    fine: usize,
    sizes: &[(u32, u32)],
    window: (u32, u32),
) -> SResult<Windows> {
    let mut w = sphere_range(cloud, 0..n, sizes, window)?;
    let f = fine_end_range(cloud, n..n + fine, sizes, window)?;
    w.windows.extend(f.windows);
    w.frames.extend(f.frames);
    Ok(w)
}

/// Views `range` of the fitting distribution: validation views take the points after the
/// fitting ones, so they are never fitted and fall where the fit's views do.
pub fn sphere_range(
    cloud: &GaussianCloud,
    range: std::ops::Range<usize>,
    sizes: &[(u32, u32)],
    window: (u32, u32),
) -> SResult<Windows> {
    views_of(cloud, range, sizes, window, false)
}

/// Views `range` of the fitting distribution moved to its fine end: each at the nearest
/// distance ([`FIT_DISTANCES`]) and the largest of `sizes`, where a view shows the most
/// detail the export is made for. Validation views of this kind see what the fitting views,
/// mostly small or far, rarely do: a fit that learns the blur of small views and loses at
/// 1080p close-ups (`docs/distill-fine-end.md`).
pub fn fine_end_range(
    cloud: &GaussianCloud,
    range: std::ops::Range<usize>,
    sizes: &[(u32, u32)],
    window: (u32, u32),
) -> SResult<Windows> {
    views_of(cloud, range, sizes, window, true)
}

/// The validation views of a fit whose fitting views took points `0..n`: `count` views of
/// the fitting distribution, then `fine` at its fine end ([`fine_end_range`]), from the
/// points after the fitting ones, so none is ever fitted.
pub fn validation_views(
    cloud: &GaussianCloud,
    n: usize,
    count: usize,
    fine: usize,
    sizes: &[(u32, u32)],
    window: (u32, u32),
) -> SResult<Windows> {
    let mut v = sphere_range(cloud, n..n + count, sizes, window)?;
    let f = fine_end_range(cloud, n + count..n + count + fine, sizes, window)?;
    v.windows.extend(f.windows);
    v.frames.extend(f.frames);
    Ok(v)
}

fn views_of(
    cloud: &GaussianCloud,
    range: std::ops::Range<usize>,
    sizes: &[(u32, u32)],
    window: (u32, u32),
    fine: bool,
) -> SResult<Windows> {
    if sizes.is_empty() {
        return Err(SceneError::Invalid("no image size to fit".into()));
    }
    let f = Frame::around(cloud)?;
    let mut out = Windows::default();
    for i in range {
        let (w, c) = sphere_view(cloud, &f, i, sizes, window, fine)?;
        out.windows.push(w);
        out.frames.push(c);
    }
    Ok(out)
}

/// The window of `cam` of at most `window` pixels whose top-left corner is at fraction
/// (`u`, `v`) of the free room: same focal length and view, the principal point moved by
/// the (whole-pixel) offset, so the window's pixels are `cam`'s. A camera that fits in the
/// window is returned as it is.
pub fn window_of(cam: &Camera, window: (u32, u32), u: f64, v: f64) -> Camera {
    let (w, h) = (window.0.min(cam.width), window.1.min(cam.height));
    let x0 = (cam.width - w) as f64 * u.clamp(0.0, 1.0);
    let y0 = (cam.height - h) as f64 * v.clamp(0.0, 1.0);
    window_at(cam, window, x0, y0)
}

/// The window of `cam` of at most `window` pixels with its top-left corner at pixel
/// (`x0`, `y0`), rounded down to whole pixels and kept inside the image.
pub fn window_at(cam: &Camera, window: (u32, u32), x0: f64, y0: f64) -> Camera {
    let (w, h) = (window.0.min(cam.width), window.1.min(cam.height));
    if (w, h) == (cam.width, cam.height) {
        return cam.clone();
    }
    let fit = |x: f64, room: u32| {
        if x.is_finite() {
            x.floor().clamp(0.0, room as f64)
        } else {
            0.0
        }
    };
    let (x0, y0) = (fit(x0, cam.width - w), fit(y0, cam.height - h));
    Camera {
        width: w,
        height: h,
        cx: cam.cx - x0,
        cy: cam.cy - y0,
        name: format!("{} [window {w}×{h} at {x0},{y0}]", cam.name),
        ..cam.clone()
    }
}

/// Where `cam` sees Gaussian `i` of `cloud` and how much of its image the Gaussian takes:
/// its centre's pixel, and its opacity × its area on screen (π·σ₁σ₂ of its two largest
/// axes at its centre's depth, plus native's 0.3 px² low-pass), capped at `cap` pixels so
/// that one huge Gaussian cannot outweigh the scene. `None` when its centre is behind the
/// camera or outside the image, or the weight is not a positive number.
fn on_screen(cloud: &GaussianCloud, cam: &Camera, i: usize, cap: f64) -> Option<(f64, f64, f64)> {
    let q = cam.to_camera(cloud.means[i].as_dvec3());
    if !(q.z > 0.0 && q.z.is_finite()) {
        return None;
    }
    let (x, y) = (cam.fx * q.x / q.z + cam.cx, cam.fy * q.y / q.z + cam.cy);
    if !((0.0..cam.width as f64).contains(&x) && (0.0..cam.height as f64).contains(&y)) {
        return None;
    }
    let s = cloud.scale(i).as_dvec3();
    let (a, b) = if s.x >= s.y && s.x >= s.z {
        (s.x, s.y.max(s.z))
    } else if s.y >= s.z {
        (s.y, s.x.max(s.z))
    } else {
        (s.z, s.x.max(s.y))
    };
    let sigma2 = a * b * cam.fx * cam.fy / (q.z * q.z);
    let area = (std::f64::consts::PI * sigma2 + 0.3).min(cap);
    let weight = cloud.opacity(i) as f64 * area;
    (weight > 0.0 && weight.is_finite()).then_some((x, y, weight))
}

/// The pixel of `cam` where the content-weighted draw `t` ∈ [0, 1) lands: the Gaussians whose
/// centres `cam` sees, each weighted by its opacity × area on screen ([`on_screen`]), laid
/// end to end in the cloud's order; `t` picks the point at that fraction of the total
/// weight. Deterministic (a low-discrepancy `t` spreads draws over the content) and
/// allocation-free: one pass sums the weights, a second finds the drawn Gaussian. `None`
/// when `cam` sees no Gaussian centre.
pub fn content_point(
    cloud: &GaussianCloud,
    cam: &Camera,
    window: (u32, u32),
    t: f64,
) -> Option<(f64, f64)> {
    let cap = window.0 as f64 * window.1 as f64;
    let total: f64 = (0..cloud.len())
        .filter_map(|i| on_screen(cloud, cam, i, cap))
        .map(|(_, _, w)| w)
        .sum();
    if !(total > 0.0 && total.is_finite()) {
        return None;
    }
    let goal = t.clamp(0.0, 1.0) * total;
    let mut sum = 0.0;
    let mut last = None;
    for i in 0..cloud.len() {
        if let Some((x, y, w)) = on_screen(cloud, cam, i, cap) {
            sum += w;
            last = Some((x, y));
            if sum >= goal {
                break;
            }
        }
    }
    last
}

/// The window of `cam` centred, as far as the image allows, on the content point drawn by
/// `t` ([`content_point`]); a view that sees no Gaussian centre is windowed at fraction
/// (`t`, `s`) of its free room instead ([`window_of`]). A view that fits in the window is
/// returned as it is.
pub fn content_window(
    cloud: &GaussianCloud,
    cam: &Camera,
    window: (u32, u32),
    t: f64,
    s: f64,
) -> Camera {
    let (w, h) = (window.0.min(cam.width), window.1.min(cam.height));
    if (w, h) == (cam.width, cam.height) {
        return cam.clone();
    }
    match content_point(cloud, cam, window, t) {
        Some((x, y)) => window_at(cam, window, x - 0.5 * w as f64, y - 0.5 * h as f64),
        None => window_of(cam, window, t, s),
    }
}

/// The smallest frame centred on `cam`'s principal point that holds its image, and the
/// offset of `cam`'s pixels in it. Native splatting derives its Jacobian clamp from a centred
/// frame's field of view (`1.3·tan(fov/2)` about the axis), so an off-centre window is
/// rendered through this frame and cut: clamped are only Gaussians whose centres lie beyond
/// 1.3× the frame, outside the window.
pub fn frame_of(cam: &Camera) -> (Camera, u32, u32) {
    let half = |c: f64, n: u32| c.max(n as f64 - c).max(0.5).ceil();
    let (hx, hy) = (half(cam.cx, cam.width), half(cam.cy, cam.height));
    let (x0, y0) = ((hx - cam.cx).round(), (hy - cam.cy).round());
    if x0 == 0.0 && y0 == 0.0 && (2.0 * hx) as u32 == cam.width && (2.0 * hy) as u32 == cam.height {
        return (cam.clone(), 0, 0);
    }
    let full = Camera {
        width: (2.0 * hx) as u32,
        height: (2.0 * hy) as u32,
        cx: cam.cx + x0,
        cy: cam.cy + y0,
        ..cam.clone()
    };
    (full, x0 as u32, y0 as u32)
}

/// Whether world point `p` is in front of `cam` and inside its image, with a margin of
/// `margin` of the image's size on every side.
pub fn sees(cam: &Camera, p: DVec3, margin: f64) -> bool {
    let q = cam.to_camera(p);
    if !(q.z > 0.0 && q.z.is_finite()) {
        return false;
    }
    let (x, y) = (cam.fx * q.x / q.z + cam.cx, cam.fy * q.y / q.z + cam.cy);
    let (w, h) = (cam.width as f64, cam.height as f64);
    (-margin * w..=(1.0 + margin) * w).contains(&x)
        && (-margin * h..=(1.0 + margin) * h).contains(&y)
}

/// Windows of given cameras (`--views` lists, the scene's own cameras): each camera larger
/// than the window gives `per` windows over its content ([`content_window`]), at places the
/// R-sequence spreads over it.
pub fn windows_of(
    cloud: &GaussianCloud,
    cams: &[Camera],
    per: usize,
    window: (u32, u32),
) -> Windows {
    let mut out = Windows::default();
    let mut k = 0;
    for c in cams {
        let fits = c.width <= window.0 && c.height <= window.1;
        for _ in 0..if fits { 1 } else { per.max(1) } {
            let [u, v] = r_sequence::<2>(k);
            k += 1;
            out.windows.push(content_window(cloud, c, window, u, v));
            out.frames.push(c.clone());
        }
    }
    out
}

/// A held-back view and the class it stands for.
#[derive(Clone, Debug)]
pub struct HeldBack {
    pub class: String,
    pub camera: Camera,
}

/// Held-back classes: (elevation°, distance factor). Elevations −10…60°, distances 0.5–1.2×
/// the orbit's: the horizon, high views, close-ups and a far low view.
pub const HELD_BACK_CLASSES: [(f64, f64); 6] = [
    (45.0, 1.0),
    (0.0, 1.0),
    (20.0, 0.6),
    (60.0, 0.8),
    (-10.0, 1.2),
    (30.0, 0.5),
];

/// `per_class` held-back views of every class in [`HELD_BACK_CLASSES`] at every size of
/// `sizes`, spread in azimuth, each turned until its direction is at least [`MIN_APART_DEG`]
/// from every camera of every set in `avoid` (the fitting views, the validation views).
pub fn held_back_classes(
    cloud: &GaussianCloud,
    sizes: &[(u32, u32)],
    per_class: usize,
    avoid: &[&[Camera]],
) -> SResult<Vec<HeldBack>> {
    let f = Frame::around(cloud)?;
    let mut out = Vec::new();
    for (ci, &(el, factor)) in HELD_BACK_CLASSES.iter().enumerate() {
        for j in 0..per_class {
            // Classes start at different azimuths, so their views do not line up.
            let base = 360.0 * j as f64 / per_class.max(1) as f64 + 37.0 * ci as f64 + 11.0;
            let mut chosen = None;
            for step in 0..360 {
                // Try 0, +1, −1, +2, −2, … degrees around the planned azimuth.
                let d = if step % 2 == 0 {
                    step / 2
                } else {
                    -(step + 1) / 2
                };
                let az = base + d as f64;
                let probe = f.camera(f.direction(el, az), factor, 8, 6)?;
                if avoid
                    .iter()
                    .flat_map(|set| set.iter())
                    .all(|a| f.angle_deg(&probe, a) >= MIN_APART_DEG)
                {
                    chosen = Some(az);
                    break;
                }
            }
            let az = chosen.ok_or_else(|| {
                SceneError::Invalid(format!(
                    "no held-back view at {el}° is {MIN_APART_DEG}° from every fitting view"
                ))
            })?;
            for &(w, h) in sizes {
                let mut camera = f.camera(f.direction(el, az), factor, w, h)?;
                let class = format!("{el:.0}° elevation, {factor:.1}× distance, {w}×{h}");
                camera.name = format!("{class}, azimuth {:.0}°", az.rem_euclid(360.0));
                out.push(HeldBack { class, camera });
            }
        }
    }
    Ok(out)
}

/// Cameras `i·step + offset` of the `n`-camera orbit around the view bounds of `cloud`, at
/// `width`×`height` (the CLI's orbit: up −y, 50° field of view, 20° elevation).
pub fn orbit(
    cloud: &GaussianCloud,
    n: usize,
    pick: impl Iterator<Item = usize>,
    width: u32,
    height: u32,
) -> SResult<Vec<Camera>> {
    let rig = OrbitRig {
        width,
        height,
        ..OrbitRig::default()
    };
    let (lo, hi) = rig.bounds(cloud)?;
    pick.map(|i| rig.camera_around(lo, hi, n, i)).collect()
}

/// `m` held-back views of an `n`-camera fitting orbit: half-way between fitting cameras,
/// spread evenly over the orbit.
pub fn held_back(
    cloud: &GaussianCloud,
    n: usize,
    m: usize,
    width: u32,
    height: u32,
) -> SResult<Vec<Camera>> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};

    fn cloud() -> GaussianCloud {
        let mut c = GaussianCloud::new(0);
        for i in 0..64 {
            let t = i as f32 / 63.0;
            c.push_activated(
                Vec3::new(t - 0.5, (7.0 * t).sin() * 0.3, (3.0 * t).cos() * 0.4),
                Vec3::splat(0.02),
                Quat::IDENTITY,
                0.8,
                Vec3::ONE,
            );
        }
        c
    }

    /// Validation views: the distribution's points after the fitting ones, then the fine
    /// end's, each at the nearest distance and the largest size (by pixels, whatever the
    /// order of `sizes`), and never the same camera as a fitting or sphere validation view.
    #[test]
    fn fine_end_views_are_the_nearest_and_largest() {
        let c = cloud();
        let f = Frame::around(&c).unwrap();
        let sizes = [(640, 480), (1920, 1080), (320, 240)];
        let fit = sphere(&c, 12, &sizes, WINDOW).unwrap();
        let v = validation_views(&c, 12, 4, 3, &sizes, WINDOW).unwrap();
        assert_eq!((v.windows.len(), v.frames.len()), (7, 7));
        assert_eq!(
            v.frames[..4],
            sphere_range(&c, 12..16, &sizes, WINDOW).unwrap().frames[..]
        );
        for (w, frame) in v.windows[4..].iter().zip(&v.frames[4..]) {
            assert_eq!((frame.width, frame.height), (1920, 1080));
            let d = (frame.centre - f.centre).length() / f.distance;
            // The camera is placed at centre + direction·distance·factor in f64.
            assert!((d - FIT_DISTANCES.0).abs() < 1e-9, "{d}");
            assert_eq!((w.width, w.height), WINDOW);
        }
        for a in &v.frames[4..] {
            for b in fit.frames.iter().chain(&v.frames[..4]) {
                assert!(
                    f.angle_deg(a, b) > 1e-6 || a.width != b.width,
                    "{} and {}",
                    a.name,
                    b.name
                );
            }
        }
    }

    /// The fine-end fitting views follow the sphere's, each at the nearest distance and the
    /// largest size, from the distribution's points after the sphere's: none is a sphere
    /// view's camera, and the validation views taken after them are none of theirs.
    #[test]
    fn fine_end_fitting_views_follow_the_sphere() {
        let c = cloud();
        let f = Frame::around(&c).unwrap();
        let sizes = [(320, 240), (1920, 1080), (640, 480)];
        let plain = sphere(&c, 12, &sizes, WINDOW).unwrap();
        let fit = sphere_with_fine(&c, 12, 3, &sizes, WINDOW).unwrap();
        assert_eq!((fit.windows.len(), fit.frames.len()), (15, 15));
        assert_eq!(fit.frames[..12], plain.frames[..]);
        assert_eq!(fit.windows[..12], plain.windows[..]);
        assert_eq!(
            fit.frames[12..],
            fine_end_range(&c, 12..15, &sizes, WINDOW).unwrap().frames[..]
        );
        for frame in &fit.frames[12..] {
            assert_eq!((frame.width, frame.height), (1920, 1080));
            let d = (frame.centre - f.centre).length() / f.distance;
            // The camera is placed at centre + direction·distance·factor in f64.
            assert!((d - FIT_DISTANCES.0).abs() < 1e-9, "{d}");
        }
        let v = validation_views(&c, fit.windows.len(), 4, 2, &sizes, WINDOW).unwrap();
        for a in &v.frames {
            for b in &fit.frames {
                assert!(
                    f.angle_deg(a, b) > 1e-6 || a.width != b.width,
                    "{} and {}",
                    a.name,
                    b.name
                );
            }
        }
        assert_eq!(
            sphere_with_fine(&c, 12, 0, &sizes, WINDOW).unwrap().frames,
            plain.frames
        );
    }

    /// A window's pixels are the full camera's: the ray through window pixel (x, y) is the
    /// full camera's ray through (x + x0, y + y0), and `frame_of` gives the full image back.
    #[test]
    fn a_window_is_the_full_views_pixels() {
        let f = Frame::around(&cloud()).unwrap();
        let full = f.camera(f.direction(30.0, 40.0), 0.7, 1920, 1080).unwrap();
        let w = window_of(&full, (240, 180), 0.37, 0.81);
        assert_eq!((w.width, w.height), (240, 180));
        let (x0, y0) = (full.cx - w.cx, full.cy - w.cy);
        assert_eq!((x0.fract(), y0.fract()), (0.0, 0.0));
        for (x, y) in [(0.5, 0.5), (239.5, 10.5), (100.25, 179.5)] {
            let a = w.ray_dir(x, y);
            let b = full.ray_dir(x + x0, y + y0);
            // f64 arithmetic on the same expressions: equal to rounding.
            assert!((a - b).length() < 1e-12, "{a} {b}");
        }
        // Its own centred frame holds it, pixel for pixel, and is no larger than the view.
        let (back, bx, by) = frame_of(&w);
        assert!(back.width <= 1920 && back.height <= 1080);
        assert_eq!(
            (back.cx, back.cy),
            (0.5 * back.width as f64, 0.5 * back.height as f64)
        );
        let (a, b) = (
            w.ray_dir(3.5, 7.5),
            back.ray_dir(3.5 + bx as f64, 7.5 + by as f64),
        );
        assert!((a - b).length() < 1e-12, "{a} {b}");
        let (same, 0, 0) = frame_of(&full) else {
            panic!("a centred camera is its own frame")
        };
        assert_eq!(same.width, 1920);
    }

    /// Two small objects far apart: most of a large view between and around them is empty.
    fn two_objects() -> GaussianCloud {
        let mut c = GaussianCloud::new(0);
        for i in 0..64 {
            let t = i as f32 / 63.0;
            let x = if i % 2 == 0 { -1.0 } else { 1.0 };
            c.push_activated(
                Vec3::new(x + 0.04 * (9.0 * t).sin(), 0.04 * (5.0 * t).cos(), 0.04 * t),
                Vec3::splat(0.01),
                Quat::IDENTITY,
                0.9,
                Vec3::ONE,
            );
        }
        c
    }

    /// Whether a Gaussian centre of `cloud` projects inside `cam`'s image.
    fn holds_content(cloud: &GaussianCloud, cam: &Camera) -> bool {
        (0..cloud.len()).any(|i| on_screen(cloud, cam, i, 1.0).is_some())
    }

    /// Fitting windows of large views land on the scene, not on the background around it:
    /// every window of a 1080p or 720p view of two small objects holds one of them, where
    /// windows spread evenly over the same views (the placement before) mostly miss both.
    /// The placement is deterministic.
    #[test]
    fn windows_land_on_content() {
        let c = two_objects();
        let sizes = [(1920, 1080), (1280, 720)];
        let set = sphere(&c, 48, &sizes, WINDOW).unwrap();
        let mut even_empty = 0;
        for (i, (w, frame)) in set.windows.iter().zip(&set.frames).enumerate() {
            assert_eq!((w.width, w.height), WINDOW);
            assert!(holds_content(&c, frame), "{}", frame.name);
            assert!(holds_content(&c, w), "{} sees nothing", w.name);
            let [_, _, _, u, v] = r_sequence::<5>(i);
            even_empty += usize::from(!holds_content(&c, &window_of(frame, WINDOW, u, v)));
        }
        // The objects take a few percent of a 1080p view, so an evenly placed 240×180 window
        // (2 % of it) misses both most of the time: at least half of the 48 here, else the
        // scene would not tell the placements apart.
        assert!(
            even_empty >= 24,
            "only {even_empty} of 48 even windows miss"
        );
        let again = sphere(&c, 48, &sizes, WINDOW).unwrap();
        for (a, b) in set.windows.iter().zip(&again.windows) {
            assert_eq!((a.cx, a.cy), (b.cx, b.cy));
        }
        // A view that sees no Gaussian centre falls back to the even placement.
        let away = Frame::around(&c).unwrap();
        let mut behind = away
            .camera(away.direction(10.0, 0.0), 1.0, 1920, 1080)
            .unwrap();
        behind.world_to_cam = -behind.world_to_cam;
        assert!(!holds_content(&c, &behind));
        let w = content_window(&c, &behind, WINDOW, 0.3, 0.6);
        let e = window_of(&behind, WINDOW, 0.3, 0.6);
        assert_eq!((w.cx, w.cy), (e.cx, e.cy));
    }

    /// The fitting set spans the elevations, distances and sizes it names, and held-back
    /// views keep their distance from it.
    #[test]
    fn sphere_covers_the_band_and_held_back_views_stay_apart() {
        let c = cloud();
        let f = Frame::around(&c).unwrap();
        let set = sphere(&c, 48, &DEFAULT_SIZES, WINDOW).unwrap();
        let fit = set.windows;
        let (mut el_lo, mut el_hi, mut d_lo, mut d_hi) = (90.0f64, -90.0f64, 9.0f64, 0.0f64);
        for cam in &fit {
            let d = cam.centre - f.centre;
            let el = (d.normalize().dot(f.up)).asin().to_degrees();
            el_lo = el_lo.min(el);
            el_hi = el_hi.max(el);
            d_lo = d_lo.min(d.length() / f.distance);
            d_hi = d_hi.max(d.length() / f.distance);
            assert!(cam.width <= WINDOW.0 && cam.height <= WINDOW.1);
        }
        // 48 low-discrepancy points over the band come within a tenth of its ends.
        assert!(el_lo < -15.0 + 8.5 && el_hi > 70.0 - 8.5, "{el_lo} {el_hi}");
        assert!(d_lo < 0.57 && d_hi > 1.13, "{d_lo} {d_hi}");
        for s in DEFAULT_SIZES {
            assert!(set.frames.iter().any(|c| (c.width, c.height) == s), "{s:?}");
        }
        let held = held_back_classes(&c, &[(320, 240)], 3, &[&fit]).unwrap();
        assert_eq!(held.len(), HELD_BACK_CLASSES.len() * 3);
        for h in &held {
            let nearest = fit
                .iter()
                .map(|a| f.angle_deg(&h.camera, a))
                .fold(f64::INFINITY, f64::min);
            assert!(nearest >= MIN_APART_DEG, "{}: {nearest}", h.camera.name);
        }
    }
}
