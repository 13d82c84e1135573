//! Sun shadows for the ray tracer (the manifest's `effects.shadows`), in both modes.
//!
//! Choice of shading point: one shadow ray per pixel, from the pixel's surface point, the
//! opacity-weighted mean hit distance the tracer already reports as depth (`o + d·t̄`), cast
//! only when the pixel's accumulated opacity reaches [`SunShadows::min_alpha`] (default ½:
//! something surface-like was hit). For a pixel whose front surface is opaque this is exactly
//! that surface; at silhouettes, where hits at very different depths mix, the point falls
//! between them, which affects only edge pixels. It costs one secondary ray per pixel instead
//! of one per composited hit (~tens per pixel on trained scenes).
//!
//! The shadow ray runs from that point towards the sun (`sun_direction`, normalised) for
//! `reach` = the point's distance to the centre of the scene bounds plus their diagonal (past
//! every Gaussian or triangle), skipping the first `bias` units (10⁻³ of the bounds' diagonal
//! by default) so the surface the point lies on does not shadow itself. Its transmittance
//! comes from [`crate::secondary::SecondaryRays::transmittance`] (semi-transparent geometry
//! lets light through: `T = Π(1 − αᵢ)`), and the surface colour is darkened by
//! `1 − strength·(1 − T)`; the background's share (`T_pixel·background`) is left alone:
//! `rgb' = (rgb − bg·(1 − a))·f + bg·(1 − a)`.
//!
//! With `Compositing::Viewer` (sRGB-encoded output) the factor scales display values, not
//! linear light; with `Compositing::Display` (the default, what native splatting produces) it
//! scales the composited values directly.
//!
//! Moving and inserted objects cast shadows because the tracer is built (gaussian mode) or
//! frozen (mesh mode, [`MeshTracer::at`]) at the frame's time.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use glam::{DVec3, Vec3};
use splatbridge_scene::effects::Shadows;
use splatbridge_scene::{Camera, Frame};

use crate::error::{Result, TraceError};
use crate::footprint::RayFootprint;
use crate::gaussian::GaussianTracer;
use crate::mesh_tracer::MeshTracer;
use crate::render::{render_frame_spp, PixelOut, RenderOptions, Stats};
use crate::secondary::SecondaryRays;

/// The sun and how shadow rays are cast.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunShadows {
    /// Unit direction towards the sun (world).
    pub towards_sun: DVec3,
    /// 0 = no darkening, 1 = black where the sun is fully blocked.
    pub strength: f32,
    /// Distance skipped at the start of a shadow ray (self-shadowing guard), scene units.
    pub bias: f64,
    /// Shadow rays are cast from pixels whose accumulated opacity reaches this.
    pub min_alpha: f32,
    /// Centre and diagonal of the scene bounds (sets each ray's reach).
    pub centre: DVec3,
    pub diagonal: f64,
}

/// What the shadow pass did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShadowStats {
    pub shadow_rays: u64,
    /// Time spent in shadow rays, summed over worker threads.
    pub cpu_seconds: f64,
}

impl SunShadows {
    /// From the declared effect and the scene's bounds (`lo`, `hi`).
    pub fn from_effect(s: &Shadows, lo: DVec3, hi: DVec3) -> Result<Self> {
        let d = Vec3::from(s.sun_direction).as_dvec3();
        let n = d.length();
        if !(n > 0.0 && n.is_finite()) || !(0.0..=1.0).contains(&s.strength) {
            return Err(TraceError::Invalid(
                "shadows: sun_direction must be finite and non-zero, strength in [0, 1]".into(),
            ));
        }
        if !lo.is_finite() || !hi.is_finite() {
            return Err(TraceError::Invalid(
                "shadows: scene bounds are not finite".into(),
            ));
        }
        let diagonal = (hi - lo).length().max(1e-6);
        Ok(SunShadows {
            towards_sun: d / n,
            strength: s.strength,
            bias: 1e-3 * diagonal,
            min_alpha: 0.5,
            centre: 0.5 * (lo + hi),
            diagonal,
        })
    }

    /// The darkening factor at world point `p`, `1 − strength·(1 − T)`.
    pub fn factor<R: SecondaryRays + ?Sized>(&self, rays: &R, p: DVec3) -> f32 {
        let reach = (p - self.centre).length() + self.diagonal;
        let t = rays.transmittance(p, p + self.towards_sun * reach, self.bias);
        1.0 - self.strength * (1.0 - t.clamp(0.0, 1.0))
    }

    /// Apply the shadow to one traced pixel (`px.depth` still the ray parameter, as tracers
    /// return it). Returns whether a shadow ray was cast.
    pub fn shade_pixel<R: SecondaryRays + ?Sized>(
        &self,
        rays: &R,
        o: DVec3,
        d: DVec3,
        background: Vec3,
        px: &mut PixelOut,
    ) -> bool {
        if !(px.alpha >= self.min_alpha) || !(px.depth > 0.0) || !px.depth.is_finite() {
            return false;
        }
        let p = o + d * px.depth as f64;
        let f = self.factor(rays, p);
        let bg = background * (1.0 - px.alpha);
        px.rgb = (px.rgb - bg) * f + bg;
        true
    }
}

/// World bounds of a Gaussian tracer's means at its current time, for
/// [`SunShadows::from_effect`].
pub fn gaussian_bounds(tracer: &GaussianTracer) -> (DVec3, DVec3) {
    tracer.bounds().unwrap_or((DVec3::ZERO, DVec3::ZERO))
}

/// World bounds of a mesh scene's instances at `time`.
pub fn mesh_bounds(tracer: &MeshTracer, time: f64) -> (DVec3, DVec3) {
    let insts = tracer.prepare_list(time);
    if insts.is_empty() {
        return (DVec3::ZERO, DVec3::ZERO);
    }
    insts.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), i| (lo.min(i.lo), hi.max(i.hi)),
    )
}

/// Render `cam` in mode `gaussian` with sun shadows: the same pixels as
/// [`GaussianTracer::render`], then one shadow ray per surface pixel.
pub fn render_gaussian_shadowed(
    tracer: &GaussianTracer,
    cam: &Camera,
    opts: &RenderOptions,
    sun: &SunShadows,
) -> Result<(Frame, Stats, ShadowStats)> {
    opts.validate()?;
    let forward = cam.world_to_cam.row(2);
    let rays = AtomicU64::new(0);
    let nanos = AtomicU64::new(0);
    // Primary rays carry their footprint as in `GaussianTracer::render`; shadow rays none.
    let variance = opts.sample_footprint.variance_px2(opts.spp);
    let padded = tracer.for_camera(cam, opts.footprint, variance)?;
    let (frame, mut stats) = render_frame_spp(cam, opts.spp, |o, d| {
        let fp = padded
            .as_ref()
            .and_then(|p| RayFootprint::pinhole(cam, d, variance).map(|f| (f, p)));
        let mut px = crate::gaussian::with_thread_buffer(opts.k, |b| {
            tracer.trace_fp(
                o,
                d,
                Some(forward),
                fp.as_ref().map(|(f, p)| (f, *p)),
                opts,
                b,
            )
        });
        let start = Instant::now();
        if sun.shade_pixel(tracer, o, d, opts.background, &mut px) {
            rays.fetch_add(1, Ordering::Relaxed);
            nanos.fetch_add(start.elapsed().as_nanos() as u64, Ordering::Relaxed);
        }
        px
    })?;
    stats.seconds += padded.map_or(0.0, |p| p.build_seconds);
    Ok((
        frame,
        stats,
        ShadowStats {
            shadow_rays: rays.into_inner(),
            cpu_seconds: nanos.into_inner() as f64 * 1e-9,
        },
    ))
}

/// Render `cam` at `time` in mode `mesh` with sun shadows: the same pixels as
/// [`MeshTracer::render`], then one shadow ray per surface pixel against the scene at `time`.
pub fn render_mesh_shadowed(
    tracer: &MeshTracer,
    cam: &Camera,
    time: f64,
    opts: &RenderOptions,
    sun: &SunShadows,
) -> Result<(Frame, Stats, ShadowStats)> {
    opts.validate()?;
    let mut frozen = tracer.at(time);
    frozen.k = opts.k;
    let rays = AtomicU64::new(0);
    let nanos = AtomicU64::new(0);
    let (frame, stats) = render_frame_spp(cam, opts.spp, |o, d| {
        let mut px = crate::mesh_tracer::with_thread_buffer(opts.k, |b| {
            tracer.trace(&frozen.insts, o, d, opts, b)
        });
        let start = Instant::now();
        if sun.shade_pixel(&frozen, o, d, opts.background, &mut px) {
            rays.fetch_add(1, Ordering::Relaxed);
            nanos.fetch_add(start.elapsed().as_nanos() as u64, Ordering::Relaxed);
        }
        px
    })?;
    Ok((
        frame,
        stats,
        ShadowStats {
            shadow_rays: rays.into_inner(),
            cpu_seconds: nanos.into_inner() as f64 * 1e-9,
        },
    ))
}
