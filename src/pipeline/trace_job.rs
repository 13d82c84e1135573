//! `trace` as one call: prepare the input ([`TraceSource`]), build the tracer once, then trace
//! one frame (with its LiDAR scans, and a sharded scan's partial report) or every frame of the
//! scene's time range as one atomic sequence. The command maps its arguments into a
//! [`TraceJob`] and prints what [`run_trace`] returns.

use std::path::PathBuf;

use anyhow::{bail, Context};
use splatbridge_raytrace::{BackendKind, BuildPreset};
use splatbridge_scene::effects::EffectCounters;
use splatbridge_scene::image_io::save_frame;

use super::export_shard::{folder_of, write_partial};
use super::sequence::{render_sequence, SequenceFrame, SequenceRequest, SequenceRun};
use super::source::is_mesh_file;
use super::still::check_image_output;
use super::{render_frame, FrameRequest, LidarRequest, Prepared, RenderedFrame, Renderer};
use super::{TraceMode, TraceSource};
use crate::batch::shard::Shard;

/// One `trace` run.
pub struct TraceJob {
    pub source: TraceSource,
    pub backend: BackendKind,
    pub preset: BuildPreset,
    /// The image (`.png` or `.exr`); with `frames`, the pattern of the frames' names.
    pub output: PathBuf,
    /// Where LiDAR scans go (default: the output's directory).
    pub lidar_out: Option<PathBuf>,
    /// Scan every frame of the time range, not only the traced one.
    pub lidar_all_frames: bool,
    /// Trace every frame of the time range.
    pub frames: bool,
    pub shard: Option<Shard>,
    /// The options as text for a sharded run's options hash (the input, backend and output
    /// name); the run's kind is prefixed.
    pub canonical: String,
}

/// One traced frame (written), with the tracer's build time.
pub struct TracedImage {
    pub prepared: Prepared,
    pub rendered: RenderedFrame,
    pub build_seconds: f64,
    pub lidar_dir: PathBuf,
}

/// What a trace did.
pub enum Traced {
    Image(Box<TracedImage>),
    /// A `--frames` sequence (each frame went to `on_frame` as it was staged).
    Frames {
        prepared: Box<Prepared>,
        run: SequenceRun,
    },
}

/// Run `job` (`warn` gets the loaders' warnings; `on_frame` sees each frame of a sequence).
pub fn run_trace(
    job: &TraceJob,
    warn: &dyn Fn(&str),
    on_frame: &mut dyn FnMut(&SequenceFrame) -> anyhow::Result<()>,
) -> anyhow::Result<Traced> {
    check_image_output(&job.output)?;
    if job.shard.is_some() && !job.frames && !job.lidar_all_frames {
        bail!("--shard: splits --frames or --lidar-all-frames");
    }
    let name = job.source.input.display().to_string();
    let all_frames = job.lidar_all_frames && job.source.mode == TraceMode::Mesh;
    let mut p = job.source.prepare(all_frames, warn)?;
    // One tracer for every shutter sample: mode mesh instances its nodes at each time, mode
    // gaussian re-poses its objects (no BVH rebuild per sample).
    // One frame without every-frame scans needs nothing more of the scene's Gaussians once
    // they are in the tracer (a sequence hashes the scene for its shards; an every-frame
    // Gaussian scan builds tracers from it).
    let take_gaussians = !job.frames && !job.lidar_all_frames;
    let mut tracer = Renderer::tracer_taking(&mut p, job.backend, job.preset, take_gaussians)
        .with_context(|| name.clone())?;
    let lidar_dir = match &job.lidar_out {
        Some(d) => d.clone(),
        None => folder_of(&job.output),
    };
    if job.frames {
        let run = trace_frames(job, &p, tracer, &lidar_dir, warn, on_frame)?;
        return Ok(Traced::Frames {
            prepared: Box::new(p),
            run,
        });
    }
    let req = FrameRequest {
        scene: p.effects_scene.as_ref(),
        effects: &p.effects,
        camera: &p.camera,
        time: p.time,
        content: p.counters.clone(),
        lidar: Some(LidarRequest {
            dir: lidar_dir.clone(),
            all_frames: job.lidar_all_frames,
            backend: job.backend,
            preset: job.preset,
            shard: job.shard,
        }),
    };
    let r = render_frame(&mut tracer, &req).with_context(|| name.clone())?;
    // After the frame: mode mesh builds a BVH the frame reads on its first use.
    let build_seconds = tracer.build_seconds();
    // LiDAR runs inside the frame, so a failing scan fails before the image is written.
    save_frame(&job.output, &r.frame)?;
    if job.shard.is_some() && r.lidar.is_none() {
        bail!("{name}: --shard splits LiDAR scans, and the scene declares no LiDAR");
    }
    if let (Some(shard), Some(scene), Some(run)) = (job.shard, &p.effects_scene, &r.lidar) {
        let mut files = run.files.clone();
        files.push(job.output.clone());
        let canonical = format!("trace --lidar-all-frames\n{}", job.canonical);
        write_partial(&lidar_dir, "trace", scene, &canonical, shard, &files)?;
    }
    Ok(Traced::Image(Box::new(TracedImage {
        prepared: p,
        rendered: r,
        build_seconds,
        lidar_dir,
    })))
}

/// `trace --frames`: every frame of the scene's time range through one tracer, through the
/// camera resolved for the traced input, as one atomic sequence. A scene that declares weather
/// is prepared again for each frame (its particles are drawn per frame, around the camera, as
/// a single `trace --time T` draws them), so each frame equals that single trace bit for bit;
/// an exported file's weather is drawn as exported.
fn trace_frames(
    job: &TraceJob,
    p: &Prepared,
    mut tracer: Renderer,
    lidar_dir: &std::path::Path,
    warn: &dyn Fn(&str),
    on_frame: &mut dyn FnMut(&SequenceFrame) -> anyhow::Result<()>,
) -> anyhow::Result<SequenceRun> {
    let name = job.source.input.display().to_string();
    let Some(scene) = p.effects_scene.as_ref() else {
        bail!("--frames: {name} has no time range; pass --effects-from MANIFEST (the scene it was exported from)");
    };
    let rebuild = p.effects.weather.is_some() && !is_mesh_file(&job.source.input);
    let mut built_at = p.time;
    let mut prepare = |r: &mut Renderer, t: f64| -> anyhow::Result<Option<EffectCounters>> {
        if !rebuild || t == built_at {
            return Ok(None);
        }
        let mut source = job.source.clone();
        source.time = t;
        let mut q = source.prepare(false, warn)?;
        *r = Renderer::tracer_taking(&mut q, job.backend, job.preset, true)?;
        built_at = t;
        Ok(Some(q.counters))
    };
    let req = SequenceRequest {
        command: "trace",
        scene,
        effects: &p.effects,
        camera: &p.camera,
        out: &job.output,
        content: p.counters.clone(),
        lidar: Some(LidarRequest {
            dir: lidar_dir.to_path_buf(),
            all_frames: false,
            backend: job.backend,
            preset: job.preset,
            shard: None,
        }),
        shard: job.shard,
        canonical: format!("trace --frames\n{}", job.canonical),
    };
    render_sequence(&mut tracer, &req, &mut prepare, on_frame).with_context(|| name.clone())
}
