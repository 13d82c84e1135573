//! The `splatbridge` command line: one subcommand per capability, errors printed as
//! `error: FILE: what went wrong` with exit status 2 (1 is left for "ran, but a check failed").

mod cmd;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "splatbridge", version, about = "Take trained 3D Gaussian Splatting scenes to meshes, surfel hybrids and a BVH ray tracer, and measure what each approximation costs.", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Describe a PLY or a scene manifest: counts, SH degree, bounds, distributions, invalid values.
    #[command(after_help = "Example:\n  splatbridge info scene.ply --json")]
    Info(cmd::info::Args),
    /// Generate a deterministic synthetic scene (street, large, hard).
    #[command(after_help = "Examples:\n  splatbridge fixture street -o out/street\n  splatbridge fixture large --count 1000000 -o out/large")]
    Fixture(cmd::fixture::Args),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Info(a) => cmd::info::run(a),
        Command::Fixture(a) => cmd::fixture::run(a),
    };
    std::process::exit(cmd::exit_code(result));
}
