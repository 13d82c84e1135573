//! The fuzz entry points: one function per target, taking the fuzzer's bytes and calling a
//! reader exactly as the CLI does. The `cargo fuzz` targets call [`run`], and the stable
//! regression test (`tests/fuzz_regressions.rs`) replays every file under
//! `fuzz/regressions/<target>/` through the same [`run`], so a crash found once stays fixed.
//!
//! Targets whose format has structure (PLY headers, glTF documents, manifests) come in two
//! kinds: raw bytes, and a structure-aware variant (`*_structured`) that decodes the bytes
//! with `arbitrary` into a small description of a plausible file and renders it, so the
//! fuzzer spends its time past the parsers' first checks.
//!
//! Adding a target: a file in `fuzz/fuzz_targets/` calling `run("name", data)`, its `[[bin]]`
//! in `fuzz/Cargo.toml`, and one line in the `TARGETS` table below (or in
//! `splat_formats.rs`'s, for the compressed splat formats).

use std::io::Write;
use std::path::Path;

use arbitrary::{Arbitrary, Unstructured};

/// A target's entry function.
pub type Entry = fn(&[u8]);

/// Every target: name and entry function.
pub const TARGETS: &[(&str, Entry)] = &[
    ("ply", ply),
    ("ply_structured", ply_structured),
    ("manifest", manifest),
    ("manifest_structured", manifest_structured),
    ("cameras", cameras),
    ("gltf", gltf),
    ("gltf_structured", gltf_structured),
    ("obj", obj),
];

/// Every target of this module, of [`crate::splat_formats`] (the compressed splat formats) and
/// of [`crate::file_formats`] (`.ksplat` and the PLY layouts).
pub fn all_targets() -> impl Iterator<Item = &'static (&'static str, Entry)> {
    TARGETS
        .iter()
        .chain(crate::splat_formats::TARGETS.iter())
        .chain(crate::file_formats::TARGETS.iter())
}

/// Run one target on one input; `false` when the target does not exist.
pub fn run(target: &str, data: &[u8]) -> bool {
    match all_targets().find(|(n, _)| *n == target) {
        Some((_, f)) => {
            f(data);
            true
        }
        None => false,
    }
}

/// Write the input to a temporary file with the given extension (path-based readers).
pub(crate) fn with_file(data: &[u8], ext: &str, f: impl FnOnce(&Path)) {
    let Ok(mut file) = tempfile::Builder::new()
        .prefix("splatbridge-fuzz-")
        .suffix(ext)
        .tempfile()
    else {
        return;
    };
    if file.write_all(data).is_err() {
        return;
    }
    f(file.path());
}

fn ply(data: &[u8]) {
    with_file(data, ".ply", |p| {
        for drop_invalid in [false, true] {
            let _ = splatbridge_scene::ply::read_ply(
                p,
                &splatbridge_scene::ply::ReadOptions { drop_invalid },
            );
        }
    });
}

fn manifest(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = splatbridge_scene::manifest::parse_manifest(Path::new("fuzz.json"), text);
    }
}

fn cameras(data: &[u8]) {
    with_file(data, ".json", |p| {
        let _ = splatbridge_scene::camera::load_cameras_json(p);
    });
}

fn gltf(data: &[u8]) {
    let _ = splatbridge_raytrace::scene_load::load_glb_bytes(data, Path::new("fuzz.glb"));
}

fn obj(data: &[u8]) {
    let _ = splatbridge_raytrace::scene_load::load_obj_bytes(data, Path::new("fuzz.obj"));
}

// ---- structure-aware inputs ----

const PLY_NAMES: &[&str] = &[
    "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1",
    "scale_2", "rot_0", "rot_1", "rot_2", "rot_3", "f_rest_0", "f_rest_1", "junk",
];
const PLY_TYPES: &[&str] = &[
    "float",
    "double",
    "float32",
    "float64",
    "uchar",
    "int",
    "short",
    "list uchar int",
    "bogus",
];

#[derive(Arbitrary, Debug)]
struct PlyIn {
    encoding: u8,
    /// Extra properties (index into the name and type tables) after the required ones.
    extra: Vec<(u8, u8)>,
    /// Drop one required property (when < 17).
    drop: u8,
    /// Use a double for every required property.
    doubles: bool,
    count: u8,
    /// Lie about the count by this much (wrapping).
    lie: i8,
    trailing_face: Option<u8>,
    values: Vec<f32>,
    tail: Vec<u8>,
}

fn ply_structured(data: &[u8]) {
    let Ok(p) = PlyIn::arbitrary(&mut Unstructured::new(data)) else {
        return;
    };
    let enc = ["binary_little_endian", "binary_big_endian", "ascii"][p.encoding as usize % 3];
    let mut props: Vec<(String, String)> = PLY_NAMES[..17]
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != p.drop as usize)
        .map(|(_, n)| {
            (
                n.to_string(),
                if p.doubles { "double" } else { "float" }.to_string(),
            )
        })
        .collect();
    for (n, t) in p.extra.iter().take(64) {
        props.push((
            PLY_NAMES[*n as usize % PLY_NAMES.len()].to_string(),
            PLY_TYPES[*t as usize % PLY_TYPES.len()].to_string(),
        ));
    }
    let declared = (p.count as i64 + p.lie as i64).max(0);
    let mut out = format!("ply\nformat {enc} 1.0\nelement vertex {declared}\n");
    for (n, t) in &props {
        out.push_str(&format!("property {t} {n}\n"));
    }
    if let Some(f) = p.trailing_face {
        out.push_str(&format!(
            "element face {f}\nproperty list uchar int vertex_indices\n"
        ));
    }
    out.push_str("end_header\n");
    let mut bytes = out.into_bytes();
    let mut vals = p.values.iter().cycle();
    let n = p.count as usize * props.len();
    for _ in 0..if p.values.is_empty() { 0 } else { n } {
        let v = *vals.next().unwrap_or(&0.0);
        match enc {
            "ascii" => bytes.extend_from_slice(format!("{v} ").as_bytes()),
            "binary_big_endian" => bytes.extend_from_slice(&v.to_be_bytes()),
            _ => bytes.extend_from_slice(&v.to_le_bytes()),
        }
    }
    bytes.extend_from_slice(&p.tail);
    ply(&bytes);
}

#[derive(Arbitrary, Debug)]
struct ManifestIn {
    format_ok: bool,
    time: (f64, f64, f64),
    objects: Vec<ObjectIn>,
    effects: Vec<(u8, f64)>,
}

#[derive(Arbitrary, Debug)]
struct ObjectIn {
    name: u8,
    remove: bool,
    keys: Vec<(f64, [f32; 3], [f32; 4])>,
    retime: Option<(f64, f64)>,
    trajectory: Option<(u8, f64, f64)>,
}

fn manifest_structured(data: &[u8]) {
    use serde_json::json;
    let Ok(m) = ManifestIn::arbitrary(&mut Unstructured::new(data)) else {
        return;
    };
    let num = |x: f64| serde_json::Number::from_f64(x).map_or(json!(null), |n| json!(n));
    let effects: serde_json::Map<String, serde_json::Value> = m
        .effects
        .iter()
        .take(4)
        .map(|(k, v)| match k % 4 {
            0 => (
                "weather".to_string(),
                json!({ "kind": (["rain", "snow"][*k as usize / 4 % 2]), "count": *v as u32,
                        "fall_speed": num(*v), "size": num(*v), "wind": [num(*v), 0, 0] }),
            ),
            1 => (
                "motion_blur".to_string(),
                json!({ "shutter": num(*v), "samples": *v as u32 }),
            ),
            2 => ("shadows".to_string(), json!({ "sun": [num(*v), -1, 0] })),
            _ => ("lidar".to_string(), json!({ "rings": *v as u32 })),
        })
        .collect();
    let objects: Vec<serde_json::Value> = m
        .objects
        .iter()
        .take(8)
        .map(|o| {
            let mut v = json!({
                "name": format!("o{}", o.name % 4),
                "gaussians": "o.ply",
                "remove": o.remove,
            });
            if !o.keys.is_empty() {
                v["track"] = o
                    .keys
                    .iter()
                    .take(16)
                    .map(|(t, tr, r)| {
                        json!({ "t": num(*t), "translation": tr.map(|x| num(x as f64)),
                                "rotation": r.map(|x| num(x as f64)) })
                    })
                    .collect();
            }
            if let Some((a, b)) = o.retime {
                v["retime"] = json!({ "offset": num(a), "scale": num(b) });
            }
            if let Some((k, a, b)) = o.trajectory {
                let start = [num(a), 0.0.into(), num(b)];
                v["trajectory"] = match k % 4 {
                    0 => json!({ "kind": "straight", "start": start, "speed": num(a) }),
                    1 => json!({ "kind": "lane_change", "start": start, "speed": num(a),
                                 "offset": num(b), "begin": num(a), "duration": num(b) }),
                    2 => json!({ "kind": "turn", "start": start, "speed": num(a),
                                 "radius": num(b), "angle_deg": num(a), "begin": num(b) }),
                    _ => json!({ "kind": "stop", "start": start, "speed": num(a),
                                 "begin": num(b), "distance": num(a) }),
                };
            }
            v
        })
        .collect();
    let doc = json!({
        "format": if m.format_ok { "splatbridge-scene/1" } else { "other" },
        "static": "static.ply",
        "time": { "start": num(m.time.0), "end": num(m.time.1), "fps": num(m.time.2) },
        "objects": objects,
        "effects": effects,
    });
    manifest(doc.to_string().as_bytes());
}

#[derive(Arbitrary, Debug)]
struct GltfIn {
    buffer_len: u16,
    bin: Vec<u8>,
    views: Vec<(u8, u16, u16, Option<u8>)>,
    accessors: Vec<AccessorIn>,
    prims: Vec<PrimIn>,
    nodes: Vec<(Option<u8>, Vec<u8>)>,
    images: Vec<(Option<u8>, bool)>,
    anims: Vec<(u8, u8, u8, u8, u8)>,
    glb_len_delta: i8,
}

#[derive(Arbitrary, Debug)]
struct AccessorIn {
    view: Option<u8>,
    offset: u16,
    count: u32,
    ctype: u8,
    ty: u8,
}

#[derive(Arbitrary, Debug)]
struct PrimIn {
    mode: u8,
    attrs: Vec<(u8, u8)>,
    indices: Option<u8>,
    material: Option<u8>,
}

fn gltf_structured(data: &[u8]) {
    use serde_json::json;
    let Ok(g) = GltfIn::arbitrary(&mut Unstructured::new(data)) else {
        return;
    };
    const CT: &[u32] = &[5120, 5121, 5122, 5123, 5125, 5126, 5124];
    const TY: &[&str] = &[
        "SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4", "VEC9",
    ];
    const SEM: &[&str] = &[
        "POSITION",
        "COLOR_0",
        "TEXCOORD_0",
        "_GAUSSIAN_ID",
        "NORMAL",
    ];
    let views: Vec<_> = g
        .views
        .iter()
        .take(8)
        .map(|(b, off, len, stride)| {
            let mut v = json!({ "buffer": b % 2, "byteOffset": off, "byteLength": len });
            if let Some(s) = stride {
                v["byteStride"] = json!(*s as u32 * 4 % 260);
            }
            v
        })
        .collect();
    let accessors: Vec<_> = g
        .accessors
        .iter()
        .take(16)
        .map(|a| {
            let mut v = json!({
                "byteOffset": a.offset,
                // Mostly small counts, sometimes a huge one (2³¹ and friends).
                "count": if a.count % 97 == 0 { a.count } else { a.count % 70_000 },
                "componentType": CT[a.ctype as usize % CT.len()],
                "type": TY[a.ty as usize % TY.len()],
            });
            if let Some(b) = a.view {
                v["bufferView"] = json!(b % 9);
            }
            v
        })
        .collect();
    let prims: Vec<_> = g
        .prims
        .iter()
        .take(4)
        .map(|p| {
            let attrs: serde_json::Map<_, _> = p
                .attrs
                .iter()
                .take(5)
                .map(|(s, a)| (SEM[*s as usize % SEM.len()].to_string(), json!(a % 17)))
                .collect();
            let mut v = json!({ "attributes": attrs, "mode": p.mode % 8 });
            if let Some(i) = p.indices {
                v["indices"] = json!(i % 17);
            }
            if let Some(m) = p.material {
                v["material"] = json!(m % 2);
            }
            v
        })
        .collect();
    let n_nodes = g.nodes.len().min(16);
    let nodes: Vec<_> = g.nodes[..n_nodes]
        .iter()
        .map(|(mesh, children)| {
            let mut v = json!({});
            if let Some(m) = mesh {
                v["mesh"] = json!(m % 2);
            }
            if !children.is_empty() {
                v["children"] = json!(children.iter().take(4).map(|c| c % 17).collect::<Vec<_>>());
            }
            v
        })
        .collect();
    let images: Vec<_> = g
        .images
        .iter()
        .take(2)
        .map(|(view, mime)| match view {
            Some(b) if *mime => json!({ "bufferView": b % 9, "mimeType": "image/png" }),
            Some(b) => json!({ "bufferView": b % 9 }),
            None => json!({}),
        })
        .collect();
    let paths = ["translation", "rotation", "scale", "weights", "bogus"];
    let anims: Vec<_> = g
        .anims
        .iter()
        .take(3)
        .map(|(node, path, input, output, interp)| {
            json!({
                "channels": [{ "sampler": 0, "target": { "node": node % 17, "path": paths[*path as usize % 5] } }],
                "samplers": [{ "input": input % 17, "output": output % 17,
                    "interpolation": (["LINEAR", "STEP", "CUBICSPLINE"][*interp as usize % 3]) }],
            })
        })
        .collect();
    let roots: Vec<usize> = (0..n_nodes).collect();
    let doc = json!({
        "asset": { "version": "2.0" },
        "buffers": [{ "byteLength": g.buffer_len }],
        "bufferViews": views,
        "accessors": accessors,
        "meshes": [{ "primitives": prims }],
        "materials": [{}],
        "nodes": nodes,
        "scenes": [{ "nodes": roots }],
        "scene": 0,
        "images": images,
        "textures": if images.is_empty() { json!([]) } else { json!([{ "source": 0 }]) },
        "animations": anims,
    });
    let mut json_bytes = doc.to_string().into_bytes();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let mut bin = g.bin.clone();
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let declared = (total as i64 + g.glb_len_delta as i64).max(0) as u32;
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&declared.to_le_bytes());
    glb.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&json_bytes);
    glb.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&bin);
    gltf(&glb);
}
