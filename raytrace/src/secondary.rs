//! Secondary rays for effects (shadows, reflections, fog): transmittance along a segment and
//! the closest hit whose opacity reaches a threshold, for both modes, with the same hit order
//! and de-duplication as primary rays (no near cull).

use std::ops::ControlFlow;

use glam::{DVec3, Vec3};

use crate::gaussian::GaussianTracer;
use crate::kbuffer::{walk, KBuffer};
use crate::mesh_tracer::{Instances, MeshTracer};

/// A closest opaque hit: world distance along the unit direction and the hit's colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpaqueHit {
    pub t: f64,
    pub rgb: Vec3,
    pub alpha: f32,
}

/// Queries any tracer answers.
pub trait SecondaryRays {
    /// Product of (1 − α) over the hits strictly between `from` and `to`, skipping the first
    /// `offset` units (to leave the surface a ray starts on). 0 once below 1e-4.
    fn transmittance(&self, from: DVec3, to: DVec3, offset: f64) -> f32;
    /// The nearest hit with α ≥ `threshold` along `o + t·d` (d unit length), `offset ≤ t ≤ tmax`.
    fn closest_opaque(
        &self,
        o: DVec3,
        d: DVec3,
        offset: f64,
        tmax: f64,
        threshold: f32,
    ) -> Option<OpaqueHit>;
}

/// A mesh scene frozen at one time, for secondary queries.
pub struct MeshAt<'a> {
    pub tracer: &'a MeshTracer,
    pub insts: Instances,
    pub k: usize,
}

impl MeshTracer {
    /// Freeze the scene at `time` for secondary rays.
    pub fn at(&self, time: f64) -> MeshAt<'_> {
        MeshAt {
            tracer: self,
            insts: self.prepare(time),
            k: 16,
        }
    }
}

fn segment(from: DVec3, to: DVec3) -> Option<(DVec3, f64)> {
    let v = to - from;
    let len = v.length();
    (len > 0.0 && len.is_finite()).then(|| (v / len, len))
}

impl SecondaryRays for MeshAt<'_> {
    fn transmittance(&self, from: DVec3, to: DVec3, offset: f64) -> f32 {
        let Some((d, len)) = segment(from, to) else {
            return 1.0;
        };
        let mut buf = KBuffer::new(self.k);
        let mut tr = 1.0f32;
        let collect = |after, buf: &mut _| {
            self.tracer
                .collect(&self.insts, from, d, offset as f32, len as f32, after, buf)
        };
        let (_, stop) = walk(&mut buf, collect, |h| {
            // Strictly before the end point: a surface at `to` does not shadow itself.
            if h.t as f64 >= len {
                return ControlFlow::Break(tr);
            }
            tr *= 1.0 - self.tracer.shade(&self.insts, h).w;
            if tr < 1e-4 {
                return ControlFlow::Break(0.0);
            }
            ControlFlow::Continue(())
        });
        stop.unwrap_or(tr)
    }

    fn closest_opaque(
        &self,
        o: DVec3,
        d: DVec3,
        offset: f64,
        tmax: f64,
        threshold: f32,
    ) -> Option<OpaqueHit> {
        let mut buf = KBuffer::new(self.k);
        let collect = |after, buf: &mut _| {
            self.tracer
                .collect(&self.insts, o, d, offset as f32, tmax as f32, after, buf)
        };
        walk(&mut buf, collect, |h| {
            let c = self.tracer.shade(&self.insts, h);
            if c.w >= threshold {
                return ControlFlow::Break(OpaqueHit {
                    t: h.t as f64,
                    rgb: c.truncate(),
                    alpha: c.w,
                });
            }
            ControlFlow::Continue(())
        })
        .1
    }
}

impl SecondaryRays for GaussianTracer {
    fn transmittance(&self, from: DVec3, to: DVec3, offset: f64) -> f32 {
        let Some((d, len)) = segment(from, to) else {
            return 1.0;
        };
        let mut tr = 1.0f32;
        // One f32 step past the end so no hit below the f64 length is lost to rounding.
        for h in self.hits_until(from, d, 16, (len as f32).next_up()) {
            let t = h.t as f64;
            if t < offset {
                continue;
            }
            if t >= len {
                break;
            }
            tr *= 1.0 - h.payload.alpha;
            if tr < 1e-4 {
                return 0.0;
            }
        }
        tr
    }

    fn closest_opaque(
        &self,
        o: DVec3,
        d: DVec3,
        offset: f64,
        tmax: f64,
        threshold: f32,
    ) -> Option<OpaqueHit> {
        self.hits_until(o, d, 16, (tmax as f32).next_up())
            .into_iter()
            .filter(|h| (h.t as f64) >= offset && (h.t as f64) <= tmax)
            .find(|h| h.payload.alpha >= threshold)
            .map(|h| OpaqueHit {
                t: h.t as f64,
                rgb: self.hit_color(&h, d),
                alpha: h.payload.alpha,
            })
    }
}
