//! `splatbridge bench distill`: what distillation's set-up and each Adam step cost, at
//! `convert --distill`'s defaults or the given views, profile and hit memory, with the counters
//! that explain them (hits a pixel, views kept and streamed, hit-list memory; peak memory is
//! printed by `bench` itself). Only the fit is timed: no validation, held-back views or export.

use std::path::PathBuf;
use std::time::Instant;

use splatbridge::distill::run::{fitting_times, resolve_views, ViewRequest};
use splatbridge::distill::{DistillOptions, Distiller};

use crate::cmd::convert::ProfileArg;
use crate::cmd::{common, distill_args};

#[derive(clap::Args)]
pub struct Args {
    #[arg(help = concat!("The scene to distil: ", scene_formats!(), "."))]
    pub scene: PathBuf,
    /// Meshing profile (texture: `convert`'s default for glTF).
    #[arg(long, value_enum, default_value = "texture")]
    pub profile: ProfileArg,
    /// Fitting views, as `convert --views` (auto: the scene's cameras, else sphere:48).
    #[arg(long, default_value = "auto")]
    pub views: String,
    /// The fitting window's width and height, as `convert --distill-width/--distill-height`.
    #[arg(long, default_value_t = ViewRequest::default().width)]
    pub width: u32,
    #[arg(long, default_value_t = ViewRequest::default().height)]
    pub height: u32,
    /// Adam steps timed (the median is reported).
    #[arg(long, default_value_t = 10)]
    pub steps: usize,
    /// Memory for the views' hit lists, GB, as `convert --distill-memory`.
    #[arg(long, value_name = "GB", default_value_t = distill_args::default_memory_gb(), value_parser = common::parse_non_negative)]
    pub memory: f64,
    /// Transmittance hits are recorded down to, as `convert --distill-record-transmittance`.
    #[arg(long, value_name = "T", default_value_t = DistillOptions::default().record_transmittance, value_parser = common::parse_transmittance)]
    pub record_transmittance: f32,
}

/// `convert`'s own command line, to take its export options exactly as it does.
#[derive(clap::Parser)]
struct ConvertLine {
    #[command(flatten)]
    args: crate::cmd::convert::Args,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // The mesh `convert SCENE --profile P -o OUT.glb` would export (its layout, up axis,
    // coplanar step): the options the distiller of `convert --distill` gets.
    let mut line = <ConvertLine as clap::Parser>::try_parse_from([
        "convert".as_ref(),
        args.scene.as_os_str(),
        "-o".as_ref(),
        "bench.glb".as_ref(),
    ] as [&std::ffi::OsStr; 4])?;
    line.args.profile = Some(args.profile);
    let req = line.args.request()?;
    let input = req.load(&common::print_warning)?;
    let scene = input.scene;
    let convert = req.mesh_options(&scene, input.kind)?;
    // As `convert --views auto`: a 3DGS `cameras.json` beside the input when the scene has none.
    let cameras = splatbridge::distill::run::cameras_beside(&args.views, &scene, &args.scene)?;
    let req = ViewRequest {
        spec: args.views.clone(),
        width: args.width,
        height: args.height,
        cameras,
        ..ViewRequest::default()
    };
    let time = scene.time.start;
    let views = resolve_views(&scene, time, &req)
        .map_err(|e| anyhow::anyhow!("--views {}: {e}", args.views))?;
    let opts = DistillOptions {
        time,
        times: fitting_times(&scene, req.times),
        hit_budget: distill_args::memory_bytes(args.memory),
        record_transmittance: args.record_transmittance,
        ..DistillOptions::default()
    };
    let t = Instant::now();
    let (mut d, _) = Distiller::for_windows(
        &scene,
        &convert,
        &views.fit.windows,
        &views.fit.frames,
        &opts,
    )?;
    let setup = t.elapsed().as_secs_f64();
    let mut steps = Vec::with_capacity(args.steps);
    for _ in 0..args.steps {
        let t = Instant::now();
        d.step()?;
        steps.push(t.elapsed().as_secs_f64());
    }
    let r = d.report();
    let pixels: u64 = views
        .fit
        .windows
        .iter()
        .map(|c| c.width as u64 * c.height as u64)
        .sum();
    println!(
        "{}: {} fitting windows {}×{} ('{}'), profile {}, {} vertices, {} threads",
        args.scene.display(),
        r.views,
        r.width,
        r.height,
        views.spec,
        clap::ValueEnum::to_possible_value(&args.profile)
            .map_or_else(String::new, |v| v.get_name().to_string()),
        r.vertices,
        rayon::current_num_threads()
    );
    println!(
        "set-up {setup:.2} s: the mesh {:.2} s (widening, the export in memory, its BVH), native targets {:.2} s, hit recording {:.2} s",
        setup - r.setup_targets_seconds - r.setup_record_seconds,
        r.setup_targets_seconds,
        r.setup_record_seconds
    );
    println!(
        "hits {} ({:.1} a pixel): {} views kept, {} streamed, {:.0} MB of hit lists",
        r.hits,
        r.hits as f64 / pixels.max(1) as f64,
        r.stored_views,
        r.streamed_views,
        r.hit_bytes as f64 / 1e6
    );
    if !steps.is_empty() {
        let mut sorted = steps.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        let iterations = DistillOptions::default().iterations;
        println!(
            "step ({} views): median {median:.3} s, min {:.3} s over {} steps, loss {:.4} → {:.4}; {iterations} steps (convert's default) ≈ {:.1} s",
            d.batch(0).len(),
            sorted[0],
            steps.len(),
            r.loss_first,
            r.loss_last,
            setup + iterations as f64 * median
        );
    }
    Ok(())
}
