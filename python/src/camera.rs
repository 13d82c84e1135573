//! `Camera`: a pinhole camera in the OpenCV frame (x right, y down, z forward), as 3DGS
//! training code holds it: a 4×4 world-to-camera matrix and fx, fy, cx, cy in pixels. The
//! functions taking a camera also take a spec string (`orbit:8:0`, `scene:0`,
//! `cameras.json:3`), resolved against the scene as the CLI's `--camera` is.

use std::path::PathBuf;

use glam::{DMat3, DVec3};
use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArray2};
use pyo3::prelude::*;
use splatbridge_scene::camera::load_cameras_json;
use splatbridge_scene::camera_spec::{CameraRequest, CameraSource, CameraSpec};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::Camera;

/// A pinhole camera (OpenCV/COLMAP frame: x right, y down, z forward).
///
/// >>> cam = splatbridge.Camera(world_to_camera, fx=500, fy=500, cx=320, cy=240,
/// ...                          width=640, height=480)
/// >>> cams = splatbridge.Camera.from_json("cameras.json")   # a 3DGS cameras.json
#[pyclass(frozen, name = "Camera", module = "splatbridge", from_py_object)]
#[derive(Clone)]
pub struct PyCamera {
    pub camera: Camera,
}

#[pymethods]
impl PyCamera {
    /// ``world_to_camera``: 4×4 (or 3×4) [R | t] with p_cam = R·p_world + t; ``cx``, ``cy``
    /// continuous pixel coordinates (``width/2`` is the centre, as 3DGS's cameras have it).
    #[new]
    #[pyo3(signature = (world_to_camera, fx, fy, cx, cy, width, height, name = "camera".to_string()))]
    fn new(
        world_to_camera: PyReadonlyArray2<'_, f64>,
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        width: u32,
        height: u32,
        name: String,
    ) -> PyResult<PyCamera> {
        let m = world_to_camera.as_array();
        let s = m.shape();
        if !(s == [4, 4] || s == [3, 4]) {
            return Err(crate::Error::new_err(format!(
                "camera '{name}': world_to_camera has shape {s:?}; expected (4, 4) or (3, 4)"
            )));
        }
        let r = DMat3::from_cols(
            DVec3::new(m[[0, 0]], m[[1, 0]], m[[2, 0]]),
            DVec3::new(m[[0, 1]], m[[1, 1]], m[[2, 1]]),
            DVec3::new(m[[0, 2]], m[[1, 2]], m[[2, 2]]),
        );
        let t = DVec3::new(m[[0, 3]], m[[1, 3]], m[[2, 3]]);
        let camera = Camera {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            // p_cam = R·(p − c) = R·p + t, so c = −Rᵀ·t.
            centre: -(r.transpose() * t),
            world_to_cam: r,
            name: name.clone(),
        };
        camera
            .validate()
            .map_err(|e| crate::Error::new_err(format!("camera '{name}': {e}")))?;
        Ok(PyCamera { camera })
    }

    /// Every camera of a 3DGS ``cameras.json`` (or camera ``index`` alone).
    #[staticmethod]
    #[pyo3(signature = (path, index = None))]
    fn from_json(path: PathBuf, index: Option<usize>) -> PyResult<Py<PyAny>> {
        let cams = load_cameras_json(&path).map_err(|e| crate::to_py(e.into()))?;
        Python::attach(|py| match index {
            None => Ok(cams
                .into_iter()
                .map(|camera| PyCamera { camera })
                .collect::<Vec<_>>()
                .into_pyobject(py)?
                .into_any()
                .unbind()),
            Some(i) => {
                let n = cams.len();
                let camera = cams.into_iter().nth(i).ok_or_else(|| {
                    crate::Error::new_err(format!(
                        "{}: camera {i} requested, file has {n}",
                        path.display()
                    ))
                })?;
                Ok(Py::new(py, PyCamera { camera })?.into_any())
            }
        })
    }

    /// The 4×4 world-to-camera matrix [R | t; 0 0 0 1].
    #[getter]
    fn world_to_camera<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let r = self.camera.world_to_cam;
        let t = -(r * self.camera.centre);
        let mut v = Vec::with_capacity(16);
        for i in 0..3 {
            v.extend([r.col(0)[i], r.col(1)[i], r.col(2)[i], t[i]]);
        }
        v.extend([0.0, 0.0, 0.0, 1.0]);
        Ok(v.into_pyarray(py).reshape([4, 4])?.into_any())
    }

    #[getter]
    fn fx(&self) -> f64 {
        self.camera.fx
    }
    #[getter]
    fn fy(&self) -> f64 {
        self.camera.fy
    }
    #[getter]
    fn cx(&self) -> f64 {
        self.camera.cx
    }
    #[getter]
    fn cy(&self) -> f64 {
        self.camera.cy
    }
    #[getter]
    fn width(&self) -> u32 {
        self.camera.width
    }
    #[getter]
    fn height(&self) -> u32 {
        self.camera.height
    }
    /// Camera centre in world coordinates.
    #[getter]
    fn centre(&self) -> (f64, f64, f64) {
        self.camera.centre.into()
    }
    #[getter]
    fn name(&self) -> &str {
        &self.camera.name
    }

    /// The same camera at another image size (intrinsics scaled).
    fn resized(&self, width: u32, height: u32) -> PyCamera {
        PyCamera {
            camera: self.camera.resized(width, height),
        }
    }

    fn __repr__(&self) -> String {
        let c = &self.camera;
        format!(
            "<splatbridge.Camera '{}' {}×{} fx {} fy {} cx {} cy {}>",
            c.name, c.width, c.height, c.fx, c.fy, c.cx, c.cy
        )
    }
}

/// A camera argument: a `Camera` or a spec string.
#[derive(FromPyObject)]
pub enum CameraArg {
    Camera(PyCamera),
    Spec(String),
}

impl CameraArg {
    /// The camera for `scene` at `time`, at `width`×`height` when given (a `Camera` is resized
    /// to it; specs as the CLI's `--camera` with `--width`/`--height`).
    pub fn resolve(
        &self,
        scene: &DynamicScene,
        time: f64,
        width: Option<u32>,
        height: Option<u32>,
    ) -> anyhow::Result<Camera> {
        match self {
            CameraArg::Camera(c) => {
                let cam = match (width, height) {
                    (None, None) => c.camera.clone(),
                    (w, h) => {
                        let c = &c.camera;
                        let w = w.unwrap_or_else(|| {
                            (c.width as f64 * h.unwrap_or(c.height) as f64 / c.height as f64)
                                .round() as u32
                        });
                        let h = h.unwrap_or_else(|| {
                            (c.height as f64 * w as f64 / c.width as f64).round() as u32
                        });
                        c.resized(w, h)
                    }
                };
                cam.validate()?;
                Ok(cam)
            }
            CameraArg::Spec(s) => {
                let mut req = CameraRequest::new(s.parse::<CameraSpec>()?);
                req.width = width;
                req.height = height;
                let cloud = scene.composite_view(time);
                Ok(req.resolve(CameraSource {
                    cloud: &cloud,
                    own: &scene.cameras,
                })?)
            }
        }
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyCamera>()
}
