//! `splatbridge bench hybrid`: the GES hybrid against the native renderer on the same scene,
//! camera and machine in one run.
//!
//! Both renderers get one untimed warm-up render, then `--repeat` timed renders; reported: the
//! median wall time of each (the hybrid's includes the split of the cloud into surfels and
//! Gaussians, done per frame as a viewer would for a scene loaded once: the split is reported
//! separately and is not in the render median), the speed ratio native/hybrid, and the PSNR
//! of the hybrid image against the native one (RGB clamped to [0, 1], data range 1). Then a
//! sweep of the two split thresholds (opacity A × flatness R) and of the pass knobs at the
//! default thresholds, each with its surfel count, median time and PSNR against native.
//!
//! The measuring is `splatbridge::measure::hybrid_bench`'s; this module prints.
//!
//! SCENE is a PLY or manifest, or `large:N` for the synthetic `large` fixture with N Gaussians.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use splatbridge::measure::hybrid_bench::{head_to_head, sweep, Row};
use splatbridge::pipeline::split_auto::{blend_name, describe_params, params_json};
use splatbridge_hybrid::RenderOptions;
use splatbridge_scene::metrics::psnr;
use splatbridge_scene::surfels::split;

use crate::cmd::common::{load, CameraArgs};
use crate::cmd::hybrid::HybridKnobs;

#[derive(clap::Args)]
pub struct Args {
    #[arg(help = concat!("The scene: ", scene_formats!(), "; or `large:N` (the synthetic large fixture with N Gaussians)."))]
    pub scene: String,
    #[command(flatten)]
    pub camera: CameraArgs,
    #[command(flatten)]
    pub knobs: HybridKnobs,
    /// Timed renders per configuration (after one warm-up).
    #[arg(long, alias = "repeats", default_value_t = 5)]
    pub repeat: usize,
    /// Timed renders per sweep setting.
    #[arg(long, default_value_t = 3)]
    pub sweep_repeat: usize,
    /// Skip the threshold sweep.
    #[arg(long)]
    pub no_sweep: bool,
    /// Opacity thresholds of the sweep (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "0.5,0.8,0.9,0.95,0.99")]
    pub sweep_opacity: Vec<f32>,
    /// Flatness thresholds of the sweep (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "0.1,0.2,0.3,0.5,1.0")]
    pub sweep_flatness: Vec<f32>,
    /// Skip the second threshold sweep with a 1.41σ surfel footprint.
    #[arg(long)]
    pub no_footprint_sweep: bool,
    /// Also print the results as one JSON object.
    #[arg(long)]
    pub json: bool,
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let cloud = if let Some(n) = args.scene.strip_prefix("large:") {
        let n: usize = n
            .parse()
            .with_context(|| format!("'{}': large:N needs a count", args.scene))?;
        splatbridge_scene::fixtures::large(n, 1)
    } else {
        let path = PathBuf::from(&args.scene);
        let scene = load(&path, false)?;
        scene.composite(scene.time.start)
    };
    let mut cam_args = args.camera.clone();
    if cam_args.width.is_none() && cam_args.height.is_none() {
        cam_args.width = Some(1920);
        cam_args.height = Some(1080);
    }
    let cam = cam_args
        .resolve(&cloud, &[])
        .with_context(|| args.scene.clone())?;
    let (surfel_split, auto) = args.knobs.resolve_split(&cloud)?;
    let opts = args.knobs.options_for(auto.as_ref(), &surfel_split);
    opts.validate()?;
    let nopts = RenderOptions {
        near: opts.near,
        background: opts.background,
        sh_degree_cap: opts.sh_degree_cap,
        ..Default::default()
    };
    println!(
        "bench hybrid {}: {} Gaussians, camera '{}' {}×{}, {} threads, repeat {}",
        args.scene,
        cloud.len(),
        cam.name,
        cam.width,
        cam.height,
        rayon::current_num_threads(),
        args.repeat
    );

    if let Some(a) = &auto {
        print!("{}", a.summary());
    }
    let p = surfel_split.checked_params()?;
    let t0 = Instant::now();
    let (s, g) = split(&cloud, &p);
    let split_time = t0.elapsed();
    let h = head_to_head(&cloud, (&s, &g), &cam, &nopts, &opts, args.repeat)?;
    let (native, nstats, t_native) = (&h.native, &h.native_stats, h.native_time);
    let (hframe, hs, t_h) = (&h.hybrid, &h.hybrid_stats, h.hybrid_time);
    let nt = &nstats.times;
    println!(
        "native: {:.1} ms median (projection {:.1}, sorting {:.1}, binning {:.1}, blending {:.1}); {} tile pairs, {} blends",
        ms(t_native),
        ms(nt.projection),
        ms(nt.sorting),
        ms(nt.binning),
        ms(nt.blending),
        nstats.tile_pairs,
        nstats.blends
    );

    let ht = &hs.times;
    let hpsnr = psnr(hframe, native)?;
    println!(
        "hybrid ({}; {}): {} surfels, {} Gaussians; split {:.1} ms",
        describe_params(&p),
        args.knobs.describe(),
        s.len(),
        g.len(),
        ms(split_time)
    );
    println!(
        "hybrid: {:.1} ms median (surfels {:.1}, projection {:.1}, binning {:.1}, blending {:.1}); {} tile pairs kept, {} culled, {} blends, {} Gaussians sorted",
        ms(t_h),
        ms(ht.surfels),
        ms(ht.projection),
        ms(ht.binning),
        ms(ht.blending),
        hs.tile_pairs,
        hs.culled_pairs,
        hs.blends,
        hs.sorted
    );
    let ratio = t_native.as_secs_f64() / t_h.as_secs_f64();
    println!("speed ratio native/hybrid: {ratio:.2}×; PSNR hybrid vs native: {hpsnr:.2} dB");

    let mut rows = Vec::new();
    if !args.no_sweep {
        println!("\nsweep (PSNR against native; time is the render median, split excluded):");
        println!(
            "{:<34} {:>9} {:>10} {:>9} {:>8} {:>12}",
            "setting", "surfels", "Gaussians", "ms", "PSNR dB", "pairs culled"
        );
        let mut push = |r: Row| {
            println!(
                "{:<34} {:>9} {:>10} {:>9.1} {:>8.2} {:>12}",
                r.label, r.surfels, r.gaussians, r.ms, r.psnr, r.stats.culled_pairs
            );
            rows.push(r);
        };
        sweep(
            &cloud,
            &p,
            &cam,
            &opts,
            native,
            (&args.sweep_opacity, &args.sweep_flatness),
            args.sweep_repeat,
            &mut push,
        )?;
    }
    if args.json {
        let sweep: Vec<serde_json::Value> = rows
            .iter()
            .map(|r| {
                serde_json::json!({
                    "setting": r.label, "surfels": r.surfels, "gaussians": r.gaussians,
                    "ms": r.ms, "psnr_db": r.psnr, "culled_pairs": r.stats.culled_pairs,
                })
            })
            .collect();
        let v = serde_json::json!({
            "scene": args.scene, "gaussians": cloud.len(), "width": cam.width, "height": cam.height,
            "threads": rayon::current_num_threads(),
            "native_ms": ms(t_native), "hybrid_ms": ms(t_h), "split_ms": ms(split_time),
            "speed_ratio": ratio, "psnr_db": hpsnr, "surfels": s.len(),
            "blend": blend_name(opts.blend), "sorted": hs.sorted,
            "native_blends": nstats.blends, "hybrid_blends": hs.blends,
            "hybrid_tile_pairs": hs.tile_pairs,
            "min_opacity": p.min_opacity, "max_flatness": p.max_flatness,
            "split_params": params_json(&p),
            "split_auto": auto.as_ref().map(|a| a.to_json()),
            "sweep": sweep,
        });
        println!("{v}");
    }
    Ok(())
}
