//! The splatbridge library face of the CLI crate: what combines the stage crates (`scene` ←
//! `convert`, `hybrid`, `raytrace` ← `distill`). Its folders are its parts:
//!
//! - [`pipeline`]: the frame pipeline every command renders through (load, renderer, one
//!   frame with its effects, sequences, exports, 3D Tiles, the automatic surfel split).
//! - [`measure`]: measurement against native splatting (parity, the accuracy sweep, viewer
//!   clients, the memory budget and memory figures, scene descriptions, reports).
//! - [`batch`]: work split across processes (shards) and joined again (merge).
//! - [`demo`]: the first run: the shipped real capture and the street, end to end.
//!
//! Mesh distillation is its own crate, `splatbridge_distill`, re-exported as [`distill`].
//! End-to-end tests and the commands share this library.

pub mod batch;
pub mod demo;
pub mod measure;
pub mod pipeline;

pub use splatbridge_distill as distill;
