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
//!
//! [`plan`] decides everything before streaming, in steps: the small data (texture, animation
//! keys), one mesh node per entry with its primitives' regions, the per-frame visibility
//! channels, the cameras and root, then the document. [`stream_bin`] writes the buffer;
//! [`write_glb`] and [`write_file`] put it in a GLB or a `.gltf` + `.bin`.

use std::io::{self, Write};
use std::path::Path;

use serde_json::{json, Value};
use splatbridge_scene::dynamic::DynamicScene;

use crate::chunked::ChunkedMesh;
pub use crate::gltf_doc::camera_node;
use crate::gltf_doc::{
    camera_nodes, object_tracks, remove_keys, root_node, typed_json, Animation, DocBuilder,
    ObjectTrack, ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, FLOAT,
};
use crate::options::{ConvertOptions, ConvertReport, Profile};
use crate::{io_err, FrameClouds, MeshEntry, Role};

pub(crate) use crate::gltf_vertex::index_bytes;
pub use crate::gltf_vertex::{vertex_bytes, Interleaved, VertexLayout};

const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;

/// A mesh region streamed after the small data.
pub(crate) struct Region {
    vertex_offset: u64,
    vertex_len: u64,
    index_len: u64,
}

/// Everything decided before streaming.
pub(crate) struct Plan {
    pub json: Vec<u8>,
    pub small: Vec<u8>,
    /// Per entry: the residual primitive's region, then the surfel primitive's.
    regions: Vec<[Option<Region>; 2]>,
    pub bin_len: u64,
    pub layout: VertexLayout,
}

/// Which of the two materials the entries use, and their indices: the splat material for
/// residual meshes, then the opaque surfel material.
#[derive(Clone, Copy)]
struct Materials {
    any_residual: bool,
    any_surfels: bool,
    splat: usize,
    surfel: usize,
}

impl Materials {
    fn of(entries: &[EntryInfo]) -> Self {
        let any_residual = entries.iter().any(|e| e.residual_used);
        Materials {
            any_residual,
            any_surfels: entries.iter().any(|e| e.surfels_used),
            splat: 0,
            surfel: usize::from(any_residual),
        }
    }

    /// Only materials a primitive uses (the validator flags unused objects); the splat
    /// material samples the falloff texture when `textured`.
    fn json(self, textured: bool, both_windings: bool) -> Vec<Value> {
        let mut materials = Vec::new();
        if self.any_residual {
            let mut material = json!({
                "name": "gaussian_splats",
                "alphaMode": "BLEND",
                // Both windings are written instead when arranged for viewers (`order.rs`).
                "doubleSided": !both_windings,
                "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
                "extensions": {"KHR_materials_unlit": {}}
            });
            if textured {
                material["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
            }
            materials.push(material);
        }
        if self.any_surfels {
            // Surfels are opaque: vertex alpha is 1 and OPAQUE ignores it anyway; no texture.
            materials.push(json!({
                "name": "surfels",
                "alphaMode": "OPAQUE",
                "doubleSided": true,
                "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
                "extensions": {"KHR_materials_unlit": {}}
            }));
        }
        materials
    }
}

/// The scene graph as it is built: nodes (the root first, filled in last), the root's
/// children, meshes and the animation.
struct Graph {
    nodes: Vec<Value>,
    children: Vec<usize>,
    meshes: Vec<Value>,
    animation: Animation,
}

/// What every entry's mesh node needs from the plan.
struct EntryContext<'a> {
    scene: &'a DynamicScene,
    layout: VertexLayout,
    materials: Materials,
    tracks: &'a [Option<ObjectTrack>],
}

/// Per-frame content's visibility: the frame times' accessor and, per frame, a scale output
/// that is 1 on its own frame and 0 elsewhere (STEP).
struct FrameVisibility {
    input: usize,
    outputs: Vec<usize>,
}

/// The vertex layout the options ask for.
pub(crate) fn layout_for(opts: &ConvertOptions) -> VertexLayout {
    VertexLayout {
        ids: opts.gaussian_ids,
        uv: opts.profile == Profile::Texture,
        normals: opts.normals,
    }
}

/// What the plan needs of one entry's meshes: counts and exact bounds of each primitive, taken
/// from the classified entry ([`EntryInfo::of`]) before the data is generated, or while it is
/// (the streamed per-frame writer, `frames_gltf.rs`), so both writers plan the same document.
#[derive(Clone, Debug)]
pub(crate) struct EntryInfo {
    pub role: Role,
    /// The residual mesh's counts (name, ids, Gaussians in, vertices, triangles).
    pub counts: crate::MeshCounts,
    /// The residual mesh has triangles (it uses the splat material).
    pub residual_used: bool,
    pub residual_bounds: Option<([f32; 3], [f32; 3])>,
    /// The surfel primitive, when the entry has surfels: vertices, triangles, surfels kept.
    pub surfels: Option<(u64, u64, u64)>,
    pub surfels_used: bool,
    pub surfel_bounds: Option<([f32; 3], [f32; 3])>,
}

impl EntryInfo {
    /// The summary of a classified entry (a bounds pass over each non-empty primitive).
    pub(crate) fn of(e: &MeshEntry<'_>) -> Self {
        use crate::chunked::ChunkedMesh;
        let m = &e.mesher;
        let residual_used = !m.is_empty();
        let surfels_used = e.surfels.as_ref().is_some_and(|s| !s.is_empty());
        EntryInfo {
            role: e.role,
            counts: m.counts.clone(),
            residual_used,
            residual_bounds: if residual_used { m.bounds() } else { None },
            surfels: e.surfels.as_ref().map(|s| {
                (
                    s.counts.vertices,
                    s.counts.triangles,
                    s.counts.surfels - s.counts.dropped_overflow,
                )
            }),
            surfels_used,
            surfel_bounds: match &e.surfels {
                Some(s) if surfels_used => s.bounds(),
                _ => None,
            },
        }
    }
}

fn plan(
    entries: &[EntryInfo],
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
    report: &ConvertReport,
    bin_uri: Option<String>,
) -> io::Result<Plan> {
    plan_at(
        entries,
        scene,
        frames.map(|f| &f.times[..]),
        opts,
        report,
        bin_uri,
    )
}

/// [`plan`] with the per-frame content given by its times alone (what the plan needs of it).
pub(crate) fn plan_at(
    entries: &[EntryInfo],
    scene: &DynamicScene,
    frame_times: Option<&[f64]>,
    opts: &ConvertOptions,
    report: &ConvertReport,
    bin_uri: Option<String>,
) -> io::Result<Plan> {
    let layout = layout_for(opts);
    let materials = Materials::of(entries);
    // Small data first: the texture and the animation keys.
    let mut d = DocBuilder::new();
    let images = falloff_image(&mut d, layout, materials);
    let tracks = object_tracks(&mut d, scene);
    let visibility = frame_visibility(&mut d, frame_times)?;
    d.align();

    let mut g = Graph {
        nodes: vec![json!({})],
        children: Vec::new(),
        meshes: Vec::new(),
        animation: Animation::default(),
    };
    let mut offset = d.small.len() as u64;
    let mut regions = Vec::with_capacity(entries.len());
    let mut frame_nodes: Vec<(usize, usize)> = Vec::new();
    let ctx = EntryContext {
        scene,
        layout,
        materials,
        tracks: &tracks,
    };
    for e in entries {
        let pair = mesh_node(&mut d, &mut g, &mut offset, e, &ctx);
        if let (Some(_), Role::Frame(k)) = (&pair, e.role) {
            frame_nodes.push((g.nodes.len() - 1, k));
        }
        regions.push(pair.unwrap_or([None, None]));
    }
    if let Some(v) = &visibility {
        for &(node, k) in &frame_nodes {
            g.animation
                .channel(node, v.input, v.outputs[k], "STEP", "scale");
        }
    }
    let cameras = camera_nodes(scene, &mut g.nodes, &mut g.children);
    g.nodes[0] = root_node(std::mem::take(&mut g.children), opts);

    let bin_len = offset;
    let textured = layout.uv && materials.any_residual;
    let doc = document(DocParts {
        d: &d,
        g,
        cameras,
        images,
        materials: materials.json(textured, opts.both_windings),
        textured,
        bin_len,
        bin_uri,
        metadata: report.metadata(opts),
    });
    Ok(Plan {
        json: typed_json(&doc)?,
        small: d.small,
        regions,
        bin_len,
        layout,
    })
}

/// The falloff texture in the small data (profile `texture` with a residual mesh; surfels
/// carry no texture coordinates): the `images` array.
fn falloff_image(d: &mut DocBuilder, layout: VertexLayout, materials: Materials) -> Vec<Value> {
    let mut images = Vec::new();
    if layout.uv && materials.any_residual {
        let view = d.small_view(&crate::texture::png(), None);
        images
            .push(json!({"bufferView": view, "mimeType": "image/png", "name": "gaussian_falloff"}));
    }
    images
}

/// Frame times and per-frame scale outputs in the small data (`None` without frames).
/// A frame's key time in f32 at or before its f64 time (the nearest f32 can lie after it, as
/// 0.3 s does), so a STEP key has switched to the frame at the frame's own time whether a
/// viewer samples in f32 or f64.
fn f32_at_or_before(t: f64) -> f32 {
    let f = t as f32;
    if f64::from(f) > t {
        f.next_down()
    } else {
        f
    }
}

/// The frame times as key times, refused when two collapse to one f32.
pub(crate) fn frame_key_times(times: &[f64]) -> io::Result<Vec<f32>> {
    let times: Vec<f32> = times.iter().map(|&t| f32_at_or_before(t)).collect();
    if times.windows(2).any(|w| !(w[1] > w[0])) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "frame times collapse in f32 seconds",
        ));
    }
    Ok(times)
}

fn frame_visibility(
    d: &mut DocBuilder,
    frame_times: Option<&[f64]>,
) -> io::Result<Option<FrameVisibility>> {
    let Some(times) = frame_times.filter(|t| !t.is_empty()) else {
        return Ok(None);
    };
    let times = frame_key_times(times)?;
    let input = d.floats(&times, "SCALAR", 1, true);
    let outputs = (0..times.len())
        .map(|i| {
            let s: Vec<f32> = (0..times.len())
                .flat_map(|j| [if i == j { 1.0 } else { 0.0 }; 3])
                .collect();
            d.floats(&s, "VEC3", 3, false)
        })
        .collect();
    Ok(Some(FrameVisibility { input, outputs }))
}

/// One entry's mesh and node: a primitive per non-empty part (residual Gaussians, then
/// surfels) with its buffer views at `offset` (advanced past them), the mesh's extras, and
/// the node under the root (animated for an object, hidden off its frame for a frame).
/// Returns the entry's regions, or `None` when it has no geometry (no node either).
fn mesh_node(
    d: &mut DocBuilder,
    g: &mut Graph,
    offset: &mut u64,
    e: &EntryInfo,
    ctx: &EntryContext<'_>,
) -> Option<[Option<Region>; 2]> {
    let (layout, materials) = (ctx.layout, ctx.materials);
    let counts = &e.counts;
    let (residual_bounds, surfel_bounds) = (e.residual_bounds, e.surfel_bounds);
    if residual_bounds.is_none() && surfel_bounds.is_none() {
        return None;
    }
    let surfel_layout = VertexLayout {
        ids: layout.ids,
        uv: false,
        normals: layout.normals,
    };
    let parts = [
        (
            residual_bounds,
            layout,
            counts.vertices,
            counts.triangles,
            materials.splat,
        ),
        (
            surfel_bounds,
            surfel_layout,
            e.surfels.map_or(0, |s| s.0),
            e.surfels.map_or(0, |s| s.1),
            materials.surfel,
        ),
    ];
    let mut prims = Vec::new();
    let mut pair = [None, None];
    for (slot, (bounds, layout, nv, nt, material)) in parts.into_iter().enumerate() {
        let Some(bounds) = bounds else { continue };
        let region = Region {
            vertex_offset: *offset,
            vertex_len: nv * layout.stride() as u64,
            index_len: nt * 12,
        };
        prims.push(primitive(d, &region, bounds, layout, nv, nt, material));
        *offset += region.vertex_len + region.index_len;
        pair[slot] = Some(region);
    }
    let (role, name) = match e.role {
        Role::Static => ("static", counts.name.clone()),
        Role::Object(k) => ("object", ctx.scene.objects[k].name.clone()),
        Role::Frame(k) => ("frame", format!("frame_{k:04}")),
    };
    let mut extras =
        json!({"role": role, "idOffset": counts.id_offset, "gaussians": counts.gaussians_in});
    if let Some(s) = e.surfels {
        extras["surfels"] = json!(s.2);
        extras["primitives"] = json!(match (&pair[0], &pair[1]) {
            (Some(_), Some(_)) => vec!["gaussians", "surfels"],
            (Some(_), None) => vec!["gaussians"],
            _ => vec!["surfels"],
        });
    }
    g.meshes
        .push(json!({"name": name, "primitives": prims, "extras": extras}));
    let mut node = json!({"name": name, "mesh": g.meshes.len() - 1});
    let index = g.nodes.len();
    match e.role {
        Role::Object(k) => {
            if let Some(track) = &ctx.tracks[k] {
                g.animation.object(index, &mut node, track);
            }
        }
        // Only frame 0 shows before the animation plays.
        Role::Frame(k) if k != 0 => node["scale"] = json!([0.0, 0.0, 0.0]),
        _ => {}
    }
    g.children.push(index);
    g.nodes.push(node);
    Some(pair)
}

/// One TRIANGLES primitive over `region`: an interleaved vertex view and an index view, the
/// accessors of the layout's attributes (POSITION with its exact bounds) and the indices.
fn primitive(
    d: &mut DocBuilder,
    region: &Region,
    (lo, hi): ([f32; 3], [f32; 3]),
    layout: VertexLayout,
    nv: u64,
    nt: u64,
    material: usize,
) -> Value {
    let offset = region.vertex_offset;
    let stride = layout.stride();
    let vv = d.view(json!({"buffer": 0, "byteOffset": offset, "byteLength": region.vertex_len, "byteStride": stride, "target": ARRAY_BUFFER}));
    let iv = d.view(json!({"buffer": 0, "byteOffset": offset + region.vertex_len, "byteLength": region.index_len, "target": ELEMENT_ARRAY_BUFFER}));
    let pos = d.accessor(json!({"bufferView": vv, "byteOffset": 0, "componentType": FLOAT, "count": nv, "type": "VEC3", "min": lo, "max": hi}));
    let mut attrs = json!({"POSITION": pos});
    if layout.normals {
        attrs["NORMAL"] = json!(d.accessor(json!({"bufferView": vv, "byteOffset": 12, "componentType": FLOAT, "count": nv, "type": "VEC3"})));
    }
    attrs["COLOR_0"] = json!(d.accessor(json!({"bufferView": vv, "byteOffset": layout.color_offset(), "componentType": UNSIGNED_SHORT, "normalized": true, "count": nv, "type": "VEC4"})));
    if layout.ids {
        attrs["_GAUSSIAN_ID"] = json!(d.accessor(json!({"bufferView": vv, "byteOffset": layout.id_offset(), "componentType": FLOAT, "count": nv, "type": "SCALAR"})));
    }
    if layout.uv {
        attrs["TEXCOORD_0"] = json!(d.accessor(json!({"bufferView": vv, "byteOffset": layout.uv_offset(), "componentType": FLOAT, "count": nv, "type": "VEC2"})));
    }
    let ind = d.accessor(
        json!({"bufferView": iv, "componentType": UNSIGNED_INT, "count": nt * 3, "type": "SCALAR"}),
    );
    json!({"attributes": attrs, "indices": ind, "material": material, "mode": 4})
}

/// What the document is assembled from.
struct DocParts<'a> {
    d: &'a DocBuilder,
    g: Graph,
    cameras: Vec<Value>,
    images: Vec<Value>,
    materials: Vec<Value>,
    textured: bool,
    bin_len: u64,
    bin_uri: Option<String>,
    metadata: Value,
}

/// The glTF document: every array the plan built, without the ones glTF forbids empty.
fn document(p: DocParts<'_>) -> Value {
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("splatbridge ", env!("CARGO_PKG_VERSION")), "extras": {"splatbridge": p.metadata}},
        "extensionsUsed": ["KHR_materials_unlit"],
        "scene": 0,
        "scenes": [{"name": "scene", "nodes": [0]}],
        "nodes": p.g.nodes,
        "materials": p.materials,
        "buffers": [{"byteLength": p.bin_len}],
        "bufferViews": p.d.views,
        "accessors": p.d.accessors,
    });
    if p.textured {
        doc["images"] = json!(p.images);
        doc["samplers"] =
            json!([{"magFilter": 9729, "minFilter": 9729, "wrapS": 33071, "wrapT": 33071}]);
        doc["textures"] = json!([{"sampler": 0, "source": 0}]);
    }
    if p.g.meshes.is_empty() {
        remove_keys(&mut doc, &["materials", "extensionsUsed"]);
    } else {
        doc["meshes"] = json!(p.g.meshes);
    }
    if let Some(a) = p.g.animation.into_json() {
        doc["animations"] = a;
    }
    if !p.cameras.is_empty() {
        doc["cameras"] = json!(p.cameras);
    }
    if p.bin_len == 0 {
        // Nothing survived (an empty scene): a zero-length buffer is invalid glTF.
        remove_keys(&mut doc, &["buffers", "bufferViews", "accessors"]);
    } else if let Some(uri) = p.bin_uri {
        doc["buffers"][0]["uri"] = json!(uri);
    }
    doc
}

fn stream_bin<W: Write>(w: &mut W, plan: &Plan, entries: &[MeshEntry<'_>]) -> io::Result<u64> {
    w.write_all(&plan.small)?;
    let mut written = plan.small.len() as u64;
    for (e, pair) in entries.iter().zip(&plan.regions) {
        debug_assert!(pair.iter().flatten().all(|r| r.vertex_offset >= written));
        written += stream_entry(w, e, plan.layout, pair.each_ref().map(|r| r.as_ref()))?;
    }
    Ok(written)
}

/// The region sizes of an entry's primitives as [`plan`] lays them out (residual, surfels).
pub(crate) fn entry_regions(e: &EntryInfo, layout: VertexLayout) -> [Option<(u64, u64)>; 2] {
    let surfel_stride = VertexLayout {
        uv: false,
        ..layout
    }
    .stride() as u64;
    [
        e.residual_bounds.map(|_| {
            (
                e.counts.vertices * layout.stride() as u64,
                e.counts.triangles * 12,
            )
        }),
        e.surfel_bounds
            .and(e.surfels)
            .map(|s| (s.0 * surfel_stride, s.1 * 12)),
    ]
}

/// Stream one entry's primitives (the regions planned for it: vertices, then indices, of the
/// residual mesh and then of the surfels); returns the bytes written.
pub(crate) fn stream_entry<W: Write>(
    w: &mut W,
    e: &MeshEntry<'_>,
    layout: VertexLayout,
    regions: [Option<&Region>; 2],
) -> io::Result<u64> {
    let mut written = 0;
    if let Some(r) = regions[0] {
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
    if let (Some(r), Some(s)) = (regions[1], &e.surfels) {
        let layout = VertexLayout {
            ids: layout.ids,
            uv: false,
            normals: layout.normals,
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
    Ok(written)
}

/// A region as the streamed writer knows it before the offsets are planned: its lengths.
pub(crate) fn region_of(vertex_len: u64, index_len: u64) -> Region {
    Region {
        vertex_offset: 0,
        vertex_len,
        index_len,
    }
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
    let infos: Vec<EntryInfo> = entries.iter().map(EntryInfo::of).collect();
    let plan = plan(&infos, scene, frames, opts, report, None)?;
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
    let bytes = crate::with_mesh_entries(
        scene,
        frames,
        opts,
        &mut report,
        |entries, scene, frames, report| {
            if glb {
                let mut bytes = 0;
                splatbridge_scene::image_io::with_atomic_writer(path, |w| {
                    bytes = write_glb(w, entries, scene, frames, opts, report)?;
                    Ok(())
                })
                .map_err(crate::scene_err)?;
                return Ok(bytes);
            }
            let bin_path = path.with_extension("bin");
            let uri = bin_path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let infos: Vec<EntryInfo> = entries.iter().map(EntryInfo::of).collect();
            let plan =
                plan(&infos, scene, frames, opts, report, Some(uri)).map_err(io_err(path))?;
            let mut n = 0;
            // The .gltf and its .bin appear together or not at all.
            let mut set = splatbridge_scene::output::OutputSet::new();
            set.write_with(&bin_path, |w| {
                n = stream_bin(w, &plan, entries)?;
                Ok(())
            })
            .map_err(crate::scene_err)?;
            set.write(path, &plan.json).map_err(crate::scene_err)?;
            set.commit().map_err(crate::scene_err)?;
            Ok(n + plan.json.len() as u64)
        },
    )?;
    report.bytes = bytes;
    Ok(report)
}
