//! The glTF 2.0 mesh writer (GLB, or `.gltf` + `.bin`), streaming.
//!
//! Layout of the binary buffer: first the small data built in memory (animation keys, the
//! falloff PNG), then per mesh one interleaved vertex view (POSITION f32×3, NORMAL f32×3
//! unless left out, COLOR_0 normalized u16×4, `_GAUSSIAN_ID` f32, TEXCOORD_0 f32×2) and one
//! u32 index view.
//! Every offset and stride is a multiple of 4. Sizes are known from the classification, so
//! the JSON (with exact POSITION min/max from a first generation pass) is written before the
//! mesh data, which is generated again chunk by chunk and streamed: memory stays at a few
//! chunks, not a copy of the mesh. The JSON goes through `gltf_json::Root`, so it is
//! schema-typed before it is written.

use std::io::{self, Write};
use std::path::Path;

use glam::{DMat3, DQuat, DVec3, Quat};
use serde_json::{json, Value};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::Camera;

use crate::options::{ConvertOptions, ConvertReport, Profile};
use crate::{io_err, shape_for, FrameClouds, MeshEntry, Role};

pub(crate) const ARRAY_BUFFER: u32 = 34962;
pub(crate) const ELEMENT_ARRAY_BUFFER: u32 = 34963;
pub(crate) const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;

/// Byte layout of one interleaved vertex.
#[derive(Clone, Copy, Debug)]
pub struct VertexLayout {
    pub ids: bool,
    pub uv: bool,
    pub normals: bool,
}

impl VertexLayout {
    pub fn stride(self) -> usize {
        self.id_offset() + if self.ids { 4 } else { 0 } + if self.uv { 8 } else { 0 }
    }
    fn color_offset(self) -> usize {
        if self.normals {
            24
        } else {
            12
        }
    }
    fn id_offset(self) -> usize {
        self.color_offset() + 8
    }
    fn uv_offset(self) -> usize {
        self.id_offset() + if self.ids { 4 } else { 0 }
    }
}

/// Encode a chunk's vertices interleaved.
pub fn vertex_bytes(s: &crate::MeshSoup, l: VertexLayout) -> Vec<u8> {
    let mut b = Vec::with_capacity(s.vertex_count() * l.stride());
    for v in 0..s.vertex_count() {
        let normal: &[f32] = if l.normals { &s.normals[v] } else { &[] };
        for x in s.positions[v].iter().chain(normal) {
            b.extend_from_slice(&x.to_le_bytes());
        }
        for c in s.colors[v] {
            b.extend_from_slice(&((c.clamp(0.0, 1.0) * 65535.0).round() as u16).to_le_bytes());
        }
        if l.ids {
            b.extend_from_slice(&(s.gaussian_ids[v] as f32).to_le_bytes());
        }
        if l.uv {
            for x in s.uvs[v] {
                b.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    b
}

/// A sink encoding vertices straight into the interleaved layout (no intermediate soup).
pub struct Interleaved {
    pub bytes: Vec<u8>,
    layout: VertexLayout,
    n: u32,
}

impl Interleaved {
    pub fn new(vertices: usize, layout: VertexLayout) -> Self {
        Interleaved {
            bytes: Vec::with_capacity(vertices * layout.stride()),
            layout,
            n: 0,
        }
    }
}

impl crate::mesh::VertexSink for Interleaved {
    const FULL: bool = true;
    #[inline]
    fn vertex(
        &mut self,
        p: glam::Vec3,
        normal: [f32; 3],
        rgba: [f32; 4],
        uv: [f32; 2],
        id: u32,
    ) -> u32 {
        let mut v = [0u8; 44];
        let mut put = |o: usize, b: [u8; 4]| v[o..o + 4].copy_from_slice(&b);
        let normal: &[f32] = if self.layout.normals { &normal } else { &[] };
        for (k, x) in p.to_array().iter().chain(normal).enumerate() {
            put(4 * k, x.to_le_bytes());
        }
        let q = |c: f32| ((c.clamp(0.0, 1.0) * 65535.0).round() as u16).to_le_bytes();
        let (c0, c1, c2, c3) = (q(rgba[0]), q(rgba[1]), q(rgba[2]), q(rgba[3]));
        let co = self.layout.color_offset();
        v[co..co + 8].copy_from_slice(&[c0[0], c0[1], c1[0], c1[1], c2[0], c2[1], c3[0], c3[1]]);
        let mut o = co + 8;
        if self.layout.ids {
            v[o..o + 4].copy_from_slice(&(id as f32).to_le_bytes());
            o += 4;
        }
        if self.layout.uv {
            v[o..o + 4].copy_from_slice(&uv[0].to_le_bytes());
            v[o + 4..o + 8].copy_from_slice(&uv[1].to_le_bytes());
        }
        self.bytes.extend_from_slice(&v[..self.layout.stride()]);
        self.n += 1;
        self.n - 1
    }
    #[inline]
    fn triangle(&mut self, _: [u32; 3]) {}
}

pub(crate) fn index_bytes(idx: &[u32]) -> Vec<u8> {
    let mut b = Vec::with_capacity(idx.len() * 4);
    for i in idx {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}

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
        while !self.small.len().is_multiple_of(4) {
            self.small.push(0);
        }
        let off = self.small.len();
        self.small.extend_from_slice(bytes);
        let mut v = json!({"buffer": 0, "byteOffset": off, "byteLength": bytes.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
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
pub fn camera_node(cam: &Camera) -> ([f32; 3], [f32; 4], Value) {
    let c2w = cam.cam_to_world() * DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
    let q = DQuat::from_mat3(&c2w).normalize();
    let yfov = 2.0 * (cam.height as f64 / (2.0 * cam.fy)).atan();
    let json = json!({
        "type": "perspective",
        "name": cam.name,
        "perspective": {"yfov": yfov, "aspectRatio": cam.width as f64 / cam.height as f64, "znear": 0.01},
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
pub(crate) fn track_keys(
    keys: &[splatbridge_scene::dynamic::PoseKey],
    start: f64,
    end: f64,
) -> Vec<(f32, [f32; 3], [f32; 4])> {
    let mut out: Vec<(f32, [f32; 3], [f32; 4])> = Vec::new();
    let mut push = |t: f64, p: splatbridge_scene::dynamic::Pose| {
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

/// Accessors of one object's animation (times, translations, rotations) and its first pose.
pub(crate) type AnimAccessors = (usize, usize, usize, [f32; 3], [f32; 4]);

/// A mesh region streamed after the small data.
struct Region {
    vertex_offset: u64,
    vertex_len: u64,
    index_len: u64,
}

/// Everything decided before streaming.
struct Plan {
    json: Vec<u8>,
    small: Vec<u8>,
    /// Per entry: the residual primitive's region, then the surfel primitive's.
    regions: Vec<[Option<Region>; 2]>,
    bin_len: u64,
    layout: VertexLayout,
}

fn plan(
    entries: &[MeshEntry<'_>],
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
    report: &ConvertReport,
    bin_uri: Option<String>,
) -> io::Result<Plan> {
    let mut d = DocBuilder::new();
    let layout = VertexLayout {
        ids: opts.gaussian_ids,
        uv: opts.profile == Profile::Texture,
        normals: opts.normals,
    };
    let mut nodes: Vec<Value> = Vec::new();
    let mut root_children: Vec<usize> = Vec::new();
    // One glTF animation for the whole scene: viewers play one clip at a time, and Blender
    // makes one action per animated object from it.
    let mut samplers: Vec<Value> = Vec::new();
    let mut channels: Vec<Value> = Vec::new();
    nodes.push(json!({})); // the root, filled in below

    // Small data first: animations and the texture.
    let mut images = Vec::new();
    let any_mesh = entries.iter().any(|e| !e.mesher.is_empty());
    // Surfels carry no texture coordinates; the falloff image serves residual meshes only.
    if layout.uv && any_mesh {
        let view = d.small_view(&crate::texture::png(), None);
        images
            .push(json!({"bufferView": view, "mimeType": "image/png", "name": "gaussian_falloff"}));
    }
    let mut object_anim: Vec<Option<AnimAccessors>> = vec![None; scene.objects.len()];
    for (k, o) in scene.objects.iter().enumerate() {
        let keys = track_keys(&o.track.keys, scene.time.start, scene.time.end);
        if keys.is_empty() {
            continue;
        }
        let times: Vec<f32> = keys.iter().map(|k| k.0).collect();
        let tr: Vec<f32> = keys.iter().flat_map(|k| k.1).collect();
        let rot: Vec<f32> = keys.iter().flat_map(|k| k.2).collect();
        let input = d.floats(&times, "SCALAR", 1, true);
        let t_acc = d.floats(&tr, "VEC3", 3, false);
        let r_acc = d.floats(&rot, "VEC4", 4, false);
        object_anim[k] = Some((input, t_acc, r_acc, keys[0].1, keys[0].2));
    }
    let mut frame_anim: Option<(usize, Vec<usize>)> = None;
    if let Some(fr) = frames {
        if !fr.times.is_empty() {
            let times: Vec<f32> = fr.times.iter().map(|&t| t as f32).collect();
            if times.windows(2).any(|w| !(w[1] > w[0])) {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    "frame times collapse in f32 seconds",
                ));
            }
            let input = d.floats(&times, "SCALAR", 1, true);
            let outs = (0..times.len())
                .map(|i| {
                    let s: Vec<f32> = (0..times.len())
                        .flat_map(|j| [if i == j { 1.0 } else { 0.0 }; 3])
                        .collect();
                    d.floats(&s, "VEC3", 3, false)
                })
                .collect();
            frame_anim = Some((input, outs));
        }
    }
    while !d.small.len().is_multiple_of(4) {
        d.small.push(0);
    }

    // Mesh regions after the small data: per entry the residual primitive, then the surfels.
    let mut offset = d.small.len() as u64;
    let surfel_layout = VertexLayout {
        ids: layout.ids,
        uv: false,
        normals: layout.normals,
    };
    let any_residual = entries.iter().any(|e| !e.mesher.is_empty());
    let any_surfels = entries
        .iter()
        .any(|e| e.surfels.as_ref().is_some_and(|s| !s.is_empty()));
    // Materials in use, in order: the splat material, then the surfel material.
    let splat_material = 0usize;
    let surfel_material = usize::from(any_residual);
    let mut regions = Vec::with_capacity(entries.len());
    let mut meshes: Vec<Value> = Vec::new();
    let mut frame_nodes: Vec<(usize, usize)> = Vec::new();
    for e in entries {
        let m = &e.mesher;
        let residual_bounds = if m.is_empty() { None } else { m.bounds() };
        let surfel_bounds =
            e.surfels
                .as_ref()
                .and_then(|s| if s.is_empty() { None } else { s.bounds() });
        if residual_bounds.is_none() && surfel_bounds.is_none() {
            regions.push([None, None]);
            continue;
        }
        let mut prims = Vec::new();
        let mut pair = [None, None];
        let parts = [
            (
                residual_bounds,
                layout,
                m.counts.vertices,
                m.counts.triangles,
                splat_material,
            ),
            (
                surfel_bounds,
                surfel_layout,
                e.surfels.as_ref().map_or(0, |s| s.counts.vertices),
                e.surfels.as_ref().map_or(0, |s| s.counts.triangles),
                surfel_material,
            ),
        ];
        for (slot, (bounds, layout, nv, nt, material)) in parts.into_iter().enumerate() {
            let Some((lo, hi)) = bounds else { continue };
            let stride = layout.stride();
            let region = Region {
                vertex_offset: offset,
                vertex_len: nv * stride as u64,
                index_len: nt * 12,
            };
            d.views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": region.vertex_len, "byteStride": stride, "target": ARRAY_BUFFER}));
            let vv = d.views.len() - 1;
            d.views.push(json!({"buffer": 0, "byteOffset": offset + region.vertex_len, "byteLength": region.index_len, "target": ELEMENT_ARRAY_BUFFER}));
            let iv = d.views.len() - 1;
            offset += region.vertex_len + region.index_len;
            let pos = d.accessor(json!({"bufferView": vv, "byteOffset": 0, "componentType": FLOAT, "count": nv, "type": "VEC3", "min": lo, "max": hi}));
            let col = d.accessor(json!({"bufferView": vv, "byteOffset": layout.color_offset(), "componentType": UNSIGNED_SHORT, "normalized": true, "count": nv, "type": "VEC4"}));
            let mut attrs = json!({"POSITION": pos, "COLOR_0": col});
            if layout.normals {
                attrs["NORMAL"] = json!(d.accessor(json!({"bufferView": vv, "byteOffset": 12, "componentType": FLOAT, "count": nv, "type": "VEC3"})));
            }
            if layout.ids {
                attrs["_GAUSSIAN_ID"] = json!(d.accessor(json!({"bufferView": vv, "byteOffset": layout.id_offset(), "componentType": FLOAT, "count": nv, "type": "SCALAR"})));
            }
            if layout.uv {
                attrs["TEXCOORD_0"] = json!(d.accessor(json!({"bufferView": vv, "byteOffset": layout.uv_offset(), "componentType": FLOAT, "count": nv, "type": "VEC2"})));
            }
            let ind = d.accessor(json!({"bufferView": iv, "componentType": UNSIGNED_INT, "count": nt * 3, "type": "SCALAR"}));
            prims.push(
                json!({"attributes": attrs, "indices": ind, "material": material, "mode": 4}),
            );
            pair[slot] = Some(region);
        }
        let (role, name) = match e.role {
            Role::Static => ("static", m.counts.name.clone()),
            Role::Object(k) => ("object", scene.objects[k].name.clone()),
            Role::Frame(k) => ("frame", format!("frame_{k:04}")),
        };
        let mut extras = json!({"role": role, "idOffset": m.counts.id_offset, "gaussians": m.counts.gaussians_in});
        if let Some(s) = &e.surfels {
            extras["surfels"] = json!(s.counts.surfels - s.counts.dropped_overflow);
            extras["primitives"] = json!(if pair[0].is_some() && pair[1].is_some() {
                vec!["gaussians", "surfels"]
            } else if pair[0].is_some() {
                vec!["gaussians"]
            } else {
                vec!["surfels"]
            });
        }
        meshes.push(json!({
            "name": name,
            "primitives": prims,
            "extras": extras
        }));
        let mesh = meshes.len() - 1;
        let mut node = json!({"name": name, "mesh": mesh});
        match e.role {
            Role::Object(k) => {
                if let Some((input, t_acc, r_acc, t0, r0)) = object_anim[k] {
                    node["translation"] = json!(t0);
                    node["rotation"] = json!(r0);
                    let ni = nodes.len();
                    for (out, path) in [(t_acc, "translation"), (r_acc, "rotation")] {
                        samplers.push(
                            json!({"input": input, "output": out, "interpolation": "LINEAR"}),
                        );
                        channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": ni, "path": path}}));
                    }
                }
            }
            Role::Frame(k) => {
                if k != 0 {
                    node["scale"] = json!([0.0, 0.0, 0.0]);
                }
                frame_nodes.push((nodes.len(), k));
            }
            Role::Static => {}
        }
        root_children.push(nodes.len());
        nodes.push(node);
        regions.push(pair);
    }
    if let Some((input, outs)) = &frame_anim {
        for &(ni, k) in &frame_nodes {
            samplers.push(json!({"input": input, "output": outs[k], "interpolation": "STEP"}));
            channels.push(
                json!({"sampler": samplers.len() - 1, "target": {"node": ni, "path": "scale"}}),
            );
        }
    }
    let mut cameras = Vec::new();
    for cam in &scene.cameras {
        let (t, r, c) = camera_node(cam);
        cameras.push(c);
        root_children.push(nodes.len());
        nodes.push(
            json!({"name": cam.name, "camera": cameras.len() - 1, "translation": t, "rotation": r}),
        );
    }
    let rq = opts.up.root_rotation();
    let mut root = json!({"name": "splatbridge_root", "children": root_children, "extras": {"inputUp": opts.up.name()}});
    if rq != Quat::IDENTITY {
        root["rotation"] = json!(rq.to_array());
    }
    nodes[0] = root;

    let bin_len = offset;
    let mut material = json!({
        "name": "gaussian_splats",
        "alphaMode": "BLEND",
        // Both windings are written instead when arranged for viewers (`order.rs`).
        "doubleSided": !opts.both_windings,
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "extensions": {"KHR_materials_unlit": {}}
    });
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("splatbridge ", env!("CARGO_PKG_VERSION")), "extras": {"splatbridge": report.metadata(opts)}},
        "extensionsUsed": ["KHR_materials_unlit"],
        "scene": 0,
        "scenes": [{"name": "scene", "nodes": [0]}],
        "nodes": nodes,
        "materials": [],
        "buffers": [{"byteLength": bin_len}],
        "bufferViews": d.views,
        "accessors": d.accessors,
    });
    let textured = layout.uv && any_residual;
    if textured {
        material["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
        doc["images"] = json!(images);
        doc["samplers"] =
            json!([{"magFilter": 9729, "minFilter": 9729, "wrapS": 33071, "wrapT": 33071}]);
        doc["textures"] = json!([{"sampler": 0, "source": 0}]);
    }
    // Only materials a primitive uses (the validator flags unused objects).
    let mut materials = Vec::new();
    if any_residual {
        materials.push(material);
    }
    if any_surfels {
        // Surfels are opaque: vertex alpha is 1 and OPAQUE ignores it anyway; no texture.
        materials.push(json!({
            "name": "surfels",
            "alphaMode": "OPAQUE",
            "doubleSided": true,
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "extensions": {"KHR_materials_unlit": {}}
        }));
    }
    doc["materials"] = json!(materials);
    if meshes.is_empty() {
        for k in ["materials", "extensionsUsed"] {
            doc.as_object_mut().map(|o| o.remove(k));
        }
    } else {
        doc["meshes"] = json!(meshes);
    }
    if !textured {
        // The falloff image is in the buffer only when a residual mesh uses it.
        for k in ["images", "samplers", "textures"] {
            doc.as_object_mut().map(|o| o.remove(k));
        }
    }
    if !channels.is_empty() {
        doc["animations"] = json!([{"name": "scene", "samplers": samplers, "channels": channels}]);
    }
    if !cameras.is_empty() {
        doc["cameras"] = json!(cameras);
    }
    if bin_len == 0 {
        // Nothing survived (an empty scene): a zero-length buffer is invalid glTF.
        for k in ["buffers", "bufferViews", "accessors"] {
            doc.as_object_mut().map(|o| o.remove(k));
        }
    } else if let Some(uri) = bin_uri {
        doc["buffers"][0]["uri"] = json!(uri);
    }
    let json = typed_json(&doc)?;
    Ok(Plan {
        json,
        small: d.small,
        regions,
        bin_len,
        layout,
    })
}

/// Pass a JSON document through `gltf_json::Root` (schema types and glTF validation) and
/// serialise it.
pub(crate) fn typed_json(doc: &Value) -> io::Result<Vec<u8>> {
    let raw = serde_json::to_vec(doc).map_err(io::Error::other)?;
    let root = gltf_json::Root::from_slice(&raw)
        .map_err(|e| io::Error::other(format!("internal glTF document error: {e}")))?;
    root.to_vec().map_err(io::Error::other)
}

fn stream_bin<W: Write>(w: &mut W, plan: &Plan, entries: &[MeshEntry<'_>]) -> io::Result<u64> {
    w.write_all(&plan.small)?;
    let mut written = plan.small.len() as u64;
    for (e, pair) in entries.iter().zip(&plan.regions) {
        if let Some(r) = &pair[0] {
            debug_assert_eq!(written, r.vertex_offset);
            let layout = plan.layout;
            let mut vb = 0u64;
            e.mesher.map_chunks_with(
                |n| Interleaved::new(n, layout),
                |s| s.bytes,
                |b| {
                    vb += b.len() as u64;
                    w.write_all(&b)
                },
            )?;
            let mut ib = 0u64;
            e.mesher.map_index_chunks(0, index_bytes, |b| {
                ib += b.len() as u64;
                w.write_all(&b)
            })?;
            check_region(&e.mesher.counts.name, vb, ib, r)?;
            written += vb + ib;
        }
        if let (Some(r), Some(s)) = (&pair[1], &e.surfels) {
            debug_assert_eq!(written, r.vertex_offset);
            let layout = VertexLayout {
                ids: plan.layout.ids,
                uv: false,
                normals: plan.layout.normals,
            };
            let mut vb = 0u64;
            s.map_chunks_with(
                |n| Interleaved::new(n, layout),
                |s| s.bytes,
                |b| {
                    vb += b.len() as u64;
                    w.write_all(&b)
                },
            )?;
            let mut ib = 0u64;
            s.map_index_chunks(0, index_bytes, |b| {
                ib += b.len() as u64;
                w.write_all(&b)
            })?;
            check_region(&s.counts.name, vb, ib, r)?;
            written += vb + ib;
        }
    }
    Ok(written)
}

fn check_region(name: &str, vb: u64, ib: u64, r: &Region) -> io::Result<()> {
    if vb != r.vertex_len || ib != r.index_len {
        return Err(io::Error::other(format!(
            "internal: mesh '{name}' produced {vb}+{ib} bytes, planned {}+{}",
            r.vertex_len, r.index_len
        )));
    }
    Ok(())
}

/// Write a GLB: header, JSON chunk (space-padded), BIN chunk (zero-padded). Returns bytes.
pub fn write_glb<W: Write>(
    w: &mut W,
    entries: &[MeshEntry<'_>],
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
    report: &ConvertReport,
) -> io::Result<u64> {
    let plan = plan(entries, scene, frames, opts, report, None)?;
    glb_container(w, &plan.json, plan.bin_len, |w| {
        stream_bin(w, &plan, entries)
    })
}

/// The GLB container around a JSON document and a streamed binary chunk of `bin_len` bytes.
pub(crate) fn glb_container<W: Write>(
    w: &mut W,
    json: &[u8],
    bin_len: u64,
    body: impl FnOnce(&mut W) -> io::Result<u64>,
) -> io::Result<u64> {
    let json_pad = (4 - json.len() % 4) % 4;
    let bin_pad = (4 - bin_len % 4) % 4;
    let json_chunk = json.len() + json_pad;
    let bin_chunk = bin_len + bin_pad;
    let total = 12 + 8 + json_chunk as u64 + if bin_len > 0 { 8 + bin_chunk } else { 0 };
    if total > u32::MAX as u64 {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "GLB would be {total} bytes; the format's limit is 4 GiB (write .gltf instead)"
            ),
        ));
    }
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&(total as u32).to_le_bytes())?;
    w.write_all(&(json_chunk as u32).to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(json)?;
    w.write_all(&b"   "[..json_pad])?;
    if bin_len > 0 {
        w.write_all(&(bin_chunk as u32).to_le_bytes())?;
        w.write_all(b"BIN\0")?;
        let n = body(w)?;
        if n != bin_len {
            return Err(io::Error::other(format!(
                "internal: binary chunk is {n} bytes, planned {bin_len}"
            )));
        }
        w.write_all(&[0u8; 3][..bin_pad as usize])?;
    }
    Ok(total)
}

/// Convert a scene to a mesh `.glb` or `.gltf` (+ `.bin` next to it), atomically.
pub fn write_file(
    path: &Path,
    glb: bool,
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
) -> crate::Result<ConvertReport> {
    let mut report = ConvertReport::new(if glb { "glb" } else { "gltf" }, opts);
    let shape = shape_for(opts);
    let split = opts
        .surfels
        .as_ref()
        .map(|o| crate::surfels::split_scene(scene, frames, o));
    let (scene, frames) = match &split {
        Some(s) => (&s.residual, s.frames.as_ref()),
        None => (scene, frames),
    };
    let parts = crate::order::arrange_for(scene, frames, opts)?;
    let entries = crate::prepare_any(
        scene,
        frames,
        split.as_ref(),
        parts.as_deref(),
        opts,
        &shape,
        &mut report,
    )?;
    if glb {
        let mut bytes = 0;
        splatbridge_scene::image_io::with_atomic_writer(path, |w| {
            bytes = write_glb(w, &entries, scene, frames, opts, &report)?;
            Ok(())
        })
        .map_err(crate::scene_err)?;
        report.bytes = bytes;
    } else {
        let bin_path = path.with_extension("bin");
        let uri = bin_path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let plan = plan(&entries, scene, frames, opts, &report, Some(uri)).map_err(io_err(path))?;
        let mut n = 0;
        splatbridge_scene::image_io::with_atomic_writer(&bin_path, |w| {
            n = stream_bin(w, &plan, &entries)?;
            Ok(())
        })
        .map_err(crate::scene_err)?;
        splatbridge_scene::image_io::write_atomic(path, &plan.json).map_err(crate::scene_err)?;
        report.bytes = n + plan.json.len() as u64;
    }
    Ok(report)
}
