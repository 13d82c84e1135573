//! Inputs of a frame: a scene (PLY or manifest) loaded with its warnings, and what the ray
//! tracer traces — an exported file (GLB/glTF/OBJ, as a viewer shows it, in the capture's frame
//! unless asked otherwise), a scene converted in memory (mode mesh), or the scene's Gaussians
//! (mode gaussian) — with the camera and the declared effects that apply to it.
//!
//! An exported file carries no effects of its own; `effects_from` names the manifest it was
//! exported from, whose effects, time range and cameras then apply. Weather particles are
//! built here because they are part of what is traced: mode gaussian traces the frame's
//! particles as a part of their own, mode mesh converts them with the scene (the traced
//! frame's, or every frame's when every frame is scanned).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use glam::{Quat, Vec3};
use splatbridge_convert::{ConvertOptions, FrameClouds, Profile};
use splatbridge_raytrace::scene_load::{load_glb_vec, load_path};
use splatbridge_raytrace::{RenderOptions, TriScene};
use splatbridge_scene::camera_spec::{CameraRequest, CameraSource};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::{EffectCounters, Effects};
use splatbridge_scene::effects_run::{effects_of, weather_frames, weather_particles};
use splatbridge_scene::manifest::load_scene;
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::{Camera, GaussianCloud};

/// Load a scene (PLY or manifest), passing the reader's warnings to `warn` (prefixed with the
/// file's name).
pub fn load_scene_warn(
    path: &Path,
    drop_invalid: bool,
    warn: &dyn Fn(&str),
) -> anyhow::Result<DynamicScene> {
    let (scene, warnings) = load_scene(path, &ReadOptions { drop_invalid })?;
    for w in warnings {
        warn(&format!("{}: {w}", path.display()));
    }
    Ok(scene)
}

/// [`load_scene_warn`], also saying what the file's Gaussians are (3D Gaussians, 2DGS
/// surfels, points).
pub fn load_scene_kind(
    path: &Path,
    drop_invalid: bool,
    warn: &dyn Fn(&str),
) -> anyhow::Result<(DynamicScene, splatbridge_scene::ply::GaussianKind)> {
    let (scene, info) = splatbridge_scene::formats::load(path, &ReadOptions { drop_invalid })?;
    for w in info.warnings {
        warn(&format!("{}: {w}", path.display()));
    }
    Ok((scene, info.kind))
}

/// How a traced input is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceMode {
    /// Composite every triangle hit front to back (what the exported file shows).
    Mesh,
    /// Ray-trace the Gaussians themselves (needs a PLY or manifest).
    Gaussian,
}

/// What to trace and how (the `trace` command's input options, without the CLI).
#[derive(Clone, Debug)]
pub struct TraceSource {
    pub input: PathBuf,
    pub camera: CameraRequest,
    pub time: f64,
    pub mode: TraceMode,
    pub options: RenderOptions,
    /// Keep the glTF world frame of a splatbridge export (default: the capture's frame).
    pub gltf_frame: bool,
    /// Converter profile for a scene traced in mode mesh (default: the converter's).
    pub profile: Option<Profile>,
    pub drop_invalid: bool,
    /// For an exported file: the manifest whose effects, time range and cameras apply.
    pub effects_from: Option<PathBuf>,
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
    /// The scene whose declared effects apply: the input scene, or `effects_from`'s.
    pub effects_scene: Option<DynamicScene>,
    pub effects: Effects,
    /// What building the frame's content cost (weather particles).
    pub counters: EffectCounters,
}

/// Whether `p` names a triangle file (traced as exported) rather than a scene.
pub fn is_mesh_file(p: &Path) -> bool {
    let ext = p
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    matches!(ext.as_str(), "glb" | "gltf" | "obj")
}

/// A points-only cloud of mesh vertices, to frame orbit cameras around a triangle scene.
///
/// The points have no extent of their own (scale 0): the triangles they span are the extent,
/// so the orbit frames the vertices' robust bounds. A unit scale here made
/// [`GaussianCloud::view_bounds`] grow every scene smaller than 3 units across to a 3-unit
/// reach, and a capture's export was traced from 17 times too far.
fn frame_cloud(scene: &TriScene, t: f64) -> GaussianCloud {
    let n: usize = scene.meshes.iter().map(|m| m.positions.len()).sum();
    let pts = scene.sample_points(t, n.div_ceil(200_000).max(1));
    let mut c = GaussianCloud::with_capacity(0, pts.len());
    for p in pts {
        c.push_activated(p.as_vec3(), Vec3::ZERO, Quat::IDENTITY, 0.5, Vec3::ONE);
    }
    c
}

impl TraceSource {
    /// Load the input, resolve the camera and build the traced frame's content.
    /// `all_weather_frames` converts every frame's weather (mode mesh), for scanning every
    /// frame, instead of the traced frame's only.
    pub fn prepare(
        &self,
        all_weather_frames: bool,
        warn: &dyn Fn(&str),
    ) -> anyhow::Result<Prepared> {
        let name = self.input.display().to_string();
        self.options.validate().with_context(|| name.clone())?;
        if is_mesh_file(&self.input) {
            return self.prepare_mesh_file(&name, warn);
        }
        if let Some(m) = &self.effects_from {
            bail!(
                "{}: --effects-from is for exported files (GLB/glTF/OBJ); {name} declares its own effects",
                m.display()
            );
        }
        let scene = load_scene_warn(&self.input, self.drop_invalid, warn)?;
        self.prepare_scene(scene, None, all_weather_frames)
    }

    /// As [`TraceSource::prepare`] for a scene already in memory (`self.input` names it in
    /// errors): `camera`, when given, is used as it is instead of resolving `self.camera`.
    pub fn prepare_scene(
        &self,
        scene: DynamicScene,
        camera: Option<Camera>,
        all_weather_frames: bool,
    ) -> anyhow::Result<Prepared> {
        let name = self.input.display().to_string();
        self.options.validate().with_context(|| name.clone())?;
        let effects = effects_of(&scene).with_context(|| name.clone())?;
        let camera = match camera {
            Some(c) => c,
            None => self
                .camera
                // Framed on the scene at its start, as stills are: one camera at every time.
                .resolve(CameraSource {
                    cloud: &scene.composite_view(scene.time.start),
                    own: &scene.cameras,
                })
                .with_context(|| name.clone())?,
        };
        let mut counters = EffectCounters::default();
        let loaded = match self.mode {
            TraceMode::Gaussian => {
                let frames = frame_weather(&scene, &effects, self.time, &camera, false)
                    .with_context(|| name.clone())?;
                Loaded::Gaussians(frames.and_then(|(mut fc, c)| {
                    counters = c;
                    fc.clouds.pop()
                }))
            }
            TraceMode::Mesh => {
                let mut opts = ConvertOptions::default();
                if let Some(p) = self.profile {
                    opts.profile = p;
                }
                let frames =
                    frame_weather(&scene, &effects, self.time, &camera, all_weather_frames)
                        .with_context(|| name.clone())?;
                if let Some((_, c)) = &frames {
                    counters = c.clone();
                }
                let (bytes, _) =
                    splatbridge_convert::glb_bytes(&scene, frames.as_ref().map(|f| &f.0), &opts)
                        .with_context(|| name.clone())?;
                let mut tri = load_glb_vec(bytes, &self.input)?;
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
            options: self.options.clone(),
            time: self.time,
            what,
            effects_scene: Some(scene),
            effects,
            counters,
        })
    }

    fn prepare_mesh_file(&self, name: &str, warn: &dyn Fn(&str)) -> anyhow::Result<Prepared> {
        if self.mode == TraceMode::Gaussian {
            bail!("{name}: mode gaussian needs Gaussians (a PLY or manifest), not a triangle file");
        }
        let mut scene = load_path(&self.input)?;
        if !self.gltf_frame {
            scene.to_capture_frame();
        }
        // Morphed meshes take their shape at the traced time (framing and camera included).
        scene.pose_morphs(self.time)?;
        let (effects_scene, effects) = match &self.effects_from {
            Some(m) => {
                let s = load_scene_warn(m, false, warn)?;
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
            .resolve(CameraSource {
                cloud: &frame_cloud(&scene, self.time),
                own: &own,
            })
            .with_context(|| name.to_string())?;
        Ok(Prepared {
            what: format!(
                "{name}: {} triangles in {} meshes",
                scene.triangle_count(),
                scene.meshes.len()
            ),
            loaded: Loaded::Mesh(scene),
            camera,
            options: self.options.clone(),
            time: self.time,
            effects_scene,
            effects,
            counters: EffectCounters::default(),
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
        match weather_frames(scene)? {
            Some(f) => f,
            None => return Ok(None),
        }
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
