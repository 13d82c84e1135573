//! Helpers shared by subcommands: scene loading, camera selection (`--camera SPEC` or an
//! explicit look-at), output paths, and progress bars that stay quiet off a terminal.

use std::io::IsTerminal;
use std::path::Path;

use anyhow::Context;
use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use splatbridge::pipeline::load_scene_warn;
use splatbridge_scene::camera_spec::{
    CameraRequest, CameraSource, CameraSpec, DEFAULT_PIXEL_BUDGET,
};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::formats::LoadInfo;
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::{Camera, GaussianCloud};

/// A progress bar on a terminal, a hidden one otherwise (pipes, CI, tests).
pub fn progress(len: u64, what: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{msg:12} [{bar:40}] {pos}/{len} {elapsed_precise}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb.set_message(what.to_string());
    pb
}

/// Load a scene (any splat format or a manifest), printing the reader's warnings to stderr.
pub fn load(path: &Path, drop_invalid: bool) -> anyhow::Result<DynamicScene> {
    load_scene_warn(path, drop_invalid, &print_warning)
}

/// Print a library warning as `warning: …` on stderr.
pub fn print_warning(w: &str) {
    eprintln!("warning: {w}");
}

/// [`load`], also saying which format was read.
pub fn load_with_info(path: &Path, drop_invalid: bool) -> anyhow::Result<(DynamicScene, LoadInfo)> {
    let (scene, info) = splatbridge_scene::formats::load(path, &ReadOptions { drop_invalid })?;
    for w in &info.warnings {
        eprintln!("warning: {}: {w}", path.display());
    }
    Ok((scene, info))
}

/// Camera selection shared by `render`, `trace`, `hybrid`.
#[derive(clap::Args, Clone, Debug)]
pub struct CameraArgs {
    /// Camera: `orbit:N:I`, `scene:I` (the scene's or file's own cameras) or `PATH.json:I`
    /// (a 3DGS cameras.json). Default `orbit:8:0` unless --eye is given.
    #[arg(long)]
    pub camera: Option<String>,
    /// Explicit camera position X,Y,Z (with --target, --up, --fov).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<DVec3>,
    /// Point the explicit camera looks at.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub target: Option<DVec3>,
    /// World direction that appears up in the image (0,-1,0 for COLMAP-style y-down worlds).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, default_value = "0,-1,0")]
    pub up: DVec3,
    /// Vertical field of view in degrees (explicit camera and orbit rigs).
    #[arg(long, default_value_t = 50.0)]
    pub fov: f64,
    /// Output width in pixels (default: the camera's own, or 640 for orbit/explicit cameras).
    #[arg(long)]
    pub width: Option<u32>,
    /// Output height in pixels (default: the camera's own, or 480 for orbit/explicit cameras).
    #[arg(long)]
    pub height: Option<u32>,
    /// Largest frame in pixels (width × height), at most 16384².
    #[arg(long, default_value_t = DEFAULT_PIXEL_BUDGET)]
    pub max_pixels: u64,
}

/// Parse `X,Y,Z`.
pub fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{s}' is not X,Y,Z"))?;
    match v[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(DVec3::new(x, y, z)),
        _ => Err(format!("'{s}' is not three finite numbers X,Y,Z")),
    }
}

impl Default for CameraArgs {
    /// The options' defaults (as clap fills them in).
    fn default() -> Self {
        CameraArgs {
            camera: None,
            eye: None,
            target: None,
            up: DVec3::NEG_Y,
            fov: 50.0,
            width: None,
            height: None,
            max_pixels: DEFAULT_PIXEL_BUDGET,
        }
    }
}

impl CameraArgs {
    /// The request these options make (`--eye` needs `--target`; no spec means `orbit:8:0`).
    pub fn request(&self) -> anyhow::Result<CameraRequest> {
        let spec = match self.eye {
            Some(eye) => CameraSpec::LookAt {
                eye,
                target: self.target.context("--eye needs --target")?,
            },
            None => self.camera.as_deref().unwrap_or("orbit:8:0").parse()?,
        };
        Ok(CameraRequest {
            spec,
            up: self.up,
            fov_y_deg: self.fov,
            width: self.width,
            height: self.height,
            max_pixels: self.max_pixels,
        })
    }

    /// Resolve to a camera. `cloud` frames orbit rigs; `own` are the input's own cameras
    /// (a manifest's cameras.json or a glTF file's camera nodes) for `scene:I`.
    pub fn resolve(&self, cloud: &GaussianCloud, own: &[Camera]) -> anyhow::Result<Camera> {
        Ok(self.request()?.resolve(CameraSource { cloud, own })?)
    }
}

/// An f32 knob as the f64 its shortest decimal form denotes (0.99, not 0.9900000095367432).
pub fn short(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(x as f64)
}

/// Parse `R,G,B` in [0, 1].
pub fn parse_rgb(s: &str) -> Result<glam::Vec3, String> {
    let v = parse_vec3(s)?;
    if v.min_element() < 0.0 || v.max_element() > 1.0 {
        return Err(format!("'{s}': colour components must be in [0, 1]"));
    }
    Ok(v.as_vec3())
}

/// A number in [0, 1].
pub fn parse_unit(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("{s:?} is not a number from 0 to 1")),
    }
}

/// A transmittance strictly between 0 and 1.
pub fn parse_transmittance(s: &str) -> Result<f32, String> {
    let t: f32 = s.parse().map_err(|e| format!("{e}"))?;
    if t > 0.0 && t < 1.0 {
        Ok(t)
    } else {
        Err(format!("{s} is not strictly between 0 and 1"))
    }
}

/// A finite f32 > 0.
pub fn parse_positive_f32(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("{s:?} is not a number > 0")),
    }
}

/// A finite number ≥ 0.
pub fn parse_non_negative(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("{s:?} is not a number ≥ 0")),
    }
}
