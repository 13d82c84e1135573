//! `splatbridge hybrid`: render with the GES-style hybrid (opaque surfels through a z-buffer,
//! then the residual Gaussians, unsorted or with `--blend sorted` in native's order;
//! `splatbridge_hybrid::ges`). Surfels come from a split
//! of the trained cloud by opacity and flatness, or from a GES PLY's own flags.
//!
//! The frame comes from `splatbridge::pipeline::still` (`render_frame` (the composite plus declared
//! weather particles; with `motion_blur`, one cloud per shutter sample, each split and
//! rendered, then averaged; shadows and LiDAR listed as not simulated). This module parses the
//! options ([`knobs`]) and prints.

mod knobs;

use std::path::PathBuf;

use anyhow::{bail, Context};
use serde_json::json;
use splatbridge::pipeline::split_auto::{blend_name, AutoChoice};
use splatbridge::pipeline::still::{check_image_output, Still};
use splatbridge::pipeline::{FrameStats, Renderer};
use splatbridge_hybrid::ges::{GesOptions, GesStats};
use splatbridge_scene::Camera;

pub use knobs::*;

use crate::cmd::common::short;
use crate::cmd::common::{print_warning, CameraArgs};

#[derive(clap::Args)]
pub struct Args {
    #[arg(help = concat!("The scene: ", scene_formats!(), "; or a GES PLY (composite at --time)."))]
    pub scene: PathBuf,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Scene time in seconds (default: the start of the scene's time range).
    #[arg(long, value_parser = super::ranges::time, allow_hyphen_values = true)]
    pub time: Option<f64>,
    #[command(flatten)]
    pub knobs: HybridKnobs,
    /// Drop invalid Gaussians (NaN, zero quaternion) with a counted warning instead of failing.
    #[arg(long)]
    pub drop_invalid: bool,
    /// Output image: .png (8-bit RGB) or .exr (float RGBA and Z depth).
    #[arg(short, long, alias = "output")]
    pub out: PathBuf,
    /// Print one JSON object (knobs, stats, effect counters) instead of the summary.
    #[arg(long)]
    pub json: bool,
}

/// The stats of a hybrid render as JSON (times in milliseconds).
pub fn stats_json(s: &GesStats, split_ms: f64) -> serde_json::Value {
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    json!({
        "surfels": s.surfels,
        "surfels_drawn": s.surfels_drawn,
        "surfel_pairs": s.surfel_pairs,
        "gaussians": s.gaussians,
        "projected": s.projected,
        "tile_pairs": s.tile_pairs,
        "culled_pairs": s.culled_pairs,
        "blends": s.blends,
        "sorted": s.sorted,
        "milliseconds": {
            "total": split_ms + ms(s.times.total()),
            "split": split_ms,
            "surfels": ms(s.times.surfels),
            "projection": ms(s.times.projection),
            "binning": ms(s.times.binning),
            "blending": ms(s.times.blending),
        },
    })
}

/// Print what a hybrid render did.
pub fn print_summary(cam: &Camera, stats: &GesStats, split_ms: f64) {
    let t = &stats.times;
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    println!(
        "  camera '{}' {}×{}; {} surfels ({} drawn, {} surfel–tile pairs), {} Gaussians ({} projected)",
        cam.name, cam.width, cam.height, stats.surfels, stats.surfels_drawn, stats.surfel_pairs, stats.gaussians, stats.projected
    );
    println!(
        "  {} tile–Gaussian pairs kept, {} culled behind surfels, {} pixel–Gaussian blends",
        stats.tile_pairs, stats.culled_pairs, stats.blends
    );
    println!(
        "  {:.1} ms (split {:.1}; surfels {:.1}, projection {:.1}, binning {:.1}, blending {:.1})",
        split_ms + ms(t.total()),
        split_ms,
        ms(t.surfels),
        ms(t.projection),
        ms(t.binning),
        ms(t.blending)
    );
}

/// The knobs as JSON with the blend and footprint the render used (chosen by `--split auto`
/// or the input's kind when not given).
fn used_knobs(knobs: &HybridKnobs, opts: &GesOptions) -> serde_json::Value {
    let mut j = knobs.to_json();
    j["blend"] = json!(blend_name(opts.blend));
    j["footprint"] = json!(short(opts.footprint_sigmas));
    j
}

pub fn run(args: Args) -> anyhow::Result<()> {
    check_image_output(&args.out)?;
    let still = Still::load(
        &args.scene,
        args.drop_invalid,
        &print_warning,
        &|| args.camera.request(),
        args.time,
        false,
    )?;
    let (name, cam, t) = (&still.name, &still.camera, still.times[0]);
    let (split, auto) = args
        .knobs
        .resolve_split(&still.scene.composite(t))
        .with_context(|| name.clone())?;
    let opts = args.knobs.options_for(auto.as_ref(), &split);
    let mut renderer = Renderer::hybrid(opts, split)?;
    let r = still.render_one(&mut renderer, &args.out)?;
    let FrameStats::Hybrid {
        stats,
        split_ms,
        surfels_by: how,
    } = &r.stats
    else {
        bail!("{name}: the hybrid returned another renderer's stats");
    };
    if args.json {
        let report = json!({
            "command": "hybrid",
            "scene": name,
            "output": args.out.display().to_string(),
            "time": t,
            "time_samples": r.time_samples,
            "surfels_by": how,
            "split_auto": auto.as_ref().map(AutoChoice::to_json),
            "camera": {"name": cam.name, "width": cam.width, "height": cam.height},
            "knobs": used_knobs(&args.knobs, &opts),
            "stats": stats_json(stats, *split_ms),
            "effects": serde_json::to_value(&r.counters)?,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    if let Some(a) = &auto {
        print!("{}", a.summary());
    }
    println!("hybrid {name}: surfels by {how}; {}", args.knobs.describe());
    if r.time_samples > 1 {
        println!(
            "{} (t = {t}, {} motion-blur samples blended; stats summed over them)",
            args.out.display(),
            r.time_samples
        );
    } else {
        println!("{} (t = {t})", args.out.display());
    }
    print_summary(cam, stats, *split_ms);
    println!("{}", r.counters.summary());
    Ok(())
}
