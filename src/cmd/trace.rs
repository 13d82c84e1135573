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
//! Loading and the frame itself are `splatbridge::pipeline`'s (`TraceSource`, `render_frame`);
//! this module parses the options and prints. Declared effects (the manifest's, or
//! `--effects-from MANIFEST`'s for an exported file, which carries none of its own) are
//! simulated: weather particles of the frame (mode gaussian:
//! a part of their own; mode mesh: converted in memory with the scene as one frame node),
//! motion blur (every shutter sample traced at its time and averaged), sun shadows
//! (`splatbridge_raytrace::shadows`) and LiDAR (one PLY per frame, `lidar_NNNN.ply` with NNNN
//! the frame index, in `--lidar-out`, by default the output image's directory). An exported
//! file's weather is drawn as exported (its per-frame particle nodes).

use std::path::PathBuf;

use anyhow::{bail, Context};
use clap::ValueEnum;
use glam::Vec3;
use serde_json::json;
use splatbridge::pipeline::sequence::{render_sequence, SequenceRequest};
use splatbridge::pipeline::source::is_mesh_file;
use splatbridge::pipeline::{
    render_frame, FrameRequest, LidarRequest, Prepared, Renderer, TraceMode, TraceSource,
};
use splatbridge_convert::Profile;
use splatbridge_raytrace::{
    BackendKind, BuildPreset, Compositing, Footprint, HitOrder, RenderOptions, SampleFootprint,
    ShDirection,
};
use splatbridge_scene::effects::EffectCounters;
use splatbridge_scene::image_io::save_frame;

use crate::cmd::common::{parse_rgb, print_warning, CameraArgs};
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
pub enum FootprintArg {
    /// Each Gaussian widened in 3-D by the ray's pixel footprint (native's 0.3-px low-pass).
    On,
    /// The exact point-sampled 3-D response (3DGRT's).
    Off,
    /// Each Gaussian evaluated as native's projection does (EWA 2-D conic at the pixel).
    Projected,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OrderArg {
    /// By the distance of maximum response along the ray (3DGRT's).
    Hit,
    /// By the view depth of the Gaussian's mean (native's sort).
    MeanDepth,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShDirectionArg {
    /// The ray's direction (3DGRT's).
    Ray,
    /// From the camera toward the Gaussian's mean (native's).
    Mean,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleFootprintArg {
    /// Each of N samples carries its sub-pixel's footprint (0.3/N px²).
    Subpixel,
    /// Each sample carries the whole pixel's footprint (0.3 px²).
    Pixel,
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
    /// Mode gaussian: primary rays carry their pixel footprint, widening each Gaussian like
    /// native splatting's 0.3-pixel low-pass: on (3-D, default in mode gaussian), off, or
    /// projected (native's 2-D conic at the pixel). Mode mesh has none.
    #[arg(long, value_enum)]
    pub footprint: Option<FootprintArg>,
    /// Mode gaussian: order of a primary ray's hits: hit (3DGRT's t*) or mean-depth (native's;
    /// the default with a footprint, hit with --footprint off).
    #[arg(long, value_enum)]
    pub order: Option<OrderArg>,
    /// Mode gaussian: SH direction of a primary ray's hits (default: ray; mean with
    /// --footprint projected).
    #[arg(long, value_enum)]
    pub sh_direction: Option<ShDirectionArg>,
    /// Samples per pixel (both modes): a fixed stratified pattern (k×k grid when N = k²),
    /// box-filtered; 1 samples the pixel centre.
    #[arg(long, default_value_t = 1, value_parser = super::ranges::spp)]
    pub spp: u32,
    /// With --spp > 1 and the footprint on: the sub-pixel's footprint or the whole pixel's.
    #[arg(long, value_enum, default_value_t = SampleFootprintArg::Subpixel)]
    pub sample_footprint: SampleFootprintArg,
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
    #[arg(short, long = "out", alias = "output")]
    pub output: PathBuf,
    /// Directory for the LiDAR scans (`lidar_NNNN.ply`) when the scene declares `lidar`
    /// (default: the output image's directory).
    #[arg(long, value_name = "DIR")]
    pub lidar_out: Option<PathBuf>,
    /// Scan every frame of the scene's time range, not only the traced one.
    #[arg(long)]
    pub lidar_all_frames: bool,
    /// Trace every frame of the scene's time range to OUT_0000.ext, OUT_0001.ext, … (with the
    /// scene's LiDAR, one scan per frame); an exported file takes its time range from
    /// --effects-from.
    #[arg(long, conflicts_with_all = ["lidar_all_frames", "time"])]
    pub frames: bool,
    /// With --frames: trace only shard I of N (0 ≤ I < N) of the frames; with
    /// --lidar-all-frames: scan only that shard of the frames (the image is traced by every
    /// shard, identically). Either writes a partial report.json for `splatbridge merge` (see
    /// docs/scale.md).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<splatbridge::batch::shard::Shard>,
    /// Print one JSON object (options, stats, effect counters, LiDAR files) instead of the
    /// summary.
    #[arg(long)]
    pub json: bool,
}

impl TraceInput {
    /// The library's description of this input.
    pub fn source(&self) -> anyhow::Result<TraceSource> {
        Ok(TraceSource {
            input: self.input.clone(),
            camera: self.camera.request()?,
            time: self.time,
            mode: match self.mode {
                Mode::Mesh => TraceMode::Mesh,
                Mode::Gaussian => TraceMode::Gaussian,
            },
            options: RenderOptions {
                k: self.k,
                background: self.background,
                min_transmittance: 1e-4,
                near: self.near,
                compositing: match self.compositing {
                    CompositingArg::Display => Compositing::Display,
                    CompositingArg::Viewer => Compositing::Viewer,
                },
                footprint: self.footprint(),
                order: match self.order {
                    Some(OrderArg::Hit) => HitOrder::Hit,
                    Some(OrderArg::MeanDepth) => HitOrder::MeanDepth,
                    // With a footprint the trace is the parity mode: native's order too.
                    None if self.footprint() != Footprint::Off => HitOrder::MeanDepth,
                    None => HitOrder::Hit,
                },
                sh_direction: match self.sh_direction {
                    Some(ShDirectionArg::Ray) => ShDirection::Ray,
                    Some(ShDirectionArg::Mean) => ShDirection::Mean,
                    None if self.footprint() == Footprint::Projected => ShDirection::Mean,
                    None => ShDirection::Ray,
                },
                spp: self.spp,
                sample_footprint: match self.sample_footprint {
                    SampleFootprintArg::Subpixel => SampleFootprint::Subpixel,
                    SampleFootprintArg::Pixel => SampleFootprint::Pixel,
                },
            },
            gltf_frame: self.gltf_frame,
            profile: self.profile.map(|p| match p {
                ProfileArg::Meshsplats => Profile::MeshSplats,
                ProfileArg::Rings => Profile::Rings,
                ProfileArg::Texture => Profile::Texture,
            }),
            drop_invalid: self.drop_invalid,
            effects_from: self.effects_from.clone(),
        })
    }

    /// `--footprint`, defaulting to on in mode gaussian (the parity mode) and off in mode mesh
    /// (triangles are not widened).
    pub fn footprint(&self) -> Footprint {
        match (self.footprint, self.mode) {
            (Some(FootprintArg::On), _) | (None, Mode::Gaussian) => Footprint::On,
            (Some(FootprintArg::Off), _) | (None, Mode::Mesh) => Footprint::Off,
            (Some(FootprintArg::Projected), _) => Footprint::Projected,
        }
    }

    pub fn prepare(&self) -> anyhow::Result<Prepared> {
        self.prepare_with(false)
    }

    /// As [`TraceInput::prepare`]; `all_weather_frames` converts every frame's weather (mode
    /// mesh), for scanning every frame, instead of the traced frame's only.
    pub fn prepare_with(&self, all_weather_frames: bool) -> anyhow::Result<Prepared> {
        self.source()?.prepare(all_weather_frames, &print_warning)
    }
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
    if args.shard.is_some() && !args.frames && !args.lidar_all_frames {
        bail!("--shard: splits --frames or --lidar-all-frames");
    }
    let name = args.input.input.display().to_string();
    let all_frames = args.lidar_all_frames && args.input.mode == Mode::Mesh;
    let mut p = args.input.prepare_with(all_frames)?;
    let backend: BackendKind = args.backend.into();
    let preset: BuildPreset = args.input.preset.into();
    // One tracer for every shutter sample: mode mesh instances its nodes at each time, mode
    // gaussian re-poses its objects (no BVH rebuild per sample).
    // One frame without every-frame scans needs nothing more of the scene's Gaussians once
    // they are in the tracer (a sequence hashes the scene for its shards; an every-frame
    // Gaussian scan builds tracers from it).
    let take_gaussians = !args.frames && !args.lidar_all_frames;
    let mut tracer = Renderer::tracer_taking(&mut p, backend, preset, take_gaussians)
        .with_context(|| name.clone())?;
    let build_seconds = tracer.build_seconds();
    let lidar_dir = match &args.lidar_out {
        Some(d) => d.clone(),
        None => splatbridge::pipeline::export_shard::folder_of(&args.output),
    };
    if args.frames {
        return run_frames(&args, &p, tracer, &lidar_dir);
    }
    let req = FrameRequest {
        scene: p.effects_scene.as_ref(),
        effects: &p.effects,
        camera: &p.camera,
        time: p.time,
        content: p.counters.clone(),
        lidar: Some(LidarRequest {
            dir: lidar_dir.clone(),
            all_frames: args.lidar_all_frames,
            backend,
            preset,
            shard: args.shard,
        }),
    };
    let r = render_frame(&mut tracer, &req).with_context(|| name.clone())?;
    // LiDAR runs inside the frame, so a failing scan fails before the image is written.
    save_frame(&args.output, &r.frame)?;
    if args.shard.is_some() && r.lidar.is_none() {
        bail!("{name}: --shard splits LiDAR scans, and the scene declares no LiDAR");
    }
    if let (Some(shard), Some(scene), Some(run)) = (args.shard, &p.effects_scene, &r.lidar) {
        let mut files = run.files.clone();
        files.push(args.output.clone());
        let canonical = format!(
            "trace --lidar-all-frames\ninput={:?}\nbackend={:?}\nout={:?}",
            args.input,
            args.backend,
            args.output.file_name()
        );
        splatbridge::pipeline::export_shard::write_partial(
            &lidar_dir, "trace", scene, &canonical, shard, &files,
        )?;
    }
    let stats = r.stats.trace().cloned().unwrap_or_default();
    let (samples, lidar, exported_weather, counters) =
        (r.time_samples, r.lidar, r.exported_weather, r.counters);
    let blurred = samples > 1;

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
            "time_samples": samples,
            "camera": {"name": p.camera.name, "width": p.camera.width, "height": p.camera.height},
            "options": {
                "k": p.options.k,
                "preset": args.input.preset.to_possible_value().map(|v| v.get_name().to_string()),
                "background": p.options.background.to_array().map(short),
                "near": short(p.options.near),
                "footprint": match p.options.footprint {
                    Footprint::Off => "off",
                    Footprint::On => "on",
                    Footprint::Projected => "projected",
                },
                "order": match p.options.order {
                    HitOrder::Hit => "hit",
                    HitOrder::MeanDepth => "mean-depth",
                },
                "sh_direction": match p.options.sh_direction {
                    ShDirection::Ray => "ray",
                    ShDirection::Mean => "mean",
                },
                "spp": p.options.spp,
                "sample_footprint": match p.options.sample_footprint {
                    SampleFootprint::Subpixel => "subpixel",
                    SampleFootprint::Pixel => "pixel",
                },
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
            format!(" (over {samples} motion-blur samples, blended)")
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

/// `trace --frames`: every frame of the scene's time range through one tracer, through the
/// camera resolved for the traced input, as one atomic sequence. A scene that declares weather
/// is prepared again for each frame (its particles are drawn per frame, around the camera, as
/// a single `trace --time T` draws them), so each frame equals that single trace bit for bit;
/// an exported file's weather is drawn as exported.
fn run_frames(
    args: &Args,
    p: &Prepared,
    mut tracer: Renderer,
    lidar_dir: &std::path::Path,
) -> anyhow::Result<()> {
    let name = args.input.input.display().to_string();
    let Some(scene) = p.effects_scene.as_ref() else {
        bail!("--frames: {name} has no time range; pass --effects-from MANIFEST (the scene it was exported from)");
    };
    let backend: BackendKind = args.backend.into();
    let preset: BuildPreset = args.input.preset.into();
    let rebuild = p.effects.weather.is_some() && !is_mesh_file(&args.input.input);
    let mut built_at = p.time;
    let mut prepare = |r: &mut Renderer, t: f64| -> anyhow::Result<Option<EffectCounters>> {
        if !rebuild || t == built_at {
            return Ok(None);
        }
        let mut source = args.input.source()?;
        source.time = t;
        let mut q = source.prepare(false, &print_warning)?;
        *r = Renderer::tracer_taking(&mut q, backend, preset, true)?;
        built_at = t;
        Ok(Some(q.counters))
    };
    let req = SequenceRequest {
        command: "trace",
        scene,
        effects: &p.effects,
        camera: &p.camera,
        out: &args.output,
        content: p.counters.clone(),
        lidar: Some(LidarRequest {
            dir: lidar_dir.to_path_buf(),
            all_frames: false,
            backend,
            preset,
            shard: None,
        }),
        shard: args.shard,
        canonical: format!(
            "trace --frames\ninput={:?}\nbackend={:?}\nout={:?}",
            args.input,
            args.backend,
            args.output.file_name()
        ),
    };
    let mut frames_json = Vec::new();
    let run = render_sequence(&mut tracer, &req, &mut prepare, &mut |f| {
        let stats = f.rendered.stats.trace().cloned().unwrap_or_default();
        if args.json {
            frames_json.push(json!({
                "output": f.path.display().to_string(),
                "time": f.time,
                "time_samples": f.rendered.time_samples,
                "rays": stats.rays,
                "hits": stats.hits,
                "trace_seconds": stats.seconds,
                "lidar": f.lidar_files.iter().map(|l| l.display().to_string()).collect::<Vec<_>>(),
            }));
        } else {
            println!(
                "{} (t = {}): trace {:.3} s ({:.2} Mrays/s), {:.2} hits/ray{}{}",
                f.path.display(),
                f.time,
                stats.seconds,
                stats.mrays_per_second(),
                stats.hits_per_ray(),
                if f.rendered.time_samples > 1 {
                    format!(", {} motion-blur samples", f.rendered.time_samples)
                } else {
                    String::new()
                },
                match f.lidar_files.first() {
                    Some(l) => format!(", LiDAR {}", l.display()),
                    None => String::new(),
                }
            );
        }
        Ok(())
    })
    .with_context(|| name.clone())?;
    if args.json {
        let report = json!({
            "command": "trace",
            "input": name,
            "mode": match args.input.mode {
                Mode::Mesh => "mesh",
                Mode::Gaussian => "gaussian",
            },
            "backend": backend.to_string(),
            "camera": {"name": p.camera.name, "width": p.camera.width, "height": p.camera.height},
            "frames": frames_json,
            "frames_total": run.total,
            "effects": serde_json::to_value(&run.counters)?,
        });
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("{}", p.what);
        println!("{} of {} frames traced", run.frames, run.total);
        println!("{}", run.counters.summary());
    }
    Ok(())
}
