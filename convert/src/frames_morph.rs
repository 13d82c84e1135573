//! Every frame of a 4D capture whose frames mesh to one topology as one glTF mesh with a morph
//! target per frame (glTF 2.0 §3.7.2.2 "Morph Targets", §3.6.2.3 "Sparse Accessors", §3.11
//! "Animations", `weights` path with STEP interpolation) — the alternative to the per-frame
//! nodes of [`crate::frames_gltf`], measured against them in docs/motion.md.
//!
//! The mesh's base is frame 0, meshed and laid out exactly as the per-frame writer lays out a
//! frame (same classification, vertex layout, material, root node); frame `f > 0` is target
//! `f - 1`, holding POSITION deltas and, when the frame's normals differ from frame 0's, NORMAL
//! deltas, as `frame f - frame 0` in f32. A target is a sparse accessor (indices of the vertices
//! that move, their deltas; zeros elsewhere) when that is smaller than a dense one — when fewer
//! than 75–86 % of the vertices move, by index width and attributes; one that moves none is an
//! accessor with neither buffer view nor sparse part (all zeros). One animation, `frames`,
//! keys the mesh's weights with STEP interpolation at the frame times so exactly one target is
//! fully on from its frame's time to the next (none at frame 0's).
//!
//! A morph target has the base's vertices and triangles, so every frame must mesh to frame 0's
//! topology: the same Gaussians in the same order, each classified the same way (a Gaussian
//! whose scales or opacity change can become a different fan, or be culled), and the same
//! per-vertex colours, ids and texture coordinates. Anything else is refused naming the first
//! frame that differs and why. Colour morphs are not written: three.js morphs `COLOR_0`
//! (`GLTFLoader` fills `morphAttributes.color`) but Blender's importer makes shape keys of
//! POSITION alone and would drop them, so a capture whose colours change keeps the per-frame
//! nodes.
//!
//! One frame is meshed at a time beside frame 0's vertices; the targets are streamed to a
//! spool next to the output, and the output is assembled and committed atomically as the
//! per-frame writer does.

use std::io::{self, BufWriter, Read, Seek, Write};
use std::path::Path;

use serde_json::{json, Value};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::output::OutputSet;
use splatbridge_scene::{Camera, GaussianCloud};

use crate::frames_gltf::{check_times, write_staged, FramesLimits};
use crate::gltf_doc::{typed_json, ARRAY_BUFFER, FLOAT};
use crate::gltf_writer::{
    entry_regions, frame_key_times, layout_for, plan_at, region_of, stream_entry, EntryInfo,
};
use crate::motion::stream::FrameSource;
use crate::options::{ConvertOptions, ConvertReport};
use crate::{check_entry, piece_entry, shape_for, ConvertError, Piece, Result, Role};

const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;

/// How one target's attribute deltas are stored.
#[derive(Clone, Debug, PartialEq)]
enum Storage {
    /// The frame equals frame 0: an accessor of zeros, no bytes.
    Zero,
    /// `count` moved vertices: their indices (u16 when the mesh has fewer than 65,536
    /// vertices, else u32; padded to 4 bytes) then, per attribute, their deltas.
    Sparse { count: usize, wide: bool },
    /// Every vertex's delta, per attribute.
    Dense,
}

/// One target as written to the spool.
#[derive(Clone, Debug)]
struct Target {
    storage: Storage,
    /// Bytes in the spool.
    len: u64,
    /// Whether NORMAL deltas follow the POSITION deltas.
    normals: bool,
    /// Bounds of the POSITION deltas (zeros included when the accessor is sparse).
    min: [f32; 3],
    max: [f32; 3],
}

/// Bytes of a sparse target's index block (4-byte aligned).
fn index_block(count: usize, wide: bool) -> u64 {
    let raw = count as u64 * if wide { 4 } else { 2 };
    raw.div_ceil(4) * 4
}

/// Read the f32×3 at `at` in a vertex.
fn vec3(v: &[u8], at: usize) -> [f32; 3] {
    let f = |i: usize| f32::from_le_bytes(v[at + 4 * i..at + 4 * i + 4].try_into().unwrap());
    [f(0), f(1), f(2)]
}

/// Compare frame `f`'s vertices with frame 0's and write its target's deltas to `w`.
/// `normals`: the layout carries NORMAL (f32×3 right after POSITION).
fn write_target<W: Write>(
    w: &mut W,
    base: &[u8],
    frame: &[u8],
    stride: usize,
    normals: bool,
) -> io::Result<Target> {
    let n = base.len() / stride;
    let attr_end = if normals { 24 } else { 12 };
    let mut moved: Vec<u32> = Vec::new();
    let mut normals_move = false;
    for v in 0..n {
        let (b, f) = (
            &base[v * stride..v * stride + attr_end],
            &frame[v * stride..v * stride + attr_end],
        );
        if b != f {
            moved.push(v as u32);
            normals_move |= normals && b[12..] != f[12..];
        }
    }
    let delta = |v: usize, at: usize| {
        let (b, f) = (
            vec3(&base[v * stride..], at),
            vec3(&frame[v * stride..], at),
        );
        [f[0] - b[0], f[1] - b[1], f[2] - b[2]]
    };
    let per_vertex = if normals_move { 24u64 } else { 12 };
    let wide = n > u16::MAX as usize;
    let sparse_len = index_block(moved.len(), wide) + moved.len() as u64 * per_vertex;
    let dense_len = n as u64 * per_vertex;
    let storage = if moved.is_empty() {
        Storage::Zero
    } else if sparse_len < dense_len {
        Storage::Sparse {
            count: moved.len(),
            wide,
        }
    } else {
        Storage::Dense
    };
    let rows: Vec<usize> = match storage {
        Storage::Zero => Vec::new(),
        Storage::Sparse { .. } => moved.iter().map(|&v| v as usize).collect(),
        Storage::Dense => (0..n).collect(),
    };
    // Unmoved vertices are zero deltas: part of the bounds unless every vertex is listed.
    let listed_all = rows.len() == n;
    let (mut min, mut max) = if listed_all {
        ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3])
    } else {
        ([0.0; 3], [0.0; 3])
    };
    let mut out = Vec::with_capacity(rows.len() * 12);
    if let Storage::Sparse { wide, .. } = storage {
        for &v in &rows {
            if wide {
                out.extend_from_slice(&(v as u32).to_le_bytes());
            } else {
                out.extend_from_slice(&(v as u16).to_le_bytes());
            }
        }
        out.resize(index_block(rows.len(), wide) as usize, 0);
    }
    for &v in &rows {
        let d = delta(v, 0);
        for i in 0..3 {
            min[i] = min[i].min(d[i]);
            max[i] = max[i].max(d[i]);
        }
        for x in d {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    if normals_move {
        for &v in &rows {
            for x in delta(v, 12) {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    w.write_all(&out)?;
    Ok(Target {
        storage,
        len: out.len() as u64,
        normals: normals_move,
        min,
        max,
    })
}

/// Mesh one frame as the per-frame writer meshes it (ids from 0): its entry info and its
/// interleaved vertex bytes and index bytes.
fn mesh_frame(
    cloud: &GaussianCloud,
    f: usize,
    opts: &ConvertOptions,
    shape: &crate::ProfileShape,
    scene: &DynamicScene,
    report: Option<&mut ConvertReport>,
) -> Result<(EntryInfo, Vec<u8>, usize)> {
    let mut offset = 0;
    let piece = Piece::whole(Role::Static, &format!("frame {f}"), cloud);
    let e = piece_entry(piece, scene, opts, shape, &mut offset)?;
    let mut scratch = ConvertReport::new("glb", opts);
    check_entry(&e, report.unwrap_or(&mut scratch))?;
    let info = EntryInfo::of(&e);
    let layout = layout_for(opts);
    let [lens, _] = entry_regions(&info, layout);
    let a = lens.map(|(v, i)| region_of(v, i));
    let mut bytes = Vec::new();
    if let Some(r) = &a {
        stream_entry(&mut bytes, &e, layout, [Some(r), None])
            .map_err(|e| ConvertError::Invalid(format!("frame {f}: {e}")))?;
    }
    let vertex_len = lens.map_or(0, |(v, _)| v as usize);
    Ok((info, bytes, vertex_len))
}

/// Write every frame of `src` (frame `f` at `times[f]`) as one mesh with a morph target per
/// frame after the first (`.glb`, or `.gltf` + `.bin`), one frame in memory at a time beside
/// frame 0. Refuses frames whose meshes differ from frame 0's in anything but vertex
/// positions and normals, and the options that split or reorder a frame (`--surfels`,
/// `--max-triangles`, chunking and orderings). The report counts the base mesh (frame 0) and
/// the file's bytes. `cameras` become the file's glTF cameras, as a scene's cameras do in
/// `convert`.
pub fn write_frames_morph(
    path: &Path,
    src: &(impl FrameSource + ?Sized),
    times: &[f64],
    opts: &ConvertOptions,
    limits: &FramesLimits,
    cameras: &[Camera],
) -> Result<ConvertReport> {
    let t0 = std::time::Instant::now();
    let glb = match crate::Format::from_path(path)? {
        crate::Format::Glb => true,
        crate::Format::Gltf => false,
        _ => {
            return Err(ConvertError::Format {
                path: path.into(),
                what: "morph targets are written to a .glb or .gltf file".into(),
            })
        }
    };
    if opts.surfels.is_some() || opts.max_triangles.is_some() || opts.arranged() {
        return Err(ConvertError::Format {
            path: path.into(),
            what: "morph targets keep each frame whole in input order: surfels, a triangle \
                   budget and the viewer layout (chunks, orderings, both windings) do not apply"
                .into(),
        });
    }
    opts.validate()?;
    check_times(path, src.len(), times)?;
    let key_times = frame_key_times(times).map_err(|e| ConvertError::Format {
        path: path.into(),
        what: e.to_string(),
    })?;
    let refuse = |what: String| ConvertError::Format {
        path: path.into(),
        what,
    };
    let shape = shape_for(opts);
    let mut scene = DynamicScene::from_static(GaussianCloud::new(0));
    scene.cameras = cameras.to_vec();
    let layout = layout_for(opts);
    let stride = layout.stride();
    let mut report = ConvertReport::new(if glb { "glb" } else { "gltf" }, opts);

    let first = src.frame(0)?;
    let (info, base, vertex_len) = mesh_frame(&first, 0, opts, &shape, &scene, Some(&mut report))?;
    drop(first);
    if info.residual_bounds.is_none() {
        return Err(refuse(
            "frame 0 meshes to no triangles: there is no base mesh for morph targets".into(),
        ));
    }
    let (base_vertices, base_indices) = base.split_at(vertex_len);

    let frames = src.len();
    let targets_n = frames - 1;
    // Keys: a time and a weight per target for each frame.
    let small = 4 * frames as u64 + 4 * (frames * targets_n) as u64;
    let mut set = OutputSet::new();
    let (spool_path, spool) = set.scratch(path).map_err(crate::scene_err)?;
    let mut spool = BufWriter::with_capacity(1 << 20, spool);
    let mut targets = Vec::with_capacity(targets_n);
    let mut written = base.len() as u64;
    for f in 1..frames {
        let cloud = src.frame(f)?;
        let (_, bytes, vl) = mesh_frame(&cloud, f, opts, &shape, &scene, None)?;
        drop(cloud);
        let (vertices, indices) = bytes.split_at(vl);
        if vertices.len() != base_vertices.len() || indices != base_indices {
            return Err(refuse(format!(
                "frame {f} meshes to {} vertices and {} triangles, frame 0 to {} and {}: morph \
                 targets need every frame meshed to frame 0's topology (the same Gaussians, \
                 each classified the same way); write per-frame nodes instead",
                vertices.len() / stride,
                indices.len() / 12,
                base_vertices.len() / stride,
                base_indices.len() / 12
            )));
        }
        let moved_from = if layout.normals { 24 } else { 12 };
        if let Some(v) = (0..vertices.len() / stride).find(|&v| {
            vertices[v * stride + moved_from..(v + 1) * stride]
                != base_vertices[v * stride + moved_from..(v + 1) * stride]
        }) {
            return Err(refuse(format!(
                "frame {f} changes vertex {v}'s colour, id or texture coordinates: morph \
                 targets here carry positions and normals only (Blender drops colour \
                 morphs); write per-frame nodes instead"
            )));
        }
        let t = write_target(&mut spool, base_vertices, vertices, stride, layout.normals)
            .map_err(crate::io_err(&spool_path))?;
        written += t.len;
        targets.push(t);
        if small + written > limits.max_bytes {
            return Err(refuse(format!(
                "morph targets passed {} bytes at frame {f} of {frames}, more than the {} a \
                 file holds",
                small + written,
                limits.max_bytes
            )));
        }
    }

    let bin_path = path.with_extension("bin");
    let uri = (!glb).then(|| {
        bin_path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    });
    let plan = plan_at(&[info], &scene, None, opts, &report, uri).map_err(crate::io_err(path))?;
    if plan.bin_len != plan.small.len() as u64 + base.len() as u64 {
        return Err(ConvertError::Invalid(format!(
            "internal: planned {} bytes of buffer, have {} + {}",
            plan.bin_len,
            plan.small.len(),
            base.len()
        )));
    }
    let mut doc: Value = serde_json::from_slice(&plan.json)
        .map_err(|e| ConvertError::Invalid(format!("internal: plan JSON: {e}")))?;
    let mut tail = Vec::new();
    let n_vertices = base_vertices.len() / stride;
    add_targets(
        &mut doc,
        &targets,
        &key_times,
        plan.bin_len,
        n_vertices,
        &mut tail,
    )?;
    let bin_len = plan.bin_len + (written - base.len() as u64) + tail.len() as u64;
    doc["buffers"][0]["byteLength"] = json!(bin_len);
    let json = typed_json(&doc).map_err(crate::io_err(path))?;

    let mut spool = spool
        .into_inner()
        .map_err(|e| crate::io_err(&spool_path)(e.into_error()))?;
    spool.rewind().map_err(crate::io_err(&spool_path))?;
    let spooled = written - base.len() as u64;
    let mut body = |w: &mut BufWriter<std::fs::File>| -> io::Result<u64> {
        w.write_all(&plan.small)?;
        w.write_all(&base)?;
        let n = io::copy(&mut (&mut spool).take(spooled), w)?;
        if n != spooled {
            return Err(io::Error::other(format!(
                "spool holds {n} bytes, {spooled} were written"
            )));
        }
        w.write_all(&tail)?;
        Ok(plan.small.len() as u64 + base.len() as u64 + n + tail.len() as u64)
    };
    if glb && 28 + json.len() as u64 + bin_len + 6 > limits.max_bytes {
        return Err(refuse(format!(
            "morph targets would write {} bytes, more than the {} a GLB holds",
            28 + json.len() as u64 + bin_len,
            limits.max_bytes
        )));
    }
    let bytes = write_staged(&mut set, path, &bin_path, glb, &json, bin_len, &mut body)?;
    set.commit().map_err(crate::scene_err)?;
    report.bytes = bytes;
    report.seconds = t0.elapsed().as_secs_f64();
    Ok(report)
}

/// Add the targets (spooled from `offset` in the buffer), their names, the mesh's weights and
/// the STEP weights animation (keys appended to `tail`, placed after the targets) to the
/// planned single-mesh document.
fn add_targets(
    doc: &mut Value,
    targets: &[Target],
    key_times: &[f32],
    offset: u64,
    n_vertices: usize,
    tail: &mut Vec<u8>,
) -> Result<()> {
    let internal = |what: &str| ConvertError::Invalid(format!("internal: {what}"));
    let mut views: Vec<Value> = doc["bufferViews"].as_array().cloned().unwrap_or_default();
    let mut accessors: Vec<Value> = doc["accessors"].as_array().cloned().unwrap_or_default();
    let view = |views: &mut Vec<Value>, off: u64, len: u64| {
        views.push(json!({"buffer": 0, "byteOffset": off, "byteLength": len}));
        views.len() - 1
    };
    let mut at = offset;
    let mut prim_targets = Vec::with_capacity(targets.len());
    for t in targets {
        let mut pos = json!({"componentType": FLOAT, "count": n_vertices, "type": "VEC3",
            "min": t.min, "max": t.max});
        let mut nor = json!({"componentType": FLOAT, "count": n_vertices, "type": "VEC3"});
        match t.storage {
            Storage::Zero => {}
            Storage::Dense => {
                let block = n_vertices as u64 * 12;
                let pv = view(&mut views, at, block);
                views[pv]["target"] = json!(ARRAY_BUFFER);
                pos["bufferView"] = json!(pv);
                if t.normals {
                    let nv = view(&mut views, at + block, block);
                    views[nv]["target"] = json!(ARRAY_BUFFER);
                    nor["bufferView"] = json!(nv);
                }
            }
            Storage::Sparse { count, wide } => {
                let ib = index_block(count, wide);
                let iv = view(&mut views, at, count as u64 * if wide { 4 } else { 2 });
                let block = count as u64 * 12;
                let ct = if wide { UNSIGNED_INT } else { UNSIGNED_SHORT };
                let pv = view(&mut views, at + ib, block);
                pos["sparse"] = json!({"count": count,
                    "indices": {"bufferView": iv, "componentType": ct},
                    "values": {"bufferView": pv}});
                if t.normals {
                    let nv = view(&mut views, at + ib + block, block);
                    nor["sparse"] = json!({"count": count,
                        "indices": {"bufferView": iv, "componentType": ct},
                        "values": {"bufferView": nv}});
                }
            }
        }
        at += t.len;
        accessors.push(pos);
        let mut target = json!({"POSITION": accessors.len() - 1});
        if t.normals {
            accessors.push(nor);
            target["NORMAL"] = json!(accessors.len() - 1);
        }
        prim_targets.push(target);
    }
    if targets.is_empty() {
        // One frame: a plain mesh, no animation.
        return Ok(());
    }
    // The animation keys: frame times, then per frame a weight per target (target f - 1 on).
    let frames = key_times.len();
    let time_off = at;
    for &t in key_times {
        tail.extend_from_slice(&t.to_le_bytes());
    }
    let tv = view(&mut views, time_off, 4 * frames as u64);
    let input = accessors.len();
    accessors.push(
        json!({"bufferView": tv, "componentType": FLOAT, "count": frames,
        "type": "SCALAR", "min": [key_times[0]], "max": [key_times[frames - 1]]}),
    );
    let weights_off = at + tail.len() as u64;
    for f in 0..frames {
        for k in 0..targets.len() {
            let w: f32 = if k + 1 == f { 1.0 } else { 0.0 };
            tail.extend_from_slice(&w.to_le_bytes());
        }
    }
    let wv = view(&mut views, weights_off, 4 * (frames * targets.len()) as u64);
    let output = accessors.len();
    accessors.push(json!({"bufferView": wv, "componentType": FLOAT,
        "count": frames * targets.len(), "type": "SCALAR"}));
    doc["bufferViews"] = Value::Array(views);
    doc["accessors"] = Value::Array(accessors);

    let meshes = doc["meshes"]
        .as_array_mut()
        .filter(|m| m.len() == 1)
        .ok_or_else(|| internal("the base document has one mesh"))?;
    let mesh = &mut meshes[0];
    if let Some(prims) = mesh["primitives"].as_array_mut() {
        for p in prims {
            p["targets"] = Value::Array(prim_targets.clone());
        }
    }
    {
        mesh["weights"] = json!(vec![0.0f32; targets.len()]);
        let names: Vec<String> = (1..frames).map(|f| format!("frame_{f:04}")).collect();
        mesh["extras"]["targetNames"] = json!(names);
        let node = doc["nodes"]
            .as_array()
            .and_then(|n| n.iter().position(|n| n.get("mesh").is_some()))
            .ok_or_else(|| internal("the base document has a mesh node"))?;
        let anim = json!({"name": "frames",
            "channels": [{"sampler": 0, "target": {"node": node, "path": "weights"}}],
            "samplers": [{"input": input, "output": output, "interpolation": "STEP"}]});
        doc["animations"] = json!([anim]);
    }
    Ok(())
}
