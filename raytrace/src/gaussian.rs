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
//!
//! Dynamic scenes are instanced, not rebuilt: the static Gaussians, each object (in its own
//! frame, under its SE(3) track) and a frame's weather particles are separate parts with their
//! own BVH. [`GaussianTracer::set_time`] only re-poses the objects; a ray is carried into each
//! part's frame in f64 (a rigid motion keeps the ray parameter), and an object's SH is evaluated
//! in the local ray direction, which equals evaluating the rotated SH in the world direction.
//! Hits keep the global index the Gaussian has in [`DynamicScene::composite`], so ties order as
//! in the composite. A part fixed in the world takes the exact path of a plain cloud
//! (`o − anchor`, `d`): a static scene renders bit-identically either way.

use std::ops::ControlFlow;
use std::sync::OnceLock;
use std::time::Instant;

use glam::{DAffine3, DVec3, Mat3, Vec3};
use splatbridge_scene::dynamic::{DynamicScene, Track};
use splatbridge_scene::{sh, Camera, Frame, GaussianCloud};

use crate::backend::{build_boxes, fits_bvh, Accel, BackendKind, BuildPreset};
use crate::error::Result;
use crate::footprint::{Footprint, HitOrder, RayFootprint, ShDirection};
use crate::geom::{ray_box, transformed_box};
use crate::kbuffer::{self, Accum, Hit, KBuffer, Key, Payload};
use crate::render::{render_frame_spp, PixelOut, RenderOptions, Stats};

mod camera;
mod exp_lanes;
mod lanes;
mod part;
mod proxy_order;
mod tiles;
use camera::LocalFootprint;
pub use camera::Padded;
use proxy_order::spatial_order;

/// The rasterizer's near cull (default of `RenderOptions::near`): view-space depth of the
/// mean must exceed this.
pub const NEAR_CULL: f32 = 0.2;

/// What a mode-gaussian hit carries: the Gaussian's index in its part's cloud and its α along
/// the ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GaussianPayload {
    pub index: u32,
    pub alpha: f32,
}

impl Payload for GaussianPayload {
    /// One Gaussian gives one hit per ray; the index only makes the choice total.
    #[inline]
    fn rank(&self) -> u32 {
        self.index
    }

    #[inline]
    fn opacity(&self) -> f32 {
        self.alpha
    }
}

/// A mode-gaussian hit.
pub type GaussianHit = Hit<GaussianPayload>;

kbuffer::thread_buffer!(pub(crate) fn with_thread_buffer, GaussianPayload);

/// One proxy's data for the hit test (anchor-relative, in its part's frame).
#[derive(Clone, Copy, Debug)]
struct Proxy {
    mean: Vec3,
    /// Squared extent in standard deviations, `2·ln(255·o)`.
    r2: f32,
    opacity: f32,
    /// `S⁻¹Rᵀ`.
    inv: Mat3,
    /// `R·S` (`Σ = M·Mᵀ`), for the footprint-widened response.
    m: Mat3,
}

/// Proxies and BVH of one cloud in its own frame: the static Gaussians, one object, or a
/// frame's particles.
struct Part {
    cloud: GaussianCloud,
    /// Global index of the part's first Gaussian (its place in the composite).
    id_offset: u32,
    /// The object's track; None for a part fixed in the world.
    track: Option<Track>,
    anchor: DVec3,
    /// Index into `cloud` of each proxy.
    index: Vec<u32>,
    /// What the hit test reads of each proxy, in one record: a candidate costs one or two
    /// cache lines instead of one per array (at 10 M Gaussians every candidate was a miss in
    /// each of five arrays, and the test's loads dominated the trace).
    proxy: Vec<Proxy>,
    /// Each proxy's box (anchor-relative), to pad per camera when the footprint is on.
    boxes: Vec<(Vec3, Vec3)>,
    /// The BVH over `boxes`, built on first use with obvhs: the tile path of primary rays
    /// never traverses it, and at 10 M Gaussians it was most of the tracer's set-up. Built at
    /// once with Embree, so that a backend that cannot build fails when the tracer is made.
    accel: OnceLock<Box<dyn Accel>>,
    backend: BackendKind,
    preset: BuildPreset,
    /// Bounds of the proxy boxes in the part's frame (absolute, not anchor-relative).
    lo: DVec3,
    hi: DVec3,
}

/// Where a moving part is at the current time.
#[derive(Clone, Copy, Debug)]
struct Placed {
    /// World point → anchor-relative local point.
    to_local: DAffine3,
    /// Local (absolute, not anchor-relative) → world.
    to_world: DAffine3,
    /// World bounds of the part's proxies, padded.
    lo: DVec3,
    hi: DVec3,
}

/// Gaussians prepared for ray tracing.
pub struct GaussianTracer {
    parts: Vec<Part>,
    /// Per part: its placement at the current time (None: fixed in the world).
    placed: Vec<Option<Placed>>,
    /// Gaussians of the scene proper (the particles' ids start here).
    scene_len: u32,
    /// Whether the last part is a frame's particles.
    has_particles: bool,
    preset: BuildPreset,
    pub backend: BackendKind,
    /// Seconds spent building every part's BVH so far.
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
        let start = Instant::now();
        let n = cloud.len() as u32;
        let part = Part::build(cloud, 0, None, backend, preset)?;
        Ok(GaussianTracer {
            parts: vec![part],
            placed: vec![None],
            scene_len: n,
            has_particles: false,
            preset,
            backend,
            build_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// Build one BVH for the static Gaussians and one per object (in the object's frame), and
    /// pose the objects at time `t`. Later times need only [`GaussianTracer::set_time`].
    pub fn for_scene(
        scene: &DynamicScene,
        t: f64,
        backend: BackendKind,
        preset: BuildPreset,
    ) -> Result<Self> {
        let clouds = std::iter::once(scene.static_gaussians.clone())
            .chain(scene.objects.iter().map(|o| o.gaussians.clone()))
            .collect();
        Self::from_parts(scene, clouds, t, backend, preset)
    }

    /// As [`GaussianTracer::for_scene`], moving the scene's Gaussians into the tracer instead
    /// of copying them: `scene` keeps its objects' tracks, cameras, time range and effects, but
    /// its clouds are left empty. A command that traces one scene holds its Gaussians once
    /// (2.5 GB of SH-3 Gaussians at 10 M).
    pub fn for_scene_taking(
        scene: &mut DynamicScene,
        t: f64,
        backend: BackendKind,
        preset: BuildPreset,
    ) -> Result<Self> {
        let mut clouds = vec![std::mem::take(&mut scene.static_gaussians)];
        clouds.extend(
            scene
                .objects
                .iter_mut()
                .map(|o| std::mem::take(&mut o.gaussians)),
        );
        Self::from_parts(scene, clouds, t, backend, preset)
    }

    /// The tracer over `clouds`: the static Gaussians, then each object's, posed by `scene`'s
    /// tracks.
    fn from_parts(
        scene: &DynamicScene,
        clouds: Vec<GaussianCloud>,
        t: f64,
        backend: BackendKind,
        preset: BuildPreset,
    ) -> Result<Self> {
        let start = Instant::now();
        let mut parts = Vec::with_capacity(clouds.len());
        let mut offset = 0u32;
        for (i, cloud) in clouds.into_iter().enumerate() {
            let n = cloud.len() as u32;
            let track = match i {
                0 => None,
                _ => Some(scene.objects[i - 1].track.clone()),
            };
            parts.push(Part::build(cloud, offset, track, backend, preset)?);
            offset += n;
        }
        let mut tracer = GaussianTracer {
            placed: vec![None; parts.len()],
            parts,
            scene_len: offset,
            has_particles: false,
            preset,
            backend,
            build_seconds: start.elapsed().as_secs_f64(),
        };
        tracer.set_time(t);
        Ok(tracer)
    }

    /// Pose every object at time `t` (no BVH is rebuilt).
    pub fn set_time(&mut self, t: f64) {
        for (slot, part) in self.placed.iter_mut().zip(&self.parts) {
            *slot = part.place(t);
        }
    }

    /// Give the Gaussians of a tracer built by [`GaussianTracer::for_scene_taking`] back to
    /// `scene` (the static cloud, then each object's, as taken), unchanged: a caller that needs
    /// the scene again after tracing lends its clouds instead of copying them.
    pub fn give_back(mut self, scene: &mut DynamicScene) {
        if self.has_particles {
            self.parts.pop();
        }
        let mut clouds = self.parts.into_iter().map(|p| p.cloud);
        if let Some(c) = clouds.next() {
            scene.static_gaussians = c;
        }
        for (o, c) in scene.objects.iter_mut().zip(clouds) {
            o.gaussians = c;
        }
    }

    /// Replace the frame's particles (world-space Gaussians after the scene's, e.g. weather):
    /// only their own small BVH is built.
    pub fn set_particles(&mut self, particles: Option<GaussianCloud>) -> Result<()> {
        if self.has_particles {
            self.parts.pop();
            self.placed.pop();
            self.has_particles = false;
        }
        if let Some(p) = particles.filter(|p| !p.is_empty()) {
            let start = Instant::now();
            let part = Part::build(p, self.scene_len, None, self.backend, self.preset)?;
            self.parts.push(part);
            self.placed.push(None);
            self.has_particles = true;
            self.build_seconds += start.elapsed().as_secs_f64();
        }
        Ok(())
    }

    /// Number of Gaussians (scene and particles).
    pub fn len(&self) -> usize {
        self.parts.iter().map(|p| p.cloud.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// World bounds of the Gaussians' means at the current time.
    pub fn bounds(&self) -> Option<(DVec3, DVec3)> {
        let mut out: Option<(DVec3, DVec3)> = None;
        for (part, placed) in self.parts.iter().zip(&self.placed) {
            for m in &part.cloud.means {
                let w = match placed {
                    Some(p) => p.to_world.transform_point3(m.as_dvec3()),
                    None => m.as_dvec3(),
                };
                if !w.is_finite() {
                    continue;
                }
                out = Some(match out {
                    Some((lo, hi)) => (lo.min(w), hi.max(w)),
                    None => (w, w),
                });
            }
        }
        out
    }

    /// A world point in part `i`'s anchor-relative frame (f32).
    #[inline]
    fn local_point(&self, i: usize, o: DVec3) -> Vec3 {
        match &self.placed[i] {
            None => (o - self.parts[i].anchor).as_vec3(),
            Some(p) => p.to_local.transform_point3(o).as_vec3(),
        }
    }

    /// A world direction in part `i`'s frame (f32); unchanged for a part fixed in the world.
    #[inline]
    fn local_dir(&self, i: usize, d: DVec3) -> Vec3 {
        match &self.placed[i] {
            None => d.as_vec3(),
            Some(p) => p.to_local.transform_vector3(d).as_vec3(),
        }
    }

    /// Fill `buf` with the k smallest-key hits with key > `after` and `t ≤ tmax` along the
    /// world ray `o + t·d` (`d` unit length). `near`: the camera's forward axis and near
    /// distance (primary rays).
    pub(crate) fn collect(
        &self,
        o: DVec3,
        d: DVec3,
        near: Option<(DVec3, f32)>,
        tmax: f32,
        after: Option<Key>,
        buf: &mut KBuffer<GaussianPayload>,
    ) {
        self.collect_fp(o, d, near, None, HitOrder::Hit, tmax, after, buf)
    }

    /// As [`GaussianTracer::collect`]; `fp`: the ray's footprint and the grown BVHs of the
    /// camera it belongs to (primary rays with the footprint on); `order`: the hit order of a
    /// primary ray.
    #[allow(clippy::too_many_arguments)]
    fn collect_fp(
        &self,
        o: DVec3,
        d: DVec3,
        near: Option<(DVec3, f32)>,
        fp: Option<(&RayFootprint, &Padded)>,
        order: HitOrder,
        tmax: f32,
        after: Option<Key>,
        buf: &mut KBuffer<GaussianPayload>,
    ) {
        buf.clear();
        for (pi, part) in self.parts.iter().enumerate() {
            if part.index.is_empty() {
                continue;
            }
            if let Some(pl) = &self.placed[pi] {
                let (lo, hi) = match fp.and_then(|(_, pad)| pad.bounds[pi]) {
                    Some(b) => b,
                    None => (pl.lo, pl.hi),
                };
                // Hits re-keyed by mean depth may come before the part's box entry (below).
                let rekeyed = near.is_some()
                    && order == HitOrder::MeanDepth
                    && fp.is_none_or(|(_, pad)| pad.mode != Footprint::Projected);
                let cull = if rekeyed { tmax } else { buf.cull(tmax) };
                match ray_box(o, d, lo, hi) {
                    Some((b0, b1)) if b1 >= 0.0 && b0 <= cull as f64 => {}
                    _ => continue,
                }
            }
            let (ro, rd) = (self.local_point(pi, o), self.local_dir(pi, d));
            let near = near.map(|(f, near)| Near {
                origin: ro,
                forward: self.local_dir(pi, f),
                near,
            });
            let local = fp.map(|(f, pad)| LocalFootprint::new(self, pi, f, pad));
            let (buckets, pboxes, splats, pixels, mode) = match fp {
                Some((_, pad)) => (
                    pad.accels[pi].as_slice(),
                    pad.boxes[pi].as_slice(),
                    pad.splats[pi].as_slice(),
                    pad.pixels[pi].as_slice(),
                    pad.mode,
                ),
                None => (&[][..], &[][..], &[][..], &[][..], Footprint::Off),
            };
            // Projected hits are keyed at the mean's depth already, and their flat proxy is
            // entered there.
            let order = match (near, mode) {
                (None, _) | (_, Footprint::Projected) => HitOrder::Hit,
                _ => order,
            };
            // Re-keyed hits (mean depth) may sit before their proxy's entry, so the traversal
            // may not stop at the k-th key itself: a hit keyed below K lies in a box the ray
            // enters before K + reach / (d·f) (`camera::Bucket`), and that is where it stops.
            let forward_cos = near.map_or(0.0, |n| rd.dot(n.forward));
            // Hits re-keyed at their mean's depth below need no `t*`.
            let keyed = near.is_some() && order == HitOrder::MeanDepth;
            let mut run = |accel: &dyn Accel, ids: Option<&[u32]>, reach: f32| {
                let widen = |c: f32| match order {
                    HitOrder::Hit => c,
                    HitOrder::MeanDepth => camera::rekeyed_cull(c, reach, forward_cos),
                };
                let cull0 = widen(buf.cull(tmax));
                accel.traverse(ro, rd, cull0, &mut |p, _, cull| {
                    buf.candidates = buf.candidates.wrapping_add(1);
                    let p = match ids {
                        Some(ids) => ids[p as usize] as usize,
                        None => p as usize,
                    };
                    if let Some(n) = near {
                        if (part.proxy[p].mean - n.origin).dot(n.forward) <= n.near {
                            return;
                        }
                    }
                    let r = match (&local, mode) {
                        (Some(f), Footprint::Projected) => {
                            part.response_projected(p, ro, rd, f, &splats[p])
                        }
                        (Some(f), _) => {
                            part.response_fp(p, ro, rd, f, pboxes[p], &pixels[p], keyed)
                        }
                        (None, _) => part.response(p, ro, rd),
                    };
                    let Some((mut t, alpha)) = r else {
                        return;
                    };
                    if let Some(n) = near {
                        if let Some(k) = camera::mean_depth_key(
                            order,
                            part.proxy[p].mean,
                            ro,
                            n.forward,
                            forward_cos,
                        ) {
                            t = k;
                        }
                    }
                    if t > tmax {
                        return;
                    }
                    let h = Hit {
                        t,
                        gaussian: part.id_offset + part.index[p],
                        instance: pi as u32,
                        group: 0,
                        payload: GaussianPayload {
                            index: part.index[p],
                            alpha,
                        },
                    };
                    if after.is_some_and(|a| h.key() <= a) {
                        return;
                    }
                    *cull = widen(buf.insert(h, tmax));
                });
            };
            if fp.is_some() {
                for b in buckets {
                    run(b.accel.as_ref(), b.ids.as_deref(), b.reach);
                }
            } else {
                run(part.accel(), None, f32::INFINITY);
            }
        }
    }

    /// Colour of a hit seen along world direction `d`: the Gaussian's full SH in that
    /// direction (an object's SH in the local direction).
    pub fn hit_color(&self, h: &GaussianHit, d: DVec3) -> Vec3 {
        let i = h.instance as usize;
        let part = &self.parts[i];
        sh::eval_color(
            part.cloud.sh_degree,
            part.cloud.sh_of(h.payload.index as usize),
            self.local_dir(i, d),
        )
    }

    /// Colour of a hit seen from world point `o` toward the Gaussian's mean (native's SH
    /// direction; an object's SH in its local frame).
    pub fn hit_color_toward_mean(&self, h: &GaussianHit, o: DVec3) -> Vec3 {
        self.color_toward_mean(h.instance as usize, h.payload.index as usize, o)
    }

    /// Colour of Gaussian `g` of part `i` seen from world point `o` toward its mean.
    fn color_toward_mean(&self, i: usize, g: usize, o: DVec3) -> Vec3 {
        let part = &self.parts[i];
        let from = match &self.placed[i] {
            None => o,
            Some(p) => p.to_local.transform_point3(o) + part.anchor,
        };
        let dir = (part.cloud.means[g].as_dvec3() - from).normalize_or_zero();
        sh::eval_color(part.cloud.sh_degree, part.cloud.sh_of(g), dir.as_vec3())
    }

    /// Every Gaussian's colour of part 0 seen from `o` toward its mean, for a frame whose
    /// rays all start at `o`: with native's SH direction a Gaussian has one colour per
    /// camera, as native evaluates it once per splat, so the tile path looks it up instead of
    /// evaluating it per hit. Each entry is [`GaussianTracer::hit_color_toward_mean`]'s value.
    fn colors_toward_mean(&self, o: DVec3) -> Vec<Vec3> {
        use rayon::prelude::*;
        (0..self.parts[0].cloud.len())
            .into_par_iter()
            .map(|g| self.color_toward_mean(0, g, o))
            .collect()
    }

    /// World normal of a hit Gaussian: its shortest axis.
    pub fn hit_normal(&self, h: &GaussianHit) -> DVec3 {
        let i = h.instance as usize;
        let part = &self.parts[i];
        let g = h.payload.index as usize;
        let s = part.cloud.scale(g);
        let axis = if s.x <= s.y && s.x <= s.z {
            0
        } else if s.y <= s.z {
            1
        } else {
            2
        };
        let n = Mat3::from_quat(part.cloud.unit_rotation(g))
            .col(axis)
            .as_dvec3();
        let n = match &self.placed[i] {
            None => n,
            Some(p) => p.to_world.matrix3 * n,
        };
        n.try_normalize().unwrap_or(DVec3::ZERO)
    }

    /// Every Gaussian the ray reaches with α ≥ 1/255 in (t*, index) order.
    pub fn all_hits(&self, o: DVec3, d: DVec3, k: usize) -> Vec<GaussianHit> {
        self.hits_until(o, d, k, f32::INFINITY)
    }

    /// As [`GaussianTracer::all_hits`], but only hits with `t ≤ tmax`: the traversal itself
    /// stops there (segment and shadow queries need nothing beyond their end).
    pub fn hits_until(&self, o: DVec3, d: DVec3, k: usize, tmax: f32) -> Vec<GaussianHit> {
        kbuffer::all_hits(k, |after, buf| self.collect(o, d, None, tmax, after, buf))
    }

    /// Composite one ray. `forward` enables the near cull (primary rays).
    pub fn trace(
        &self,
        o: DVec3,
        d: DVec3,
        forward: Option<DVec3>,
        opts: &RenderOptions,
        buf: &mut KBuffer<GaussianPayload>,
    ) -> PixelOut {
        self.trace_fp(o, d, forward, None, opts, buf)
    }

    /// As [`GaussianTracer::trace`] for a primary ray carrying its footprint `fp` (with the
    /// camera's padded BVHs from [`GaussianTracer::padded`]).
    pub fn trace_fp(
        &self,
        o: DVec3,
        d: DVec3,
        forward: Option<DVec3>,
        fp: Option<(&RayFootprint, &Padded)>,
        opts: &RenderOptions,
        buf: &mut KBuffer<GaussianPayload>,
    ) -> PixelOut {
        let near = forward.map(|f| (f, opts.near));
        let mut out = PixelOut::default();
        let mut acc = Accum::default();
        let mut hits = 0u32;
        buf.candidates = 0;
        // The transmittance compositing has reached, for the buffer's stop (`KBuffer::stop`).
        let tr = std::cell::Cell::new(acc.tr);
        let (rounds, _) = kbuffer::walk(
            buf,
            |after, buf| {
                buf.stop = Some((tr.get(), opts.min_transmittance));
                self.collect_fp(o, d, near, fp, opts.order, f32::INFINITY, after, buf)
            },
            |h| {
                let a = h.payload.alpha;
                // Native splatting's rule: a Gaussian that would take T below the threshold
                // stops the ray without being added.
                if acc.after(a) < opts.min_transmittance {
                    return ControlFlow::Break(());
                }
                hits += 1;
                let color = match (opts.sh_direction, forward) {
                    (ShDirection::Mean, Some(_)) => self.hit_color_toward_mean(h, o),
                    _ => self.hit_color(h, d),
                };
                acc.add(color, a, h.t);
                tr.set(acc.tr);
                ControlFlow::Continue(())
            },
        );
        buf.stop = None;
        out.hits = hits;
        out.traversals = rounds;
        out.rgb = acc.rgb + opts.background * acc.tr;
        out.alpha = 1.0 - acc.tr;
        out.depth = acc.depth();
        out.candidates = buf.candidates;
        out
    }

    /// Render `cam` at the current time, with `opts.spp` samples per pixel and, when
    /// `opts.footprint` is on, each primary ray's footprint (the per-camera padded BVHs are
    /// built first and their build time is counted in the render's seconds).
    pub fn render(&self, cam: &Camera, opts: &RenderOptions) -> Result<(Frame, Stats)> {
        opts.validate()?;
        let variance = opts.sample_footprint.variance_px2(opts.spp);
        if self.tiles_apply(opts) {
            return self.render_tiles(cam, opts);
        }
        let padded = self.for_camera(cam, opts.footprint, variance)?;
        let (frame, mut stats) = self.render_padded(cam, opts, padded.as_ref())?;
        stats.seconds += padded.map_or(0.0, |p| p.build_seconds);
        Ok((frame, stats))
    }

    /// [`GaussianTracer::render`] through per-camera footprint BVHs already built (`None`
    /// without a footprint); the cull tests render the same frame with their cull disabled.
    pub(crate) fn render_padded(
        &self,
        cam: &Camera,
        opts: &RenderOptions,
        padded: Option<&Padded>,
    ) -> Result<(Frame, Stats)> {
        let forward = cam.world_to_cam.row(2);
        let variance = opts.sample_footprint.variance_px2(opts.spp);
        render_frame_spp(cam, opts.spp, |o, d| {
            let fp = padded.and_then(|p| RayFootprint::pinhole(cam, d, variance).map(|f| (f, p)));
            with_thread_buffer(opts.k, |b| {
                self.trace_fp(
                    o,
                    d,
                    Some(forward),
                    fp.as_ref().map(|(f, p)| (f, *p)),
                    opts,
                    b,
                )
            })
        })
    }

    /// [`GaussianTracer::render`] tile by tile ([`tiles`]): the camera's grown boxes (no
    /// BVH) and tile lists are built first and counted in the render's seconds.
    fn render_tiles(&self, cam: &Camera, opts: &RenderOptions) -> Result<(Frame, Stats)> {
        let start = Instant::now();
        let forward = cam.world_to_cam.row(2);
        let variance = opts.sample_footprint.variance_px2(opts.spp);
        let padded = self.grown_boxes(cam, opts.footprint, variance)?;
        let boxes = match &padded {
            Some(p) => p.boxes[0].as_slice(),
            None => self.parts[0].boxes.as_slice(),
        };
        let lists = tiles::TileLists::build(self, cam, boxes, padded.as_ref(), opts.near);
        // Every primary ray starts at the camera's centre (`render::camera_ray`).
        let mean_colors = (opts.sh_direction == ShDirection::Mean)
            .then(|| (cam.centre, self.colors_toward_mean(cam.centre)));
        let mean_colors = mean_colors.as_ref().map(|(o, c)| (*o, c.as_slice()));
        // Mode `on` reads the whole footprint only for the odd lane without a usable pixel
        // record; where the frame guarantees every ray one, a ray starts with its pixel alone.
        let pixel_only = padded.as_ref().is_some_and(|p| p.mode == Footprint::On)
            && crate::footprint::covers_frame(cam, variance);
        let prepare = start.elapsed().as_secs_f64();
        let (frame, mut stats) = crate::render::render_frame_tiles(
            cam,
            opts.spp,
            tiles::TILE,
            || (tiles::Cells::default(), tiles::Scratch::default()),
            |(cells, _), tx, ty| *cells = lists.cells(tx, ty, padded.as_ref()),
            |(cells, scratch), o, d, uv| {
                // The sample's pixel (a sample of pixel i lies in [i, i + 1)).
                let ray = tiles::TileRay {
                    list: cells.of(uv.0 as u32, uv.1 as u32),
                    o,
                    d,
                    uv,
                    forward,
                    fp: None,
                    mean_colors,
                };
                let fp = padded.as_ref().map(|p| {
                    let f = if pixel_only {
                        crate::footprint::pinhole_pixel(cam, d).map(|pixel| tiles::RayFp::Pixel {
                            cam,
                            d,
                            variance,
                            pixel,
                        })
                    } else {
                        RayFootprint::pinhole(cam, d, variance).map(tiles::RayFp::Whole)
                    };
                    (f, p)
                });
                match fp {
                    // A footprint the camera cannot give this ray: the per-ray path's fallback.
                    Some((None, _)) => with_thread_buffer(opts.k, |b| {
                        self.trace_fp(o, d, Some(forward), None, opts, b)
                    }),
                    Some((Some(f), p)) => {
                        let ray = tiles::TileRay {
                            fp: Some((f, p)),
                            ..ray
                        };
                        self.trace_tile(ray, opts, scratch)
                    }
                    None => self.trace_tile(ray, opts, scratch),
                }
            },
        )?;
        stats.seconds += prepare;
        Ok((frame, stats))
    }
}

#[cfg(test)]
mod brute_tests;
#[cfg(test)]
mod cull_tests;
#[cfg(test)]
mod pixel_tests;
#[cfg(test)]
mod tile_tests;
