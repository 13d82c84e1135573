//! Camera selection, shared by every command and the parity pipeline: a [`CameraSpec`] (as
//! written on the command line), a [`CameraRequest`] (the spec with the rig's up axis, field
//! of view and the requested image size) resolved against a scene ([`CameraSource`]), and the
//! camera-list syntax of `compare` and `accuracy` ([`parse_camera_list`]: `orbit:N`, `scene`,
//! single specs, comma-separated).
//!
//! Resolution is where sizes are bounded, so no renderer allocates a frame from an unchecked
//! number: an image side is at most [`MAX_IMAGE_SIDE`] pixels (from the command line and from a
//! `cameras.json`), a frame at most `max_pixels` pixels ([`DEFAULT_PIXEL_BUDGET`] unless raised),
//! and an orbit rig has at most [`MAX_ORBIT_CAMERAS`] cameras. `orbit:N:I` builds camera I alone,
//! so a huge N costs nothing.

use std::path::PathBuf;

use glam::DVec3;

use crate::camera::{load_cameras_json, Camera, OrbitRig};
use crate::error::{Result, SceneError};
use crate::GaussianCloud;

/// Largest image side in pixels (the texture limit of common GPUs; a frame's buffers at this
/// size and the pixel budget fit comfortably in memory).
pub const MAX_IMAGE_SIDE: u32 = 16_384;

/// Default largest frame in pixels: 2²⁶ = 67,108,864 (8192×8192, about 1.3 GB of frame
/// buffers at the renderers' 20 bytes per pixel). `CameraRequest::max_pixels` raises it, up to
/// `MAX_IMAGE_SIDE²`.
pub const DEFAULT_PIXEL_BUDGET: u64 = 1 << 26;

/// Largest N of `orbit:N` and `orbit:N:I`. A rig is a list of evenly spaced azimuths; beyond
/// this many cameras neighbouring views are closer than 0.004° and add nothing.
pub const MAX_ORBIT_CAMERAS: usize = 100_000;

/// Default image size for orbit rigs and look-at cameras.
pub const DEFAULT_SIZE: (u32, u32) = (640, 480);

/// A camera as named on the command line (or built from an explicit look-at).
#[derive(Clone, Debug, PartialEq)]
pub enum CameraSpec {
    /// `orbit:N:I`: camera I of an N-camera orbit rig around the scene.
    Orbit { n: usize, index: usize },
    /// `scene:I`: camera I of the scene's own cameras.
    Scene(usize),
    /// `PATH.json:I`: camera I of a 3DGS `cameras.json`.
    Json { path: PathBuf, index: usize },
    /// A camera at `eye` looking at `target` (the request's up axis and field of view).
    LookAt { eye: DVec3, target: DVec3 },
}

fn check_orbit_n(spec: &str, n: usize) -> Result<()> {
    if n == 0 || n > MAX_ORBIT_CAMERAS {
        return Err(SceneError::Invalid(format!(
            "camera spec '{spec}': N must be in 1..={MAX_ORBIT_CAMERAS}"
        )));
    }
    Ok(())
}

impl std::str::FromStr for CameraSpec {
    type Err = SceneError;

    fn from_str(s: &str) -> Result<Self> {
        let bad = || {
            SceneError::Invalid(format!(
                "camera spec '{s}' is not orbit:N:I, scene:I or PATH.json:I"
            ))
        };
        let num = |t: &str| t.parse::<usize>().map_err(|_| bad());
        if let Some(rest) = s.strip_prefix("orbit:") {
            let (n, i) = rest.split_once(':').ok_or_else(bad)?;
            let (n, index) = (num(n)?, num(i)?);
            check_orbit_n(s, n)?;
            if index >= n {
                return Err(SceneError::Invalid(format!(
                    "camera spec '{s}': index must be below N > 0"
                )));
            }
            return Ok(CameraSpec::Orbit { n, index });
        }
        if let Some(rest) = s.strip_prefix("scene:") {
            return Ok(CameraSpec::Scene(num(rest)?));
        }
        let (path, i) = s.rsplit_once(':').ok_or_else(bad)?;
        if !path.ends_with(".json") {
            return Err(bad());
        }
        Ok(CameraSpec::Json {
            path: path.into(),
            index: num(i)?,
        })
    }
}

/// One item of a camera list: a whole rig, all the scene's cameras, or one camera.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraListItem {
    /// `orbit:N`: every camera of an N-camera orbit rig.
    Orbit(usize),
    /// `scene`: every camera of the scene's own.
    Scene,
    /// `PATH.json`: every camera of a 3DGS `cameras.json`.
    File(PathBuf),
    /// Any single camera spec.
    One(CameraSpec),
}

/// Parse a comma-separated camera list (`orbit:4`, `scene`, `cams.json`,
/// `orbit:8:1,scene:0,a.json:2`).
/// Empty items are skipped; a list naming no camera is an error.
pub fn parse_camera_list(s: &str) -> Result<Vec<CameraListItem>> {
    let mut items = Vec::new();
    for item in s.split(',').map(str::trim).filter(|t| !t.is_empty()) {
        if let Some(n) = item.strip_prefix("orbit:").filter(|r| !r.contains(':')) {
            let n: usize = n.parse().map_err(|_| {
                SceneError::Invalid(format!("camera list item '{item}' is not orbit:N"))
            })?;
            check_orbit_n(item, n)?;
            items.push(CameraListItem::Orbit(n));
        } else if item == "scene" {
            items.push(CameraListItem::Scene);
        } else if item.ends_with(".json") {
            items.push(CameraListItem::File(item.into()));
        } else {
            items.push(CameraListItem::One(item.parse()?));
        }
    }
    if items.is_empty() {
        return Err(SceneError::Invalid(format!(
            "camera list '{s}' names no camera"
        )));
    }
    Ok(items)
}

/// Check one image side named `what` (`width`, `height`) is in 1..=[`MAX_IMAGE_SIDE`].
pub fn check_side(what: &str, v: u32) -> std::result::Result<(), String> {
    if v == 0 || v > MAX_IMAGE_SIDE {
        return Err(format!("{what} {v} is outside 1..={MAX_IMAGE_SIDE} pixels"));
    }
    Ok(())
}

/// What a camera is resolved against: a cloud that frames orbit rigs and the input's own
/// cameras (a manifest's `cameras.json`, a glTF file's camera nodes) for `scene:I`.
#[derive(Clone, Copy)]
pub struct CameraSource<'a> {
    pub cloud: &'a GaussianCloud,
    pub own: &'a [Camera],
}

/// A camera spec with the rig parameters and the requested image size.
#[derive(Clone, Debug)]
pub struct CameraRequest {
    pub spec: CameraSpec,
    /// World direction that appears up (orbit rigs and look-at cameras).
    pub up: DVec3,
    /// Vertical field of view in degrees (orbit rigs and look-at cameras).
    pub fov_y_deg: f64,
    /// Requested width: orbit/look-at default 640; a camera of its own is resized to it
    /// (keeping its aspect when only one side is given).
    pub width: Option<u32>,
    pub height: Option<u32>,
    /// Largest frame in pixels.
    pub max_pixels: u64,
}

impl CameraRequest {
    /// A request for `spec` with the CLI's defaults (up −y, 50° field of view, the camera's
    /// own size or 640×480, the default pixel budget).
    pub fn new(spec: CameraSpec) -> Self {
        CameraRequest {
            spec,
            up: DVec3::NEG_Y,
            fov_y_deg: 50.0,
            width: None,
            height: None,
            max_pixels: DEFAULT_PIXEL_BUDGET,
        }
    }

    /// The same request for another spec.
    pub fn with_spec(&self, spec: CameraSpec) -> Self {
        CameraRequest {
            spec,
            ..self.clone()
        }
    }

    fn check_request(&self) -> Result<()> {
        for (name, v) in [("--width", self.width), ("--height", self.height)] {
            if let Some(v) = v {
                check_side(name, v).map_err(SceneError::Invalid)?;
            }
        }
        let cap = u64::from(MAX_IMAGE_SIDE) * u64::from(MAX_IMAGE_SIDE);
        if self.max_pixels == 0 || self.max_pixels > cap {
            return Err(SceneError::Invalid(format!(
                "--max-pixels {} is outside 1..={cap}",
                self.max_pixels
            )));
        }
        Ok(())
    }

    fn rig(&self) -> OrbitRig {
        let (w, h) = self.default_size();
        OrbitRig {
            up: self.up.as_vec3(),
            fov_y_deg: self.fov_y_deg,
            width: w,
            height: h,
            ..OrbitRig::default()
        }
    }

    fn default_size(&self) -> (u32, u32) {
        (
            self.width.unwrap_or(DEFAULT_SIZE.0),
            self.height.unwrap_or(DEFAULT_SIZE.1),
        )
    }

    /// Resolve to one camera, sized as requested and within the pixel budget.
    pub fn resolve(&self, src: CameraSource) -> Result<Camera> {
        self.check_request()?;
        let cam = match &self.spec {
            CameraSpec::LookAt { eye, target } => {
                let (w, h) = self.default_size();
                Camera::look_at(*eye, *target, self.up, self.fov_y_deg, w, h)?
            }
            CameraSpec::Orbit { n, index } => self.rig().camera(src.cloud, *n, *index)?,
            CameraSpec::Scene(i) => {
                if src.own.is_empty() {
                    return Err(SceneError::Invalid(format!(
                        "scene:{i}: the input has no cameras of its own (use orbit:N:I or PATH.json:I)"
                    )));
                }
                let cam = src.own.get(*i).ok_or_else(|| {
                    SceneError::Invalid(format!(
                        "scene:{i}: the input has only {} cameras",
                        src.own.len()
                    ))
                })?;
                self.resize(cam)
            }
            CameraSpec::Json { path, index } => {
                let cams = load_cameras_json(path)?;
                let cam = cams.get(*index).ok_or_else(|| {
                    SceneError::format(
                        path,
                        format!("camera {index} requested, file has {}", cams.len()),
                    )
                })?;
                self.resize(cam)
            }
        };
        self.check_budget(&cam)?;
        Ok(cam)
    }

    /// Resolve every camera of a list, in order (`orbit:N` expands to its N cameras, `scene`
    /// to the source's own). Each item's cameras are the ones [`CameraRequest::resolve`] gives
    /// for its single specs.
    pub fn resolve_list(&self, items: &[CameraListItem], src: CameraSource) -> Result<Vec<Camera>> {
        self.check_request()?;
        let mut cams = Vec::new();
        for item in items {
            match item {
                CameraListItem::Orbit(n) => {
                    check_orbit_n(&format!("orbit:{n}"), *n)?;
                    let rig = self.rig();
                    let (lo, hi) = rig.bounds(src.cloud)?;
                    for cam in rig.cameras_around(lo, hi, *n)? {
                        self.check_budget(&cam)?;
                        cams.push(cam);
                    }
                }
                CameraListItem::Scene => {
                    for i in 0..src.own.len() {
                        cams.push(self.with_spec(CameraSpec::Scene(i)).resolve(src)?);
                    }
                }
                CameraListItem::File(path) => {
                    for cam in load_cameras_json(path)? {
                        let cam = self.resize(&cam);
                        self.check_budget(&cam)?;
                        cams.push(cam);
                    }
                }
                CameraListItem::One(spec) => cams.push(self.with_spec(spec.clone()).resolve(src)?),
            }
        }
        Ok(cams)
    }

    /// A camera of the input's own, resized to the requested size (the other side follows
    /// the camera's aspect when only one is given).
    fn resize(&self, cam: &Camera) -> Camera {
        match (self.width, self.height) {
            (None, None) => cam.clone(),
            (Some(w), None) => {
                let h = ((w as f64 * cam.height as f64 / cam.width as f64).round() as u32).max(1);
                cam.resized(w, h)
            }
            (None, Some(h)) => {
                let w = ((h as f64 * cam.width as f64 / cam.height as f64).round() as u32).max(1);
                cam.resized(w, h)
            }
            (Some(w), Some(h)) => cam.resized(w, h),
        }
    }

    fn check_budget(&self, cam: &Camera) -> Result<()> {
        check_side("width", cam.width)
            .and_then(|()| check_side("height", cam.height))
            .map_err(|what| SceneError::Invalid(format!("camera '{}': {what}", cam.name)))?;
        let pixels = u64::from(cam.width) * u64::from(cam.height);
        if pixels > self.max_pixels {
            return Err(SceneError::Invalid(format!(
                "camera '{}' is {}×{} = {pixels} pixels, above the budget of {} (raise it with --max-pixels)",
                cam.name, cam.width, cam.height, self.max_pixels
            )));
        }
        Ok(())
    }
}
