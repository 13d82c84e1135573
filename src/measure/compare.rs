//! `compare` as a run: the cameras and times it measures at, and the comparison written as one
//! set (every image, heat-map, export and report staged inside the output folder and moved
//! into place only when the whole comparison succeeded), whole or as one shard's partial
//! report. The measuring itself is [`super::parity`]'s.

use std::path::Path;

use anyhow::Context;
use splatbridge_convert::Profile;
use splatbridge_scene::camera_spec::{parse_camera_list, CameraRequest, CameraSource, CameraSpec};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::output::OutputSet;
use splatbridge_scene::{Camera, GaussianCloud};

use super::parity::{self, CompareConfig};
use super::report::Record;
use crate::batch::merge::{self, PartialReport};
use crate::batch::shard::{Shard, WorkKey};

/// The report's title.
pub const TITLE: &str = "splatbridge compare";

/// The cameras of a `--cameras` list (comma-separated) at `width`×`height` (orbit rigs frame
/// `cloud`).
pub fn resolve_cameras(
    spec: &str,
    cloud: &GaussianCloud,
    scene: &DynamicScene,
    width: u32,
    height: u32,
) -> anyhow::Result<Vec<Camera>> {
    let items = parse_camera_list(spec).with_context(|| format!("--cameras '{spec}'"))?;
    let mut request = CameraRequest::new(CameraSpec::Scene(0));
    request.width = Some(width);
    request.height = Some(height);
    let cams = request.resolve_list(
        &items,
        CameraSource {
            cloud,
            own: &scene.cameras,
        },
    )?;
    if cams.is_empty() {
        anyhow::bail!("--cameras '{spec}' names no camera");
    }
    Ok(cams)
}

/// The cameras of `spec` for a comparison at `times`: orbit rigs frame the first time's
/// composite; a static scene's is its own cloud, and a dynamic scene's copy is dropped before
/// anything is rendered.
pub fn scene_cameras(
    spec: &str,
    scene: &DynamicScene,
    times: &[f64],
    width: u32,
    height: u32,
) -> anyhow::Result<Vec<Camera>> {
    if scene.objects.is_empty() {
        resolve_cameras(spec, &scene.static_gaussians, scene, width, height)
    } else {
        let frame0 = scene.composite_view(times[0]);
        resolve_cameras(spec, &frame0, scene, width, height)
    }
}

/// The default times: the start of a static scene; start, middle and end of a dynamic one.
pub fn default_times(scene: &DynamicScene) -> Vec<f64> {
    if scene.objects.is_empty() && scene.four_d.is_none() {
        vec![scene.time.start]
    } else {
        let (a, b) = (scene.time.start, scene.time.end);
        vec![a, 0.5 * (a + b), b]
    }
}

/// Converter profiles by name (meshsplats, rings, texture).
pub fn parse_profiles(names: &[String]) -> anyhow::Result<Vec<Profile>> {
    names
        .iter()
        .map(|n| match n.as_str() {
            "meshsplats" => Ok(Profile::MeshSplats),
            "rings" => Ok(Profile::Rings),
            "texture" => Ok(Profile::Texture),
            other => anyhow::bail!("unknown profile '{other}' (meshsplats, rings, texture)"),
        })
        .collect()
}

/// What a comparison wrote.
pub enum Compared {
    /// The whole comparison: its records in report order (`report.md`, `report.json`).
    Whole(Vec<Record>),
    /// One shard's partial report, with this many records.
    Shard(Shard, usize),
}

/// Compare `scene` at `cams` × `times` into `out`. With `shard`, only the (time, camera)
/// items it owns, written as a partial report whose options hash is `options_text`'s.
pub fn run_compare(
    scene: &mut DynamicScene,
    cams: &[Camera],
    times: &[f64],
    cfg: &CompareConfig,
    out: &Path,
    shard: Option<Shard>,
    options_text: &str,
    preamble: String,
    progress: &dyn Fn(&str),
) -> anyhow::Result<Compared> {
    let mut outputs = OutputSet::new();
    let stage = outputs.stage_dir(out)?;
    let Some(shard) = shard else {
        let placed =
            parity::compare_selected(scene, cams, times, &stage, cfg, &|_, _| true, progress)?;
        let records = parity::report_order(placed);
        parity::write_reports(&stage, TITLE, &preamble, &records)?;
        outputs.commit()?;
        return Ok(Compared::Whole(records));
    };
    let hash = merge::scene_hash(scene);
    let key = |ti: usize, ci: usize| WorkKey {
        scene: hash.clone(),
        time: times[ti],
        camera: format!("{ci}:{}", cams[ci].name),
        setting: String::new(),
    };
    let owned = |ti: usize, ci: usize| shard.owns(&key(ti, ci));
    let placed = parity::compare_selected(scene, cams, times, &stage, cfg, &owned, progress)?;
    let n = placed.len();
    let report = PartialReport {
        format: merge::PARTIAL_FORMAT.into(),
        command: "compare".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        scene_hash: hash.clone(),
        options_hash: merge::options_hash(options_text),
        shard,
        title: TITLE.into(),
        preamble,
        files: Vec::new(),
        peak_memory_bytes: 0,
        records: placed,
    };
    merge::commit_shard(outputs, &stage, report)?;
    Ok(Compared::Shard(shard, n))
}
