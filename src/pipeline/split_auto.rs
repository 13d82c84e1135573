//! `--split auto`: choose the surfel split and the Gaussian blend per scene by measuring them.
//! Native splatting (the reference) and the GES hybrid render the scene from a few orbit views
//! at a small size, for each split of a short ladder ([`ladder`]) with each blend of
//! [`AutoConfig::blends`] (unsorted and sorted unless `--blend` pins one); the combination kept
//! is the cheapest whose worst view stays at or above the requested PSNR plus
//! [`AutoConfig::margin`] (the views are fewer and smaller than the cameras the target is for).
//! When none does, the one with the best worst view is kept and the choice says so.
//!
//! "Cheapest" is the hybrid's counted work summed over the views (pixel–Gaussian blends plus
//! tile–Gaussian pairs, which its blending and binning time follow; a sorted blend counts
//! 5/2, its measured cost, and the Gaussians it sorts are added), not the measured
//! milliseconds: the counters make the choice the same on every run and under any load, and
//! the measured times are reported beside them. The cost of choosing (wall milliseconds, views,
//! renders) is part of the result, so a caller can report it.

use std::time::Instant;

use anyhow::Context;
use serde_json::json;
use splatbridge_hybrid::ges::{render_ges, Blend, GesOptions};
use splatbridge_hybrid::RenderOptions;
use splatbridge_scene::camera_spec::{CameraRequest, CameraSource, CameraSpec};
use splatbridge_scene::metrics::psnr;
use splatbridge_scene::surfels::{looks_like_ges, split_counted, SplitParams};
use splatbridge_scene::{Camera, GaussianCloud};

use crate::pipeline::SurfelSplit;

/// The CLI's default blend: the one that keeps ≥ 28 dB on every shared scene (with the
/// [`DISC_FOOTPRINT_SIGMAS`] disc; `docs/blend.md`). `--blend unsorted` is the fast knob.
pub const DEFAULT_BLEND: Blend = Blend::Sorted;

/// Default accuracy target of `--split auto` (dB against native, worst view): the goal.
pub const DEFAULT_MIN_PSNR: f64 = 28.0;

/// How the choice is measured.
#[derive(Clone, Debug, PartialEq)]
pub struct AutoConfig {
    /// The worst view's PSNR against native that the chosen split must keep.
    pub min_psnr: f64,
    /// Orbit views (`orbit:views:I`, I = 0..views).
    pub views: usize,
    pub width: u32,
    pub height: u32,
    /// The blends tried with every split.
    pub blends: Vec<Blend>,
    /// dB the fitting views must keep above `min_psnr` (see [`DEFAULT_MARGIN`]).
    pub margin: f64,
}

/// Default safety margin of `--split auto` (dB above `--min-psnr` on its 4 views at 240×180).
/// The largest gap measured between auto's 4-view 240×180 worst view and the worst of 12 orbit
/// cameras at 480×360 for the same choice was 2.02 dB (`tile_lod1`, 28.47 → 26.45 dB; `donut`
/// 29.47 → 27.75, 1.72 dB; `docs/blend.md`), rounded up to the next half dB.
pub const DEFAULT_MARGIN: f64 = 2.5;

/// The surfel footprint of the disc rungs (σ): √2, where the disc's area equals the integral
/// of the unit-opacity Gaussian it replaces; the footprint at which the sorted hybrid kept
/// ≥ 37.9 dB on every shared scene at every camera (`docs/blend.md`).
pub const DISC_FOOTPRINT_SIGMAS: f32 = std::f32::consts::SQRT_2;

/// The hybrid as the CLI runs it by default (`hybrid`, `compare`, `demo`): the [`DEFAULT_BLEND`]
/// with split surfels drawn as [`DISC_FOOTPRINT_SIGMAS`] discs. `GesOptions::default()` stays
/// GES's own renderer (unsorted, GES's footprint), the one a GES PLY is drawn with.
pub fn default_ges_options() -> GesOptions {
    GesOptions {
        blend: DEFAULT_BLEND,
        footprint_sigmas: DISC_FOOTPRINT_SIGMAS,
        ..GesOptions::default()
    }
}

impl Default for AutoConfig {
    fn default() -> Self {
        // 4 views at 240×180: the smallest rig that sees a scene from every side, at a size
        // where a 1 M-Gaussian scene's ladder costs seconds.
        AutoConfig {
            min_psnr: DEFAULT_MIN_PSNR,
            views: 4,
            width: 240,
            height: 180,
            blends: vec![Blend::Unsorted, Blend::Sorted],
            margin: DEFAULT_MARGIN,
        }
    }
}

/// Cost of one sorted blend in unsorted blends, times 2: the sorted pass's tile loop (native's,
/// with the transmittance chain and its masked lanes) measured 2.4–2.5× the unsorted pass's
/// time per counted blend at 1080p (`bench hybrid`, `fourth_st` 53.7 / 21.6 ns, `plant`
/// 70.7 / 29.3 ns; `docs/blend.md`), so a sorted blend counts as 5/2 unsorted ones.
const SORTED_BLEND_COST: u64 = 5;

/// One rung of the ladder, measured.
#[derive(Clone, Debug)]
pub struct Candidate {
    pub label: String,
    pub params: SplitParams,
    pub blend: Blend,
    /// Surfel footprint radius (σ) the rung renders with.
    pub footprint: f32,
    pub surfels: usize,
    /// PSNR against native per view (dB).
    pub psnr: Vec<f64>,
    pub worst_psnr: f64,
    /// Blends plus tile pairs over the views (the cost the choice minimises).
    pub work: u64,
    /// Measured hybrid milliseconds over the views (split included).
    pub ms: f64,
}

/// The chosen split with what choosing it cost.
#[derive(Clone, Debug)]
pub struct AutoChoice {
    pub config: AutoConfig,
    /// Index into `candidates`.
    pub chosen: usize,
    /// Whether the chosen split meets `min_psnr` + `margin` on every view.
    pub met: bool,
    pub candidates: Vec<Candidate>,
    /// Wall milliseconds of the whole choice (native and every candidate).
    pub ms: f64,
    /// Renders it took (native once per view plus each candidate per view).
    pub renders: usize,
}

/// One rung: a label, the split thresholds and the surfel footprint (σ; `None`: the caller's).
pub type Rung = (String, SplitParams, Option<f32>);

/// The candidate splits, from the most surfels to none: the default guards with looser and
/// stricter local thresholds, looser and stricter guards, the local test alone, the default
/// guards with the √2σ disc ([`DISC_FOOTPRINT_SIGMAS`]) and no surfels.
pub fn ladder() -> Vec<Rung> {
    let d = SplitParams::default();
    let strict = SplitParams {
        max_scene_fraction: d.max_scene_fraction * 0.5,
        max_neighbour_ratio: d.max_neighbour_ratio * 0.5,
        min_neighbours: d.min_neighbours * 2,
        ..d
    };
    let loose = SplitParams {
        max_scene_fraction: d.max_scene_fraction * 2.0,
        max_neighbour_ratio: d.max_neighbour_ratio * 2.0,
        min_neighbours: d.min_neighbours / 2,
        ..d
    };
    vec![
        (
            "loose guards, A 0.5 R 0.5".into(),
            SplitParams {
                min_opacity: 0.5,
                max_flatness: 0.5,
                ..loose
            },
            None,
        ),
        ("loose guards".into(), loose, None),
        ("default".into(), d, None),
        ("strict guards".into(), strict, None),
        (
            "strict guards, A 0.95 R 0.2".into(),
            SplitParams {
                min_opacity: 0.95,
                max_flatness: 0.2,
                ..strict
            },
            None,
        ),
        ("default, disc 1.41σ".into(), d, Some(DISC_FOOTPRINT_SIGMAS)),
        ("no surfels".into(), SplitParams::none(), None),
    ]
}

/// The orbit views of the choice.
fn views(cloud: &GaussianCloud, cfg: &AutoConfig) -> anyhow::Result<Vec<Camera>> {
    (0..cfg.views)
        .map(|index| {
            let req = CameraRequest {
                width: Some(cfg.width),
                height: Some(cfg.height),
                ..CameraRequest::new(CameraSpec::Orbit {
                    n: cfg.views,
                    index,
                })
            };
            Ok(req.resolve(CameraSource { cloud, own: &[] })?)
        })
        .collect()
}

/// Measure every rung of `ladder` on `cloud` and choose (see the module docs).
pub fn choose_from(
    cloud: &GaussianCloud,
    ges: &GesOptions,
    cfg: &AutoConfig,
    ladder: Vec<Rung>,
) -> anyhow::Result<AutoChoice> {
    anyhow::ensure!(
        cfg.min_psnr.is_finite() && cfg.min_psnr > 0.0,
        "--min-psnr {} must be a finite number of dB > 0",
        cfg.min_psnr
    );
    anyhow::ensure!(
        cfg.margin.is_finite() && cfg.margin >= 0.0,
        "--split auto margin {} must be a finite number of dB ≥ 0",
        cfg.margin
    );
    let target = cfg.min_psnr + cfg.margin;
    anyhow::ensure!(!ladder.is_empty(), "the split ladder is empty");
    anyhow::ensure!(!cfg.blends.is_empty(), "no blend to try");
    let t0 = Instant::now();
    let cams = views(cloud, cfg).context("--split auto: orbit views")?;
    let nopts = RenderOptions {
        near: ges.near,
        background: ges.background,
        sh_degree_cap: ges.sh_degree_cap,
        ..Default::default()
    };
    let mut native = Vec::with_capacity(cams.len());
    let mut renderer = splatbridge_hybrid::Renderer::new();
    for cam in &cams {
        native.push(renderer.render(cloud, cam, &nopts)?.0);
    }
    let mut candidates = Vec::with_capacity(ladder.len());
    for (label, params, footprint) in ladder {
        // A disc rung at the caller's own footprint repeats its split's rung: skip it.
        if footprint == Some(ges.footprint_sigmas) {
            continue;
        }
        let footprint = footprint.unwrap_or(ges.footprint_sigmas);
        let c0 = Instant::now();
        let (s, g, _) = split_counted(cloud, &params);
        let split_ms = c0.elapsed().as_secs_f64() * 1e3;
        for &blend in &cfg.blends {
            let c0 = Instant::now();
            let opts = GesOptions {
                blend,
                footprint_sigmas: footprint,
                ..*ges
            };
            let mut psnrs = Vec::with_capacity(cams.len());
            let mut work = 0u64;
            for (cam, reference) in cams.iter().zip(&native) {
                let (img, st) = render_ges(&s, &g, cam, &opts)?;
                psnrs.push(psnr(reference, &img)?);
                work += match blend {
                    Blend::Unsorted => st.blends + st.tile_pairs,
                    Blend::Sorted => {
                        SORTED_BLEND_COST * st.blends / 2 + st.tile_pairs + st.sorted as u64
                    }
                };
            }
            let worst = psnrs.iter().copied().fold(f64::INFINITY, f64::min);
            candidates.push(Candidate {
                label: format!("{label}, {}", blend_name(blend)),
                params,
                blend,
                footprint,
                surfels: s.len(),
                psnr: psnrs,
                worst_psnr: worst,
                work,
                ms: split_ms + c0.elapsed().as_secs_f64() * 1e3,
            });
        }
    }
    let meeting = candidates
        .iter()
        .enumerate()
        .filter(|(_, c)| c.worst_psnr >= target)
        .min_by_key(|(i, c)| (c.work, *i))
        .map(|(i, _)| i);
    let (chosen, met) = match meeting {
        Some(i) => (i, true),
        None => {
            let best = candidates
                .iter()
                .enumerate()
                .max_by(|a, b| {
                    a.1.worst_psnr
                        .total_cmp(&b.1.worst_psnr)
                        .then(b.0.cmp(&a.0))
                })
                .map(|(i, _)| i)
                .unwrap_or(0);
            (best, false)
        }
    };
    let renders = cams.len() * (1 + candidates.len());
    Ok(AutoChoice {
        config: cfg.clone(),
        chosen,
        met,
        candidates,
        ms: t0.elapsed().as_secs_f64() * 1e3,
        renders,
    })
}

/// [`choose_from`] over the default [`ladder`].
pub fn choose(
    cloud: &GaussianCloud,
    ges: &GesOptions,
    cfg: &AutoConfig,
) -> anyhow::Result<AutoChoice> {
    choose_from(cloud, ges, cfg, ladder())
}

/// The name of a blend, as `--blend` spells it.
pub fn blend_name(b: Blend) -> &'static str {
    match b {
        Blend::Unsorted => "unsorted",
        Blend::Sorted => "sorted",
    }
}

/// A split's thresholds as JSON.
pub fn params_json(p: &SplitParams) -> serde_json::Value {
    let f = |x: f32| {
        if x.is_finite() {
            json!(x)
        } else {
            json!("off")
        }
    };
    json!({
        "min_opacity": p.min_opacity,
        "max_flatness": p.max_flatness,
        "max_scene_fraction": f(p.max_scene_fraction),
        "max_neighbour_ratio": f(p.max_neighbour_ratio),
        "min_neighbours": p.min_neighbours,
    })
}

/// One line of thresholds for a summary.
pub fn describe_params(p: &SplitParams) -> String {
    let f = |x: f32| {
        if x.is_finite() {
            x.to_string()
        } else {
            "off".into()
        }
    };
    format!(
        "opacity ≥ {}, flatness ≤ {}, footprint ≤ {} of the scene, ≤ {}× the neighbours' size, ≥ {} neighbours",
        p.min_opacity,
        p.max_flatness,
        f(p.max_scene_fraction),
        f(p.max_neighbour_ratio),
        p.min_neighbours
    )
}

impl AutoChoice {
    /// The chosen thresholds.
    pub fn params(&self) -> SplitParams {
        self.candidates[self.chosen].params
    }

    /// The chosen blend.
    pub fn blend(&self) -> Blend {
        self.candidates[self.chosen].blend
    }

    /// The chosen surfel footprint (σ).
    pub fn footprint(&self) -> f32 {
        self.candidates[self.chosen].footprint
    }

    /// `ges` with the chosen blend and footprint.
    pub fn apply(&self, ges: &GesOptions) -> GesOptions {
        GesOptions {
            blend: self.blend(),
            footprint_sigmas: self.footprint(),
            ..*ges
        }
    }

    pub fn to_json(&self) -> serde_json::Value {
        let c = &self.candidates[self.chosen];
        json!({
            "min_psnr": self.config.min_psnr,
            "margin": self.config.margin,
            "met": self.met,
            "chosen": c.label,
            "params": params_json(&c.params),
            "blend": blend_name(c.blend),
            "footprint": c.footprint,
            "worst_psnr": c.worst_psnr,
            "cost": {
                "milliseconds": self.ms,
                "views": self.config.views,
                "width": self.config.width,
                "height": self.config.height,
                "renders": self.renders,
            },
            "candidates": self.candidates.iter().map(|c| json!({
                "label": c.label,
                "params": params_json(&c.params),
                "blend": blend_name(c.blend),
                "footprint": c.footprint,
                "surfels": c.surfels,
                "psnr": c.psnr,
                "worst_psnr": c.worst_psnr,
                "work": c.work,
                "milliseconds": c.ms,
            })).collect::<Vec<_>>(),
        })
    }

    /// Lines for a terminal.
    pub fn summary(&self) -> String {
        let c = &self.candidates[self.chosen];
        let mut s = format!(
            "split auto: '{}' ({}, disc {:.2}σ) — worst view {:.2} dB {} {} + {} dB; chosen in {:.0} ms over {} views at {}×{} ({} renders)\n",
            c.label,
            describe_params(&c.params),
            c.footprint,
            c.worst_psnr,
            if self.met { "≥" } else { "< (no candidate met)" },
            self.config.min_psnr,
            self.config.margin,
            self.ms,
            self.config.views,
            self.config.width,
            self.config.height,
            self.renders
        );
        for c in &self.candidates {
            s += &format!(
                "  {:<40} {:>8} surfels  worst {:>6.2} dB  work {:>12}  {:>8.1} ms\n",
                c.label, c.surfels, c.worst_psnr, c.work, c.ms
            );
        }
        s
    }
}

/// The `accuracy` sweep's rows for the guards (family `hybrid`): the default split without
/// any guard, and each guard looser and stricter than its default with the others at theirs,
/// so the plot shows what each guard trades (dB against ms).
pub fn accuracy_rows() -> Vec<(
    &'static str,
    String,
    crate::measure::accuracy::Setting,
    bool,
)> {
    use crate::measure::accuracy::Setting;
    let d = SplitParams::default();
    let mut v = vec![(
        "hybrid",
        "unguarded".to_string(),
        Setting::Hybrid(SplitParams::unguarded(d.min_opacity, d.max_flatness)),
        false,
    )];
    for f in [0.5, 2.0] {
        let p = SplitParams {
            max_scene_fraction: d.max_scene_fraction * f,
            ..d
        };
        v.push((
            "hybrid",
            format!("scene fraction≤{}", p.max_scene_fraction),
            Setting::Hybrid(p),
            false,
        ));
        let p = SplitParams {
            max_neighbour_ratio: d.max_neighbour_ratio * f,
            ..d
        };
        v.push((
            "hybrid",
            format!("neighbour ratio≤{}", p.max_neighbour_ratio),
            Setting::Hybrid(p),
            false,
        ));
        let p = SplitParams {
            min_neighbours: (d.min_neighbours as f32 / f).round() as u32,
            ..d
        };
        v.push((
            "hybrid",
            format!("neighbours≥{}", p.min_neighbours),
            Setting::Hybrid(p),
            false,
        ));
    }
    v
}

/// The `accuracy` sweep's rows for the blend (family `blend`): the default split and no
/// surfels, each with the unsorted and the sorted blend, so the plot shows what sorting costs
/// and buys with and without the surfels' occlusion.
pub fn blend_accuracy_rows() -> Vec<(
    &'static str,
    String,
    crate::measure::accuracy::Setting,
    bool,
)> {
    use crate::measure::accuracy::Setting;
    let mut v = Vec::new();
    for (name, split) in [
        ("guarded", SplitParams::default()),
        ("no surfels", SplitParams::none()),
    ] {
        for blend in [Blend::Unsorted, Blend::Sorted] {
            v.push((
                "blend",
                format!("{name}, {}", blend_name(blend)),
                Setting::HybridWith(
                    split,
                    GesOptions {
                        blend,
                        ..GesOptions::default()
                    },
                ),
                false,
            ));
        }
    }
    v
}

/// How surfels are found for `cloud`: `split` as asked, or with `auto` the thresholds and
/// blend chosen on the cloud ([`choose`] over the blends `blend` allows: the one named, or
/// both). A GES PLY (named, or detected here so the options keep GES's footprint) keeps its
/// own flags and is not measured.
pub fn resolve_split(
    cloud: &GaussianCloud,
    mut split: SurfelSplit,
    auto: bool,
    min_psnr: f64,
    blend: Option<Blend>,
    ges: &GesOptions,
) -> anyhow::Result<(SurfelSplit, Option<AutoChoice>)> {
    split.ges_ply |= looks_like_ges(cloud);
    if !auto || split.ges_ply {
        return Ok((split, None));
    }
    let cfg = AutoConfig {
        min_psnr,
        blends: match blend {
            Some(b) => vec![b],
            None => AutoConfig::default().blends,
        },
        ..AutoConfig::default()
    };
    let choice = choose(cloud, ges, &cfg)?;
    split.params = choice.params();
    Ok((split, Some(choice)))
}
