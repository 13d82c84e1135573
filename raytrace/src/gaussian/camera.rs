//! Per-camera preparation of mode `gaussian` for primary rays that carry a pixel footprint
//! ([`crate::footprint`]): BVHs over proxies grown to hold what the footprint brings onto a ray,
//! and the two footprint responses.
//!
//! - [`Footprint::On`], the general path: the Gaussian widened in 3-D by the ray's footprint at
//!   its mean's depth (`response_fp`), evaluated in pixels from a per-camera record
//!   ([`PixelSplat`], with the 3-D form as its reference); proxies padded by `pad_for`.
//! - [`Footprint::Projected`]: the Gaussian evaluated the way native's projection evaluates it
//!   (`hybrid::project` / the reference's `preprocessCUDA` and `renderCUDA`): the EWA 2-D
//!   covariance `J·W·Σ·Wᵀ·Jᵀ` at the mean with the `1.3·tan(fov/2)` Jacobian clamp, plus the
//!   low-pass, its conic evaluated at the ray's pixel position; the pixel is skipped outside the
//!   tiles of the `ceil(3·sqrt(λ))` rectangle, as native skips it. The proxy is the flat box of
//!   the screen square holding the splat's `α ≥ 1/255` ellipse, back-projected to the mean's
//!   depth: every ray through a pixel the splat can reach crosses it, at the ray parameter of
//!   the mean's depth, which is the hit's ordering key under [`HitOrder::MeanDepth`]. It is a
//!   pinhole-camera mode for primary rays only, and a reference for what the 3-D path cannot
//!   match (see `docs/footprint.md`).

use std::time::Instant;

use glam::{DMat3, DVec3, Vec3};
use rayon::prelude::*;
use splatbridge_scene::Camera;

use super::part::alpha_of;
use super::{GaussianTracer, Part};
use crate::backend::{build_boxes, fits_bvh, Accel};
use crate::error::Result;
use crate::footprint::{pad_for, Footprint, HitOrder};
use crate::geom::transformed_box;

/// Native's tile edge in pixels (the reference's `BLOCK_X = BLOCK_Y`).
const TILE: f64 = 16.0;

/// A ray's footprint in one part's frame (f32): the widening `F` (with `det F`) in the basis
/// `(e1, e2)` of the plane ⊥ d, the camera's forward axis, and the ray's continuous pixel.
#[derive(Clone, Copy, Debug)]
pub(super) struct LocalFootprint {
    pub forward: Vec3,
    pub e1: Vec3,
    pub e2: Vec3,
    pub cov: [f32; 3],
    pub det: f32,
    pub pixel: (f32, f32),
    /// The ray's pixel relative to the principal point, `(u − cx, v − cy)` (for
    /// [`PixelSplat`]s).
    pub centred: (f32, f32),
    /// The low-pass variance `s` in pixels² and `s²`.
    pub s: f32,
    pub s2: f32,
}

impl LocalFootprint {
    /// `f` in part `pi`'s frame, for a render through `pad`.
    pub(super) fn new(
        tracer: &GaussianTracer,
        pi: usize,
        f: &crate::footprint::RayFootprint,
        pad: &Padded,
    ) -> Self {
        let s = pad.variance as f32;
        LocalFootprint {
            forward: tracer.local_dir(pi, f.forward),
            e1: tracer.local_dir(pi, f.e1),
            e2: tracer.local_dir(pi, f.e2),
            cov: f.cov.map(|v| v as f32),
            det: (f.cov[0] * f.cov[2] - f.cov[1] * f.cov[1]) as f32,
            pixel: (f.pixel.0 as f32, f.pixel.1 as f32),
            centred: (
                (f.pixel.0 - pad.principal.0) as f32,
                (f.pixel.1 - pad.principal.1) as f32,
            ),
            s,
            s2: s * s,
        }
    }
}

/// One Gaussian's footprint-widened response for the rays of one pinhole camera, as a function
/// of the ray's pixel (mode `on`).
///
/// The widened response of [`Part::response_widened_3d`] is `q = xᵀ(C + Δ)⁻¹x` on the plane
/// ⊥ d, with `Δ` native's low-pass `s·I` pulled back through the perspective Jacobian `A`
/// of that plane at the mean's depth `z` (see [`crate::footprint`]). Carried to pixels by
/// `A` it is `q = δᵀ(J·Σ·Jᵀ + s·I)⁻¹δ`, with `J` the full 2×3 Jacobian of the projection at
/// the ray's point of depth `z` (`J·d = 0`, so `J` equals `A` on the plane) and `δ = J·(μ − o)`.
/// For a ray through pixel `(u, v)` (centred: `ū = u − cx`), `J = (1/z)·[[fx, 0, −ū],
/// [0, fy, −v̄]]·W`, which is affine in the pixel, and `δ = (μ̄u − ū, μ̄v − v̄)` is the pixel's
/// offset from the mean's projection. With `W·M` (`Σ = M·Mᵀ`) stored as `p0 = fx·row₀/z`,
/// `p1 = fy·row₁/z` and `w = row₂/z`, a ray needs `b0 = p0 − ū·w` and `b1 = p1 − v̄·w`
/// (`J·Σ·Jᵀ = [bᵢ·bⱼ]`), and `det(J·Σ·Jᵀ) = |b0 × b1|²` (Lagrange's identity: no cancellation
/// for a needle seen end-on). The same number as the 3-D form up to rounding, for about half
/// its arithmetic, on one 56-byte record instead of the 92-byte proxy.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct PixelSplat {
    pub(super) mu: [f32; 2],
    pub(super) p0: [f32; 3],
    pub(super) p1: [f32; 3],
    pub(super) w: [f32; 3],
    /// The proxy's squared extent in standard deviations (its `r2`) and peak opacity.
    pub(super) r2: f32,
    pub(super) opacity: f32,
    /// False where the record cannot hold the response (the mean in the camera's plane, or a
    /// coefficient beyond f32): the 3-D form is evaluated instead.
    pub(super) ok: bool,
}

/// A [`PixelSplat::bound`]: the ellipse's centre `μ` (centred pixels), `K`, `a_max`, and its
/// half-extents in pixels along the image axes.
pub(super) type ScreenBound = ([f32; 2], [f32; 3], f32, [f64; 2]);

impl PixelSplat {
    /// The record of a Gaussian with `Σ = M·Mᵀ` (world `m`) and world mean `mean`, for `cam`.
    pub(super) fn new(cam: &Camera, mean: DVec3, m: &DMat3, r2: f32, opacity: f32) -> Self {
        let w = cam.world_to_cam;
        let rc = w * (mean - cam.centre);
        let mc = w * *m;
        let z = rc.z;
        let v = |x: DVec3| [x.x as f32, x.y as f32, x.z as f32];
        let rec = PixelSplat {
            mu: [(cam.fx * rc.x / z) as f32, (cam.fy * rc.y / z) as f32],
            p0: v(mc.row(0) * (cam.fx / z)),
            p1: v(mc.row(1) * (cam.fy / z)),
            w: v(mc.row(2) / z),
            r2,
            opacity,
            ok: true,
        };
        let finite = rec.mu.iter().chain(&rec.p0).chain(&rec.p1).chain(&rec.w);
        let ok = z != 0.0 && finite.into_iter().all(|x| x.is_finite());
        PixelSplat { ok, ..rec }
    }

    /// A screen ellipse holding every ray [`PixelSplat::q`] can pass (`q ≤ r2`), for a low-pass
    /// of `s` pixels²: `(μ, K, a_max)` with the ray's centred pixel `p` passing only if
    /// `δᵀ·K·δ ≤ a_max`, `δ = μ − p`, and the ellipse's half-extents along the axes. None where
    /// no useful bound holds (the record unused, or a Gaussian deep along the view axis).
    ///
    /// Why it holds: with `B(p) = [b0, b1]`, `B(p) = B(μ) + w·δᵀ`, so for any `ε > 0`
    /// `J·Σ·Jᵀ = BᵀB ⪯ (1 + ε)·B(μ)ᵀB(μ) + (1 + 1/ε)·|w|²·δδᵀ`. With
    /// `A = (1 + ε)·B(μ)ᵀB(μ) + s·I`, `c = (1 + 1/ε)·|w|²` and `a = δᵀA⁻¹δ`,
    /// `q ≥ δᵀ(A + c·δδᵀ)⁻¹δ = a/(1 + c·a)` (Sherman–Morrison), so `q ≤ r2` gives
    /// `a ≤ r2/(1 − c·r2)` when `c·r2 < 1`. `ε = |w|·√r2` nearly minimises the bound's growth
    /// (`≈ 1 + 2|w|√r2`; `|w|` is the Gaussian's extent along the view axis over its depth,
    /// 1e-3 to 1e-2 in captures). The bound is widened for f32 rounding of `q` and of the test
    /// itself: a relative 1e-3 plus 1e-5 per unit of `A`'s condition number (the quadratic
    /// forms lose about that many ulps to cancellation), far above the ~1e-6 measured gaps
    /// (`pixel_tests`); `tile_tests` check that no hit is lost, bit for bit.
    pub(super) fn bound(&self, s: f64) -> Option<ScreenBound> {
        if !self.ok {
            return None;
        }
        let d = |x: [f32; 3]| DVec3::new(x[0] as f64, x[1] as f64, x[2] as f64);
        let (p0, p1, w) = (d(self.p0), d(self.p1), d(self.w));
        let (mu0, mu1) = (self.mu[0] as f64, self.mu[1] as f64);
        let r2 = self.r2 as f64;
        let (b0, b1) = (p0 - mu0 * w, p1 - mu1 * w);
        let ww = w.length_squared();
        let eps = (ww.sqrt() * r2.sqrt()).max(1e-6);
        let c = (1.0 + 1.0 / eps) * ww;
        if !(c * r2 < 0.5) {
            return None;
        }
        let (a00, a01, a11) = (
            (1.0 + eps) * b0.dot(b0) + s,
            (1.0 + eps) * b0.dot(b1),
            (1.0 + eps) * b1.dot(b1) + s,
        );
        let det = a00 * a11 - a01 * a01;
        // λ_max / λ_min of A (≥ 1).
        let tr = a00 + a11;
        let disc = ((a00 - a11).powi(2) + 4.0 * a01 * a01).sqrt();
        let cond = (tr + disc) / (tr - disc).max(f64::MIN_POSITIVE);
        let amax = r2 / (1.0 - c * r2) * (1.0 + 1e-3 + 1e-5 * cond);
        let k = [a11 / det, -a01 / det, a00 / det];
        let half = [(amax * a00).sqrt(), (amax * a11).sqrt()];
        let ok = det > 0.0
            && amax.is_finite()
            && k.iter().chain(&half).all(|x| x.is_finite())
            && cond < 1e4;
        ok.then(|| (self.mu, k.map(|x| x as f32), amax as f32, half))
    }

    /// The widened squared Mahalanobis distance `q` for the ray through the centred pixel of
    /// `fp`; None where `det(J·Σ·Jᵀ + s·I)` is not a positive finite number.
    #[inline]
    pub(super) fn q(&self, fp: &LocalFootprint) -> Option<f32> {
        let (u, v) = fp.centred;
        let w = Vec3::from(self.w);
        let b0 = Vec3::from(self.p0) - u * w;
        let b1 = Vec3::from(self.p1) - v * w;
        let (m00, m01, m11) = (b0.dot(b0), b0.dot(b1), b1.dot(b1));
        let s = fp.s;
        let det = b0.cross(b1).length_squared() + s * (m00 + m11) + fp.s2;
        if !(det > 0.0 && det.is_finite()) {
            return None;
        }
        let (x0, x1) = (self.mu[0] - u, self.mu[1] - v);
        Some((x0 * x0 * (m11 + s) - 2.0 * x0 * x1 * m01 + x1 * x1 * (m00 + s)) / det)
    }
}

/// One Gaussian as native's projection sees it from the camera (mode `projected`).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Splat2d {
    /// Screen position of the mean, pixel `i` sampled at `i`.
    x: f32,
    y: f32,
    conic: [f32; 3],
    /// Tile rectangle `[x0, y0, x1, y1)` (empty: never drawn).
    rect: [i32; 4],
}

/// Per-camera BVHs over the grown proxies (one per part), each moving part's grown world
/// bounds, and in mode `projected` each proxy's splat.
pub struct Padded {
    pub(super) mode: Footprint,
    /// Per part, its grown proxies' BVHs (see [`Bucket`]).
    pub(super) accels: Vec<Vec<Bucket>>,
    /// Each part's grown proxy boxes (anchor-relative, in the part's frame).
    pub(super) boxes: Vec<Vec<(Vec3, Vec3)>>,
    pub(super) bounds: Vec<Option<(DVec3, DVec3)>>,
    pub(super) splats: Vec<Vec<Splat2d>>,
    /// Per part, each proxy's [`PixelSplat`] (mode `on`; empty otherwise).
    pub(super) pixels: Vec<Vec<PixelSplat>>,
    /// The low-pass variance in pixels² and the camera's principal point.
    pub(super) variance: f64,
    pub(super) principal: (f64, f64),
    /// Seconds spent building them.
    pub build_seconds: f64,
}

/// Proxies of one part whose grown boxes have diagonals within a factor [`BUCKET_RATIO`] of
/// each other, under their own BVH; a part's buckets are listed most populous first.
///
/// Under [`HitOrder::MeanDepth`] a hit's key is its mean's view depth along the ray,
/// `(μ − o)·f / (d·f)`, which can come before the ray enters the proxy's box; so a traversal
/// cannot stop at the k-th key K. It can stop a little later: the mean and the point where
/// the ray enters the grown box both lie in that box, so a hit keyed below K is in a box the
/// ray enters before `K + diagonal / (d·f)`. With one BVH over every proxy, the largest
/// Gaussian's diagonal would set that margin for all of them; grouping proxies by size keeps
/// each group's margin (`reach`, its largest diagonal) near its own proxies' size.
pub(super) struct Bucket {
    pub(super) accel: Box<dyn Accel>,
    /// The part's proxy index of each of the BVH's primitives (None: the identity).
    pub(super) ids: Option<Vec<u32>>,
    /// Largest diagonal of the bucket's grown boxes.
    pub(super) reach: f32,
}

/// Size ratio between the smallest and largest proxies of a bucket. With 4 a capture whose
/// Gaussians span five decades of size gets about nine buckets (nine BVH roots per ray), and
/// every bucket's margin is at most 4 × (with the √3 of a box's diagonal) its smallest
/// proxy's extent.
const BUCKET_RATIO: f32 = 4.0;

/// Most buckets a part is split into; larger proxies share the last one.
const MAX_BUCKETS: usize = 16;

/// The traversal's cull distance for a k-th key `k` under mean-depth keys (see [`Bucket`]):
/// `k + reach / cos`, where `cos = d·f` is the ray's cosine to the camera's forward axis.
/// Widened by a relative 1e-5 (the f32 rounding of the key, `1.2e-7` per operation, over a
/// few operations, with a hundredfold margin) and 1e-4 ray units (the node test's own
/// epsilon, `ObvhsAccel::walk`); infinite when no bound holds (`cos ≤ 0`, unbounded reach).
#[inline]
pub(super) fn rekeyed_cull(k: f32, reach: f32, cos: f32) -> f32 {
    if !(cos > 0.0) || !k.is_finite() {
        return f32::INFINITY;
    }
    let margin = reach / cos;
    let c = k + margin;
    // Never NaN: k is finite, cos > 0 and reach ≥ 0 (a diagonal length), so c is finite or +∞.
    c + (c.abs() + margin) * 1e-5 + 1e-4
}

/// Split `boxes` (a part's grown proxies) into [`Bucket`]s by diagonal and build each one's
/// BVH; a part whose proxies all fall in one bucket keeps the identity order.
fn buckets(tracer: &GaussianTracer, boxes: &[(Vec3, Vec3)]) -> Result<Vec<Bucket>> {
    if boxes.is_empty() {
        return Ok(Vec::new());
    }
    let diag: Vec<f32> = boxes.iter().map(|(lo, hi)| (*hi - *lo).length()).collect();
    let smallest = diag
        .iter()
        .copied()
        .filter(|d| *d > 0.0)
        .fold(f32::INFINITY, f32::min);
    let class = |d: f32| -> usize {
        if !(d > smallest) || !smallest.is_finite() {
            return 0;
        }
        let c = ((d / smallest).ln() / BUCKET_RATIO.ln()).floor();
        if c.is_finite() {
            (c as usize).min(MAX_BUCKETS - 1)
        } else {
            MAX_BUCKETS - 1
        }
    };
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); MAX_BUCKETS];
    for (i, d) in diag.iter().enumerate() {
        members[class(*d)].push(i as u32);
    }
    let reach_of = |ids: &[u32]| {
        ids.iter()
            .map(|&i| diag[i as usize])
            .fold(0.0f32, |a, d| if d > a { d } else { a })
    };
    let used = members.iter().filter(|m| !m.is_empty()).count();
    if used == 1 {
        return Ok(vec![Bucket {
            accel: build_boxes(tracer.backend, tracer.preset, boxes)?,
            ids: None,
            reach: diag.iter().copied().fold(0.0f32, f32::max),
        }]);
    }
    // Until the k-buffer is full nothing is culled, so the bucket most likely to fill it, the
    // most populous, is traversed first; the others then start from its k-th key.
    let mut members: Vec<Vec<u32>> = members.into_iter().filter(|m| !m.is_empty()).collect();
    members.sort_by_key(|m| std::cmp::Reverse(m.len()));
    let mut out = Vec::with_capacity(used);
    for ids in members {
        let sub: Vec<(Vec3, Vec3)> = ids.iter().map(|&i| boxes[i as usize]).collect();
        out.push(Bucket {
            accel: build_boxes(tracer.backend, tracer.preset, &sub)?,
            reach: reach_of(&ids),
            ids: Some(ids),
        });
    }
    Ok(out)
}

impl Part {
    /// As [`Part::response`] with the Gaussian widened by the ray's footprint at its mean's
    /// view depth (see [`crate::footprint`]): the 2-D marginal `C` of the Gaussian on the plane
    /// ⊥ d plus `z²·F`, evaluated at the mean's offset in that plane; peak opacity unchanged,
    /// as in native splatting. `q` is the widened squared Mahalanobis distance of the ray
    /// ([`PixelSplat::q`], or [`Part::widened_q_3d`] where the record cannot hold it). With
    /// `keyed` the caller keys the hit at its mean's depth and the distance returned is 0;
    /// otherwise it is the unwidened `t*`, clamped into the ray's interval inside the padded proxy
    /// `bx`: a ray that meets only the widened Gaussian can have its unwidened `t*` outside the
    /// box, and the k-buffer's cull distance must never be passed by a hit whose box the
    /// traversal has not entered yet.
    #[inline]
    pub(super) fn response_fp(
        &self,
        p: usize,
        o: Vec3,
        d: Vec3,
        fp: &LocalFootprint,
        bx: (Vec3, Vec3),
        px: &PixelSplat,
        keyed: bool,
    ) -> Option<(f32, f32)> {
        // The widened test first, on the per-camera record alone: most candidates fail it,
        // and every condition of the response is independent of the others, so their order
        // does not change the result.
        let q = if px.ok {
            px.q(fp)?
        } else {
            self.widened_q_3d(p, o, fp)?
        };
        if !(q <= px.r2) {
            return None;
        }
        let alpha = alpha_of(px.opacity, q)?;
        if keyed {
            // The caller keys the hit at its mean's depth: `t*` is not needed.
            return Some((0.0, alpha));
        }
        let x = &self.proxy[p];
        let inv = x.inv;
        let og = inv * (o - x.mean);
        let dg = inv * d;
        let dd = dg.length_squared();
        if !(dd > 0.0 && dd.is_finite()) {
            return None;
        }
        let t = (-og.dot(dg) / dd).max(0.0) + 0.0;
        let (t0, t1) = slab(o, d, bx);
        let t = if t0 <= t1 {
            t.clamp(t0.max(0.0), t1.max(0.0))
        } else {
            t
        };
        t.is_finite().then_some((t, alpha))
    }

    /// The widened squared Mahalanobis distance of the ray from proxy `p`, in 3-D: the 2-D
    /// marginal `C = [aᵢ·aⱼ]` (`aᵢ = Mᵀeᵢ`) on the plane ⊥ d plus `z²·F`, at the mean's offset
    /// `x` in that plane, `q = xᵀ(C + z²F)⁻¹x`. None where the determinant is not a positive
    /// finite number. The reference [`PixelSplat::q`] is checked against, and its fallback.
    #[inline]
    pub(super) fn widened_q_3d(&self, p: usize, o: Vec3, fp: &LocalFootprint) -> Option<f32> {
        let x = &self.proxy[p];
        let rel = x.mean - o;
        let z = rel.dot(fp.forward);
        let z2 = z * z;
        let mt = x.m.transpose();
        let (a1, a2) = (mt * fp.e1, mt * fp.e2);
        let (g0, g1, g2) = (a1.dot(a1), a1.dot(a2), a2.dot(a2));
        let [f0, f1, f2] = fp.cov;
        let (c0, c1, c2) = (g0 + z2 * f0, g1 + z2 * f1, g2 + z2 * f2);
        // det(G + z²F) expanded so that no term cancels: det G = |a1 × a2|² (Lagrange's
        // identity) rather than g0·g2 − g1², which loses everything for a needle seen end-on.
        let det = a1.cross(a2).length_squared()
            + z2 * (g0 * f2 + g2 * f0 - 2.0 * g1 * f1)
            + z2 * z2 * fp.det;
        if !(det > 0.0 && det.is_finite()) {
            return None;
        }
        let (x0, x1) = (rel.dot(fp.e1), rel.dot(fp.e2));
        Some((c2 * x0 * x0 - 2.0 * c1 * x0 * x1 + c0 * x1 * x1) / det)
    }

    /// Native's response of proxy `p` at the ray's pixel (mode `projected`): the splat's conic
    /// at `(u − ½, v − ½)` (pixel `i` sampled at `i`), skipped outside its tile rectangle,
    /// where `power > 0` and below α = 1/255, α clamped at 0.99. The hit distance is the ray
    /// parameter at the mean's view depth.
    #[inline]
    pub(super) fn response_projected(
        &self,
        p: usize,
        o: Vec3,
        d: Vec3,
        fp: &LocalFootprint,
        s: &Splat2d,
    ) -> Option<(f32, f32)> {
        let (u, v) = fp.pixel;
        let (i, j) = (
            (u.floor() as i32).div_euclid(16),
            (v.floor() as i32).div_euclid(16),
        );
        if !(i >= s.rect[0] && i < s.rect[2] && j >= s.rect[1] && j < s.rect[3]) {
            return None;
        }
        let (dx, dy) = (s.x - (u - 0.5), s.y - (v - 0.5));
        let [c0, c1, c2] = s.conic;
        let power = -0.5 * ((c0 * dx) * dx + (c2 * dy) * dy) - dx * (c1 * dy);
        if !(power <= 0.0) {
            return None;
        }
        // −2·power is exact, so −½ of it is `power` again, bit for bit.
        let alpha = self.alpha(p, -2.0 * power)?;
        let t = (self.proxy[p].mean - o).dot(fp.forward) / d.dot(fp.forward);
        (t.is_finite() && t >= 0.0).then_some((t, alpha))
    }
}

/// The ray's parameter interval inside a box (f32 slab test; empty when `t0 > t1`).
#[inline]
fn slab(o: Vec3, d: Vec3, (lo, hi): (Vec3, Vec3)) -> (f32, f32) {
    let inv = d.recip();
    let (a, b) = ((lo - o) * inv, (hi - o) * inv);
    let (near, far) = (a.min(b), a.max(b));
    // An axis the ray is parallel to gives NaN or ±inf; f32::max/min ignore NaN.
    (near.max_element(), far.min_element())
}

/// One f32 ulp of the box's coordinates plus a relative 1e-5 of its size, as the unpadded
/// proxies are padded, so rounding cannot clip a grown proxy.
fn slack(lo: Vec3, hi: Vec3) -> Vec3 {
    (hi - lo).abs() * 1e-5 + Vec3::splat(lo.abs().max(hi.abs()).max_element() * 1.2e-7)
}

impl GaussianTracer {
    /// What a render of `cam` with `footprint` and a low-pass of `variance_px2` pixels² needs
    /// beyond the tracer's own BVHs (None with the footprint off).
    pub fn for_camera(
        &self,
        cam: &Camera,
        footprint: Footprint,
        variance_px2: f64,
    ) -> Result<Option<Padded>> {
        match footprint {
            Footprint::Off => Ok(None),
            Footprint::On => self.padded(cam, variance_px2).map(Some),
            Footprint::Projected => self.projected(cam, variance_px2).map(Some),
        }
    }

    /// BVHs for `cam` at the current time over proxies padded by the largest footprint of a
    /// low-pass of `variance_px2` pixels² ([`pad_for`]), so that no Gaussian the widening
    /// brings onto a ray is missed. Built per camera (and pose), like native's projection.
    pub fn padded(&self, cam: &Camera, variance_px2: f64) -> Result<Padded> {
        self.padded_with(cam, variance_px2, true)
    }

    /// [`GaussianTracer::padded`], with its BVHs (`bvh`) or only its boxes.
    fn padded_with(&self, cam: &Camera, variance_px2: f64, bvh: bool) -> Result<Padded> {
        let forward = cam.world_to_cam.row(2);
        self.grown(Footprint::On, bvh, |part, pi, p, (blo, bhi)| {
            let w = self.world_mean(pi, part, p);
            let z = (w - cam.centre).dot(forward);
            let pad = pad_for(cam, variance_px2, z, part.proxy[p].r2.sqrt() as f64);
            let pad = Vec3::splat((pad * (1.0 + 1e-5)) as f32) + slack(blo, bhi);
            let rot = match &self.placed[pi] {
                Some(pl) => pl.to_world.matrix3,
                None => DMat3::IDENTITY,
            };
            let m = rot * part.proxy[p].m.as_dmat3();
            let x = &part.proxy[p];
            let px = PixelSplat::new(cam, w, &m, x.r2, x.opacity);
            ((blo - pad, bhi + pad), Splat2d::default(), px)
        })
        .map(|mut out| {
            out.variance = variance_px2;
            out.principal = (cam.cx, cam.cy);
            out
        })
    }

    /// Native's projection of every proxy for `cam` with a low-pass of `variance_px2` pixels²,
    /// and BVHs over the flat back-projected boxes of their screen footprints (mode
    /// `projected`).
    pub fn projected(&self, cam: &Camera, variance_px2: f64) -> Result<Padded> {
        self.projected_with(cam, variance_px2, true)
    }

    /// [`GaussianTracer::projected`], with its BVH (`bvh`) or only its boxes and splats.
    fn projected_with(&self, cam: &Camera, variance_px2: f64, bvh: bool) -> Result<Padded> {
        let w = cam.world_to_cam;
        let grid = [
            (cam.width as f64 / TILE).ceil(),
            (cam.height as f64 / TILE).ceil(),
        ];
        self.grown(Footprint::Projected, bvh, |part, pi, p, own| {
            let world = self.world_mean(pi, part, p);
            let t = w * (world - cam.centre);
            // The part's rotation carries the Gaussian's axes into the world.
            let rot = match &self.placed[pi] {
                Some(pl) => pl.to_world.matrix3,
                None => DMat3::IDENTITY,
            };
            let m = rot * part.proxy[p].m.as_dmat3();
            let Some((s, half)) = splat_2d(cam, t, &m, variance_px2, part.proxy[p].r2 as f64, grid)
            else {
                return (own, Splat2d::default(), PixelSplat::default());
            };
            // The screen square holding the α ≥ 1/255 ellipse, back-projected to depth t.z.
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
                let (u, v) = (s.x as f64 + 0.5 + sx * half, s.y as f64 + 0.5 + sy * half);
                let pc = DVec3::new((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0) * t.z;
                let q = self.local_point(pi, cam.centre + w.transpose() * pc);
                lo = lo.min(q);
                hi = hi.max(q);
            }
            let pad = slack(lo, hi);
            if !(lo.is_finite() && hi.is_finite()) {
                return (own, Splat2d::default(), PixelSplat::default());
            }
            ((lo - pad, hi + pad), s, PixelSplat::default())
        })
    }

    /// World position of proxy `p`'s mean at the current pose.
    fn world_mean(&self, pi: usize, part: &Part, p: usize) -> DVec3 {
        let m = part.proxy[p].mean.as_dvec3() + part.anchor;
        match &self.placed[pi] {
            Some(pl) => pl.to_world.transform_point3(m),
            None => m,
        }
    }

    /// As [`GaussianTracer::for_camera`] without the BVHs: the grown boxes (and splats) the
    /// tile path bins (`tiles`).
    pub(super) fn grown_boxes(
        &self,
        cam: &Camera,
        footprint: Footprint,
        variance_px2: f64,
    ) -> Result<Option<Padded>> {
        match footprint {
            Footprint::Off => Ok(None),
            Footprint::On => self.padded_with(cam, variance_px2, false).map(Some),
            Footprint::Projected => self.projected_with(cam, variance_px2, false).map(Some),
        }
    }

    /// Per-part `grow(part, part index, proxy, own box)` boxes (and splats, pixel records),
    /// in parallel over the proxies, and the BVHs over them when `bvh` is set (none
    /// otherwise: `accels` is left empty).
    fn grown<F>(&self, mode: Footprint, bvh: bool, grow: F) -> Result<Padded>
    where
        F: Fn(&Part, usize, usize, (Vec3, Vec3)) -> ((Vec3, Vec3), Splat2d, PixelSplat) + Sync,
    {
        let start = Instant::now();
        let n = self.parts.len();
        let mut out = Padded {
            mode,
            accels: Vec::with_capacity(n),
            boxes: Vec::with_capacity(n),
            bounds: Vec::with_capacity(n),
            splats: Vec::with_capacity(n),
            pixels: Vec::with_capacity(n),
            variance: 0.0,
            principal: (0.0, 0.0),
            build_seconds: 0.0,
        };
        for (pi, part) in self.parts.iter().enumerate() {
            let grown: Vec<((Vec3, Vec3), Splat2d, PixelSplat)> = part
                .boxes
                .par_iter()
                .enumerate()
                .map(|(p, &own)| {
                    let (mut b, s, px) = grow(part, pi, p, own);
                    // A footprint so wide that the grown box leaves what an f32 BVH holds (a
                    // camera ~1e12 away, framing an outlier) covers far less than a pixel
                    // there: keep the Gaussian's own box rather than refuse the render (the
                    // tracer's own BVHs cull such boxes the same way, `Part::new`).
                    if !(fits_bvh(b.0) && fits_bvh(b.1)) {
                        b = own;
                    }
                    (b, s, px)
                })
                .collect();
            let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            for (b, _, _) in &grown {
                lo = lo.min(b.0.as_dvec3() + part.anchor);
                hi = hi.max(b.1.as_dvec3() + part.anchor);
            }
            let boxes: Vec<(Vec3, Vec3)> = grown.iter().map(|g| g.0).collect();
            let splats = match mode {
                Footprint::Projected => grown.iter().map(|g| g.1).collect(),
                _ => Vec::new(),
            };
            let pixels = match mode {
                Footprint::On => grown.iter().map(|g| g.2).collect(),
                _ => Vec::new(),
            };
            drop(grown);
            out.accels.push(match mode {
                _ if !bvh => Vec::new(),
                // Projected hits are keyed where their flat proxy is entered: one BVH.
                Footprint::Projected if !boxes.is_empty() => vec![Bucket {
                    accel: build_boxes(self.backend, self.preset, &boxes)?,
                    ids: None,
                    reach: f32::INFINITY,
                }],
                _ => buckets(self, &boxes)?,
            });
            out.bounds.push(match &self.placed[pi] {
                Some(pl) if !boxes.is_empty() => Some(transformed_box(&pl.to_world, lo, hi)),
                _ => None,
            });
            out.boxes.push(boxes);
            out.splats.push(splats);
            out.pixels.push(pixels);
        }
        out.build_seconds = start.elapsed().as_secs_f64();
        Ok(out)
    }
}

/// Native's projection of a Gaussian with `Σ = M·Mᵀ` (world) whose mean is at camera-space
/// `t`: the splat and the half-size in pixels of the square holding its `r2` ellipse (plus a
/// pixel of slack for the f32 evaluation). None where native culls it (behind, degenerate,
/// off-screen).
fn splat_2d(
    cam: &Camera,
    t: DVec3,
    m: &DMat3,
    variance_px2: f64,
    r2: f64,
    grid: [f64; 2],
) -> Option<(Splat2d, f64)> {
    if !(t.z > 0.0) || !t.is_finite() {
        return None;
    }
    let limx = 1.3 * 0.5 * cam.width as f64 / cam.fx;
    let limy = 1.3 * 0.5 * cam.height as f64 / cam.fy;
    let tx = (t.x / t.z).clamp(-limx, limx) * t.z;
    let ty = (t.y / t.z).clamp(-limy, limy) * t.z;
    let tz2 = t.z * t.z;
    let wt = cam.world_to_cam.transpose();
    let m0 = wt * DVec3::new(cam.fx / t.z, 0.0, -cam.fx * tx / tz2);
    let m1 = wt * DVec3::new(0.0, cam.fy / t.z, -cam.fy * ty / tz2);
    let (a0, a1) = (m.transpose() * m0, m.transpose() * m1);
    let (a, b, c) = (
        a0.dot(a0) + variance_px2,
        a0.dot(a1),
        a1.dot(a1) + variance_px2,
    );
    let det = a * c - b * b;
    if !(det > 0.0 && det.is_finite()) {
        return None;
    }
    let mid = 0.5 * (a + c);
    let lambda = mid + (mid * mid - det).max(0.1).sqrt();
    let radius = (3.0 * lambda.sqrt()).ceil();
    let x = cam.fx * t.x / t.z + cam.cx - 0.5;
    let y = cam.fy * t.y / t.z + cam.cy - 0.5;
    if !(radius.is_finite() && x.is_finite() && y.is_finite()) {
        return None;
    }
    // The reference's getRect, truncating toward zero and clamped to the grid.
    let clamp = |v: f64, g: f64| v.trunc().clamp(0.0, g) as i32;
    let rect = [
        clamp((x - radius) / TILE, grid[0]),
        clamp((y - radius) / TILE, grid[1]),
        clamp((x + radius + TILE - 1.0) / TILE, grid[0]),
        clamp((y + radius + TILE - 1.0) / TILE, grid[1]),
    ];
    if rect[2] <= rect[0] || rect[3] <= rect[1] {
        return None;
    }
    let lmax = mid + (mid * mid - det).max(0.0).sqrt();
    let half = (r2 * lmax).sqrt() + 1.0;
    let splat = Splat2d {
        x: x as f32,
        y: y as f32,
        conic: [(c / det) as f32, (-b / det) as f32, (a / det) as f32],
        rect,
    };
    half.is_finite().then_some((splat, half))
}

/// The hit key of a primary ray's hit under `order` (None: keep the hit's own `t`): the mean's
/// depth along the camera axis `f` over the ray's cosine `d·f` to it (computed once per ray).
#[inline]
pub(super) fn mean_depth_key(
    order: HitOrder,
    mean: Vec3,
    o: Vec3,
    f: Vec3,
    cos: f32,
) -> Option<f32> {
    (order == HitOrder::MeanDepth).then(|| (mean - o).dot(f) / cos)
}
