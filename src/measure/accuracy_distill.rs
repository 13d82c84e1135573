//! Distillation rows of the accuracy sweep (`accuracy --only distill`): PSNR on the sweep's
//! cameras, which the fit never sees, against distillation time and iterations.
//!
//! Fitting views, at the size of the sweep's cameras: `n` cameras half-way between those of the standard `n`-camera orbit (the odd
//! cameras of the 2n rig, [`crate::distill::views::held_back`]); any that coincides with a
//! sweep camera is dropped, so every measured view is held back. Each profile is fitted once
//! and measured at the checkpoints; iteration 0 is the undistilled export.

use std::path::Path;

use anyhow::Context;
use splatbridge_convert::{ConvertOptions, Profile};

use crate::distill::{views, DistillOptions, Distiller};
use crate::measure::accuracy::Sweep;
use crate::measure::parity;
use crate::measure::report::plot::{self, Point};
use crate::measure::report::Record;

/// What the distillation rows fit.
#[derive(Clone, Debug)]
pub struct DistillSweep {
    pub profiles: Vec<Profile>,
    /// Fitting views (half-way around the orbit).
    pub views: usize,
    /// Fitting image size; None: the size of the sweep's cameras (a fit is made for the size
    /// it is seen at: fitted at 240×180 and measured at 320×240, the footprint-widened
    /// `texture` profile of `pc_short` fell from 41.24 to 40.63 dB; docs/distill.md).
    pub size: Option<(u32, u32)>,
    /// Iterations at which the held-back views are measured (ascending).
    pub checkpoints: Vec<usize>,
    pub options: DistillOptions,
}

impl Default for DistillSweep {
    fn default() -> Self {
        DistillSweep {
            profiles: vec![Profile::MeshSplats, Profile::Rings, Profile::Texture],
            views: crate::distill::DEFAULT_VIEWS,
            size: None,
            checkpoints: vec![0, 5, 10, 20, 40, 60],
            options: DistillOptions::default(),
        }
    }
}

/// One measured checkpoint: the record and the distillation seconds it took (set-up
/// included), for the curve.
pub struct CurvePoint {
    pub record: Record,
    pub seconds: f64,
    pub iterations: usize,
    pub profile: String,
    /// The undistilled MeshSplats profile made from the Gaussians as they are: the MeshSplats
    /// default, marked in the plot (not when the fit's mesh is widened for the footprint).
    pub baseline: bool,
}

/// Fit each profile and measure the sweep's cameras at every checkpoint.
pub fn distill_rows(s: &Sweep<'_>, cfg: &DistillSweep) -> anyhow::Result<Vec<CurvePoint>> {
    let scene = s.scene;
    let (width, height) = cfg.size.unwrap_or_else(|| {
        s.cameras
            .first()
            .map_or((240, 180), |c| (c.width, c.height))
    });
    let fit: Vec<_> = views::held_back(s.cloud(), cfg.views, cfg.views, width, height)?
        .into_iter()
        .filter(|f| {
            s.cameras
                .iter()
                .all(|c| (c.centre - f.centre).length() > 1e-6 * (1.0 + c.centre.length()))
        })
        .collect();
    let last = cfg.checkpoints.iter().copied().max().unwrap_or(0);
    let mut out = Vec::new();
    for &profile in &cfg.profiles {
        let name = profile_name(profile);
        let convert = ConvertOptions {
            profile,
            ..ConvertOptions::default()
        };
        let opts = DistillOptions {
            iterations: last,
            ..cfg.options.clone()
        };
        let (mut d, widened) = Distiller::for_export(scene, &convert, &fit, &opts)
            .with_context(|| format!("distilling profile {name}"))?;
        let triangles = d.triangles();
        loop {
            let it = d.history.len();
            if cfg.checkpoints.contains(&it) {
                let seconds = d.elapsed();
                let mut psnr = 0.0;
                let mut ms = 0.0;
                let mut first: Option<Record> = None;
                for (cam, reference) in s.cameras.iter().zip(s.references) {
                    let t0 = std::time::Instant::now();
                    let img = d.render(cam)?;
                    let t_ms = t0.elapsed().as_secs_f64() * 1e3;
                    let r = parity::measure(
                        reference,
                        &img,
                        Record {
                            renderer: "trace-mesh".into(),
                            profile: name.into(),
                            knob: "distill".into(),
                            value: format!("{name} it={it} ({seconds:.1} s)"),
                            camera: format!("mean of {}", s.cameras.len()),
                            time: s.time,
                            milliseconds: t_ms,
                            triangles,
                            ..Record::default()
                        },
                    )?;
                    psnr += r.psnr / s.cameras.len() as f64;
                    ms += t_ms / s.cameras.len() as f64;
                    first.get_or_insert(r);
                }
                let mut record = first.context("no camera")?;
                record.psnr = psnr;
                record.milliseconds = ms;
                out.push(CurvePoint {
                    baseline: profile == Profile::MeshSplats && it == 0 && widened.is_none(),
                    record,
                    seconds,
                    iterations: it,
                    profile: name.into(),
                });
            }
            if it >= last {
                break;
            }
            d.step()?;
        }
    }
    Ok(out)
}

fn profile_name(p: Profile) -> &'static str {
    match p {
        Profile::MeshSplats => "meshsplats",
        Profile::Rings => "rings",
        Profile::Texture => "texture",
    }
}

/// `distill.md` and the plot of held-back PSNR against distillation seconds, in `out`.
pub fn write_curve(out: &Path, what: &str, points: &[CurvePoint]) -> anyhow::Result<()> {
    let pts: Vec<Point> = points
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
        "# Distillation: held-back PSNR against time\n\n{what}. Views measured are never fitted. \
         Iteration 0 is the undistilled export.\n\n![PSNR against distillation time](psnr_vs_distill_time.png)\n\n\
         | profile | iterations | seconds | PSNR dB | SSIM | triangles |\n|---|---|---|---|---|---|\n"
    );
    for p in points {
        md += &format!(
            "| {} | {} | {:.1} | {:.2} | {:.4} | {} |\n",
            p.profile, p.iterations, p.seconds, p.record.psnr, p.record.ssim, p.record.triangles
        );
    }
    let path = out.join("distill.md");
    std::fs::write(&path, md).with_context(|| path.display().to_string())?;
    Ok(())
}
