//! The native 3DGS renderer: projection → depth sort → tile binning → blending, with the
//! reference settings as defaults and every departure a named knob ([`RenderOptions`]).
//!
//! Output is deterministic: projection is per Gaussian, the depth order is total (ties broken by
//! content, see [`crate::bin`]), and each pixel is blended sequentially by one task, so the
//! image bits do not depend on the thread count or on the order of the input Gaussians.

use std::time::{Duration, Instant};

use rayon::prelude::*;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use crate::bin::{bin_tiles, depth_order};
pub use crate::project::Extent;
use crate::project::{project_one, Culled, Projected, ViewParams};
use crate::raster::{rasterize, BlendParams};

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

/// Project every Gaussian (in parallel); returns the visible ones in input order and the counts.
pub fn project_cloud(
    cloud: &GaussianCloud,
    view: &ViewParams,
    opts: &RenderOptions,
    stats: &mut RenderStats,
) -> Vec<Projected> {
    let degree = cloud.sh_degree.min(opts.sh_degree_cap);
    let parts: Vec<(Vec<Projected>, [usize; 6])> = (0..cloud.len())
        .into_par_iter()
        .chunks(8192)
        .map(|idx| {
            let mut vis = Vec::with_capacity(idx.len());
            let mut c = [0usize; 6];
            for i in idx {
                match project_one(cloud, i, view, opts.extent, degree) {
                    Ok(p) => vis.push(p),
                    Err(Culled::Near { in_view }) => {
                        c[0] += 1;
                        c[1] += in_view as usize;
                    }
                    Err(Culled::Behind) => c[2] += 1,
                    Err(Culled::Transparent) => c[3] += 1,
                    Err(Culled::Degenerate) => c[4] += 1,
                    Err(Culled::Offscreen) => c[5] += 1,
                }
            }
            (vis, c)
        })
        .collect();
    let mut out = Vec::with_capacity(parts.iter().map(|p| p.0.len()).sum());
    for (vis, c) in parts {
        out.extend(vis);
        stats.culled_near += c[0];
        stats.culled_near_in_view += c[1];
        stats.culled_behind += c[2];
        stats.culled_transparent += c[3];
        stats.culled_degenerate += c[4];
        stats.culled_offscreen += c[5];
    }
    out
}

/// Render `cloud` from `camera`: RGB, alpha `1 − T` and blended depth, with counters and timings.
pub fn render(
    cloud: &GaussianCloud,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<(Frame, RenderStats), RenderError> {
    camera.validate()?;
    cloud.check_shape()?;
    opts.validate()?;
    let view = ViewParams::new(camera, opts.near as f64);
    let mut stats = RenderStats {
        gaussians: cloud.len(),
        ..Default::default()
    };

    let t0 = Instant::now();
    let proj = project_cloud(cloud, &view, opts, &mut stats);
    stats.projected = proj.len();
    let t1 = Instant::now();
    let order = depth_order(&proj, cloud);
    let t2 = Instant::now();
    let bins = bin_tiles(&proj, &order, view.grid, MAX_PAIRS).map_err(RenderError::TooManyPairs)?;
    stats.tile_pairs = bins.pairs() as u64;
    let splats: Vec<_> = order.par_iter().map(|&k| proj[k as usize].splat).collect();
    drop(proj);
    let t3 = Instant::now();
    let params = BlendParams {
        alpha_clamp: opts.alpha_clamp,
        background: opts.background,
        exhaustive: opts.exhaustive,
    };
    let (frame, blends) = rasterize(&splats, &bins, camera.width, camera.height, &params);
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
