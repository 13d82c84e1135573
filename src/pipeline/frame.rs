//! One frame with its declared effects, for every renderer: [`render_frame`].
//!
//! Native splatting and the hybrid draw the cloud `effects_run::build_blur_frames` builds
//! (composite, weather particles, and with `motion_blur` one cloud per shutter sample). The
//! tracers draw their prebuilt BVHs posed at each of `effects_run::time_samples`, with sun
//! shadows (`raytrace::shadows`) when declared; their content counters (weather particles,
//! built with the BVH) come in with the request. Samples are averaged by `blend_frames`; with
//! nothing declared the one sample is drawn as is, so the image is the plain render bit for bit.
//! LiDAR (tracers only) scans the traced frame, or every frame of the scene, and writes one PLY
//! per frame. The counters say what ran and what the renderer does not simulate.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use splatbridge_raytrace::lidar::{
    frame_file, scan, scan_mesh_frames_selected, scan_scene_gaussian_selected, write_ply, LidarRun,
    LidarSensor,
};
use splatbridge_raytrace::shadows::{
    gaussian_bounds, mesh_bounds, render_gaussian_shadowed, render_mesh_shadowed, SunShadows,
};
use splatbridge_raytrace::{BackendKind, BuildPreset, Stats};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::{EffectCounters, Effects};
use splatbridge_scene::effects_run::{
    blend_frames, build_blur_frames, not_simulated, time_samples,
};
use splatbridge_scene::{Camera, Frame};

use super::renderer::{FrameStats, Renderer};

/// Effects native splatting and the hybrid simulate (the others are ray-traced).
pub const CLOUD_SIMULATES: &[&str] = &["weather", "motion_blur"];
/// Effects the tracers simulate.
pub const TRACE_SIMULATES: &[&str] = &["weather", "motion_blur", "shadows", "lidar"];

/// Where and how LiDAR scans are written (tracers only).
#[derive(Clone, Debug)]
pub struct LidarRequest {
    pub dir: PathBuf,
    /// Scan every frame of the scene's time range, not only the traced one.
    pub all_frames: bool,
    /// Backend and preset of the per-frame tracers of an every-frame Gaussian scan.
    pub backend: BackendKind,
    pub preset: BuildPreset,
    /// With `all_frames`: scan only the frames this shard owns (work key: scene hash, the
    /// frame's time, no camera, `lidar I`; see `crate::batch::shard`).
    pub shard: Option<crate::batch::shard::Shard>,
}

/// The work key of LiDAR frame `index` at `time`.
pub fn lidar_key(scene_hash: &str, index: usize, time: f64) -> crate::batch::shard::WorkKey {
    crate::batch::shard::WorkKey {
        scene: scene_hash.to_string(),
        time,
        camera: String::new(),
        setting: format!("lidar {index}"),
    }
}

/// One frame to render.
pub struct FrameRequest<'a> {
    /// The scene whose content (native, hybrid) and declared effects apply; `None` for an
    /// exported file traced without a manifest (drawn as exported, one sample).
    pub scene: Option<&'a DynamicScene>,
    pub effects: &'a Effects,
    pub camera: &'a Camera,
    pub time: f64,
    /// What building the tracers' content cost (their weather particles); empty otherwise.
    pub content: EffectCounters,
    /// Scan the declared LiDAR here (tracers).
    pub lidar: Option<LidarRequest>,
}

/// A rendered frame and what it cost.
pub struct RenderedFrame {
    pub frame: Frame,
    /// Summed over the shutter samples.
    pub stats: FrameStats,
    pub time_samples: usize,
    /// Shadow rays and LiDAR are counted here too.
    pub counters: EffectCounters,
    pub lidar: Option<LidarRun>,
    /// An exported file's weather, drawn as exported (its per-frame particle nodes).
    pub exported_weather: bool,
}

/// Render one frame with its declared effects.
pub fn render_frame(r: &mut Renderer, req: &FrameRequest) -> anyhow::Result<RenderedFrame> {
    if r.draws_clouds() {
        render_cloud_frame(r, req)
    } else {
        render_traced_frame(r, req)
    }
}

fn blend(mut frames: Vec<Frame>, weights: &[f32]) -> anyhow::Result<Frame> {
    if frames.len() == 1 {
        if let Some(f) = frames.pop() {
            return Ok(f);
        }
    }
    Ok(blend_frames(&frames, weights)?)
}

fn render_cloud_frame(r: &mut Renderer, req: &FrameRequest) -> anyhow::Result<RenderedFrame> {
    let Some(scene) = req.scene else {
        bail!("native splatting and the hybrid need a scene");
    };
    if req.effects.is_empty() && scene.effects.is_empty() {
        // Nothing declared: the frame is the scene's cloud at the time, which a static scene
        // lends rather than copies (the copy was 10–20 % of a 131k-Gaussian render).
        let cloud = scene.composite_view(req.time);
        let (frame, st) = r.render_cloud(&cloud, req.camera)?;
        let mut stats = FrameStats::zero_for(r);
        stats.add(&st)?;
        return Ok(RenderedFrame {
            frame,
            stats,
            time_samples: 1,
            counters: EffectCounters::default(),
            lidar: None,
            exported_weather: false,
        });
    }
    let blur = build_blur_frames(scene, req.time, Some(req.camera))?;
    let mut stats = FrameStats::zero_for(r);
    let mut frames = Vec::with_capacity(blur.samples.len());
    for s in &blur.samples {
        let (f, st) = r.render_cloud(&s.cloud, req.camera)?;
        frames.push(f);
        stats.add(&st)?;
    }
    let weights: Vec<f32> = blur.samples.iter().map(|s| s.weight).collect();
    let mut counters = blur.counters;
    counters.not_simulated = not_simulated(req.effects, CLOUD_SIMULATES);
    Ok(RenderedFrame {
        frame: blend(frames, &weights)?,
        stats,
        time_samples: blur.samples.len(),
        counters,
        lidar: None,
        exported_weather: false,
    })
}

/// One traced shutter sample and what its shadows cost.
struct Traced {
    frame: Frame,
    stats: Stats,
    shadow_rays: u64,
    shadow_ms: f64,
}

fn trace_sample(
    r: &Renderer,
    cam: &Camera,
    time: f64,
    effects: &Effects,
) -> anyhow::Result<Traced> {
    let Some(s) = &effects.shadows else {
        let (frame, stats) = r.render_traced(cam, time)?;
        return Ok(Traced {
            frame,
            stats,
            shadow_rays: 0,
            shadow_ms: 0.0,
        });
    };
    let (frame, stats, st) = match r {
        Renderer::Mesh { tracer, options } => {
            let (lo, hi) = mesh_bounds(tracer, time);
            let sun = SunShadows::from_effect(s, lo, hi)?;
            render_mesh_shadowed(tracer, cam, time, options, &sun)?
        }
        Renderer::Gaussian { tracer, options } => {
            let (lo, hi) = gaussian_bounds(tracer);
            let sun = SunShadows::from_effect(s, lo, hi)?;
            render_gaussian_shadowed(tracer, cam, options, &sun)?
        }
        _ => bail!("shadows are ray-traced"),
    };
    Ok(Traced {
        frame,
        stats,
        shadow_rays: st.shadow_rays,
        // Shadow-ray time is summed over worker threads; divided by their number it estimates
        // the wall time the shadows added.
        shadow_ms: st.cpu_seconds * 1e3 / rayon::current_num_threads().max(1) as f64,
    })
}

fn render_traced_frame(r: &mut Renderer, req: &FrameRequest) -> anyhow::Result<RenderedFrame> {
    let samples = match req.scene {
        Some(s) => time_samples(s, req.time)?,
        None => vec![(req.time, 1.0)],
    };
    let mut counters = req.content.clone();
    let mut traced = Vec::with_capacity(samples.len());
    let mut blur_ms = 0.0;
    for (i, &(ts, _)) in samples.iter().enumerate() {
        let start = Instant::now();
        r.set_time(ts)?;
        traced.push(trace_sample(r, req.camera, ts, req.effects)?);
        if i > 0 {
            blur_ms += start.elapsed().as_secs_f64() * 1e3;
        }
    }
    r.set_time(req.time)?;
    if req.effects.motion_blur.is_some() && !counters.simulated.iter().any(|n| n == "motion_blur") {
        counters.extra_time_samples += samples.len() as u64 - 1;
        counters.simulated.push("motion_blur".into());
    }
    counters.milliseconds += blur_ms;
    let mut stats = FrameStats::Trace(Stats::default());
    let mut shadow_rays = 0;
    let mut frames = Vec::with_capacity(traced.len());
    for t in traced {
        stats.add(&FrameStats::Trace(t.stats))?;
        shadow_rays += t.shadow_rays;
        counters.milliseconds += t.shadow_ms;
        frames.push(t.frame);
    }
    if req.effects.shadows.is_some() {
        counters.shadow_rays += shadow_rays;
        counters.simulated.push("shadows".into());
    }
    let weights: Vec<f32> = samples.iter().map(|s| s.1).collect();
    let frame = blend(frames, &weights)?;

    let lidar = match &req.lidar {
        Some(l) => run_lidar(&mut *r, req, l)?,
        None => None,
    };
    if let (Some(run), Some(w), Renderer::Gaussian { .. }, Some(l)) =
        (&lidar, &req.effects.weather, &*r, &req.lidar)
    {
        if l.all_frames {
            // scan_scene_gaussian generates each scanned frame's particles again (the count
            // is constant over time; effects::Weather::count).
            counters.particles += run.files.len() as u64 * w.count as u64;
        }
    }
    if let Some(run) = &lidar {
        counters.lidar_rays += run.rays;
        counters.lidar_points += run.points;
        counters.milliseconds += run.seconds * 1e3;
        counters.simulated.push("lidar".into());
    }
    // An exported file's weather is part of the file: drawn as exported, not simulated here.
    let exported_weather = matches!(r, Renderer::Mesh { .. })
        && req.effects.weather.is_some()
        && !counters.simulated.iter().any(|n| n == "weather");
    let simulates: &[&str] = if exported_weather {
        &["motion_blur", "shadows", "lidar", "weather"]
    } else {
        TRACE_SIMULATES
    };
    counters.not_simulated = not_simulated(req.effects, simulates);
    Ok(RenderedFrame {
        frame,
        stats,
        time_samples: samples.len(),
        counters,
        lidar,
        exported_weather,
    })
}

/// Index of the scene frame nearest to `t` (names the LiDAR file of a single-frame scan).
fn frame_index(times: &[f64], t: f64) -> usize {
    times
        .iter()
        .enumerate()
        .min_by(|a, b| (a.1 - t).abs().total_cmp(&(b.1 - t).abs()))
        .map(|(i, _)| i)
        .unwrap_or(0)
}

/// Cast the declared LiDAR: the traced frame through the tracer (frozen at the frame time), or
/// every frame of the scene.
fn run_lidar(
    r: &mut Renderer,
    req: &FrameRequest,
    l: &LidarRequest,
) -> anyhow::Result<Option<LidarRun>> {
    let (Some(lidar), Some(scene)) = (&req.effects.lidar, req.scene) else {
        return Ok(None);
    };
    if l.all_frames {
        let hash = l.shard.map(|_| crate::batch::merge::scene_hash(scene));
        let keep = |i: usize, t: f64| match (l.shard, &hash) {
            (Some(s), Some(h)) => s.owns(&lidar_key(h, i, t)),
            _ => true,
        };
        return Ok(match r {
            Renderer::Gaussian { .. } => {
                scan_scene_gaussian_selected(scene, &l.dir, l.backend, l.preset, &keep)?
            }
            Renderer::Mesh { tracer, .. } => Some(scan_mesh_frames_selected(
                tracer,
                lidar,
                &scene.cameras,
                &scene.frame_times(),
                &l.dir,
                &keep,
            )?),
            _ => bail!("LiDAR is ray-traced"),
        });
    }
    let sensor = LidarSensor::from_effect(lidar, &scene.cameras)?;
    let s = match r {
        Renderer::Gaussian { tracer, .. } => scan(tracer, &sensor, req.time),
        Renderer::Mesh { tracer, .. } => scan(&tracer.at(req.time), &sensor, req.time),
        _ => bail!("LiDAR is ray-traced"),
    };
    std::fs::create_dir_all(&l.dir).with_context(|| l.dir.display().to_string())?;
    let path = frame_file(&l.dir, frame_index(&scene.frame_times(), req.time));
    write_ply(&path, &s)?;
    Ok(Some(LidarRun {
        files: vec![path],
        rays: s.rays,
        points: s.points.len() as u64,
        seconds: s.seconds,
    }))
}
