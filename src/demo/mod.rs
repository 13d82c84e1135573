//! `splatbridge demo`: the first run. A real capture shipped with the project
//! (`fixtures/real/fourth_st.spz`) is converted the ways a user takes it away and rendered by
//! every renderer, each measured against native splatting; `report.md` opens with one picture
//! (native and each output side by side, PSNR under each) and a table of which export to use
//! for which viewer. The built-in street scene follows for what a capture cannot show: moving
//! objects as animated nodes. Every stage is timed (wall and CPU).
//!
//! The command only parses arguments and prints; this module orchestrates the library
//! (`parity`, `distill`, the converter and the report writers).

pub mod capture;
pub mod picture;
pub mod report;
pub mod stages;
pub mod street;

use std::path::{Path, PathBuf};

use anyhow::Context;

pub use capture::{CaptureConfig, CaptureRun};
pub use stages::{Stage, Stages};
pub use street::{StreetConfig, StreetRun};

/// The outputs shown in the picture, left to right.
pub const PICTURE_KEYS: [&str; 5] = ["native", "glb", "distilled", "hybrid", "trace-gaussian"];

/// What the demo runs. `street: None` leaves the dynamic part out.
#[derive(Clone, Debug, Default)]
pub struct DemoConfig {
    pub capture: CaptureConfig,
    pub street: Option<StreetConfig>,
}

/// What the demo wrote and measured.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DemoRun {
    pub capture: CaptureRun,
    pub street: Option<StreetRun>,
    /// Every stage of the run, capture and street, in order.
    pub stages: Stages,
    pub report: PathBuf,
    pub picture: PathBuf,
    pub picture_size: (u32, u32),
}

/// Run the demo into `out`: `report.md`, `report.json`, `overview.png`, the capture's
/// exports and images, and the street's part in `out/street`.
pub fn run(cfg: &DemoConfig, out: &Path, progress: &dyn Fn(&str)) -> anyhow::Result<DemoRun> {
    std::fs::create_dir_all(out)
        .with_context(|| format!("{}: cannot create the output folder", out.display()))?;
    let (capture, frames) = capture::run(&cfg.capture, out, progress)?;
    let mut all = capture.stages.clone();
    let street = match &cfg.street {
        Some(s) => {
            let st = street::run(s, &out.join("street"), progress)?;
            all.stages.extend(st.stages.stages.iter().cloned());
            Some(st)
        }
        None => None,
    };
    let picture = out.join(report::PICTURE);
    let report_md = out.join("report.md");
    let mut picture_size = (0, 0);
    // The stage's own time is not in the table it writes; it is a few hundred milliseconds
    // (a PNG and two text files).
    let mut tail = Stages::default();
    tail.time("picture and report", || -> anyhow::Result<()> {
        let panels: Vec<picture::Panel<'_>> = PICTURE_KEYS
            .iter()
            .filter_map(|k| {
                let o = capture.output(k)?;
                let (_, f) = frames.iter().find(|(fk, _)| fk == k)?;
                Some(picture::Panel {
                    frame: f,
                    title: o.title.clone(),
                    caption: report::caption(o),
                })
            })
            .collect();
        let img = picture::compose(&panels)?;
        picture_size = (img.width, img.height);
        img.save_png(&picture)?;
        let md = report::markdown(&capture, street.as_ref(), &all, stages::load_average());
        splatbridge_scene::image_io::write_atomic(&report_md, md.as_bytes())?;
        Ok(())
    })?;
    all.stages.extend(tail.stages);
    let run = DemoRun {
        capture,
        street,
        stages: all,
        report: report_md,
        picture,
        picture_size,
    };
    let json = serde_json::to_string_pretty(&run)?;
    splatbridge_scene::image_io::write_atomic(&out.join("report.json"), json.as_bytes())?;
    Ok(run)
}
