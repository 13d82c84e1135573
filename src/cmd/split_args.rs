//! `--split`, `--min-psnr` and `--blend` for the commands that run the hybrid beside other
//! renderers (`compare`, `accuracy`): the same choices as `hybrid`'s own
//! ([`super::hybrid::HybridKnobs`]), with the other hybrid knobs at their defaults.

use splatbridge::pipeline::split_auto::{
    blend_name, choose, AutoChoice, AutoConfig, DEFAULT_BLEND, DEFAULT_MIN_PSNR,
    DISC_FOOTPRINT_SIGMAS,
};
use splatbridge_hybrid::ges::{Blend, GesOptions};
use splatbridge_scene::surfels::SplitParams;
use splatbridge_scene::GaussianCloud;

use super::hybrid::{parse_min_psnr, BlendMode, SplitMode};

#[derive(clap::Args, Clone, Debug)]
pub struct SplitArgs {
    /// How the hybrid chooses surfels: guarded (default), thresholds (no guards) or auto
    /// (measured against native on the scene, see --min-psnr).
    #[arg(long, value_enum)]
    pub split: Option<SplitMode>,
    /// With --split auto: the PSNR (dB against native, worst of 4 orbit views at 240×180) the
    /// chosen split and blend must keep.
    #[arg(long, default_value_t = DEFAULT_MIN_PSNR, value_parser = parse_min_psnr)]
    pub min_psnr: f64,
    /// How the hybrid blends the Gaussians left after the surfels: sorted (default, with the
    /// 1.41σ surfel disc) or unsorted; with --split auto and no --blend, both are measured.
    #[arg(long, value_enum)]
    pub blend: Option<BlendMode>,
}

/// A split and blend ready to render, and the measurement that chose them (`--split auto`).
pub struct ResolvedSplit {
    pub params: SplitParams,
    pub ges: GesOptions,
    pub auto: Option<AutoChoice>,
}

impl SplitArgs {
    /// Whether either knob was given (otherwise the defaults apply).
    pub fn given(&self) -> bool {
        self.split.is_some() || self.blend.is_some()
    }

    /// The split and blend on top of `base`; `--split auto` measures them on the cloud `cloud`
    /// makes (called only then).
    pub fn resolve(
        &self,
        cloud: impl FnOnce() -> GaussianCloud,
        base: GesOptions,
    ) -> anyhow::Result<ResolvedSplit> {
        let d = SplitParams::default();
        let pinned = self.blend.map(Blend::from);
        // Split surfels render with the √2σ disc, as `hybrid`'s default.
        let base = GesOptions {
            footprint_sigmas: DISC_FOOTPRINT_SIGMAS,
            ..base
        };
        let plain = |params| ResolvedSplit {
            params,
            ges: GesOptions {
                blend: pinned.unwrap_or(DEFAULT_BLEND),
                ..base
            },
            auto: None,
        };
        Ok(match self.split.unwrap_or(SplitMode::Guarded) {
            SplitMode::Guarded => plain(d),
            SplitMode::Thresholds => plain(SplitParams::unguarded(d.min_opacity, d.max_flatness)),
            SplitMode::Auto => {
                let cfg = AutoConfig {
                    min_psnr: self.min_psnr,
                    blends: match pinned {
                        Some(b) => vec![b],
                        None => AutoConfig::default().blends,
                    },
                    ..AutoConfig::default()
                };
                let choice = choose(&cloud(), &base, &cfg)?;
                ResolvedSplit {
                    params: choice.params(),
                    ges: choice.apply(&base),
                    auto: Some(choice),
                }
            }
        })
    }

    /// The knobs as one line (for option hashes and row labels).
    pub fn text(&self) -> String {
        let split = match self.split.unwrap_or(SplitMode::Guarded) {
            SplitMode::Guarded => "guarded".to_string(),
            SplitMode::Thresholds => "thresholds".to_string(),
            SplitMode::Auto => format!("auto ≥ {} dB", self.min_psnr),
        };
        let blend = match self.blend {
            Some(b) => blend_name(b.into()),
            None if self.split == Some(SplitMode::Auto) => "measured",
            None => blend_name(DEFAULT_BLEND),
        };
        format!("split {split}, blend {blend}")
    }
}
