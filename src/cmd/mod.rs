//! Subcommands. Each module owns its clap `Args` and a `run` returning `anyhow::Result`.

pub mod accuracy;
pub mod bench;
pub mod common;
pub mod compare;
pub mod convert;
pub mod demo;
pub mod distill_args;
mod distill_report;
pub mod fixture;
pub mod hybrid;
pub mod info;
pub mod merge;
pub mod ranges;
pub mod render;
pub mod render_args;
pub mod split_args;
pub mod tiles;
pub mod trace;

/// Print an error chain as `error: …` and map it to the exit status: 0 success, 2 error.
pub fn exit_code(result: anyhow::Result<()>) -> i32 {
    match result {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e:#}");
            2
        }
    }
}
