//! Camera rays, the per-pixel loop (parallel over rows with rayon, deterministic: each pixel
//! depends only on its own ray) and the statistics every render reports.
//!
//! Pixel (i, j) is sampled through continuous image coordinate (i + 0.5, j + 0.5), which is the
//! integer-pixel sample of the reference rasterizer (see `splatbridge_scene::camera`). Rays are
//! formed in f64 from the camera centre; tracers subtract their own anchor before f32, so
//! scenes far from the origin keep their precision.

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use splatbridge_scene::{Camera, Frame};

use crate::error::{Result, TraceError};
use crate::footprint::{sample_offsets, Footprint, HitOrder, SampleFootprint, ShDirection};
pub use crate::geom::{ray_box, transformed_box};

/// How mode `mesh` turns vertex colours into the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Compositing {
    /// Blend display values, as native splatting does: linear file colours (glTF) are
    /// sRGB-encoded per hit before blending. The image compares directly with native renders.
    #[default]
    Display,
    /// Blend in linear light and encode the result to sRGB, as a viewer (Blender, three.js)
    /// shows the file.
    Viewer,
}

/// Options shared by the modes.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// k-buffer size: hits collected per traversal before compositing and resuming.
    pub k: usize,
    /// Colour behind everything (`C + T·background`).
    pub background: Vec3,
    /// Compositing stops once transmittance falls below this (native splatting's 1e-4).
    pub min_transmittance: f32,
    /// Mode `gaussian`: Gaussians whose mean is at view depth ≤ `near` are culled, as the
    /// rasterizer does (reference 0.2).
    pub near: f32,
    /// Mode `mesh`: colour handling (see [`Compositing`]).
    pub compositing: Compositing,
    /// Mode `gaussian`: whether primary rays carry their pixel footprint (native's low-pass;
    /// see [`crate::footprint`]). Off by default here, the exact 3DGRT response; the `trace`
    /// command turns it on for mode gaussian.
    pub footprint: Footprint,
    /// Samples per pixel (both modes), on the fixed stratified pattern of
    /// [`crate::footprint::sample_offsets`], box-filtered. 1 is the pixel centre.
    pub spp: u32,
    /// With `spp > 1` and the footprint on: the sub-pixel's footprint or the whole pixel's.
    pub sample_footprint: SampleFootprint,
    /// Mode `gaussian`, primary rays: hit order (3DGRT's `t*`, or native's mean depth).
    pub order: HitOrder,
    /// Mode `gaussian`, primary rays: SH direction (the ray, or toward the mean as native).
    pub sh_direction: ShDirection,
}

/// Largest `spp` accepted (a 32×32 grid).
pub const MAX_SPP: u32 = 1024;

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            k: 16,
            background: Vec3::ZERO,
            min_transmittance: 1e-4,
            near: crate::gaussian::NEAR_CULL,
            compositing: Compositing::Display,
            footprint: Footprint::Off,
            spp: 1,
            sample_footprint: SampleFootprint::Subpixel,
            order: HitOrder::Hit,
            sh_direction: ShDirection::Ray,
        }
    }
}

impl RenderOptions {
    pub fn validate(&self) -> Result<()> {
        if self.k == 0 || self.k > 4096 {
            return Err(TraceError::Invalid(format!(
                "k = {} is outside 1..=4096",
                self.k
            )));
        }
        if self.spp == 0 || self.spp > MAX_SPP {
            return Err(TraceError::Invalid(format!(
                "spp = {} is outside 1..={MAX_SPP}",
                self.spp
            )));
        }
        if !(self.min_transmittance > 0.0 && self.min_transmittance < 1.0)
            || !self.background.is_finite()
            || !self.near.is_finite()
        {
            return Err(TraceError::Invalid(
                "min transmittance must be in (0, 1) and the background finite".into(),
            ));
        }
        Ok(())
    }
}

/// Counters of one render.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    pub rays: u64,
    /// Hits composited (after de-duplication, before early termination cut the rest).
    pub hits: u64,
    /// Traversals (one per k-buffer round per ray).
    pub traversals: u64,
    /// Candidate primitives the BVH handed to the exact test (mode mesh: triangles).
    pub candidates: u64,
    pub seconds: f64,
}

impl Stats {
    pub fn hits_per_ray(&self) -> f64 {
        self.hits as f64 / self.rays.max(1) as f64
    }
    pub fn mrays_per_second(&self) -> f64 {
        self.rays as f64 / self.seconds.max(1e-12) / 1e6
    }
}

/// What a ray returns to the frame.
#[derive(Clone, Copy, Debug, Default)]
pub struct PixelOut {
    pub rgb: Vec3,
    pub alpha: f32,
    pub depth: f32,
    pub hits: u32,
    pub traversals: u32,
    pub candidates: u32,
}

/// World-space ray through continuous pixel coordinate (u, v): origin, unit direction.
pub fn camera_ray(cam: &Camera, u: f64, v: f64) -> (DVec3, DVec3) {
    (cam.centre, cam.ray_dir(u, v))
}

/// Render `cam` by calling `trace(origin, dir)` for every pixel; `trace` returns the pixel
/// with `depth` as the ray parameter–weighted mean, converted here to view-space depth.
pub fn render_frame<F>(cam: &Camera, trace: F) -> Result<(Frame, Stats)>
where
    F: Fn(DVec3, DVec3) -> PixelOut + Sync,
{
    render_frame_spp(cam, 1, trace)
}

/// As [`render_frame`] with `spp` samples per pixel at the fixed offsets of
/// [`sample_offsets`], averaged with a box filter (colour, alpha and depth, in the values the
/// frame holds, as motion-blur samples are averaged). `spp = 1` is exactly [`render_frame`].
/// Each pixel's samples are traced in a fixed order by one task, so the image does not depend
/// on the thread count.
pub fn render_frame_spp<F>(cam: &Camera, spp: u32, trace: F) -> Result<(Frame, Stats)>
where
    F: Fn(DVec3, DVec3) -> PixelOut + Sync,
{
    cam.validate()?;
    if spp == 0 || spp > MAX_SPP {
        return Err(TraceError::Invalid(format!(
            "spp = {spp} is outside 1..={MAX_SPP}"
        )));
    }
    let start = std::time::Instant::now();
    let w = cam.width as usize;
    let offsets = sample_offsets(spp);
    let rows: Vec<Vec<PixelOut>> = (0..cam.height as usize)
        .into_par_iter()
        .map(|j| {
            (0..w)
                .map(|i| pixel(cam, spp, &offsets, i, j, &trace))
                .collect()
        })
        .collect();
    Ok(to_frame(cam, spp, rows.into_iter().flatten(), start))
}

/// As [`render_frame_spp`], parallel over square tiles of `tile` pixels instead of rows:
/// `prepare(ctx, tx, ty)` runs once per tile (column `tx`, row `ty`, row-major tile index
/// `ty·⌈w/tile⌉ + tx`) and the context it filled traces each of the tile's samples. A
/// context comes from `init` once per worker's run of tiles and is filled again for each
/// tile, so its buffers keep their allocations from tile to tile (fresh ones every tile
/// cost page faults: `docs/trace-speed-mesh.md`, "tile contexts kept"). Every pixel's samples
/// are traced exactly as [`render_frame_spp`] traces them, so a tracer whose `trace` gives the
/// same pixel gives the same image, at any thread count.
pub fn render_frame_tiles<C, I, P, F>(
    cam: &Camera,
    spp: u32,
    tile: u32,
    init: I,
    prepare: P,
    trace: F,
) -> Result<(Frame, Stats)>
where
    I: Fn() -> C + Sync + Send,
    P: Fn(&mut C, u32, u32) + Sync,
    F: Fn(&mut C, DVec3, DVec3, (f64, f64)) -> PixelOut + Sync,
{
    cam.validate()?;
    if spp == 0 || spp > MAX_SPP {
        return Err(TraceError::Invalid(format!(
            "spp = {spp} is outside 1..={MAX_SPP}"
        )));
    }
    let start = std::time::Instant::now();
    let (w, h) = (cam.width as usize, cam.height as usize);
    let t = tile.max(1) as usize;
    let (tw, th) = (w.div_ceil(t), h.div_ceil(t));
    let offsets = sample_offsets(spp);
    let tiles: Vec<Vec<PixelOut>> = (0..tw * th)
        .into_par_iter()
        .map_init(&init, |ctx, k| {
            let (tx, ty) = (k % tw, k / tw);
            prepare(ctx, tx as u32, ty as u32);
            let mut out = Vec::with_capacity(t * t);
            for j in ty * t..((ty + 1) * t).min(h) {
                for i in tx * t..((tx + 1) * t).min(w) {
                    let f = |o: DVec3, d: DVec3, uv: (f64, f64)| trace(ctx, o, d, uv);
                    out.push(pixel_at(cam, spp, &offsets, i, j, f));
                }
            }
            out
        })
        .collect();
    // Row-major pixels from the tiles' row-major pixels.
    let mut pixels = vec![PixelOut::default(); w * h];
    for (k, px) in tiles.into_iter().enumerate() {
        let (tx, ty) = (k % tw, k / tw);
        let x0 = tx * t;
        let tw_px = (x0 + t).min(w) - x0;
        for (n, p) in px.into_iter().enumerate() {
            let (i, j) = (x0 + n % tw_px, ty * t + n / tw_px);
            pixels[j * w + i] = p;
        }
    }
    Ok(to_frame(cam, spp, pixels.into_iter(), start))
}

/// One pixel of a frame through `trace(origin, direction)` (see [`render_frame_spp`]).
fn pixel<F>(
    cam: &Camera,
    spp: u32,
    offsets: &[(f64, f64)],
    i: usize,
    j: usize,
    trace: &F,
) -> PixelOut
where
    F: Fn(DVec3, DVec3) -> PixelOut,
{
    pixel_at(cam, spp, offsets, i, j, |o, d, _| trace(o, d))
}

/// One pixel through `trace(origin, direction, (u, v))`, `(u, v)` the sample's continuous
/// image coordinate: its `spp` samples traced in a fixed order and box-filtered.
fn pixel_at<F>(
    cam: &Camera,
    spp: u32,
    offsets: &[(f64, f64)],
    i: usize,
    j: usize,
    mut trace: F,
) -> PixelOut
where
    F: FnMut(DVec3, DVec3, (f64, f64)) -> PixelOut,
{
    let forward = cam.world_to_cam.row(2);
    let mut sample = |u: f64, v: f64| {
        let (o, d) = camera_ray(cam, u, v);
        let mut p = trace(o, d, (u, v));
        // Ray parameter t along a unit direction → view-space depth t·(d·forward).
        p.depth *= d.dot(forward) as f32;
        p
    };
    if spp == 1 {
        return sample(i as f64 + 0.5, j as f64 + 0.5);
    }
    let mut acc = PixelOut::default();
    for &(du, dv) in offsets {
        let p = sample(i as f64 + du, j as f64 + dv);
        acc.rgb += p.rgb;
        acc.alpha += p.alpha;
        acc.depth += p.depth;
        acc.hits = acc.hits.saturating_add(p.hits);
        acc.traversals = acc.traversals.saturating_add(p.traversals);
        acc.candidates = acc.candidates.wrapping_add(p.candidates);
    }
    let inv = 1.0 / spp as f32;
    acc.rgb *= inv;
    acc.alpha *= inv;
    acc.depth *= inv;
    acc
}

/// The frame and statistics of a render's pixels, row-major.
fn to_frame(
    cam: &Camera,
    spp: u32,
    pixels: impl Iterator<Item = PixelOut>,
    start: std::time::Instant,
) -> (Frame, Stats) {
    let w = cam.width as usize;
    let h = cam.height as usize;
    let mut frame = Frame::new(cam.width, cam.height);
    let mut stats = Stats::default();
    for (k, p) in pixels.enumerate() {
        frame.rgb[3 * k] = p.rgb.x;
        frame.rgb[3 * k + 1] = p.rgb.y;
        frame.rgb[3 * k + 2] = p.rgb.z;
        frame.alpha[k] = p.alpha;
        frame.depth[k] = p.depth;
        stats.hits += p.hits as u64;
        stats.traversals += p.traversals as u64;
        stats.candidates += p.candidates as u64;
    }
    stats.rays = (w * h) as u64 * spp as u64;
    stats.seconds = start.elapsed().as_secs_f64();
    (frame, stats)
}
