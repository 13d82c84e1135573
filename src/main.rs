//! The `splatbridge` command line: one subcommand per capability, errors printed as
//! `error: FILE: what went wrong` with exit status 2.

/// Every scene format the reading commands accept (`splatbridge_scene::formats`, recognised
/// by content), as help text; `concat!` puts it into each command's help.
macro_rules! scene_formats {
    () => {
        "a 3DGS PLY (also 2DGS, Mip-Splatting and red-green-blue point PLYs), a compressed PLY, \
         .splat, .spz, .ksplat, SOG (a folder's meta.json or a .sog zip), \
         glTF/GLB with KHR_gaussian_splatting, a splatbridge-scene/1 manifest (JSON), or a 4D \
         model (SpacetimeGaussians lite PLY, .splatv, Dynamic3DGaussians params.npz, or a folder \
         or pattern of numbered frame PLYs)"
    };
}

mod cmd;

/// Counted, so `bench` can report what a stage allocates at its peak (`splatbridge::measure::heap`).
#[global_allocator]
static ALLOC: splatbridge::measure::heap::Counting = splatbridge::measure::heap::Counting;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "splatbridge", version, about = "Take trained 3D Gaussian Splatting scenes to meshes, surfel hybrids and a BVH ray tracer, and measure what each approximation costs.", long_about = None, after_help = concat!("Scenes are read from ", scene_formats!(), "; the format is recognised by content. trace also reads GLB, glTF and OBJ meshes."))]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Frame rate of 4D inputs: frame i of a params.npz or a numbered frame sequence is at
    /// i/fps seconds; continuous models (SpacetimeGaussians, .splatv) are sampled at this rate
    /// over their [0, 1] time range.
    #[arg(long, global = true, value_name = "FPS", default_value_t = 30.0, value_parser = parse_fps)]
    fps: f64,
}

fn parse_fps(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    splatbridge_scene::fourd::check_fps(v)
}

#[derive(Subcommand)]
enum Command {
    /// Describe a scene (any splat format or a manifest): counts, SH degree, bounds, distributions, invalid values.
    #[command(after_help = "Example:\n  splatbridge info scene.ply --json")]
    Info(cmd::info::Args),
    /// Generate a deterministic synthetic scene (street, large, hard).
    #[command(
        after_help = "Examples:\n  splatbridge fixture street -o out/street\n  splatbridge fixture large --count 1000000 -o out/large"
    )]
    Fixture(cmd::fixture::Args),
    /// Render a scene with the native 3DGS splatting renderer (the reference).
    #[command(
        after_help = "Example:\n  splatbridge render scene.ply --camera orbit:8:0 -o out.png"
    )]
    Render(cmd::render::Args),
    /// Convert Gaussians to triangle meshes (GLB/glTF/OBJ/PLY) or native glTF splats.
    #[command(after_help = "Example:\n  splatbridge convert scene.ply --profile rings -o out.glb")]
    Convert(Box<cmd::convert::Args>),
    /// Ray-trace an exported file (or a scene converted in memory) with a BVH.
    #[command(after_help = "Example:\n  splatbridge trace out.glb --camera scene:0 -o traced.png")]
    Trace(cmd::trace::Args),
    /// Render with the GES-style hybrid: opaque surfels, then the Gaussians they leave (sorted by default, or GES's unsorted blend).
    #[command(
        after_help = "Example:\n  splatbridge hybrid scene.ply --camera orbit:8:0 -o hybrid.png"
    )]
    Hybrid(cmd::hybrid::Args),
    /// Render every renderer and profile against native splatting and report parity.
    #[command(
        after_help = "Example:\n  splatbridge compare scene.ply --cameras orbit:4 -o compare/"
    )]
    Compare(cmd::compare::Args),
    /// Sweep the accuracy knobs one at a time and plot error against time.
    #[command(after_help = "Example:\n  splatbridge accuracy scene.ply -o accuracy/")]
    Accuracy(cmd::accuracy::Args),
    /// Join the output folders of a sharded compare or accuracy run (--shard I/N).
    #[command(
        after_help = "Example:\n  splatbridge merge out/shard-0 out/shard-1 out/shard-2 -o out/merged"
    )]
    Merge(cmd::merge::Args),
    /// Benchmarks: PLY load, native render, convert, trace, hybrid.
    #[command(
        after_help = "Example:\n  splatbridge bench render scene.ply --width 1920 --height 1080"
    )]
    Bench(cmd::bench::Args),
    /// The first run: the shipped real capture exported and rendered every way, measured against native splatting, with a picture and a report; the street scene for motion.
    #[command(after_help = "Example:\n  splatbridge demo -o demo/")]
    Demo(cmd::demo::Args),
}

/// Subcommands print with `println!`, which panics when stdout cannot be written (a full
/// disk, `> /dev/full`; a closed pipe, `| head -c1`). This hook turns exactly that failure into
/// the CLI's convention: a closed pipe ends the run quietly (the reader wanted no more), any
/// other write error is `error: stdout: …` with exit status 2. Every other panic keeps the
/// default report.
fn install_stdout_hook() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if let Some(err) = msg.strip_prefix("failed printing to stdout: ") {
            std::process::exit(stdout_failure(err));
        }
        default(info);
    }));
}

/// Exit status for a failed write to stdout, printing the error unless the pipe was closed.
fn stdout_failure(err: &str) -> i32 {
    if err.contains("Broken pipe") || err.contains("os error 32") {
        0
    } else {
        eprintln!("error: stdout: {err}");
        2
    }
}

fn main() {
    install_stdout_hook();
    let cli = Cli::parse();
    // Checked by the parser already; a failure here cannot happen.
    let _ = splatbridge_scene::fourd::set_frame_rate(cli.fps);
    let result = match cli.command {
        Command::Info(a) => cmd::info::run(a),
        Command::Fixture(a) => cmd::fixture::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::Convert(a) => cmd::convert::run(*a),
        Command::Trace(a) => cmd::trace::run(a),
        Command::Hybrid(a) => cmd::hybrid::run(a),
        Command::Compare(a) => cmd::compare::run(a),
        Command::Accuracy(a) => cmd::accuracy::run(a),
        Command::Merge(a) => cmd::merge::run(a),
        Command::Bench(a) => cmd::bench::run(a),
        Command::Demo(a) => cmd::demo::run(a),
    };
    let mut code = cmd::exit_code(result);
    // `print!` output still buffered is flushed here so its write error is seen, not dropped.
    if let Err(e) = std::io::Write::flush(&mut std::io::stdout()) {
        if code == 0 {
            code = stdout_failure(&e.to_string());
        }
    }
    std::process::exit(code);
}
