//! Fuzz entry points for the compressed splat formats of `scene::formats`: `.splat`, SPZ
//! (gzip versions 1–3 and the zstd version 4), compressed PLY, SOG (a `.sog` zip or a
//! `meta.json` beside WebP images) and `KHR_gaussian_splatting` glTF (plain and SPZ).
//!
//! Raw targets hand the fuzzer's bytes to the format's reader as a file. The structure-aware
//! targets decode the bytes with `arbitrary` into the fields of a plausible file (header
//! values, declared counts and sizes that may lie, codebooks, image sizes) and build the file
//! the way a writer would — gzip, zstd frames, WebP images, a zip — so inputs get past the
//! magic and checksum checks into the count, size and dequantisation logic.
//!
//! Included by path from `tests/fuzz_regressions.rs`, so it depends only on crates that the
//! root package also has.

use std::io::Write;
use std::path::Path;

use arbitrary::{Arbitrary, Unstructured};
use serde_json::{json, Value};
use splatbridge_scene::formats;
use splatbridge_scene::ply::ReadOptions;

use crate::entries::with_file;

/// Read a file as the CLI does: detection, the format's reader, the invalid-Gaussian policy.
pub(crate) fn load_both(p: &Path) {
    let _ = formats::detect(p);
    for drop_invalid in [false, true] {
        let _ = formats::load(p, &ReadOptions { drop_invalid });
    }
}

pub fn splat(data: &[u8]) {
    let _ = formats::splat::decode_splat(data, Path::new("fuzz.splat"));
    with_file(data, ".splat", load_both);
}

pub fn spz(data: &[u8]) {
    with_file(data, ".spz", |p| {
        let _ = formats::spz::read_spz(p);
        load_both(p);
    });
}

pub fn compressed_ply(data: &[u8]) {
    let _ = formats::compressed_ply::decode_compressed_ply(data, Path::new("fuzz.compressed.ply"));
    with_file(data, ".compressed.ply", load_both);
}

pub fn sog(data: &[u8]) {
    with_file(data, ".sog", |p| {
        let _ = formats::sog::read_sog(p);
        load_both(p);
    });
}

pub fn gltf_splats(data: &[u8]) {
    with_file(data, ".glb", |p| {
        let _ = formats::gltf_khr::read_gltf_splats(p);
        load_both(p);
    });
}

// ---- SPZ ----

#[derive(Arbitrary, Debug)]
pub struct SpzIn {
    /// 1–4 mostly; other values test the version check.
    version: u8,
    count: u16,
    /// Declare this count instead of the real one.
    count_lie: Option<u32>,
    sh_degree: u8,
    fractional_bits: u8,
    flags: u8,
    /// Extension records (flag 2; version 4: between header and table of contents).
    ext: Vec<u8>,
    /// Payload bytes, repeated to the size the real count needs.
    payload: Vec<u8>,
    /// Cut or extend the payload by this much.
    payload_delta: i16,
    gzip_level: u8,
    /// Version 4: per stream, lies about the compressed and uncompressed sizes.
    v4_lies: Vec<(i16, i16)>,
    /// Version 4: stream count and TOC offset lies.
    v4_streams_lie: i8,
    v4_toc_lie: i16,
    /// Version 4: compress the planes (otherwise raw zstd blocks).
    v4_compress: bool,
    /// Gzip a version-4 layout, or store a version-1–3 one without gzip.
    swap_container: bool,
    tail: Vec<u8>,
}

fn spz_planes(version: u32, n: u64, degree: u8) -> [u64; 6] {
    let pos = if version == 1 { 6 } else { 9 };
    let rot = if version >= 3 { 4 } else { 3 };
    let d = degree.min(4) as u64;
    let sh = 3 * ((d + 1) * (d + 1) - 1);
    [pos * n, n, 3 * n, 3 * n, rot * n, sh * n]
}

fn fill(src: &[u8], len: usize) -> Vec<u8> {
    if src.is_empty() {
        return vec![0; len];
    }
    src.iter().copied().cycle().take(len).collect()
}

fn adjust(len: u64, delta: i64) -> u64 {
    (len as i64 + delta).max(0) as u64
}

/// Build an SPZ file from arbitrary fields.
pub fn build_spz(s: &SpzIn) -> Vec<u8> {
    let version = match s.version % 8 {
        0..=4 => (s.version % 4) as u32 + 1,
        5 => 0,
        6 => 5,
        _ => s.version as u32,
    };
    let n = (s.count % 1024) as u64;
    let declared = s.count_lie.unwrap_or(n as u32);
    let degree = s.sh_degree % 6;
    let frac = if s.fractional_bits < 200 {
        s.fractional_bits % 24
    } else {
        s.fractional_bits
    };
    let planes = spz_planes(version, n, degree);
    let v4_layout = (version == 4) != s.swap_container;
    if !v4_layout {
        let total: u64 = planes.iter().sum();
        let body_len = adjust(total, s.payload_delta as i64) as usize;
        let mut raw = Vec::with_capacity(16 + body_len);
        raw.extend_from_slice(&0x5053_474e_u32.to_le_bytes());
        raw.extend_from_slice(&version.to_le_bytes());
        raw.extend_from_slice(&declared.to_le_bytes());
        raw.extend_from_slice(&[degree, frac, s.flags, 0]);
        raw.extend_from_slice(&fill(&s.payload, body_len));
        if s.flags & 2 != 0 {
            raw.extend_from_slice(&s.ext);
        }
        if version == 4 {
            // A version-1–3 layout carrying version 4 goes out raw (the no-gzip branch).
            raw.extend_from_slice(&s.tail);
            return raw;
        }
        let mut gz = flate2::write::GzEncoder::new(
            Vec::new(),
            flate2::Compression::new((s.gzip_level % 10) as u32),
        );
        let _ = gz.write_all(&raw);
        let mut out = gz.finish().unwrap_or_default();
        out.extend_from_slice(&s.tail);
        return out;
    }
    let present: Vec<u64> = planes.iter().copied().filter(|&p| p > 0).collect();
    let streams = (present.len() as i64 + s.v4_streams_lie as i64).clamp(0, 255) as u8;
    let ext = &s.ext[..s.ext.len().min(256)];
    let toc = adjust(32 + ext.len() as u64, s.v4_toc_lie as i64) as u32;
    let mut header = Vec::with_capacity(32);
    header.extend_from_slice(&0x5053_474e_u32.to_le_bytes());
    header.extend_from_slice(&version.to_le_bytes());
    header.extend_from_slice(&declared.to_le_bytes());
    header.extend_from_slice(&[degree, frac, s.flags, streams]);
    header.extend_from_slice(&toc.to_le_bytes());
    header.extend_from_slice(&[0; 12]);
    let mut frames = Vec::new();
    let mut entries = Vec::new();
    let mut src = s.payload.iter().copied().cycle();
    for (k, &len) in present.iter().enumerate() {
        let (clie, ulie) = s.v4_lies.get(k).copied().unwrap_or((0, 0));
        let take = if k + 1 == present.len() {
            adjust(len, s.payload_delta as i64)
        } else {
            len
        };
        let plane: Vec<u8> = if s.payload.is_empty() {
            vec![0; take as usize]
        } else {
            src.by_ref().take(take as usize).collect()
        };
        let level = if s.v4_compress {
            ruzstd::encoding::CompressionLevel::Fastest
        } else {
            ruzstd::encoding::CompressionLevel::Uncompressed
        };
        let frame = ruzstd::encoding::compress_to_vec(plane.as_slice(), level);
        entries.push((
            adjust(frame.len() as u64, clie as i64),
            adjust(len, ulie as i64),
        ));
        frames.extend_from_slice(&frame);
    }
    let mut out = header;
    out.extend_from_slice(ext);
    for (c, u) in entries {
        out.extend_from_slice(&c.to_le_bytes());
        out.extend_from_slice(&u.to_le_bytes());
    }
    out.extend_from_slice(&frames);
    out.extend_from_slice(&s.tail);
    if s.swap_container {
        // A version-4 layout inside gzip.
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        let _ = gz.write_all(&out);
        return gz.finish().unwrap_or_default();
    }
    out
}

pub fn spz_structured(data: &[u8]) {
    let Ok(s) = SpzIn::arbitrary(&mut Unstructured::new(data)) else {
        return;
    };
    let bytes = build_spz(&s);
    with_file(&bytes, ".spz", load_both);
}

// ---- compressed PLY ----

#[derive(Arbitrary, Debug)]
struct CplyIn {
    count: u16,
    /// Lie about the vertex count (wrapping add).
    vertex_lie: i16,
    chunk_lie: i8,
    colour_bounds: bool,
    /// Drop one required chunk property (when < 12) or packed property (12–15).
    drop: u8,
    /// 0: no `sh` element; else 9, 24 or 45 coefficients, or a wrong count.
    sh: u8,
    sh_lie: i16,
    /// Property types: `float`/`uint` or an odd one.
    odd_type: Option<u8>,
    bounds: Vec<f32>,
    packed: Vec<u32>,
    sh_bytes: Vec<u8>,
    payload_delta: i16,
    ascii: bool,
}

fn compressed_ply_structured(data: &[u8]) {
    let Ok(c) = CplyIn::arbitrary(&mut Unstructured::new(data)) else {
        return;
    };
    const CHUNK: [&str; 18] = [
        "min_x",
        "min_y",
        "min_z",
        "max_x",
        "max_y",
        "max_z",
        "min_scale_x",
        "min_scale_y",
        "min_scale_z",
        "max_scale_x",
        "max_scale_y",
        "max_scale_z",
        "min_r",
        "min_g",
        "min_b",
        "max_r",
        "max_g",
        "max_b",
    ];
    const PACKED: [&str; 4] = [
        "packed_position",
        "packed_rotation",
        "packed_scale",
        "packed_color",
    ];
    const ODD: [&str; 5] = ["double", "uchar", "int", "list uchar int", "half"];
    let n = (c.count % 2048) as i64;
    let chunks = (n + 255) / 256;
    let chunk_props: Vec<&str> = CHUNK[..if c.colour_bounds { 18 } else { 12 }]
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != c.drop as usize)
        .map(|(_, p)| *p)
        .collect();
    let packed: Vec<&str> = PACKED
        .iter()
        .enumerate()
        .filter(|(i, _)| *i + 12 != c.drop as usize)
        .map(|(_, p)| *p)
        .collect();
    let sh_k = match c.sh % 5 {
        0 => 0,
        1 => 9,
        2 => 24,
        3 => 45,
        _ => (c.sh as i64 % 64) + 1,
    } as usize;
    let enc = if c.ascii {
        "ascii"
    } else {
        "binary_little_endian"
    };
    let ty = |default: &'static str| c.odd_type.map_or(default, |t| ODD[t as usize % ODD.len()]);
    let mut h = format!(
        "ply\nformat {enc} 1.0\nelement chunk {}\n",
        (chunks + c.chunk_lie as i64).max(0)
    );
    for p in &chunk_props {
        h.push_str(&format!("property {} {p}\n", ty("float")));
    }
    h.push_str(&format!(
        "element vertex {}\n",
        (n + c.vertex_lie as i64).max(0)
    ));
    for p in &packed {
        h.push_str(&format!("property uint {p}\n"));
    }
    if sh_k > 0 {
        h.push_str(&format!("element sh {}\n", (n + c.sh_lie as i64).max(0)));
        for k in 0..sh_k {
            h.push_str(&format!("property uchar f_rest_{k}\n"));
        }
    }
    h.push_str("end_header\n");
    let mut out = h.into_bytes();
    let mut body = Vec::new();
    let mut b = c
        .bounds
        .iter()
        .copied()
        .chain(std::iter::repeat(0.0))
        .cycle();
    for _ in 0..chunks as usize * chunk_props.len() {
        body.extend_from_slice(&b.next().unwrap_or(0.0).to_le_bytes());
    }
    let mut p = c.packed.iter().copied().chain(std::iter::repeat(0)).cycle();
    for _ in 0..n as usize * packed.len() {
        body.extend_from_slice(&p.next().unwrap_or(0).to_le_bytes());
    }
    body.extend_from_slice(&fill(&c.sh_bytes, n as usize * sh_k));
    let body_len = adjust(body.len() as u64, c.payload_delta as i64) as usize;
    body.resize(body_len, 0);
    out.extend_from_slice(&body);
    compressed_ply(&out);
}

// ---- SOG ----

#[derive(Arbitrary, Debug)]
struct SogIn {
    /// 0: v1 (no key), 1: v2, else a bad version value.
    version: u8,
    count: u16,
    count_lie: Option<u32>,
    /// Image size deltas from the square layout (wrong sizes).
    w_delta: i8,
    h_delta: i8,
    /// Which image gets the wrong size (index into the file list), if any.
    wrong_image: Option<u8>,
    means: [f32; 6],
    /// Range and codebook values (cycled); NaN and infinities become `null` or bare tokens.
    values: Vec<f32>,
    /// Codebook length delta from 256.
    codebook_delta: i8,
    shn: Option<(u8, u16)>,
    /// Remove one key of `meta.json` (index into a table of paths).
    drop_key: Option<u8>,
    /// Write non-finite numbers as bare `NaN`/`Infinity` tokens instead of `null`.
    bare_nan: bool,
    pixels: Vec<u8>,
    /// Leave out one image file, or replace it by garbage.
    missing: Option<u8>,
    garbage: Option<(u8, Vec<u8>)>,
    bundled: bool,
    stored: bool,
}

const SOG_FILES: [&str; 7] = [
    "means_l.webp",
    "means_u.webp",
    "quats.webp",
    "scales.webp",
    "sh0.webp",
    "shN_centroids.webp",
    "shN_labels.webp",
];

fn num(x: f32) -> Value {
    serde_json::Number::from_f64(x as f64).map_or(Value::Null, Value::Number)
}

fn webp(w: u32, h: u32, pixels: &[u8]) -> Vec<u8> {
    let data = fill(pixels, (w * h * 4) as usize);
    let mut out = Vec::new();
    let enc = image_webp::WebPEncoder::new(&mut out);
    if enc
        .encode(&data, w, h, image_webp::ColorType::Rgba8)
        .is_err()
    {
        return Vec::new();
    }
    out
}

fn sog_structured(data: &[u8]) {
    let Ok(s) = SogIn::arbitrary(&mut Unstructured::new(data)) else {
        return;
    };
    let n = (s.count % 600) as u32 + 1;
    let declared = s.count_lie.map_or(n as u64, |c| c as u64);
    let side = (n as f64).sqrt().ceil() as u32;
    let (w, h) = (side.max(1), n.div_ceil(side.max(1)));
    let mut vals = s.values.iter().copied().chain(std::iter::once(0.5)).cycle();
    let mut take =
        |k: usize| -> Vec<Value> { (0..k).map(|_| num(vals.next().unwrap_or(0.0))).collect() };
    let version = s.version % 4;
    let mut meta = json!({
        "means": {
            "mins": s.means[..3].iter().map(|&x| num(x)).collect::<Vec<_>>(),
            "maxs": s.means[3..].iter().map(|&x| num(x)).collect::<Vec<_>>(),
            "files": ["means_l.webp", "means_u.webp"],
            "shape": [declared, 3],
        },
        "quats": { "files": ["quats.webp"] },
        "scales": { "files": ["scales.webp"] },
        "sh0": { "files": ["sh0.webp"] },
    });
    let cb_len = (256 + s.codebook_delta as i64).max(0) as usize;
    let (shn_bands, shn_palette) = s.shn.map_or((0, 0), |(b, p)| (b % 5, (p % 300) as u32 + 1));
    if version == 0 {
        meta["scales"]["mins"] = json!(take(3));
        meta["scales"]["maxs"] = json!(take(3));
        meta["sh0"]["mins"] = json!(take(4));
        meta["sh0"]["maxs"] = json!(take(4));
    } else {
        meta["version"] = if version == 1 {
            json!(2)
        } else {
            json!(version)
        };
        meta["count"] = json!(declared);
        meta["scales"]["codebook"] = json!(take(cb_len));
        meta["sh0"]["codebook"] = json!(take(cb_len));
    }
    if s.shn.is_some() {
        meta["shN"] = json!({ "files": ["shN_centroids.webp", "shN_labels.webp"] });
        if version == 0 {
            meta["shN"]["mins"] = take(1).remove(0);
            meta["shN"]["maxs"] = take(1).remove(0);
        } else {
            meta["shN"]["bands"] = json!(shn_bands);
            meta["shN"]["count"] = json!(shn_palette);
            meta["shN"]["codebook"] = json!(take(cb_len));
        }
    }
    const KEYS: [(&str, &str); 10] = [
        ("means", "mins"),
        ("means", "maxs"),
        ("means", "files"),
        ("means", "shape"),
        ("quats", "files"),
        ("scales", "codebook"),
        ("scales", "mins"),
        ("sh0", "maxs"),
        ("sh0", "codebook"),
        ("", "count"),
    ];
    if let Some(k) = s.drop_key {
        let (a, b) = KEYS[k as usize % KEYS.len()];
        let obj = if a.is_empty() {
            meta.as_object_mut()
        } else {
            meta[a].as_object_mut()
        };
        if let Some(o) = obj {
            o.remove(b);
        }
    }
    let mut text = meta.to_string();
    if s.bare_nan {
        text = text.replacen("null", "NaN", 1);
    }
    let coeffs = [0u32, 3, 8, 15, 15][shn_bands as usize];
    let mut files: Vec<(String, Vec<u8>)> = vec![("meta.json".into(), text.into_bytes())];
    for (i, name) in SOG_FILES.iter().enumerate() {
        if i >= 5 && s.shn.is_none() {
            break;
        }
        let (mut iw, mut ih) = match i {
            5 => (64 * coeffs.max(1), shn_palette.div_ceil(64)),
            _ => (w, h),
        };
        if s.wrong_image.map(|x| x as usize % 7) == Some(i) {
            // Small enough that encoding stays fast, large enough to break the padding rule.
            iw = (iw as i64 + s.w_delta as i64).clamp(1, 256) as u32;
            ih = (ih as i64 + s.h_delta as i64).clamp(1, 256) as u32;
        }
        let bytes = match &s.garbage {
            Some((g, junk)) if *g as usize % 7 == i => junk.clone(),
            _ => webp(iw, ih, &s.pixels),
        };
        if s.missing.map(|x| x as usize % 8) == Some(i) {
            continue;
        }
        files.push((name.to_string(), bytes));
    }
    if s.bundled {
        let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
        let method = if s.stored {
            zip::CompressionMethod::Stored
        } else {
            zip::CompressionMethod::Deflated
        };
        let opts = zip::write::SimpleFileOptions::default().compression_method(method);
        for (name, bytes) in &files {
            if zip.start_file(name.as_str(), opts).is_err() || zip.write_all(bytes).is_err() {
                return;
            }
        }
        let Ok(cursor) = zip.finish() else {
            return;
        };
        sog(&cursor.into_inner());
    } else {
        let Ok(dir) = tempfile::tempdir() else {
            return;
        };
        for (name, bytes) in &files {
            if std::fs::write(dir.path().join(name), bytes).is_err() {
                return;
            }
        }
        let meta = dir.path().join("meta.json");
        let _ = formats::sog::read_sog(&meta);
        load_both(&meta);
    }
}

// ---- KHR_gaussian_splatting glTF ----

/// A node: translation, rotation, scale, children.
type NodeIn = ([f32; 3], [f32; 4], [f32; 3], Vec<u8>);

#[derive(Arbitrary, Debug)]
struct KhrIn {
    count: u16,
    /// Per attribute: count lie, component type, accessor type, normalized.
    attrs: Vec<(i16, u8, u8, bool)>,
    sh_degree: u8,
    /// Drop one attribute (index), or point it at a wrong accessor.
    drop: Option<u8>,
    floats: Vec<f32>,
    view_offset_lie: u16,
    view_len_lie: i16,
    stride: Option<u8>,
    nodes: Vec<NodeIn>,
    matrix: Option<[f32; 16]>,
    /// An animation: node, key times, and whether translation/rotation outputs exist.
    anim: Option<(u8, Vec<f32>, bool, bool, i8)>,
    /// Replace the attributes by an SPZ stream built from these fields.
    spz: Option<SpzIn>,
    spz_count_lie: i16,
    glb: bool,
    bin_delta: i16,
}

fn gltf_splats_structured(data: &[u8]) {
    let Ok(k) = KhrIn::arbitrary(&mut Unstructured::new(data)) else {
        return;
    };
    const EXT: &str = "KHR_gaussian_splatting";
    const CT: [u32; 6] = [5126, 5121, 5123, 5120, 5122, 5125];
    const TY: [&str; 5] = ["SCALAR", "VEC2", "VEC3", "VEC4", "MAT4"];
    let n = (k.count % 512) as i64;
    let degree = k.sh_degree % 5;
    let mut names: Vec<(String, usize)> = vec![
        ("POSITION".into(), 3),
        (format!("{EXT}:ROTATION"), 4),
        (format!("{EXT}:SCALE"), 3),
        (format!("{EXT}:OPACITY"), 1),
        ("COLOR_0".into(), 4),
    ];
    for l in 1..=degree {
        for c in 0..(2 * l + 1) {
            names.push((format!("{EXT}:SH_DEGREE_{l}_COEF_{c}"), 3));
        }
    }
    let mut bin = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut attributes = serde_json::Map::new();
    let mut fl = k
        .floats
        .iter()
        .copied()
        .chain(std::iter::once(0.25))
        .cycle();
    for (i, (name, comps)) in names.iter().enumerate() {
        if k.drop.map(|d| d as usize % 32) == Some(i) {
            continue;
        }
        let (lie, ct, ty, normalized) = k.attrs.get(i).copied().unwrap_or((0, 0, 255, false));
        let count = (n + lie as i64 % 8).max(0);
        let ctype = if ct < 200 {
            5126
        } else {
            CT[ct as usize % CT.len()]
        };
        // Mostly the right type; a high byte picks any type (VEC2 positions, MAT4 scales).
        let ttype = if ty < 200 {
            match *comps {
                1 => "SCALAR",
                3 => "VEC3",
                _ => "VEC4",
            }
        } else {
            TY[ty as usize % TY.len()]
        };
        let offset = bin.len();
        if k.spz.is_none() {
            for _ in 0..count as usize * comps {
                bin.extend_from_slice(&fl.next().unwrap_or(0.0).to_le_bytes());
            }
            let len = adjust((bin.len() - offset) as u64, k.view_len_lie as i64 % 64);
            let mut view = json!({ "buffer": 0, "byteOffset": view_offset(offset, k.view_offset_lie), "byteLength": len });
            if let Some(s) = k.stride {
                view["byteStride"] = json!(s as u32 * 4 % 256);
            }
            views.push(view);
        }
        let mut acc = json!({ "componentType": ctype, "count": count, "type": ttype });
        if normalized {
            acc["normalized"] = json!(true);
        }
        if k.spz.is_none() {
            acc["bufferView"] = json!(views.len() - 1);
        } else {
            acc["count"] = json!((n + k.spz_count_lie as i64 % 4).max(0));
        }
        accessors.push(acc);
        attributes.insert(name.clone(), json!(accessors.len() - 1));
    }
    let mut ext = json!({});
    let mut used = vec![json!(EXT)];
    if let Some(s) = &k.spz {
        let stream = build_spz(s);
        views.push(json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": adjust(stream.len() as u64, k.view_len_lie as i64 % 16) }));
        bin.extend_from_slice(&stream);
        let name = "KHR_gaussian_splatting_compression_spz_2";
        let mut nested = serde_json::Map::new();
        nested.insert(name.into(), json!({ "bufferView": views.len() - 1 }));
        ext["extensions"] = Value::Object(nested);
        used.push(json!(name));
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let mut nodes: Vec<Value> = k
        .nodes
        .iter()
        .take(8)
        .map(|(t, r, s, children)| {
            json!({
                "translation": (*t).map(num), "rotation": (*r).map(num), "scale": (*s).map(num),
                "children": children.iter().take(3).map(|c| c % 9).collect::<Vec<_>>(),
            })
        })
        .collect();
    let mut mesh_node = json!({ "mesh": 0 });
    if let Some(m) = k.matrix {
        mesh_node["matrix"] = json!(m.map(num));
    }
    nodes.push(mesh_node);
    let roots: Vec<usize> = (0..nodes.len()).collect();
    let mut prim_ext = serde_json::Map::new();
    prim_ext.insert(EXT.into(), ext);
    let mut doc = json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": used,
        "scene": 0,
        "scenes": [{ "nodes": roots }],
        "nodes": nodes,
        "meshes": [{ "primitives": [{ "attributes": attributes, "mode": 0,
                                      "extensions": prim_ext }] }],
        "accessors": accessors,
        "bufferViews": views,
    });
    if let Some((node, times, tr, rot, lie)) = &k.anim {
        let mut accs = doc["accessors"].as_array().cloned().unwrap_or_default();
        let mut views = doc["bufferViews"].as_array().cloned().unwrap_or_default();
        let nt = times.len().min(16);
        let mut push = |vals: Vec<f32>, ty: &str, count: usize, bin: &mut Vec<u8>| -> usize {
            let off = bin.len();
            for v in &vals {
                bin.extend_from_slice(&v.to_le_bytes());
            }
            views.push(json!({ "buffer": 0, "byteOffset": off, "byteLength": vals.len() * 4 }));
            accs.push(
                json!({ "bufferView": views.len() - 1, "componentType": 5126,
                              "count": (count as i64 + *lie as i64 % 3).max(0), "type": ty }),
            );
            accs.len() - 1
        };
        let input = push(times[..nt].to_vec(), "SCALAR", nt, &mut bin);
        let mut channels = Vec::new();
        let mut samplers = Vec::new();
        if *tr {
            let out = push(fill_f32(&k.floats, 3 * nt), "VEC3", nt, &mut bin);
            samplers.push(json!({ "input": input, "output": out }));
            channels.push(json!({ "sampler": samplers.len() - 1,
                                  "target": { "node": node % 10, "path": "translation" } }));
        }
        if *rot {
            let out = push(fill_f32(&k.floats, 4 * nt), "VEC4", nt, &mut bin);
            samplers.push(json!({ "input": input, "output": out }));
            channels.push(json!({ "sampler": samplers.len() - 1,
                                  "target": { "node": node % 10, "path": "rotation" } }));
        }
        doc["accessors"] = json!(accs);
        doc["bufferViews"] = json!(views);
        doc["animations"] = json!([{ "channels": channels, "samplers": samplers }]);
    }
    let bin_len = adjust(bin.len() as u64, k.bin_delta as i64 % 64);
    doc["buffers"] = json!([{ "byteLength": bin_len }]);
    let mut text = doc.to_string().into_bytes();
    if !k.glb {
        // A .gltf with its buffer embedded as a base64 data URI is what `convert` never
        // writes; GLB is the common case, so the text form references a missing file.
        doc["buffers"][0]["uri"] = json!("missing.bin");
        text = doc.to_string().into_bytes();
        with_file(&text, ".gltf", |p| {
            let _ = formats::gltf_khr::read_gltf_splats(p);
        });
        return;
    }
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let mut glb = Vec::with_capacity(28 + text.len() + bin.len());
    let total = 12 + 8 + text.len() + 8 + bin.len();
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(text.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&text);
    glb.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&bin);
    gltf_splats(&glb);
}

/// The view's real offset, or now and then one far past the buffer.
fn view_offset(offset: usize, lie: u16) -> u64 {
    if lie > 65000 {
        offset as u64 + (lie as u64) * 65536
    } else {
        offset as u64
    }
}

fn fill_f32(src: &[f32], len: usize) -> Vec<f32> {
    if src.is_empty() {
        return vec![0.0; len];
    }
    src.iter().copied().cycle().take(len).collect()
}

/// A target's entry function.
pub type Entry = fn(&[u8]);

/// Every target of this module: name and entry function.
pub const TARGETS: &[(&str, Entry)] = &[
    ("splat", splat),
    ("spz", spz),
    ("spz_structured", spz_structured),
    ("compressed_ply", compressed_ply),
    ("compressed_ply_structured", compressed_ply_structured),
    ("sog", sog),
    ("sog_structured", sog_structured),
    ("gltf_splats", gltf_splats),
    ("gltf_splats_structured", gltf_splats_structured),
];
