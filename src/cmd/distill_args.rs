//! `convert --distill` options: fit the exported mesh's vertex colours to native splatting
//! (`splatbridge::distill`) before writing it.

use anyhow::Context;
use splatbridge::distill::run::{distill_export, ViewRequest};
use splatbridge::distill::{DistillOptions, HitOrder, Loss, ParamMode};
use splatbridge_convert::ConvertOptions;
use splatbridge_scene::dynamic::DynamicScene;

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum LossArg {
    /// MeshSplats' 0.6·L1 + 0.4·(1 − SSIM).
    L1Ssim,
    L1,
    L2,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum ParamsArg {
    /// Every vertex's colour and opacity.
    Vertex,
    /// A colour shift and an opacity scale per Gaussian.
    Gaussian,
    /// Per Gaussian where the vertices' parameters outnumber the fitting pixels' values.
    Auto,
}

impl ParamsArg {
    pub fn mode(self) -> ParamMode {
        match self {
            ParamsArg::Vertex => ParamMode::Vertex,
            ParamsArg::Gaussian => ParamMode::Gaussian,
            ParamsArg::Auto => ParamMode::Auto,
        }
    }
}

#[derive(clap::Args, Debug, Clone)]
pub struct DistillArgs {
    /// Fit the mesh's vertex colours and opacities to native splatting before writing
    /// (glTF mesh outputs).
    #[arg(long)]
    pub distill: bool,
    /// Fitting views: auto (the scene's own cameras, or a cameras.json beside the input,
    /// else sphere:48), sphere:N (N views over the view sphere: elevations −15…70°, 0.5–1.2×
    /// the orbit's distance, the --distill-for sizes), or a camera list: orbit:N, scene,
    /// PATH.json or single specs, comma-separated.
    #[arg(
        long,
        value_name = "LIST",
        default_value_t = ViewRequest::default().spec,
        requires = "distill"
    )]
    pub views: String,
    /// Adam steps, each over a batch of views.
    #[arg(long, value_name = "K", default_value_t = DistillOptions::default().iterations, requires = "distill")]
    pub iterations: usize,
    /// Stop fitting after this many seconds (set-up included).
    #[arg(long, value_name = "S", requires = "distill")]
    pub distill_time: Option<f64>,
    /// The fitting window's width and height: larger views are fitted through windows of
    /// this size (their pixels exactly, at the cost of a small image).
    #[arg(long, value_name = "W", default_value_t = ViewRequest::default().width, requires = "distill")]
    pub distill_width: u32,
    #[arg(long, value_name = "H", default_value_t = ViewRequest::default().height, requires = "distill")]
    pub distill_height: u32,
    /// The image size the export is made for (repeatable, comma-separated); default the
    /// sizes of --camera views, else 320×240, 640×480, 1280×720 and 1920×1080.
    #[arg(long, value_name = "WxH", value_delimiter = ',', value_parser = super::convert::parse_wxh, requires = "distill")]
    pub distill_for: Vec<(u32, u32)>,
    /// Fitting views at the fine end of `sphere:N` (its nearest distance at the largest size),
    /// after its N: the 1080p close-ups a fit through small windows would otherwise make worse.
    #[arg(long, value_name = "N", default_value_t = ViewRequest::default().fit_fine, requires = "distill")]
    pub distill_fit_fine: usize,
    /// Validation views (never fitted) that pick the iteration kept: none may end below
    /// where it started.
    #[arg(long, value_name = "N", default_value_t = ViewRequest::default().validation, requires = "distill")]
    pub distill_validation: usize,
    /// Validation views at the fine end of the `sphere:N` fitting views (their nearest
    /// distance and largest size), after the --distill-validation ones: a 1080p close-up
    /// that the small fitting views' fit would make worse refuses the step.
    #[arg(long, value_name = "N", default_value_t = ViewRequest::default().validation_fine, requires = "distill")]
    pub distill_validation_fine: usize,
    #[arg(long, value_enum, default_value = "l1-ssim", requires = "distill")]
    pub distill_loss: LossArg,
    /// Held-back views measured before and after: one per class (elevation, distance) in
    /// turn, apart from every fitting view (between the cameras for --views orbit:N).
    #[arg(long, value_name = "M", default_value_t = ViewRequest::default().held_back, requires = "distill")]
    pub held_back: usize,
    /// Held-back image size (default 320×240; the window size for --views orbit:N).
    #[arg(long, value_name = "WxH", value_parser = super::convert::parse_wxh, requires = "distill")]
    pub held_back_size: Option<(u32, u32)>,
    /// Scene times a dynamic scene is fitted at (evenly over its time range), given to the
    /// views in turn; static scenes are fitted at their start.
    #[arg(long, value_name = "N", default_value_t = ViewRequest::default().times, requires = "distill", value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=1024))]
    pub distill_times: usize,
    /// What the fit moves: per-vertex or per-Gaussian colour and opacity.
    #[arg(long, value_enum, default_value = "vertex", requires = "distill")]
    pub distill_params: ParamsArg,
    /// k-buffer size of the hit recording (the order is the same; larger walks a deep
    /// pixel's BVH fewer times).
    #[arg(long, value_name = "K", default_value_t = DistillOptions::default().record_k, requires = "distill")]
    pub distill_record_k: usize,
    /// Transmittance each pixel's hits are recorded down to: the hits behind it are not in
    /// the fit, so a fit that lowers the opacities in front cannot see them (smaller keeps
    /// more hits a pixel: more memory and time a step).
    #[arg(long, value_name = "T", default_value_t = DistillOptions::default().record_transmittance, value_parser = super::common::parse_transmittance, requires = "distill")]
    pub distill_record_transmittance: f32,
    /// Memory (GB) for the views' recorded hits, kept between steps; views beyond it are
    /// traced again in every step they are used (slower, same result).
    #[arg(long, value_name = "GB", default_value_t = default_memory_gb(), value_parser = super::common::parse_non_negative, requires = "distill")]
    pub distill_memory: f64,
    /// Views per Adam step, spread around the rig and taken in turn (0: every view).
    #[arg(long, value_name = "B", default_value_t = DistillOptions::default().batch, requires = "distill")]
    pub distill_batch: usize,
    /// Adam's ε in units of one pixel's loss (ε·W·H): vertices whose gradient is below it
    /// move less than the step size, so what the views barely see stays as converted.
    #[arg(long, value_name = "E", default_value_t = DistillOptions::default().eps_pixels, requires = "distill")]
    pub distill_eps: f32,
    /// Adam's ε, in the same units, once the guard refuses a validation: the fit goes back
    /// to the best iteration the validation views accept and goes on with it (not larger
    /// than --distill-eps: never).
    #[arg(long, value_name = "E", default_value_t = DistillOptions::default().eps_backtrack_pixels, requires = "distill")]
    pub distill_eps_backtrack: f32,
    /// Make the mesh from the Gaussians widened by native splatting's 0.3 px² low-pass at
    /// their depth in the fitting views (as --footprint-for does for given cameras), so the
    /// fit starts from fans that blur as native does at the fitting size.
    #[arg(long, value_enum, default_value = "on", requires = "distill")]
    pub distill_footprint: OnOff,
    /// Which footprint of the views that see a Gaussian it is widened by: 0 the smallest
    /// (the most detailed view's), 1 the largest, between them a quantile.
    #[arg(long, value_name = "Q", default_value_t = DistillOptions::default().footprint_quantile, value_parser = super::common::parse_unit, requires = "distill")]
    pub distill_footprint_quantile: f64,
    /// How far (dB) a validation view may fall below its start before the guard refuses an
    /// iteration; the default refuses any real loss.
    #[arg(long, value_name = "DB", default_value_t = DistillOptions::default().guard_tolerance_db, value_parser = super::common::parse_non_negative, requires = "distill")]
    pub distill_guard_tolerance: f64,
    /// Check the kept result of the widened mesh against the export without distillation on
    /// the validation views, and write that export where the result is below it at one of
    /// them (off: write the kept result, and skip tracing the undistilled export from the
    /// validation views).
    #[arg(long, value_enum, default_value = "on", requires = "distill")]
    pub distill_floor: OnOff,
    /// Validations in a row (10 steps apart) without progress, after which the fit stops:
    /// none finds a better admissible iteration or a refused one closer to admissible than
    /// before (0: run every iteration).
    #[arg(long, value_name = "N", default_value_t = DistillOptions::default().patience, requires = "distill")]
    pub distill_patience: usize,
    /// Highest SH degree of the native targets (and held-back references); 0 fits and
    /// measures against view-independent colour, to see what view-dependence costs.
    #[arg(long, value_name = "D", default_value_t = 3, value_parser = clap::value_parser!(u8).range(0..=3), requires = "distill")]
    pub distill_sh_degree: u8,
    /// Native splatting's near plane (view depth, scene units) for the fit's targets and
    /// held-back references: Gaussians at `z ≤ Z` are dropped from them, as native drops them
    /// (the reference's 0.2). A mesh has no such cull, so close views of a scene small in
    /// scene units show holes in the targets that the export does not have.
    #[arg(long, value_name = "Z", default_value_t = DistillOptions::default().target_near, value_parser = super::common::parse_positive_f32, requires = "distill")]
    pub distill_near: f32,
    /// Highest SH degree of the fitting views' targets alone (validation and held-back views
    /// keep --distill-sh-degree).
    #[arg(long, value_name = "D", value_parser = clap::value_parser!(u8).range(0..=3), requires = "distill")]
    pub distill_fit_sh_degree: Option<u8>,
    /// The order the fit composites each pixel's hits in: ray (the tracer's, what every viewer
    /// draws) or splat (whole Gaussians by the depth of their centres, as native splatting
    /// sorts). Splat is a measurement of what ray order costs: the held-back figures are in
    /// that order, and the export, drawn in ray order by viewers, is not what was fitted.
    #[arg(long, value_enum, default_value = "ray", requires = "distill")]
    pub distill_order: OrderArg,
    /// Fit vertex positions too (meshsplats and rings profiles): each step re-traces its
    /// views with the moved mesh, so each step costs a BVH rebuild.
    #[arg(long, requires = "distill")]
    pub distill_positions: bool,
    /// Adam's step for positions, in units of each Gaussian's size (with --distill-positions).
    #[arg(long, value_name = "S", default_value_t = DistillOptions::default().lr_position, requires = "distill_positions")]
    pub distill_position_step: f32,
    /// Adam's step for the vertices' colours (linear RGB, 0…1).
    #[arg(long, value_name = "S", default_value_t = DistillOptions::default().lr_colour, requires = "distill")]
    pub distill_colour_step: f32,
    /// Adam's step for the vertices' opacities (0 keeps them as converted).
    #[arg(long, value_name = "S", default_value_t = DistillOptions::default().lr_alpha, requires = "distill")]
    pub distill_alpha_step: f32,
    /// Write what the fit did as JSON: every validation (each view's PSNR and change) and
    /// each held-back view's PSNR before and after.
    #[arg(long, value_name = "FILE", requires = "distill")]
    pub distill_log: Option<std::path::PathBuf>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OrderArg {
    Ray,
    Splat,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    On,
    Off,
}

impl DistillArgs {
    /// Fit when asked, setting the options' vertex colours; prints what it did. `input` is
    /// the scene's path (a `cameras.json` beside it is a fitting-view source) and `sizes` the
    /// sizes of the `--camera` views given to convert.
    pub fn apply(
        &self,
        scene: &mut DynamicScene,
        opts: &mut ConvertOptions,
        input: &std::path::Path,
        sizes: &[(u32, u32)],
    ) -> anyhow::Result<()> {
        if !self.distill {
            return Ok(());
        }
        let d = DistillOptions {
            time: scene.time.start,
            iterations: self.iterations,
            max_seconds: self.distill_time,
            loss: match self.distill_loss {
                LossArg::L1Ssim => Loss::L1Ssim(0.4),
                LossArg::L1 => Loss::L1,
                LossArg::L2 => Loss::L2,
            },
            params: self.distill_params.mode(),
            record_k: self.distill_record_k,
            record_transmittance: self.distill_record_transmittance,
            hit_budget: memory_bytes(self.distill_memory),
            batch: self.distill_batch,
            eps_pixels: self.distill_eps,
            eps_backtrack_pixels: self.distill_eps_backtrack,
            footprint: self.distill_footprint == OnOff::On,
            footprint_quantile: self.distill_footprint_quantile,
            guard_tolerance_db: self.distill_guard_tolerance,
            floor: self.distill_floor == OnOff::On,
            patience: self.distill_patience,
            target_sh_degree: self.distill_sh_degree,
            target_near: self.distill_near,
            fit_sh_degree: self.distill_fit_sh_degree,
            lr_colour: self.distill_colour_step,
            lr_alpha: self.distill_alpha_step,
            order: match self.distill_order {
                OrderArg::Ray => HitOrder::Ray,
                OrderArg::Splat => HitOrder::Splat,
            },
            positions: self.distill_positions,
            lr_position: self.distill_position_step,
            ..DistillOptions::default()
        };
        let cameras = splatbridge::distill::run::cameras_beside(&self.views, scene, input)?;
        let req = ViewRequest {
            spec: self.views.clone(),
            width: self.distill_width,
            height: self.distill_height,
            sizes: if self.distill_for.is_empty() {
                sizes.to_vec()
            } else {
                self.distill_for.clone()
            },
            cameras,
            held_back: self.held_back,
            held_size: self.held_back_size,
            fit_fine: self.distill_fit_fine,
            validation: self.distill_validation,
            validation_fine: self.distill_validation_fine,
            times: self.distill_times,
        };
        let pb = super::common::progress(self.iterations as u64, "distilling");
        let out = distill_export(scene, opts, &req, &d, |_| pb.inc(1))
            .with_context(|| format!("--distill (views {})", self.views))?;
        pb.finish_and_clear();
        if let Some(path) = &self.distill_log {
            let json = serde_json::to_vec_pretty(&out).context("--distill-log")?;
            std::fs::write(path, json)
                .with_context(|| format!("--distill-log: {}", path.display()))?;
        }
        super::distill_report::print(&out, self);
        Ok(())
    }
}

/// The hit-list memory of `--distill-memory` and `bench distill --memory` by default, GB.
pub fn default_memory_gb() -> f64 {
    DistillOptions::default().hit_budget as f64 / 1e9
}

/// Bytes of `gb` GB (saturating, as float-to-integer casts do).
pub fn memory_bytes(gb: f64) -> u64 {
    (gb * 1e9) as u64
}
