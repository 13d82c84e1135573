//! A part of a traced cloud: its proxies (one padded ellipsoid box per Gaussian), their BVH,
//! where the part stands at time t, and the per-proxy response and α the tracer composites.

use rayon::prelude::*;

use super::*;

/// Gaussian `i`'s box (anchor-relative), index and proxy record; None for a Gaussian that
/// cannot be traced (invalid, never reaching α = 1/255, degenerate, or beyond what an f32
/// BVH holds).
fn proxy_of(cloud: &GaussianCloud, i: usize, anchor: DVec3) -> Option<((Vec3, Vec3), u32, Proxy)> {
    if cloud.invalid_reason(i).is_some() {
        return None;
    }
    let o = cloud.opacity(i);
    // Below 1/255 the Gaussian never reaches the α cut anywhere.
    if !(o * 255.0 > 1.0) {
        return None;
    }
    let r2 = 2.0 * (255.0 * o).ln();
    let s = cloud.scale(i);
    if !(s.min_element() > 0.0) || !s.is_finite() {
        return None;
    }
    let rot = Mat3::from_quat(cloud.unit_rotation(i));
    let inv = Mat3::from_diagonal(s.recip()) * rot.transpose();
    if !inv.is_finite() {
        return None;
    }
    let mu = (cloud.means[i].as_dvec3() - anchor).as_vec3();
    let m = rot * Mat3::from_diagonal(s * r2.sqrt());
    // Half-extent of the ellipsoid R·diag(s·r) along each world axis, padded by a relative
    // 1e-5 plus one f32 ulp of the mean so rounding cannot clip the proxy.
    let half = Vec3::new(m.row(0).length(), m.row(1).length(), m.row(2).length());
    let pad = half * 1e-5 + Vec3::splat(mu.abs().max_element() * 1.2e-7);
    let (blo, bhi) = (mu - half - pad, mu + half + pad);
    // Culled: boxes an f32 BVH cannot hold (positions ~1e26, log-scales ~45); see
    // `backend::MAX_BVH_COORD`.
    if !(fits_bvh(blo) && fits_bvh(bhi) && fits_bvh(cloud.means[i])) {
        return None;
    }
    let proxy = Proxy {
        mean: mu,
        r2,
        opacity: o,
        inv,
        m: rot * Mat3::from_diagonal(s),
    };
    Some(((blo, bhi), i as u32, proxy))
}

impl Part {
    pub(super) fn build(
        cloud: GaussianCloud,
        id_offset: u32,
        track: Option<Track>,
        backend: BackendKind,
        preset: BuildPreset,
    ) -> Result<Self> {
        cloud.check_shape()?;
        // The anchor is the centre of the means a BVH can hold (the others are culled below),
        // so one far-away Gaussian does not move every other one out of f32 range.
        let (lo, hi) = cloud
            .means
            .iter()
            .filter(|m| fits_bvh(**m))
            .fold(None, |acc: Option<(Vec3, Vec3)>, &m| {
                Some(acc.map_or((m, m), |(lo, hi)| (lo.min(m), hi.max(m))))
            })
            .unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let anchor = (0.5 * (lo.as_dvec3() + hi.as_dvec3())).as_vec3().as_dvec3();
        let mut t = Part {
            cloud: GaussianCloud::new(0),
            id_offset,
            track,
            anchor,
            index: Vec::new(),
            proxy: Vec::new(),
            boxes: Vec::new(),
            accel: OnceLock::new(),
            backend,
            preset,
            lo: DVec3::splat(f64::INFINITY),
            hi: DVec3::splat(f64::NEG_INFINITY),
        };
        // Each Gaussian's proxy on its own, in parallel, then gathered in the cloud's order.
        let made: Vec<((Vec3, Vec3), u32, Proxy)> = (0..cloud.len())
            .into_par_iter()
            .filter_map(|i| proxy_of(&cloud, i, anchor))
            .collect();
        let mut boxes = Vec::with_capacity(made.len());
        t.index.reserve_exact(made.len());
        t.proxy.reserve_exact(made.len());
        for ((blo, bhi), i, x) in made {
            t.lo = t.lo.min(blo.as_dvec3() + anchor);
            t.hi = t.hi.max(bhi.as_dvec3() + anchor);
            boxes.push((blo, bhi));
            t.index.push(i);
            t.proxy.push(x);
        }
        spatial_order(&mut boxes, &mut t.index, &mut t.proxy);
        if backend != BackendKind::Obvhs {
            let _ = t.accel.set(build_boxes(backend, preset, &boxes)?);
        }
        t.boxes = boxes;
        t.cloud = cloud;
        Ok(t)
    }

    /// The part's BVH (see [`Part::accel`]'s field).
    pub(super) fn accel(&self) -> &dyn Accel {
        self.accel
            .get_or_init(|| {
                // obvhs fails only on boxes beyond what an f32 BVH holds, and `Part::build`
                // kept none of those (`fits_bvh`); other backends were built eagerly.
                build_boxes(self.backend, self.preset, &self.boxes)
                    .unwrap_or_else(|e| unreachable!("proxy boxes were checked: {e}"))
            })
            .as_ref()
    }

    /// The part's placement at `t` (None for a part fixed in the world).
    pub(super) fn place(&self, t: f64) -> Option<Placed> {
        let track = self.track.as_ref()?;
        let pose = track.sample(t);
        let to_world = DAffine3::from_rotation_translation(
            pose.rotation.as_dquat(),
            pose.translation.as_dvec3(),
        );
        let (lo, hi) = if self.index.is_empty() {
            (DVec3::ZERO, DVec3::ZERO)
        } else {
            transformed_box(&to_world, self.lo, self.hi)
        };
        Some(Placed {
            to_local: DAffine3::from_translation(-self.anchor) * to_world.inverse(),
            to_world,
            lo,
            hi,
        })
    }

    /// Response of proxy `p` along the ray (relative origin `o`, unit direction `d`):
    /// (t*, α) or None when α < 1/255.
    #[inline]
    pub(super) fn response(&self, p: usize, o: Vec3, d: Vec3) -> Option<(f32, f32)> {
        let x = &self.proxy[p];
        let inv = x.inv;
        let og = inv * (o - x.mean);
        let dg = inv * d;
        let dd = dg.length_squared();
        if !(dd > 0.0 && dd.is_finite()) {
            return None;
        }
        let n = dg / dd.sqrt();
        let d2 = n.cross(og).length_squared();
        if !(d2 <= x.r2) {
            return None;
        }
        let alpha = self.alpha(p, d2)?;
        let t = (-og.dot(dg) / dd).max(0.0) + 0.0;
        t.is_finite().then_some((t, alpha))
    }

    /// Proxy `p`'s α at squared Mahalanobis distance `q` from its mean: the rasterizer's
    /// clamp at 0.99 and cut below 1/255 (None).
    #[inline]
    pub(crate) fn alpha(&self, p: usize, q: f32) -> Option<f32> {
        alpha_of(self.proxy[p].opacity, q)
    }
}

/// α of a Gaussian of peak opacity `opacity` at squared Mahalanobis distance `q` (see
/// [`Part::alpha`]).
#[inline]
pub(super) fn alpha_of(opacity: f32, q: f32) -> Option<f32> {
    alpha_of_exp(opacity, (-0.5 * q).exp())
}

/// [`alpha_of`] given its exponential `e = exp(−q/2)` (the tile walk takes eight at once).
#[inline(always)]
pub(super) fn alpha_of_exp(opacity: f32, e: f32) -> Option<f32> {
    let alpha = (opacity * e).min(0.99);
    (alpha >= 1.0 / 255.0).then_some(alpha)
}
