//! Pinhole cameras in the OpenCV/COLMAP frame (x right, y down, z forward), as 3DGS uses,
//! the `cameras.json` that 3DGS training writes, orbit rigs, and camera specs from the CLI.
//!
//! Pixel convention: `cx`, `cy` are continuous image coordinates in which pixel `i` spans
//! `[i, i+1)`; the reference rasterizer samples pixel `i` at continuous coordinate `i + 0.5`
//! when `cx = W/2` (its `ndc2Pix` puts the principal point at `(W−1)/2` in integer pixel
//! coordinates), so renderers compute `pixel = f·x/z + c − 0.5` and sample at integers.
//!
//! The pose is stored camera-relative: the camera centre in world space (f64) and the
//! world-to-camera rotation (f64), so scenes far from the origin keep their precision
//! (`p_cam = R·(p − centre)` is formed from a difference of nearby numbers).

use std::path::Path;

use glam::{DMat3, DVec3, Mat3, Vec3};
use serde::{Deserialize, Serialize};

use crate::error::{Result, SceneError};

/// A pinhole camera: intrinsics in pixels and a world-to-camera pose (OpenCV frame).
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// Camera centre in world coordinates.
    pub centre: DVec3,
    /// World-to-camera rotation: rows are the camera's x (right), y (down), z (forward) axes
    /// expressed in world coordinates.
    pub world_to_cam: DMat3,
    /// A name for reports (image name, "orbit 3/8", …).
    pub name: String,
}

impl Camera {
    /// A camera at `eye` looking at `target`: z = normalize(target − eye), x = normalize(z × up),
    /// y = z × x (so `up` is the world direction that appears up in the image), vertical field of
    /// view `fov_y_deg`, square pixels, principal point at the image centre.
    pub fn look_at(
        eye: DVec3,
        target: DVec3,
        up: DVec3,
        fov_y_deg: f64,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(SceneError::Invalid(format!(
                "image size {width}×{height} is empty"
            )));
        }
        if !(fov_y_deg > 0.0 && fov_y_deg < 180.0) {
            return Err(SceneError::Invalid(format!(
                "field of view {fov_y_deg}° is outside (0°, 180°)"
            )));
        }
        let z = target - eye;
        if !(z.length() > 0.0) || !z.is_finite() || !up.is_finite() {
            return Err(SceneError::Invalid(
                "camera eye and target coincide or are not finite".into(),
            ));
        }
        let z = z.normalize();
        let x = z.cross(up);
        if !(x.length() > 1e-12) {
            return Err(SceneError::Invalid(
                "camera up vector is parallel to the view direction".into(),
            ));
        }
        let x = x.normalize();
        let y = z.cross(x);
        let f = 0.5 * height as f64 / (0.5 * fov_y_deg.to_radians()).tan();
        Ok(Camera {
            width,
            height,
            fx: f,
            fy: f,
            cx: 0.5 * width as f64,
            cy: 0.5 * height as f64,
            centre: eye,
            world_to_cam: DMat3::from_cols(x, y, z).transpose(),
            name: "look-at".into(),
        })
    }

    /// Horizontal and vertical field of view in radians.
    pub fn fov(&self) -> (f64, f64) {
        (
            2.0 * (0.5 * self.width as f64 / self.fx).atan(),
            2.0 * (0.5 * self.height as f64 / self.fy).atan(),
        )
    }

    /// The same camera at another resolution: focal lengths and principal point scale with it,
    /// so the field of view is kept.
    pub fn resized(&self, width: u32, height: u32) -> Camera {
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        Camera {
            width,
            height,
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: self.cx * sx,
            cy: self.cy * sy,
            ..self.clone()
        }
    }

    /// Camera-to-world rotation (columns are the camera axes in world space).
    pub fn cam_to_world(&self) -> DMat3 {
        self.world_to_cam.transpose()
    }

    /// World point to camera coordinates (f64, camera-relative).
    #[inline]
    pub fn to_camera(&self, p: DVec3) -> DVec3 {
        self.world_to_cam * (p - self.centre)
    }

    /// f32 rotation for hot loops that first subtract the centre in f64.
    pub fn world_to_cam_f32(&self) -> Mat3 {
        self.world_to_cam.as_mat3()
    }

    /// The world-space direction of the ray through continuous image coordinate (u, v)
    /// (pixel `i`'s centre is `i + 0.5`), unit length.
    pub fn ray_dir(&self, u: f64, v: f64) -> DVec3 {
        let d = DVec3::new((u - self.cx) / self.fx, (v - self.cy) / self.fy, 1.0);
        (self.cam_to_world() * d).normalize()
    }

    /// Check intrinsics and pose are usable (finite, positive focal lengths, non-empty image,
    /// orthonormal rotation).
    pub fn validate(&self) -> Result<()> {
        let ok = self.width > 0
            && self.height > 0
            && self.fx > 0.0
            && self.fy > 0.0
            && self.fx.is_finite()
            && self.fy.is_finite()
            && self.cx.is_finite()
            && self.cy.is_finite()
            && self.centre.is_finite()
            && self.world_to_cam.is_finite();
        if !ok {
            return Err(SceneError::Invalid(format!(
                "camera '{}' has invalid intrinsics or pose",
                self.name
            )));
        }
        let r = self.world_to_cam;
        let e = (r * r.transpose() - DMat3::IDENTITY)
            .to_cols_array()
            .iter()
            // `f64::max` skips NaN, which overflowing entries (inf − inf) produce: count a
            // NaN as an infinite error.
            .fold(0.0f64, |a, v| {
                if v.is_nan() {
                    f64::INFINITY
                } else {
                    a.max(v.abs())
                }
            });
        if e > 1e-3 {
            return Err(SceneError::Invalid(format!(
                "camera '{}' rotation is not orthonormal (error {e:.2e})",
                self.name
            )));
        }
        Ok(())
    }
}

/// Largest camera-centre coordinate a `cameras.json` may hold: the ray tracer's BVHs hold
/// ±1e12 (`raytrace::backend::MAX_BVH_COORD`), and the splatting renderer projects in f32, so a
/// camera further out than any scene can be is refused rather than rendered as nothing.
pub const MAX_CAMERA_COORD: f64 = 1e12;
/// Focal-length bounds per pixel of the image side: fx = side/(2·tan(fov/2)), so 1e5 is a
/// field of view of ~0.0006° and 1e-4 one of ~179.98°; anything outside is not a lens.
const MAX_FOCAL_PER_PIXEL: f64 = 1e5;
const MIN_FOCAL_PER_PIXEL: f64 = 1e-4;

/// One entry of the `cameras.json` that 3DGS training writes (`utils/camera_utils.py`,
/// `camera_to_JSON`): `position` is the camera centre and `rotation` the camera-to-world
/// rotation (rows of the 3×3 matrix), both in the world frame.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CameraJson {
    pub id: i64,
    pub img_name: String,
    #[serde(deserialize_with = "de_width")]
    pub width: u32,
    #[serde(deserialize_with = "de_height")]
    pub height: u32,
    pub position: [f64; 3],
    pub rotation: [[f64; 3]; 3],
    pub fx: f64,
    pub fy: f64,
}

/// A number as a message shows it: plain when short, in exponent form when huge or tiny (the
/// plain form of 1e308 has 309 digits).
fn show(x: f64) -> String {
    if x != 0.0 && x.is_finite() && !(1e-4..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// An image side as any JSON number, so a value such as 1e308 or 2.5 is refused by name
/// (serde's own message would say only "expected u32").
fn de_side<'de, D: serde::Deserializer<'de>>(
    d: D,
    name: &str,
) -> std::result::Result<u32, D::Error> {
    let v = f64::deserialize(d)?;
    if v.fract() == 0.0 && (1.0..=crate::camera_spec::MAX_IMAGE_SIDE as f64).contains(&v) {
        Ok(v as u32)
    } else {
        Err(serde::de::Error::custom(format!(
            "{name} {} is not a whole number of pixels in 1..={}",
            show(v),
            crate::camera_spec::MAX_IMAGE_SIDE
        )))
    }
}

fn de_width<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<u32, D::Error> {
    de_side(d, "width")
}

fn de_height<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<u32, D::Error> {
    de_side(d, "height")
}

impl CameraJson {
    pub fn to_camera(&self) -> Camera {
        let r = &self.rotation;
        // rotation[i][j] is row i: camera-to-world; the world-to-camera rotation is its transpose.
        let c2w = DMat3::from_cols(
            DVec3::new(r[0][0], r[1][0], r[2][0]),
            DVec3::new(r[0][1], r[1][1], r[2][1]),
            DVec3::new(r[0][2], r[1][2], r[2][2]),
        );
        Camera {
            width: self.width,
            height: self.height,
            fx: self.fx,
            fy: self.fy,
            cx: 0.5 * self.width as f64,
            cy: 0.5 * self.height as f64,
            centre: DVec3::from_array(self.position),
            world_to_cam: c2w.transpose(),
            name: self.img_name.clone(),
        }
    }

    /// Check every field against what a camera can be, naming the first field that is not:
    /// finite values, a centre within ±[`MAX_CAMERA_COORD`], rotation entries of an
    /// orthonormal matrix, and focal lengths giving a field of view strictly between
    /// ~0.0006° and ~179.98° (`fx` within [10⁻⁴, 10⁵] × `width`, `fy` × `height`). Image
    /// sizes are checked by [`crate::camera_spec::check_side`].
    pub fn check(&self) -> std::result::Result<(), String> {
        for (k, &x) in self.position.iter().enumerate() {
            if !(x.abs() <= MAX_CAMERA_COORD) {
                return Err(format!(
                    "position[{k}] is {}, not a finite coordinate within ±{MAX_CAMERA_COORD:e}",
                    show(x)
                ));
            }
        }
        for (i, row) in self.rotation.iter().enumerate() {
            for (j, &x) in row.iter().enumerate() {
                // An orthonormal matrix's entries lie in [−1, 1]; the slack matches the
                // orthonormality tolerance of `Camera::validate`.
                if !(x.abs() <= 1.0 + 1e-3) {
                    return Err(format!(
                        "rotation[{i}][{j}] is {}, not an entry of a rotation matrix (|x| ≤ 1)",
                        show(x)
                    ));
                }
            }
        }
        for (name, f, side) in [("fx", self.fx, self.width), ("fy", self.fy, self.height)] {
            let side = side as f64;
            if !(f >= MIN_FOCAL_PER_PIXEL * side && f <= MAX_FOCAL_PER_PIXEL * side) {
                return Err(format!(
                    "{name} is {}, outside {:e}..={:e} pixels for a {side}-pixel side \
                     (fields of view between about 0.0006° and 179.98°)",
                    show(f),
                    MIN_FOCAL_PER_PIXEL * side,
                    MAX_FOCAL_PER_PIXEL * side
                ));
            }
        }
        Ok(())
    }

    pub fn from_camera(id: i64, cam: &Camera) -> Self {
        let c2w = cam.cam_to_world();
        let rows = [c2w.row(0), c2w.row(1), c2w.row(2)];
        CameraJson {
            id,
            img_name: cam.name.clone(),
            width: cam.width,
            height: cam.height,
            position: cam.centre.to_array(),
            rotation: rows.map(|r| r.to_array()),
            fx: cam.fx,
            fy: cam.fy,
        }
    }
}

/// Read a 3DGS `cameras.json`; every camera is validated and errors name the entry.
pub fn load_cameras_json(path: &Path) -> Result<Vec<Camera>> {
    let text = crate::input::read_text_bounded(path, crate::input::Cap::Text)?;
    let entries: Vec<CameraJson> = serde_json::from_str(&text).map_err(|e| {
        SceneError::format(
            path,
            format!(
                "not a 3DGS cameras.json: {}",
                crate::input::clip_to(&e.to_string(), 400)
            ),
        )
    })?;
    entries
        .iter()
        .enumerate()
        .map(|(i, e)| {
            e.check().map_err(|what| {
                SceneError::format(
                    path,
                    format!("camera {i} ('{}'): {what}", crate::input::clip(&e.img_name)),
                )
            })?;
            let c = e.to_camera();
            crate::camera_spec::check_side("width", c.width)
                .and_then(|()| crate::camera_spec::check_side("height", c.height))
                .map_err(|what| {
                    SceneError::format(path, format!("camera {i} ('{}'): {what}", e.img_name))
                })?;
            c.validate().map_err(|err| {
                // The validation message repeats the camera's name; both are clipped.
                SceneError::format(
                    path,
                    format!(
                        "camera {i} ('{}'): {}",
                        crate::input::clip(&e.img_name),
                        crate::input::clip_to(&err.to_string(), 200)
                    ),
                )
            })?;
            Ok(c)
        })
        .collect()
}

/// Write cameras in the 3DGS `cameras.json` layout.
pub fn save_cameras_json(path: &Path, cams: &[Camera]) -> Result<()> {
    crate::image_io::write_atomic(path, cameras_json_text(cams)?.as_bytes())
}

/// The text [`save_cameras_json`] writes.
pub fn cameras_json_text(cams: &[Camera]) -> Result<String> {
    let entries: Vec<CameraJson> = cams
        .iter()
        .enumerate()
        .map(|(i, c)| CameraJson::from_camera(i as i64, c))
        .collect();
    serde_json::to_string_pretty(&entries).map_err(|e| SceneError::Invalid(e.to_string()))
}

/// An orbit rig around a point cloud. The up axis defaults to −y, the COLMAP convention most
/// 3DGS captures (and this project's fixtures) use: y points down in the world.
#[derive(Clone, Debug)]
pub struct OrbitRig {
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f64,
    /// Elevation of the orbit above the centre's horizontal plane, in degrees.
    pub elevation_deg: f64,
    /// Percentile cut on each side of the robust bounds (0.02 = 2nd to 98th percentile).
    pub percentile: f32,
    pub width: u32,
    pub height: u32,
}

impl Default for OrbitRig {
    fn default() -> Self {
        OrbitRig {
            up: Vec3::NEG_Y,
            fov_y_deg: 50.0,
            elevation_deg: 20.0,
            percentile: 0.02,
            width: 640,
            height: 480,
        }
    }
}

impl OrbitRig {
    /// `n` cameras evenly spaced in azimuth around the centre of `cloud`'s view bounds
    /// ([`crate::GaussianCloud::view_bounds`]), far enough that their bounding sphere fills
    /// the vertical field of view.
    pub fn cameras(&self, cloud: &crate::GaussianCloud, n: usize) -> Result<Vec<Camera>> {
        let (lo, hi) = self.bounds(cloud)?;
        self.cameras_around(lo, hi, n)
    }

    /// The bounds the rig's orbits frame around `cloud`: its view bounds at the rig's
    /// percentile ([`crate::GaussianCloud::view_bounds`]). An error for an empty scene.
    pub fn bounds(&self, cloud: &crate::GaussianCloud) -> Result<(DVec3, DVec3)> {
        let (lo, hi) = cloud.view_bounds(self.percentile).ok_or_else(|| {
            SceneError::Invalid("cannot place an orbit around an empty scene".into())
        })?;
        Ok((lo.as_dvec3(), hi.as_dvec3()))
    }

    /// Orbit around explicit bounds.
    pub fn cameras_around(&self, lo: DVec3, hi: DVec3, n: usize) -> Result<Vec<Camera>> {
        (0..n.max(1))
            .map(|i| self.camera_around(lo, hi, n, i))
            .collect()
    }

    /// Camera `index` of the `n`-camera orbit around the view bounds of `cloud`, built alone
    /// (no other camera of the rig is allocated, so `n` may be huge).
    pub fn camera(&self, cloud: &crate::GaussianCloud, n: usize, index: usize) -> Result<Camera> {
        let (lo, hi) = self.bounds(cloud)?;
        self.camera_around(lo, hi, n, index)
    }

    /// Camera `i` of the `n`-camera orbit around explicit bounds; `cameras_around` is this for
    /// every `i`, so one camera and the whole rig agree bit for bit.
    pub fn camera_around(&self, lo: DVec3, hi: DVec3, n: usize, i: usize) -> Result<Camera> {
        let OrbitPlacement {
            centre,
            distance: dist,
            up,
            e1,
            e2,
        } = self.placement(lo, hi);
        let el = self.elevation_deg.to_radians();
        let az = std::f64::consts::TAU * i as f64 / n.max(1) as f64;
        let dir = (e1 * az.cos() + e2 * az.sin()) * el.cos() + up * el.sin();
        let mut cam = Camera::look_at(
            centre + dir * dist,
            centre,
            up,
            self.fov_y_deg,
            self.width,
            self.height,
        )?;
        cam.name = format!("orbit {i}/{n}");
        Ok(cam)
    }
}

impl OrbitRig {
    /// Where the rig's orbits around explicit bounds stand: the bounds' centre, the distance
    /// at which their bounding sphere fills the vertical field of view, the unit up and two
    /// horizontal axes orthogonal to it (azimuth 0 along `e1`). Every orbit camera, and
    /// distillation's views about the same orbit, are placed from these numbers.
    pub fn placement(&self, lo: DVec3, hi: DVec3) -> OrbitPlacement {
        let centre = 0.5 * (lo + hi);
        let radius = (0.5 * (hi - lo).length()).max(1e-6);
        let up = self.up.as_dvec3().normalize();
        let distance = radius / (0.5 * self.fov_y_deg.to_radians()).sin() * 1.05;
        let a = if up.x.abs() < 0.9 { DVec3::X } else { DVec3::Z };
        let e1 = (a - up * a.dot(up)).normalize();
        OrbitPlacement {
            centre,
            distance,
            up,
            e1,
            e2: up.cross(e1),
        }
    }
}

/// An orbit's centre, distance and axes ([`OrbitRig::placement`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitPlacement {
    pub centre: DVec3,
    pub distance: f64,
    pub up: DVec3,
    pub e1: DVec3,
    pub e2: DVec3,
}

pub use crate::camera_spec::CameraSpec;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_with_minus_y_up_is_upright_in_y_down_world() {
        let c = Camera::look_at(
            DVec3::new(0.0, 0.0, -5.0),
            DVec3::ZERO,
            DVec3::NEG_Y,
            60.0,
            64,
            48,
        )
        .unwrap();
        // A point above the target (−y in a y-down world) appears in the upper half of the image.
        let p = c.to_camera(DVec3::new(0.0, -1.0, 0.0));
        assert!(p.y < 0.0 && p.z > 0.0);
        let q = c.to_camera(DVec3::new(1.0, 0.0, 0.0));
        assert!(q.x > 0.0);
    }

    #[test]
    fn cameras_json_round_trip() {
        let c = Camera::look_at(
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::ZERO,
            DVec3::NEG_Y,
            45.0,
            100,
            50,
        )
        .unwrap();
        let j = CameraJson::from_camera(0, &c);
        let back = j.to_camera();
        assert!((back.world_to_cam - c.world_to_cam)
            .to_cols_array()
            .iter()
            .all(|v| v.abs() < 1e-12));
        assert_eq!(back.centre, c.centre);
    }

    #[test]
    fn camera_specs_parse() {
        assert_eq!(
            "orbit:8:3".parse::<CameraSpec>().unwrap(),
            CameraSpec::Orbit { n: 8, index: 3 }
        );
        assert_eq!(
            "scene:2".parse::<CameraSpec>().unwrap(),
            CameraSpec::Scene(2)
        );
        assert!(matches!(
            "a/cameras.json:1".parse::<CameraSpec>().unwrap(),
            CameraSpec::Json { index: 1, .. }
        ));
        assert!("orbit:8:9".parse::<CameraSpec>().is_err());
        assert!("nonsense".parse::<CameraSpec>().is_err());
    }
}
