//! Export: a loaded scene to a triangle mesh (GLB/glTF/OBJ/PLY, through `splatbridge-convert`),
//! native glTF splats (`KHR_gaussian_splatting`) or a single-cloud splat file (3DGS PLY,
//! compressed PLY, `.splat`, `.spz`, through `splatbridge_scene::formats`), with the scene's
//! per-frame content and effect counters. `splatbridge convert` parses its arguments into
//! these calls and prints what they return.
//!
//! Weather is per-frame content: one glTF node per frame, particles in every OBJ frame
//! (`--splats` writes the scene's Gaussians only). Other declared effects are not content and
//! are reported as not simulated.

use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context};
use splatbridge_convert::splats_gltf::KhrCompression;
use splatbridge_convert::{ConvertOptions, ConvertReport, FrameClouds};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::EffectCounters;
use splatbridge_scene::effects_run::{effects_of, not_simulated, weather_frames};
use splatbridge_scene::formats::ksplat::KsplatOptions;
use splatbridge_scene::formats::spz::SpzOptions;
use splatbridge_scene::formats::{write_cloud, CloudFormat};

use super::source::load_scene_kind;

/// Whether a path names a glTF file (`.glb` or `.gltf`, any case).
pub fn is_gltf(p: &Path) -> bool {
    p.extension()
        .map(|e| {
            let e = e.to_string_lossy().to_ascii_lowercase();
            e == "glb" || e == "gltf"
        })
        .unwrap_or(false)
}

/// Load what `convert` converts: a `KHR_gaussian_splatting` glTF (which must hold
/// Gaussians), or any splat format or manifest (warnings to `warn`).
pub fn load_export_input(
    path: &Path,
    drop_invalid: bool,
    warn: &dyn Fn(&str),
) -> anyhow::Result<DynamicScene> {
    Ok(load_export_input_kind(path, drop_invalid, warn)?.0)
}

/// [`load_export_input`], also saying what the Gaussians are (2DGS surfels, points, …).
pub fn load_export_input_kind(
    path: &Path,
    drop_invalid: bool,
    warn: &dyn Fn(&str),
) -> anyhow::Result<(DynamicScene, splatbridge_scene::ply::GaussianKind)> {
    // One loader for every input, so a glTF's splats get the invalid-Gaussian policy of
    // every other format (NaN or infinite values refused, or dropped with --drop-invalid).
    let (scene, kind) = load_scene_kind(path, drop_invalid, warn)?;
    if is_gltf(path) {
        // A mesh-only glTF is not a scene to convert (it would write an empty file).
        splatbridge_scene::input::require_gaussians(path, &scene)?;
    }
    Ok((scene, kind))
}

/// Whether a `.ply` output (or `--format ply`) holds Gaussians: yes, the 3DGS PLY every splat
/// tool writes, unless a mesh option (`--mesh`, `--profile`) asks for a triangle mesh PLY.
pub fn ply_holds_gaussians(splats: bool, mesh_asked: bool) -> bool {
    splats || !mesh_asked
}

/// An output format named explicitly (instead of the one the output's extension implies).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    /// The 3DGS PLY, or a mesh PLY when a mesh is asked for.
    Ply,
    SplatPly,
    CompressedPly,
    Splat,
    Spz,
    Ksplat,
    Glb,
    Gltf,
    Obj,
}

/// The single-cloud splat format an output asks for, if any (`splats`: a `.ply` means the
/// 3DGS PLY; see [`ply_holds_gaussians`]), with the SPZ version and `.ksplat` level asked
/// for; an error when `format` names a mesh/glTF format that disagrees with the output's
/// extension.
pub fn cloud_format(
    output: &Path,
    format: Option<OutputFormat>,
    splats: bool,
    spz_version: u32,
    ksplat_level: u8,
) -> anyhow::Result<Option<CloudFormat>> {
    let spz = CloudFormat::Spz(SpzOptions {
        version: spz_version,
        ..SpzOptions::default()
    });
    let ksplat = CloudFormat::Ksplat(KsplatOptions {
        level: ksplat_level,
        ..KsplatOptions::default()
    });
    let ext = output
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    Ok(match format {
        Some(OutputFormat::SplatPly) => Some(CloudFormat::Ply),
        Some(OutputFormat::Ply) if splats => Some(CloudFormat::Ply),
        Some(OutputFormat::CompressedPly) => Some(CloudFormat::CompressedPly),
        Some(OutputFormat::Splat) => Some(CloudFormat::Splat),
        Some(OutputFormat::Spz) => Some(spz),
        Some(OutputFormat::Ksplat) => Some(ksplat),
        Some(f) => {
            let want = match f {
                OutputFormat::Ply => "ply",
                OutputFormat::Glb => "glb",
                OutputFormat::Gltf => "gltf",
                _ => "obj",
            };
            if ext != want || CloudFormat::for_path(output, false).is_some() {
                bail!(
                    "{}: --format {want} writes a .{want} file; name the output so",
                    output.display()
                );
            }
            None
        }
        None => match CloudFormat::for_path(output, splats) {
            Some(CloudFormat::Spz(_)) => Some(spz),
            Some(CloudFormat::Ksplat(_)) => Some(ksplat),
            other => other,
        },
    })
}

/// What a single-cloud export wrote.
#[derive(Clone, Debug)]
pub struct CloudExport {
    pub format: &'static str,
    pub gaussians: usize,
    pub sh_degree: u8,
    /// The time the scene was composited at.
    pub time: f64,
    pub bytes: u64,
}

/// Write a single-cloud splat file: the scene composited at `time` (default: its start),
/// cut to the first `first` Gaussians when asked.
pub fn write_cloud_export(
    scene: DynamicScene,
    output: &Path,
    format: CloudFormat,
    time: Option<f64>,
    first: Option<usize>,
    kind: splatbridge_scene::ply::GaussianKind,
) -> anyhow::Result<CloudExport> {
    let t = time.unwrap_or(scene.time.start);
    if !t.is_finite() {
        bail!("--time {t} is not a finite time");
    }
    // Consumed, so a scene without objects is written from its own cloud, not a copy.
    let mut cloud = scene.into_composite(t);
    if let Some(n) = first {
        cloud.retain_indices(|i| i < n);
    }
    // 2DGS surfels stay 2DGS surfels in a PLY: two scales, no third (the thin axis they were
    // given on read is not written).
    let surfels_ply = kind == splatbridge_scene::ply::GaussianKind::Surfels2D
        && matches!(format, CloudFormat::Ply);
    let bytes = if surfels_ply {
        splatbridge_scene::ply::write_ply_2dgs(output, &cloud)?;
        std::fs::metadata(output)?.len()
    } else {
        write_cloud(output, &cloud, format)?
    };
    Ok(CloudExport {
        format: if surfels_ply {
            "2DGS PLY"
        } else {
            format.name()
        },
        gaussians: cloud.len(),
        sh_degree: cloud.sh_degree,
        time: t,
        bytes,
    })
}

/// What a mesh or glTF splat export writes besides the scene's Gaussians.
#[derive(Clone, Copy, Debug)]
pub enum ExportKind {
    /// A triangle mesh; `frames`: one OBJ per frame.
    Mesh { frames: bool },
    /// Native glTF splats with this attribute compression.
    Splats(KhrCompression),
}

/// A mesh export's per-frame content (the scene's weather, when `mesh`) and the effect
/// counters: what is simulated, and what is declared but not.
pub fn content(
    scene: &DynamicScene,
    input: &Path,
    mesh: bool,
) -> anyhow::Result<(Option<FrameClouds>, EffectCounters)> {
    let declared = effects_of(scene).with_context(|| input.display().to_string())?;
    let mut effects = EffectCounters::default();
    let weather = if mesh {
        let start = Instant::now();
        let w = weather_frames(scene).with_context(|| input.display().to_string())?;
        w.map(|(times, clouds)| {
            effects.particles = clouds.iter().map(|c| c.len() as u64).sum();
            effects.milliseconds = start.elapsed().as_secs_f64() * 1e3;
            effects.simulated.push("weather".into());
            FrameClouds { times, clouds }
        })
    } else {
        None
    };
    effects.not_simulated = not_simulated(
        &declared,
        if weather.is_some() { &["weather"] } else { &[] },
    );
    Ok((weather, effects))
}

/// Convert `scene` (read from `input`, named in errors) to `output`: the converter's report
/// and the effect counters (weather built as per-frame content for meshes).
pub fn export_scene(
    scene: &DynamicScene,
    input: &Path,
    output: &Path,
    opts: &ConvertOptions,
    kind: ExportKind,
) -> anyhow::Result<(ConvertReport, EffectCounters)> {
    let (weather, effects) = content(scene, input, matches!(kind, ExportKind::Mesh { .. }))?;
    let report = match kind {
        ExportKind::Splats(_) if !scene.frames.is_empty() => bail!(
            "{}: --splats writes the static part and objects only; this scene has per-frame content (write a mesh glTF)",
            input.display()
        ),
        ExportKind::Splats(compression) => {
            if !is_gltf(output) {
                bail!(
                    "{}: --splats writes glTF; use .glb or .gltf",
                    output.display()
                );
            }
            splatbridge_convert::splats_gltf::write_file_with(output, scene, opts, compression)?
        }
        ExportKind::Mesh { frames } => {
            splatbridge_convert::convert_to_file(output, scene, weather.as_ref(), opts, frames)?
        }
    };
    Ok((report, effects))
}

/// Resolve `convert --camera` lists against the scene (orbits frame its composite at the
/// start; a `.json` item is every camera of that file), in the order given.
pub fn embedded_cameras(
    specs: &[String],
    scene: &DynamicScene,
) -> anyhow::Result<Vec<splatbridge_scene::Camera>> {
    use splatbridge_scene::camera_spec::{
        parse_camera_list, CameraRequest, CameraSource, CameraSpec,
    };
    let composite = scene.composite(scene.time.start);
    let src = CameraSource {
        cloud: &composite,
        own: &scene.cameras,
    };
    let req = CameraRequest::new(CameraSpec::Scene(0));
    let mut cams = Vec::new();
    for spec in specs {
        let items = parse_camera_list(spec).with_context(|| format!("--camera {spec}"))?;
        cams.extend(
            req.resolve_list(&items, src)
                .with_context(|| format!("--camera {spec}"))?,
        );
    }
    Ok(cams)
}
