//! splatbridge-hybrid: the native 3D Gaussian Splatting renderer on a CPU (the exact forward
//! pass of the reference implementation, graphdeco-inria `diff-gaussian-rasterization`, see
//! `../shared/reference/3dgs-conventions.md`) and, built on its projection and blending, the
//! GES-style surfel-plus-Gaussian hybrid.
//!
//! Native renderer modules: [`project`] (per-Gaussian projection), [`bin`] (depth order and
//! tile lists), [`raster`] (per-tile blending) on the SIMD [`kernel`], and [`native`] (the
//! renderer API: options, statistics, reusable buffers). [`surfel2d`] renders 2DGS surfels as
//! 2D Gaussian Splatting's own rasterizer does (ray–splat intersection, its low-pass filter).
//! Measured figures: `hybrid/README.md`.

pub mod bin;
pub mod ges;
pub mod kernel;
pub mod native;
pub mod project;
pub mod raster;
pub mod surfel2d;

pub use native::{render, Extent, PhaseTimes, RenderError, RenderOptions, RenderStats, Renderer};
