//! Native 2D Gaussian Splatting: the forward pass of 2DGS's own rasterizer (Huang et al. 2024,
//! "2D Gaussian Splatting for Geometrically Accurate Radiance Fields"; `hbb1/diff-surfel-rasterization`,
//! `cuda_rasterizer/forward.cu`, `auxiliary.h`, `config.h`) on a CPU.
//!
//! A 2DGS surfel is a flat Gaussian disc: centre `p`, tangent axes `t_u`, `t_v` (the first two
//! columns of its rotation), standard deviations `s_u`, `s_v` (`exp(scale_0)`, `exp(scale_1)`);
//! the third column of the rotation is its normal and there is no third scale. A point of the
//! plane is `P(u, v) = p + s_u·u·t_u + s_v·v·t_v`, with the Gaussian `G(u, v) = exp(−(u² + v²)/2)`.
//!
//! What each stage reproduces (module [`project`], then [`raster`]):
//! - **Homogeneous transform** (`computeCov3D`): `M = [W·t_u·s_u, W·t_v·s_v, W·p + t]` in camera
//!   space and the rows `T_u, T_v, T_w` of `P·M` with the pinhole intrinsics, so that
//!   `(x·w, y·w, w) = T·(u, v, 1)`. A surfel seen exactly edge-on (`n·(W·p + t) = 0`) is
//!   dropped, as there.
//! - **Screen bounds** (`computeCenter`): the centre and half-extents of the image of the unit
//!   circle `u² + v² = 1` from the dual conic `T·diag(1, 1, −1)·Tᵀ`; the radius
//!   `ceil(R·max(extent_x, extent_y, FilterSize))` with `R = sqrt(max(9 + ln o, 1e-6))`
//!   (`TIGHTBBOX`) and the tile rectangle of `getRect` (16×16 tiles).
//! - **Culling** (`preprocessCUDA`, `in_frustum`): view depth `z ≤ 0.2` (the near plane knob);
//!   surfels with opacity below 1/255 are dropped here (the reference drops them below 1e-4;
//!   between the two, `α < 1/255` is skipped at every pixel, so the image is the same).
//! - **Depth order**: one sort by the view depth of the centre (`depths[idx] = p_view.z`), exact
//!   ties by the stored values ([`crate::bin`]) rather than the reference's input order.
//! - **Ray–splat intersection** (`renderCUDA`): the pixel `(x, y)` (sampled at its centre,
//!   `pix + 0.5`) is the intersection of the planes `k = −T_u + x·T_w` and `l = −T_v + y·T_w`
//!   with the splat plane: `(u, v) = ((l_z·k_y − k_z·l_y), −(l_z·k_x − k_z·l_x)) / (k_x·l_y − k_y·l_x)`,
//!   `ρ3d = u² + v²`.
//! - **Object-space low-pass** (the paper's Eq. 11 after Botsch et al. 2005, as the code has it):
//!   `ρ2d = |c − pixel|² / FilterSize²` with `FilterSize = √2/2` (so `2·|c − pixel|²`) and `c`
//!   the centre from `computeCenter`; `ρ = min(ρ3d, ρ2d)`, i.e. `G = max(G(u, v), G(√2·d))`.
//!   The paper (Eq. 11) centres the filter on the projected surfel centre instead; the two
//!   part on large or grazing surfels, where perspective moves the centre of the projected
//!   circle. [`LowPassCentre`] picks one (default: the code's). Measured against the paper's
//!   per-pixel formulas (`tests/surfel2d.rs`, black background): 72.9–79.9 dB on random
//!   scenes with the paper's centre, 44.2–49.4 dB with the code's; against the same formulas
//!   with the code's centre, 52.1–82.0 dB (close-up to random) and 63.2–69.5 dB on
//!   `fourth_st` flattened to surfels.
//! - **Compositing**: skip `−ρ/2 > 0`; `α = min(0.99, o·exp(−ρ/2))`; skip `α < 1/255`; stop
//!   without adding when `T·(1 − α) < 1e-4`; colour `C + T·background`. Depth is the
//!   intersection depth `u·T_w,x + v·T_w,y + T_w,z` where the splat term wins and the centre
//!   depth where the low-pass wins (`INTERSECT_DEPTH`), reported as `Σ wᵢ zᵢ / Σ wᵢ` like every
//!   frame here (the reference writes the unnormalised sum).
//! - **Colour**: SH of degree ≤ 3 in the direction camera → centre, `+0.5`, clamped at 0
//!   (`computeColorFromSH`, the same as 3DGS).
//!
//! Departures, all at or below the reference's f32 rounding: the transform is formed in f64
//! from the camera-relative centre, and the per-pixel intersection runs in f64 (in f32 the
//! `k_x·l_y − k_y·l_x` of a surfel seen nearly edge-on cancels); the principal point is the
//! camera's own (`cx`, `cy`) where the reference fixes it at the image centre.
//!
//! Named departures, off by default, for measuring what meshes of surfels can carry
//! (docs/formats.md#2dgs-surfels): [`LowPassCentre::Off`] drops the low-pass (`ρ = ρ3d`) and
//! [`SurfelOrder::HitDepth`] blends each pixel's surfels in the order of their ray–plane hits
//! instead of centre depth; both are checked against the per-pixel formulas with the same
//! change (`tests/surfel2d.rs`).
//!
//! [`RenderOptions::extent`] is ignored: the footprint is always 2DGS's own.

pub mod project;
pub mod raster;

use std::time::Instant;

use rayon::prelude::*;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use crate::bin::{bin_tiles, depth_key, depth_order, Bins};
use crate::native::{RenderError, RenderOptions, RenderStats, MAX_PAIRS};
use crate::project::Culled;
pub use project::LowPassCentre;
use project::{project_surfel, SurfelSplat, View};
pub use raster::SurfelOrder;

/// The renderer with its working buffers, kept between frames.
#[derive(Default)]
pub struct SurfelRenderer {
    /// Where the low-pass filter is centred (default: as 2DGS's rasterizer).
    pub low_pass: LowPassCentre,
    /// The blending order (default: 2DGS's centre-depth order).
    pub blend_order: SurfelOrder,
    all: Vec<Result<(SurfelSplat, [u32; 4]), Culled>>,
    keys: Vec<u64>,
    order: Vec<u32>,
    rects: Vec<[u32; 4]>,
    bins: Bins,
    splats: Vec<SurfelSplat>,
}

impl SurfelRenderer {
    pub fn new() -> Self {
        Self::default()
    }

    /// Render `cloud` as 2DGS surfels (scale x, y and the rotation; the third log-scale is not
    /// read) from `camera`: RGB, alpha `1 − T` and blended depth, with counters and timings.
    pub fn render(
        &mut self,
        cloud: &GaussianCloud,
        camera: &Camera,
        opts: &RenderOptions,
    ) -> Result<(Frame, RenderStats), RenderError> {
        camera.validate()?;
        cloud.check_shape()?;
        opts.validate()?;
        let view = View::new(camera, opts.near as f64, self.low_pass);
        let degree = cloud.sh_degree.min(opts.sh_degree_cap);
        let mut stats = RenderStats {
            gaussians: cloud.len(),
            ..Default::default()
        };
        let t0 = Instant::now();
        self.all.clear();
        self.all.par_extend(
            (0..cloud.len())
                .into_par_iter()
                .with_min_len(4096)
                .map(|i| project_surfel(cloud, i, &view, degree)),
        );
        for r in &self.all {
            match r {
                Ok(_) => stats.projected += 1,
                Err(Culled::Near { in_view }) => {
                    stats.culled_near += 1;
                    stats.culled_near_in_view += *in_view as usize;
                }
                Err(Culled::Behind) => stats.culled_behind += 1,
                Err(Culled::Transparent) => stats.culled_transparent += 1,
                Err(Culled::Degenerate) => stats.culled_degenerate += 1,
                Err(Culled::Offscreen) => stats.culled_offscreen += 1,
            }
        }
        self.keys.clear();
        self.keys.extend(
            self.all
                .iter()
                .enumerate()
                .filter_map(|(i, r)| r.as_ref().ok().map(|(s, _)| depth_key(s.depth, i as u32))),
        );
        let t1 = Instant::now();
        depth_order(&mut self.keys, cloud, &mut self.order);
        let t2 = Instant::now();
        let all = &self.all;
        let visible = |i: u32| match &all[i as usize] {
            Ok(p) => p,
            Err(_) => unreachable!("only projected surfels are ordered"),
        };
        self.rects.clear();
        self.rects.extend(self.order.iter().map(|&i| visible(i).1));
        bin_tiles(&self.rects, view.grid, MAX_PAIRS, &mut self.bins)
            .map_err(RenderError::TooManyPairs)?;
        stats.tile_pairs = self.bins.pairs() as u64;
        self.splats.clear();
        self.splats.extend(self.order.iter().map(|&i| visible(i).0));
        let t3 = Instant::now();
        let (frame, blends) = raster::rasterize(
            &self.splats,
            &self.bins,
            camera.width,
            camera.height,
            opts.alpha_clamp as f64,
            opts.background,
            self.blend_order,
        );
        let t4 = Instant::now();
        stats.blends = blends;
        stats.times = crate::native::PhaseTimes {
            projection: t1 - t0,
            sorting: t2 - t1,
            binning: t3 - t2,
            blending: t4 - t3,
        };
        Ok((frame, stats))
    }
}

/// Render `cloud` as 2DGS surfels with a fresh [`SurfelRenderer`].
pub fn render_surfels(
    cloud: &GaussianCloud,
    camera: &Camera,
    opts: &RenderOptions,
) -> Result<(Frame, RenderStats), RenderError> {
    SurfelRenderer::new().render(cloud, camera, opts)
}
