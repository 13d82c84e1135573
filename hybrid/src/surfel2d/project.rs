//! Per-surfel setup of 2DGS's `preprocessCUDA` (`computeCov3D`, `computeCenter`, `getRect`),
//! see the parent module for the formulas and their source.

use glam::{DMat3, DVec3};
use splatbridge_scene::{sh, Camera, GaussianCloud};

use crate::project::{get_rect, Culled, TILE};

/// 2DGS's screen-space low-pass filter size in pixels (`FilterSize` in `auxiliary.h`: √2/2).
pub const FILTER_SIZE: f64 = std::f64::consts::FRAC_1_SQRT_2;
/// `1/FilterSize²` (`FilterInvSquare`).
pub const FILTER_INV_SQUARE: f64 = 2.0;

/// Where the screen-space low-pass filter is centred.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LowPassCentre {
    /// 2DGS's rasterizer: the centre of the screen image of the unit circle (`computeCenter`),
    /// which perspective moves away from the projected surfel centre on large or grazing
    /// surfels.
    #[default]
    Code,
    /// The paper's Eq. 11: the projection of the surfel's centre.
    Projected,
    /// No low-pass at all (`ρ = ρ3d`, `G = G(u, v)`): not the reference but a named
    /// approximation of it, the footprint a fixed mesh of the surfel can carry, for measuring
    /// what the filter adds (docs/formats.md#2dgs-surfels). The centre is put at infinity, so
    /// `ρ2d = ∞` at every pixel.
    Off,
}

/// The camera as the per-surfel setup needs it.
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    /// Principal point in continuous pixel coordinates (pixel `i` sampled at `i + 0.5`).
    pub cx: f64,
    pub cy: f64,
    pub centre: DVec3,
    pub world_to_cam: DMat3,
    pub grid: [u32; 2],
    pub near: f64,
    pub low_pass: LowPassCentre,
}

impl View {
    pub fn new(cam: &Camera, near: f64, low_pass: LowPassCentre) -> Self {
        View {
            width: cam.width,
            height: cam.height,
            fx: cam.fx,
            fy: cam.fy,
            cx: cam.cx,
            cy: cam.cy,
            centre: cam.centre,
            world_to_cam: cam.world_to_cam,
            grid: [cam.width.div_ceil(TILE), cam.height.div_ceil(TILE)],
            near,
            low_pass,
        }
    }
}

/// A set-up surfel: the rows of its homogeneous transform, its screen centre, opacity,
/// colour and centre depth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfelSplat {
    /// `(x·w, y·w, w) = (T_u, T_v, T_w)·(u, v, 1)`.
    pub tu: DVec3,
    pub tv: DVec3,
    pub tw: DVec3,
    /// Where the low-pass is centred ([`LowPassCentre`]; infinite when it is off).
    pub centre: [f64; 2],
    pub opacity: f32,
    pub color: [f32; 3],
    /// View depth of the surfel's centre (the sort key).
    pub depth: f32,
}

/// The transform rows `T_u, T_v, T_w` of a surfel with camera-space tangent columns `a_u`, `a_v`
/// (already scaled) and camera-space centre `c` (`computeCov3D`).
pub fn transform_rows(view: &View, a_u: DVec3, a_v: DVec3, c: DVec3) -> [DVec3; 3] {
    let row = |f: f64, cc: f64, pick: fn(DVec3) -> f64| {
        DVec3::new(
            f * pick(a_u) + cc * a_u.z,
            f * pick(a_v) + cc * a_v.z,
            f * pick(c) + cc * c.z,
        )
    };
    [
        row(view.fx, view.cx, |v| v.x),
        row(view.fy, view.cy, |v| v.y),
        DVec3::new(a_u.z, a_v.z, c.z),
    ]
}

/// `computeCenter`: the centre and half-extents of the screen image of the unit circle, or
/// `None` when the dual conic's `w` term vanishes.
pub fn center_extent(t: &[DVec3; 3]) -> Option<([f64; 2], [f64; 2])> {
    let [tu, tv, tw] = *t;
    let sgn = DVec3::new(1.0, 1.0, -1.0);
    let d = sgn.dot(tw * tw);
    if d == 0.0 {
        return None;
    }
    let f = sgn / d;
    let p = [f.dot(tu * tw), f.dot(tv * tw)];
    let h = [
        (p[0] * p[0] - f.dot(tu * tu)).max(0.0).sqrt(),
        (p[1] * p[1] - f.dot(tv * tv)).max(0.0).sqrt(),
    ];
    Some((p, h))
}

/// Set up surfel `i` (scale x, y and the rotation; the third log-scale is not read).
pub fn project_surfel(
    cloud: &GaussianCloud,
    i: usize,
    view: &View,
    sh_degree: u8,
) -> Result<(SurfelSplat, [u32; 4]), Culled> {
    let rel = cloud.means[i].as_dvec3() - view.centre;
    let c = view.world_to_cam * rel;
    if !c.is_finite() {
        return Err(Culled::Degenerate);
    }
    if c.z <= view.near {
        if c.z <= 0.0 {
            return Err(Culled::Behind);
        }
        let u = view.fx * c.x / c.z + view.cx;
        let v = view.fy * c.y / c.z + view.cy;
        let in_view =
            (0.0..=view.width as f64).contains(&u) && (0.0..=view.height as f64).contains(&v);
        return Err(Culled::Near { in_view });
    }
    let opacity = cloud.opacity(i);
    if !(opacity >= 1.0 / 255.0) {
        return Err(Culled::Transparent);
    }
    let r = DMat3::from_quat(cloud.unit_rotation(i).as_dquat());
    let s = cloud.scale(i).as_dvec3();
    let w = view.world_to_cam;
    let a_u = w * r.x_axis * s.x;
    let a_v = w * r.y_axis * s.y;
    let normal = w * r.z_axis;
    if normal.dot(c) == 0.0 {
        return Err(Culled::Degenerate);
    }
    let t = transform_rows(view, a_u, a_v, c);
    let Some((centre, ext)) = center_extent(&t) else {
        return Err(Culled::Degenerate);
    };
    let truncated = (9.0 + (opacity as f64).ln()).max(1e-6).sqrt();
    let radius_f = (truncated * ext[0].max(ext[1]).max(FILTER_SIZE)).ceil();
    if !(radius_f.is_finite() && centre[0].is_finite() && centre[1].is_finite())
        || !t.iter().all(|r| r.is_finite())
    {
        return Err(Culled::Degenerate);
    }
    let radius = radius_f.min(i32::MAX as f64) as i32;
    let rect = get_rect(centre[0], centre[1], radius, view.grid);
    if rect[2] <= rect[0] || rect[3] <= rect[1] {
        return Err(Culled::Offscreen);
    }
    let color = sh::eval_color(sh_degree, cloud.sh_of(i), rel.normalize().as_vec3());
    let centre = match view.low_pass {
        LowPassCentre::Code => centre,
        LowPassCentre::Projected => [view.fx * c.x / c.z + view.cx, view.fy * c.y / c.z + view.cy],
        LowPassCentre::Off => [f64::INFINITY; 2],
    };
    Ok((
        SurfelSplat {
            tu: t[0],
            tv: t[1],
            tw: t[2],
            centre,
            opacity,
            color: color.to_array(),
            depth: c.z as f32,
        },
        rect,
    ))
}
