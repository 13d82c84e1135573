//! `splatbridge trace`: ray-trace an exported file (GLB/glTF/OBJ, rendered as a viewer shows
//! it), or a scene (PLY or manifest) converted in memory (mode `mesh`) or traced as Gaussians
//! (mode `gaussian`, 3DGRT-style), with the obvhs or Embree BVH backend.
//!
//! Files written by `splatbridge convert` carry a root node that maps the capture's up axis
//! onto glTF's +Y; by default that node is undone, so cameras (`orbit`, `cameras.json`,
//! `scene:I`) and renders live in the capture's frame like native renders. `--gltf-frame`
//! keeps the glTF world frame.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use glam::{Quat, Vec3};
use splatbridge_raytrace::scene_load::load_path;
use splatbridge_raytrace::{
    BackendKind, BuildPreset, Compositing, GaussianTracer, MeshTracer, RenderOptions, Stats,
    TriScene,
};
use splatbridge_scene::image_io::save_frame;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use crate::cmd::common::{load, parse_rgb, CameraArgs};

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
    #[arg(long, default_value_t = 0.0)]
    pub time: f64,
    /// mesh: composite the triangles; gaussian: ray-trace the Gaussians (PLY/manifest input).
    #[arg(long, value_enum, default_value_t = Mode::Mesh)]
    pub mode: Mode,
    /// k-buffer size: hits gathered per traversal before compositing and resuming.
    #[arg(long, default_value_t = 16)]
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
}

/// A loaded input, ready to build tracers for any backend.
pub enum Loaded {
    Mesh(TriScene),
    Gaussians(GaussianCloud),
}

/// The input, the camera and the options.
pub struct Prepared {
    pub loaded: Loaded,
    pub camera: Camera,
    pub options: RenderOptions,
    pub time: f64,
    pub what: String,
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
            let own = scene.cameras(self.time);
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
            });
        }
        let scene = load(&self.input, self.drop_invalid)?;
        let cloud = scene.composite(self.time);
        let camera = self
            .camera
            .resolve(&cloud, &scene.cameras)
            .with_context(|| name.clone())?;
        let loaded = match self.mode {
            Mode::Gaussian => Loaded::Gaussians(cloud),
            Mode::Mesh => {
                let mut opts = splatbridge_convert::ConvertOptions::default();
                if let Some(p) = self.profile {
                    opts.profile = match p {
                        ProfileArg::Meshsplats => splatbridge_convert::Profile::MeshSplats,
                        ProfileArg::Rings => splatbridge_convert::Profile::Rings,
                        ProfileArg::Texture => splatbridge_convert::Profile::Texture,
                    };
                }
                let (bytes, _) = splatbridge_convert::glb_bytes(&scene, None, &opts)
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
            Loaded::Gaussians(c) => format!("{name}: {} Gaussians at t = {}", c.len(), self.time),
        };
        Ok(Prepared {
            loaded,
            camera,
            options,
            time: self.time,
            what,
        })
    }
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
            Loaded::Gaussians(c) => {
                Tracer::Gaussians(GaussianTracer::new(c.clone(), backend, preset)?)
            }
        })
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

pub fn run(args: Args) -> anyhow::Result<()> {
    let ext = args
        .output
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if ext != "png" && ext != "exr" {
        bail!("{}: output must end in .png or .exr", args.output.display());
    }
    let p = args.input.prepare()?;
    let backend: BackendKind = args.backend.into();
    let tracer = Tracer::build(&p, backend, args.input.preset.into())
        .with_context(|| args.input.input.display().to_string())?;
    let (frame, stats) = tracer.render(&p)?;
    save_frame(&args.output, &frame)?;
    println!("{}", p.what);
    println!(
        "{}: {}×{} camera '{}', backend {backend}, BVH build {:.3} s, trace {:.3} s ({:.2} Mrays/s), {:.2} hits/ray, {:.2} traversals/ray",
        args.output.display(),
        p.camera.width,
        p.camera.height,
        p.camera.name,
        tracer.build_seconds(),
        stats.seconds,
        stats.mrays_per_second(),
        stats.hits_per_ray(),
        stats.traversals as f64 / stats.rays.max(1) as f64,
    );
    Ok(())
}
