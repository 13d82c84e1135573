//! The dynamic scene graph: static Gaussians ∪ rigid objects, each with Gaussians in a local
//! frame and an SE(3) pose track over time (the street-scene decomposition of driving-scene
//! Gaussian methods such as Street Gaussians / DrivingGaussian: a static background plus
//! per-object clouds moved by tracked poses).
//!
//! Poses interpolate linearly in translation and by shortest-path slerp in rotation, computed in
//! f64 (keys are normalised; `q` and `−q` are the same rotation; nearly identical keys fall back to
//! a normalised lerp so no `0/0` appears), and are held constant outside the keyed range.
//! [`DynamicScene::composite`] gives the world-space cloud at a time: means transformed,
//! rotations composed (`q_world = q_pose · normalize(q_local)`, stored unit length), log-scales
//! and opacities unchanged, SH degree 1–3 coefficients rotated with the object
//! ([`crate::sh_rotate`]), object ids 0 for static Gaussians and k+1 for object k.

use glam::{DQuat, DVec3, Quat, Vec3};
use rayon::prelude::*;

use crate::error::{Result, SceneError};
use crate::sh_rotate::ShRotation;
use crate::{Camera, GaussianCloud};

/// A rigid pose: `world = rotation · local + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub translation: Vec3,
    /// Unit quaternion.
    pub rotation: Quat,
}

impl Default for Pose {
    fn default() -> Self {
        Pose::IDENTITY
    }
}

impl Pose {
    pub const IDENTITY: Pose = Pose {
        translation: Vec3::ZERO,
        rotation: Quat::IDENTITY,
    };

    /// A pose from a translation and any non-zero rotation quaternion (normalised here; a zero
    /// or non-finite quaternion becomes the identity).
    pub fn new(translation: Vec3, rotation: Quat) -> Self {
        Pose {
            translation,
            rotation: normalize_or_identity(rotation),
        }
    }

    /// Local point to world.
    #[inline]
    pub fn transform_point(&self, p: Vec3) -> Vec3 {
        self.rotation * p + self.translation
    }

    /// Local point to world in f64 (for consumers far from the origin).
    pub fn transform_point_f64(&self, p: DVec3) -> DVec3 {
        self.rotation.as_dquat() * p + self.translation.as_dvec3()
    }

    pub fn is_identity(&self) -> bool {
        self.translation == Vec3::ZERO && self.rotation == Quat::IDENTITY
    }
}

/// Normalise a quaternion; zero, tiny or non-finite ones become the identity (never NaN).
pub fn normalize_or_identity(q: Quat) -> Quat {
    let n2 = q.length_squared();
    // Already unit to a few ulps (f32 rounding of a unit f64 quaternion): keep it, so normalising
    // is idempotent and a key sampled at its own time comes back bit-exact.
    if (n2 - 1.0).abs() < 1e-6 {
        return q;
    }
    let d = q.as_dquat();
    let n = d.length();
    if n > 0.0 && n.is_finite() {
        (d / n).as_quat()
    } else {
        Quat::IDENTITY
    }
}

/// Shortest-path spherical interpolation between rotations `a` and `b` at `s` ∈ [0, 1], in f64.
/// `a` and `b` need not be unit; `b` is negated when `a·b < 0` (same rotation, shorter arc), and
/// when the angle between them is tiny the normalised lerp is used (slerp's `sin θ` → 0).
pub fn slerp_shortest(a: Quat, b: Quat, s: f64) -> Quat {
    let a = unit_f64(a);
    let mut b = unit_f64(b);
    let mut dot = a.dot(b);
    if dot < 0.0 {
        b = -b;
        dot = -dot;
    }
    let q = if dot > 1.0 - 1e-10 {
        // Angle below ~1.4e-5 rad: lerp and slerp differ by O(θ³), far below f32 resolution.
        a * (1.0 - s) + b * s
    } else {
        let theta = dot.min(1.0).acos();
        let sin = theta.sin();
        a * (((1.0 - s) * theta).sin() / sin) + b * ((s * theta).sin() / sin)
    };
    let n = q.length();
    if n > 0.0 && n.is_finite() {
        (q / n).as_quat()
    } else {
        a.as_quat()
    }
}

fn unit_f64(q: Quat) -> DQuat {
    let d = q.as_dquat();
    let n = d.length();
    if n > 0.0 && n.is_finite() {
        d / n
    } else {
        DQuat::IDENTITY
    }
}

/// One keyframe of a track.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseKey {
    pub t: f64,
    pub pose: Pose,
}

impl PoseKey {
    /// A key from a time, translation and rotation (normalised; zero becomes the identity —
    /// the manifest rejects zero quaternions before this point).
    pub fn new(t: f64, translation: Vec3, rotation: Quat) -> Self {
        PoseKey {
            t,
            pose: Pose::new(translation, rotation),
        }
    }
}

/// A pose track: keys with strictly increasing times (validated); linear translation,
/// shortest-path slerp rotation, held constant outside the keyed range.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Track {
    pub keys: Vec<PoseKey>,
}

impl Track {
    pub fn new(keys: Vec<PoseKey>) -> Self {
        Track { keys }
    }

    /// A one-key track holding `pose` forever.
    pub fn constant(pose: Pose) -> Self {
        Track {
            keys: vec![PoseKey { t: 0.0, pose }],
        }
    }

    /// The pose at time `t`. At a key's time exactly, that key's pose (rotation unit); before the
    /// first key the first pose, after the last the last; an empty track is the identity; a NaN
    /// time is treated as the start.
    pub fn sample(&self, t: f64) -> Pose {
        let keys = &self.keys;
        let (first, last) = match (keys.first(), keys.last()) {
            (Some(f), Some(l)) => (f, l),
            _ => return Pose::IDENTITY,
        };
        let unit = |p: &Pose| Pose::new(p.translation, p.rotation);
        if t.is_nan() || t <= first.t {
            return unit(&first.pose);
        }
        if t >= last.t {
            return unit(&last.pose);
        }
        // First key with time > t; t lies in [keys[i-1].t, keys[i].t).
        let i = keys.partition_point(|k| k.t <= t);
        let (k0, k1) = (&keys[i - 1], &keys[i]);
        if k0.t == t {
            return unit(&k0.pose);
        }
        let span = k1.t - k0.t;
        let s = if span > 0.0 {
            ((t - k0.t) / span).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let a = k0.pose.translation.as_dvec3();
        let b = k1.pose.translation.as_dvec3();
        Pose {
            translation: (a + (b - a) * s).as_vec3(),
            rotation: slerp_shortest(k0.pose.rotation, k1.pose.rotation, s),
        }
    }

    /// First and last key times; `None` when empty.
    pub fn span(&self) -> Option<(f64, f64)> {
        Some((self.keys.first()?.t, self.keys.last()?.t))
    }

    /// True when every key has the same pose (the object never moves), so a renderer needs to
    /// sample it only once (motion blur) and an exporter needs no animation.
    pub fn is_constant(&self) -> bool {
        self.keys.windows(2).all(|w| {
            w[0].pose.translation == w[1].pose.translation
                && (w[0].pose.rotation == w[1].pose.rotation
                    || w[0].pose.rotation == -w[1].pose.rotation)
        })
    }

    /// Check the track: at least one key, finite times strictly increasing, finite translations,
    /// finite non-zero rotations. The message names the key.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if self.keys.is_empty() {
            return Err("track is empty (needs at least one key)".into());
        }
        for (i, k) in self.keys.iter().enumerate() {
            if !k.t.is_finite() {
                return Err(format!("track[{i}].t = {} is not finite", k.t));
            }
            if !k.pose.translation.is_finite() {
                return Err(format!(
                    "track[{i}].translation {:?} is not finite",
                    k.pose.translation.to_array()
                ));
            }
            let q = k.pose.rotation;
            if !q.is_finite() {
                return Err(format!(
                    "track[{i}].rotation {:?} is not finite",
                    quat_wxyz(q)
                ));
            }
            if q.length_squared() == 0.0 {
                return Err(format!("track[{i}].rotation is the zero quaternion"));
            }
            if i > 0 && k.t <= self.keys[i - 1].t {
                return Err(format!(
                    "track[{i}].t = {} is not after track[{}].t = {} (times must increase strictly)",
                    k.t,
                    i - 1,
                    self.keys[i - 1].t
                ));
            }
        }
        Ok(())
    }
}

/// A quaternion as the manifest and PLY write it: w, x, y, z.
pub fn quat_wxyz(q: Quat) -> [f32; 4] {
    [q.w, q.x, q.y, q.z]
}

/// A quaternion from w, x, y, z (not normalised).
pub fn quat_from_wxyz(v: [f32; 4]) -> Quat {
    Quat::from_xyzw(v[1], v[2], v[3], v[0])
}

/// The scene's time range and frame rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeRange {
    pub start: f64,
    pub end: f64,
    pub fps: f64,
}

/// Most frames a time range may describe (a typo such as `fps: 1e9` is an error, not a hang).
pub const MAX_FRAMES: usize = 1_000_000;

impl TimeRange {
    /// Number of frames: times `start + i/fps` for `i = 0, 1, …` up to and including `end`
    /// (1e-9 s of slack so 4.0 s at 10 fps gives 41 frames despite rounding). At least 1.
    pub fn frame_count(&self) -> usize {
        if !(self.fps > 0.0 && self.fps.is_finite())
            || !(self.end > self.start)
            || !self.start.is_finite()
        {
            return 1;
        }
        let n = ((self.end - self.start) * self.fps + 1e-9).floor();
        if n.is_finite() {
            (n as usize).saturating_add(1).min(MAX_FRAMES)
        } else {
            MAX_FRAMES
        }
    }

    /// Time of frame `i` (`start + i/fps`).
    pub fn frame_time(&self, i: usize) -> f64 {
        if self.fps > 0.0 && self.fps.is_finite() {
            self.start + i as f64 / self.fps
        } else {
            self.start
        }
    }

    /// Check finite values, `end ≥ start`, `fps > 0` and at most [`MAX_FRAMES`] frames.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if !self.start.is_finite() || !self.end.is_finite() || !self.fps.is_finite() {
            return Err(format!(
                "time: start {}, end {}, fps {} must all be finite",
                self.start, self.end, self.fps
            ));
        }
        if self.end < self.start {
            return Err(format!(
                "time.end = {} is before time.start = {}",
                self.end, self.start
            ));
        }
        if self.fps <= 0.0 {
            return Err(format!("time.fps = {} must be positive", self.fps));
        }
        if (self.end - self.start) * self.fps >= MAX_FRAMES as f64 {
            return Err(format!(
                "time: {} s at {} fps is more than {MAX_FRAMES} frames",
                self.end - self.start,
                self.fps
            ));
        }
        Ok(())
    }
}

/// A rigid object: Gaussians in its local frame and a pose track.
#[derive(Clone, Debug)]
pub struct SceneObject {
    pub name: String,
    pub gaussians: GaussianCloud,
    pub track: Track,
}

/// Content of one frame that moves without a rigid track (what a decomposition of a 4D
/// capture could not explain by rigid motion), in world coordinates. It is shown from its time
/// until the next frame's (the first frame also before its time, the last after).
#[derive(Clone, Debug)]
pub struct FrameContent {
    pub t: f64,
    pub gaussians: GaussianCloud,
}

/// Static Gaussians ∪ objects ∪ per-frame content, the scene's cameras and declared effects.
#[derive(Clone, Debug)]
pub struct DynamicScene {
    pub time: TimeRange,
    pub static_gaussians: GaussianCloud,
    pub objects: Vec<SceneObject>,
    /// Per-frame content, times strictly increasing (empty for most scenes).
    pub frames: Vec<FrameContent>,
    pub cameras: Vec<Camera>,
    /// The manifest's `effects` object (validated names; empty when none declared).
    pub effects: serde_json::Map<String, serde_json::Value>,
    /// A 4D model whose Gaussians at time t replace the static cloud in
    /// [`DynamicScene::composite`] (`static_gaussians` then holds the model at its start).
    pub four_d: Option<std::sync::Arc<crate::fourd::FourD>>,
}

impl DynamicScene {
    /// A static scene holding one cloud (what a plain PLY is).
    pub fn from_static(cloud: GaussianCloud) -> Self {
        DynamicScene {
            time: TimeRange {
                start: 0.0,
                end: 0.0,
                fps: 1.0,
            },
            static_gaussians: cloud,
            objects: Vec::new(),
            frames: Vec::new(),
            cameras: Vec::new(),
            effects: serde_json::Map::new(),
            four_d: None,
        }
    }

    /// Frame times `start + i/fps` from `start` up to and including `end` (one frame, `start`,
    /// for a static scene).
    pub fn frame_times(&self) -> Vec<f64> {
        (0..self.time.frame_count())
            .map(|i| self.time.frame_time(i))
            .collect()
    }

    /// Total number of Gaussians (static plus every object's), without per-frame content.
    pub fn gaussian_count(&self) -> usize {
        self.four_d
            .as_ref()
            .map_or(self.static_gaussians.len(), |m| m.max_count())
            + self
                .objects
                .iter()
                .map(|o| o.gaussians.len())
                .sum::<usize>()
    }

    /// The per-frame content shown at `t` (see [`FrameContent`]); `None` when there is none.
    pub fn frame_at(&self, t: f64) -> Option<&FrameContent> {
        let first = self.frames.first()?;
        if t.is_nan() {
            return Some(first);
        }
        let i = self.frames.partition_point(|f| f.t <= t);
        Some(&self.frames[i.saturating_sub(1)])
    }

    /// Number of Gaussians of the composite at `t` (with that time's per-frame content).
    pub fn gaussian_count_at(&self, t: f64) -> usize {
        self.gaussian_count() + self.frame_at(t).map_or(0, |f| f.gaussians.len())
    }

    /// The SH degree of a composite: the highest of the static cloud's, the objects' and the
    /// per-frame content's.
    pub fn sh_degree(&self) -> u8 {
        self.objects
            .iter()
            .map(|o| o.gaussians.sh_degree)
            .chain(self.frames.iter().map(|f| f.gaussians.sh_degree))
            .fold(self.static_gaussians.sh_degree, u8::max)
    }

    /// True when some object moves (its track is not constant) or there is per-frame content.
    pub fn is_dynamic(&self) -> bool {
        self.four_d.is_some()
            || self.objects.iter().any(|o| !o.track.is_constant())
            || self.frames.len() > 1
    }

    /// Every object's pose at time `t`, in object order.
    pub fn object_poses(&self, t: f64) -> Vec<Pose> {
        self.objects.iter().map(|o| o.track.sample(t)).collect()
    }

    /// Check the time range, every track, object names (non-empty, unique) and cloud shapes.
    /// Messages name the object (`objects[k] ('name')`).
    pub fn validate(&self) -> Result<()> {
        self.time.validate().map_err(SceneError::Invalid)?;
        self.static_gaussians
            .check_shape()
            .map_err(|e| SceneError::Invalid(format!("static Gaussians: {e}")))?;
        for (k, o) in self.objects.iter().enumerate() {
            let at = format!("objects[{k}] ('{}')", o.name);
            if o.name.trim().is_empty() {
                return Err(SceneError::Invalid(format!("objects[{k}]: name is empty")));
            }
            if let Some(j) = self.objects[..k].iter().position(|p| p.name == o.name) {
                return Err(SceneError::Invalid(format!(
                    "{at}: name already used by objects[{j}]"
                )));
            }
            o.track
                .validate()
                .map_err(|e| SceneError::Invalid(format!("{at}: {e}")))?;
            o.gaussians
                .check_shape()
                .map_err(|e| SceneError::Invalid(format!("{at}: {e}")))?;
        }
        for (k, f) in self.frames.iter().enumerate() {
            if !f.t.is_finite() {
                return Err(SceneError::Invalid(format!(
                    "frames[{k}].t = {} is not finite",
                    f.t
                )));
            }
            if k > 0 && f.t <= self.frames[k - 1].t {
                return Err(SceneError::Invalid(format!(
                    "frames[{k}].t = {} is not after frames[{}].t = {} (times must increase strictly)",
                    f.t,
                    k - 1,
                    self.frames[k - 1].t
                )));
            }
            f.gaussians
                .check_shape()
                .map_err(|e| SceneError::Invalid(format!("frames[{k}]: {e}")))?;
        }
        Ok(())
    }

    /// The world-space cloud at time `t`. Static Gaussians are copied unchanged (stored values,
    /// bit-exact); each object's Gaussians get its pose at `t`: means `R·m + T`, rotations
    /// `q_pose · normalize(q_local)` (stored unit), log-scales and opacity logits unchanged, SH
    /// bands 1–3 rotated by `R`. The SH degree is [`DynamicScene::sh_degree`] (lower-degree clouds
    /// are zero-filled). Object ids: 0 for static Gaussians, k+1 for object k, and the number of
    /// objects plus one for the per-frame content shown at `t` (last, as stored).
    pub fn composite(&self, t: f64) -> GaussianCloud {
        let mut out = GaussianCloud::with_capacity(self.sh_degree(), self.gaussian_count_at(t));
        self.composite_into(t, &mut out);
        out
    }

    /// The Gaussians at `t` for a reader that needs positions, shapes and colours only (framing
    /// a camera, statistics): a scene without objects lends its static cloud (which carries no
    /// object ids) instead of copying it, a multi-gigabyte copy at 10 M Gaussians.
    pub fn composite_view(&self, t: f64) -> std::borrow::Cow<'_, GaussianCloud> {
        if self.objects.is_empty() && self.frames.is_empty() && self.four_d.is_none() {
            std::borrow::Cow::Borrowed(&self.static_gaussians)
        } else {
            std::borrow::Cow::Owned(self.composite(t))
        }
    }

    /// [`DynamicScene::composite`] consuming the scene: a scene without objects hands over its
    /// static cloud instead of copying it (the same values and ids), so loading a file and
    /// writing it elsewhere holds one cloud, not two.
    pub fn into_composite(self, t: f64) -> GaussianCloud {
        if !self.objects.is_empty() || !self.frames.is_empty() || self.four_d.is_some() {
            return self.composite(t);
        }
        let mut out = self.static_gaussians;
        out.object_ids = Some(vec![0; out.len()]);
        out
    }

    /// [`DynamicScene::composite`] into an existing cloud, reusing its allocations (per-frame
    /// loops over large scenes avoid re-faulting hundreds of megabytes each frame).
    pub fn composite_into(&self, t: f64, out: &mut GaussianCloud) {
        if let Some(m) = &self.four_d {
            // A frame file that changed after the sequence was opened cannot be read: the
            // frame is then empty (nothing drawn) rather than stale.
            *out = m.sample(t).unwrap_or_default();
            let n = out.len();
            out.object_ids = Some(vec![0; n]);
            return;
        }
        let n = self.gaussian_count_at(t);
        out.means.clear();
        out.log_scales.clear();
        out.rotations.clear();
        out.opacity_logits.clear();
        out.sh.clear();
        out.sh_degree = self.sh_degree();
        let ids = out.object_ids.get_or_insert_with(Vec::new);
        ids.clear();
        ids.reserve(n);
        append(out, &self.static_gaussians, None, 0);
        for (k, o) in self.objects.iter().enumerate() {
            append(out, &o.gaussians, Some(o.track.sample(t)), k as u32 + 1);
        }
        if let Some(f) = self.frame_at(t) {
            append(out, &f.gaussians, None, self.objects.len() as u32 + 1);
        }
    }
}

/// Append `src` to `out` (whose degree is ≥ `src`'s), transformed by `pose` when given.
fn append(out: &mut GaussianCloud, src: &GaussianCloud, pose: Option<Pose>, id: u32) {
    let n = src.len();
    let k_out = out.coeffs();
    let k_src = src.coeffs().min(k_out);
    let sh_start = out.sh.len();
    if src.coeffs() == k_out {
        out.sh.extend_from_slice(&src.sh);
    } else {
        out.sh.reserve(n * k_out);
        for c in src.sh.chunks(src.coeffs().max(1)) {
            out.sh.extend_from_slice(&c[..k_src]);
            out.sh
                .extend(std::iter::repeat_n(Vec3::ZERO, k_out - k_src));
        }
    }
    out.object_ids
        .get_or_insert_with(Vec::new)
        .extend(std::iter::repeat_n(id, n));
    out.log_scales.extend_from_slice(&src.log_scales);
    out.opacity_logits.extend_from_slice(&src.opacity_logits);
    match pose {
        None => {
            out.means.extend_from_slice(&src.means);
            out.rotations.extend_from_slice(&src.rotations);
        }
        Some(pose) => {
            let r = pose.rotation;
            let tr = pose.translation;
            out.means
                .par_extend(src.means.par_iter().map(|&m| r * m + tr));
            out.rotations.par_extend(
                src.rotations
                    .par_iter()
                    .map(|&q| normalize_or_identity(r * normalize_or_identity(q))),
            );
            let shr = ShRotation::from_quat(r);
            let degree = src.sh_degree.min(out.sh_degree);
            if !shr.identity && degree > 0 {
                out.sh[sh_start..]
                    .par_chunks_mut(k_out.max(1))
                    .with_min_len(1024)
                    .for_each(|d| shr.apply(degree, &mut d[..k_src]));
            }
        }
    }
}
