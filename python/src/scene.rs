//! `Scene`: a loaded scene (static Gaussians, dynamic objects, cameras, time range) whose
//! attributes are NumPy arrays viewing the Rust storage without copies, read-only (the scene
//! is immutable, so the views stay valid as long as any of them lives: each keeps the scene
//! alive). Rotations are the one copy: the cloud stores glam's x, y, z, w order and Python
//! gets the PLY's and 3DGS training's w, x, y, z.
//!
//! `load` and `save` are the CLI's readers and writers (`convert IN -o OUT.ply` writes the same
//! bytes as `save(load(IN), OUT.ply)`).

use std::path::PathBuf;

use glam::{Quat, Vec3};
use numpy::ndarray::ArrayView;
use numpy::{IntoPyArray, PyArray, PyArrayMethods, PyReadonlyArrayDyn};
use pyo3::prelude::*;
use splatbridge::pipeline::export::{cloud_format, write_cloud_export};
use splatbridge::pipeline::source::load_scene_kind;
use splatbridge_scene::dynamic::{quat_wxyz, DynamicScene};
use splatbridge_scene::gaussians::sh_coeffs;
use splatbridge_scene::ply::GaussianKind;
use splatbridge_scene::GaussianCloud;

use crate::camera::PyCamera;
use crate::run::run;

/// A Gaussian scene: a static cloud, dynamic objects (each a cloud on a trajectory), the
/// scene's own cameras and its time range.
///
/// Array attributes describe the static cloud, as stored (before activation), and are
/// read-only views of the scene's memory (no copies except ``rotations``):
///
/// >>> scene = splatbridge.load("scene.ply")
/// >>> scene.means.shape, scene.sh.shape
/// ((131072, 3), (131072, 16, 3))
///
/// A dynamic scene's cloud at a time is ``scene.composite(t)``.
#[pyclass(frozen, name = "Scene", module = "splatbridge")]
pub struct PyScene {
    pub scene: DynamicScene,
    /// The name errors and reports use (the file it was loaded from, or "arrays").
    pub name: String,
    /// What the file's Gaussians are (2DGS surfels stay surfels when saved or converted, as
    /// `convert` keeps them).
    pub kind: GaussianKind,
    /// The native renderer's buffers from the last `render` of this scene, reused by the next
    /// (a fresh renderer per call faulted in its frame buffers each time). Taken under the
    /// lock, so concurrent renders of one scene each get buffers (one of them fresh).
    pub native_buffers: std::sync::Mutex<Option<splatbridge_hybrid::Renderer>>,
}

/// A read-only NumPy view of `data` (whose elements are `width` f32 each, `width` 1 giving a
/// 1-D array) owned by `owner`.
fn view<'py, T: Copy>(
    owner: &Bound<'py, PyScene>,
    data: &[T],
    shape: &[usize],
) -> PyResult<Bound<'py, PyAny>> {
    let floats = std::mem::size_of_val(data) / std::mem::size_of::<f32>();
    debug_assert_eq!(floats, shape.iter().product::<usize>());
    // SAFETY: Vec3 and f32 slices are plain f32 data (glam's Vec3 is `#[repr(C)]` x, y, z
    // without padding), so `data` is `floats` consecutive, aligned f32 values.
    let flat: &[f32] = unsafe { std::slice::from_raw_parts(data.as_ptr().cast::<f32>(), floats) };
    let v = ArrayView::from_shape(shape.to_vec(), flat)
        .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
    // SAFETY: the scene is frozen (never mutated after construction), so its vectors are
    // never reallocated; the array keeps `owner` alive as its base object.
    let arr = unsafe { PyArray::borrow_from_array(&v, owner.clone().into_any()) };
    arr.call_method1("setflags", (false,))?;
    Ok(arr.into_any())
}

#[pymethods]
impl PyScene {
    /// Positions, shape (N, 3), float32.
    #[getter]
    fn means<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let c = &slf.get().scene.static_gaussians;
        view(slf, &c.means, &[c.len(), 3])
    }

    /// Natural log of the per-axis standard deviations, shape (N, 3), float32.
    #[getter]
    fn log_scales<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let c = &slf.get().scene.static_gaussians;
        view(slf, &c.log_scales, &[c.len(), 3])
    }

    /// Opacity logits (before the sigmoid), shape (N,), float32.
    #[getter]
    fn opacities<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let c = &slf.get().scene.static_gaussians;
        view(slf, &c.opacity_logits, &[c.len()])
    }

    /// Spherical-harmonic coefficients, shape (N, (degree+1)², 3), float32; ``sh[:, 0]`` is
    /// the DC term (3DGS's ``f_dc``), then 3DGS's ``f_rest`` coefficient by coefficient.
    #[getter]
    fn sh<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let c = &slf.get().scene.static_gaussians;
        view(slf, &c.sh, &[c.len(), sh_coeffs(c.sh_degree), 3])
    }

    /// Rotations as stored (w, x, y, z; not necessarily unit length), shape (N, 4), float32.
    /// A copy: the scene stores x, y, z, w.
    #[getter]
    fn rotations<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let c = &self.scene.static_gaussians;
        let flat: Vec<f32> = c.rotations.iter().flat_map(|&q| quat_wxyz(q)).collect();
        Ok(flat.into_pyarray(py).reshape([c.len(), 4])?.into_any())
    }

    /// SH degree (0–3).
    #[getter]
    fn sh_degree(&self) -> u8 {
        self.scene.static_gaussians.sh_degree
    }

    /// Whether the scene has dynamic objects.
    #[getter]
    fn is_dynamic(&self) -> bool {
        self.scene.is_dynamic()
    }

    /// (start, end, fps) of the scene's time range in seconds.
    #[getter]
    fn time_range(&self) -> (f64, f64, f64) {
        let t = &self.scene.time;
        (t.start, t.end, t.fps)
    }

    /// Every frame time of the time range (one, the start, for a static scene).
    #[getter]
    fn frame_times(&self) -> Vec<f64> {
        self.scene.frame_times()
    }

    /// The scene's own cameras (a manifest's ``cameras.json``, a glTF file's camera nodes).
    #[getter]
    fn cameras(&self) -> Vec<PyCamera> {
        self.scene
            .cameras
            .iter()
            .map(|c| PyCamera { camera: c.clone() })
            .collect()
    }

    /// The camera a spec names for this scene (``"orbit:N:I"``, ``"scene:I"``,
    /// ``"cameras.json:I"``), resolved once: an orbit frames the scene's Gaussians at
    /// ``time`` (default: its start), which a render loop need not repeat per frame.
    ///
    /// >>> cam = scene.camera("orbit:8:0", 640, 480)
    /// >>> img = splatbridge.render(scene, cam)
    #[pyo3(signature = (spec, width = None, height = None, *, time = None))]
    fn camera(
        &self,
        py: Python<'_>,
        spec: String,
        width: Option<u32>,
        height: Option<u32>,
        time: Option<f64>,
    ) -> PyResult<PyCamera> {
        let t = time.unwrap_or(self.scene.time.start);
        let arg = crate::camera::CameraArg::Spec(spec);
        let camera = run(py, |_| {
            anyhow::Context::with_context(arg.resolve(&self.scene, t, width, height), || {
                self.name.clone()
            })
        })?;
        Ok(PyCamera { camera })
    }

    /// The name used in errors (the file it was loaded from, or ``"arrays"``).
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// Every Gaussian of the scene, static and dynamic objects together.
    fn __len__(&self) -> usize {
        self.scene.gaussian_count()
    }

    /// What the Gaussians are, as read: ``"3dgs"`` (3D Gaussians, Mip-Splatting's filter
    /// folded in), ``"2dgs"`` (2D Gaussian surfels: ``save`` writes them back as a 2DGS PLY,
    /// ``convert`` makes fans in their plane) or ``"points"`` (coloured points).
    #[getter]
    fn kind(&self) -> &'static str {
        match self.kind {
            GaussianKind::Gaussians3D => "3dgs",
            GaussianKind::Surfels2D => "2dgs",
            GaussianKind::Points => "points",
        }
    }

    fn __repr__(&self) -> String {
        format!(
            "<splatbridge.Scene '{}': {} Gaussians, SH degree {}, {} objects, {} cameras>",
            self.name,
            self.scene.gaussian_count(),
            self.scene.sh_degree(),
            self.scene.objects.len(),
            self.scene.cameras.len()
        )
    }

    /// The whole cloud (static and every object posed) at ``time`` seconds, as a static
    /// scene.
    ///
    /// >>> frame = scene.composite(0.5)
    fn composite(&self, py: Python<'_>, time: f64) -> PyResult<PyScene> {
        let scene = &self.scene;
        let cloud = run(py, |_| Ok(scene.composite(time)))?;
        Ok(PyScene {
            scene: DynamicScene::from_static(cloud),
            name: self.name.clone(),
            kind: self.kind,
            native_buffers: Default::default(),
        })
    }

    /// A static scene from arrays (copied; any float dtype, C order or not):
    /// ``means`` (N, 3), ``log_scales`` (N, 3), ``rotations`` (N, 4) w, x, y, z,
    /// ``opacities`` (N,) logits, ``sh`` (N, K, 3) with K = 1, 4, 9 or 16 (or (N, 3) for
    /// degree 0). Invalid values (NaN, infinite scales, zero quaternions) raise
    /// ``splatbridge.Error`` as loading a file does.
    ///
    /// >>> s = splatbridge.Scene.from_arrays(means, log_scales, rotations, opacities, sh)
    #[staticmethod]
    fn from_arrays<'py>(
        py: Python<'py>,
        means: &Bound<'py, PyAny>,
        log_scales: &Bound<'py, PyAny>,
        rotations: &Bound<'py, PyAny>,
        opacities: &Bound<'py, PyAny>,
        sh: &Bound<'py, PyAny>,
    ) -> PyResult<PyScene> {
        let np = py.import("numpy")?;
        let f32s = |a: &Bound<'py, PyAny>| -> PyResult<PyReadonlyArrayDyn<'py, f32>> {
            np.call_method1("asarray", (a, "float32"))?.extract()
        };
        let (means, log_scales, rotations, opacities, sh) = (
            f32s(means)?,
            f32s(log_scales)?,
            f32s(rotations)?,
            f32s(opacities)?,
            f32s(sh)?,
        );
        let bad = |m: String| crate::Error::new_err(format!("arrays: {m}"));
        let n = means.as_array().shape().first().copied().unwrap_or(0);
        let check = |name: &str, a: &PyReadonlyArrayDyn<'_, f32>, tail: &[usize]| {
            let s = a.as_array().shape().to_vec();
            if s.len() != 1 + tail.len() || s[0] != n || s[1..] != *tail {
                let want: Vec<String> = std::iter::once("N".to_string())
                    .chain(tail.iter().map(|t| t.to_string()))
                    .collect();
                return Err(bad(format!(
                    "{name} has shape {s:?}; expected ({}) with N = {n}",
                    want.join(", ")
                )));
            }
            Ok(())
        };
        check("means", &means, &[3])?;
        check("log_scales", &log_scales, &[3])?;
        check("rotations", &rotations, &[4])?;
        check("opacities", &opacities, &[])?;
        let shs = sh.as_array().shape().to_vec();
        let k = match shs[..] {
            [m, 3] if m == n => 1,
            [m, k, 3] if m == n => k,
            _ => {
                return Err(bad(format!(
                    "sh has shape {shs:?}; expected (N, K, 3) with N = {n}"
                )))
            }
        };
        let degree = match k {
            1 => 0u8,
            4 => 1,
            9 => 2,
            16 => 3,
            _ => {
                return Err(bad(format!(
                    "sh has {k} coefficients per channel; expected 1, 4, 9 or 16"
                )))
            }
        };
        let flat = |a: &PyReadonlyArrayDyn<'_, f32>| -> Vec<f32> {
            a.as_array().iter().copied().collect()
        };
        let (m, ls, r, o, s) = (
            flat(&means),
            flat(&log_scales),
            flat(&rotations),
            flat(&opacities),
            flat(&sh),
        );
        let cloud = run(py, move |_| {
            let v3 = |v: &[f32]| -> Vec<Vec3> { v.chunks_exact(3).map(Vec3::from_slice).collect() };
            let cloud = GaussianCloud {
                means: v3(&m),
                log_scales: v3(&ls),
                rotations: r
                    .chunks_exact(4)
                    .map(|q| Quat::from_xyzw(q[1], q[2], q[3], q[0]))
                    .collect(),
                opacity_logits: o,
                sh_degree: degree,
                sh: v3(&s),
                object_ids: None,
            };
            cloud.check_shape()?;
            for i in 0..cloud.len() {
                if let Some(why) = cloud.invalid_reason(i) {
                    anyhow::bail!("arrays: Gaussian {i}: {why}");
                }
            }
            Ok(cloud)
        })?;
        Ok(PyScene {
            scene: DynamicScene::from_static(cloud),
            name: "arrays".into(),
            kind: GaussianKind::default(),
            native_buffers: Default::default(),
        })
    }
}

/// Load a scene from any format the CLI reads, recognised by content: a 3DGS PLY (and
/// 2DGS, Mip-Splatting and point PLYs), a compressed PLY, ``.splat``, ``.spz``, ``.ksplat``,
/// SOG (a ``meta.json`` or ``.sog``), glTF/GLB with ``KHR_gaussian_splatting``, or a
/// splatbridge-scene/1 manifest (JSON, dynamic objects included).
///
/// With ``drop_invalid``, Gaussians with NaN or infinite values are dropped with a warning
/// (Python's ``warnings``) instead of raising.
///
/// >>> scene = splatbridge.load("scene.ply")
/// >>> len(scene)
/// 131072
#[pyfunction]
#[pyo3(signature = (path, *, drop_invalid = false))]
fn load(py: Python<'_>, path: PathBuf, drop_invalid: bool) -> PyResult<PyScene> {
    let (scene, warnings) = run(py, |_| {
        let warnings = std::sync::Mutex::new(Vec::new());
        let (scene, kind) = load_scene_kind(&path, drop_invalid, &|w: &str| {
            if let Ok(mut v) = warnings.lock() {
                v.push(w.to_string());
            }
        })?;
        Ok(((scene, kind), warnings.into_inner().unwrap_or_default()))
    })?;
    warn_all(py, &warnings)?;
    let (scene, kind) = scene;
    Ok(PyScene {
        scene,
        name: path.display().to_string(),
        kind,
        native_buffers: Default::default(),
    })
}

/// Issue library warnings as Python `UserWarning`s.
pub fn warn_all(py: Python<'_>, warnings: &[String]) -> PyResult<()> {
    if warnings.is_empty() {
        return Ok(());
    }
    let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
    for w in warnings {
        let msg = std::ffi::CString::new(w.replace('\0', " "))
            .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
        PyErr::warn(py, &category, &msg, 1)?;
    }
    Ok(())
}

/// Write a scene's splats, the format chosen by the extension as ``splatbridge convert``
/// chooses it: ``.ply`` (3DGS PLY), ``.compressed.ply``, ``.splat``, ``.spz``, ``.ksplat``
/// (one cloud: a dynamic scene is composited at ``time``, default its start), or ``.glb`` /
/// ``.gltf`` (``KHR_gaussian_splatting``, dynamic objects as animated nodes). The bytes are
/// the CLI's (``convert IN -o OUT`` for splat files, ``convert IN --splats -o OUT`` for glTF).
/// Returns the bytes written.
///
/// >>> splatbridge.save(scene, "out.spz")
#[pyfunction]
#[pyo3(signature = (scene, path, *, time = None, spz_version = None))]
fn save(
    py: Python<'_>,
    scene: &Bound<'_, PyScene>,
    path: PathBuf,
    time: Option<f64>,
    spz_version: Option<u32>,
) -> PyResult<u64> {
    let s = scene.get();
    let (sc, name) = (&s.scene, &s.name);
    run(py, |_| {
        let version = spz_version.unwrap_or(splatbridge_scene::formats::spz::WRITE_VERSION);
        if let Some(format) = cloud_format(&path, None, true, version, 1)? {
            return Ok(write_cloud_export(sc.clone(), &path, format, time, None, s.kind)?.bytes);
        }
        if splatbridge::pipeline::export::is_gltf(&path) {
            let req = crate::convert::request(sc, name, &path, true, None, None, None)?;
            let opts = req.mesh_options(sc, s.kind)?;
            req.export(sc, &opts)?;
            return Ok(std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0));
        }
        anyhow::bail!(
            "{}: save writes .ply, .compressed.ply, .splat, .spz, .ksplat, .glb or .gltf splats (meshes: convert)",
            path.display()
        )
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyScene>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(save, m)?)?;
    Ok(())
}
