//! `convert` and `compare`: the library calls `splatbridge convert` and `splatbridge compare`
//! make, with their defaults, for a scene in memory.
//!
//! `convert` builds the CLI's `ExportRequest` (`splatbridge::pipeline::export_request`), so
//! the options and every refusal are the command's: a splat file output is written by
//! `write_cloud`, a mesh or glTF splat output through `mesh_options`, the distillation fit
//! (`splatbridge::distill::run::distill_export`) and `export`. `compare` runs
//! `splatbridge::measure::compare::run_compare` into a folder and returns its `report.json`.

use std::path::{Path, PathBuf};

use anyhow::Context;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use splatbridge::distill::run::{distill_export, ViewRequest};
use splatbridge::distill::{DistillOptions, HitOrder, Loss, ParamMode};
use splatbridge::measure::compare::{default_times, parse_profiles, run_compare, Compared};
use splatbridge::measure::parity::CompareConfig;
use splatbridge::pipeline::export::{cloud_format, embedded_cameras, ply_holds_gaussians};
use splatbridge::pipeline::export_request::{default_profile, ExportRequest, MeshRequest};
use splatbridge::pipeline::split_auto::{DEFAULT_BLEND, DISC_FOOTPRINT_SIGMAS};
use splatbridge_convert::splats_gltf::KhrCompression;
use splatbridge_convert::{ColorEncoding, ConvertOptions, Profile, UpAxis};
use splatbridge_hybrid::ges::GesOptions;
use splatbridge_scene::camera_spec::{parse_camera_list, CameraRequest, CameraSource, CameraSpec};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::Camera;

use crate::camera::CameraArg;
use crate::run::run;
use crate::scene::PyScene;

/// A converter profile by the CLI's name.
pub fn profile(name: &str) -> PyResult<Profile> {
    match name {
        "meshsplats" => Ok(Profile::MeshSplats),
        "rings" => Ok(Profile::Rings),
        "texture" => Ok(Profile::Texture),
        other => Err(crate::Error::new_err(format!(
            "unknown profile '{other}' (meshsplats, rings, texture)"
        ))),
    }
}

/// The `ExportRequest` `splatbridge convert SCENE -o OUTPUT` makes with these options and the
/// rest at their defaults (`splats`: `--splats`).
pub fn request(
    _scene: &DynamicScene,
    name: &str,
    output: &Path,
    splats: bool,
    profile: Option<Profile>,
    up: Option<UpAxis>,
    color: Option<ColorEncoding>,
) -> anyhow::Result<ExportRequest> {
    let options = ConvertOptions {
        profile: profile.unwrap_or_else(|| default_profile(output)),
        up: up.unwrap_or(UpAxis::NegY),
        color_encoding: color.unwrap_or(ColorEncoding::Linear),
        gaussian_ids: true,
        coplanar_offset: true,
        ..ConvertOptions::default()
    };
    Ok(ExportRequest {
        input: PathBuf::from(name),
        output: output.to_path_buf(),
        format: None,
        splats,
        khr_compression: KhrCompression::None,
        spz_version: splatbridge_scene::formats::spz::WRITE_VERSION,
        ksplat_level: 1,
        mesh_asked: profile.is_some(),
        time: None,
        first: None,
        frames: false,
        shard: None,
        drop_invalid: false,
        cameras: Vec::new(),
        footprint_for: None,
        mesh: MeshRequest {
            options,
            viewer_layout: true,
            ..MeshRequest::default()
        },
        distill: false,
    })
}

/// `distill=`: True for the CLI's defaults, or a dict of its options.
#[derive(Clone, Debug)]
struct Distill {
    views: ViewRequest,
    options: DistillOptions,
}

fn distill_of(d: &Bound<'_, PyAny>, time: f64) -> PyResult<Option<Distill>> {
    if d.is_none() {
        return Ok(None);
    }
    // The CLI's defaults (`convert --distill`).
    let mut views = ViewRequest::default();
    let mut options = DistillOptions {
        time,
        loss: Loss::L1Ssim(0.4),
        params: ParamMode::Vertex,
        order: HitOrder::Ray,
        footprint: true,
        target_sh_degree: 3,
        ..DistillOptions::default()
    };
    if let Ok(on) = d.extract::<bool>() {
        return Ok(on.then_some(Distill { views, options }));
    }
    let dict = d.cast::<PyDict>().map_err(|_| {
        crate::Error::new_err("distill: expected True or a dict (views, iterations, time_budget, width, height, held_back, times, batch, patience)")
    })?;
    for (k, v) in dict.iter() {
        let key: String = k.extract()?;
        match key.as_str() {
            "views" => views.spec = v.extract()?,
            "width" => views.width = v.extract()?,
            "height" => views.height = v.extract()?,
            "held_back" => views.held_back = v.extract()?,
            "times" => views.times = v.extract()?,
            "iterations" => options.iterations = v.extract()?,
            "time_budget" => options.max_seconds = v.extract()?,
            "batch" => options.batch = v.extract()?,
            "patience" => options.patience = v.extract()?,
            other => {
                return Err(crate::Error::new_err(format!(
                    "distill: unknown option '{other}' (views, iterations, time_budget, width, height, held_back, times, batch, patience)"
                )))
            }
        }
    }
    Ok(Some(Distill { views, options }))
}

/// Convert a scene as ``splatbridge convert`` does, the format chosen by ``path``'s
/// extension: a mesh (``.glb``/``.gltf``: profile texture by default; ``.obj``; ``.ply`` with a
/// ``profile``: rings by default), glTF splats (``splats=True``), or a splat file (``.ply``
/// without a profile, ``.compressed.ply``, ``.splat``, ``.spz``, ``.ksplat``).
///
/// ``profile``: ``"meshsplats"``, ``"rings"`` or ``"texture"``. ``up``: the scene's up axis
/// (``"-y"``, ``"y"``, ``"z"``). ``color_encoding``: ``"linear"`` or ``"display"``.
/// ``distill``: fit the mesh's colours to native splatting first (glTF meshes): ``True`` for
/// the CLI's defaults or a dict, e.g. ``{"views": "orbit:16", "time_budget": 30}``
/// (``views``, ``iterations``, ``time_budget`` seconds, ``width``, ``height``, ``held_back``,
/// ``times``, ``batch``, ``patience``: validations without progress before the fit stops, 0
/// never). ``cameras``: cameras to embed in glTF outputs instead of the
/// scene's own (the CLI's ``--camera``: ``"orbit:8"``, ``"scene"``, ``"cams.json"``, specs).
/// Returns the report ``convert --json`` prints (a splat file: format, Gaussians, bytes).
///
/// >>> splatbridge.convert(scene, "scene.glb", profile="texture")
/// >>> splatbridge.convert(scene, "fit.glb", distill={"views": "orbit:16", "time_budget": 20})
#[pyfunction]
#[pyo3(signature = (scene, path, *, profile = None, distill = None, splats = false, up = "-y", color_encoding = "linear", cameras = None))]
fn convert<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyScene>,
    path: PathBuf,
    profile: Option<&str>,
    distill: Option<Bound<'py, PyAny>>,
    splats: bool,
    up: &str,
    color_encoding: &str,
    cameras: Option<String>,
) -> PyResult<Bound<'py, PyAny>> {
    let profile = profile.map(self::profile).transpose()?;
    let up = match up {
        "-y" => UpAxis::NegY,
        "y" => UpAxis::Y,
        "z" => UpAxis::Z,
        other => {
            return Err(crate::Error::new_err(format!(
                "up '{other}' is not -y, y or z"
            )))
        }
    };
    let color = match color_encoding {
        "linear" => ColorEncoding::Linear,
        "display" => ColorEncoding::Display,
        other => {
            return Err(crate::Error::new_err(format!(
                "color_encoding '{other}' is not linear or display"
            )))
        }
    };
    let s = scene.get();
    let (sc, name) = (&s.scene, &s.name);
    let fit = match &distill {
        Some(d) => distill_of(d, sc.time.start)?,
        None => None,
    };
    let json = run(py, |cancel| -> anyhow::Result<String> {
        let mut req = request(sc, name, &path, splats, profile, Some(up), Some(color))?;
        req.distill = fit.is_some();
        // `--camera`: embedded in glTF outputs instead of the scene's own.
        let mut owned: Option<DynamicScene> = None;
        if let Some(spec) = &cameras {
            let mut s = sc.clone();
            s.cameras = embedded_cameras(std::slice::from_ref(spec), sc)?;
            owned = Some(s);
        }
        let cloud = cloud_format(
            &path,
            None,
            ply_holds_gaussians(splats, req.mesh_asked),
            req.spz_version,
            req.ksplat_level,
        )?;
        if let Some(format) = cloud {
            if fit.is_some() {
                anyhow::bail!(
                    "{}: --distill fits a mesh glTF (.glb or .gltf without --splats)",
                    path.display()
                );
            }
            let c = req.write_cloud(owned.unwrap_or_else(|| sc.clone()), format, s.kind)?;
            return Ok(serde_json::json!({
                "format": c.format,
                "gaussians": c.gaussians,
                "sh_degree": c.sh_degree,
                "time": c.time,
                "bytes": c.bytes,
            })
            .to_string());
        }
        let mut opts = req.mesh_options(owned.as_ref().unwrap_or(sc), s.kind)?;
        if let Some(d) = &fit {
            let s = owned.get_or_insert_with(|| sc.clone());
            distill_export(s, &mut opts, &d.views, &d.options, |_| cancel.check())
                .with_context(|| format!("--distill (views {})", d.views.spec))?;
        }
        let scene = owned.as_ref().unwrap_or(sc);
        let (report, effects) = req.export(scene, &opts)?;
        let mut v = serde_json::to_value(&report)?;
        v["effects"] = serde_json::to_value(&effects)?;
        Ok(v.to_string())
    })?;
    json_loads(py, &json)
}

fn json_loads<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (text,))
}

/// The cameras of `compare`: a camera-list string (the CLI's `--cameras`) or a list of
/// `Camera`s and single specs.
#[derive(FromPyObject)]
enum CameraList {
    Spec(String),
    List(Vec<CameraArg>),
}

/// Compare every renderer and converter profile against native splatting at ``cameras`` ×
/// ``times``, as ``splatbridge compare`` does, and return its ``report.json`` (a dict: the
/// same records and figures, PSNR, SSIM, milliseconds, per renderer, profile and format),
/// as ``{"records": [...]}``.
///
/// ``cameras``: a list string (``"orbit:4"``, ``"scene"``, ``"cams.json"``, single specs,
/// comma-separated) or a list of ``Camera`` objects and specs; images are ``width``×``height``
/// (default 320×240). ``times``: seconds (default: the start; start, middle and end of a
/// dynamic scene). ``out``: the folder for images, heat maps and the reports (default: a
/// temporary folder, removed).
///
/// >>> report = splatbridge.compare(scene, "orbit:4", profiles=["texture"])
/// >>> [(r["renderer"], r["profile"], r["psnr"]) for r in report["records"]]
#[pyfunction]
#[pyo3(signature = (scene, cameras = CameraList::Spec("orbit:4".into()), *, times = None, profiles = vec!["meshsplats".to_string(), "rings".to_string(), "texture".to_string()], width = 320, height = 240, backend = "obvhs", k = 16, obj = true, out = None))]
fn compare<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyScene>,
    cameras: CameraList,
    times: Option<Vec<f64>>,
    profiles: Vec<String>,
    width: u32,
    height: u32,
    backend: &str,
    k: usize,
    obj: bool,
    out: Option<PathBuf>,
) -> PyResult<Bound<'py, PyAny>> {
    let s = scene.get();
    let (sc, name) = (&s.scene, &s.name);
    let json = run(py, |cancel| -> anyhow::Result<String> {
        let max_memory = splatbridge::measure::budget::parse_budget("auto")
            .map_err(|e| anyhow::anyhow!("--max-memory: {e}"))?;
        let times = times.clone().unwrap_or_else(|| default_times(sc));
        let t0 = *times.first().context("times: no time given")?;
        let cams: Vec<Camera> = match &cameras {
            CameraList::Spec(spec) => {
                splatbridge::measure::compare::scene_cameras(spec, sc, &times, width, height)?
            }
            CameraList::List(list) => {
                let mut v = Vec::with_capacity(list.len());
                for c in list {
                    v.push(match c {
                        CameraArg::Camera(_) => c.resolve(sc, t0, Some(width), Some(height))?,
                        CameraArg::Spec(spec) => {
                            // One spec, or a list item (`orbit:N`) as the CLI reads it.
                            let items = parse_camera_list(spec)?;
                            let mut req = CameraRequest::new(CameraSpec::Scene(0));
                            req.width = Some(width);
                            req.height = Some(height);
                            let cloud = sc.composite_view(t0);
                            let got = req.resolve_list(
                                &items,
                                CameraSource {
                                    cloud: &cloud,
                                    own: &sc.cameras,
                                },
                            )?;
                            v.extend(got);
                            continue;
                        }
                    });
                }
                v
            }
        };
        if cams.is_empty() {
            anyhow::bail!("cameras: no camera given");
        }
        let base = GesOptions {
            footprint_sigmas: DISC_FOOTPRINT_SIGMAS,
            blend: DEFAULT_BLEND,
            ..CompareConfig::default().ges
        };
        let cfg = CompareConfig {
            ges: base,
            profiles: parse_profiles(&profiles)?,
            obj,
            backend: backend.parse()?,
            k,
            max_memory,
            ..CompareConfig::default()
        };
        let tmp;
        let dir = match &out {
            Some(d) => d.clone(),
            None => {
                tmp = tempfile::tempdir()?;
                tmp.path().join("compare")
            }
        };
        let preamble = format!(
            "Scene `{name}`: {} cameras × {} times, {width}×{height} pixels. Reference: native splatting with reference settings. \
             PSNR/SSIM against the reference; milliseconds are render times on this machine (BVH builds and exports excluded).",
            cams.len(),
            times.len(),
        );
        let mut owned = sc.clone();
        let compared = run_compare(
            &mut owned,
            &cams,
            &times,
            &cfg,
            &dir,
            None,
            "",
            preamble,
            &|_| cancel.check(),
        )?;
        let Compared::Whole(_) = compared else {
            anyhow::bail!("compare: a whole comparison returned a shard");
        };
        let records = std::fs::read_to_string(dir.join("report.json"))
            .with_context(|| dir.join("report.json").display().to_string())?;
        Ok(format!("{{\"records\": {records}}}"))
    })?;
    json_loads(py, &json)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(convert, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    Ok(())
}
