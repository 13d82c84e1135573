//! Distillation rows of the accuracy sweep (`accuracy --only distill`): held-back views drawn
//! apart from the fitting ones, by class (elevation, distance) and image size, against
//! distillation time and iterations.
//!
//! Fitting views: the distillation's default, `sphere:N` over the view sphere at the fit's
//! sizes through its window, plus its validation views ([`crate::distill::guard`]). Held-back
//! views: [`views::held_back_classes`] at the measured sizes, each at least
//! [`views::MIN_APART_DEG`] from every fitting and validation view. Every view is measured
//! against three meshes: the undistilled MeshSplats default (the plain export), the plain
//! export of the profile fitted, and the fit at each checkpoint (iteration 0 is the fit's
//! start, the mesh widened for the fitting views). At the last checkpoint the distilled
//! export is what `convert --distill` writes: the kept fit, or the plain export where the
//! kept fit is below it at a validation view (`distill::plain`, `--distill-floor`). The
//! distribution over views, worst and median, is reported per class, not only the mean.

use std::path::Path;

use anyhow::Context;
use splatbridge_convert::{ConvertOptions, Profile};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use crate::distill::plain::Undistilled;
use crate::distill::run::worst_and_median;
use crate::distill::{native_targets_sh, views, DistillOptions, Distiller};
use crate::measure::accuracy::Sweep;
use crate::measure::report::plot::{self, Point};
use crate::measure::report::Record;

/// What the distillation rows fit and measure.
#[derive(Clone, Debug)]
pub struct DistillSweep {
    pub profiles: Vec<Profile>,
    /// Fitting views over the view sphere.
    pub views: usize,
    /// Sizes the export is made for (`--distill-for`); empty: the default range to 1080p.
    pub fit_sizes: Vec<(u32, u32)>,
    /// Held-back image sizes.
    pub sizes: Vec<(u32, u32)>,
    /// Held-back views per class and size.
    pub per_class: usize,
    /// Fitting views at the fine end, after the sphere's.
    pub fit_fine: usize,
    /// Validation views.
    pub validation: usize,
    /// Validation views at the fitting distribution's fine end.
    pub validation_fine: usize,
    /// Iterations at which the held-back views are measured (ascending; the last is where
    /// the fit ends and keeps its best validated iteration).
    pub checkpoints: Vec<usize>,
    pub options: DistillOptions,
}

impl Default for DistillSweep {
    fn default() -> Self {
        DistillSweep {
            profiles: vec![Profile::MeshSplats, Profile::Rings, Profile::Texture],
            views: crate::distill::DEFAULT_VIEWS,
            fit_sizes: Vec::new(),
            sizes: vec![(320, 240), (640, 480)],
            per_class: 1,
            fit_fine: crate::distill::run::ViewRequest::default().fit_fine,
            validation: crate::distill::run::ViewRequest::default().validation,
            validation_fine: crate::distill::run::ViewRequest::default().validation_fine,
            checkpoints: vec![0, 20, 60],
            options: DistillOptions::default(),
        }
    }
}

/// One measured checkpoint: the record (mean over the held-back views) and the distillation
/// seconds it took (set-up included), for the curve.
pub struct CurvePoint {
    pub record: Record,
    pub seconds: f64,
    pub iterations: usize,
    pub profile: String,
    /// The undistilled MeshSplats default, marked in the plot.
    pub baseline: bool,
}

/// One held-back view of one profile's fit: PSNR of the MeshSplats default, of the plain
/// export of the profile, of the fit's start (the mesh made from the widened Gaussians,
/// colours as converted) and of the fit at its end. Start against plain is what the
/// footprint widening did to the view; distilled against start, what the fit did.
#[derive(Clone, Debug)]
pub struct ViewResult {
    pub profile: String,
    pub class: String,
    pub camera: String,
    pub default_psnr: f64,
    pub plain_psnr: f64,
    pub start_psnr: f64,
    pub distilled_psnr: f64,
}

/// The held-back view where a profile's fit gains least over its plain export (or loses
/// most), rendered for a person to look at: native splatting, the plain export and the
/// distilled export, with their PSNRs against native.
pub struct WorstView {
    pub profile: String,
    pub camera: String,
    pub plain_psnr: f64,
    pub distilled_psnr: f64,
    pub native: Frame,
    pub plain: Frame,
    pub distilled: Frame,
}

/// What the distillation rows measured.
pub struct DistillRows {
    /// Per profile, its worst held-back view against the plain export.
    pub worst: Vec<WorstView>,
    pub curve: Vec<CurvePoint>,
    pub views: Vec<ViewResult>,
    /// Per profile: set-up seconds (targets, hit recording), fitting seconds, kept iteration.
    pub timing: Vec<(String, f64, f64, usize)>,
    /// Per profile: every validation of the fit (the guard's log).
    pub validation: Vec<(String, Vec<crate::distill::guard::Validation>)>,
    pub fit_description: String,
}

/// PSNR of the plain (undistilled, unwidened) export of `profile` of `scene` against `refs`
/// at each camera of `cams` (also `examples/sh_ceiling.rs`), traced at the fit's default time.
/// `accuracy` sweeps a static scene (a dynamic one's composite at `--time`, `cmd::accuracy`),
/// so the time traced at does not move the figures: the sweep's time is already in the
/// Gaussians.
pub fn plain_export_psnr(
    scene: &DynamicScene,
    profile: Profile,
    cams: &[Camera],
    refs: &[Frame],
) -> anyhow::Result<Vec<f64>> {
    let times = vec![DistillOptions::default().time; cams.len()];
    Ok(plain_export(scene, profile)?.psnr_each(cams, &times, refs)?)
}

/// The plain (undistilled, unwidened) export of `profile` of `scene`, traced as the fit traces.
fn plain_export(scene: &DynamicScene, profile: Profile) -> anyhow::Result<Undistilled> {
    let convert = ConvertOptions {
        profile,
        ..ConvertOptions::default()
    };
    Ok(Undistilled::new(
        scene,
        &convert,
        &DistillOptions::default(),
    )?)
}

fn psnr_at(d: &mut Distiller, cams: &[Camera], refs: &[Frame]) -> anyhow::Result<Vec<f64>> {
    cams.iter()
        .zip(refs)
        .map(|(c, r)| Ok(splatbridge_scene::metrics::psnr(&d.render(c)?, r)?))
        .collect()
}

/// The views of a sweep of `cloud`: the fitting views (the sphere's and its fine end's), the
/// validation views after them, and the held-back classes apart from both
/// (`examples/sh_ceiling.rs` measures at the same held-back views).
pub struct SweepViews {
    pub fit: views::Windows,
    pub validation: views::Windows,
    pub held: Vec<views::HeldBack>,
    /// The sizes the fit is made for.
    pub sizes: Vec<(u32, u32)>,
}

/// [`SweepViews`] of `cloud` for `cfg`.
pub fn sweep_views(cloud: &GaussianCloud, cfg: &DistillSweep) -> anyhow::Result<SweepViews> {
    let sizes: Vec<(u32, u32)> = if cfg.fit_sizes.is_empty() {
        views::DEFAULT_SIZES.to_vec()
    } else {
        cfg.fit_sizes.clone()
    };
    let fit = views::sphere_with_fine(cloud, cfg.views, cfg.fit_fine, &sizes, views::WINDOW)?;
    let validation = views::validation_views(
        cloud,
        fit.windows.len(),
        cfg.validation,
        cfg.validation_fine,
        &sizes,
        views::WINDOW,
    )?;
    let avoid = [&fit.frames[..], &validation.frames];
    let held = views::held_back_classes(cloud, &cfg.sizes, cfg.per_class, &avoid)?;
    Ok(SweepViews {
        fit,
        validation,
        held,
        sizes,
    })
}

/// Fit each profile on the sphere's views and measure the held-back classes.
pub fn distill_rows(s: &Sweep<'_>, cfg: &DistillSweep) -> anyhow::Result<DistillRows> {
    let scene = s.scene;
    let SweepViews {
        fit,
        validation: val,
        held,
        sizes,
    } = sweep_views(s.cloud(), cfg)?;
    let cams: Vec<Camera> = held.iter().map(|h| h.camera.clone()).collect();
    let o = &cfg.options;
    let times = vec![s.time; cams.len()];
    let refs = native_targets_sh(scene, &cams, &times, o.target_sh_degree, o.target_near)?;
    let default_psnr = plain_export_psnr(scene, Profile::MeshSplats, &cams, &refs)?;
    let last = cfg.checkpoints.iter().copied().max().unwrap_or(0);
    let mut out = DistillRows {
        worst: Vec::new(),
        curve: Vec::new(),
        views: Vec::new(),
        timing: Vec::new(),
        validation: Vec::new(),
        fit_description: format!(
            "sphere:{}{} through {}×{} windows of views at {}, {} validation views{}; {} held-back views ({} per class and size)",
            cfg.views,
            if cfg.fit_fine > 0 {
                format!(" and {} views at its fine end", cfg.fit_fine)
            } else {
                String::new()
            },
            views::WINDOW.0,
            views::WINDOW.1,
            sizes
                .iter()
                .map(|(w, h)| format!("{w}×{h}"))
                .collect::<Vec<_>>()
                .join(", "),
            cfg.validation,
            if cfg.validation_fine > 0 {
                format!(" and {} at the fine end", cfg.validation_fine)
            } else {
                String::new()
            },
            cams.len(),
            cfg.per_class
        ),
    };
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len().max(1) as f64;
    out.curve.push(CurvePoint {
        record: record("meshsplats", "undistilled default", mean(&default_psnr), 0),
        seconds: 1e-3,
        iterations: 0,
        profile: "meshsplats".into(),
        baseline: true,
    });
    for &profile in &cfg.profiles {
        let name = profile_name(profile);
        let plain = if profile == Profile::MeshSplats {
            default_psnr.clone()
        } else {
            plain_export_psnr(scene, profile, &cams, &refs)?
        };
        let convert = ConvertOptions {
            profile,
            ..ConvertOptions::default()
        };
        let opts = DistillOptions {
            iterations: last,
            time: s.time,
            ..cfg.options.clone()
        };
        let (mut d, _) = Distiller::for_windows(scene, &convert, &fit.windows, &fit.frames, &opts)
            .with_context(|| format!("distilling profile {name}"))?;
        d.add_validation(scene, &val.windows, &vec![s.time; val.windows.len()])?;
        let triangles = d.triangles();
        let mut fit_seconds = 0.0;
        d.validate()?;
        // The fit's start (the widened mesh, colours as converted): every view's start
        // column, and the it=0 checkpoint's figures.
        let start = psnr_at(&mut d, &cams, &refs)?;
        // Whether the result is the undistilled export, as `convert --distill` decides it
        // (`distill::plain`): the kept fit below it at a validation view.
        let mut to_undistilled = false;
        loop {
            let it = d.history.len();
            if it >= last {
                d.validate()?;
                d.keep_best();
                if opts.floor && opts.footprint && d.report().validation_views > 0 {
                    let undistilled = Undistilled::new(scene, &convert, &opts)?;
                    let check = d.check_floor(d.validation_psnr_of(&undistilled)?);
                    to_undistilled = check.kept_undistilled;
                }
            }
            if cfg.checkpoints.contains(&it) {
                let seconds = d.elapsed();
                let psnr = if to_undistilled {
                    plain.clone()
                } else if it == 0 {
                    start.clone()
                } else {
                    psnr_at(&mut d, &cams, &refs)?
                };
                let mut r = record(
                    name,
                    &format!("{name} it={it} ({seconds:.1} s)"),
                    mean(&psnr),
                    triangles,
                );
                r.ssim = 0.0;
                out.curve.push(CurvePoint {
                    record: r,
                    seconds,
                    iterations: it,
                    profile: name.into(),
                    baseline: false,
                });
                if it >= last {
                    let worst = (0..psnr.len())
                        .min_by(|&a, &b| (psnr[a] - plain[a]).total_cmp(&(psnr[b] - plain[b])));
                    if let Some(i) = worst {
                        let cam = &cams[i];
                        // Built again for one view rather than held through the fit (the
                        // plain mesh's memory beside the fitted one's).
                        let plain_image = plain_export(scene, profile)?
                            .render_at(cam, DistillOptions::default().time)?;
                        out.worst.push(WorstView {
                            profile: name.into(),
                            camera: cam.name.clone(),
                            plain_psnr: plain[i],
                            distilled_psnr: psnr[i],
                            native: refs[i].clone(),
                            distilled: if to_undistilled {
                                plain_image.clone()
                            } else {
                                d.render(cam)?
                            },
                            plain: plain_image,
                        });
                    }
                    for (i, (h, &p)) in held.iter().zip(&psnr).enumerate() {
                        out.views.push(ViewResult {
                            profile: name.into(),
                            class: h.class.clone(),
                            camera: h.camera.name.clone(),
                            default_psnr: default_psnr[i],
                            plain_psnr: plain[i],
                            start_psnr: start[i],
                            distilled_psnr: p,
                        });
                    }
                }
            }
            if it >= last {
                break;
            }
            let t0 = std::time::Instant::now();
            d.step()?;
            fit_seconds += t0.elapsed().as_secs_f64();
            if d.history.len() % crate::distill::guard::EVERY == 0 {
                // The fit's own rule, backtracking included; the sweep runs every step
                // (its checkpoints), so the patience is not applied.
                d.validate_step()?;
            }
        }
        let r = d.report();
        out.timing
            .push((name.into(), r.setup_seconds, fit_seconds, r.kept_iteration));
        out.validation
            .push((name.into(), d.validation_log().to_vec()));
    }
    Ok(out)
}

fn record(profile: &str, value: &str, psnr: f64, triangles: u64) -> Record {
    Record {
        renderer: "trace-mesh".into(),
        profile: profile.into(),
        knob: "distill".into(),
        value: value.into(),
        camera: "held-back views".into(),
        psnr,
        triangles,
        ..Record::default()
    }
}

fn profile_name(p: Profile) -> &'static str {
    match p {
        Profile::MeshSplats => "meshsplats",
        Profile::Rings => "rings",
        Profile::Texture => "texture",
    }
}

/// `distill.md` (per class: worst and median change against the MeshSplats default and
/// against the profile's plain export) and the plot of held-back PSNR against distillation
/// seconds, in `out`.
pub fn write_curve(out: &Path, what: &str, rows: &DistillRows) -> anyhow::Result<()> {
    let pts: Vec<Point> = rows
        .curve
        .iter()
        .map(|p| Point {
            label: format!("it={}", p.iterations),
            series: p.profile.clone(),
            cost: p.seconds.max(1e-3),
            psnr: p.record.psnr,
            baseline: p.baseline,
        })
        .collect();
    plot::plot(
        &pts,
        "distillation seconds, set-up included (log)",
        "held-back PSNR against distillation time",
        &out.join("psnr_vs_distill_time"),
    )?;
    let mut md = format!(
        "# Distillation on held-back views\n\n{what}. Fitting: {}. No held-back view is within \
         {}° of a fitting or validation view.\n\n![PSNR against distillation time](psnr_vs_distill_time.png)\n\n\
         ## Per class\n\nPSNR against native in dB; changes are of the distilled export, worst / median over the class's views.\n\n\
         | profile | class | views | MeshSplats default (median) | plain export (median) | start (median) | distilled (median) | vs default worst / median | vs plain worst / median | start vs plain worst / median |\n|---|---|---|---|---|---|---|---|---|---|\n",
        rows.fit_description,
        views::MIN_APART_DEG
    );
    let mut classes: Vec<(String, String)> = Vec::new();
    for v in &rows.views {
        let k = (v.profile.clone(), v.class.clone());
        if !classes.contains(&k) {
            classes.push(k);
        }
    }
    let all = "all views".to_string();
    let mut profiles: Vec<String> = Vec::new();
    for (p, _) in &classes {
        if !profiles.contains(p) {
            profiles.push(p.clone());
        }
    }
    let keys = classes
        .iter()
        .cloned()
        .chain(profiles.iter().map(|p| (p.clone(), all.clone())));
    for (p, c) in keys {
        let vs: Vec<&ViewResult> = rows
            .views
            .iter()
            .filter(|v| v.profile == p && (c == all || v.class == c))
            .collect();
        let med = |f: &dyn Fn(&ViewResult) -> f64| {
            worst_and_median(&vs.iter().map(|v| f(v)).collect::<Vec<_>>()).map_or(f64::NAN, |x| x.1)
        };
        let wm = |f: &dyn Fn(&ViewResult) -> f64| {
            worst_and_median(&vs.iter().map(|v| f(v)).collect::<Vec<_>>())
                .unwrap_or((f64::NAN, f64::NAN))
        };
        let (dw, dm) = wm(&|v| v.distilled_psnr - v.default_psnr);
        let (pw, pm) = wm(&|v| v.distilled_psnr - v.plain_psnr);
        let (sw, sm) = wm(&|v| v.start_psnr - v.plain_psnr);
        md += &format!(
            "| {p} | {c} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {dw:+.2} / {dm:+.2} | {pw:+.2} / {pm:+.2} | {sw:+.2} / {sm:+.2} |\n",
            vs.len(),
            med(&|v| v.default_psnr),
            med(&|v| v.plain_psnr),
            med(&|v| v.start_psnr),
            med(&|v| v.distilled_psnr),
        );
    }
    md += "\n## Time\n\n| profile | set-up s (targets, hit recording) | fitting s (steps) | iteration kept |\n|---|---|---|---|\n";
    for (p, setup, fit, kept) in &rows.timing {
        md += &format!("| {p} | {setup:.1} | {fit:.1} | {kept} |\n");
    }
    md += "\n## Validation\n\nThe guard's views at every validation: mean PSNR, each view's PSNR at the start and its change from there (dB); an iteration is admissible when no view is below its start by more than the guard's tolerance.\n\n| profile | iteration | mean | changes | admissible |\n|---|---|---|---|---|\n";
    for (p, log) in &rows.validation {
        for v in log {
            let ch: Vec<String> = if v.iteration == 0 {
                v.psnr.iter().map(|c| format!("{c:.2}")).collect()
            } else {
                v.change.iter().map(|c| format!("{c:+.3}")).collect()
            };
            md += &format!(
                "| {p} | {} | {:.2} | {} | {} |\n",
                v.iteration,
                v.mean,
                ch.join(" "),
                if v.admissible { "yes" } else { "no" }
            );
        }
    }
    md += "\n## Every view\n\nStart: the mesh made from the widened Gaussians with the colours as converted, before the first step. Distilled: what `convert --distill` writes (the plain export where the kept fit is below it at a validation view, unless `--distill-floor off`).\n\n| profile | view | default | plain | start | distilled |\n|---|---|---|---|---|---|\n";
    for v in &rows.views {
        md += &format!(
            "| {} | {} | {:.2} | {:.2} | {:.2} | {:.2} |\n",
            v.profile, v.camera, v.default_psnr, v.plain_psnr, v.start_psnr, v.distilled_psnr
        );
    }
    if !rows.worst.is_empty() {
        md += "\n## The view that gains least\n\nPer profile, the held-back view where the distilled export gains least over the plain export (or loses most): native splatting, the plain export, the distilled export.\n";
    }
    for w in &rows.worst {
        let mut cells = Vec::new();
        for (what, frame) in [
            ("native", &w.native),
            ("plain", &w.plain),
            ("distilled", &w.distilled),
        ] {
            let file = format!("worst_{}_{what}.png", w.profile);
            splatbridge_scene::image_io::save_frame(&out.join(&file), frame)?;
            cells.push(format!("![{what}]({file})"));
        }
        md += &format!(
            "\n{}, {}: plain {:.2} dB, distilled {:.2} dB ({:+.2}).\n\n| native | plain | distilled |\n|---|---|---|\n| {} |\n",
            w.profile,
            w.camera,
            w.plain_psnr,
            w.distilled_psnr,
            w.distilled_psnr - w.plain_psnr,
            cells.join(" | ")
        );
    }
    let path = out.join("distill.md");
    std::fs::write(&path, md).with_context(|| path.display().to_string())?;
    Ok(())
}
