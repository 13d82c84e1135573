//! The splatbridge library face of the CLI crate: what combines the stage crates (`scene` ←
//! `convert`, `hybrid`, `raytrace`): the frame pipeline every command renders through, the
//! parity pipeline, the accuracy sweep, scene descriptions and the reports. End-to-end tests
//! and the commands share it.

pub mod accuracy;
pub mod clients;
pub mod describe;
pub mod parity;
pub mod pipeline;
pub mod report;
pub mod tiles;
