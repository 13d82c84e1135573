//! Ordered hit lists of mode-mesh rays: per pixel, the triangles a ray crossed in the order
//! the compositor blends them (triangle, barycentrics, distance), for consumers that
//! re-composite the same hits with other vertex colours (mesh distillation: the geometry is
//! fixed while colours and opacities are fitted, so one trace serves every iteration).
//!
//! The walk is [`MeshTracer::trace`]'s: the same k-buffer rounds, keys and α > 0 filter, and
//! front-to-back transmittance. It stops below `min_transmittance`, which a caller may set
//! lower than the renderer's threshold to keep hits that become visible when opacities drop.

use std::ops::ControlFlow;

use glam::DVec3;
use rayon::prelude::*;

use crate::error::Result;
use crate::kbuffer::{self, Accum, KBuffer};
use crate::mesh_tracer::{with_thread_buffer, Instances, MeshHit, MeshTracer, TrianglePayload};
use crate::render::camera_ray;
use splatbridge_scene::Camera;

/// One composited crossing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecordedHit {
    /// Mesh index in the scene (`TriScene::meshes`).
    pub mesh: u32,
    /// Triangle index in that mesh.
    pub tri: u32,
    pub bary: [f32; 3],
    /// World ray parameter.
    pub t: f32,
    /// What the hit's material and texture multiply its interpolated vertex α by (the base
    /// colour's α times the texture's at the hit), for consumers that change vertex α.
    pub alpha_factor: f32,
}

/// Every pixel's hits, row-major: pixel `p`'s hits are `hits[offsets[p]..offsets[p + 1]]`;
/// each hit a [`RecordedHit`], or what [`MeshTracer::record_hits_map`] made of it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HitLists<H = RecordedHit> {
    pub width: u32,
    pub height: u32,
    pub offsets: Vec<u64>,
    pub hits: Vec<H>,
}

/// Record hit `h` of mesh `mesh` (shaded with [`KBuffer::record_alpha`]) where it shades to
/// α > 0, and composite its α into `acc`:
/// true once the transmittance is below `min_transmittance`, where recording stops (the rule
/// of both recorders, per ray and through the tiles).
#[inline]
pub(crate) fn record(
    h: &MeshHit,
    mesh: usize,
    acc: &mut Accum,
    out: &mut Vec<RecordedHit>,
    min_transmittance: f32,
) -> bool {
    let a = h.payload.rgba.w;
    if !(a > 0.0) {
        return false;
    }
    out.push(RecordedHit {
        mesh: mesh as u32,
        tri: h.payload.tri,
        bary: h.payload.bary,
        t: h.t,
        alpha_factor: h.payload.rgba.x,
    });
    acc.add(glam::Vec3::ZERO, a, h.t);
    acc.tr < min_transmittance
}

impl<H> HitLists<H> {
    pub fn pixel(&self, p: usize) -> &[H] {
        &self.hits[self.offsets[p] as usize..self.offsets[p + 1] as usize]
    }

    /// The same lists with each hit as `f` makes it (in parallel, in order).
    pub fn map<T: Send, F: Fn(&H) -> T + Sync>(self, f: F) -> HitLists<T>
    where
        H: Sync,
    {
        HitLists {
            width: self.width,
            height: self.height,
            hits: self.hits.par_iter().map(&f).collect(),
            offsets: self.offsets,
        }
    }
}

impl MeshTracer {
    /// Append the hits of one world ray (`d` unit length) in compositing order to `out`,
    /// stopping once the transmittance falls below `min_transmittance`.
    pub fn ordered_hits(
        &self,
        insts: &Instances,
        o: DVec3,
        d: DVec3,
        min_transmittance: f32,
        buf: &mut KBuffer<TrianglePayload>,
        out: &mut Vec<RecordedHit>,
    ) {
        let mut acc = Accum::default();
        buf.shade_on_insert = true;
        buf.record_alpha = true;
        // The transmittance reached, for the buffer's stop (`KBuffer::stop`): the same rule as
        // below, so nothing beyond the stopping hit is collected.
        let tr = std::cell::Cell::new(acc.tr);
        kbuffer::walk(
            buf,
            |after, buf| {
                buf.stop = Some((tr.get(), min_transmittance));
                self.collect(insts, o, d, 0.0, f32::INFINITY, after, buf)
            },
            |h| {
                let mesh = insts[h.instance as usize].mesh;
                let stop = record(h, mesh, &mut acc, out, min_transmittance);
                tr.set(acc.tr);
                if stop {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            },
        );
        buf.shade_on_insert = false;
        buf.record_alpha = false;
        buf.stop = None;
    }

    /// The hit lists of every pixel of `cam` at time `time` (rays through pixel centres, as
    /// [`MeshTracer::render`] shoots them): through the screen tiles where
    /// [`MeshTracer::tiles_pay`] (one pass a ray, the same hits), otherwise with a k-buffer
    /// of `k`.
    pub fn record_hits(
        &self,
        cam: &Camera,
        time: f64,
        k: usize,
        min_transmittance: f32,
    ) -> Result<HitLists> {
        self.record_hits_map(cam, time, k, min_transmittance, |h| *h)
    }

    /// [`MeshTracer::record_hits`] with each hit stored as `map` makes it (a consumer's own
    /// record of a hit, made as the lists are assembled instead of in a pass over them).
    pub fn record_hits_map<T, F>(
        &self,
        cam: &Camera,
        time: f64,
        k: usize,
        min_transmittance: f32,
        map: F,
    ) -> Result<HitLists<T>>
    where
        T: Copy + Send + Sync,
        F: Fn(&RecordedHit) -> T + Sync,
    {
        if self.tiles_pay(time, cam.width as u64 * cam.height as u64) {
            return self.record_hits_tiles_map(cam, time, min_transmittance, map);
        }
        Ok(self
            .record_hits_per_ray(cam, time, k, min_transmittance)?
            .map(map))
    }

    /// [`MeshTracer::record_hits`] ray by ray through the BVHs and k-buffer rounds.
    pub fn record_hits_per_ray(
        &self,
        cam: &Camera,
        time: f64,
        k: usize,
        min_transmittance: f32,
    ) -> Result<HitLists> {
        cam.validate()?;
        let insts = self.prepare(time);
        let (w, h) = (cam.width as usize, cam.height as usize);
        let rows: Vec<(Vec<u32>, Vec<RecordedHit>)> = (0..h)
            .into_par_iter()
            .map(|j| {
                let mut counts = Vec::with_capacity(w);
                let mut hits = Vec::new();
                for i in 0..w {
                    let (o, d) = camera_ray(cam, i as f64 + 0.5, j as f64 + 0.5);
                    let before = hits.len();
                    with_thread_buffer(k.max(1), |b| {
                        self.ordered_hits(&insts, o, d, min_transmittance, b, &mut hits)
                    });
                    counts.push((hits.len() - before) as u32);
                }
                (counts, hits)
            })
            .collect();
        let total: usize = rows.iter().map(|r| r.1.len()).sum();
        let mut out = HitLists {
            width: cam.width,
            height: cam.height,
            offsets: Vec::with_capacity(w * h + 1),
            hits: Vec::with_capacity(total),
        };
        out.offsets.push(0);
        for (counts, hits) in rows {
            for c in counts {
                let last = *out.offsets.last().unwrap_or(&0);
                out.offsets.push(last + c as u64);
            }
            out.hits.extend_from_slice(&hits);
        }
        Ok(out)
    }
}
