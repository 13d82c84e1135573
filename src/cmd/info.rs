//! `splatbridge info`: describe any scene file (every splat format, or a manifest) with
//! `splatbridge::measure::describe`, as text or one JSON object.

use std::path::PathBuf;

use serde_json::Value;
use splatbridge::measure::describe::{QUANTILES, ROBUST_P, TINY_LOG_SCALE};

use crate::cmd::common::load_with_info;

#[derive(clap::Args)]
pub struct Args {
    #[arg(help = concat!("The scene: ", scene_formats!(), "; the format is recognised by content."))]
    pub file: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Drop invalid Gaussians (NaN, zero quaternion) with a counted warning instead of failing.
    #[arg(long)]
    pub drop_invalid: bool,
    /// Also report the spatial blocks (the tiles of `convert --tiles`): counts, depths, bounds.
    #[arg(long)]
    pub blocks: bool,
    /// Gaussian budget of a block (with --blocks).
    #[arg(long, value_name = "N", requires = "blocks", value_parser = clap::value_parser!(u32).range(1..=16_777_216))]
    pub max_gaussians_per_tile: Option<u32>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (scene, info) = load_with_info(&args.file, args.drop_invalid)?;
    let mut out = splatbridge::measure::describe::describe(&args.file, &scene, &info);
    if args.blocks {
        let n = args
            .max_gaussians_per_tile
            .map_or(splatbridge_scene::blocks::DEFAULT_MAX_PER_BLOCK, |n| {
                n as usize
            });
        // The cloud `convert --tiles` partitions: objects placed at the scene's start.
        let cloud = scene.composite_view(scene.time.start);
        out["blocks"] = splatbridge_scene::blocks::Blocks::build(&cloud, n).summary();
    }
    if args.json {
        println!("{out}");
    } else {
        print_text(&out);
        if args.blocks {
            print_blocks(&out["blocks"]);
        }
    }
    Ok(())
}

fn fmt3(v: &Value) -> String {
    match v.as_array() {
        Some(a) => {
            let s: Vec<String> = a
                .iter()
                .map(|x| format!("{:.6}", x.as_f64().unwrap_or(f64::NAN)))
                .collect();
            format!("({})", s.join(", "))
        }
        None => "-".into(),
    }
}

fn fmt_dist(v: &Value) -> String {
    if v.is_null() {
        return "-".into();
    }
    QUANTILES
        .iter()
        .map(|(name, _)| format!("{name} {:.4e}", v[*name].as_f64().unwrap_or(f64::NAN)))
        .collect::<Vec<_>>()
        .join("  ")
}

fn print_text(v: &Value) {
    println!(
        "file        {} ({})",
        v["file"].as_str().unwrap_or("?"),
        v["kind"].as_str().unwrap_or("?")
    );
    println!(
        "format      {}",
        v["format"]["description"].as_str().unwrap_or("?")
    );
    println!(
        "quantised   {}",
        v["format"]["quantisation"].as_str().unwrap_or("?")
    );
    println!(
        "content     {}",
        v["format"]["content"].as_str().unwrap_or("?")
    );
    println!("gaussians   {}", v["gaussians"]);
    println!("SH degree   {}", v["sh_degree"]);
    println!(
        "bounds      min {}  max {}",
        fmt3(&v["bounds"]["min"]),
        fmt3(&v["bounds"]["max"])
    );
    println!(
        "robust      min {}  max {}  ({}–{} percentiles per axis)",
        fmt3(&v["robust_bounds"]["min"]),
        fmt3(&v["robust_bounds"]["max"]),
        ROBUST_P * 100.0,
        100.0 - ROBUST_P * 100.0
    );
    println!("opacity     {}", fmt_dist(&v["opacity"]));
    println!("scale max   {}", fmt_dist(&v["scale_max_axis"]));
    println!("scale min   {}", fmt_dist(&v["scale_min_axis"]));
    let u = &v["unusual"];
    println!(
        "unusual     {} +inf and {} −inf opacity logits, {} with opacity < 1/255, {} unnormalised quaternions, {} log-scales < {TINY_LOG_SCALE}, {} invalid",
        u["opacity_logit_pos_inf"],
        u["opacity_logit_neg_inf"],
        u["opacity_below_1_255"],
        u["unnormalised_quaternions"],
        u["tiny_log_scales"],
        u["invalid"]
    );
    if let Some(f) = v.get("four_d") {
        let t = &f["time"];
        println!(
            "4D          {}: {} s to {} s, {} frames at {} fps; at most {} Gaussians{}",
            f["form"].as_str().unwrap_or("?"),
            t["start"],
            t["end"],
            t["frames"],
            t["fps"],
            f["max_gaussians"],
            if f["same_count"] == true {
                " in every frame"
            } else {
                " (counts vary by frame)"
            }
        );
        let d = &f["displacement"];
        if d.is_null() {
            println!("motion      - (frames differ in count: no per-Gaussian trajectories)");
        } else {
            println!(
                "motion      per-Gaussian largest displacement from the start: median {:.4e}, p95 {:.4e}, max {:.4e}; {:.1} % move more than 1 % of the extent {:.4e}",
                d["median"].as_f64().unwrap_or(f64::NAN),
                d["p95"].as_f64().unwrap_or(f64::NAN),
                d["max"].as_f64().unwrap_or(f64::NAN),
                100.0 * d["moving_fraction"].as_f64().unwrap_or(f64::NAN),
                d["extent"].as_f64().unwrap_or(f64::NAN)
            );
        }
    }
    if v["kind"] == "manifest" {
        let t = &v["time"];
        println!(
            "time        {} s to {} s at {} fps: {} frames; {} cameras; effects {}",
            t["start"], t["end"], t["fps"], t["frames"], v["cameras"], v["effects"]
        );
        println!("static      {} Gaussians", v["static_gaussians"]);
        for o in v["objects"].as_array().into_iter().flatten() {
            println!(
                "object      {}: {} Gaussians (SH {}), {} keys spanning {}",
                o["name"].as_str().unwrap_or("?"),
                o["gaussians"],
                o["sh_degree"],
                o["keys"],
                o["track_span"]
            );
        }
    }
}

fn print_blocks(b: &Value) {
    println!(
        "blocks      {} blocks, {} leaves of at most {} Gaussians ({} over budget), depth {}",
        b["blocks"], b["leaves"], b["max_per_block"], b["leaves_over_budget"], b["max_depth"]
    );
    println!(
        "leaf size   min {}  median {}  max {}; leaves per depth {}",
        b["leaf_size"]["min"],
        b["leaf_size"]["median"],
        b["leaf_size"]["max"],
        b["leaves_per_depth"]
    );
    println!(
        "block cell  min {}  max {}",
        fmt3(&b["cell"]["min"]),
        fmt3(&b["cell"]["max"])
    );
    println!(
        "footprint   min {}  max {}  (3σ boxes of every Gaussian)",
        fmt3(&b["footprint"]["min"]),
        fmt3(&b["footprint"]["max"])
    );
}
