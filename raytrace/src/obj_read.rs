//! Streaming OBJ/MTL reader for the triangle tracer (Wavefront OBJ as Blender, tobj and
//! `splatbridge convert` read and write it): `v x y z [w | r g b]`, `vt`, `vn`, `f` with
//! `v`, `v/vt`, `v//vn`, `v/vt/vn` corners and negative (relative) indices, polygons
//! fan-triangulated from their first corner, `o`/`g`/`usemtl` starting a new object (as tobj
//! does), `s`/`mtllib`/comments and unknown keywords skipped.
//!
//! Why not tobj: its single-index mode hashes every (v, vt, vn) tuple, which for a multi-GB
//! export costs more than the geometry. The tracer uses positions and colours, which belong
//! to `v`, so a vertex is its `v` index; `vt`/`vn` are range-checked and otherwise ignored.
//! Lines are read one at a time through a bounded buffer; memory is the vertex and triangle
//! arrays plus one `u32` per vertex for the per-object renumbering.

use std::io::BufRead;
use std::path::Path;

use glam::Vec3;

use crate::error::{Result, TraceError};

/// Longest accepted line; a 1000-corner polygon with `v/vt/vn` corners fits comfortably.
pub const MAX_LINE: usize = 1 << 16;

/// One object: its own vertices (renumbered from 0 in first-use order) and triangles.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct ObjObject {
    pub name: String,
    pub positions: Vec<Vec3>,
    /// Present when every vertex of the object has `v x y z r g b`.
    pub colors: Option<Vec<Vec3>>,
    pub tris: Vec<[u32; 3]>,
    /// Index into the MTL materials, when `usemtl` named a known one.
    pub material: Option<usize>,
}

/// MTL material: `newmtl`, `Kd`, `d`.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct ObjMaterial {
    pub name: String,
    pub diffuse: Option<[f32; 3]>,
    pub dissolve: Option<f32>,
}

struct Pending {
    name: String,
    material: Option<usize>,
    tris: Vec<[u32; 3]>,
}

/// Read one line (without its terminator) into `buf`; `false` at end of input.
fn next_line(r: &mut impl BufRead, buf: &mut Vec<u8>, path: &Path, line: usize) -> Result<bool> {
    use std::io::Read;
    buf.clear();
    let n = r
        .take(MAX_LINE as u64 + 1)
        .read_until(b'\n', buf)
        .map_err(|e| TraceError::format(path, format!("line {line}: cannot read: {e}")))?;
    if n == 0 {
        return Ok(false);
    }
    if buf.last() == Some(&b'\n') {
        buf.pop();
    } else if buf.len() > MAX_LINE {
        return Err(TraceError::format(
            path,
            format!("line {line}: longer than {MAX_LINE} bytes"),
        ));
    }
    if buf.last() == Some(&b'\r') {
        buf.pop();
    }
    Ok(true)
}

fn nums<'a>(
    it: impl Iterator<Item = &'a str>,
    path: &Path,
    line: usize,
    out: &mut [f32; 7],
) -> Result<usize> {
    let mut n = 0;
    for t in it {
        if n == out.len() {
            return Err(TraceError::format(
                path,
                format!("line {line}: too many numbers"),
            ));
        }
        out[n] = t.parse().map_err(|_| {
            TraceError::format(
                path,
                format!(
                    "line {line}: '{}' is not a number",
                    splatbridge_scene::input::clip(t)
                ),
            )
        })?;
        n += 1;
    }
    Ok(n)
}

/// Resolve a 1-based or negative OBJ index against `count` elements defined so far.
fn resolve(tok: &str, count: usize, what: &str, path: &Path, line: usize) -> Result<usize> {
    let bad = || {
        TraceError::format(
            path,
            format!(
                "line {line}: {what} index '{}' out of range ({count} defined)",
                splatbridge_scene::input::clip(tok)
            ),
        )
    };
    let i: i64 = tok.parse().map_err(|_| bad())?;
    let idx = if i > 0 {
        i - 1
    } else if i < 0 {
        count as i64 + i
    } else {
        return Err(bad());
    };
    if idx < 0 || idx as usize >= count {
        return Err(bad());
    }
    Ok(idx as usize)
}

/// Parse an OBJ stream. `load_mtl` is called with each `mtllib` argument and returns that
/// library's materials (or nothing, when it cannot be read: geometry stays usable).
pub fn read_obj(
    r: &mut impl BufRead,
    path: &Path,
    mut load_mtl: impl FnMut(&str) -> Option<Vec<ObjMaterial>>,
) -> Result<(Vec<ObjObject>, Vec<ObjMaterial>)> {
    let mut positions: Vec<Vec3> = Vec::new();
    // NaN where the vertex has no colour.
    let mut colors: Vec<Vec3> = Vec::new();
    let (mut n_vt, mut n_vn) = (0usize, 0usize);
    let mut mats: Vec<ObjMaterial> = Vec::new();
    let mut done: Vec<Pending> = Vec::new();
    let mut cur = Pending {
        name: "unnamed_object".into(),
        material: None,
        tris: Vec::new(),
    };
    let mut buf = Vec::new();
    let mut corners: Vec<u32> = Vec::new();
    let mut vals = [0f32; 7];
    let mut line = 0usize;
    while next_line(r, &mut buf, path, line + 1)? {
        line += 1;
        let text = std::str::from_utf8(&buf)
            .map_err(|_| TraceError::format(path, format!("line {line}: not UTF-8")))?;
        let text = text.trim();
        let mut it = text.split_ascii_whitespace();
        let Some(key) = it.next() else { continue };
        let rest = || text[key.len()..].trim();
        match key {
            "v" => {
                let n = nums(it, path, line, &mut vals)?;
                let p = Vec3::new(vals[0], vals[1], vals[2]);
                let c = match n {
                    3 | 4 => Vec3::NAN,
                    6 => Vec3::new(vals[3], vals[4], vals[5]),
                    _ => {
                        return Err(TraceError::format(
                            path,
                            format!("line {line}: 'v' takes 3, 4 or 6 numbers, not {n}"),
                        ))
                    }
                };
                positions.push(p);
                colors.push(c);
            }
            "vt" => n_vt += 1,
            "vn" => n_vn += 1,
            "f" => {
                corners.clear();
                for c in it {
                    let mut parts = c.split('/');
                    let v = parts.next().unwrap_or("");
                    corners.push(resolve(v, positions.len(), "vertex", path, line)? as u32);
                    if let Some(t) = parts.next().filter(|t| !t.is_empty()) {
                        resolve(t, n_vt, "texture", path, line)?;
                    }
                    if let Some(t) = parts.next().filter(|t| !t.is_empty()) {
                        resolve(t, n_vn, "normal", path, line)?;
                    }
                    if parts.next().is_some() {
                        return Err(TraceError::format(
                            path,
                            format!(
                                "line {line}: face corner '{}' has more than three parts",
                                splatbridge_scene::input::clip(c)
                            ),
                        ));
                    }
                }
                if corners.len() < 3 {
                    return Err(TraceError::format(
                        path,
                        format!("line {line}: a face needs 3 corners, not {}", corners.len()),
                    ));
                }
                for k in 1..corners.len() - 1 {
                    cur.tris.push([corners[0], corners[k], corners[k + 1]]);
                }
            }
            "o" | "g" => {
                if !cur.tris.is_empty() {
                    let next = Pending {
                        name: String::new(),
                        material: cur.material,
                        tris: Vec::new(),
                    };
                    done.push(std::mem::replace(&mut cur, next));
                }
                cur.name = rest().to_owned();
                if cur.name.is_empty() {
                    cur.name = "unnamed_object".into();
                }
            }
            "usemtl" => {
                let name = rest();
                let m = mats.iter().position(|m| m.name == name);
                if m != cur.material && !cur.tris.is_empty() {
                    let next = Pending {
                        name: cur.name.clone(),
                        material: m,
                        tris: Vec::new(),
                    };
                    done.push(std::mem::replace(&mut cur, next));
                }
                cur.material = m;
            }
            "mtllib" => {
                if let Some(mut m) = load_mtl(rest()) {
                    mats.append(&mut m);
                }
            }
            _ => {}
        }
    }
    if !cur.tris.is_empty() {
        done.push(cur);
    }
    // Renumber each object's vertices in first-use order through one shared table.
    let mut remap = vec![u32::MAX; positions.len()];
    let mut objects = Vec::with_capacity(done.len());
    for p in done {
        let mut used: Vec<u32> = Vec::new();
        let mut tris = p.tris;
        for t in &mut tris {
            for i in t.iter_mut() {
                let g = *i as usize;
                if remap[g] == u32::MAX {
                    remap[g] = used.len() as u32;
                    used.push(*i);
                }
                *i = remap[g];
            }
        }
        let pos: Vec<Vec3> = used.iter().map(|&g| positions[g as usize]).collect();
        let all_colored = used.iter().all(|&g| !colors[g as usize].is_nan());
        let col = all_colored.then(|| used.iter().map(|&g| colors[g as usize]).collect());
        for &g in &used {
            remap[g as usize] = u32::MAX;
        }
        objects.push(ObjObject {
            name: p.name,
            positions: pos,
            colors: col,
            tris,
            material: p.material,
        });
    }
    Ok((objects, mats))
}

/// Parse an MTL library: `newmtl`, `Kd`, `d` (other statements are skipped).
pub fn read_mtl(r: &mut impl BufRead, path: &Path) -> Result<Vec<ObjMaterial>> {
    let mut mats: Vec<ObjMaterial> = Vec::new();
    let mut buf = Vec::new();
    let mut vals = [0f32; 7];
    let mut line = 0usize;
    while next_line(r, &mut buf, path, line + 1)? {
        line += 1;
        let text = String::from_utf8_lossy(&buf);
        let text = text.trim();
        let mut it = text.split_ascii_whitespace();
        let Some(key) = it.next() else { continue };
        match key {
            "newmtl" => mats.push(ObjMaterial {
                name: text[key.len()..].trim().to_owned(),
                ..ObjMaterial::default()
            }),
            "Kd" | "d" => {
                let n = nums(it, path, line, &mut vals)?;
                let Some(m) = mats.last_mut() else { continue };
                match (key, n) {
                    ("Kd", 3) => m.diffuse = Some([vals[0], vals[1], vals[2]]),
                    ("d", 1) => m.dissolve = Some(vals[0]),
                    _ => {
                        return Err(TraceError::format(
                            path,
                            format!("line {line}: '{key}' with {n} numbers"),
                        ))
                    }
                }
            }
            _ => {}
        }
    }
    Ok(mats)
}
