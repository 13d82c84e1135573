//! The dynamic scene graph: static Gaussians ∪ objects, each with Gaussians in a local frame
//! and an SE(3) pose track over time. To be completed: see issue "Foundation".

use glam::{Quat, Vec3};

use crate::{Camera, GaussianCloud};

/// A rigid pose: `world = rotation · local + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub translation: Vec3,
    /// Unit quaternion.
    pub rotation: Quat,
}

/// One keyframe of a track.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseKey {
    pub t: f64,
    pub pose: Pose,
}

/// A pose track: keys with strictly increasing times (validated); linear translation,
/// shortest-path slerp rotation, held constant outside the keyed range.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Track {
    pub keys: Vec<PoseKey>,
}

/// The scene's time range and frame rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeRange {
    pub start: f64,
    pub end: f64,
    pub fps: f64,
}

/// A rigid object: Gaussians in its local frame and a pose track.
#[derive(Clone, Debug)]
pub struct SceneObject {
    pub name: String,
    pub gaussians: GaussianCloud,
    pub track: Track,
}

/// Static Gaussians ∪ objects, the scene's cameras and declared effects.
#[derive(Clone, Debug)]
pub struct DynamicScene {
    pub time: TimeRange,
    pub static_gaussians: GaussianCloud,
    pub objects: Vec<SceneObject>,
    pub cameras: Vec<Camera>,
    /// The manifest's `effects` object (validated names; empty when none declared).
    pub effects: serde_json::Map<String, serde_json::Value>,
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
            cameras: Vec::new(),
            effects: serde_json::Map::new(),
        }
    }

    /// The world-space cloud at time `t`. Object ids: 0 for static Gaussians, k+1 for object k.
    /// (Stub: objects are added untransformed until the scene graph lands.)
    pub fn composite(&self, t: f64) -> GaussianCloud {
        let _ = t;
        let mut out = self.static_gaussians.clone();
        for (k, o) in self.objects.iter().enumerate() {
            out.extend_from(&o.gaussians, Some(k as u32 + 1));
        }
        out
    }
}
