//! The GES-style hybrid renderer (Gaussian-enhanced Surfels, arXiv 2504.17545, `YessionCC/GES`;
//! facts in `../shared/reference/meshsplats-and-ges.md`): opaque surfels carry the coarse
//! geometry and appearance, the residual Gaussians the detail, and nothing is sorted (unless
//! [`Blend::Sorted`] asks for native's order in pass 2, [`sorted_pass`]).
//!
//! 1. [`surfel_pass`]: surfels through a per-sample z-buffer (ray–plane intersection, exact
//!    ellipse coverage), optional 4× supersampling, optional 3×3 colour blur.
//! 2. [`gauss_pass`]: Gaussians projected exactly as the native renderer does (its
//!    [`crate::project`], through [`project_gauss`], which drops those behind the surfels of
//!    every tile they touch before their colour is evaluated), binned without sorting,
//!    accumulated additively where their depth is within `D_S + ε` of the covering surfel
//!    (ε = F·mean scale, GES: F = 5).
//! 3. [`composite`]: `C = (w_S·C_S + C_G)/(w_S + W_G)` where a surfel covers the pixel; weighted
//!    blended transparency over the background where none does.
//!
//! Where the speed comes from, against the native renderer on the same cloud: no depth sort; no
//! per-pixel transmittance chain (every Gaussian–pixel pair is independent); and, above all, the
//! surfels occlude: a Gaussian enters a tile's list only if its depth is within the tile's
//! largest `D_S + ε`, so the Gaussians behind the opaque surface cost nothing past their tile
//! rectangle.
//!
//! Surfels come from [`splatbridge_scene::surfels`] (split of a 3DGS cloud, or GES's PLY flag).

pub mod composite;
pub mod gauss_pass;
pub mod project_gauss;
pub mod sorted_pass;
pub mod surfel_pass;
pub mod surfel_project;
pub mod tiles;

use std::time::{Duration, Instant};

use rayon::prelude::*;
use splatbridge_scene::surfels::{
    split, split_ges, SplitParams, SurfelCloud, FOOTPRINT_SIGMAS, GES_EPSILON_FACTOR,
};
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use crate::native::{RenderError, RenderOptions, ALPHA_CLAMP_REFERENCE, MAX_PAIRS, NEAR_REFERENCE};
use crate::project::{Extent, Splat, ViewParams};
use crate::raster::BlendParams;

use gauss_pass::{gauss_tile, FrameOut};
use project_gauss::{project_unhidden, Projection};
use surfel_pass::T;

/// Knobs of the hybrid renderer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GesOptions {
    /// Depth tolerance factor F: `ε = F·mean_scale` of the covering surfel (GES: 5).
    pub epsilon_factor: f32,
    /// Surfel footprint radius in standard deviations: GES's 1/255 boundary
    /// [`FOOTPRINT_SIGMAS`] (≈ 3.33, default), or smaller for surfels split from a 3DGS cloud,
    /// e.g. `sqrt(2)` ≈ 1.41, where the disc's area equals the integral of a unit-opacity
    /// Gaussian (2π·s_u·s_v = π·r²·s_u·s_v).
    pub footprint_sigmas: f32,
    /// Samples per pixel in pass 1: 1 or 4.
    pub supersample: u32,
    /// GES's 3×3 surfel colour blur.
    pub blur: bool,
    pub background: [f32; 3],
    /// Near plane for surfels (per sample) and Gaussians (per mean), as the native renderer.
    pub near: f32,
    pub sh_degree_cap: u8,
    /// Extent of a Gaussian's tile footprint. `Alpha` (default) is exactly the set where
    /// `opacity·G ≥ 1/255`, the pass's own inclusion rule; `Sigma3` the native 3σ square.
    pub extent: Extent,
    /// How the Gaussians left after the surfel pass are blended (see [`Blend`]).
    pub blend: Blend,
}

/// How pass 2 blends the Gaussians that the surfels leave.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Blend {
    /// GES's order-independent weighted blend ([`gauss_pass`], [`composite`]): no sort. The
    /// default: it is where the hybrid's speed comes from (about half the cost per blend of
    /// the sorted pass, measured in `docs/blend.md`).
    #[default]
    Unsorted,
    /// Sorted front to back and blended as the native renderer does, the surfel an opaque layer
    /// behind them ([`sorted_pass`]); with no surfels, the native image. Accurate, but about
    /// as slow as native splatting on trained captures.
    Sorted,
}

impl Default for GesOptions {
    fn default() -> Self {
        GesOptions {
            epsilon_factor: GES_EPSILON_FACTOR,
            footprint_sigmas: FOOTPRINT_SIGMAS,
            supersample: 1,
            blur: false,
            background: [0.0; 3],
            near: NEAR_REFERENCE,
            sh_degree_cap: 3,
            extent: Extent::Alpha,
            blend: Blend::default(),
        }
    }
}

impl GesOptions {
    pub fn validate(&self) -> Result<(), RenderError> {
        if !(self.epsilon_factor.is_finite() && self.epsilon_factor >= 0.0) {
            return Err(RenderError::Option(format!(
                "epsilon factor {} must be finite and ≥ 0",
                self.epsilon_factor
            )));
        }
        if !(self.footprint_sigmas > 0.0 && self.footprint_sigmas.is_finite()) {
            return Err(RenderError::Option(format!(
                "surfel footprint {} must be finite and > 0",
                self.footprint_sigmas
            )));
        }
        if self.supersample != 1 && self.supersample != 4 {
            return Err(RenderError::Option(format!(
                "supersample {} must be 1 or 4",
                self.supersample
            )));
        }
        RenderOptions {
            near: self.near,
            background: self.background,
            ..Default::default()
        }
        .validate()
    }
}

/// Wall time of each phase.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GesTimes {
    /// Surfel projection, binning, z-buffer and blur.
    pub surfels: Duration,
    /// Gaussian projection and SH colour (and the sorted blend's depth sort).
    pub projection: Duration,
    /// Tile lists with the per-tile depth cull.
    pub binning: Duration,
    /// Accumulation, composite and frame assembly.
    pub blending: Duration,
}

impl GesTimes {
    pub fn total(&self) -> Duration {
        self.surfels + self.projection + self.binning + self.blending
    }
}

/// What a hybrid render did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GesStats {
    pub surfels: usize,
    /// Surfels that reached at least one tile.
    pub surfels_drawn: usize,
    pub surfel_pairs: usize,
    pub gaussians: usize,
    /// Gaussians that survived projection.
    pub projected: usize,
    /// Tile–Gaussian pairs kept, and dropped by the per-tile depth cull.
    pub tile_pairs: u64,
    pub culled_pairs: u64,
    /// Pixel–Gaussian additions.
    pub blends: u64,
    /// Gaussians depth-sorted (the sorted blend's survivors of the surfel test; 0 unsorted).
    pub sorted: usize,
    pub times: GesTimes,
}

/// Stats of several renders summed (the time samples of one motion-blurred frame).
impl std::ops::AddAssign<&GesStats> for GesStats {
    fn add_assign(&mut self, s: &GesStats) {
        self.surfels += s.surfels;
        self.surfels_drawn += s.surfels_drawn;
        self.surfel_pairs += s.surfel_pairs;
        self.gaussians += s.gaussians;
        self.projected += s.projected;
        self.tile_pairs += s.tile_pairs;
        self.culled_pairs += s.culled_pairs;
        self.blends += s.blends;
        self.sorted += s.sorted;
        self.times.surfels += s.times.surfels;
        self.times.projection += s.times.projection;
        self.times.binning += s.times.binning;
        self.times.blending += s.times.blending;
    }
}

/// Render surfels and residual Gaussians from `camera`.
pub fn render_ges(
    surfels: &SurfelCloud,
    gaussians: &GaussianCloud,
    camera: &Camera,
    opts: &GesOptions,
) -> Result<(Frame, GesStats), RenderError> {
    render_impl(surfels, gaussians, camera, opts, false).map(|(f, s, _)| (f, s))
}

/// As [`render_ges`], also returning per pixel (row-major) the index of the surfel that won the
/// pixel's first sample (`u32::MAX` where none): for tests and diagnostics.
pub fn render_ges_with_ids(
    surfels: &SurfelCloud,
    gaussians: &GaussianCloud,
    camera: &Camera,
    opts: &GesOptions,
) -> Result<(Frame, GesStats, Vec<u32>), RenderError> {
    render_impl(surfels, gaussians, camera, opts, true)
}

/// The render; the per-pixel surfel ids (a full-frame buffer) only when `want_ids`.
fn render_impl(
    surfels: &SurfelCloud,
    gaussians: &GaussianCloud,
    camera: &Camera,
    opts: &GesOptions,
    want_ids: bool,
) -> Result<(Frame, GesStats, Vec<u32>), RenderError> {
    camera.validate()?;
    gaussians.check_shape()?;
    opts.validate()?;
    let k = surfels.coeffs();
    let n = surfels.len();
    let shape_ok = surfels.axes_u.len() == n
        && surfels.axes_v.len() == n
        && surfels.scales.len() == n
        && surfels.mean_scales.len() == n
        && surfels.sh.len() == n * k
        && surfels.sh_degree <= 3;
    if !shape_ok {
        return Err(RenderError::Option(
            "inconsistent surfel cloud (array lengths or SH degree)".into(),
        ));
    }
    let view = ViewParams::new(camera, opts.near as f64);
    let mut stats = GesStats {
        surfels: n,
        gaussians: gaussians.len(),
        ..Default::default()
    };

    let t0 = Instant::now();
    let mut sb = surfel_pass::surfel_pass(
        surfels,
        &view,
        opts.epsilon_factor,
        opts.footprint_sigmas,
        opts.sh_degree_cap,
        opts.supersample,
        MAX_PAIRS,
        want_ids,
    )
    .map_err(RenderError::TooManyPairs)?;
    if opts.blur {
        composite::blur_surfels(
            &sb.slot,
            &mut sb.planes,
            camera.width,
            camera.height,
            view.grid,
        );
    }
    stats.surfels_drawn = sb.drawn;
    stats.surfel_pairs = sb.pairs;
    let t1 = Instant::now();

    let (gx, gy) = (view.grid[0] as usize, view.grid[1] as usize);
    let tile_max: Vec<f32> = (0..gx * gy).map(|t| sb.tile_max(t)).collect();
    let Projected {
        mut splats,
        mut rects,
        index,
        hidden,
        hidden_pairs,
    } = project_all(gaussians, &view, opts, &tile_max);
    stats.projected = splats.len() + hidden;
    if opts.blend == Blend::Sorted {
        sorted_pass::sort_by_depth(gaussians, &index, &mut splats, &mut rects);
        stats.sorted = splats.len();
    }
    drop(index);
    let t2 = Instant::now();

    let total_pairs: u64 = rects.iter().map(rect_pairs).sum::<u64>() + hidden_pairs;
    let bins = tiles::bin_rects(&rects, view.grid, MAX_PAIRS, |i, t| {
        splats[i].depth <= sb.tile_max(t)
    })
    .map_err(RenderError::TooManyPairs)?;
    stats.tile_pairs = bins.pairs() as u64;
    stats.culled_pairs = total_pairs - stats.tile_pairs;
    drop(rects);
    let t3 = Instant::now();

    let mut order: Vec<usize> = (0..gx * gy).collect();
    order.sort_by_key(|&t| std::cmp::Reverse(bins.tile(t).len()));
    let bg = opts.background;
    let mut frame = Frame::new(camera.width, camera.height);
    let out = FrameOut::new(&mut frame);
    let params = BlendParams {
        alpha_clamp: ALPHA_CLAMP_REFERENCE,
        background: bg,
        exhaustive: false,
    };
    stats.blends = order
        .into_par_iter()
        .with_max_len(1)
        .map(|t| {
            let (px0, py0) = (((t % gx) * T) as i32, ((t / gx) * T) as i32);
            let (list, surf) = (bins.tile(t), sb.tile(t));
            // SAFETY: each tile index appears once in `order`, so each pixel is written once;
            // `frame` is not otherwise used until the parallel loop has finished.
            unsafe {
                match opts.blend {
                    Blend::Unsorted => gauss_tile(&splats, list, px0, py0, surf, bg, &out),
                    Blend::Sorted => {
                        sorted_pass::sorted_tile(&splats, list, px0, py0, surf, &params, &out)
                    }
                }
            }
        })
        .sum();
    let t4 = Instant::now();
    stats.times = GesTimes {
        surfels: t1 - t0,
        projection: t2 - t1,
        binning: t3 - t2,
        blending: t4 - t3,
    };
    Ok((frame, stats, sb.ids))
}

/// Gaussians projected per parallel job of [`project_all`].
const PROJECT_CHUNK: usize = 8192;

/// What [`project_all`] returns: the splats, tile rectangles and cloud indices of the
/// Gaussians that are visible and not behind the largest limit of every tile they touch, in
/// input order; the Gaussians hidden that way and their tile pairs.
#[derive(Default)]
struct Projected {
    splats: Vec<Splat>,
    rects: Vec<[u32; 4]>,
    index: Vec<u32>,
    hidden: usize,
    hidden_pairs: u64,
}

/// Project every Gaussian as the native renderer's [`crate::project::project_one`] does (in
/// parallel, in fixed chunks), with the depth test against `tile_max` (see [`project_gauss`]).
fn project_all(
    cloud: &GaussianCloud,
    view: &ViewParams,
    opts: &GesOptions,
    tile_max: &[f32],
) -> Projected {
    let degree = cloud.sh_degree.min(opts.sh_degree_cap);
    let n = cloud.len();
    let parts: Vec<Projected> = (0..n.div_ceil(PROJECT_CHUNK))
        .into_par_iter()
        .with_max_len(1)
        .map(|c| {
            let range = c * PROJECT_CHUNK..n.min((c + 1) * PROJECT_CHUNK);
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("sse4.1") {
                // SAFETY: SSE4.1 is present.
                return unsafe {
                    project_range_sse41(cloud, range, view, opts.extent, degree, tile_max)
                };
            }
            project_range(cloud, range, view, opts.extent, degree, tile_max)
        })
        .collect();
    let total: usize = parts.iter().map(|p| p.splats.len()).sum();
    let mut out = Projected {
        splats: Vec::with_capacity(total),
        rects: Vec::with_capacity(total),
        index: Vec::with_capacity(total),
        ..Default::default()
    };
    for p in parts {
        out.splats.extend_from_slice(&p.splats);
        out.rects.extend_from_slice(&p.rects);
        out.index.extend_from_slice(&p.index);
        out.hidden += p.hidden;
        out.hidden_pairs += p.hidden_pairs;
    }
    out
}

/// Project the Gaussians of `range` (see [`project_all`]).
#[inline(always)]
fn project_range(
    cloud: &GaussianCloud,
    range: std::ops::Range<usize>,
    view: &ViewParams,
    extent: Extent,
    degree: u8,
    tile_max: &[f32],
) -> Projected {
    let mut p = Projected::default();
    for i in range {
        match project_unhidden(cloud, i, view, extent, degree, tile_max) {
            Projection::Visible(s, r) => {
                p.splats.push(s);
                p.rects.push(r);
                p.index.push(i as u32);
            }
            Projection::Hidden(r) => {
                p.hidden += 1;
                p.hidden_pairs += rect_pairs(&r);
            }
            Projection::Culled => {}
        }
    }
    p
}

/// [`project_range`] compiled with SSE4.1, whose `roundsd` does the floor and ceil of the
/// radius and footprint box that otherwise are calls (the same IEEE results).
///
/// # Safety
/// The CPU must support SSE4.1.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1")]
unsafe fn project_range_sse41(
    cloud: &GaussianCloud,
    range: std::ops::Range<usize>,
    view: &ViewParams,
    extent: Extent,
    degree: u8,
    tile_max: &[f32],
) -> Projected {
    project_range(cloud, range, view, extent, degree, tile_max)
}

/// Tiles of a tile rectangle `[x0, y0, x1, y1)`.
fn rect_pairs(r: &[u32; 4]) -> u64 {
    (r[2] - r[0]) as u64 * (r[3] - r[1]) as u64
}

/// How a cloud is turned into surfels and Gaussians.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SplitMode {
    /// Split a trained 3DGS cloud by opacity and flatness.
    Thresholds(SplitParams),
    /// The cloud is a GES PLY (surfels flagged by stored opacity above 1000).
    GesPly,
}

/// Split `cloud` as `mode` says, then render. Returns the frame, the statistics and the time
/// the split took.
pub fn render_cloud(
    cloud: &GaussianCloud,
    mode: SplitMode,
    camera: &Camera,
    opts: &GesOptions,
) -> Result<(Frame, GesStats, Duration), RenderError> {
    let t0 = Instant::now();
    let (surfels, rest) = match mode {
        SplitMode::Thresholds(p) => split(cloud, &p),
        SplitMode::GesPly => {
            let (s, g, _) = split_ges(cloud);
            (s, g)
        }
    };
    let dt = t0.elapsed();
    let (frame, stats) = render_ges(&surfels, &rest, camera, opts)?;
    Ok((frame, stats, dt))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use splatbridge_scene::rng::Rng;

    /// Every field of a splat, floats as bits (so that −0 and NaN patterns count too).
    fn bits(s: &Splat) -> Vec<u32> {
        let mut v = [s.x, s.y, s.opacity, s.depth].map(f32::to_bits).to_vec();
        v.extend(s.conic.map(f32::to_bits));
        v.extend(s.color.map(f32::to_bits));
        v.extend(s.bbox.map(|b| b as u32));
        v
    }

    /// The SSE4.1 projection loop gives the portable loop's splats, rectangles and hidden
    /// counts bit for bit, for both extents, on the large fixture seen from inside its region
    /// with random tile limits.
    #[cfg(target_arch = "x86_64")]
    #[test]
    #[cfg_attr(not(host_sse41), ignore = "the CPU has no SSE4.1")]
    fn sse41_projection_matches_portable() {
        // Built where the CPU has it (build.rs); running it elsewhere would be undefined.
        assert!(std::arch::is_x86_feature_detected!("sse4.1"));
        let cloud = splatbridge_scene::fixtures::large(30_000, 3);
        let cam = Camera::look_at(
            DVec3::new(3.0, -2.0, -12.0),
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::NEG_Y,
            60.0,
            320,
            200,
        )
        .unwrap();
        let view = ViewParams::new(&cam, 0.2);
        let mut rng = Rng::new(4);
        let ntiles = (view.grid[0] * view.grid[1]) as usize;
        let limits: Vec<f32> = (0..ntiles).map(|_| rng.range(0.0, 30.0)).collect();
        for extent in [Extent::Alpha, Extent::Sigma3] {
            let a = project_range(&cloud, 0..cloud.len(), &view, extent, 3, &limits);
            // SAFETY: SSE4.1 was detected above.
            let b =
                unsafe { project_range_sse41(&cloud, 0..cloud.len(), &view, extent, 3, &limits) };
            assert!(
                a.splats.len() > 1000 && a.hidden > 1000,
                "{} {}",
                a.splats.len(),
                a.hidden
            );
            assert_eq!((a.hidden, a.hidden_pairs), (b.hidden, b.hidden_pairs));
            assert_eq!(a.rects, b.rects);
            let (sa, sb): (Vec<_>, Vec<_>) = (
                a.splats.iter().map(bits).collect(),
                b.splats.iter().map(bits).collect(),
            );
            assert_eq!(sa, sb);
        }
    }
}
