//! What the mesh glTF writer (`gltf_writer`) and the splat glTF writer (`splats_gltf`) build
//! alike: the JSON arrays and the in-memory part of the binary buffer ([`DocBuilder`]), the
//! objects' animation tracks and the scene's one animation ([`ObjectTrack`], [`Animation`]),
//! camera nodes, the up-axis root node, and the pass through `gltf_json` that types the
//! document before it is written (glTF 2.0 specification, §3 and §5).

use std::io;

use glam::{DMat3, DQuat, DVec3, Quat};
use serde_json::{json, Value};
use splatbridge_scene::dynamic::{DynamicScene, Pose, PoseKey};
use splatbridge_scene::Camera;

use crate::options::ConvertOptions;

pub(crate) const ARRAY_BUFFER: u32 = 34962;
pub(crate) const ELEMENT_ARRAY_BUFFER: u32 = 34963;
pub(crate) const FLOAT: u32 = 5126;

/// Collects glTF JSON arrays and the in-memory part of the binary buffer.
pub(crate) struct DocBuilder {
    pub accessors: Vec<Value>,
    pub views: Vec<Value>,
    pub small: Vec<u8>,
}

impl DocBuilder {
    pub fn new() -> Self {
        DocBuilder {
            accessors: Vec::new(),
            views: Vec::new(),
            small: Vec::new(),
        }
    }

    /// Append bytes to the in-memory part (4-byte aligned) and return a view index.
    pub fn small_view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        self.align();
        let off = self.small.len();
        self.small.extend_from_slice(bytes);
        let mut v = json!({"buffer": 0, "byteOffset": off, "byteLength": bytes.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.views.push(v);
        self.views.len() - 1
    }

    /// Pad the in-memory part to a multiple of 4 bytes (where streamed data starts).
    pub fn align(&mut self) {
        while !self.small.len().is_multiple_of(4) {
            self.small.push(0);
        }
    }

    /// Add a buffer view of the streamed part and return its index.
    pub fn view(&mut self, v: Value) -> usize {
        self.views.push(v);
        self.views.len() - 1
    }

    pub fn accessor(&mut self, a: Value) -> usize {
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    /// A FLOAT accessor over f32 values in the small part, with min/max when asked.
    pub fn floats(&mut self, data: &[f32], ty: &str, comps: usize, minmax: bool) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.small_view(&bytes, None);
        let count = data.len() / comps;
        let mut a = json!({"bufferView": view, "componentType": FLOAT, "count": count, "type": ty});
        if minmax {
            let mut lo = vec![f32::INFINITY; comps];
            let mut hi = vec![f32::NEG_INFINITY; comps];
            for (i, &x) in data.iter().enumerate() {
                lo[i % comps] = lo[i % comps].min(x);
                hi[i % comps] = hi[i % comps].max(x);
            }
            a["min"] = json!(lo);
            a["max"] = json!(hi);
        }
        self.accessor(a)
    }
}

/// glTF camera frame from an OpenCV camera: glTF cameras look down −Z with +Y up, OpenCV
/// cameras down +Z with +Y down, so the camera-to-world rotation gains a 180° turn about
/// the camera's x axis. Returns (translation, rotation x,y,z,w, camera JSON).
/// The near plane (`znear`, scene units) of the perspective cameras splatbridge writes.
pub const CAMERA_ZNEAR: f64 = 0.01;

pub fn camera_node(cam: &Camera) -> ([f32; 3], [f32; 4], Value) {
    let c2w = cam.cam_to_world() * DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
    let q = DQuat::from_mat3(&c2w).normalize();
    let yfov = 2.0 * (cam.height as f64 / (2.0 * cam.fy)).atan();
    let json = json!({
        "type": "perspective",
        "name": cam.name,
        "perspective": {"yfov": yfov, "aspectRatio": cam.width as f64 / cam.height as f64, "znear": CAMERA_ZNEAR},
        "extras": {"opencv": {"width": cam.width, "height": cam.height, "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy}}
    });
    (
        cam.centre.as_vec3().to_array(),
        q.as_quat().to_array(),
        json,
    )
}

/// Keys of an object's track in f32 seconds, extended to span the scene's time range, with
/// sign-continuous unit quaternions and strictly increasing times.
pub(crate) fn track_keys(keys: &[PoseKey], start: f64, end: f64) -> Vec<(f32, [f32; 3], [f32; 4])> {
    let mut out: Vec<(f32, [f32; 3], [f32; 4])> = Vec::new();
    let mut push = |t: f64, p: Pose| {
        let t = t as f32;
        if out.last().is_some_and(|l| !(t > l.0)) {
            return;
        }
        let mut q = p.rotation.normalize();
        if let Some(l) = out.last() {
            if Quat::from_array(l.2).dot(q) < 0.0 {
                q = -q;
            }
        }
        out.push((t, p.translation.to_array(), q.to_array()));
    };
    let (Some(first), Some(last)) = (keys.first(), keys.last()) else {
        return out;
    };
    if end > start && start < first.t {
        push(start, first.pose);
    }
    for k in keys {
        push(k.t, k.pose);
    }
    if end > start && end > last.t {
        push(end, last.pose);
    }
    out
}

/// One object's track in the small data: accessors of the key times, translations and
/// rotations, and the first pose (the node's rest transform).
#[derive(Clone, Copy, Debug)]
pub(crate) struct ObjectTrack {
    input: usize,
    translation: usize,
    rotation: usize,
    t0: [f32; 3],
    r0: [f32; 4],
}

/// Every object's track (`None` for an object without keys), written into the small data in
/// object order.
pub(crate) fn object_tracks(d: &mut DocBuilder, scene: &DynamicScene) -> Vec<Option<ObjectTrack>> {
    scene
        .objects
        .iter()
        .map(|o| {
            let keys = track_keys(&o.track.keys, scene.time.start, scene.time.end);
            let first = keys.first()?;
            let times: Vec<f32> = keys.iter().map(|k| k.0).collect();
            let tr: Vec<f32> = keys.iter().flat_map(|k| k.1).collect();
            let rot: Vec<f32> = keys.iter().flat_map(|k| k.2).collect();
            Some(ObjectTrack {
                t0: first.1,
                r0: first.2,
                input: d.floats(&times, "SCALAR", 1, true),
                translation: d.floats(&tr, "VEC3", 3, false),
                rotation: d.floats(&rot, "VEC4", 4, false),
            })
        })
        .collect()
}

/// The scene's one glTF animation: viewers play one clip at a time, and Blender makes one
/// action per animated object from it.
#[derive(Default)]
pub(crate) struct Animation {
    samplers: Vec<Value>,
    channels: Vec<Value>,
}

impl Animation {
    /// Move node `index` (its JSON `node`) along `track`: it rests at the first pose, and
    /// LINEAR translation and rotation channels follow the keys.
    pub fn object(&mut self, index: usize, node: &mut Value, track: &ObjectTrack) {
        node["translation"] = json!(track.t0);
        node["rotation"] = json!(track.r0);
        for (out, path) in [
            (track.translation, "translation"),
            (track.rotation, "rotation"),
        ] {
            self.channel(index, track.input, out, "LINEAR", path);
        }
    }

    /// A channel of node `index` on `path` with a new sampler.
    pub fn channel(
        &mut self,
        index: usize,
        input: usize,
        output: usize,
        interpolation: &str,
        path: &str,
    ) {
        self.samplers
            .push(json!({"input": input, "output": output, "interpolation": interpolation}));
        self.channels.push(
            json!({"sampler": self.samplers.len() - 1, "target": {"node": index, "path": path}}),
        );
    }

    /// The `animations` array, or `None` when nothing moves.
    pub fn into_json(self) -> Option<Value> {
        (!self.channels.is_empty()).then(
            || json!([{"name": "scene", "samplers": self.samplers, "channels": self.channels}]),
        )
    }
}

/// Add the scene's cameras as nodes under the root (`children`); returns the `cameras` array.
pub(crate) fn camera_nodes(
    scene: &DynamicScene,
    nodes: &mut Vec<Value>,
    children: &mut Vec<usize>,
) -> Vec<Value> {
    let mut cameras = Vec::new();
    for cam in &scene.cameras {
        let (t, r, c) = camera_node(cam);
        cameras.push(c);
        children.push(nodes.len());
        nodes.push(
            json!({"name": cam.name, "camera": cameras.len() - 1, "translation": t, "rotation": r}),
        );
    }
    cameras
}

/// The root node `splatbridge_root`: its rotation maps the input's up axis onto glTF's +Y.
pub(crate) fn root_node(children: Vec<usize>, opts: &ConvertOptions) -> Value {
    let mut root = json!({"name": "splatbridge_root", "children": children, "extras": {"inputUp": opts.up.name()}});
    let rq = opts.up.root_rotation();
    if rq != Quat::IDENTITY {
        root["rotation"] = json!(rq.to_array());
    }
    root
}

/// Remove top-level keys from a document.
pub(crate) fn remove_keys(doc: &mut Value, keys: &[&str]) {
    if let Some(o) = doc.as_object_mut() {
        for k in keys {
            o.remove(*k);
        }
    }
}

/// Pass a JSON document through `gltf_json::Root` (schema types and glTF validation) and
/// serialise it.
pub(crate) fn typed_json(doc: &Value) -> io::Result<Vec<u8>> {
    let raw = serde_json::to_vec(doc).map_err(io::Error::other)?;
    let root = gltf_json::Root::from_slice(&raw)
        .map_err(|e| io::Error::other(format!("internal glTF document error: {e}")))?;
    root.to_vec().map_err(io::Error::other)
}
