//! The splatbridge library face of the CLI crate: what combines the stage crates (`scene` ←
//! `convert`, `hybrid`, `raytrace`): the frame pipeline every command renders through, the
//! parity pipeline and the reports. End-to-end tests and the commands share it.

pub mod clients;
pub mod parity;
pub mod pipeline;
pub mod report;
