//! Per-Gaussian projection, as the reference 3DGS `preprocessCUDA` (`forward.cu`) does it:
//! near cull, EWA 2D covariance `J·W·Σ·Wᵀ·Jᵀ` with the 1.3·tan(fov/2) Jacobian clamp, the 0.3
//! low-pass dilation, the conic, the `ceil(3·sqrt(λmax))` radius and the tile rectangle of
//! `getRect`, SH colour with `+0.5` and the clamp at 0.
//!
//! Departures from the reference, all below f32 rounding of the reference's own output:
//! - The mean is made camera-relative in f64 (`R·(p − centre)`) before anything is rounded, so a
//!   scene 1e5 units from the origin keeps sub-millimetre precision near the camera.
//! - The 2D covariance, determinant, conic and radius are formed in f64 and rounded to f32 at the
//!   end. The reference works in f32, where `a·c − b²` of a needle (scale ratio 1e6) cancels
//!   catastrophically and can even turn negative; here a non-positive determinant can only come
//!   from degenerate input and is skipped like the reference's `det == 0`.
//! - The projected pixel is `f·x/z + c − 0.5` exactly (the reference's `ndc2Pix` of the full
//!   projection matrix, minus its `+1e-7` in the homogeneous divide).
//! - Gaussians with opacity below 1/255 are dropped here: `α ≤ opacity < 1/255` is skipped at
//!   every pixel anyway, so the image is unchanged and the tiles hold less work.
//!
//! The same projection serves the GES hybrid renderer, which needs the screen mean, conic,
//! colour, opacity and depth of each Gaussian but not the tile sort.

use glam::{DMat3, DVec3, Vec3};
use splatbridge_scene::{sh, Camera, GaussianCloud};

/// Tile edge in pixels (the reference's `BLOCK_X = BLOCK_Y = 16`).
pub const TILE: u32 = 16;

/// The reference's low-pass dilation added to both diagonal entries of the 2D covariance.
pub const DILATION: f64 = 0.3;

/// How far from its mean a Gaussian is considered on screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Extent {
    /// The reference: `radius = ceil(3·sqrt(λmax))` pixels.
    #[default]
    Sigma3,
    /// The footprint where `opacity·exp(−r²/2) ≥ 1/255`: `r = sqrt(2·ln(255·opacity))` standard
    /// deviations along the major axis (GCC's alpha-based boundary identification). Smaller than
    /// 3σ for opacity below about 0.35 and up to 3.33σ for opaque Gaussians, so faint Gaussians
    /// touch fewer tiles; the pixels it drops from a faint Gaussian's 3σ square are exactly those
    /// where `α < 1/255` and were skipped anyway, while opaque Gaussians reach a little further
    /// than the reference's square.
    Alpha,
}

/// A projected Gaussian, packed for the blending loop (one cache line).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Splat {
    /// Screen position of the mean in pixel coordinates (pixel `i` sampled at `i`).
    pub x: f32,
    pub y: f32,
    /// Inverse of the dilated 2D covariance `(c0, c1, c2)`: `power = −½(c0·dx² + c2·dy²) − c1·dx·dy`.
    pub conic: [f32; 3],
    /// Activated opacity.
    pub opacity: f32,
    /// Colour: SH + 0.5, clamped at 0.
    pub color: [f32; 3],
    /// View-space depth of the mean.
    pub depth: f32,
    /// Pixel box (inclusive) outside which `opacity·exp(power) < 1/255` for certain, with a
    /// margin above the f32 evaluation error of `power`; the blending loop uses it only to skip
    /// work, never to decide a pixel (see [`footprint_box`]).
    pub bbox: [i32; 4],
}

/// Where a projected Gaussian lands: its splat, the tile rectangle `[x0, x1) × [y0, y1)` in
/// tiles (the reference's `getRect`), its radius in pixels and its index in the input cloud.
#[derive(Clone, Copy, Debug)]
pub struct Projected {
    pub splat: Splat,
    pub rect: [u32; 4],
    pub radius: i32,
    pub index: u32,
}

/// Why a Gaussian did not reach the screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Culled {
    /// View-space depth `z ≤ near` (and `z > 0`); `in_view` is true when the mean projects
    /// inside the image, i.e. the near plane rather than the frustum's sides removed it.
    Near { in_view: bool },
    /// Behind the camera (`z ≤ 0`).
    Behind,
    /// Opacity below 1/255: contributes nowhere.
    Transparent,
    /// Zero (or non-positive) determinant of the 2D covariance, or non-finite values.
    Degenerate,
    /// The tile rectangle is empty: entirely off-screen.
    Offscreen,
}

/// Camera quantities the projection needs, in the reference's terms.
#[derive(Clone, Copy, Debug)]
pub struct ViewParams {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    /// Principal point in pixel coordinates sampled at integers (`c − 0.5`).
    pub px0: f64,
    pub py0: f64,
    /// `tan(fov/2)` per axis as the reference derives it: `W / (2·fx)`.
    pub tan_fovx: f64,
    pub tan_fovy: f64,
    pub centre: DVec3,
    pub world_to_cam: DMat3,
    pub grid: [u32; 2],
    /// The tiles rendered, `[x0, y0, x1, y1)` within `grid` (all of it unless a window of the
    /// frame is rendered, [`crate::native::Renderer::render_window`]): a Gaussian whose tile
    /// rectangle misses them is [`Culled::Offscreen`] before its colour is evaluated.
    pub clip: [u32; 4],
    pub near: f64,
}

impl ViewParams {
    pub fn new(cam: &Camera, near: f64) -> Self {
        ViewParams {
            width: cam.width,
            height: cam.height,
            fx: cam.fx,
            fy: cam.fy,
            px0: cam.cx - 0.5,
            py0: cam.cy - 0.5,
            tan_fovx: 0.5 * cam.width as f64 / cam.fx,
            tan_fovy: 0.5 * cam.height as f64 / cam.fy,
            centre: cam.centre,
            world_to_cam: cam.world_to_cam,
            grid: [cam.width.div_ceil(TILE), cam.height.div_ceil(TILE)],
            clip: [0, 0, cam.width.div_ceil(TILE), cam.height.div_ceil(TILE)],
            near,
        }
    }

    /// The tiles that hold pixels `[x0, x0 + w) × [y0, y0 + h)` of the frame (clamped to it).
    pub fn tiles_of(&self, x0: u32, y0: u32, w: u32, h: u32) -> [u32; 4] {
        let [gx, gy] = self.grid;
        let end = |a: u32, n: u32, g: u32| a.saturating_add(n).div_ceil(TILE).min(g);
        [
            (x0 / TILE).min(gx),
            (y0 / TILE).min(gy),
            end(x0, w, gx),
            end(y0, h, gy),
        ]
    }
}

/// `rect ∩ clip` (both `[x0, y0, x1, y1)`); empty when `x1 ≤ x0` or `y1 ≤ y0`.
pub fn clip_rect(rect: [u32; 4], clip: [u32; 4]) -> [u32; 4] {
    [
        rect[0].max(clip[0]),
        rect[1].max(clip[1]),
        rect[2].min(clip[2]),
        rect[3].min(clip[3]),
    ]
}

/// The reference's `getRect`: tiles touched by the square of half-size `radius` around `(x, y)`,
/// as `[x0, y0, x1, y1)` clamped to the grid. Float-to-int conversion truncates toward zero as
/// CUDA's `(int)` does (and saturates instead of overflowing).
pub fn get_rect(x: f64, y: f64, radius: i32, grid: [u32; 2]) -> [u32; 4] {
    let r = radius as f64;
    let t = TILE as f64;
    let clamp = |v: f64, g: u32| -> u32 { (v as i64).clamp(0, g as i64) as u32 };
    [
        clamp((x - r) / t, grid[0]),
        clamp((y - r) / t, grid[1]),
        clamp((x + r + t - 1.0) / t, grid[0]),
        clamp((y + r + t - 1.0) / t, grid[1]),
    ]
}

/// Dilated 2D covariance `(a, b, c)` of a Gaussian with world covariance `sigma` whose mean is
/// at camera-space `t` (z > 0), with the reference's Jacobian clamp.
pub fn covariance_2d(view: &ViewParams, t: DVec3, sigma: &DMat3) -> [f64; 3] {
    let limx = 1.3 * view.tan_fovx;
    let limy = 1.3 * view.tan_fovy;
    let tx = (t.x / t.z).clamp(-limx, limx) * t.z;
    let ty = (t.y / t.z).clamp(-limy, limy) * t.z;
    let tz2 = t.z * t.z;
    // Rows of J (the third row is zero); J·W applied row by row.
    let j0 = DVec3::new(view.fx / t.z, 0.0, -view.fx * tx / tz2);
    let j1 = DVec3::new(0.0, view.fy / t.z, -view.fy * ty / tz2);
    let w = view.world_to_cam;
    // (J·W) rows = Wᵀ·(J rows).
    let wt = w.transpose();
    let m0 = wt * j0;
    let m1 = wt * j1;
    let s0 = *sigma * m0;
    let s1 = *sigma * m1;
    [m0.dot(s0) + DILATION, m0.dot(s1), m1.dot(s1) + DILATION]
}

/// World covariance `R·S²·Rᵀ` in f64 from the activated f32 scale and unit rotation.
pub fn covariance_3d(cloud: &GaussianCloud, i: usize) -> DMat3 {
    let r = DMat3::from_quat(cloud.unit_rotation(i).as_dquat());
    let s = cloud.scale(i).as_dvec3();
    let m = r * DMat3::from_diagonal(s);
    m * m.transpose()
}

/// Pixel box in which `½·dᵀ·Q·d ≤ L` can hold (Q the conic), widened so that the f32
/// evaluation of `power` in the blending loop can never accept a pixel outside it:
/// the error of `c0·dx² + 2·c1·dx·dy + c2·dy²` in f32 is below `8·ε·B` with `B` the sum of the
/// absolute terms (ε = 2⁻²⁴), and exp/product rounding moves the 1/255 threshold by a few ulp.
pub fn footprint_box(x: f64, y: f64, cov: [f64; 3], conic: [f64; 3], level: f64) -> [i32; 4] {
    let half = |l: f64| ((2.0 * l * cov[0]).sqrt(), (2.0 * l * cov[2]).sqrt());
    let (hx, hy) = half(level);
    let b = conic[0].abs() * hx * hx + conic[2].abs() * hy * hy + 2.0 * conic[1].abs() * hx * hy;
    let widened = level * (1.0 + 1e-5) + 1e-5 + 1e-6 * b;
    let (hx, hy) = half(widened);
    let lo = |c: f64, h: f64| (c - h - 0.01).ceil().clamp(-1.0e9, 1.0e9) as i32;
    let hi = |c: f64, h: f64| (c + h + 0.01).floor().clamp(-1.0e9, 1.0e9) as i32;
    [lo(x, hx), lo(y, hy), hi(x, hx), hi(y, hy)]
}

/// Project Gaussian `i`. `sh_degree` is the degree to evaluate (cloud degree capped).
pub fn project_one(
    cloud: &GaussianCloud,
    i: usize,
    view: &ViewParams,
    extent: Extent,
    sh_degree: u8,
) -> Result<Projected, Culled> {
    let rel = cloud.means[i].as_dvec3() - view.centre;
    let t = view.world_to_cam * rel;
    if !t.is_finite() {
        return Err(Culled::Degenerate);
    }
    if t.z <= view.near {
        if t.z <= 0.0 {
            return Err(Culled::Behind);
        }
        let u = view.fx * t.x / t.z + view.px0;
        let v = view.fy * t.y / t.z + view.py0;
        let in_view = (-0.5..=view.width as f64 - 0.5).contains(&u)
            && (-0.5..=view.height as f64 - 0.5).contains(&v);
        return Err(Culled::Near { in_view });
    }
    let opacity = cloud.opacity(i);
    if !(opacity >= 1.0 / 255.0) {
        return Err(Culled::Transparent);
    }
    let sigma = covariance_3d(cloud, i);
    let [a, b, c] = covariance_2d(view, t, &sigma);
    let det = a * c - b * b;
    if !(det > 0.0) || !det.is_finite() {
        return Err(Culled::Degenerate);
    }
    let conic = [c / det, -b / det, a / det];
    let mid = 0.5 * (a + c);
    let lambda = mid + (mid * mid - det).max(0.1).sqrt();
    let sigmas = match extent {
        Extent::Sigma3 => 3.0,
        Extent::Alpha => (2.0 * (255.0 * opacity as f64).ln()).sqrt(),
    };
    let radius_f = (sigmas * lambda.sqrt()).ceil();
    let x = view.fx * t.x / t.z + view.px0;
    let y = view.fy * t.y / t.z + view.py0;
    if !(radius_f.is_finite() && x.is_finite() && y.is_finite()) {
        return Err(Culled::Degenerate);
    }
    // The reference holds the radius in an int; saturate rather than wrap.
    let radius = radius_f.min(i32::MAX as f64) as i32;
    // The whole grid's clip leaves the rectangle as it is (it is clamped to the grid).
    let rect = clip_rect(get_rect(x, y, radius, view.grid), view.clip);
    if rect[2] <= rect[0] || rect[3] <= rect[1] {
        return Err(Culled::Offscreen);
    }
    let dir = rel.normalize();
    let color = sh::eval_color(sh_degree, cloud.sh_of(i), dir.as_vec3());
    let level = (255.0 * opacity as f64).ln();
    let (xf, yf) = (x as f32, y as f32);
    let splat = Splat {
        x: xf,
        y: yf,
        conic: conic.map(|v| v as f32),
        opacity,
        color: color.to_array(),
        depth: t.z as f32,
        // The box is centred on the f32 position the blending loop uses (far off-screen means
        // lose more than the box's 0.01 px slack when rounded to f32).
        bbox: footprint_box(xf as f64, yf as f64, [a, b, c], conic, level),
    };
    Ok(Projected {
        splat,
        rect,
        radius,
        index: i as u32,
    })
}

/// Colour of Gaussian `i` seen from `centre` (for callers that project themselves).
pub fn color_of(cloud: &GaussianCloud, i: usize, centre: DVec3, sh_degree: u8) -> Vec3 {
    let dir = (cloud.means[i].as_dvec3() - centre).normalize();
    sh::eval_color(sh_degree, cloud.sh_of(i), dir.as_vec3())
}
