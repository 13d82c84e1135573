//! `splatbridge demo`: the first run (`splatbridge::demo`). The shipped real capture converted
//! and rendered every way, measured against native splatting, with one picture and a table of
//! which export to use for which viewer; then the built-in street for the dynamic part.

use std::path::PathBuf;
use std::time::Instant;

use splatbridge::demo::{self, CaptureConfig, DemoConfig, StreetConfig};

use super::common;

#[derive(clap::Args)]
pub struct Args {
    /// Output folder.
    #[arg(short, long, alias = "output", default_value = "out/demo")]
    pub out: PathBuf,
    /// The capture to run on (any splat format; default: the shipped `fourth_st.spz`).
    #[arg(long)]
    pub capture: Option<PathBuf>,
    /// Image width of the capture's views (the distillation is fitted at this size).
    #[arg(long, default_value_t = 160, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub width: u32,
    /// Image height of the capture's views.
    #[arg(long, default_value_t = 120, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub height: u32,
    /// Views measured (half-way between fitting views; the first is the picture's).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u64).range(1..=64))]
    pub views: u64,
    /// Fitting views of the distillation (`orbit:N`).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub fit_views: u64,
    /// Adam steps of the distillation.
    #[arg(long, default_value_t = 15, value_parser = clap::value_parser!(u64).range(0..=100_000))]
    pub iterations: u64,
    /// Leave out the street scene (the dynamic part).
    #[arg(long)]
    pub no_street: bool,
    /// Seed of the street scene.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let defaults = CaptureConfig::default();
    let cfg = DemoConfig {
        capture: CaptureConfig {
            input: args.capture.unwrap_or(defaults.input),
            width: args.width,
            height: args.height,
            views: args.views as usize,
            fit_views: args.fit_views as usize,
            iterations: args.iterations as usize,
            ..defaults
        },
        street: (!args.no_street).then(|| StreetConfig {
            seed: args.seed,
            ..StreetConfig::default()
        }),
    };
    let pb = common::progress(0, "demo");
    let run = demo::run(&cfg, &args.out, &|m| pb.set_message(m.to_string()));
    pb.finish_and_clear();
    let run = run?;
    println!("{}", run.stages.markdown());
    for o in &run.capture.outputs {
        let size = o
            .bytes
            .map_or(String::new(), |b| format!(", {}", demo::report::size(b)));
        println!(
            "{:<40} mean PSNR {}{size}",
            o.title,
            demo::report::db(o.mean_psnr())
        );
    }
    println!(
        "demo finished in {:.1} s: {} (report), {} (picture)",
        t0.elapsed().as_secs_f64(),
        run.report.display(),
        run.picture.display(),
    );
    Ok(())
}
