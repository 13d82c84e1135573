//! The splatting knobs `render`, `bench render` and `compare` share: footprint extent, which
//! model draws the scene (3DGS or 2DGS), and the renderer options.

use anyhow::bail;
use serde_json::json;
use splatbridge::pipeline::Renderer;
use splatbridge_hybrid::{Extent, RenderOptions};
use splatbridge_scene::ply::GaussianKind;

use crate::cmd::common::{parse_rgb, short};

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
