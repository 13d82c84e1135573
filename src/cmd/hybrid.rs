//! `splatbridge hybrid`: render with the GES-style hybrid (opaque surfels through a z-buffer,
//! then the residual Gaussians, unsorted or with `--blend sorted` in native's order;
//! `splatbridge_hybrid::ges`). Surfels come from a split
//! of the trained cloud by opacity and flatness, or from a GES PLY's own flags.
//!
//! The frame comes from `splatbridge::pipeline::render_frame` (the composite plus declared
//! weather particles; with `motion_blur`, one cloud per shutter sample, each split and
//! rendered, then averaged; shadows and LiDAR listed as not simulated). This module parses the
//! options and prints.

use std::path::PathBuf;

use anyhow::{bail, Context};
use serde_json::json;
use splatbridge::pipeline::{render_frame, FrameRequest, FrameStats, Renderer, SurfelSplit};
use splatbridge::pipeline::split_auto::{
    blend_name, choose, params_json, AutoChoice, AutoConfig, DEFAULT_BLEND, DEFAULT_MIN_PSNR,
    DISC_FOOTPRINT_SIGMAS,
};
use splatbridge_hybrid::ges::{Blend, GesOptions, GesStats};
use splatbridge_scene::effects_run::effects_of;
use splatbridge_scene::image_io::save_frame;
use splatbridge_scene::surfels::{
    looks_like_ges, SplitParams, DEFAULT_MAX_FLATNESS, DEFAULT_MAX_NEIGHBOUR_RATIO,
    DEFAULT_MAX_SCENE_FRACTION, DEFAULT_MIN_NEIGHBOURS, DEFAULT_MIN_OPACITY, FOOTPRINT_SIGMAS,
    GES_EPSILON_FACTOR,
};
use splatbridge_scene::{Camera, GaussianCloud};

use crate::cmd::common::{load, parse_rgb, CameraArgs};
use crate::cmd::render::short;

/// `on` or `off`.
pub fn parse_on_off(s: &str) -> Result<bool, String> {
    match s.trim() {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("'{s}': expected on or off")),
    }
}

/// `1` or `4`.
pub fn parse_supersample(s: &str) -> Result<u32, String> {
    match s.trim() {
        "1" => Ok(1),
        "4" => Ok(4),
        _ => Err(format!("'{s}': supersampling is 1 or 4")),
    }
}

/// How `--split` chooses surfels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SplitMode {
    /// The opacity and flatness test plus the scene-scale, neighbourhood and isolation guards.
    Guarded,
    /// The opacity and flatness test alone (no guards).
    Thresholds,
    /// Measured per scene against native on a few small orbit views (`--min-psnr`).
    Auto,
}

/// How pass 2 blends the Gaussians the surfels leave (`--blend`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BlendMode {
    /// GES's weighted blended transparency: no sort, exact only for one Gaussian per pixel.
    Unsorted,
    /// Front to back in depth order as native splatting, the surfels an opaque layer behind.
    Sorted,
}

impl From<BlendMode> for Blend {
    fn from(b: BlendMode) -> Blend {
        match b {
            BlendMode::Unsorted => Blend::Unsorted,
            BlendMode::Sorted => Blend::Sorted,
        }
    }
}

/// `--min-psnr`: a finite number of dB above 0.
pub fn parse_min_psnr(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v <= 200.0 => Ok(v),
        _ => Err(format!("'{s}': expected a PSNR in dB, in (0, 200]")),
    }
}

/// A positive limit or `off` (infinity).
fn parse_limit(s: &str) -> Result<f32, String> {
    if s.trim() == "off" {
        return Ok(f32::INFINITY);
    }
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}': expected a number > 0 or off")),
    }
}

/// The hybrid's knobs, shared by `hybrid` and `bench hybrid`.
#[derive(clap::Args, Clone, Debug)]
pub struct HybridKnobs {
    /// How surfels are chosen: guarded (the thresholds below), thresholds (opacity and
    /// flatness alone, no guards) or auto (measured against native per scene, see --min-psnr).
    #[arg(long, value_enum, default_value = "guarded")]
    pub split: SplitMode,
    /// With --split auto: the PSNR (dB against native, worst of 4 orbit views at 240×180)
    /// the chosen split must keep.
    #[arg(long, default_value_t = DEFAULT_MIN_PSNR, value_parser = parse_min_psnr)]
    pub min_psnr: f64,
    /// How the Gaussians left after the surfels are blended: sorted (front to back as native:
    /// ≥ 28 dB on every shared scene, about native's speed; the default) or unsorted (GES's
    /// weighted blend, no sort: about 1.9× native at 1080p, 20–28 dB on trained captures).
    /// With --split auto and no --blend, both are measured and the cheaper one that keeps
    /// --min-psnr is used.
    #[arg(long, value_enum)]
    pub blend: Option<BlendMode>,
    /// Guard: a surfel's footprint radius is at most this fraction of the scene's robust
    /// extent (off: no limit).
    #[arg(long, default_value_t = DEFAULT_MAX_SCENE_FRACTION, value_parser = parse_limit)]
    pub surfel_scene_fraction: f32,
    /// Guard: a surfel's largest scale is at most this multiple of its nearest neighbours'
    /// median (off: no limit).
    #[arg(long, default_value_t = DEFAULT_MAX_NEIGHBOUR_RATIO, value_parser = parse_limit)]
    pub surfel_neighbour_ratio: f32,
    /// Guard: at least this many other Gaussian centres lie within a surfel's footprint.
    #[arg(long, default_value_t = DEFAULT_MIN_NEIGHBOURS)]
    pub surfel_min_neighbours: u32,
    /// A Gaussian becomes a surfel when its opacity is at least A (above 1: no surfels) …
    #[arg(long, default_value_t = DEFAULT_MIN_OPACITY)]
    pub surfel_opacity: f32,
    /// … and its flatness (smallest / middle scale) is at most R.
    #[arg(long, default_value_t = DEFAULT_MAX_FLATNESS)]
    pub surfel_flatness: f32,
    /// Depth tolerance factor F: a Gaussian counts at a surfel pixel if its depth is within
    /// F·mean(surfel scales) of the surfel (GES: 5).
    #[arg(long, default_value_t = GES_EPSILON_FACTOR)]
    pub epsilon: f32,
    /// Surfel footprint radius in standard deviations. Default: 1.41 (√2, keeps a split
    /// Gaussian's integrated opacity) for surfels split from a 3DGS cloud, GES's
    /// sqrt(2·ln 255) ≈ 3.33 for a GES PLY's own surfels.
    #[arg(long)]
    pub footprint: Option<f32>,
    /// Surfel samples per pixel: 1 or 4.
    #[arg(long, default_value_t = 1, value_parser = parse_supersample)]
    pub supersample: u32,
    /// GES's 3×3 surfel colour blur: on or off (`--blur` alone means on).
    #[arg(
        long,
        value_parser = parse_on_off,
        default_value = "off",
        num_args = 0..=1,
        default_missing_value = "on",
        action = clap::ArgAction::Set
    )]
    pub blur: bool,
    /// Treat the input as a GES PLY (stored opacity above 1000 marks a surfel). Detected
    /// automatically when any stored opacity exceeds 1000.
    #[arg(long)]
    pub ges_ply: bool,
    /// Background colour R,G,B in [0, 1].
    #[arg(long, value_parser = parse_rgb, default_value = "0,0,0")]
    pub background: glam::Vec3,
    /// Near plane (view-space z), as the native renderer (reference 0.2).
    #[arg(long, default_value_t = 0.2)]
    pub near: f32,
    /// Highest SH degree evaluated (0–3).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(0..=3))]
    pub sh_degree: u8,
}

impl HybridKnobs {
    /// The renderer options; with a `--split auto` choice, its blend unless `--blend` pins one.
    /// `split` is what [`HybridKnobs::resolve_split`] returned (it says whether the surfels are
    /// a GES PLY's own, which keep GES's footprint).
    pub fn options_for(&self, auto: Option<&AutoChoice>, split: &SurfelSplit) -> GesOptions {
        let blend = match (self.blend, auto) {
            (Some(b), _) => b.into(),
            (None, Some(a)) => a.blend(),
            (None, None) => DEFAULT_BLEND,
        };
        // A disc rung's footprint comes with the choice; every other rung rendered with the
        // footprint `options()` gives, which the choice then returns.
        let footprint_sigmas = match auto {
            Some(a) => a.footprint(),
            None => self.footprint_for(split.ges_ply),
        };
        GesOptions {
            blend,
            footprint_sigmas,
            ..self.options()
        }
    }

    /// `--footprint`, or its default for split surfels (`ges = false`) or a GES PLY's.
    pub fn footprint_for(&self, ges: bool) -> f32 {
        match (self.footprint, ges) {
            (Some(f), _) => f,
            (None, false) => DISC_FOOTPRINT_SIGMAS,
            (None, true) => FOOTPRINT_SIGMAS,
        }
    }

    fn footprint_text(&self) -> String {
        match self.footprint {
            Some(f) => short(f).to_string(),
            None => format!(
                "{} (split) / {} (GES PLY)",
                short(DISC_FOOTPRINT_SIGMAS),
                short(FOOTPRINT_SIGMAS)
            ),
        }
    }

    /// The renderer options (the blend `--blend` names, or the default).
    pub fn options(&self) -> GesOptions {
        GesOptions {
            blend: self.blend.map(Blend::from).unwrap_or(DEFAULT_BLEND),
            epsilon_factor: self.epsilon,
            footprint_sigmas: self.footprint_for(self.ges_ply),
            supersample: self.supersample,
            blur: self.blur,
            background: self.background.to_array(),
            near: self.near,
            sh_degree_cap: self.sh_degree,
            ..Default::default()
        }
    }

    /// The thresholds the options name (`--split guarded` or `thresholds`).
    pub fn split_params(&self) -> SplitParams {
        match self.split {
            SplitMode::Thresholds => {
                SplitParams::unguarded(self.surfel_opacity, self.surfel_flatness)
            }
            SplitMode::Guarded | SplitMode::Auto => SplitParams {
                min_opacity: self.surfel_opacity,
                max_flatness: self.surfel_flatness,
                max_scene_fraction: self.surfel_scene_fraction,
                max_neighbour_ratio: self.surfel_neighbour_ratio,
                min_neighbours: self.surfel_min_neighbours,
            },
        }
    }

    /// How surfels are found (the thresholds are checked when a split uses them); with
    /// `--split auto`, use [`HybridKnobs::resolve_split`].
    pub fn surfel_split(&self) -> SurfelSplit {
        SurfelSplit {
            params: self.split_params(),
            ges_ply: self.ges_ply,
            detect_ges: true,
        }
    }

    /// How surfels are found for `cloud`: with `--split auto`, the thresholds are chosen on it
    /// (a GES PLY keeps its own flags and is not measured).
    pub fn resolve_split(
        &self,
        cloud: &GaussianCloud,
    ) -> anyhow::Result<(SurfelSplit, Option<AutoChoice>)> {
        let mut s = self.surfel_split();
        // Detected here (the split would detect it too) so the options keep GES's footprint.
        s.ges_ply |= looks_like_ges(cloud);
        if self.split != SplitMode::Auto || s.ges_ply {
            return Ok((s, None));
        }
        let cfg = AutoConfig {
            min_psnr: self.min_psnr,
            blends: match self.blend {
                Some(b) => vec![b.into()],
                None => AutoConfig::default().blends,
            },
            ..AutoConfig::default()
        };
        let choice = choose(cloud, &self.options(), &cfg)?;
        s.params = choice.params();
        Ok((s, Some(choice)))
    }

    /// The knobs as JSON (for `--json` reports).
    pub fn to_json(&self) -> serde_json::Value {
        json!({
            "split": format!("{:?}", self.split).to_lowercase(),
            "min_psnr": self.min_psnr,
            "blend": blend_name(self.options().blend),
            "split_params": params_json(&self.split_params()),
            "surfel_opacity": short(self.surfel_opacity),
            "surfel_flatness": short(self.surfel_flatness),
            "epsilon": short(self.epsilon),
            "footprint": self.footprint_text(),
            "supersample": self.supersample,
            "blur": self.blur,
            "ges_ply": self.ges_ply,
            "background": self.background.to_array().map(short),
            "near": short(self.near),
            "sh_degree": self.sh_degree,
        })
    }

    pub fn describe(&self) -> String {
        format!(
            "{} blend, footprint {}σ, ε factor {}, supersample {}, blur {}, near {}, SH degree cap {}",
            blend_name(self.options().blend),
            self.footprint_text(),
            self.epsilon,
            self.supersample,
            if self.blur { "on" } else { "off" },
            self.near,
            self.sh_degree
        )
    }
}

#[derive(clap::Args)]
pub struct Args {
    /// A 3DGS PLY (or a GES PLY), or a splatbridge-scene/1 manifest (composite at --time).
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
    let ext = args
        .out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if ext != "png" && ext != "exr" {
        bail!("{}: output must end in .png or .exr", args.out.display());
    }
    let name = args.scene.display().to_string();
    let scene = load(&args.scene, args.drop_invalid)?;
    let effects = effects_of(&scene).with_context(|| name.clone())?;
    let t = args.time.unwrap_or(scene.time.start);
    // Orbit rigs frame the composite (without particles), as `render` does.
    let cam = args
        .camera
        .resolve(&scene.composite_view(t), &scene.cameras)
        .with_context(|| name.clone())?;
    let (split, auto) = args
        .knobs
        .resolve_split(&scene.composite(t))
        .with_context(|| name.clone())?;
    let opts = args.knobs.options_for(auto.as_ref(), &split);
    let mut renderer = Renderer::hybrid(opts, split)?;
    let req = FrameRequest {
        scene: Some(&scene),
        effects: &effects,
        camera: &cam,
        time: t,
        content: Default::default(),
        lidar: None,
    };
    let r = render_frame(&mut renderer, &req).with_context(|| name.clone())?;
    let FrameStats::Hybrid {
        stats,
        split_ms,
        surfels_by: how,
    } = &r.stats
    else {
        bail!("{name}: the hybrid returned another renderer's stats");
    };
    save_frame(&args.out, &r.frame)?;
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
    print_summary(&cam, stats, *split_ms);
    println!("{}", r.counters.summary());
    Ok(())
}
