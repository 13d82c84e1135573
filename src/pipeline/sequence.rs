//! A `--frames` sequence: every frame of a scene's time range through one renderer, written as
//! `OUT_NNNN.ext` — what `render --frames` and `trace --frames` run, sharded or not.
//!
//! The sequence is one atomic output set: its frames, the LiDAR scans a tracer makes of each
//! frame (`lidar_NNNN.ply`, staged with the frames), and with `--shard I/N` a partial
//! `report.json` appear together when the last frame is done, or not at all. A shard renders
//! the frames it owns (work item: scene hash, the frame's time, the camera's name,
//! `COMMAND i`; `crate::batch::shard`), so `splatbridge merge` of N shards gives the unsharded run's
//! files bit for bit. Frames are rendered one at a time and written as they are staged: memory
//! holds one frame, not the sequence.

use std::path::{Path, PathBuf};

use anyhow::bail;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::{EffectCounters, Effects};
use splatbridge_scene::image_io::stage_frame;
use splatbridge_scene::output::OutputSet;
use splatbridge_scene::Camera;

use super::export_shard::partial_report;
use super::frame::{render_frame, FrameRequest, LidarRequest, RenderedFrame};
use super::renderer::Renderer;
use crate::batch::merge::{scene_hash, REPORT};
use crate::batch::shard::{Shard, WorkKey};

/// A sequence to render.
pub struct SequenceRequest<'a> {
    /// `render` or `trace`: names the work items and the merge.
    pub command: &'a str,
    pub scene: &'a DynamicScene,
    pub effects: &'a Effects,
    pub camera: &'a Camera,
    /// Frame `i` is written to `OUT_{i:04}.ext`.
    pub out: &'a Path,
    /// What building the tracers' content cost (their weather particles); empty otherwise.
    pub content: EffectCounters,
    /// Tracers: scan the declared LiDAR of each frame into this folder (`lidar_NNNN.ply`).
    pub lidar: Option<LidarRequest>,
    pub shard: Option<Shard>,
    /// Every option that shapes the files (hashed into the partial report, so shards run with
    /// different options do not merge); not the output folder, which differs per shard.
    pub canonical: String,
}

/// One frame of a sequence, as it is staged.
pub struct SequenceFrame<'a> {
    pub index: usize,
    pub time: f64,
    /// Where the frame appears when the sequence commits.
    pub path: PathBuf,
    pub rendered: &'a RenderedFrame,
    /// The LiDAR scans of this frame, at their final paths.
    pub lidar_files: Vec<PathBuf>,
}

/// What a sequence did.
#[derive(Default)]
pub struct SequenceRun {
    /// Frames rendered by this run (a shard's own).
    pub frames: usize,
    /// Frames of the whole sequence.
    pub total: usize,
    pub counters: EffectCounters,
}

/// `out` with `_suffix` before its extension.
pub fn with_suffix(out: &Path, suffix: &str) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = out
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    out.with_file_name(format!("{stem}_{suffix}{ext}"))
}

/// The work key of frame `index` at `time` of `command`'s sequence through `camera`.
pub fn sequence_key(
    scene_hash: &str,
    command: &str,
    camera: &str,
    index: usize,
    time: f64,
) -> WorkKey {
    WorkKey {
        scene: scene_hash.to_string(),
        time,
        camera: camera.to_string(),
        setting: format!("{command} {index}"),
    }
}

/// Render `req`'s sequence through `r`. `prepare(r, t)` runs before each frame: a tracer whose
/// content depends on the frame (weather particles) is rebuilt there, and returns what building
/// it cost (`None`: `r` is kept, its content counted once, with the first frame); `on_frame`
/// sees each frame as it is staged (for printing). Nothing is visible until the last frame.
pub fn render_sequence(
    r: &mut Renderer,
    req: &SequenceRequest,
    prepare: &mut dyn FnMut(&mut Renderer, f64) -> anyhow::Result<Option<EffectCounters>>,
    on_frame: &mut dyn FnMut(&SequenceFrame) -> anyhow::Result<()>,
) -> anyhow::Result<SequenceRun> {
    let times = req.scene.frame_times();
    let hash = req.shard.map(|_| scene_hash(req.scene));
    let mut set = OutputSet::new();
    let lidar_stage = match &req.lidar {
        Some(l) if req.effects.lidar.is_some() => Some((set.stage_dir(&l.dir)?, l.dir.clone())),
        _ => None,
    };
    let out_dir = super::export_shard::folder_of(req.out);
    if let (Some(_), Some((_, dir))) = (req.shard, &lidar_stage) {
        if *dir != out_dir {
            bail!(
                "--lidar-out: a sharded sequence writes its scans beside its frames ({}), not in {}",
                out_dir.display(),
                dir.display()
            );
        }
    }
    let mut run = SequenceRun {
        total: times.len(),
        ..SequenceRun::default()
    };
    let mut listed = Vec::new();
    for (i, &t) in times.iter().enumerate() {
        if let (Some(shard), Some(h)) = (req.shard, &hash) {
            if !shard.owns(&sequence_key(h, req.command, &req.camera.name, i, t)) {
                continue;
            }
        }
        let content = prepare(r, t)?;
        let lidar = match (&req.lidar, &lidar_stage) {
            (Some(l), Some((stage, _))) => Some(LidarRequest {
                dir: stage.clone(),
                all_frames: false,
                shard: None,
                ..l.clone()
            }),
            _ => None,
        };
        let frame_req = FrameRequest {
            scene: Some(req.scene),
            effects: req.effects,
            camera: req.camera,
            time: t,
            content: match content {
                Some(c) => c,
                None if run.frames == 0 => req.content.clone(),
                None => EffectCounters::default(),
            },
            lidar,
        };
        let rendered = render_frame(r, &frame_req)?;
        let path = with_suffix(req.out, &format!("{i:04}"));
        stage_frame(&mut set, &path, &rendered.frame)?;
        listed.push(path.clone());
        let mut lidar_files = Vec::new();
        if let (Some(scan), Some((_, dir))) = (&rendered.lidar, &lidar_stage) {
            for f in &scan.files {
                if let Some(name) = f.file_name() {
                    lidar_files.push(dir.join(name));
                }
            }
        }
        listed.extend(lidar_files.iter().cloned());
        run.counters.add(&rendered.counters);
        run.frames += 1;
        on_frame(&SequenceFrame {
            index: i,
            time: t,
            path,
            rendered: &rendered,
            lidar_files,
        })?;
    }
    if let (Some(shard), Some(scene_hash)) = (req.shard, hash) {
        let partial = partial_report(req.command, scene_hash, &req.canonical, shard, &listed);
        set.write(
            &out_dir.join(REPORT),
            serde_json::to_string_pretty(&partial)?.as_bytes(),
        )?;
    }
    set.commit()?;
    Ok(run)
}
