//! `splatbridge bench …`: benchmarks that report medians over repeated runs and the counters
//! that explain them. Each target is its own module.

pub mod convert;
pub mod effects;
pub mod hybrid;
pub mod ply;
pub mod render;
pub mod trace;

#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub target: Target,
}

#[derive(clap::Subcommand)]
pub enum Target {
    /// PLY load throughput (MB/s) and peak memory.
    Ply(ply::Args),
    /// Native splatting: median frame time, Gaussians/s, tile–Gaussian pairs, blends.
    Render(render::Args),
    /// Converter: Gaussians to GLB time and size.
    Convert(convert::Args),
    /// BVH ray tracer: build time, Mrays/s, hits per ray, both backends.
    Trace(trace::Args),
    /// GES hybrid against native on the same scene and camera.
    Hybrid(hybrid::Args),
    /// Cost of each effect per frame (weather, motion blur, shadows, LiDAR) with counters.
    Effects(effects::Args),
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.target {
        Target::Ply(a) => ply::run(a),
        Target::Render(a) => render::run(a),
        Target::Convert(a) => convert::run(a),
        Target::Trace(a) => trace::run(a),
        Target::Hybrid(a) => hybrid::run(a),
        Target::Effects(a) => effects::run(a),
    }
}
