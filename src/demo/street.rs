//! The demo's dynamic part, on the built-in street scene (generated in memory): an animated
//! GLB (the cars as animated nodes, the scene's cameras), an OBJ of the first frame, and the
//! parity pipeline (`parity::compare`) over a few cameras at two times, with its report.

use std::path::{Path, PathBuf};

use anyhow::Context;
use splatbridge_convert::{ConvertOptions, Profile};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::fixtures::{street_with, StreetParams};

use super::stages::Stages;
use crate::measure::parity::{self, CompareConfig};
use crate::measure::report::Record;

/// What the street part runs.
#[derive(Clone, Debug)]
pub struct StreetConfig {
    pub seed: u64,
    /// Gaussians of the generated street (static plus cars).
    pub gaussians: usize,
    /// Size of the compared images (the scene's cameras are resized).
    pub width: u32,
    pub height: u32,
    /// How many of the scene's four cameras are compared.
    pub cameras: usize,
    /// Converter profiles traced (GLB; OBJ of each per frame when `obj`).
    pub profiles: Vec<Profile>,
    pub obj: bool,
}

impl Default for StreetConfig {
    fn default() -> Self {
        // A quarter of the comparisons the street demo used to run (4 cameras × 3 profiles
        // with OBJ at 320×240): the capture now shows the quality, the street the motion.
        StreetConfig {
            seed: 1,
            gaussians: splatbridge_scene::fixtures::DEFAULT_STREET_GAUSSIANS,
            width: 160,
            height: 120,
            cameras: 2,
            profiles: vec![Profile::Texture],
            obj: false,
        }
    }
}

/// What the street part wrote and measured.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StreetRun {
    pub glb: PathBuf,
    pub glb_bytes: u64,
    pub glb_triangles: u64,
    pub obj: PathBuf,
    pub objects: usize,
    pub gaussians: usize,
    pub records: Vec<Record>,
    pub stages: Stages,
}

/// Run the street part into `dir` (its own `report.md` there).
pub fn run(cfg: &StreetConfig, dir: &Path, progress: &dyn Fn(&str)) -> anyhow::Result<StreetRun> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the output folder", dir.display()))?;
    let mut stages = Stages::default();
    let mut scene = street_with(&StreetParams::new(cfg.seed, cfg.gaussians));
    let opts = ConvertOptions::default();
    let glb = dir.join("street.glb");
    let obj = dir.join("street_t0.obj");
    let report = stages.time("street: scene, animated GLB and first-frame OBJ", || {
        progress("street exports");
        splatbridge_scene::manifest::save_manifest(&dir.join("scene"), &scene)?;
        let report = splatbridge_convert::convert_to_file(&glb, &scene, None, &opts, false)?;
        // OBJ cannot animate: one OBJ of the first frame (`convert --frames` writes every frame).
        let first = DynamicScene::from_static(scene.composite(scene.time.start));
        splatbridge_convert::convert_to_file(&obj, &first, None, &opts, false)?;
        anyhow::Ok(report)
    })?;
    let cams: Vec<_> = scene
        .cameras
        .iter()
        .take(cfg.cameras.max(1))
        .map(|c| c.resized(cfg.width, cfg.height))
        .collect();
    let times = vec![scene.time.start, 0.5 * (scene.time.start + scene.time.end)];
    let compare_cfg = CompareConfig {
        profiles: cfg.profiles.clone(),
        obj: cfg.obj,
        ..CompareConfig::default()
    };
    let records = stages.time(
        &format!(
            "street: compare, {} cameras × {} times",
            cams.len(),
            times.len()
        ),
        || {
            parity::compare(
                &mut scene,
                &cams,
                &times,
                &dir.join("compare"),
                &compare_cfg,
                progress,
            )
        },
    )?;
    let rel: Vec<_> = records
        .iter()
        .cloned()
        .map(|mut r| {
            r.image = format!("compare/{}", r.image);
            r.heatmap = format!("compare/{}", r.heatmap);
            r
        })
        .collect();
    let preamble = format!(
        "The built-in street scene (seed {}): {} static Gaussians, {} moving objects, {} cameras, {:.1}–{:.1} s at {} fps.\n\n\
         Exports: `street.glb` ({} triangles, {} bytes; profile `{}`, animated object nodes and the scene's cameras) and \
         `street_t0.obj` (the first frame: OBJ has neither per-vertex alpha nor animation; `convert --frames` writes one OBJ per frame). The scene itself is in `scene/` \
         (manifest, PLYs, cameras.json).\n\n\
         Every image below is measured against native splatting (the reference) at the same camera and time.",
        cfg.seed,
        scene.static_gaussians.len(),
        scene.objects.len(),
        scene.cameras.len(),
        scene.time.start,
        scene.time.end,
        scene.time.fps,
        report.triangles,
        report.bytes,
        opts.profile.name(),
    );
    parity::write_reports(
        dir,
        "splatbridge demo: the street (dynamic)",
        &preamble,
        &rel,
    )?;
    Ok(StreetRun {
        glb,
        glb_bytes: report.bytes,
        glb_triangles: report.triangles,
        obj,
        objects: scene.objects.len(),
        gaussians: scene.static_gaussians.len()
            + scene
                .objects
                .iter()
                .map(|o| o.gaussians.len())
                .sum::<usize>(),
        records: rel,
        stages,
    })
}
