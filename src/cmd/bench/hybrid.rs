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
//! SCENE is a PLY or manifest, or `large:N` for the synthetic `large` fixture with N Gaussians.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use splatbridge_hybrid::ges::{render_ges, Blend, GesOptions, GesStats};
use splatbridge_hybrid::{render, RenderOptions};
use splatbridge_scene::metrics::psnr;
use splatbridge_scene::surfels::{split, SplitParams};
use splatbridge_scene::{Frame, GaussianCloud};

use crate::cmd::common::{load, CameraArgs};
use crate::cmd::hybrid::HybridKnobs;

#[derive(clap::Args)]
pub struct Args {
    /// A PLY or manifest, or `large:N` (the synthetic large fixture with N Gaussians).
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

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Median time of `repeat` runs of `f` after one warm-up; returns the last output.
fn timed<T>(
    repeat: usize,
    mut f: impl FnMut() -> anyhow::Result<T>,
) -> anyhow::Result<(Duration, T)> {
    let mut out = f()?;
    let mut times = Vec::with_capacity(repeat);
    for _ in 0..repeat.max(1) {
        let t0 = Instant::now();
        out = f()?;
        times.push(t0.elapsed());
    }
    Ok((median(times), out))
}

struct Row {
    label: String,
    surfels: usize,
    gaussians: usize,
    ms: f64,
    psnr: f64,
    stats: GesStats,
}

fn hybrid_row(
    label: String,
    cloud: &GaussianCloud,
    p: &SplitParams,
    cam: &splatbridge_scene::Camera,
    opts: &GesOptions,
    native: &Frame,
    repeat: usize,
) -> anyhow::Result<Row> {
    let (s, g) = split(cloud, p);
    let (t, (frame, stats)) = timed(repeat, || Ok(render_ges(&s, &g, cam, opts)?))?;
    Ok(Row {
        label,
        surfels: s.len(),
        gaussians: g.len(),
        ms: ms(t),
        psnr: psnr(&frame, native)?,
        stats,
    })
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
    // Native and hybrid renders alternate, so load from other processes hits both alike.
    let (mut native, mut nstats) = render(&cloud, &cam, &nopts)?;
    let (mut hframe, mut hs) = render_ges(&s, &g, &cam, &opts)?;
    let (mut tn, mut th) = (Vec::new(), Vec::new());
    for _ in 0..args.repeat.max(1) {
        let t0 = Instant::now();
        (native, nstats) = render(&cloud, &cam, &nopts)?;
        tn.push(t0.elapsed());
        let t0 = Instant::now();
        (hframe, hs) = render_ges(&s, &g, &cam, &opts)?;
        th.push(t0.elapsed());
    }
    let (t_native, t_h) = (median(tn), median(th));
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
    let hpsnr = psnr(&hframe, &native)?;
    println!(
        "hybrid ({}; {}): {} surfels, {} Gaussians; split {:.1} ms",
        splatbridge::pipeline::split_auto::describe_params(&p),
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
        let none = SplitParams::none();
        push(hybrid_row(
            "no surfels (pass 2 only)".into(),
            &cloud,
            &none,
            &cam,
            &opts,
            &native,
            args.sweep_repeat,
        )?);
        for &a in &args.sweep_opacity {
            for &r in &args.sweep_flatness {
                let sp = SplitParams {
                    min_opacity: a,
                    max_flatness: r,
                    ..p
                };
                push(hybrid_row(
                    format!("A={a} R={r}"),
                    &cloud,
                    &sp,
                    &cam,
                    &opts,
                    &native,
                    args.sweep_repeat,
                )?);
            }
        }
        // The other surfel footprint than the one benchmarked: GES's rim or the √2σ disc.
        let (fp_label, fp) = if opts.footprint_sigmas == std::f32::consts::SQRT_2 {
            (
                "defaults, footprint 3.33σ",
                splatbridge_scene::surfels::FOOTPRINT_SIGMAS,
            )
        } else {
            ("defaults, footprint 1.41σ", std::f32::consts::SQRT_2)
        };
        let other = match opts.blend {
            Blend::Sorted => ("defaults, unsorted blend", Blend::Unsorted),
            Blend::Unsorted => ("defaults, sorted blend", Blend::Sorted),
        };
        let variants: [(&str, GesOptions); 7] = [
            (
                other.0,
                GesOptions {
                    blend: other.1,
                    ..opts
                },
            ),
            (
                fp_label,
                GesOptions {
                    footprint_sigmas: fp,
                    ..opts
                },
            ),
            ("defaults, blur on", GesOptions { blur: true, ..opts }),
            (
                "defaults, supersample 4",
                GesOptions {
                    supersample: 4,
                    ..opts
                },
            ),
            (
                "defaults, ε factor 2",
                GesOptions {
                    epsilon_factor: 2.0,
                    ..opts
                },
            ),
            (
                "defaults, ε factor 10",
                GesOptions {
                    epsilon_factor: 10.0,
                    ..opts
                },
            ),
            (
                "defaults, ε factor 0",
                GesOptions {
                    epsilon_factor: 0.0,
                    ..opts
                },
            ),
        ];
        for (label, o) in variants {
            push(hybrid_row(
                label.into(),
                &cloud,
                &p,
                &cam,
                &o,
                &native,
                args.sweep_repeat,
            )?);
        }
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
            "blend": splatbridge::pipeline::split_auto::blend_name(opts.blend), "sorted": hs.sorted,
            "native_blends": nstats.blends, "hybrid_blends": hs.blends,
            "hybrid_tile_pairs": hs.tile_pairs,
            "min_opacity": p.min_opacity, "max_flatness": p.max_flatness,
            "split_params": splatbridge::pipeline::split_auto::params_json(&p),
            "split_auto": auto.as_ref().map(|a| a.to_json()),
            "sweep": sweep,
        });
        println!("{v}");
    }
    Ok(())
}
