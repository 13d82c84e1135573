//! The splatbridge library face of the CLI crate: the parity pipeline and the reports that
//! combine the stage crates (`scene` ← `convert`, `hybrid`, `raytrace`). End-to-end tests and
//! the `compare`, `accuracy` and `demo` commands share it.

pub mod parity;
pub mod report;
