//! Measurement: every renderer and export against native splatting, and what a run costs.
//!
//! - [`parity`]: each renderer and converter profile at the same cameras and times, measured
//!   against the reference, in memory-bounded stages ([`frame_store`] keeps the references,
//!   [`budget`] estimates each stage's peak before it runs, [`clients`] adds viewer clients).
//! - [`compare`]: `compare`'s run (cameras, times, the staged outputs, whole or one shard).
//! - [`hybrid_bench`]: `bench hybrid`'s timings and sweep.
//! - [`accuracy`]: the one-knob-at-a-time sweep ([`accuracy_distill`]: its distillation rows).
//! - [`report`]: records, tables and Pareto plots.
//! - [`describe`]: what `info` reports about a scene.
//! - [`memory`], [`heap`]: peak resident memory and the counting allocator.

pub mod accuracy;
pub mod accuracy_distill;
pub mod budget;
pub mod clients;
pub mod compare;
pub mod describe;
pub mod frame_store;
pub mod heap;
pub mod hybrid_bench;
pub mod memory;
pub mod parity;
pub mod report;
