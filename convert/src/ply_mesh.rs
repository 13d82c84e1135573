//! PLY triangle-mesh writer (binary little-endian) with RGBA vertex colours, and a reader
//! for the files it writes.
//!
//! Vertex: `x y z nx ny nz` (float), `red green blue alpha` (uchar, display colour and
//! opacity: the PLY convention importers expect), `gaussian_id` (uint) and, for the
//! `texture` profile, `s t` (float). Faces: `list uchar uint vertex_indices`. Like OBJ, PLY
//! has no node hierarchy: the up rotation and the objects' poses at the scene's start time
//! are baked into the vertices. The options and counts are in a `comment splatbridge` line.

use std::io::{self, Read, Write};
use std::path::Path;

use glam::Vec3;
use splatbridge_scene::dynamic::DynamicScene;

use crate::chunked::ChunkedMesh;
use crate::obj::{display_opts, placement};
use crate::options::{ConvertOptions, ConvertReport};
use crate::{prepare, shape_for, ConvertError, FrameClouds, MeshSoup};

fn u8c(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Write the scene at its start time as one PLY mesh, atomically.
pub fn write_file(
    path: &Path,
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
) -> crate::Result<ConvertReport> {
    let dopts = display_opts(opts);
    let mut report = ConvertReport::new("ply", &dopts);
    let shape = shape_for(&dopts);
    let entries = prepare(scene, frames, &dopts, &shape, &mut report)?;
    let t = scene.time.start;
    let shown: Vec<_> = entries
        .iter()
        .filter(|e| !e.mesher.is_empty())
        .filter_map(|e| placement(e, scene, frames, &dopts, t).map(|x| (e, x)))
        .collect();
    let nv: u64 = shown.iter().map(|(e, _)| e.mesher.counts.vertices).sum();
    let nt: u64 = shown.iter().map(|(e, _)| e.mesher.counts.triangles).sum();
    if nv >= u32::MAX as u64 {
        return Err(ConvertError::Invalid(format!(
            "{nv} vertices do not fit PLY uint indices"
        )));
    }
    let uv = shape.has_uv();
    let meta = serde_json::to_string(&report.metadata(&dopts))
        .map_err(|e| ConvertError::Invalid(e.to_string()))?;
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment splatbridge {meta}\nelement vertex {nv}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\nproperty uint gaussian_id\n"
    );
    if uv {
        header.push_str("property float s\nproperty float t\n");
    }
    header.push_str(&format!(
        "element face {nt}\nproperty list uchar uint vertex_indices\nend_header\n"
    ));
    let mut bytes = 0u64;
    splatbridge_scene::image_io::with_atomic_writer(path, |w| {
        w.write_all(header.as_bytes())?;
        bytes += header.len() as u64;
        for (e, xf) in &shown {
            e.mesher.map_chunks(
                |c| {
                    let mut b = Vec::with_capacity(c.vertex_count() * 40);
                    for v in 0..c.vertex_count() {
                        let p = xf.transform_point3(Vec3::from_array(c.positions[v]));
                        let n = xf
                            .transform_vector3(Vec3::from_array(c.normals[v]))
                            .normalize_or_zero();
                        for x in p.to_array().iter().chain(&n.to_array()) {
                            b.extend_from_slice(&x.to_le_bytes());
                        }
                        b.extend(c.colors[v].map(u8c));
                        b.extend_from_slice(&c.gaussian_ids[v].to_le_bytes());
                        if uv {
                            for x in c.uvs[v] {
                                b.extend_from_slice(&x.to_le_bytes());
                            }
                        }
                    }
                    b
                },
                |b| {
                    bytes += b.len() as u64;
                    w.write_all(&b)
                },
            )?;
        }
        let mut base = 0u32;
        for (e, _) in &shown {
            e.mesher.map_index_chunks(
                base,
                |idx| {
                    let mut b = Vec::with_capacity(idx.len() / 3 * 13);
                    for t in idx.chunks_exact(3) {
                        b.push(3u8);
                        for i in t {
                            b.extend_from_slice(&i.to_le_bytes());
                        }
                    }
                    b
                },
                |b| {
                    bytes += b.len() as u64;
                    w.write_all(&b)
                },
            )?;
            base += e.mesher.counts.vertices as u32;
        }
        Ok(())
    })
    .map_err(crate::scene_err)?;
    report.bytes = bytes;
    Ok(report)
}

/// Read a PLY mesh written by [`write_file`] (colours as u8/255, alpha included).
pub fn read_file(path: &Path) -> crate::Result<MeshSoup> {
    let bad = |what: String| ConvertError::Format {
        path: path.into(),
        what,
    };
    let data = std::fs::read(path).map_err(crate::io_err(path))?;
    let end = data
        .windows(11)
        .position(|w| w == b"end_header\n")
        .ok_or_else(|| bad("no end_header line".into()))?;
    let header =
        std::str::from_utf8(&data[..end]).map_err(|_| bad("header is not UTF-8".into()))?;
    let mut nv = None;
    let mut nt = None;
    let mut uv = false;
    for (ln, line) in header.lines().enumerate() {
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.as_slice() {
            ["format", f, _] if *f != "binary_little_endian" => {
                return Err(bad(format!(
                    "line {}: only binary_little_endian is read, got {f}",
                    ln + 1
                )))
            }
            ["element", "vertex", n] => {
                nv = Some(
                    n.parse::<usize>()
                        .map_err(|_| bad(format!("line {}: bad vertex count", ln + 1)))?,
                )
            }
            ["element", "face", n] => {
                nt = Some(
                    n.parse::<usize>()
                        .map_err(|_| bad(format!("line {}: bad face count", ln + 1)))?,
                )
            }
            ["property", "float", "s"] => uv = true,
            _ => {}
        }
    }
    let (nv, nt) = (
        nv.ok_or_else(|| bad("no vertex element".into()))?,
        nt.ok_or_else(|| bad("no face element".into()))?,
    );
    let mut r = &data[end + 11..];
    let f4 = |r: &mut &[u8]| -> io::Result<[u8; 4]> {
        let mut b = [0u8; 4];
        r.read_exact(&mut b)?;
        Ok(b)
    };
    let mut m = MeshSoup::default();
    let trunc = |_| bad("file is truncated".into());
    for _ in 0..nv {
        let mut v = [0f32; 6];
        for x in &mut v {
            *x = f32::from_le_bytes(f4(&mut r).map_err(trunc)?);
        }
        let c = f4(&mut r).map_err(trunc)?;
        let id = u32::from_le_bytes(f4(&mut r).map_err(trunc)?);
        m.positions.push([v[0], v[1], v[2]]);
        m.normals.push([v[3], v[4], v[5]]);
        m.colors.push(c.map(|x| x as f32 / 255.0));
        m.gaussian_ids.push(id);
        if uv {
            let s = f32::from_le_bytes(f4(&mut r).map_err(trunc)?);
            let t = f32::from_le_bytes(f4(&mut r).map_err(trunc)?);
            m.uvs.push([s, t]);
        }
    }
    for f in 0..nt {
        let mut k = [0u8; 1];
        r.read_exact(&mut k).map_err(trunc)?;
        if k[0] != 3 {
            return Err(bad(format!("face {f} has {} vertices, expected 3", k[0])));
        }
        for _ in 0..3 {
            let i = u32::from_le_bytes(f4(&mut r).map_err(trunc)?);
            if i as usize >= nv {
                return Err(bad(format!("face {f} refers to vertex {i} of {nv}")));
            }
            m.indices.push(i);
        }
    }
    Ok(m)
}
