//! Fuzz entry points for the `cargo fuzz` targets in `fuzz_targets/`; see `entries.rs`.

pub mod entries;
pub mod file_formats;
pub mod splat_formats;

pub use entries::{run, TARGETS};
