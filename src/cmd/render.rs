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
use splatbridge::pipeline::{FrameStats, RenderedFrame, Renderer};
use splatbridge_hybrid::{Extent, RenderOptions, RenderStats};
use splatbridge_scene::ply::GaussianKind;
use splatbridge_scene::Camera;

use crate::cmd::common::{parse_rgb, print_warning, short, CameraArgs};

/// Footprint extent (see `splatbridge_hybrid::Extent`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExtentArg {
    /// ceil(3·sqrt(λmax)) pixels, the reference.
    Sigma3,
    /// The footprint where opacity·exp(−r²/2) ≥ 1/255.
    Alpha,
}

impl From<ExtentArg> for Extent {
    fn from(e: ExtentArg) -> Self {
        match e {
            ExtentArg::Sigma3 => Extent::Sigma3,
            ExtentArg::Alpha => Extent::Alpha,
        }
    }
}

/// Which splatting model draws the scene.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelArg {
    /// 2DGS surfels (files with `scale_0 scale_1` only) by the 2DGS renderer, everything
    /// else by 3DGS splatting.
    Auto,
    /// 3DGS splatting (2DGS surfels drawn as discs 1000× thinner than wide).
    #[value(name = "3dgs")]
    Gaussians3D,
    /// 2D Gaussian Splatting's rasterizer: ray–splat intersection, its low-pass filter. Only
    /// for 2DGS surfels.
    #[value(name = "2dgs")]
    Surfels2D,
}

/// Whether `model` draws content of `kind` with the 2DGS renderer (`name` names the input in
/// errors: `--model 2dgs` on anything but 2DGS surfels is one).
pub fn model_is_2dgs(model: ModelArg, kind: GaussianKind, name: &str) -> anyhow::Result<bool> {
    let is_2dgs = kind == GaussianKind::Surfels2D;
    match model {
        ModelArg::Auto => Ok(is_2dgs),
        ModelArg::Gaussians3D => Ok(false),
        ModelArg::Surfels2D if is_2dgs => Ok(true),
        ModelArg::Surfels2D => bail!(
            "{name}: --model 2dgs draws 2DGS surfels (a PLY with scale_0 scale_1 only), \
             and this file holds {}",
            kind.name()
        ),
    }
}

/// The renderer knobs shared by `render` and `bench render`.
#[derive(clap::Args, Clone, Debug)]
pub struct RenderKnobs {
    /// Background colour R,G,B in [0, 1] (composited as C + T·background).
    #[arg(long, value_parser = parse_rgb, default_value = "0,0,0")]
    pub background: glam::Vec3,
    /// Near plane: Gaussians with view-space z ≤ NEAR are dropped (reference 0.2; scenes that
    /// are small in world units may need less).
    #[arg(long, default_value_t = 0.2)]
    pub near: f32,
    /// Footprint extent: sigma3 (reference) or alpha (opacity-dependent, 1/255 boundary).
    #[arg(long, value_enum, default_value_t = ExtentArg::Sigma3)]
    pub extent: ExtentArg,
    /// α clamp: 0.99 (reference) or 0.999 (gsplat).
    #[arg(long, value_parser = super::ranges::alpha_clamp, default_value = "0.99")]
    pub alpha_clamp: f32,
    /// Highest SH degree evaluated (0–3; the scene's own degree if lower).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(0..=3))]
    pub sh_degree: u8,
    /// Splatting model: auto (2DGS surfels by the 2DGS renderer, the rest by 3DGS), 3dgs
    /// (force 3DGS splatting) or 2dgs (2D Gaussian Splatting's rasterizer; 2DGS files only).
    #[arg(long, value_enum, default_value_t = ModelArg::Auto)]
    pub model: ModelArg,
}

impl RenderKnobs {
    pub fn options(&self) -> RenderOptions {
        RenderOptions {
            extent: self.extent.into(),
            alpha_clamp: self.alpha_clamp,
            sh_degree_cap: self.sh_degree,
            near: self.near,
            background: self.background.to_array(),
            exhaustive: false,
        }
    }

    /// Whether the 2DGS renderer draws content of `kind` (`name` names the input in errors).
    pub fn surfels_2d(&self, kind: GaussianKind, name: &str) -> anyhow::Result<bool> {
        model_is_2dgs(self.model, kind, name)
    }

    /// The renderer for content of `kind` (see [`RenderKnobs::surfels_2d`]).
    pub fn renderer(&self, kind: GaussianKind, name: &str) -> anyhow::Result<Renderer> {
        if self.surfels_2d(kind, name)? {
            Renderer::surfels_2d(self.options())
        } else {
            Renderer::native(self.options())
        }
    }

    fn extent_name(&self) -> &'static str {
        match self.extent {
            ExtentArg::Sigma3 => "sigma3",
            ExtentArg::Alpha => "alpha",
        }
    }

    /// The knobs as JSON (for `--json` reports).
    pub fn to_json(&self) -> serde_json::Value {
        json!({
            "extent": self.extent_name(),
            "alpha_clamp": short(self.alpha_clamp),
            "sh_degree": self.sh_degree,
            "near": short(self.near),
            "background": self.background.to_array().map(short),
        })
    }

    pub fn describe(&self) -> String {
        format!(
            "extent {}, alpha clamp {}, SH degree cap {}, near {}, background {},{},{}",
            self.extent_name(),
            self.alpha_clamp,
            self.sh_degree,
            self.near,
            self.background.x,
            self.background.y,
            self.background.z
        )
    }
}

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
