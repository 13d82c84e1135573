//! The model every stage shares: Gaussian clouds (structure of arrays), PLY and other IO,
//! cameras, the dynamic scene graph, frames (RGB, alpha, depth) and image metrics.
//!
//! Conventions follow the reference 3DGS implementation (graphdeco-inria `gaussian-splatting`):
//! values are kept as they are stored (log-scales, opacity logits, raw w,x,y,z quaternions) and
//! activated through accessors, SH coefficients are coefficient-major (RGB interleaved per
//! coefficient), cameras use the OpenCV frame (x right, y down, z forward).

pub mod blocks;
pub mod camera;
pub mod camera_spec;
pub mod dynamic;
pub mod effects;
pub mod effects_run;
pub mod error;
pub mod fixtures;
pub mod formats;
pub mod fourd;
pub mod frame;
pub mod gaussians;
pub mod image_io;
pub mod input;
pub mod manifest;
pub mod metrics;
pub mod output;
pub mod ply;
pub mod rng;
pub mod sh;
pub mod sh_rotate;
pub mod srgb;
pub mod surfel_guard;
pub mod surfels;
pub mod trajectory;
pub mod weather;

pub use camera::Camera;
pub use error::{Result, SceneError};
pub use frame::Frame;
pub use gaussians::GaussianCloud;
