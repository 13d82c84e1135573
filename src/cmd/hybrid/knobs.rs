//! The hybrid's knobs (shared by `hybrid`, `bench hybrid` and, through `split_args`,
//! `compare` and `accuracy`): their parsers and the renderer options they name.

use serde_json::json;
use splatbridge::pipeline::split_auto::{
    blend_name, params_json, resolve_split, AutoChoice, DEFAULT_BLEND, DEFAULT_MIN_PSNR,
    DISC_FOOTPRINT_SIGMAS,
};
use splatbridge::pipeline::SurfelSplit;
use splatbridge_hybrid::ges::{Blend, GesOptions};
use splatbridge_scene::surfels::{
    SplitParams, DEFAULT_MAX_FLATNESS, DEFAULT_MAX_NEIGHBOUR_RATIO, DEFAULT_MAX_SCENE_FRACTION,
    DEFAULT_MIN_NEIGHBOURS, DEFAULT_MIN_OPACITY, FOOTPRINT_SIGMAS, GES_EPSILON_FACTOR,
};
use splatbridge_scene::GaussianCloud;

use crate::cmd::common::parse_rgb;
use crate::cmd::common::short;

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
        resolve_split(
            cloud,
            self.surfel_split(),
            self.split == SplitMode::Auto,
            self.min_psnr,
            self.blend.map(Blend::from),
            &self.options(),
        )
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
