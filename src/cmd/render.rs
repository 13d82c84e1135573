//! `splatbridge render`: render a scene with the native 3DGS splatting renderer (the reference
//! forward pass; knobs and their reference defaults in `splatbridge_hybrid::native`).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use splatbridge_hybrid::{Extent, RenderOptions, RenderStats, Renderer};
use splatbridge_scene::image_io::save_frame;
use splatbridge_scene::Camera;

use crate::cmd::common::{load, parse_rgb, with_suffix, CameraArgs};

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

/// Parse the α clamp: 0.99 (reference) or 0.999 (gsplat).
pub fn parse_alpha_clamp(s: &str) -> Result<f32, String> {
    match s.trim() {
        "0.99" => Ok(0.99),
        "0.999" => Ok(0.999),
        _ => Err(format!(
            "'{s}': alpha clamp is 0.99 (reference) or 0.999 (gsplat)"
        )),
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
    #[arg(long, value_parser = parse_alpha_clamp, default_value = "0.99")]
    pub alpha_clamp: f32,
    /// Highest SH degree evaluated (0–3; the scene's own degree if lower).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(0..=3))]
    pub sh_degree: u8,
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

    pub fn describe(&self) -> String {
        format!(
            "extent {}, alpha clamp {}, SH degree cap {}, near {}, background {},{},{}",
            match self.extent {
                ExtentArg::Sigma3 => "sigma3",
                ExtentArg::Alpha => "alpha",
            },
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
    /// A 3DGS PLY or a splatbridge-scene/1 manifest (rendered as the composite at --time).
    pub scene: PathBuf,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Scene time in seconds (default: the start of the scene's time range).
    #[arg(long)]
    pub time: Option<f64>,
    /// Render every frame of the scene's time range to OUT_0000.ext, OUT_0001.ext, ….
    #[arg(long, conflicts_with = "time")]
    pub frames: bool,
    #[command(flatten)]
    pub knobs: RenderKnobs,
    /// Drop invalid Gaussians (NaN, zero quaternion) with a counted warning instead of failing.
    #[arg(long)]
    pub drop_invalid: bool,
    /// Output image: .png (8-bit RGB) or .exr (float RGBA and Z depth).
    #[arg(short, long)]
    pub out: PathBuf,
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
    if stats.culled_near_in_view > 0 {
        eprintln!(
            "warning: the near plane (z ≤ {near}) culled {} Gaussians that project inside the view; \
             the scene may be small in world units (try a smaller --near)",
            stats.culled_near_in_view
        );
    }
}

fn check_output(out: &Path) -> anyhow::Result<()> {
    let ext = out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if ext != "png" && ext != "exr" {
        bail!("{}: output must end in .png or .exr", out.display());
    }
    Ok(())
}

pub fn run(args: Args) -> anyhow::Result<()> {
    check_output(&args.out)?;
    let scene = load(&args.scene, args.drop_invalid)?;
    let opts = args.knobs.options();
    opts.validate()?;
    let times = if args.frames {
        scene.frame_times()
    } else {
        vec![args.time.unwrap_or(scene.time.start)]
    };
    // The camera is resolved once (orbit rigs frame the first composite), so frames share it.
    let first = scene.composite(times[0]);
    let cam = args
        .camera
        .resolve(&first, &scene.cameras)
        .with_context(|| args.scene.display().to_string())?;
    println!("render {}: {}", args.scene.display(), args.knobs.describe());
    let mut cloud = Some(first);
    let mut renderer = Renderer::new();
    for (i, &t) in times.iter().enumerate() {
        let c = match cloud.take() {
            Some(c) => c,
            None => scene.composite(t),
        };
        let (frame, stats) = renderer
            .render(&c, &cam, &opts)
            .with_context(|| args.scene.display().to_string())?;
        let out = if args.frames {
            with_suffix(&args.out, &format!("{i:04}"))
        } else {
            args.out.clone()
        };
        save_frame(&out, &frame)?;
        println!("{} (t = {t})", out.display());
        print_summary(&cam, &stats, opts.near);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alpha_clamp_accepts_only_the_named_values() {
        assert_eq!(parse_alpha_clamp("0.99"), Ok(0.99));
        assert_eq!(parse_alpha_clamp("0.999"), Ok(0.999));
        assert!(parse_alpha_clamp("0.9").is_err());
        assert!(parse_alpha_clamp("1").is_err());
    }

    #[test]
    fn outputs_must_be_png_or_exr() {
        assert!(check_output(Path::new("a/b.PNG")).is_ok());
        assert!(check_output(Path::new("b.exr")).is_ok());
        assert!(check_output(Path::new("b.jpg")).is_err());
        assert!(check_output(Path::new("b")).is_err());
    }
}
