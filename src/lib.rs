//! The splatbridge library face of the CLI crate: what combines the stage crates (`scene` ←
//! `convert`, `hybrid`, `raytrace`): the frame pipeline every command renders through, the
//! parity pipeline, the accuracy sweep, scene descriptions and the reports. End-to-end tests
//! and the commands share it.

pub mod accuracy;
pub mod accuracy_distill;
pub mod budget;
pub mod clients;
pub mod demo;
pub mod describe;
pub mod distill;
pub mod footprint_export;
pub mod frame_store;
pub mod heap;
pub mod memory;
pub mod merge;
pub mod parity;
pub mod pipeline;
pub mod report;
pub mod shard;
pub mod split_auto;
pub mod tiles;
