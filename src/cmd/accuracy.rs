//! `splatbridge accuracy`: sweep the named knobs one at a time around the defaults and measure
//! error against the reference (native splatting, reference settings) and time
//! (`splatbridge::measure::accuracy`). Writes `accuracy.json`, `accuracy.md` and plots of PSNR against
//! time and against triangles, with the Pareto front and the MeshSplats default marked.

use std::path::PathBuf;

use anyhow::Context;
use splatbridge::batch::merge::{self, PartialReport};
use splatbridge::batch::shard::{Shard, WorkKey};
use splatbridge::measure::accuracy::{
    commit_outputs, measure_setting, read_records, reference_frames, settings, Sweep,
};
use splatbridge::measure::parity::Placed;
use splatbridge::measure::report::Record;
use splatbridge_scene::{Camera, GaussianCloud};

use super::common;
use splatbridge::measure::compare::{parse_profiles, resolve_cameras};

#[derive(clap::Args)]
pub struct Args {
    #[arg(help = concat!("The scene: ", scene_formats!(), " (measured at --time)."))]
    pub scene: PathBuf,
    /// Cameras, comma-separated (as `compare --cameras`).
    #[arg(long, default_value = "orbit:3")]
    pub cameras: String,
    #[arg(long, default_value_t = 0.0, value_parser = super::ranges::time, allow_hyphen_values = true)]
    pub time: f64,
    #[arg(long, default_value_t = 320)]
    pub width: u32,
    #[arg(long, default_value_t = 240)]
    pub height: u32,
    /// Knob families to sweep (default: all): profile, segments, extent, k, native-extent,
    /// hybrid, blend (the hybrid's unsorted and sorted blend, with the default split and with
    /// no surfels), sh-degree, format (each splat file format's quantisation: the cloud written by
    /// our writer, read back and rendered natively), footprint (ray-traced Gaussians with the
    /// pixel footprint off/on), footprint-spp (the same at 4 samples per pixel),
    /// footprint-causes (native's hit order and SH direction on top, and the projected mode),
    /// footprint-default (only when named: `trace`'s default, footprint on with mean-depth
    /// order, alone),
    /// mesh-spp (the default profile's mesh traced at 1 and 4 samples per pixel), distill (only
    /// when named: each profile's mesh distilled at its defaults, 48 views over the view
    /// sphere, measured on held-back views of other elevations, distances and sizes
    /// (--distill-sizes) against the undistilled MeshSplats default and the profile's plain
    /// export; writes distill.md with worst and median per class).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Converter profiles the distill sweep fits (with `--only distill`), comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "meshsplats,rings,texture"
    )]
    pub distill_profiles: Vec<String>,
    /// Held-back image sizes of the distill rows, comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = super::convert::parse_wxh, default_value = "320x240,640x480")]
    pub distill_sizes: Vec<(u32, u32)>,
    /// Sizes the distilled exports are made for (default: 320×240 to 1920×1080).
    #[arg(long, value_delimiter = ',', value_parser = super::convert::parse_wxh)]
    pub distill_for: Vec<(u32, u32)>,
    /// Held-back views per class and size in the distill rows.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub distill_per_class: usize,
    /// Make the distilled meshes from the Gaussians widened for the fitting views (on), or
    /// as they are (off).
    #[arg(long, value_enum, default_value = "on")]
    pub distill_footprint: super::distill_args::OnOff,
    /// Report the undistilled export as the distilled one where the kept fit is below it at
    /// a validation view, as `convert --distill` writes it (on), or the kept fit (off).
    #[arg(long, value_enum, default_value = "on")]
    pub distill_floor: super::distill_args::OnOff,
    /// Which footprint of the views that see a Gaussian the distilled meshes widen it by
    /// (0 the smallest, 1 the largest).
    #[arg(long, value_name = "Q", default_value_t = splatbridge::distill::DistillOptions::default().footprint_quantile, value_parser = super::common::parse_unit)]
    pub distill_footprint_quantile: f64,
    /// What the distill rows' fits move: per-vertex or per-Gaussian colour and opacity.
    #[arg(long, value_enum, default_value = "vertex")]
    pub distill_params: super::distill_args::ParamsArg,
    /// Fitting views of the distill rows' fits at the sphere's fine end (nearest distance,
    /// largest size), after its 48.
    #[arg(long, value_name = "N", default_value_t = splatbridge::distill::run::ViewRequest::default().fit_fine)]
    pub distill_fit_fine: usize,
    /// Validation views of the distill rows' fits (the guard; 0: none, the last iteration
    /// is kept).
    #[arg(long, value_name = "N", default_value_t = splatbridge::distill::run::ViewRequest::default().validation)]
    pub distill_validation: usize,
    /// Validation views of the distill rows' fits at the fitting views' fine end (nearest
    /// distance, largest size), after the --distill-validation ones.
    #[arg(long, value_name = "N", default_value_t = splatbridge::distill::run::ViewRequest::default().validation_fine)]
    pub distill_validation_fine: usize,
    /// How far (dB) a validation view may fall below its start before the distill rows'
    /// guard refuses an iteration.
    #[arg(long, value_name = "DB", default_value_t = splatbridge::distill::DistillOptions::default().guard_tolerance_db, value_parser = super::common::parse_non_negative)]
    pub distill_guard_tolerance: f64,
    /// Native splatting's near plane for the distill rows' targets and held-back references
    /// (as `convert --distill-near`).
    #[arg(long, value_name = "Z", default_value_t = splatbridge::distill::DistillOptions::default().target_near, value_parser = super::common::parse_positive_f32)]
    pub distill_near: f32,
    /// Iterations of the distill rows' fits.
    #[arg(long, value_name = "K", default_value_t = splatbridge::distill::DistillOptions::default().iterations)]
    pub distill_iterations: usize,
    #[arg(long)]
    pub drop_invalid: bool,
    /// Re-draw the plots and table from OUT/accuracy.json without measuring again.
    #[arg(long)]
    pub replot: bool,
    /// Do only shard I of N (0 ≤ I < N) of the settings and write a partial report.json for
    /// `splatbridge merge` (see docs/scale.md).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<Shard>,
    /// With --split or --blend: one more row (family `hybrid`) with that split and blend
    /// (`--split auto` measures them on the scene first).
    #[command(flatten)]
    pub hybrid_split: super::split_args::SplitArgs,
    #[arg(short, long, alias = "output")]
    pub out: PathBuf,
}

fn print_records(records: &[Record]) {
    for r in records {
        println!(
            "{:14} {:28} PSNR {:7.2} dB  {:9.1} ms  {:>10} triangles",
            r.knob, r.value, r.psnr, r.milliseconds, r.triangles
        );
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // Options first: a bad one is reported before a large scene is loaded.
    let distill_profiles = parse_profiles(&args.distill_profiles)
        .map_err(|e| anyhow::anyhow!("--distill-profiles: {e}"))?;
    if args.replot {
        let records = read_records(&args.out)?;
        let what = format!("`{}` (re-plotted from accuracy.json)", args.scene.display());
        commit_outputs(&args.out, &what, &records)?;
        print_records(&records);
        println!("wrote {}", args.out.join("accuracy.md").display());
        return Ok(());
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create the output folder", args.out.display()))?;
    let scene = common::load(&args.scene, args.drop_invalid)?;
    let scene_hash = args.shard.map(|_| merge::scene_hash(&scene));
    // One cloud: a static scene's composite is its own cloud, handed over, not copied.
    let cams: Vec<Camera>;
    let cloud: GaussianCloud = if scene.objects.is_empty() {
        cams = resolve_cameras(
            &args.cameras,
            &scene.static_gaussians,
            &scene,
            args.width,
            args.height,
        )?;
        scene.into_composite(args.time)
    } else {
        let cloud = scene.composite(args.time);
        cams = resolve_cameras(&args.cameras, &cloud, &scene, args.width, args.height)?;
        cloud
    };
    // The sweep's exports read this scene in place (no copy of the cloud per export).
    let swept = splatbridge_scene::dynamic::DynamicScene::from_static(cloud);
    let cloud = &swept.static_gaussians;
    let refs = reference_frames(cloud, &cams)?;
    let sweep = Sweep {
        scene: &swept,
        cameras: &cams,
        references: &refs,
        time: args.time,
        work_dir: &args.out,
        drop_invalid: args.drop_invalid,
    };
    let mut settings = settings(&args.only);
    if args.hybrid_split.given() {
        let r = args
            .hybrid_split
            .resolve(|| cloud.clone(), Default::default())
            .with_context(|| args.scene.display().to_string())?;
        if let Some(a) = &r.auto {
            print!("{}", a.summary());
        }
        settings.push((
            "hybrid",
            args.hybrid_split.text(),
            splatbridge::measure::accuracy::Setting::HybridWith(r.params, r.ges),
            false,
        ));
    }
    let pb = common::progress(settings.len() as u64, "accuracy");
    let mut records = Vec::new();
    let mut placed = Vec::new();
    for (index, (family, value, setting, _baseline)) in settings.into_iter().enumerate() {
        if let (Some(shard), Some(hash)) = (args.shard, &scene_hash) {
            let key = WorkKey {
                scene: hash.clone(),
                time: args.time,
                camera: args.cameras.clone(),
                setting: format!("{index}:{family}:{value}"),
            };
            if !shard.owns(&key) {
                pb.inc(1);
                continue;
            }
        }
        pb.set_message(format!("{family} {value}"));
        let r = measure_setting(&sweep, index, family, &value, &setting)?;
        placed.push(Placed {
            order: [index as u64, 0, 0, 0],
            skipped: false,
            record: r.clone(),
        });
        records.push(r);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let curve = if args.only.iter().any(|o| o == "distill") {
        let it = args.distill_iterations;
        let cfg = splatbridge::measure::accuracy_distill::DistillSweep {
            profiles: distill_profiles,
            fit_sizes: args.distill_for.clone(),
            sizes: args.distill_sizes.clone(),
            per_class: args.distill_per_class.max(1),
            checkpoints: vec![0, it / 3, it],
            fit_fine: args.distill_fit_fine,
            validation: args.distill_validation,
            validation_fine: args.distill_validation_fine,
            options: splatbridge::distill::DistillOptions {
                iterations: it,
                footprint: args.distill_footprint == super::distill_args::OnOff::On,
                floor: args.distill_floor == super::distill_args::OnOff::On,
                footprint_quantile: args.distill_footprint_quantile,
                params: args.distill_params.mode(),
                guard_tolerance_db: args.distill_guard_tolerance,
                target_near: args.distill_near,
                ..Default::default()
            },
            ..Default::default()
        };
        let rows = splatbridge::measure::accuracy_distill::distill_rows(&sweep, &cfg)?;
        records.extend(rows.curve.iter().map(|p| p.record.clone()));
        Some(rows)
    } else {
        None
    };
    let what = format!(
        "`{}`: {} cameras at {}×{}, time {}",
        args.scene.display(),
        cams.len(),
        args.width,
        args.height,
        args.time
    );
    if let (Some(shard), Some(scene_hash)) = (args.shard, scene_hash) {
        let mut set = splatbridge_scene::output::OutputSet::new();
        let stage = set.stage_dir(&args.out)?;
        let options = format!(
            "accuracy\ncameras={}\ntime={}\nsize={}x{}\nonly={:?}\ndrop_invalid={}\nhybrid={}",
            args.cameras,
            args.time.to_bits(),
            args.width,
            args.height,
            args.only,
            args.drop_invalid,
            args.hybrid_split.text()
        );
        let report = PartialReport {
            format: merge::PARTIAL_FORMAT.into(),
            command: "accuracy".into(),
            version: env!("CARGO_PKG_VERSION").into(),
            scene_hash,
            options_hash: merge::options_hash(&options),
            shard,
            title: "Accuracy against cost".into(),
            preamble: what,
            files: Vec::new(),
            peak_memory_bytes: 0,
            records: placed,
        };
        merge::commit_shard(set, &stage, report)?;
        print_records(&records);
        println!(
            "shard {shard}: wrote {}",
            args.out.join(merge::REPORT).display()
        );
        return Ok(());
    }
    commit_outputs(&args.out, &what, &records)?;
    if let Some(pts) = curve {
        splatbridge::measure::accuracy_distill::write_curve(&args.out, &what, &pts)?;
        println!("wrote {}", args.out.join("distill.md").display());
    }
    print_records(&records);
    println!("wrote {}", args.out.join("accuracy.md").display());
    Ok(())
}
