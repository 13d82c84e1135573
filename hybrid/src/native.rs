//! The native 3DGS renderer: projection → depth sort → tile binning → blending, with the
//! reference settings as defaults and every departure a named knob ([`RenderOptions`]).
//!
//! Output is deterministic: projection is per Gaussian, the depth order is total (ties broken by
//! content, see [`crate::bin`]), and each pixel is blended sequentially by one task, so the
//! image bits do not depend on the thread count or on the order of the input Gaussians.

use std::time::{Duration, Instant};

use rayon::prelude::*;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use crate::bin::{bin_tiles, depth_key, depth_order, Bins};
pub use crate::project::Extent;
use crate::project::{project_one, Culled, Projected, Splat, ViewParams, TILE};
use crate::raster::{rasterize_region, BlendParams};

/// The reference's α clamp.
pub const ALPHA_CLAMP_REFERENCE: f32 = 0.99;
/// gsplat's α clamp.
pub const ALPHA_CLAMP_GSPLAT: f32 = 0.999;
/// The reference's near plane (view-space z).
pub const NEAR_REFERENCE: f32 = 0.2;
/// Tile–Gaussian pairs beyond which a render is refused rather than exhausting memory
/// (4 bytes each: 8 GiB).
pub const MAX_PAIRS: usize = 1 << 31;

/// Accuracy and time knobs; `Default` is the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    pub extent: Extent,
    /// Upper bound of a Gaussian's α at a pixel: 0.99 (reference) or 0.999 (gsplat).
    pub alpha_clamp: f32,
    /// Highest SH degree evaluated (the cloud's own degree if lower).
    pub sh_degree_cap: u8,
    /// Gaussians with view-space depth `z ≤ near` are dropped.
    pub near: f32,
    /// Colour behind everything (`C + T·background`).
    pub background: [f32; 3],
    /// Visit every pixel of every touched tile (bit-identical output, slower; for tests).
    pub exhaustive: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            extent: Extent::Sigma3,
            alpha_clamp: ALPHA_CLAMP_REFERENCE,
            sh_degree_cap: 3,
            near: NEAR_REFERENCE,
            background: [0.0; 3],
            exhaustive: false,
        }
    }
}

/// Wall time of each phase.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseTimes {
    /// Per-Gaussian projection and SH colour.
    pub projection: Duration,
    /// Global depth sort.
    pub sorting: Duration,
    /// Tile lists (counting sort by tile).
    pub binning: Duration,
    /// Per-tile blending and frame assembly.
    pub blending: Duration,
}

impl PhaseTimes {
    pub fn total(&self) -> Duration {
        self.projection + self.sorting + self.binning + self.blending
    }
}

/// What a render did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderStats {
    /// Gaussians in the input.
    pub gaussians: usize,
    /// Gaussians that reached at least one tile.
    pub projected: usize,
    /// Dropped by the near plane (`0 < z ≤ near`).
    pub culled_near: usize,
    /// Of those, how many project inside the image: the near plane, not the view, removed them.
    pub culled_near_in_view: usize,
    /// Behind the camera.
    pub culled_behind: usize,
    /// Opacity below 1/255.
    pub culled_transparent: usize,
    /// Degenerate 2D covariance or non-finite values.
    pub culled_degenerate: usize,
    /// Outside the image.
    pub culled_offscreen: usize,
    /// Tile–Gaussian pairs (entries of all tile lists).
    pub tile_pairs: u64,
    /// Pixel–Gaussian blends (times a Gaussian was added to a pixel).
    pub blends: u64,
    pub times: PhaseTimes,
}

/// Stats of several renders summed (the time samples of one motion-blurred frame).
impl std::ops::AddAssign<&RenderStats> for RenderStats {
    fn add_assign(&mut self, s: &RenderStats) {
        self.gaussians += s.gaussians;
        self.projected += s.projected;
        self.culled_near += s.culled_near;
        self.culled_near_in_view += s.culled_near_in_view;
        self.culled_behind += s.culled_behind;
        self.culled_transparent += s.culled_transparent;
        self.culled_degenerate += s.culled_degenerate;
        self.culled_offscreen += s.culled_offscreen;
        self.tile_pairs += s.tile_pairs;
        self.blends += s.blends;
        self.times.projection += s.times.projection;
        self.times.sorting += s.times.sorting;
        self.times.binning += s.times.binning;
        self.times.blending += s.times.blending;
    }
}

/// Errors of a render request.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("invalid camera: {0}")]
    Camera(#[from] splatbridge_scene::SceneError),
    #[error("invalid render option: {0}")]
    Option(String),
    #[error("{0} tile–Gaussian pairs exceed the limit of {MAX_PAIRS}; lower the resolution or move the camera back")]
    TooManyPairs(usize),
}

impl RenderOptions {
    pub fn validate(&self) -> Result<(), RenderError> {
        if !(self.near.is_finite() && self.near >= 0.0) {
            return Err(RenderError::Option(format!(
                "near plane {} must be finite and ≥ 0",
                self.near
            )));
        }
        if !(self.alpha_clamp > 1.0 / 255.0 && self.alpha_clamp < 1.0) {
            return Err(RenderError::Option(format!(
                "alpha clamp {} must be in (1/255, 1)",
                self.alpha_clamp
            )));
        }
        if self.background.iter().any(|c| !c.is_finite()) {
            return Err(RenderError::Option(
                "background colour must be finite".into(),
            ));
        }
        Ok(())
    }
}

/// Count why Gaussians were culled.
fn count_culled(all: &[Result<Projected, Culled>], stats: &mut RenderStats) {
    let c = all
        .par_chunks(CHUNK)
        .map(|rs| {
            let mut c = [0usize; 6];
            for r in rs {
                match r {
                    Ok(_) => {}
                    Err(Culled::Near { in_view }) => {
                        c[0] += 1;
                        c[1] += *in_view as usize;
                    }
                    Err(Culled::Behind) => c[2] += 1,
                    Err(Culled::Transparent) => c[3] += 1,
                    Err(Culled::Degenerate) => c[4] += 1,
                    Err(Culled::Offscreen) => c[5] += 1,
                }
            }
            c
        })
        .reduce(|| [0; 6], |a, b| std::array::from_fn(|i| a[i] + b[i]));
    stats.culled_near = c[0];
    stats.culled_near_in_view = c[1];
    stats.culled_behind = c[2];
    stats.culled_transparent = c[3];
    stats.culled_degenerate = c[4];
    stats.culled_offscreen = c[5];
}

const CHUNK: usize = 8192;

/// The renderer with its working buffers, kept between frames so an animation or a benchmark
/// does not pay for fresh memory (page faults) on every frame. [`render`] uses a fresh one.
#[derive(Default)]
pub struct Renderer {
    all: Vec<Result<Projected, Culled>>,
    keys: Vec<u64>,
    order: Vec<u32>,
    rects: Vec<[u32; 4]>,
    bins: Bins,
    splats: Vec<Splat>,
}

impl Renderer {
    pub fn new() -> Self {
        Self::default()
    }

    /// Render `cloud` from `camera`: RGB, alpha `1 − T` and blended depth, with counters and
    /// timings.
    pub fn render(
        &mut self,
        cloud: &GaussianCloud,
        camera: &Camera,
        opts: &RenderOptions,
    ) -> Result<(Frame, RenderStats), RenderError> {
        self.render_tiles(cloud, camera, opts, None)
    }

    /// The `w`×`h` window at pixel (`x0`, `y0`) of [`Renderer::render`]'s frame, bit for
    /// bit, rendering only the tiles that hold it: a Gaussian is projected as for the whole
    /// frame (the Jacobian clamp is the frame's), and only those whose tile rectangle meets
    /// the window's tiles are coloured, sorted, binned and blended. A tile's list is the
    /// frame's list of that tile (the depth order restricted to its members), so its pixels
    /// are the frame's. The counters count the window's Gaussians and blends only.
    pub fn render_window(
        &mut self,
        cloud: &GaussianCloud,
        camera: &Camera,
        opts: &RenderOptions,
        [x0, y0, w, h]: [u32; 4],
    ) -> Result<(Frame, RenderStats), RenderError> {
        let inside = |a: u32, n: u32, of: u32| n > 0 && a.checked_add(n).is_some_and(|e| e <= of);
        if !(inside(x0, w, camera.width) && inside(y0, h, camera.height)) {
            return Err(RenderError::Option(format!(
                "window {w}×{h} at ({x0}, {y0}) is not inside the {}×{} frame",
                camera.width, camera.height
            )));
        }
        self.render_tiles(cloud, camera, opts, Some([x0, y0, w, h]))
    }

    /// [`Renderer::render`] of the tiles that hold the pixel window `[x0, y0, w, h]` (None:
    /// every tile, the whole frame), the window cut from their pixels.
    fn render_tiles(
        &mut self,
        cloud: &GaussianCloud,
        camera: &Camera,
        opts: &RenderOptions,
        window: Option<[u32; 4]>,
    ) -> Result<(Frame, RenderStats), RenderError> {
        camera.validate()?;
        cloud.check_shape()?;
        opts.validate()?;
        let mut view = ViewParams::new(camera, opts.near as f64);
        if let Some([x0, y0, w, h]) = window {
            view.clip = view.tiles_of(x0, y0, w, h);
        }
        let mut stats = RenderStats {
            gaussians: cloud.len(),
            ..Default::default()
        };
        let degree = cloud.sh_degree.min(opts.sh_degree_cap);

        let t0 = Instant::now();
        self.all.clear();
        self.all.par_extend(
            (0..cloud.len())
                .into_par_iter()
                .with_min_len(CHUNK)
                .map(|i| project_one(cloud, i, &view, opts.extent, degree)),
        );
        count_culled(&self.all, &mut stats);
        self.keys.clear();
        self.keys.par_extend(
            self.all
                .par_iter()
                .enumerate()
                .filter_map(|(i, r)| r.as_ref().ok().map(|p| depth_key(p.splat.depth, i as u32))),
        );
        stats.projected = self.keys.len();
        let t1 = Instant::now();
        depth_order(&mut self.keys, cloud, &mut self.order);
        let t2 = Instant::now();
        let all = &self.all;
        let visible = |i: u32| match &all[i as usize] {
            Ok(p) => p,
            Err(_) => unreachable!("only projected Gaussians are ordered"),
        };
        self.rects.clear();
        self.rects
            .par_extend(self.order.par_iter().map(|&i| visible(i).rect));
        bin_tiles(&self.rects, view.grid, MAX_PAIRS, &mut self.bins)
            .map_err(RenderError::TooManyPairs)?;
        stats.tile_pairs = self.bins.pairs() as u64;
        self.splats.clear();
        self.splats
            .par_extend(self.order.par_iter().map(|&i| visible(i).splat));
        let t3 = Instant::now();
        let params = BlendParams {
            alpha_clamp: opts.alpha_clamp,
            background: opts.background,
            exhaustive: opts.exhaustive,
        };
        let (frame, blends) = rasterize_region(
            &self.splats,
            &self.bins,
            camera.width,
            camera.height,
            view.clip,
            &params,
        );
        // The region's pixels start at its first tile's; the window lies within them.
        let frame = match window {
            Some([x0, y0, w, h]) => frame
                .crop(x0 - view.clip[0] * TILE, y0 - view.clip[1] * TILE, w, h)
                .expect("the region's tiles hold the window"),
            None => frame,
        };
        let t4 = Instant::now();
        stats.blends = blends;
        stats.times = PhaseTimes {
            projection: t1 - t0,
            sorting: t2 - t1,
            binning: t3 - t2,
            blending: t4 - t3,
        };
        Ok((frame, stats))
    }
}

/// Render `cloud` from `camera` with a fresh [`Renderer`].
pub fn render(
    cloud: &GaussianCloud,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<(Frame, RenderStats), RenderError> {
    Renderer::new().render(cloud, camera, opts)
}
