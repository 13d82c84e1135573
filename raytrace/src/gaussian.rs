//! Mode `gaussian`: ray-trace the Gaussians themselves, after 3DGRT (Moenne-Loccoz et al.,
//! "3D Gaussian Ray Tracing", 2024), as a reference that isolates the conversion's error from
//! the rasterizer's approximations.
//!
//! Proxy: each Gaussian's ellipsoid at its opacity-aware 1/255 extent, `r = sqrt(2·ln(255·o))`
//! standard deviations (a Gaussian with o < 1/255 can never contribute and gets none), bounded
//! by its axis-aligned box in the BVH. The proxy test is exact rather than polyhedral: a ray
//! passes within the extent iff its Mahalanobis distance of closest approach is ≤ r, which is
//! precisely the condition α ≥ 1/255 at the point of maximum response.
//!
//! Response, evaluated once per ray and Gaussian: `o_g = S⁻¹Rᵀ(o − μ)`, `d_g = S⁻¹Rᵀd`,
//! `ρ = exp(−½·|normalize(d_g) × o_g|²)`, `α = min(0.99, o·ρ)`, skipped below 1/255; the hit
//! distance is that of maximum response, `t* = −(o_g·d_g)/|d_g|²` (clamped at 0), and hits are
//! ordered by (t*, Gaussian index). Colour is the full SH evaluated in the ray direction.
//! Compositing follows native splatting: front to back, and a Gaussian that would take T below
//! 1e-4 stops the ray without being added. As in the rasterizer, a Gaussian whose mean is at
//! view depth ≤ `RenderOptions::near` (0.2) is culled (primary rays only).

use std::time::Instant;

use glam::{DVec3, Mat3, Vec3};
use splatbridge_scene::{sh, Camera, Frame, GaussianCloud};

use crate::backend::{build_boxes, Accel, BackendKind, BuildPreset};
use crate::composite::{Hit, KBuffer};
use crate::error::Result;
use crate::render::{render_frame, PixelOut, RenderOptions, Stats};

/// The rasterizer's near cull (default of `RenderOptions::near`): view-space depth of the
/// mean must exceed this.
pub const NEAR_CULL: f32 = 0.2;

/// Gaussians prepared for ray tracing.
pub struct GaussianTracer {
    pub cloud: GaussianCloud,
    pub anchor: DVec3,
    /// Index into `cloud` of each proxy.
    pub index: Vec<u32>,
    pub mean: Vec<Vec3>,
    /// `S⁻¹Rᵀ`.
    pub inv: Vec<Mat3>,
    pub opacity: Vec<f32>,
    /// Squared extent in standard deviations, `2·ln(255·o)`.
    pub r2: Vec<f32>,
    pub accel: Box<dyn Accel>,
    pub backend: BackendKind,
    pub build_seconds: f64,
}

/// Near culling for primary rays: the camera origin (relative to the anchor) and forward axis.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Near {
    origin: Vec3,
    forward: Vec3,
    near: f32,
}

impl GaussianTracer {
    /// Build proxies and their BVH over a (world-space) cloud.
    pub fn new(cloud: GaussianCloud, backend: BackendKind, preset: BuildPreset) -> Result<Self> {
        cloud.check_shape()?;
        let start = Instant::now();
        let (lo, hi) = cloud.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let anchor = (0.5 * (lo.as_dvec3() + hi.as_dvec3())).as_vec3().as_dvec3();
        let mut t = GaussianTracer {
            anchor,
            index: Vec::new(),
            mean: Vec::new(),
            inv: Vec::new(),
            opacity: Vec::new(),
            r2: Vec::new(),
            accel: Box::new(crate::backend::EmptyAccel),
            backend,
            build_seconds: 0.0,
            cloud: GaussianCloud::new(0),
        };
        let mut boxes = Vec::new();
        for i in 0..cloud.len() {
            if cloud.invalid_reason(i).is_some() {
                continue;
            }
            let o = cloud.opacity(i);
            // Below 1/255 the Gaussian never reaches the α cut anywhere.
            if !(o * 255.0 > 1.0) {
                continue;
            }
            let r2 = 2.0 * (255.0 * o).ln();
            let s = cloud.scale(i);
            if !(s.min_element() > 0.0) || !s.is_finite() {
                continue;
            }
            let rot = Mat3::from_quat(cloud.unit_rotation(i));
            let inv = Mat3::from_diagonal(s.recip()) * rot.transpose();
            if !inv.is_finite() {
                continue;
            }
            let mu = (cloud.means[i].as_dvec3() - anchor).as_vec3();
            let m = rot * Mat3::from_diagonal(s * r2.sqrt());
            // Half-extent of the ellipsoid R·diag(s·r) along each world axis, padded by a
            // relative 1e-5 plus one f32 ulp of the mean so rounding cannot clip the proxy.
            let half = Vec3::new(m.row(0).length(), m.row(1).length(), m.row(2).length());
            let pad = half * 1e-5 + Vec3::splat(mu.abs().max_element() * 1.2e-7);
            boxes.push((mu - half - pad, mu + half + pad));
            t.index.push(i as u32);
            t.mean.push(mu);
            t.inv.push(inv);
            t.opacity.push(o);
            t.r2.push(r2);
        }
        t.accel = build_boxes(backend, preset, &boxes)?;
        t.cloud = cloud;
        t.build_seconds = start.elapsed().as_secs_f64();
        Ok(t)
    }

    /// Response of proxy `p` along the ray (relative origin `o`, unit direction `d`):
    /// (t*, α) or None when α < 1/255.
    #[inline]
    pub fn response(&self, p: usize, o: Vec3, d: Vec3) -> Option<(f32, f32)> {
        let inv = self.inv[p];
        let og = inv * (o - self.mean[p]);
        let dg = inv * d;
        let dd = dg.length_squared();
        if !(dd > 0.0 && dd.is_finite()) {
            return None;
        }
        let n = dg / dd.sqrt();
        let d2 = n.cross(og).length_squared();
        if !(d2 <= self.r2[p]) {
            return None;
        }
        let alpha = (self.opacity[p] * (-0.5 * d2).exp()).min(0.99);
        if !(alpha >= 1.0 / 255.0) {
            return None;
        }
        let t = (-og.dot(dg) / dd).max(0.0) + 0.0;
        t.is_finite().then_some((t, alpha))
    }

    pub(crate) fn collect(
        &self,
        o: Vec3,
        d: Vec3,
        near: Option<Near>,
        tmax: f32,
        after: Option<(u32, u32, u32, u32)>,
        buf: &mut KBuffer,
    ) {
        buf.clear();
        self.accel.traverse(o, d, tmax, &mut |p, _, cull| {
            let p = p as usize;
            if let Some(n) = near {
                if (self.mean[p] - n.origin).dot(n.forward) <= n.near {
                    return;
                }
            }
            let Some((t, alpha)) = self.response(p, o, d) else {
                return;
            };
            if t > tmax {
                return;
            }
            let h = Hit {
                t,
                gaussian: self.index[p],
                instance: 0,
                group: 0,
                tri: p as u32,
                bary: [alpha, 0.0, 0.0],
            };
            if after.is_some_and(|a| h.key() <= a) {
                return;
            }
            *cull = buf.insert(h, tmax);
        });
    }

    /// Every Gaussian the ray reaches with α ≥ 1/255 in (t*, index) order, as (hit, α).
    pub fn all_hits(&self, o: DVec3, d: DVec3, k: usize) -> Vec<Hit> {
        self.hits_until(o, d, k, f32::INFINITY)
    }

    /// As [`GaussianTracer::all_hits`], but only hits with `t ≤ tmax`: the traversal itself
    /// stops there (segment and shadow queries need nothing beyond their end).
    pub fn hits_until(&self, o: DVec3, d: DVec3, k: usize, tmax: f32) -> Vec<Hit> {
        let o = (o - self.anchor).as_vec3();
        let d = d.as_vec3();
        let mut out = Vec::new();
        let mut buf = KBuffer::new(k.max(1));
        let mut after = None;
        loop {
            self.collect(o, d, None, tmax, after, &mut buf);
            out.extend_from_slice(&buf.hits);
            if !buf.is_full() {
                return out;
            }
            after = buf.hits.last().map(Hit::key);
        }
    }

    /// Composite one ray. `forward` enables the near cull (primary rays).
    pub fn trace(
        &self,
        o: DVec3,
        d: DVec3,
        forward: Option<DVec3>,
        opts: &RenderOptions,
        buf: &mut KBuffer,
    ) -> PixelOut {
        let ro = (o - self.anchor).as_vec3();
        let rd = d.as_vec3();
        let near = forward.map(|f| Near {
            origin: ro,
            forward: f.as_vec3(),
            near: opts.near,
        });
        let mut out = PixelOut::default();
        let mut tr = 1.0f32;
        let (mut c, mut dsum, mut wsum) = (Vec3::ZERO, 0.0f32, 0.0f32);
        let mut after = None;
        'rounds: loop {
            self.collect(ro, rd, near, f32::INFINITY, after, buf);
            out.traversals += 1;
            for h in &buf.hits {
                let a = h.bary[0];
                let next = tr * (1.0 - a);
                if next < opts.min_transmittance {
                    break 'rounds;
                }
                out.hits += 1;
                let g = h.gaussian as usize;
                let col = sh::eval_color(self.cloud.sh_degree, self.cloud.sh_of(g), rd);
                let w = a * tr;
                c += col * w;
                dsum += w * h.t;
                wsum += w;
                tr = next;
            }
            if !buf.is_full() {
                break;
            }
            after = buf.hits.last().map(Hit::key);
        }
        out.rgb = c + opts.background * tr;
        out.alpha = 1.0 - tr;
        out.depth = if wsum > 0.0 { dsum / wsum } else { 0.0 };
        out
    }

    /// Render `cam`.
    pub fn render(&self, cam: &Camera, opts: &RenderOptions) -> Result<(Frame, Stats)> {
        opts.validate()?;
        let forward = cam.world_to_cam.row(2);
        render_frame(cam, |o, d| {
            thread_local! {
                static BUF: std::cell::RefCell<KBuffer> = std::cell::RefCell::new(KBuffer::new(16));
            }
            BUF.with(|b| {
                let mut b = b.borrow_mut();
                if b.k != opts.k {
                    *b = KBuffer::new(opts.k);
                }
                self.trace(o, d, Some(forward), opts, &mut b)
            })
        })
    }
}
