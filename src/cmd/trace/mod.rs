//! `splatbridge trace`: ray-trace an exported file (GLB/glTF/OBJ, rendered as a viewer shows
//! it), or a scene (PLY or manifest) converted in memory (mode `mesh`) or traced as Gaussians
//! (mode `gaussian`, 3DGRT-style), with the obvhs or Embree BVH backend.
//!
//! Files written by `splatbridge convert` carry a root node that maps the capture's up axis
//! onto glTF's +Y; by default that node is undone, so cameras (`orbit`, `cameras.json`,
//! `scene:I`) and renders live in the capture's frame like native renders. `--gltf-frame`
//! keeps the glTF world frame.
//!
//! Mode gaussian builds one BVH per part (static Gaussians, each object in its own frame, the
//! frame's weather particles) and poses the objects at each time (instancing, no rebuild).
//!
//! Loading, the frame and the sequence are `splatbridge::pipeline::trace_job`'s ([`input`]
//! describes the input as a `TraceSource`); this module parses the options and prints. Declared effects (the manifest's, or
//! `--effects-from MANIFEST`'s for an exported file, which carries none of its own) are
//! simulated: weather particles of the frame (mode gaussian:
//! a part of their own; mode mesh: converted in memory with the scene as one frame node),
//! motion blur (every shutter sample traced at its time and averaged), sun shadows
//! (`splatbridge_raytrace::shadows`) and LiDAR (one PLY per frame, `lidar_NNNN.ply` with NNNN
//! the frame index, in `--lidar-out`, by default the output image's directory). An exported
//! file's weather is drawn as exported (its per-frame particle nodes).

mod input;

use std::path::PathBuf;

use clap::ValueEnum;
use serde_json::json;
use splatbridge::pipeline::sequence::{SequenceFrame, SequenceRun};
use splatbridge::pipeline::trace_job::{run_trace, TraceJob, Traced};
use splatbridge::pipeline::Prepared;
use splatbridge_raytrace::{
    BackendKind, Compositing, Footprint, HitOrder, SampleFootprint, ShDirection,
};

pub use input::*;

use crate::cmd::common::print_warning;
use crate::cmd::common::short;

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub input: TraceInput,
    /// BVH backend (embree needs a build with `--features embree`).
    #[arg(long, value_enum, default_value_t = BackendArg::Obvhs)]
    pub backend: BackendArg,
    /// Output image (.png or .exr).
    #[arg(short, long = "out", alias = "output")]
    pub output: PathBuf,
    /// Directory for the LiDAR scans (`lidar_NNNN.ply`) when the scene declares `lidar`
    /// (default: the output image's directory).
    #[arg(long, value_name = "DIR")]
    pub lidar_out: Option<PathBuf>,
    /// Scan every frame of the scene's time range, not only the traced one.
    #[arg(long)]
    pub lidar_all_frames: bool,
    /// Trace every frame of the scene's time range to OUT_0000.ext, OUT_0001.ext, … (with the
    /// scene's LiDAR, one scan per frame); an exported file takes its time range from
    /// --effects-from.
    #[arg(long, conflicts_with_all = ["lidar_all_frames", "time"])]
    pub frames: bool,
    /// With --frames: trace only shard I of N (0 ≤ I < N) of the frames; with
    /// --lidar-all-frames: scan only that shard of the frames (the image is traced by every
    /// shard, identically). Either writes a partial report.json for `splatbridge merge` (see
    /// docs/scale.md).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<splatbridge::batch::shard::Shard>,
    /// Print one JSON object (options, stats, effect counters, LiDAR files) instead of the
    /// summary.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let name = args.input.input.display().to_string();
    let backend: BackendKind = args.backend.into();
    let job = TraceJob {
        source: args.input.source()?,
        backend,
        preset: args.input.preset.into(),
        output: args.output.clone(),
        lidar_out: args.lidar_out.clone(),
        lidar_all_frames: args.lidar_all_frames,
        frames: args.frames,
        shard: args.shard,
        canonical: format!(
            "input={:?}\nbackend={:?}\nout={:?}",
            args.input,
            args.backend,
            args.output.file_name()
        ),
    };
    let mut frames_json = Vec::new();
    let mut on_frame = |f: &SequenceFrame| -> anyhow::Result<()> {
        print_frame(&args, f, &mut frames_json);
        Ok(())
    };
    let image = match run_trace(&job, &print_warning, &mut on_frame)? {
        Traced::Frames { prepared, run } => {
            return print_frames(&args, &prepared, &run, frames_json)
        }
        Traced::Image(image) => *image,
    };
    let (p, r) = (image.prepared, image.rendered);
    let (build_seconds, lidar_dir) = (image.build_seconds, image.lidar_dir);
    let stats = r.stats.trace().cloned().unwrap_or_default();
    let (samples, lidar, exported_weather, counters) =
        (r.time_samples, r.lidar, r.exported_weather, r.counters);
    let blurred = samples > 1;

    if args.json {
        let report = json!({
            "command": "trace",
            "input": name,
            "output": args.output.display().to_string(),
            "mode": match args.input.mode {
                Mode::Mesh => "mesh",
                Mode::Gaussian => "gaussian",
            },
            "backend": backend.to_string(),
            "time": p.time,
            "time_samples": samples,
            "camera": {"name": p.camera.name, "width": p.camera.width, "height": p.camera.height},
            "options": {
                "k": p.options.k,
                "preset": args.input.preset.to_possible_value().map(|v| v.get_name().to_string()),
                "background": p.options.background.to_array().map(short),
                "near": short(p.options.near),
                "footprint": match p.options.footprint {
                    Footprint::Off => "off",
                    Footprint::On => "on",
                    Footprint::Projected => "projected",
                },
                "order": match p.options.order {
                    HitOrder::Hit => "hit",
                    HitOrder::MeanDepth => "mean-depth",
                },
                "sh_direction": match p.options.sh_direction {
                    ShDirection::Ray => "ray",
                    ShDirection::Mean => "mean",
                },
                "spp": p.options.spp,
                "sample_footprint": match p.options.sample_footprint {
                    SampleFootprint::Subpixel => "subpixel",
                    SampleFootprint::Pixel => "pixel",
                },
                "compositing": match p.options.compositing {
                    Compositing::Display => "display",
                    Compositing::Viewer => "viewer",
                },
            },
            "stats": {
                "what": p.what,
                "rays": stats.rays,
                "hits": stats.hits,
                "traversals": stats.traversals,
                "trace_seconds": stats.seconds,
                "build_seconds": build_seconds,
                "mrays_per_second": stats.mrays_per_second(),
                "hits_per_ray": stats.hits_per_ray(),
            },
            "lidar": lidar.as_ref().map(|r| json!({
                "dir": lidar_dir.display().to_string(),
                "files": r.files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
                "rays": r.rays,
                "points": r.points,
            })),
            "exported_weather": exported_weather,
            "effects": serde_json::to_value(&counters)?,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!("{}", p.what);
    println!(
        "{}: {}×{} camera '{}', backend {backend}, BVH build {:.3} s, trace {:.3} s ({:.2} Mrays/s), {:.2} hits/ray, {:.2} traversals/ray{}",
        args.output.display(),
        p.camera.width,
        p.camera.height,
        p.camera.name,
        build_seconds,
        stats.seconds,
        stats.mrays_per_second(),
        stats.hits_per_ray(),
        stats.traversals as f64 / stats.rays.max(1) as f64,
        if blurred {
            format!(" (over {samples} motion-blur samples, blended)")
        } else {
            String::new()
        }
    );
    if let Some(r) = &lidar {
        println!(
            "LiDAR: {} scan(s) in {}, {} rays → {} points",
            r.files.len(),
            lidar_dir.display(),
            r.rays,
            r.points
        );
    }
    if exported_weather {
        println!("weather: drawn as exported (the file's per-frame particle nodes)");
    }
    println!("{}", counters.summary());
    Ok(())
}

/// One frame of `trace --frames`, as it is staged: a line, or an entry of the JSON report.
fn print_frame(args: &Args, f: &SequenceFrame, frames_json: &mut Vec<serde_json::Value>) {
    let stats = f.rendered.stats.trace().cloned().unwrap_or_default();
    if args.json {
        frames_json.push(json!({
            "output": f.path.display().to_string(),
            "time": f.time,
            "time_samples": f.rendered.time_samples,
            "rays": stats.rays,
            "hits": stats.hits,
            "trace_seconds": stats.seconds,
            "lidar": f.lidar_files.iter().map(|l| l.display().to_string()).collect::<Vec<_>>(),
        }));
    } else {
        println!(
            "{} (t = {}): trace {:.3} s ({:.2} Mrays/s), {:.2} hits/ray{}{}",
            f.path.display(),
            f.time,
            stats.seconds,
            stats.mrays_per_second(),
            stats.hits_per_ray(),
            if f.rendered.time_samples > 1 {
                format!(", {} motion-blur samples", f.rendered.time_samples)
            } else {
                String::new()
            },
            match f.lidar_files.first() {
                Some(l) => format!(", LiDAR {}", l.display()),
                None => String::new(),
            }
        );
    }
}

/// The end of `trace --frames`: the JSON report, or the totals.
fn print_frames(
    args: &Args,
    p: &Prepared,
    run: &SequenceRun,
    frames_json: Vec<serde_json::Value>,
) -> anyhow::Result<()> {
    let name = args.input.input.display().to_string();
    let backend: BackendKind = args.backend.into();
    if args.json {
        let report = json!({
            "command": "trace",
            "input": name,
            "mode": match args.input.mode {
                Mode::Mesh => "mesh",
                Mode::Gaussian => "gaussian",
            },
            "backend": backend.to_string(),
            "camera": {"name": p.camera.name, "width": p.camera.width, "height": p.camera.height},
            "frames": frames_json,
            "frames_total": run.total,
            "effects": serde_json::to_value(&run.counters)?,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("{}", p.what);
        println!("{} of {} frames traced", run.frames, run.total);
        println!("{}", run.counters.summary());
    }
    Ok(())
}
