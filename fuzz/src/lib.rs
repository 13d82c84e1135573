//! Fuzz entry points for the `cargo fuzz` targets in `fuzz_targets/`; see `entries.rs`.

pub mod entries;

pub use entries::{run, TARGETS};
