//! Projection for pass 1 of the GES hybrid (`surfel_pass`): each surfel becomes a
//! [`SurfelSplat`] in camera space, the linear coefficients of its ray–plane test and the exact
//! screen box of its footprint ellipse (see `surfel_pass`'s module documentation for the
//! per-sample test these coefficients serve).

use glam::DVec3;
use splatbridge_scene::sh;
use splatbridge_scene::surfels::{SurfelCloud, FOOTPRINT_SIGMAS};

use crate::project::ViewParams;

/// `(2·ln 255)`: the squared footprint radius in standard deviations.
pub fn footprint_r2() -> f32 {
    FOOTPRINT_SIGMAS * FOOTPRINT_SIGMAS
}

/// A surfel in camera space, ready for the per-sample test.
#[derive(Clone, Copy, Debug)]
pub struct SurfelSplat {
    /// `n·d = n[0]·x + n[1]·y + n[2]` at pixel coordinates (x, y); likewise u, v (scaled axes).
    pub n: [f32; 3],
    pub u: [f32; 3],
    pub v: [f32; 3],
    /// `n·c`, `(a_u·c)/s_u`, `(a_v·c)/s_v`.
    pub nc: f32,
    pub uc: f32,
    pub vc: f32,
    pub color: [f32; 3],
    /// Depth tolerance ε in view-depth units (world units).
    pub eps: f32,
    /// Inclusive pixel box.
    pub bbox: [i32; 4],
    pub index: u32,
}

impl SurfelSplat {
    /// The placeholder of culled surfel `i`: an empty box, in no tile list.
    pub(crate) fn culled(i: usize) -> Self {
        SurfelSplat {
            n: [0.0; 3],
            u: [0.0; 3],
            v: [0.0; 3],
            nc: 0.0,
            uc: 0.0,
            vc: 0.0,
            color: [0.0; 3],
            eps: 0.0,
            bbox: [0, 0, -1, -1],
            index: i as u32,
        }
    }

    /// View depth of the hit and whether the sample at (x, y) is covered.
    #[inline(always)]
    pub fn hit(&self, x: f32, y: f32, near: f32, r2: f32) -> (f32, bool) {
        let den = self.n[0] * x + self.n[1] * y + self.n[2];
        let t = self.nc / den;
        let u = t * (self.u[0] * x + self.u[1] * y + self.u[2]) - self.uc;
        let v = t * (self.v[0] * x + self.v[1] * y + self.v[2]) - self.vc;
        let covered = t > near && t < f32::MAX && u * u + v * v <= r2;
        (t, covered)
    }
}

/// Screen bounding box (continuous pixel coordinates, pixel `i` at `i`) of the ellipse
/// `c + cos θ·U + sin θ·W` (camera space, every rim point in front of the camera): the extremes
/// of `X(θ)/Z(θ)` satisfy `(X'Z − XZ') = 0`, i.e. `P·sin θ + Q·cos θ = K` with
/// `P = U.z·c.x − U.x·c.z`, `Q = W.x·c.z − W.z·c.x`, `K = U.x·W.z − W.x·U.z`. The two solutions
/// are where the line `P·s + Q·c = K` meets the unit circle, `(s, c) = (K·(P, Q) ± √(ρ² − K²)·(Q, −P))/ρ²`
/// with `ρ² = P² + Q²`: no trigonometry.
pub fn screen_box(view: &ViewParams, c: DVec3, u: DVec3, w: DVec3) -> [f64; 4] {
    let along = |ci: f64, ui: f64, wi: f64, f: f64, p0: f64| -> (f64, f64) {
        let p = u.z * ci - ui * c.z;
        let q = wi * c.z - w.z * ci;
        let k = ui * w.z - wi * u.z;
        let rho2 = p * p + q * q;
        let proj = |s: f64, co: f64| f * (ci + co * ui + s * wi) / (c.z + co * u.z + s * w.z) + p0;
        let disc = rho2 - k * k;
        if rho2 > 1e-300 && disc >= 0.0 {
            let sq = disc.sqrt();
            let x0 = proj((k * p + sq * q) / rho2, (k * q - sq * p) / rho2);
            let x1 = proj((k * p - sq * q) / rho2, (k * q + sq * p) / rho2);
            (x0.min(x1), x0.max(x1))
        } else {
            // Degenerate (the projection is constant along the rim): the centre and four rim
            // points bound it.
            let pts = [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0)].map(|(s, co)| proj(s, co));
            let lo = pts.iter().cloned().fold(f64::INFINITY, f64::min);
            let hi = pts.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            (lo, hi)
        }
    };
    let (x0, x1) = along(c.x, u.x, w.x, view.fx, view.px0);
    let (y0, y1) = along(c.y, u.y, w.y, view.fy, view.py0);
    [x0, y0, x1, y1]
}

/// `v` clamped to `[−1, m]` (`v` finite).
#[inline(always)]
pub(crate) fn clamp_box(v: f64, m: i64) -> f64 {
    v.max(-1.0).min(m as f64)
}

/// `floor(v)` for finite `v` within `i64`'s range (the truncation, one lower below zero).
#[inline(always)]
pub(crate) fn floor_in(v: f64) -> i64 {
    let i = v as i64;
    i - ((i as f64) > v) as i64
}

/// `ceil(v)` for finite `v` within `i64`'s range.
#[inline(always)]
pub(crate) fn ceil_in(v: f64) -> i64 {
    let i = v as i64;
    i + ((i as f64) < v) as i64
}

/// Project surfel `i` for this view; `None` when entirely behind the near plane, off-screen or
/// degenerate. The ellipse reaches `footprint` standard deviations (GES: [`FOOTPRINT_SIGMAS`]),
/// realised by scaling both axes by `footprint / FOOTPRINT_SIGMAS` (ε is not affected).
pub fn project_surfel(
    s: &SurfelCloud,
    i: usize,
    view: &ViewParams,
    eps_factor: f32,
    footprint: f32,
    sh_degree: u8,
) -> Option<SurfelSplat> {
    let w2c = view.world_to_cam;
    let rel = s.means[i].as_dvec3() - view.centre;
    let c = w2c * rel;
    let au = w2c * s.axes_u[i].as_dvec3();
    let av = w2c * s.axes_v[i].as_dvec3();
    let k = footprint as f64 / FOOTPRINT_SIGMAS as f64;
    let [su, sv] = s.scales[i].map(|v| v as f64 * k);
    let n = au.cross(av);
    if !(c.is_finite() && n.is_finite() && su > 0.0 && sv > 0.0 && su.is_finite() && sv.is_finite())
        || n.length_squared() == 0.0
    {
        return None;
    }
    let r = FOOTPRINT_SIGMAS as f64;
    let (uu, ww) = (au * (r * su), av * (r * sv));
    let zr = (uu.z * uu.z + ww.z * ww.z).sqrt();
    if c.z + zr <= view.near {
        return None;
    }
    let (wpx, hpx) = (view.width as i64, view.height as i64);
    let bbox = if c.z - zr > view.near {
        let b = screen_box(view, c, uu, ww);
        if !b.iter().all(|v| v.is_finite()) {
            return None;
        }
        // One pixel of margin for the supersample offsets (≤ 3/8) and f32 evaluation. Clamping
        // to [−1, m] commutes with floor and ceil (integer bounds), and on that range the
        // integer forms equal them without a libm call.
        let lo = |v: f64, m: i64| floor_in(clamp_box(v - 1.0, m)) as i32;
        let hi = |v: f64, m: i64| ceil_in(clamp_box(v + 1.0, m)) as i32;
        [lo(b[0], wpx), lo(b[1], hpx), hi(b[2], wpx), hi(b[3], hpx)]
    } else {
        [0, 0, wpx as i32 - 1, hpx as i32 - 1]
    };
    let bbox = [
        bbox[0].max(0),
        bbox[1].max(0),
        bbox[2].min(wpx as i32 - 1),
        bbox[3].min(hpx as i32 - 1),
    ];
    if bbox[0] > bbox[2] || bbox[1] > bbox[3] {
        return None;
    }
    // d(x, y) = ((x − px0)/fx, (y − py0)/fy, 1): a·d = (a.x/fx)·x + (a.y/fy)·y + (a.z − a.x·px0/fx − a.y·py0/fy).
    let form = |a: DVec3| -> [f32; 3] {
        [
            (a.x / view.fx) as f32,
            (a.y / view.fy) as f32,
            (a.z - a.x * view.px0 / view.fx - a.y * view.py0 / view.fy) as f32,
        ]
    };
    let (au_s, av_s) = (au / su, av / sv);
    let color = sh::eval_color(sh_degree, s.sh_of(i), rel.normalize().as_vec3());
    Some(SurfelSplat {
        n: form(n),
        u: form(au_s),
        v: form(av_s),
        nc: n.dot(c) as f32,
        uc: au_s.dot(c) as f32,
        vc: av_s.dot(c) as f32,
        color: color.to_array(),
        eps: eps_factor * s.mean_scales[i],
        bbox,
        index: i as u32,
    })
}
