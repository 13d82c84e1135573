//! `render` (native splatting), `trace` (the BVH ray tracer), `hybrid` (GES surfels and
//! Gaussians): one frame as a NumPy array, through `splatbridge::pipeline::render_frame`, the
//! function `splatbridge render`, `trace` and `hybrid` write their images from, with the
//! commands' defaults, so `save_image(render(...), "x.png")` writes the CLI's bytes.

use std::path::PathBuf;

use anyhow::Context;
use glam::Vec3;
use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArray3};
use pyo3::prelude::*;
use splatbridge::pipeline::split_auto::{DEFAULT_BLEND, DISC_FOOTPRINT_SIGMAS};
use splatbridge::pipeline::{
    render_frame, FrameRequest, Renderer, SurfelSplit, TraceMode, TraceSource,
};
use splatbridge_hybrid::ges::GesOptions;
use splatbridge_hybrid::{Extent, RenderOptions};
use splatbridge_raytrace::{
    BackendKind, BuildPreset, Compositing, Footprint, HitOrder, ShDirection,
};
use splatbridge_scene::camera_spec::{CameraRequest, CameraSpec};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::EffectCounters;
use splatbridge_scene::effects_run::effects_of;
use splatbridge_scene::image_io::save_frame;
use splatbridge_scene::surfels::SplitParams;
use splatbridge_scene::{Camera, Frame};

use crate::camera::CameraArg;
use crate::run::run;
use crate::scene::PyScene;

/// Which planes a render returns.
#[derive(Clone, Copy)]
enum Channels {
    Rgb,
    Rgba,
    /// RGB, alpha and depth (what an `.exr` holds).
    Rgbaz,
}

fn channels(s: &str) -> PyResult<Channels> {
    match s {
        "rgb" => Ok(Channels::Rgb),
        "rgba" => Ok(Channels::Rgba),
        "rgbaz" => Ok(Channels::Rgbaz),
        other => Err(crate::Error::new_err(format!(
            "channels '{other}' is not rgb, rgba or rgbaz"
        ))),
    }
}

/// A frame as an (H, W, C) float32 array: RGB is moved, not copied; alpha and depth are
/// interleaved into a new array.
fn to_array(py: Python<'_>, f: Frame, c: Channels) -> PyResult<Bound<'_, PyAny>> {
    let (h, w) = (f.height as usize, f.width as usize);
    let (data, n) = match c {
        Channels::Rgb => (f.rgb, 3),
        Channels::Rgba | Channels::Rgbaz => {
            let n = if matches!(c, Channels::Rgba) { 4 } else { 5 };
            let mut v = Vec::with_capacity(w * h * n);
            for i in 0..w * h {
                v.extend_from_slice(&f.rgb[3 * i..3 * i + 3]);
                v.push(f.alpha[i]);
                if n == 5 {
                    v.push(f.depth[i]);
                }
            }
            (v, n)
        }
    };
    Ok(data.into_pyarray(py).reshape([h, w, n])?.into_any())
}

fn frame_of(
    scene: &DynamicScene,
    name: &str,
    r: &mut Renderer,
    cam: &Camera,
    time: f64,
) -> anyhow::Result<Frame> {
    let effects = effects_of(scene).with_context(|| name.to_string())?;
    let req = FrameRequest {
        scene: Some(scene),
        effects: &effects,
        camera: cam,
        time,
        content: EffectCounters::default(),
        lidar: None,
    };
    Ok(render_frame(r, &req)
        .with_context(|| name.to_string())?
        .frame)
}

fn rgb(v: (f32, f32, f32)) -> [f32; 3] {
    [v.0, v.1, v.2]
}

/// Render one frame with native 3DGS splatting (the reference forward pass), as
/// ``splatbridge render`` does: the scene composited at ``time`` (default: its start) with
/// its declared weather and motion blur.
///
/// ``camera``: a ``Camera`` (resized to ``width``×``height`` when given) or a spec,
/// ``"orbit:N:I"``, ``"scene:I"``, ``"cameras.json:I"`` (default size 640×480 for orbits).
/// Knobs and defaults are the CLI's: ``background`` RGB, ``near`` 0.2, ``extent``
/// ``"sigma3"`` or ``"alpha"``, ``alpha_clamp`` 0.99 (or 0.999), ``sh_degree`` cap 0–3.
/// Returns linear RGB, shape (H, W, 3) float32 (``channels="rgba"`` adds opacity,
/// ``"rgbaz"`` opacity and depth).
///
/// >>> img = splatbridge.render(scene, "orbit:8:0", 640, 480)
/// >>> img.shape
/// (480, 640, 3)
#[pyfunction]
#[pyo3(signature = (scene, camera = CameraArg::Spec("orbit:8:0".into()), width = None, height = None, *, time = None, background = (0.0, 0.0, 0.0), near = 0.2, extent = "sigma3", alpha_clamp = 0.99, sh_degree = 3, channels = "rgb"))]
fn render<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyScene>,
    camera: CameraArg,
    width: Option<u32>,
    height: Option<u32>,
    time: Option<f64>,
    background: (f32, f32, f32),
    near: f32,
    extent: &str,
    alpha_clamp: f32,
    sh_degree: u8,
    channels: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let ch = self::channels(channels)?;
    let extent = match extent {
        "sigma3" => Extent::Sigma3,
        "alpha" => Extent::Alpha,
        other => {
            return Err(crate::Error::new_err(format!(
                "extent '{other}' is not sigma3 or alpha"
            )))
        }
    };
    if sh_degree > 3 {
        return Err(crate::Error::new_err(format!(
            "sh_degree {sh_degree} is outside 0..=3"
        )));
    }
    let s = scene.get();
    let (sc, name) = (&s.scene, &s.name);
    let frame = run(py, |_| {
        let t = time.unwrap_or(sc.time.start);
        let cam = camera
            .resolve(sc, t, width, height)
            .with_context(|| name.clone())?;
        let options = RenderOptions {
            extent,
            alpha_clamp,
            sh_degree_cap: sh_degree,
            near,
            background: rgb(background),
            exhaustive: false,
        };
        // Warm buffers from this scene's last render when no other thread holds them.
        let kept = s.native_buffers.try_lock().ok().and_then(|mut b| b.take());
        let mut r = match kept {
            Some(buffers) => Renderer::native_reusing(options, buffers)?,
            None => Renderer::native(options)?,
        };
        let frame = frame_of(sc, name, &mut r, &cam, t);
        if let (Some(buffers), Ok(mut slot)) =
            (r.into_native_buffers(), s.native_buffers.try_lock())
        {
            *slot = Some(buffers);
        }
        frame
    })?;
    to_array(py, frame, ch)
}

/// Render one frame with the GES-style hybrid (opaque surfels split off with the guarded
/// thresholds, then the Gaussians they leave, sorted), as ``splatbridge hybrid`` does with
/// its defaults. Arguments and result as :func:`render`.
///
/// >>> img = splatbridge.hybrid(scene, "orbit:8:0", 640, 480)
#[pyfunction]
#[pyo3(signature = (scene, camera = CameraArg::Spec("orbit:8:0".into()), width = None, height = None, *, time = None, background = (0.0, 0.0, 0.0), near = 0.2, sh_degree = 3, channels = "rgb"))]
fn hybrid<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyScene>,
    camera: CameraArg,
    width: Option<u32>,
    height: Option<u32>,
    time: Option<f64>,
    background: (f32, f32, f32),
    near: f32,
    sh_degree: u8,
    channels: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let ch = self::channels(channels)?;
    let s = scene.get();
    let (sc, name) = (&s.scene, &s.name);
    let frame = run(py, |_| {
        let t = time.unwrap_or(sc.time.start);
        let cam = camera
            .resolve(sc, t, width, height)
            .with_context(|| name.clone())?;
        let options = GesOptions {
            blend: DEFAULT_BLEND,
            footprint_sigmas: DISC_FOOTPRINT_SIGMAS,
            background: rgb(background),
            near,
            sh_degree_cap: sh_degree,
            ..GesOptions::default()
        };
        let split = SurfelSplit {
            params: SplitParams::default(),
            ges_ply: false,
            detect_ges: true,
        };
        let mut r = Renderer::hybrid(options, split)?;
        frame_of(sc, name, &mut r, &cam, t)
    })?;
    to_array(py, frame, ch)
}

/// What `trace` traces: a scene in memory or a file (an export: GLB, glTF, OBJ).
#[derive(FromPyObject)]
enum Traced<'py> {
    Scene(Bound<'py, PyScene>),
    Path(PathBuf),
}

/// Ray-trace one frame with the BVH tracer, as ``splatbridge trace`` does: a ``Scene``
/// traced as its Gaussians (``mode="gaussian"``, the default for scenes: footprint on, hits
/// in mean-depth order, the parity mode) or converted to a mesh in memory (``mode="mesh"``,
/// with ``profile``), or an exported file (GLB, glTF, OBJ path) traced as exported.
/// ``backend`` ``"obvhs"`` (or ``"embree"`` where built), ``k`` the k-buffer size.
/// ``time`` defaults to 0 as the CLI's ``--time``. Result as :func:`render`.
///
/// >>> img = splatbridge.trace(scene, "orbit:8:0", 640, 480)
/// >>> img = splatbridge.trace("export.glb", "scene:0")
#[pyfunction]
#[pyo3(signature = (scene, camera = CameraArg::Spec("orbit:8:0".into()), width = None, height = None, *, time = 0.0, mode = None, profile = None, backend = "obvhs", k = 16, background = (0.0, 0.0, 0.0), near = 0.2, channels = "rgb"))]
fn trace<'py>(
    py: Python<'py>,
    scene: Traced<'py>,
    camera: CameraArg,
    width: Option<u32>,
    height: Option<u32>,
    time: f64,
    mode: Option<&str>,
    profile: Option<&str>,
    backend: &str,
    k: usize,
    background: (f32, f32, f32),
    near: f32,
    channels: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let ch = self::channels(channels)?;
    let is_path = matches!(scene, Traced::Path(_));
    let mode = match mode.unwrap_or(if is_path { "mesh" } else { "gaussian" }) {
        "gaussian" => TraceMode::Gaussian,
        "mesh" => TraceMode::Mesh,
        other => {
            return Err(crate::Error::new_err(format!(
                "mode '{other}' is not gaussian or mesh"
            )))
        }
    };
    let profile = profile.map(crate::convert::profile).transpose()?;
    let backend: BackendKind = backend
        .parse()
        .map_err(|e: splatbridge_raytrace::TraceError| crate::Error::new_err(e.to_string()))?;
    // The CLI's defaults: mode gaussian is the parity mode (footprint, native's order).
    let (footprint, order) = match mode {
        TraceMode::Gaussian => (Footprint::On, HitOrder::MeanDepth),
        TraceMode::Mesh => (Footprint::Off, HitOrder::Hit),
    };
    let options = splatbridge_raytrace::RenderOptions {
        k,
        background: Vec3::from(rgb(background)),
        min_transmittance: 1e-4,
        near,
        compositing: Compositing::Display,
        footprint,
        order,
        sh_direction: ShDirection::for_footprint(footprint),
        ..splatbridge_raytrace::RenderOptions::default()
    };
    let (input, held) = match &scene {
        Traced::Scene(s) => (PathBuf::from(&s.get().name), Some(s.get())),
        Traced::Path(p) => (p.clone(), None),
    };
    let spec = match &camera {
        CameraArg::Spec(s) => s.parse::<CameraSpec>().map_err(|e| crate::to_py(e.into()))?,
        CameraArg::Camera(_) if held.is_none() => {
            return Err(crate::Error::new_err(
                "trace of a file takes a camera spec (orbit:N:I, scene:I, PATH.json:I); load a scene to pass a Camera",
            ))
        }
        CameraArg::Camera(_) => CameraSpec::Scene(0),
    };
    let mut request = CameraRequest::new(spec);
    request.width = width;
    request.height = height;
    let src = TraceSource {
        input,
        camera: request,
        time,
        mode,
        options,
        gltf_frame: false,
        profile,
        drop_invalid: false,
        effects_from: None,
    };
    let frame = run(py, |_| {
        let mut p = match held {
            Some(s) => {
                let cam = match &camera {
                    CameraArg::Camera(_) => Some(camera.resolve(&s.scene, time, width, height)?),
                    CameraArg::Spec(_) => None,
                };
                src.prepare_scene(s.scene.clone(), cam, false)?
            }
            None => src.prepare(false, &|_| {})?,
        };
        let name = src.input.display().to_string();
        let mut tracer = Renderer::tracer_taking(&mut p, backend, BuildPreset::Medium, true)
            .with_context(|| name.clone())?;
        let req = FrameRequest {
            scene: p.effects_scene.as_ref(),
            effects: &p.effects,
            camera: &p.camera,
            time: p.time,
            content: p.counters.clone(),
            lidar: None,
        };
        Ok(render_frame(&mut tracer, &req)
            .with_context(|| name.clone())?
            .frame)
    })?;
    to_array(py, frame, ch)
}

/// Write an image returned by :func:`render`, :func:`trace` or :func:`hybrid` as the CLI
/// writes its ``-o``: ``.png`` (8-bit RGB) or ``.exr`` (float RGBA and Z; needs
/// ``channels="rgbaz"``, or alpha 1 and depth 0 are written).
///
/// >>> splatbridge.save_image(img, "frame.png")
#[pyfunction]
fn save_image(py: Python<'_>, image: PyReadonlyArray3<'_, f32>, path: PathBuf) -> PyResult<()> {
    let a = image.as_array();
    let (h, w, c) = a.dim();
    if !(c == 3 || c == 4 || c == 5) {
        return Err(crate::Error::new_err(format!(
            "{}: image has {c} channels; expected 3 (RGB), 4 (RGBA) or 5 (RGBA and depth)",
            path.display()
        )));
    }
    let mut f = Frame::new(w as u32, h as u32);
    f.alpha.fill(1.0);
    for (i, px) in a.rows().into_iter().enumerate() {
        f.rgb[3 * i..3 * i + 3].copy_from_slice(&[px[0], px[1], px[2]]);
        if c > 3 {
            f.alpha[i] = px[3];
        }
        if c > 4 {
            f.depth[i] = px[4];
        }
    }
    run(py, |_| Ok(save_frame(&path, &f)?))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(hybrid, m)?)?;
    m.add_function(wrap_pyfunction!(trace, m)?)?;
    m.add_function(wrap_pyfunction!(save_image, m)?)?;
    Ok(())
}
