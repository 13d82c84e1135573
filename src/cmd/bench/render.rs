//! `splatbridge bench render`: the native renderer's (or, for 2DGS surfels, the 2DGS
//! renderer's, see `--model`) median frame time over repeated renders
//! of one scene and camera, Gaussians per second, tile–Gaussian pairs, pixel–Gaussian blends
//! and the median time of each phase (projection, sorting, binning, blending).
//!
//! One untimed render warms caches, the thread pool and the renderer's buffers; then `--repeat`
//! timed renders (CPU time of the process is reported beside wall time, since on a shared
//! machine the wall time depends on other load). With
//! `--large N` the scene is the deterministic `large` fixture of N Gaussians generated in memory.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use splatbridge_hybrid::{RenderStats, Renderer};
use splatbridge_scene::{fixtures, GaussianCloud};

use splatbridge::pipeline::load_scene_kind;
use splatbridge_hybrid::surfel2d::SurfelRenderer;
use splatbridge_scene::ply::GaussianKind;

use crate::cmd::common::{print_warning, CameraArgs};
use crate::cmd::render::RenderKnobs;

#[derive(clap::Args)]
pub struct Args {
    #[arg(help = concat!("The scene: ", scene_formats!(), " (its composite at the start time). Omit with --large."))]
    pub scene: Option<PathBuf>,
    /// Generate the `large` fixture with this many Gaussians instead of loading a file.
    #[arg(long, conflicts_with = "scene")]
    pub large: Option<usize>,
    #[command(flatten)]
    pub camera: CameraArgs,
    #[command(flatten)]
    pub knobs: RenderKnobs,
    /// Timed renders (after one warm-up render).
    #[arg(long, alias = "repeats", default_value_t = 5)]
    pub repeat: usize,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// User + system CPU time of this process in seconds (Linux `/proc/self/stat`; None elsewhere).
fn process_cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    let f: Vec<&str> = s.rsplit(')').next()?.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    // USER_HZ is 100 on every Linux platform Rust targets.
    Some(ticks / 100.0)
}

/// The 1-minute load average, to judge how much of the machine the benchmark had.
fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (name, cloud, own, kind): (String, GaussianCloud, _, _) = match (&args.scene, args.large) {
        (Some(p), None) => {
            let (s, kind) = load_scene_kind(p, false, &print_warning)?;
            (
                p.display().to_string(),
                s.composite(s.time.start),
                s.cameras.clone(),
                kind,
            )
        }
        (None, Some(n)) => (
            format!("large fixture ({n} Gaussians, seed 1)"),
            fixtures::large(n, 1),
            Vec::new(),
            GaussianKind::Gaussians3D,
        ),
        _ => bail!("give a SCENE file or --large N"),
    };
    let cam = args
        .camera
        .resolve(&cloud, &own)
        .with_context(|| name.clone())?;
    let opts = args.knobs.options();
    opts.validate()?;
    let surfels = args.knobs.surfels_2d(kind, &name)?;
    let threads = args.threads.unwrap_or_else(rayon::current_num_threads);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let repeat = args.repeat.max(1);
    let mut cpu0 = None;
    let runs: Vec<(Duration, RenderStats)> = pool.install(|| -> anyhow::Result<_> {
        // One renderer across runs: its buffers are warm after the untimed render, as in an
        // animation; the frame itself is allocated fresh every time.
        let mut renderer = Renderer::new();
        let mut surfel_renderer = SurfelRenderer::new();
        let mut draw = || -> anyhow::Result<RenderStats> {
            Ok(if surfels {
                surfel_renderer.render(&cloud, &cam, &opts)?.1
            } else {
                renderer.render(&cloud, &cam, &opts)?.1
            })
        };
        draw()?;
        let mut runs = Vec::with_capacity(repeat);
        cpu0 = process_cpu_seconds();
        for _ in 0..repeat {
            let t = Instant::now();
            let stats = draw()?;
            runs.push((t.elapsed(), stats));
        }
        Ok(runs)
    })?;
    let cpu_ms = match (cpu0, process_cpu_seconds()) {
        (Some(a), Some(b)) => Some((b - a) * 1e3 / repeat as f64),
        _ => None,
    };
    let load = load_average();
    let frame = median(runs.iter().map(|r| r.0).collect());
    let phase = |f: fn(&RenderStats) -> Duration| median(runs.iter().map(|r| f(&r.1)).collect());
    let (proj, sort, bin, blend) = (
        phase(|s| s.times.projection),
        phase(|s| s.times.sorting),
        phase(|s| s.times.binning),
        phase(|s| s.times.blending),
    );
    let s = runs[0].1;
    let gps = cloud.len() as f64 / frame.as_secs_f64();
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    if args.json {
        let v = serde_json::json!({
            "scene": name, "gaussians": cloud.len(), "width": cam.width, "height": cam.height,
            "threads": threads, "repeat": repeat, "median_frame_ms": ms(frame),
            "cpu_ms_per_frame": cpu_ms, "load_average_1min": load,
            "gaussians_per_second": gps, "projected": s.projected, "tile_pairs": s.tile_pairs,
            "blends": s.blends, "culled_near": s.culled_near, "culled_near_in_view": s.culled_near_in_view,
            "phase_ms": {"projection": ms(proj), "sorting": ms(sort), "binning": ms(bin), "blending": ms(blend)},
            "knobs": args.knobs.describe(),
            "model": if surfels { "2dgs" } else { "3dgs" },
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!(
        "bench render: {name} ({})",
        if surfels { "2dgs" } else { "3dgs" }
    );
    println!(
        "  camera '{}' {}×{}, {threads} threads, {repeat} timed renders; {}",
        cam.name,
        cam.width,
        cam.height,
        args.knobs.describe()
    );
    println!(
        "  median frame {:.1} ms ({:.2} M Gaussians/s); {} projected, {} tile–Gaussian pairs, {} pixel–Gaussian blends",
        ms(frame),
        gps / 1e6,
        s.projected,
        s.tile_pairs,
        s.blends
    );
    if let Some(c) = cpu_ms {
        println!(
            "  CPU time {c:.1} ms per frame (all threads; 1-min load average {})",
            load.map_or("n/a".to_string(), |l| format!("{l:.2}"))
        );
    }
    println!(
        "  median phases: projection {:.1} ms, sorting {:.1} ms, binning {:.1} ms, blending {:.1} ms",
        ms(proj),
        ms(sort),
        ms(bin),
        ms(blend)
    );
    if s.culled_near_in_view > 0 {
        eprintln!(
            "warning: the near plane culled {} Gaussians inside the view (try a smaller --near)",
            s.culled_near_in_view
        );
    }
    Ok(())
}
