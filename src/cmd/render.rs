//! `splatbridge render`: render a scene with the native 3DGS splatting renderer (the reference
//! forward pass; knobs and their reference defaults in `splatbridge_hybrid::native`), or 2DGS
//! surfels with 2D Gaussian Splatting's own rasterizer (`splatbridge_hybrid::surfel2d`):
//! `--model auto` (the default) picks it for files read as 2DGS surfels, `--model 3dgs` forces
//! 3DGS splatting of their thin discs.
//!
//! Frames come from `splatbridge::pipeline::still` (`render_frame`: the composite plus declared weather
//! particles, one cloud per motion-blur sample, averaged; shadows and LiDAR are ray-traced
//! effects, listed as not simulated). This module parses the options and prints.

use std::path::{Path, PathBuf};

use anyhow::bail;
use serde_json::json;
use splatbridge::pipeline::sequence::SequenceFrame;
use splatbridge::pipeline::still::{check_image_output, Still};
use splatbridge::pipeline::{FrameStats, RenderedFrame};
use splatbridge_hybrid::RenderStats;
use splatbridge_scene::Camera;

use crate::cmd::common::{print_warning, CameraArgs};

pub use super::render_args::{model_is_2dgs, ModelArg, RenderKnobs};

#[derive(clap::Args)]
pub struct Args {
    #[arg(help = concat!("The scene: ", scene_formats!(), " (rendered as the composite at --time)."))]
    pub scene: PathBuf,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Scene time in seconds (default: the start of the scene's time range).
    #[arg(long, value_parser = super::ranges::time, allow_hyphen_values = true)]
    pub time: Option<f64>,
    /// Render every frame of the scene's time range to OUT_0000.ext, OUT_0001.ext, ….
    #[arg(long, conflicts_with = "time")]
    pub frames: bool,
    /// With --frames: render only shard I of N (0 ≤ I < N) of the frames and write a partial
    /// report.json beside them for `splatbridge merge` (see docs/scale.md).
    #[arg(long, value_name = "I/N", requires = "frames")]
    pub shard: Option<splatbridge::batch::shard::Shard>,
    #[command(flatten)]
    pub knobs: RenderKnobs,
    /// Drop invalid Gaussians (NaN, zero quaternion) with a counted warning instead of failing.
    #[arg(long)]
    pub drop_invalid: bool,
    /// Output image: .png (8-bit RGB) or .exr (float RGBA and Z depth).
    #[arg(short, long, alias = "output")]
    pub out: PathBuf,
    /// Print one JSON object (knobs, per-frame stats, effect counters) instead of the summary.
    #[arg(long)]
    pub json: bool,
}

/// The stats of a render as JSON (times in milliseconds).
pub fn stats_json(s: &RenderStats) -> serde_json::Value {
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    json!({
        "gaussians": s.gaussians,
        "projected": s.projected,
        "culled_near": s.culled_near,
        "culled_near_in_view": s.culled_near_in_view,
        "culled_behind": s.culled_behind,
        "culled_transparent": s.culled_transparent,
        "culled_degenerate": s.culled_degenerate,
        "culled_offscreen": s.culled_offscreen,
        "tile_pairs": s.tile_pairs,
        "blends": s.blends,
        "milliseconds": {
            "total": ms(s.times.total()),
            "projection": ms(s.times.projection),
            "sorting": ms(s.times.sorting),
            "binning": ms(s.times.binning),
            "blending": ms(s.times.blending),
        },
    })
}

/// Print what a render did; warn when the near plane removed Gaussians inside the view.
pub fn print_summary(cam: &Camera, stats: &RenderStats, near: f32) {
    let t = &stats.times;
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    println!(
        "  camera '{}' {}×{}; {} Gaussians, {} projected; culled: {} near, {} behind, {} transparent, {} off-screen, {} degenerate",
        cam.name,
        cam.width,
        cam.height,
        stats.gaussians,
        stats.projected,
        stats.culled_near,
        stats.culled_behind,
        stats.culled_transparent,
        stats.culled_offscreen,
        stats.culled_degenerate
    );
    println!(
        "  {} tile–Gaussian pairs, {} pixel–Gaussian blends; {:.1} ms (projection {:.1}, sorting {:.1}, binning {:.1}, blending {:.1})",
        stats.tile_pairs,
        stats.blends,
        ms(t.total()),
        ms(t.projection),
        ms(t.sorting),
        ms(t.binning),
        ms(t.blending)
    );
    warn_near(stats, near);
}

/// Warn when the near plane removed Gaussians that project inside the view.
pub fn warn_near(stats: &RenderStats, near: f32) {
    if stats.culled_near_in_view > 0 {
        eprintln!(
            "warning: the near plane (z ≤ {near}) culled {} Gaussians that project inside the view; \
             the scene may be small in world units (try a smaller --near)",
            stats.culled_near_in_view
        );
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    check_image_output(&args.out)?;
    let still = Still::load(
        &args.scene,
        args.drop_invalid,
        &print_warning,
        &|| args.camera.request(),
        args.time,
        args.frames,
    )?;
    let (name, cam, near) = (&still.name, &still.camera, args.knobs.near);
    let surfels = args.knobs.surfels_2d(still.kind, name)?;
    let mut renderer = args.knobs.renderer(still.kind, name)?;
    let model = if surfels { "2dgs" } else { "3dgs" };
    if !args.json {
        println!("render {name} ({model}): {}", args.knobs.describe());
    }
    let mut frames_json = Vec::with_capacity(still.times.len());
    let mut print_frame = |out: &Path, t: f64, r: &RenderedFrame| -> anyhow::Result<()> {
        let FrameStats::Native(stats) = &r.stats else {
            bail!("{name}: native splatting returned another renderer's stats");
        };
        if args.json {
            frames_json.push(json!({
                "output": out.display().to_string(),
                "time": t,
                "time_samples": r.time_samples,
                "stats": stats_json(stats),
            }));
            warn_near(stats, near);
        } else {
            if r.time_samples > 1 {
                println!(
                    "{} (t = {t}, {} motion-blur samples blended; stats summed over them)",
                    out.display(),
                    r.time_samples
                );
            } else {
                println!("{} (t = {t})", out.display());
            }
            print_summary(cam, stats, near);
        }
        Ok(())
    };
    let counters = if args.frames {
        // A `--frames` sequence appears together or not at all (and never half old, half new).
        let canonical = format!(
            "render\ncamera={:?}\nknobs={}\ndrop_invalid={}\nout={:?}",
            cam,
            args.knobs.describe(),
            args.drop_invalid,
            args.out.file_name()
        );
        let mut on_frame = |f: &SequenceFrame| print_frame(&f.path, f.time, f.rendered);
        let run = still.render_frames(
            &mut renderer,
            &args.out,
            "render",
            args.shard,
            canonical,
            &mut on_frame,
        )?;
        run.counters
    } else {
        let r = still.render_one(&mut renderer, &args.out)?;
        print_frame(&args.out, still.times[0], &r)?;
        r.counters
    };
    if args.json {
        let report = json!({
            "command": "render",
            "scene": name,
            "camera": {"name": cam.name, "width": cam.width, "height": cam.height},
            "model": model,
            "knobs": args.knobs.to_json(),
            "frames": frames_json,
            "effects": serde_json::to_value(&counters)?,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("{}", counters.summary());
    }
    Ok(())
}
