//! The frame pipeline: from an input file to a rendered frame, for every renderer, with the
//! scene's declared effects. Commands, benchmarks, the parity pipeline and the tests call it;
//! the CLI only parses arguments and prints.
//!
//! - [`source`]: load a scene (PLY or manifest), or prepare what the ray tracer traces (an
//!   exported file, a scene converted in memory, or the Gaussians) with its camera and effects.
//! - [`renderer`]: [`Renderer`], one type over native splatting, the GES hybrid, the mesh
//!   tracer and the Gaussian tracer.
//! - [`frame`]: [`render_frame`], one frame with its time samples, motion-blur samples, weather
//!   particles, shadows, LiDAR and effect counters.
//! - [`sequence`]: [`sequence::render_sequence`], every frame of a scene's time range as one
//!   atomic set of images (and LiDAR scans), sharded with `--shard I/N`.
//! - [`export`]: a scene to a mesh, glTF splats or a single-cloud splat file, with its
//!   per-frame content and effect counters (what `convert` runs); [`export_shard`] a
//!   sharded frame export; [`export_request`] what `convert` asks, checked and resolved.
//! - [`still`]: a scene rendered by native splatting or the hybrid, one frame or a sequence
//!   (`render`, `hybrid`); [`trace_job`]: `trace`'s frame or sequence.
//! - [`motion`]: frame sequences (4D captures) to scenes: what moves found (static, rigid
//!   objects with tracks, per-frame content), or every frame kept whole.
//! - [`tiles`]: 3D Tiles with geometric errors measured by rendering (`convert --tiles`).
//! - [`split_auto`]: `--split auto`, the hybrid renderer's surfel split chosen by measuring.
//!
//! Cameras are chosen with `splatbridge_scene::camera_spec`.

pub mod export;
pub mod export_request;
pub mod export_shard;
pub mod frame;
pub mod motion;
pub mod renderer;
pub mod sequence;
pub mod source;
pub mod split_auto;
pub mod still;
pub mod tiles;
pub mod trace_job;

pub use frame::{render_frame, FrameRequest, LidarRequest, RenderedFrame};
pub use renderer::{FrameStats, Renderer, SurfelSplit};
pub use source::{load_scene_kind, load_scene_warn, Loaded, Prepared, TraceMode, TraceSource};
