//! `splatbridge trace`: ray-trace an exported file (GLB/glTF/OBJ, rendered as a viewer shows
//! it), or a scene (PLY or manifest) converted in memory (mode `mesh`) or traced as Gaussians
//! (mode `gaussian`, 3DGRT-style), with the obvhs or Embree BVH backend.
//!
//! Files written by `splatbridge convert` carry a root node that maps the capture's up axis
//! onto glTF's +Y; by default that node is undone, so cameras (`orbit`, `cameras.json`,
//! `scene:I`) and renders live in the capture's frame like native renders. `--gltf-frame`
//! keeps the glTF world frame.
//!
//! Mode gaussian builds one BVH per part (static Gaussians, each object in its own frame, the
//! frame's weather particles) and poses the objects at each time (instancing, no rebuild).
//!
//! Declared effects (the manifest's, or `--effects-from MANIFEST`'s for an exported file, which
//! carries none of its own) are simulated here: weather particles of the frame (mode gaussian:
//! a part of their own; mode mesh: converted in memory with the scene as one frame node),
//! motion blur (every shutter sample traced at its time and averaged), sun shadows
//! (`splatbridge_raytrace::shadows`) and LiDAR (one PLY per frame, `lidar_NNNN.ply` with NNNN
//! the frame index, in `--lidar-out`, by default the output image's directory). An exported
//! file's weather is drawn as exported (its per-frame particle nodes).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use clap::ValueEnum;
use glam::{Quat, Vec3};
use serde_json::json;
use splatbridge_convert::FrameClouds;
use splatbridge_raytrace::lidar::{
    frame_file, scan, scan_mesh_frames, scan_scene_gaussian, write_ply, LidarRun, LidarSensor,
};
use splatbridge_raytrace::scene_load::load_path;
use splatbridge_raytrace::shadows::{
    gaussian_bounds, mesh_bounds, render_gaussian_shadowed, render_mesh_shadowed, SunShadows,
};
use splatbridge_raytrace::{
    BackendKind, BuildPreset, Compositing, GaussianTracer, MeshTracer, RenderOptions, Stats,
    TriScene,
};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::{EffectCounters, Effects, Shadows};
use splatbridge_scene::effects_run::{
    blend_frames, effects_of, not_simulated, time_samples, weather_frames, weather_particles,
};
use splatbridge_scene::image_io::save_frame;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use crate::cmd::common::{load, parse_rgb, CameraArgs};
use crate::cmd::render::short;

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Composite every triangle hit front to back (what the exported file shows).
    Mesh,
    /// Ray-trace the Gaussians themselves (needs a PLY or manifest).
    Gaussian,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendArg {
    Obvhs,
    Embree,
}

impl From<BackendArg> for BackendKind {
    fn from(b: BackendArg) -> Self {
        match b {
            BackendArg::Obvhs => BackendKind::Obvhs,
            BackendArg::Embree => BackendKind::Embree,
        }
    }
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PresetArg {
    Fastest,
    VeryFast,
    Fast,
    Medium,
}

impl From<PresetArg> for BuildPreset {
    fn from(p: PresetArg) -> Self {
        match p {
            PresetArg::Fastest => BuildPreset::Fastest,
            PresetArg::VeryFast => BuildPreset::VeryFast,
            PresetArg::Fast => BuildPreset::Fast,
            PresetArg::Medium => BuildPreset::Medium,
        }
    }
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompositingArg {
    /// Blend display values like native splatting (glTF's linear colours encoded per hit).
    Display,
    /// Blend in linear light and encode the result, as viewers show the file.
    Viewer,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProfileArg {
    Meshsplats,
    Rings,
    Texture,
}

/// What is traced, shared with `bench trace`.
#[derive(clap::Args, Clone, Debug)]
pub struct TraceInput {
    /// GLB, glTF or OBJ (traced as exported), or a scene: 3DGS PLY or manifest.
    pub input: PathBuf,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Scene time in seconds (animated files and manifests).
    #[arg(long, default_value_t = 0.0, value_parser = super::ranges::time, allow_hyphen_values = true)]
    pub time: f64,
    /// mesh: composite the triangles; gaussian: ray-trace the Gaussians (PLY/manifest input).
    #[arg(long, value_enum, default_value_t = Mode::Mesh)]
    pub mode: Mode,
    /// k-buffer size: hits gathered per traversal before compositing and resuming.
    #[arg(long, default_value_t = 16, value_parser = super::ranges::k_buffer)]
    pub k: usize,
    /// BVH build preset (none pre-splits triangles).
    #[arg(long, value_enum, default_value_t = PresetArg::Medium)]
    pub preset: PresetArg,
    /// Background colour R,G,B in [0, 1].
    #[arg(long, value_parser = parse_rgb, default_value = "0,0,0")]
    pub background: Vec3,
    /// Mode gaussian: cull Gaussians whose mean is at view depth ≤ NEAR (reference 0.2).
    #[arg(long, default_value_t = 0.2)]
    pub near: f32,
    /// Mode mesh: display (compare with native splatting) or viewer (as Blender shows it).
    #[arg(long, value_enum, default_value_t = CompositingArg::Display)]
    pub compositing: CompositingArg,
    /// Keep the glTF world frame of a splatbridge export (default: the capture's frame).
    #[arg(long)]
    pub gltf_frame: bool,
    /// Converter profile for PLY/manifest input in mode mesh (default: the converter's).
    #[arg(long, value_enum)]
    pub profile: Option<ProfileArg>,
    /// Drop invalid Gaussians with a warning instead of failing (PLY/manifest input).
    #[arg(long)]
    pub drop_invalid: bool,
    /// For an exported file (GLB/glTF/OBJ): take the declared effects, time range and cameras
    /// of this manifest (the scene it was exported from).
    #[arg(long, value_name = "MANIFEST")]
    pub effects_from: Option<PathBuf>,
}

#[derive(clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub input: TraceInput,
    /// BVH backend (embree needs a build with `--features embree`).
    #[arg(long, value_enum, default_value_t = BackendArg::Obvhs)]
    pub backend: BackendArg,
    /// Output image (.png or .exr).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Directory for the LiDAR scans (`lidar_NNNN.ply`) when the scene declares `lidar`
    /// (default: the output image's directory).
    #[arg(long, value_name = "DIR")]
    pub lidar_out: Option<PathBuf>,
    /// Scan every frame of the scene's time range, not only the traced one.
    #[arg(long)]
    pub lidar_all_frames: bool,
    /// Print one JSON object (options, stats, effect counters, LiDAR files) instead of the
    /// summary.
    #[arg(long)]
    pub json: bool,
}

/// A loaded input, ready to build tracers for any backend.
pub enum Loaded {
    Mesh(TriScene),
    /// The scene (`Prepared::effects_scene`) traced as Gaussians, with the traced frame's
    /// weather particles when weather is declared.
    Gaussians(Option<GaussianCloud>),
}

/// The input, the camera and the options.
pub struct Prepared {
    pub loaded: Loaded,
    pub camera: Camera,
    pub options: RenderOptions,
    pub time: f64,
    pub what: String,
    /// The scene whose declared effects apply: the input scene, or `--effects-from`'s.
    pub effects_scene: Option<DynamicScene>,
    pub effects: Effects,
    /// What building the frame's content cost (weather particles).
    pub counters: EffectCounters,
}

fn is_mesh_file(p: &Path) -> bool {
    let ext = p
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    matches!(ext.as_str(), "glb" | "gltf" | "obj")
}

/// A points-only cloud of mesh vertices, to frame orbit cameras around a triangle scene.
fn frame_cloud(scene: &TriScene, t: f64) -> GaussianCloud {
    let n: usize = scene.meshes.iter().map(|m| m.positions.len()).sum();
    let pts = scene.sample_points(t, n.div_ceil(200_000).max(1));
    let mut c = GaussianCloud::with_capacity(0, pts.len());
    for p in pts {
        c.push_activated(p.as_vec3(), Vec3::ONE, Quat::IDENTITY, 0.5, Vec3::ONE);
    }
    c
}

impl TraceInput {
    pub fn prepare(&self) -> anyhow::Result<Prepared> {
        self.prepare_with(false)
    }

    /// As [`TraceInput::prepare`]; `all_weather_frames` converts every frame's weather (mode
    /// mesh), for scanning every frame, instead of the traced frame's only.
    pub fn prepare_with(&self, all_weather_frames: bool) -> anyhow::Result<Prepared> {
        let name = self.input.display().to_string();
        let options = RenderOptions {
            k: self.k,
            background: self.background,
            min_transmittance: 1e-4,
            near: self.near,
            compositing: match self.compositing {
                CompositingArg::Display => Compositing::Display,
                CompositingArg::Viewer => Compositing::Viewer,
            },
        };
        options.validate().with_context(|| name.clone())?;
        if is_mesh_file(&self.input) {
            if self.mode == Mode::Gaussian {
                bail!("{name}: mode gaussian needs Gaussians (a PLY or manifest), not a triangle file");
            }
            let mut scene = load_path(&self.input)?;
            if !self.gltf_frame {
                scene.to_capture_frame();
            }
            let (effects_scene, effects) = match &self.effects_from {
                Some(m) => {
                    let s = load(m, false)?;
                    let e = effects_of(&s).with_context(|| m.display().to_string())?;
                    (Some(s), e)
                }
                None => (None, Effects::default()),
            };
            let mut own = scene.cameras(self.time);
            if own.is_empty() {
                if let Some(s) = &effects_scene {
                    own = s.cameras.clone();
                }
            }
            let camera = self
                .camera
                .resolve(&frame_cloud(&scene, self.time), &own)
                .with_context(|| name.clone())?;
            return Ok(Prepared {
                what: format!(
                    "{name}: {} triangles in {} meshes",
                    scene.triangle_count(),
                    scene.meshes.len()
                ),
                loaded: Loaded::Mesh(scene),
                camera,
                options,
                time: self.time,
                effects_scene,
                effects,
                counters: EffectCounters::default(),
            });
        }
        if let Some(m) = &self.effects_from {
            bail!(
                "{}: --effects-from is for exported files (GLB/glTF/OBJ); {name} declares its own effects",
                m.display()
            );
        }
        let scene = load(&self.input, self.drop_invalid)?;
        let effects = effects_of(&scene).with_context(|| name.clone())?;
        let cloud = scene.composite(self.time);
        let camera = self
            .camera
            .resolve(&cloud, &scene.cameras)
            .with_context(|| name.clone())?;
        let mut counters = EffectCounters::default();
        let loaded = match self.mode {
            Mode::Gaussian => {
                let frames = frame_weather(&scene, &effects, self.time, &camera, false)
                    .with_context(|| name.clone())?;
                Loaded::Gaussians(frames.map(|(mut fc, c)| {
                    counters = c;
                    fc.clouds.pop().expect("the traced frame's particles")
                }))
            }
            Mode::Mesh => {
                let mut opts = splatbridge_convert::ConvertOptions::default();
                if let Some(p) = self.profile {
                    opts.profile = match p {
                        ProfileArg::Meshsplats => splatbridge_convert::Profile::MeshSplats,
                        ProfileArg::Rings => splatbridge_convert::Profile::Rings,
                        ProfileArg::Texture => splatbridge_convert::Profile::Texture,
                    };
                }
                let frames =
                    frame_weather(&scene, &effects, self.time, &camera, all_weather_frames)
                        .with_context(|| name.clone())?;
                if let Some((fc, c)) = &frames {
                    counters = c.clone();
                    debug_assert!(fc.times.len() == fc.clouds.len());
                }
                let (bytes, _) =
                    splatbridge_convert::glb_bytes(&scene, frames.as_ref().map(|f| &f.0), &opts)
                        .with_context(|| name.clone())?;
                let mut tri =
                    splatbridge_raytrace::scene_load::load_glb_bytes(&bytes, &self.input)?;
                tri.to_capture_frame();
                Loaded::Mesh(tri)
            }
        };
        let what = match &loaded {
            Loaded::Mesh(s) => format!(
                "{name}: converted in memory, {} triangles",
                s.triangle_count()
            ),
            Loaded::Gaussians(particles) => format!(
                "{name}: {} Gaussians at t = {}{}",
                scene.gaussian_count(),
                self.time,
                match particles {
                    Some(p) => format!(" and {} weather particles", p.len()),
                    None => String::new(),
                }
            ),
        };
        Ok(Prepared {
            loaded,
            camera,
            options,
            time: self.time,
            what,
            effects_scene: Some(scene),
            effects,
            counters,
        })
    }
}

/// Weather particles: the traced frame's (mode gaussian, and mode mesh's in-memory conversion
/// as the one frame node, always visible), or every frame's (`all`, for scanning every frame).
fn frame_weather(
    scene: &DynamicScene,
    effects: &Effects,
    t: f64,
    camera: &Camera,
    all: bool,
) -> anyhow::Result<Option<(FrameClouds, EffectCounters)>> {
    let Some(w) = &effects.weather else {
        return Ok(None);
    };
    let start = Instant::now();
    let (times, clouds) = if all {
        weather_frames(scene)?.expect("weather is declared")
    } else {
        (vec![t], vec![weather_particles(scene, w, t, Some(camera))?])
    };
    let counters = EffectCounters {
        particles: clouds.iter().map(|c| c.len() as u64).sum(),
        milliseconds: start.elapsed().as_secs_f64() * 1e3,
        simulated: vec!["weather".into()],
        ..Default::default()
    };
    Ok(Some((FrameClouds { times, clouds }, counters)))
}

/// A tracer built for one backend.
pub enum Tracer {
    Mesh(MeshTracer),
    Gaussians(GaussianTracer),
}

impl Tracer {
    pub fn build(
        p: &Prepared,
        backend: BackendKind,
        preset: BuildPreset,
    ) -> anyhow::Result<Tracer> {
        Ok(match &p.loaded {
            Loaded::Mesh(s) => Tracer::Mesh(MeshTracer::new(s.clone(), backend, preset)?),
            Loaded::Gaussians(particles) => {
                let scene = p
                    .effects_scene
                    .as_ref()
                    .expect("a Gaussian input keeps its scene");
                let mut g = GaussianTracer::for_scene(scene, p.time, backend, preset)?;
                g.set_particles(particles.clone())?;
                Tracer::Gaussians(g)
            }
        })
    }

    /// Pose the scene at `t` for the next render (mode gaussian re-poses its objects; mode
    /// mesh takes the time per render).
    pub fn set_time(&mut self, t: f64) {
        if let Tracer::Gaussians(g) = self {
            g.set_time(t);
        }
    }

    pub fn build_seconds(&self) -> f64 {
        match self {
            Tracer::Mesh(t) => t.build_seconds,
            Tracer::Gaussians(t) => t.build_seconds,
        }
    }

    pub fn render(&self, p: &Prepared) -> anyhow::Result<(Frame, Stats)> {
        Ok(match self {
            Tracer::Mesh(t) => t.render(&p.camera, p.time, &p.options)?,
            Tracer::Gaussians(t) => t.render(&p.camera, &p.options)?,
        })
    }
}

/// One traced image (a frame, or one shutter sample of it) and what its shadows cost.
struct Traced {
    frame: Frame,
    stats: Stats,
    shadow_rays: u64,
    shadow_ms: f64,
}

/// Trace `tracer` at `time`, with sun shadows when `shadows` is declared.
fn trace_at(
    tracer: &Tracer,
    p: &Prepared,
    time: f64,
    shadows: Option<&Shadows>,
) -> anyhow::Result<Traced> {
    let Some(s) = shadows else {
        let (frame, stats) = match tracer {
            Tracer::Mesh(t) => t.render(&p.camera, time, &p.options)?,
            Tracer::Gaussians(t) => t.render(&p.camera, &p.options)?,
        };
        return Ok(Traced {
            frame,
            stats,
            shadow_rays: 0,
            shadow_ms: 0.0,
        });
    };
    let (frame, stats, st) = match tracer {
        Tracer::Mesh(t) => {
            let (lo, hi) = mesh_bounds(t, time);
            let sun = SunShadows::from_effect(s, lo, hi)?;
            render_mesh_shadowed(t, &p.camera, time, &p.options, &sun)?
        }
        Tracer::Gaussians(t) => {
            let (lo, hi) = gaussian_bounds(t);
            let sun = SunShadows::from_effect(s, lo, hi)?;
            render_gaussian_shadowed(t, &p.camera, &p.options, &sun)?
        }
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

/// Index of the scene frame nearest to `t` (names the LiDAR file of a single-frame scan).
fn frame_index(times: &[f64], t: f64) -> usize {
    times
        .iter()
        .enumerate()
        .min_by(|a, b| (a.1 - t).abs().total_cmp(&(b.1 - t).abs()))
        .map(|(i, _)| i)
        .unwrap_or(0)
}

/// Cast the declared LiDAR: the traced frame through `tracer` (frozen at the frame time), or
/// every frame of the scene.
fn run_lidar(
    args: &Args,
    p: &Prepared,
    tracer: &Tracer,
    dir: &Path,
) -> anyhow::Result<Option<LidarRun>> {
    let (Some(l), Some(scene)) = (&p.effects.lidar, &p.effects_scene) else {
        return Ok(None);
    };
    let backend: BackendKind = args.backend.into();
    if args.lidar_all_frames {
        return Ok(match tracer {
            Tracer::Gaussians(_) => {
                scan_scene_gaussian(scene, dir, backend, args.input.preset.into())?
            }
            Tracer::Mesh(t) => Some(scan_mesh_frames(
                t,
                l,
                &scene.cameras,
                &scene.frame_times(),
                dir,
            )?),
        });
    }
    let sensor = LidarSensor::from_effect(l, &scene.cameras)?;
    let s = match tracer {
        Tracer::Gaussians(t) => scan(t, &sensor, p.time),
        Tracer::Mesh(t) => scan(&t.at(p.time), &sensor, p.time),
    };
    std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
    let path = frame_file(dir, frame_index(&scene.frame_times(), p.time));
    write_ply(&path, &s)?;
    Ok(Some(LidarRun {
        files: vec![path],
        rays: s.rays,
        points: s.points.len() as u64,
        seconds: s.seconds,
    }))
}

fn add_trace_stats(total: &mut Stats, s: &Stats) {
    total.rays += s.rays;
    total.hits += s.hits;
    total.traversals += s.traversals;
    total.seconds += s.seconds;
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let ext = args
        .output
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if ext != "png" && ext != "exr" {
        bail!("{}: output must end in .png or .exr", args.output.display());
    }
    let name = args.input.input.display().to_string();
    let all_frames = args.lidar_all_frames && args.input.mode == Mode::Mesh;
    let p = args.input.prepare_with(all_frames)?;
    let backend: BackendKind = args.backend.into();
    let preset: BuildPreset = args.input.preset.into();
    let samples = match &p.effects_scene {
        Some(s) => time_samples(s, p.time).with_context(|| name.clone())?,
        None => vec![(p.time, 1.0)],
    };
    let blurred = samples.len() > 1;
    let shadows = p.effects.shadows.as_ref();
    let mut counters = p.counters.clone();
    let mut build_seconds = 0.0;
    // One tracer for every shutter sample: mode mesh instances its nodes at each time, mode
    // gaussian re-poses its objects (no BVH rebuild per sample).
    let mut tracer = Tracer::build(&p, backend, preset).with_context(|| name.clone())?;
    build_seconds += tracer.build_seconds();
    let mut traced = Vec::with_capacity(samples.len());
    let mut stats = Stats::default();
    let mut blur_ms = 0.0;
    for (i, &(ts, _)) in samples.iter().enumerate() {
        let start = Instant::now();
        tracer.set_time(ts);
        traced.push(trace_at(&tracer, &p, ts, shadows).with_context(|| name.clone())?);
        if i > 0 {
            blur_ms += start.elapsed().as_secs_f64() * 1e3;
        }
    }
    tracer.set_time(p.time);
    if p.effects.motion_blur.is_some() && !counters.simulated.iter().any(|n| n == "motion_blur") {
        counters.extra_time_samples += samples.len() as u64 - 1;
        counters.simulated.push("motion_blur".into());
    }
    counters.milliseconds += blur_ms;
    let mut shadow_rays = 0;
    for t in &traced {
        add_trace_stats(&mut stats, &t.stats);
        shadow_rays += t.shadow_rays;
        counters.milliseconds += t.shadow_ms;
    }
    if shadows.is_some() {
        counters.shadow_rays += shadow_rays;
        counters.simulated.push("shadows".into());
    }
    let frame = if traced.len() == 1 {
        traced.pop().expect("one sample").frame
    } else {
        let frames: Vec<Frame> = traced.into_iter().map(|t| t.frame).collect();
        let weights: Vec<f32> = samples.iter().map(|s| s.1).collect();
        blend_frames(&frames, &weights).with_context(|| name.clone())?
    };
    save_frame(&args.output, &frame)?;

    let lidar_dir = match &args.lidar_out {
        Some(d) => d.clone(),
        None => match args.output.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        },
    };
    let lidar = run_lidar(&args, &p, &tracer, &lidar_dir).with_context(|| name.clone())?;
    if let (Some(run), Some(w), Loaded::Gaussians(_)) = (&lidar, &p.effects.weather, &p.loaded) {
        if args.lidar_all_frames {
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
    let exported_weather = matches!(p.loaded, Loaded::Mesh(_))
        && p.effects.weather.is_some()
        && !counters.simulated.iter().any(|n| n == "weather");
    let simulates: &[&str] = if exported_weather {
        &["motion_blur", "shadows", "lidar", "weather"]
    } else {
        &["weather", "motion_blur", "shadows", "lidar"]
    };
    counters.not_simulated = not_simulated(&p.effects, simulates);

    if args.json {
        let report = json!({
            "command": "trace",
            "input": name,
            "output": args.output.display().to_string(),
            "mode": match args.input.mode {
                Mode::Mesh => "mesh",
                Mode::Gaussian => "gaussian",
            },
            "backend": backend.to_string(),
            "time": p.time,
            "time_samples": samples.len(),
            "camera": {"name": p.camera.name, "width": p.camera.width, "height": p.camera.height},
            "options": {
                "k": p.options.k,
                "preset": args.input.preset.to_possible_value().map(|v| v.get_name().to_string()),
                "background": p.options.background.to_array().map(short),
                "near": short(p.options.near),
                "compositing": match p.options.compositing {
                    Compositing::Display => "display",
                    Compositing::Viewer => "viewer",
                },
            },
            "stats": {
                "what": p.what,
                "rays": stats.rays,
                "hits": stats.hits,
                "traversals": stats.traversals,
                "trace_seconds": stats.seconds,
                "build_seconds": build_seconds,
                "mrays_per_second": stats.mrays_per_second(),
                "hits_per_ray": stats.hits_per_ray(),
            },
            "lidar": lidar.as_ref().map(|r| json!({
                "dir": lidar_dir.display().to_string(),
                "files": r.files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
                "rays": r.rays,
                "points": r.points,
            })),
            "exported_weather": exported_weather,
            "effects": serde_json::to_value(&counters)?,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!("{}", p.what);
    println!(
        "{}: {}×{} camera '{}', backend {backend}, BVH build {:.3} s, trace {:.3} s ({:.2} Mrays/s), {:.2} hits/ray, {:.2} traversals/ray{}",
        args.output.display(),
        p.camera.width,
        p.camera.height,
        p.camera.name,
        build_seconds,
        stats.seconds,
        stats.mrays_per_second(),
        stats.hits_per_ray(),
        stats.traversals as f64 / stats.rays.max(1) as f64,
        if blurred {
            format!(" (over {} motion-blur samples, blended)", samples.len())
        } else {
            String::new()
        }
    );
    if let Some(r) = &lidar {
        println!(
            "LiDAR: {} scan(s) in {}, {} rays → {} points",
            r.files.len(),
            lidar_dir.display(),
            r.rays,
            r.points
        );
    }
    if exported_weather {
        println!("weather: drawn as exported (the file's per-frame particle nodes)");
    }
    println!("{}", counters.summary());
    Ok(())
}
