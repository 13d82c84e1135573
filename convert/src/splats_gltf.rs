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

use serde_json::{json, Value};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::formats::gltf_khr::spz::{encode_khr_spz, SPZ_EXTENSIONS};
use splatbridge_scene::formats::spz::{encode_spz, SpzAxes, SpzOptions};
use splatbridge_scene::gaussians::sh_coeffs;
use splatbridge_scene::{sh, GaussianCloud};

use crate::gltf_doc::{
    camera_nodes, object_tracks, remove_keys, root_node, typed_json, Animation, DocBuilder,
    ARRAY_BUFFER, FLOAT,
};
use crate::gltf_writer::glb_container;
use crate::options::{ConvertOptions, ConvertReport, MeshCounts};
use crate::ConvertError;

const EXT: &str = "KHR_gaussian_splatting";
const UNSIGNED_BYTE: u32 = 5121;

/// The SPZ stream's gzip level of `--splats` files (SPZ's own default, zlib's 6); tiles
/// choose theirs ([`write_tile_glb`]).
pub const SPZ_GZIP_LEVEL: u32 = 6;

/// How the Gaussians of a `--splats` file are stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum KhrCompression {
    /// Float attribute accessors (lossless).
    #[default]
    None,
    /// One SPZ stream per primitive (`KHR_gaussian_splatting_compression_spz_2`): SPZ v3's
    /// quantisation (24-bit fixed-point positions, 8-bit log-scales, colours and opacity,
    /// 10-bit smallest-three rotations, 5/4-bit SH), about 10× smaller. The stream is
    /// packed from the extension's Left-Up-Front frame, as its text asks (RUB in the stream).
    Spz,
    /// [`KhrCompression::Spz`] with the stream holding the glTF mesh's own coordinates (no
    /// RUB ↔ LUF half turn about y): what CesiumJS decodes. CesiumJS 1.145 unpacks the
    /// extension's SPZ with `coordinateSystem: "UNSPECIFIED"` (`GltfSpzLoader.js`), so a
    /// stream packed from LUF shows up turned 180° about the glTF up axis there. 3D Tiles
    /// splat content is read by CesiumJS alone, so tilesets use this by default.
    SpzCesium,
}

impl KhrCompression {
    pub fn name(self) -> &'static str {
        match self {
            KhrCompression::None => "none",
            KhrCompression::Spz => "spz",
            KhrCompression::SpzCesium => "spz-cesium",
        }
    }

    /// Whether the attributes are one SPZ stream.
    pub fn is_spz(self) -> bool {
        self != KhrCompression::None
    }
}

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
    /// The SPZ stream (padded to 4 bytes) that replaces `streams` under SPZ compression.
    spz: Option<Vec<u8>>,
}

/// Write native splats as GLB into any writer. Returns the report (bytes filled in).
pub fn write_glb<W: Write>(
    w: &mut W,
    scene: &DynamicScene,
    opts: &ConvertOptions,
) -> crate::Result<ConvertReport> {
    write_glb_with(w, scene, opts, KhrCompression::None)
}

/// [`write_glb`] with a choice of attribute compression.
pub fn write_glb_with<W: Write>(
    w: &mut W,
    scene: &DynamicScene,
    opts: &ConvertOptions,
    compression: KhrCompression,
) -> crate::Result<ConvertReport> {
    write_glb_impl(w, scene, opts, compression, SPZ_GZIP_LEVEL, false)
}

/// A tile's GLB (3D Tiles content): [`write_glb_with`], except that a static scene's one
/// primitive sits on the root node itself, which carries the up-axis rotation. CesiumJS's
/// splat tiles read only the first scene node's primitive and that node's own matrix, so the
/// usual root → mesh node hierarchy would lose both the Gaussians and the up axis.
/// `gzip_level` (0–9) is the SPZ stream's deflate level.
pub fn write_tile_glb<W: Write>(
    w: &mut W,
    scene: &DynamicScene,
    opts: &ConvertOptions,
    compression: KhrCompression,
    gzip_level: u32,
) -> crate::Result<ConvertReport> {
    write_glb_impl(w, scene, opts, compression, gzip_level, true)
}

fn write_glb_impl<W: Write>(
    w: &mut W,
    scene: &DynamicScene,
    opts: &ConvertOptions,
    compression: KhrCompression,
    gzip_level: u32,
    flat: bool,
) -> crate::Result<ConvertReport> {
    let (json, small, plans, bin_len, mut report) =
        plan(scene, opts, None, (compression, gzip_level), flat)?;
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
    write_file_with(path, scene, opts, KhrCompression::None)
}

/// [`write_file`] with a choice of attribute compression.
pub fn write_file_with(
    path: &Path,
    scene: &DynamicScene,
    opts: &ConvertOptions,
    compression: KhrCompression,
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
            rep = Some(write_glb_with(w, scene, opts, compression).map_err(io::Error::other)?);
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
        let (json, small, plans, _bin_len, mut report) =
            plan(scene, opts, Some(uri), (compression, SPZ_GZIP_LEVEL), false)?;
        let mut n = 0;
        // The .gltf and its .bin appear together or not at all.
        let mut set = splatbridge_scene::output::OutputSet::new();
        set.write_with(&bin_path, |w| {
            n = stream(w, &small, &plans)?;
            Ok(())
        })
        .map_err(crate::scene_err)?;
        set.write(path, &json).map_err(crate::scene_err)?;
        set.commit().map_err(crate::scene_err)?;
        report.bytes = n + json.len() as u64;
        report.format = "gltf splats".into();
        Ok(report)
    }
}

type Planned<'a> = (Vec<u8>, Vec<u8>, Vec<CloudPlan<'a>>, u64, ConvertReport);

/// Decide everything before streaming, in steps: the objects' tracks in the small data, then
/// per cloud its kept Gaussians, attribute views and accessors, mesh and node, then the
/// cameras and root, the document, and the extension's attribute names.
fn plan<'a>(
    scene: &'a DynamicScene,
    opts: &ConvertOptions,
    bin_uri: Option<String>,
    (compression, gzip_level): (KhrCompression, u32),
    flat: bool,
) -> crate::Result<Planned<'a>> {
    let mut report = ConvertReport::new("splats", opts);
    report.profile = "splats".into();
    let mut d = DocBuilder::new();
    // Animation data first (small), then the attribute streams.
    let tracks = object_tracks(&mut d, scene);
    d.align();
    let mut offset = d.small.len() as u64;
    let mut plans = Vec::new();
    let mut meshes = Vec::new();
    let mut nodes = vec![json!({})];
    let mut children = Vec::new();
    let mut animation = Animation::default();
    let mut id_offset = 0u64;
    for (name, cloud, obj) in scene_clouds(scene) {
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
        let first_id = id_offset;
        id_offset += cloud.len() as u64;
        if keep.is_empty() {
            continue;
        }
        let (plan, primitive) =
            cloud_primitive(&mut d, &mut offset, cloud, keep, (compression, gzip_level))?;
        meshes.push(json!({
            "name": name,
            "primitives": [primitive],
            "extras": {"role": if obj.is_some() { "object" } else { "static" }, "idOffset": first_id}
        }));
        let mut node = json!({"name": name, "mesh": meshes.len() - 1});
        if let Some(track) = obj.and_then(|k| tracks[k].as_ref()) {
            animation.object(nodes.len(), &mut node, track);
        }
        children.push(nodes.len());
        nodes.push(node);
        plans.push(plan);
    }
    let cameras = camera_nodes(scene, &mut nodes, &mut children);
    nodes[0] = root_node(children, opts);
    if flat && scene.objects.is_empty() && cameras.is_empty() && nodes.len() == 2 {
        let mesh = nodes[1]["mesh"].clone();
        let mut root = root_node(Vec::new(), opts);
        if let Some(o) = root.as_object_mut() {
            o.remove("children");
            // As a matrix: CesiumJS's splat tiles read the node's `matrix`, not its TRS.
            if o.remove("rotation").is_some() {
                let m = glam::Mat4::from_quat(opts.up.root_rotation());
                o.insert("matrix".into(), json!(m.to_cols_array()));
            }
        }
        root["mesh"] = mesh;
        nodes = vec![root];
    }
    let bin_len = offset;
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("splatbridge ", env!("CARGO_PKG_VERSION")), "extras": {"splatbridge": report.metadata(opts)}},
        "extensionsUsed": if compression.is_spz() { json!([EXT, SPZ_EXTENSIONS[0]]) } else { json!([EXT]) },
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "meshes": meshes,
        "buffers": [{"byteLength": bin_len}],
        "bufferViews": d.views,
        "accessors": d.accessors,
    });
    if compression.is_spz() {
        // No float fallback is written, so a reader must understand the compression.
        doc["extensionsRequired"] = json!([EXT, SPZ_EXTENSIONS[0]]);
        doc["asset"]["extras"]["splatbridge"]["khrCompression"] = json!(compression.name());
    }
    if let Some(a) = animation.into_json() {
        doc["animations"] = a;
    }
    if !cameras.is_empty() {
        doc["cameras"] = json!(cameras);
    }
    if bin_len == 0 {
        remove_keys(&mut doc, &["buffers", "bufferViews", "accessors", "meshes"]);
    } else if let Some(uri) = bin_uri {
        doc["buffers"][0]["uri"] = json!(uri);
    }
    let json = typed_with_extension_names(&doc)?;
    Ok((json, d.small, plans, bin_len, report))
}

/// The scene's clouds in composite order: (name, cloud, object index).
fn scene_clouds(scene: &DynamicScene) -> Vec<(String, &GaussianCloud, Option<usize>)> {
    let mut clouds = vec![("static".to_string(), &scene.static_gaussians, None)];
    for (k, o) in scene.objects.iter().enumerate() {
        clouds.push((o.name.clone(), &o.gaussians, Some(k)));
    }
    clouds
}

/// One cloud's POINTS primitive over its kept Gaussians: the attribute streams' views at
/// `offset` (advanced past them; under SPZ compression one view holds the whole stream and
/// the accessors describe the decoded attributes without views of their own), their
/// accessors, and the extension object.
fn cloud_primitive<'a>(
    d: &mut DocBuilder,
    offset: &mut u64,
    cloud: &'a GaussianCloud,
    keep: Vec<u32>,
    (compression, gzip_level): (KhrCompression, u32),
) -> crate::Result<(CloudPlan<'a>, Value)> {
    let n = keep.len() as u64;
    let names = attribute_names(cloud.sh_degree);
    let mut streams = vec![(Stream::Position, 0u64)];
    streams.extend([Stream::Rotation, Stream::Scale, Stream::Opacity].map(|s| (s, 0)));
    for k in 0..sh_coeffs(cloud.sh_degree) {
        streams.push((Stream::Sh(k), 0));
    }
    streams.push((Stream::Color, 0));
    let spz = match compression {
        KhrCompression::None => None,
        KhrCompression::Spz | KhrCompression::SpzCesium => {
            let mut bytes = spz_stream(cloud, &keep, compression, gzip_level)?;
            let len = bytes.len() as u64;
            bytes.resize(bytes.len().next_multiple_of(4), 0);
            let view = d.view(json!({"buffer": 0, "byteOffset": *offset, "byteLength": len}));
            *offset += bytes.len() as u64;
            Some((bytes, view))
        }
    };
    let mut attrs = serde_json::Map::new();
    for (si, (s, off)) in streams.iter_mut().enumerate() {
        *off = *offset;
        let view = if spz.is_some() {
            None
        } else {
            let len = s.bytes_per() * n;
            let v = d.view(json!({"buffer": 0, "byteOffset": *offset, "byteLength": len, "target": ARRAY_BUFFER}));
            *offset += len;
            Some(v)
        };
        let a = d.accessor(stream_accessor(*s, view, cloud, &keep));
        let key = match si {
            0 => "POSITION".to_string(),
            _ if matches!(s, Stream::Color) => "COLOR_0".to_string(),
            _ => names[si - 1].0.clone(),
        };
        attrs.insert(key, json!(a));
    }
    let mut ext = json!({"kernel": "ellipse", "colorSpace": "srgb_rec709_display", "projection": "perspective", "sortingMethod": "cameraDistance"});
    if let Some((_, view)) = &spz {
        let spz_ext = SPZ_EXTENSIONS[0];
        ext["extensions"] = json!({spz_ext: {"bufferView": view}});
    }
    let primitive = json!({"attributes": attrs, "mode": 0, "extensions": {EXT: ext}});
    let plan = CloudPlan {
        cloud,
        keep,
        streams,
        spz: spz.map(|s| s.0),
    };
    Ok((plan, primitive))
}

/// The SPZ stream of the kept Gaussians.
fn spz_stream(
    cloud: &GaussianCloud,
    keep: &[u32],
    compression: KhrCompression,
    level: u32,
) -> crate::Result<Vec<u8>> {
    let encode = |c: &GaussianCloud| match compression {
        KhrCompression::SpzCesium => encode_spz(
            c,
            &SpzOptions {
                axes: SpzAxes::AsStored,
                level,
                ..SpzOptions::default()
            },
        ),
        _ => encode_khr_spz(
            c,
            &SpzOptions {
                level,
                ..SpzOptions::default()
            },
        ),
    };
    if keep.len() == cloud.len() {
        encode(cloud)
    } else {
        let mut sub = cloud.clone();
        let mut mask = vec![false; cloud.len()];
        keep.iter().for_each(|&i| mask[i as usize] = true);
        sub.retain_indices(|i| mask[i]);
        encode(&sub)
    }
    .map_err(crate::scene_err)
}

/// The accessor of one attribute stream (`view`: its buffer view; none under SPZ).
fn stream_accessor(s: Stream, view: Option<usize>, cloud: &GaussianCloud, keep: &[u32]) -> Value {
    let n = keep.len();
    let mut acc = match s {
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
            json!({"componentType": FLOAT, "count": n, "type": "VEC3", "min": lo, "max": hi})
        }
        Stream::Rotation => json!({"componentType": FLOAT, "count": n, "type": "VEC4"}),
        Stream::Scale | Stream::Sh(_) => {
            json!({"componentType": FLOAT, "count": n, "type": "VEC3"})
        }
        Stream::Opacity => json!({"componentType": FLOAT, "count": n, "type": "SCALAR"}),
        Stream::Color => {
            json!({"componentType": UNSIGNED_BYTE, "normalized": true, "count": n, "type": "VEC4"})
        }
    };
    if let Some(v) = view {
        acc["bufferView"] = json!(v);
    }
    acc
}

/// Type the document (with placeholder attribute names `gltf_json` accepts), then rename the
/// placeholders to the extension's names.
fn typed_with_extension_names(doc: &Value) -> crate::Result<Vec<u8>> {
    let typed = typed_json(doc).map_err(|e| ConvertError::Invalid(e.to_string()))?;
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
    serde_json::to_vec(&v).map_err(|e| ConvertError::Invalid(e.to_string()))
}

fn stream<W: Write>(w: &mut W, small: &[u8], plans: &[CloudPlan<'_>]) -> io::Result<u64> {
    use rayon::prelude::*;
    w.write_all(small)?;
    let mut n = small.len() as u64;
    // Each attribute is encoded in parallel chunks and written in order.
    let batch = 2 * rayon::current_num_threads().max(1);
    for p in plans {
        if let Some(bytes) = &p.spz {
            w.write_all(bytes)?;
            n += bytes.len() as u64;
            continue;
        }
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

/// Read a `KHR_gaussian_splatting` glTF/GLB back into a scene (the scene crate's reader,
/// which every command uses through its format detection).
pub fn read_file(path: &Path) -> crate::Result<DynamicScene> {
    splatbridge_scene::formats::gltf_khr::read_gltf_splats(path).map_err(crate::scene_err)
}
