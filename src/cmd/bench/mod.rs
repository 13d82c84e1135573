//! `splatbridge bench …`: benchmarks that report medians over repeated runs and the counters
//! that explain them. Each target is its own module.
//!
//! Renderer benchmarks measure the steady state of a render loop: glibc's allocator is told to
//! keep freed memory (no `mmap` per large buffer, no trimming), so each frame reuses the pages
//! of the last instead of faulting in fresh ones. Without it, comparisons that alternate two
//! renderers measure the allocator: freeing one renderer's buffers returned them to the OS and
//! the other faulted its own back in (native splatting of the 1 M fixture took 352 ms inside
//! `bench hybrid` against 249 ms alone; 256 ms with this setting).

pub mod convert;
pub mod distill;
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
    /// Mesh distillation: set-up and step time, hits a pixel, views kept and streamed.
    Distill(distill::Args),
}

/// Keep freed memory in the process (see the module docs). Only glibc has these knobs; elsewhere
/// the allocator's default stands.
fn steady_state_allocator() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes allocator parameters; it is called before any worker thread
    // exists and its result (0 on failure) only means the default stays.
    unsafe {
        // No mmap-backed chunks (M_MMAP_THRESHOLD cannot exceed 32 MiB, below the renderers'
        // largest buffers), and no returning the heap's top to the OS.
        libc::mallopt(libc::M_MMAP_MAX, 0);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if matches!(
        args.target,
        Target::Render(_)
            | Target::Trace(_)
            | Target::Hybrid(_)
            | Target::Effects(_)
            | Target::Distill(_)
    ) {
        steady_state_allocator();
    }
    let result = match args.target {
        Target::Ply(a) => ply::run(a),
        Target::Render(a) => render::run(a),
        Target::Convert(a) => convert::run(a),
        Target::Trace(a) => trace::run(a),
        Target::Hybrid(a) => hybrid::run(a),
        Target::Effects(a) => effects::run(a),
        Target::Distill(a) => distill::run(a),
    };
    // On stderr, so a `--json` report on stdout stays one JSON document.
    if let Some(peak) = splatbridge::measure::memory::peak_bytes() {
        eprintln!("peak memory {:.1} MB (VmHWM)", peak as f64 / 1e6);
    }
    result
}
