//! Native splats in glTF with `KHR_gaussian_splatting`, and a reader of such files.
//!
//! Writer: one POINTS primitive per cloud (static Gaussians; each object in its local frame
//! under an animated node, as in the mesh writer; cameras as camera nodes; the up-axis root).
//! Attributes, each a tightly packed FLOAT accessor: `POSITION`,
//! `KHR_gaussian_splatting:ROTATION` (unit x,y,z,w), `…:SCALE` (linear, `exp` of the stored
//! log-scale), `…:OPACITY` (after the sigmoid), `…:SH_DEGREE_l_COEF_n` for every degree
//! present (coefficients in the reference 3DGS order, which runs from m = −l to m = l), and
//! the `COLOR_0` fallback `clamp(SH_C0·f_dc + 0.5)` with alpha = opacity (normalized u8).
//! The extension object is `{"kernel": "ellipse", "colorSpace": "srgb_rec709_display",
//! "projection": "perspective", "sortingMethod": "cameraDistance"}`.
//! `gltf_json` cannot name these attributes, so the document is typed with placeholder
//! names and renamed in the JSON value before output. Invalid Gaussians (NaN, zero
//! quaternions) are dropped and counted.
//!
//! Reader: GLB or `.gltf` + external/embedded buffers; every primitive carrying the
//! extension becomes Gaussians. Nodes without animation are baked into one static cloud with
//! their world transforms (uniform scale only); animated nodes (LINEAR translation/rotation)
//! become objects with tracks; a `splatbridge_root` written by this crate is undone, so a
//! round trip returns the input frame.

use std::io::{self, Write};
use std::path::Path;

use glam::{Affine3A, DMat3, DQuat, DVec3, Quat, Vec3};
use serde_json::{json, Value};
use splatbridge_scene::dynamic::{DynamicScene, Pose, PoseKey, SceneObject, TimeRange, Track};
use splatbridge_scene::gaussians::{logit, sh_coeffs};
use splatbridge_scene::{sh, Camera, GaussianCloud};

use crate::gltf_writer::{
    camera_node, glb_container, track_keys, typed_json, DocBuilder, ARRAY_BUFFER, FLOAT,
};
use crate::options::{ConvertOptions, ConvertReport, MeshCounts};
use crate::ConvertError;

const EXT: &str = "KHR_gaussian_splatting";
const UNSIGNED_BYTE: u32 = 5121;

/// Attribute names: the placeholder used while typing the document, and the real name.
fn attribute_names(degree: u8) -> Vec<(String, String)> {
    let mut v = vec![
        ("_SPLAT_ROTATION".to_string(), format!("{EXT}:ROTATION")),
        ("_SPLAT_SCALE".to_string(), format!("{EXT}:SCALE")),
        ("_SPLAT_OPACITY".to_string(), format!("{EXT}:OPACITY")),
    ];
    for l in 0..=degree as usize {
        for n in 0..2 * l + 1 {
            v.push((
                format!("_SPLAT_SH_{l}_{n}"),
                format!("{EXT}:SH_DEGREE_{l}_COEF_{n}"),
            ));
        }
    }
    v
}

/// One attribute stream of one cloud.
#[derive(Clone, Copy)]
enum Stream {
    Position,
    Rotation,
    Scale,
    Opacity,
    /// SH coefficient index (0-based, coefficient-major).
    Sh(usize),
    Color,
}

impl Stream {
    fn bytes_per(self) -> u64 {
        match self {
            Stream::Position | Stream::Scale | Stream::Sh(_) => 12,
            Stream::Rotation => 16,
            Stream::Opacity | Stream::Color => 4,
        }
    }

    fn write(self, c: &GaussianCloud, keep: &[u32], out: &mut Vec<u8>) {
        if let Stream::Color = self {
            let q = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
            for &i in keep {
                let rgb = sh::dc_color(c.sh_of(i as usize));
                out.extend_from_slice(&[q(rgb.x), q(rgb.y), q(rgb.z), q(c.opacity(i as usize))]);
            }
            return;
        }
        let mut f = |x: f32| out.extend_from_slice(&x.to_le_bytes());
        for &i in keep {
            let i = i as usize;
            match self {
                Stream::Position => c.means[i].to_array().into_iter().for_each(&mut f),
                Stream::Rotation => {
                    let q = c.unit_rotation(i);
                    [q.x, q.y, q.z, q.w].into_iter().for_each(&mut f)
                }
                Stream::Scale => c.scale(i).to_array().into_iter().for_each(&mut f),
                Stream::Opacity => f(c.opacity(i)),
                Stream::Sh(k) => c.sh_of(i)[k].to_array().into_iter().for_each(&mut f),
                Stream::Color => unreachable!("handled above"),
            }
        }
    }
}

struct CloudPlan<'a> {
    cloud: &'a GaussianCloud,
    keep: Vec<u32>,
    streams: Vec<(Stream, u64)>,
}

/// Write native splats as GLB into any writer. Returns the report (bytes filled in).
pub fn write_glb<W: Write>(
    w: &mut W,
    scene: &DynamicScene,
    opts: &ConvertOptions,
) -> crate::Result<ConvertReport> {
    let (json, small, plans, bin_len, mut report) = plan(scene, opts, None)?;
    let bytes = glb_container(w, &json, bin_len, |w| stream(w, &small, &plans)).map_err(|e| {
        ConvertError::Io {
            path: "<memory>".into(),
            err: e,
        }
    })?;
    report.bytes = bytes;
    Ok(report)
}

/// Write native splats to `.glb` or `.gltf` (+ `.bin`), atomically.
pub fn write_file(
    path: &Path,
    scene: &DynamicScene,
    opts: &ConvertOptions,
) -> crate::Result<ConvertReport> {
    let glb = match crate::Format::from_path(path)? {
        crate::Format::Glb => true,
        crate::Format::Gltf => false,
        _ => {
            return Err(ConvertError::Format {
                path: path.into(),
                what: "--splats writes glTF: use .glb or .gltf".into(),
            })
        }
    };
    if glb {
        let mut rep = None;
        splatbridge_scene::image_io::with_atomic_writer(path, |w| {
            rep = Some(write_glb(w, scene, opts).map_err(io::Error::other)?);
            Ok(())
        })
        .map_err(crate::scene_err)?;
        let mut r = rep.expect("written");
        r.format = "glb splats".into();
        Ok(r)
    } else {
        let bin_path = path.with_extension("bin");
        let uri = bin_path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let (json, small, plans, _bin_len, mut report) = plan(scene, opts, Some(uri))?;
        let mut n = 0;
        splatbridge_scene::image_io::with_atomic_writer(&bin_path, |w| {
            n = stream(w, &small, &plans)?;
            Ok(())
        })
        .map_err(crate::scene_err)?;
        splatbridge_scene::image_io::write_atomic(path, &json).map_err(crate::scene_err)?;
        report.bytes = n + json.len() as u64;
        report.format = "gltf splats".into();
        Ok(report)
    }
}

type Planned<'a> = (Vec<u8>, Vec<u8>, Vec<CloudPlan<'a>>, u64, ConvertReport);

fn plan<'a>(
    scene: &'a DynamicScene,
    opts: &ConvertOptions,
    bin_uri: Option<String>,
) -> crate::Result<Planned<'a>> {
    let mut report = ConvertReport::new("splats", opts);
    report.profile = "splats".into();
    let mut d = DocBuilder::new();
    let mut clouds: Vec<(String, &GaussianCloud, Option<usize>)> =
        vec![("static".into(), &scene.static_gaussians, None)];
    for (k, o) in scene.objects.iter().enumerate() {
        clouds.push((o.name.clone(), &o.gaussians, Some(k)));
    }
    // Animation data first (small), then the attribute streams.
    let mut anim = Vec::new();
    for o in &scene.objects {
        let keys = track_keys(&o.track.keys, scene.time.start, scene.time.end);
        if keys.is_empty() {
            anim.push(None);
            continue;
        }
        let times: Vec<f32> = keys.iter().map(|k| k.0).collect();
        let tr: Vec<f32> = keys.iter().flat_map(|k| k.1).collect();
        let rot: Vec<f32> = keys.iter().flat_map(|k| k.2).collect();
        let input = d.floats(&times, "SCALAR", 1, true);
        let ta = d.floats(&tr, "VEC3", 3, false);
        let ra = d.floats(&rot, "VEC4", 4, false);
        anim.push(Some((input, ta, ra, keys[0].1, keys[0].2)));
    }
    while d.small.len() % 4 != 0 {
        d.small.push(0);
    }
    let mut offset = d.small.len() as u64;
    let mut plans = Vec::new();
    let mut meshes = Vec::new();
    let mut nodes = vec![json!({})];
    let mut children = Vec::new();
    let mut samplers: Vec<Value> = Vec::new();
    let mut channels: Vec<Value> = Vec::new();
    let mut id_offset = 0u64;
    for (name, cloud, obj) in clouds {
        cloud.check_shape()?;
        let keep: Vec<u32> = (0..cloud.len() as u32)
            .filter(|&i| cloud.invalid_reason(i as usize).is_none())
            .collect();
        report.add(MeshCounts {
            name: name.clone(),
            gaussians_in: cloud.len() as u64,
            dropped_invalid: (cloud.len() - keep.len()) as u64,
            id_offset,
            ..Default::default()
        });
        id_offset += cloud.len() as u64;
        if keep.is_empty() {
            continue;
        }
        let n = keep.len() as u64;
        let names = attribute_names(cloud.sh_degree);
        let mut streams = vec![(Stream::Position, 0u64)];
        streams.extend([Stream::Rotation, Stream::Scale, Stream::Opacity].map(|s| (s, 0)));
        for k in 0..sh_coeffs(cloud.sh_degree) {
            streams.push((Stream::Sh(k), 0));
        }
        streams.push((Stream::Color, 0));
        let mut attrs = serde_json::Map::new();
        for (si, (s, off)) in streams.iter_mut().enumerate() {
            *off = offset;
            let len = s.bytes_per() * n;
            d.views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": len, "target": ARRAY_BUFFER}));
            let view = d.views.len() - 1;
            offset += len;
            let acc = match s {
                Stream::Position => {
                    let (lo, hi) = keep.iter().fold(
                        ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
                        |(mut lo, mut hi), &i| {
                            let p = cloud.means[i as usize].to_array();
                            for a in 0..3 {
                                lo[a] = lo[a].min(p[a]);
                                hi[a] = hi[a].max(p[a]);
                            }
                            (lo, hi)
                        },
                    );
                    json!({"bufferView": view, "componentType": FLOAT, "count": n, "type": "VEC3", "min": lo, "max": hi})
                }
                Stream::Rotation => {
                    json!({"bufferView": view, "componentType": FLOAT, "count": n, "type": "VEC4"})
                }
                Stream::Scale | Stream::Sh(_) => {
                    json!({"bufferView": view, "componentType": FLOAT, "count": n, "type": "VEC3"})
                }
                Stream::Opacity => {
                    json!({"bufferView": view, "componentType": FLOAT, "count": n, "type": "SCALAR"})
                }
                Stream::Color => {
                    json!({"bufferView": view, "componentType": UNSIGNED_BYTE, "normalized": true, "count": n, "type": "VEC4"})
                }
            };
            let a = d.accessor(acc);
            let key = match si {
                0 => "POSITION".to_string(),
                _ if matches!(s, Stream::Color) => "COLOR_0".to_string(),
                _ => names[si - 1].0.clone(),
            };
            attrs.insert(key, json!(a));
        }
        meshes.push(json!({
            "name": name,
            "primitives": [{"attributes": attrs, "mode": 0, "extensions": {EXT: {"kernel": "ellipse", "colorSpace": "srgb_rec709_display", "projection": "perspective", "sortingMethod": "cameraDistance"}}}],
            "extras": {"role": if obj.is_some() { "object" } else { "static" }, "idOffset": report.meshes.last().map(|m| m.id_offset)}
        }));
        let mut node = json!({"name": name, "mesh": meshes.len() - 1});
        if let Some(Some((input, ta, ra, t0, r0))) = obj.map(|k| anim[k]) {
            node["translation"] = json!(t0);
            node["rotation"] = json!(r0);
            for (out, path) in [(ta, "translation"), (ra, "rotation")] {
                samplers.push(json!({"input": input, "output": out, "interpolation": "LINEAR"}));
                channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": nodes.len(), "path": path}}));
            }
        }
        children.push(nodes.len());
        nodes.push(node);
        plans.push(CloudPlan {
            cloud,
            keep,
            streams,
        });
    }
    let mut cameras = Vec::new();
    for cam in &scene.cameras {
        let (t, r, c) = camera_node(cam);
        cameras.push(c);
        children.push(nodes.len());
        nodes.push(
            json!({"name": cam.name, "camera": cameras.len() - 1, "translation": t, "rotation": r}),
        );
    }
    let mut root = json!({"name": "splatbridge_root", "children": children, "extras": {"inputUp": opts.up.name()}});
    let rq = opts.up.root_rotation();
    if rq != Quat::IDENTITY {
        root["rotation"] = json!(rq.to_array());
    }
    nodes[0] = root;
    let bin_len = offset;
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("splatbridge ", env!("CARGO_PKG_VERSION")), "extras": {"splatbridge": report.metadata(opts)}},
        "extensionsUsed": [EXT],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "meshes": meshes,
        "buffers": [{"byteLength": bin_len}],
        "bufferViews": d.views,
        "accessors": d.accessors,
    });
    if !channels.is_empty() {
        doc["animations"] = json!([{"name": "scene", "samplers": samplers, "channels": channels}]);
    }
    if !cameras.is_empty() {
        doc["cameras"] = json!(cameras);
    }
    if bin_len == 0 {
        for k in ["buffers", "bufferViews", "accessors", "meshes"] {
            doc.as_object_mut().map(|o| o.remove(k));
        }
    } else if let Some(uri) = bin_uri {
        doc["buffers"][0]["uri"] = json!(uri);
    }
    let typed = typed_json(&doc).map_err(|e| ConvertError::Invalid(e.to_string()))?;
    // Rename the placeholder attributes to the extension's names.
    let mut v: Value =
        serde_json::from_slice(&typed).map_err(|e| ConvertError::Invalid(e.to_string()))?;
    if let Some(ms) = v["meshes"].as_array_mut() {
        for m in ms {
            for p in m["primitives"].as_array_mut().into_iter().flatten() {
                if let Some(a) = p["attributes"].as_object_mut() {
                    for (from, to) in attribute_names(3) {
                        if let Some(x) = a.remove(&from) {
                            a.insert(to, x);
                        }
                    }
                }
            }
        }
    }
    let json = serde_json::to_vec(&v).map_err(|e| ConvertError::Invalid(e.to_string()))?;
    Ok((json, d.small, plans, bin_len, report))
}

fn stream<W: Write>(w: &mut W, small: &[u8], plans: &[CloudPlan<'_>]) -> io::Result<u64> {
    use rayon::prelude::*;
    w.write_all(small)?;
    let mut n = small.len() as u64;
    // Each attribute is encoded in parallel chunks and written in order.
    let batch = 2 * rayon::current_num_threads().max(1);
    for p in plans {
        for &(s, off) in &p.streams {
            debug_assert_eq!(off, n);
            let chunks: Vec<&[u32]> = p.keep.chunks(1 << 15).collect();
            for group in chunks.chunks(batch) {
                let bufs: Vec<Vec<u8>> = group
                    .par_iter()
                    .map(|c| {
                        let mut buf = Vec::with_capacity(c.len() * s.bytes_per() as usize);
                        s.write(p.cloud, c, &mut buf);
                        buf
                    })
                    .collect();
                for b in bufs {
                    w.write_all(&b)?;
                    n += b.len() as u64;
                }
            }
        }
    }
    Ok(n)
}

// ---------------------------------------------------------------- reader

/// Split a GLB into its JSON and BIN chunks, or read a `.gltf` and its buffers.
fn load_document(path: &Path) -> crate::Result<(Value, Vec<Vec<u8>>)> {
    let bad = |what: String| ConvertError::Format {
        path: path.into(),
        what,
    };
    let data = std::fs::read(path).map_err(crate::io_err(path))?;
    let (json, bin) = if data.starts_with(b"glTF") {
        let u32at = |o: usize| -> crate::Result<u32> {
            data.get(o..o + 4)
                .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
                .ok_or_else(|| bad(format!("GLB truncated at byte {o}")))
        };
        let mut o = 12;
        let (mut json, mut bin) = (None, None);
        while o + 8 <= data.len() {
            let len = u32at(o)? as usize;
            let ty = &data[o + 4..o + 8];
            let body = data
                .get(o + 8..o + 8 + len)
                .ok_or_else(|| bad(format!("GLB chunk at byte {o} runs past the end")))?;
            match ty {
                b"JSON" => json = Some(body.to_vec()),
                b"BIN\0" => bin = Some(body.to_vec()),
                _ => {}
            }
            o += 8 + len;
        }
        (
            json.ok_or_else(|| bad("GLB has no JSON chunk".into()))?,
            bin,
        )
    } else {
        (data, None)
    };
    let v: Value = serde_json::from_slice(&json).map_err(|e| bad(format!("glTF JSON: {e}")))?;
    let mut buffers = Vec::new();
    for (i, b) in v["buffers"].as_array().into_iter().flatten().enumerate() {
        match b["uri"].as_str() {
            None => buffers.push(bin.clone().ok_or_else(|| {
                bad(format!(
                    "buffer {i} has no uri and there is no GLB BIN chunk"
                ))
            })?),
            Some(uri) if uri.starts_with("data:") => {
                return Err(bad(format!("buffer {i}: data URIs are not supported")))
            }
            Some(uri) => {
                let p = path.parent().unwrap_or(Path::new(".")).join(uri);
                buffers.push(std::fs::read(&p).map_err(crate::io_err(&p))?);
            }
        }
    }
    Ok((v, buffers))
}

/// Read accessor `a` as f32 tuples of `comps` (FLOAT, or normalized u8/u16).
fn read_accessor(
    path: &Path,
    v: &Value,
    bufs: &[Vec<u8>],
    a: usize,
    comps: usize,
) -> crate::Result<Vec<f32>> {
    let bad = |what: String| ConvertError::Format {
        path: path.into(),
        what,
    };
    let acc = &v["accessors"][a];
    let count = acc["count"]
        .as_u64()
        .ok_or_else(|| bad(format!("accessor {a} has no count")))? as usize;
    let ct = acc["componentType"].as_u64().unwrap_or(0) as u32;
    let size = match ct {
        FLOAT => 4,
        UNSIGNED_BYTE => 1,
        5123 => 2,
        _ => {
            return Err(bad(format!(
                "accessor {a}: component type {ct} is not read (FLOAT, normalized u8/u16)"
            )))
        }
    };
    let view = &v["bufferViews"][acc["bufferView"]
        .as_u64()
        .ok_or_else(|| bad(format!("accessor {a} has no bufferView")))?
        as usize];
    let buf = &bufs[view["buffer"].as_u64().unwrap_or(0) as usize];
    let base = view["byteOffset"].as_u64().unwrap_or(0) as usize
        + acc["byteOffset"].as_u64().unwrap_or(0) as usize;
    let stride = view["byteStride"]
        .as_u64()
        .map(|s| s as usize)
        .unwrap_or(size * comps);
    let mut out = Vec::with_capacity(count * comps);
    for i in 0..count {
        for c in 0..comps {
            let o = base + i * stride + c * size;
            let b = buf
                .get(o..o + size)
                .ok_or_else(|| bad(format!("accessor {a} element {i} lies outside its buffer")))?;
            out.push(match size {
                4 => f32::from_le_bytes(b.try_into().unwrap()),
                1 => b[0] as f32 / 255.0,
                _ => u16::from_le_bytes(b.try_into().unwrap()) as f32 / 65535.0,
            });
        }
    }
    Ok(out)
}

fn node_local(n: &Value) -> Affine3A {
    let arr = |k: &str, d: &[f32]| -> Vec<f32> {
        n[k].as_array()
            .map(|a| a.iter().map(|x| x.as_f64().unwrap_or(0.0) as f32).collect())
            .unwrap_or_else(|| d.to_vec())
    };
    if let Some(m) = n["matrix"].as_array() {
        let m: Vec<f32> = m.iter().map(|x| x.as_f64().unwrap_or(0.0) as f32).collect();
        if m.len() == 16 {
            return Affine3A::from_mat4(glam::Mat4::from_cols_slice(&m));
        }
    }
    let t = arr("translation", &[0.0; 3]);
    let r = arr("rotation", &[0.0, 0.0, 0.0, 1.0]);
    let s = arr("scale", &[1.0; 3]);
    Affine3A::from_scale_rotation_translation(
        Vec3::new(s[0], s[1], s[2]),
        Quat::from_xyzw(r[0], r[1], r[2], r[3]).normalize(),
        Vec3::new(t[0], t[1], t[2]),
    )
}

/// Read the Gaussians of one splat primitive into `cloud` (transformed by `xf`).
fn read_primitive(
    path: &Path,
    v: &Value,
    bufs: &[Vec<u8>],
    prim: &Value,
    xf: Affine3A,
    cloud: &mut GaussianCloud,
) -> crate::Result<()> {
    let bad = |what: String| ConvertError::Format {
        path: path.into(),
        what,
    };
    let attrs = &prim["attributes"];
    let get = |name: &str, comps: usize| -> crate::Result<Option<Vec<f32>>> {
        match attrs[name].as_u64() {
            Some(a) => Ok(Some(read_accessor(path, v, bufs, a as usize, comps)?)),
            None => Ok(None),
        }
    };
    let need = |name: &str, comps: usize| -> crate::Result<Vec<f32>> {
        get(name, comps)?.ok_or_else(|| bad(format!("splat primitive lacks {name}")))
    };
    let pos = need("POSITION", 3)?;
    let rot = need(&format!("{EXT}:ROTATION"), 4)?;
    let scale = need(&format!("{EXT}:SCALE"), 3)?;
    let opac = need(&format!("{EXT}:OPACITY"), 1)?;
    let n = pos.len() / 3;
    let mut degree = 0u8;
    while degree < 3 && attrs[format!("{EXT}:SH_DEGREE_{}_COEF_0", degree + 1)].is_u64() {
        degree += 1;
    }
    let mut sh_cols = Vec::new();
    for l in 0..=degree as usize {
        for c in 0..2 * l + 1 {
            sh_cols.push(need(&format!("{EXT}:SH_DEGREE_{l}_COEF_{c}"), 3)?);
        }
    }
    if rot.len() != 4 * n
        || scale.len() != 3 * n
        || opac.len() != n
        || sh_cols.iter().any(|c| c.len() != 3 * n)
    {
        return Err(bad("splat attributes have different counts".into()));
    }
    if cloud.is_empty() && cloud.sh_degree < degree {
        cloud.sh_degree = degree;
    }
    let (s, r, _) = xf.to_scale_rotation_translation();
    if (s.x - s.y).abs() > 1e-4 * s.x.abs() || (s.x - s.z).abs() > 1e-4 * s.x.abs() {
        return Err(bad(format!(
            "node scale {s} is not uniform; splats cannot be baked through it"
        )));
    }
    let k = sh_coeffs(cloud.sh_degree);
    let mut part = GaussianCloud::with_capacity(cloud.sh_degree, n);
    for i in 0..n {
        let q = Quat::from_xyzw(rot[4 * i], rot[4 * i + 1], rot[4 * i + 2], rot[4 * i + 3]);
        let mean = xf.transform_point3(Vec3::new(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]));
        let sc = Vec3::new(scale[3 * i], scale[3 * i + 1], scale[3 * i + 2]) * s.x;
        let coeffs: Vec<Vec3> = (0..k)
            .map(|j| {
                sh_cols
                    .get(j)
                    .map(|c| Vec3::new(c[3 * i], c[3 * i + 1], c[3 * i + 2]))
                    .unwrap_or(Vec3::ZERO)
            })
            .collect();
        let q = if r == Quat::IDENTITY { q } else { r * q };
        part.push(
            mean,
            Vec3::new(sc.x.ln(), sc.y.ln(), sc.z.ln()),
            q,
            logit(opac[i]),
            &coeffs,
        );
    }
    cloud.extend_from(&part, None);
    Ok(())
}

/// Key times, translations and rotations of one animated node.
type NodeAnimation = (Vec<f32>, Option<Vec<f32>>, Option<Vec<f32>>);

/// Read a `KHR_gaussian_splatting` glTF/GLB back into a scene.
pub fn read_file(path: &Path) -> crate::Result<DynamicScene> {
    let bad = |what: String| ConvertError::Format {
        path: path.into(),
        what,
    };
    let (v, bufs) = load_document(path)?;
    let nodes = v["nodes"].as_array().cloned().unwrap_or_default();
    // Animated nodes: node -> (times, translations, rotations).
    let mut animated: std::collections::HashMap<usize, NodeAnimation> = Default::default();
    for a in v["animations"].as_array().into_iter().flatten() {
        for ch in a["channels"].as_array().into_iter().flatten() {
            let node = ch["target"]["node"]
                .as_u64()
                .ok_or_else(|| bad("animation channel without node".into()))?
                as usize;
            let s = &a["samplers"][ch["sampler"].as_u64().unwrap_or(0) as usize];
            let times = read_accessor(
                path,
                &v,
                &bufs,
                s["input"].as_u64().unwrap_or(0) as usize,
                1,
            )?;
            let path_name = ch["target"]["path"].as_str().unwrap_or("");
            let comps = if path_name == "rotation" { 4 } else { 3 };
            let out = read_accessor(
                path,
                &v,
                &bufs,
                s["output"].as_u64().unwrap_or(0) as usize,
                comps,
            )?;
            let e = animated.entry(node).or_insert((times, None, None));
            match path_name {
                "translation" => e.1 = Some(out),
                "rotation" => e.2 = Some(out),
                _ => {}
            }
        }
    }
    let mut scene = DynamicScene::from_static(GaussianCloud::new(0));
    let mut t_range: Option<(f64, f64)> = None;
    let roots: Vec<usize> = v["scenes"][v["scene"].as_u64().unwrap_or(0) as usize]["nodes"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|x| x.as_u64().map(|x| x as usize))
                .collect()
        })
        .unwrap_or_else(|| (0..nodes.len()).collect());
    let mut stack: Vec<(usize, Affine3A)> =
        roots.into_iter().map(|r| (r, Affine3A::IDENTITY)).collect();
    let mut guard = 0;
    while let Some((ni, parent)) = stack.pop() {
        guard += 1;
        if guard > 1_000_000 {
            return Err(bad("node hierarchy has a cycle".into()));
        }
        let n = nodes
            .get(ni)
            .ok_or_else(|| bad(format!("node {ni} does not exist")))?;
        let ours = n["name"] == "splatbridge_root" && n["extras"]["inputUp"].is_string();
        let local = if ours {
            Affine3A::IDENTITY
        } else {
            node_local(n)
        };
        let world = parent * local;
        for c in n["children"].as_array().into_iter().flatten() {
            stack.push((c.as_u64().unwrap_or(u64::MAX) as usize, world));
        }
        if let (Some(ci), Some(o)) = (
            n["camera"].as_u64(),
            n["extras"].as_object().or(Some(&serde_json::Map::new())),
        ) {
            let _ = o;
            if let Some(cam) = read_camera(
                &v,
                ci as usize,
                world,
                n["name"].as_str().unwrap_or("camera"),
            ) {
                scene.cameras.push(cam);
            }
        }
        let Some(mi) = n["mesh"].as_u64() else {
            continue;
        };
        let mesh = &v["meshes"][mi as usize];
        let prims: Vec<&Value> = mesh["primitives"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|p| p["extensions"][EXT].is_object())
            .collect();
        if prims.is_empty() {
            continue;
        }
        if let Some((times, tr, rot)) = animated.get(&ni) {
            let mut cloud = GaussianCloud::new(0);
            for p in prims {
                read_primitive(path, &v, &bufs, p, Affine3A::IDENTITY, &mut cloud)?;
            }
            let keys = times
                .iter()
                .enumerate()
                .map(|(i, &t)| {
                    let translation = tr
                        .as_ref()
                        .map(|x| Vec3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]))
                        .unwrap_or(Vec3::ZERO);
                    let rotation = rot
                        .as_ref()
                        .map(|x| {
                            Quat::from_xyzw(x[4 * i], x[4 * i + 1], x[4 * i + 2], x[4 * i + 3])
                                .normalize()
                        })
                        .unwrap_or(Quat::IDENTITY);
                    PoseKey {
                        t: t as f64,
                        pose: Pose {
                            translation,
                            rotation,
                        },
                    }
                })
                .collect::<Vec<_>>();
            if let (Some(f), Some(l)) = (keys.first(), keys.last()) {
                t_range = Some(t_range.map_or((f.t, l.t), |(a, b)| (a.min(f.t), b.max(l.t))));
            }
            scene.objects.push(SceneObject {
                name: n["name"].as_str().unwrap_or("object").to_string(),
                gaussians: cloud,
                track: Track { keys },
            });
        } else {
            for p in prims {
                read_primitive(path, &v, &bufs, p, world, &mut scene.static_gaussians)?;
            }
        }
    }
    if let Some((a, b)) = t_range {
        scene.time = TimeRange {
            start: a,
            end: b,
            fps: scene.time.fps.max(30.0),
        };
    }
    // Objects in file order (the stack visits children last-first).
    scene.objects.reverse();
    scene.cameras.reverse();
    Ok(scene)
}

fn read_camera(v: &Value, ci: usize, world: Affine3A, name: &str) -> Option<Camera> {
    let c = &v["cameras"][ci];
    let cv = &c["extras"]["opencv"];
    let p = &c["perspective"];
    let yfov = p["yfov"].as_f64()?;
    let (w, h, fx, fy, cx, cy) = if cv.is_object() {
        (
            cv["width"].as_u64()? as u32,
            cv["height"].as_u64()? as u32,
            cv["fx"].as_f64()?,
            cv["fy"].as_f64()?,
            cv["cx"].as_f64()?,
            cv["cy"].as_f64()?,
        )
    } else {
        let aspect = p["aspectRatio"].as_f64().unwrap_or(1.0);
        let h = 1000u32;
        let w = (h as f64 * aspect).round() as u32;
        let f = h as f64 / (2.0 * (yfov / 2.0).tan());
        (w, h, f, f, w as f64 / 2.0, h as f64 / 2.0)
    };
    let (_, r, t) = world.to_scale_rotation_translation();
    let r = DQuat::from_xyzw(r.x as f64, r.y as f64, r.z as f64, r.w as f64);
    let c2w = DMat3::from_quat(r) * DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
    Some(Camera {
        width: w,
        height: h,
        fx,
        fy,
        cx,
        cy,
        centre: t.as_dvec3(),
        world_to_cam: c2w.transpose(),
        name: name.to_string(),
    })
}
