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

pub(crate) struct Pending {
    pub name: String,
    pub material: Option<usize>,
    pub tris: Vec<[u32; 3]>,
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
        return Err(too_long(path, line));
    }
    if buf.last() == Some(&b'\r') {
        buf.pop();
    }
    Ok(true)
}

pub(crate) fn too_long(path: &Path, line: usize) -> TraceError {
    TraceError::format(path, format!("line {line}: longer than {MAX_LINE} bytes"))
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
    resolved(i, count).ok_or_else(bad)
}

/// Where the parsed OBJ index `i` points among `count` elements: 1-based, or counted back
/// from the last when negative; None for 0 and out of range.
#[inline]
pub(crate) fn resolved(i: i64, count: usize) -> Option<usize> {
    let idx = if i > 0 {
        i - 1
    } else if i < 0 {
        count as i64 + i
    } else {
        return None;
    };
    (idx >= 0 && (idx as usize) < count).then_some(idx as usize)
}

/// What has been read so far: every vertex, the objects finished and the one being read.
pub(crate) struct ObjState<'a, F> {
    pub path: &'a Path,
    pub positions: Vec<Vec3>,
    /// NaN where the vertex has no colour.
    pub colors: Vec<Vec3>,
    pub n_vt: usize,
    pub n_vn: usize,
    pub mats: Vec<ObjMaterial>,
    pub done: Vec<Pending>,
    pub cur: Pending,
    pub load_mtl: F,
    corners: Vec<u32>,
}

impl<'a, F: FnMut(&str) -> Option<Vec<ObjMaterial>>> ObjState<'a, F> {
    pub fn new(path: &'a Path, load_mtl: F) -> Self {
        ObjState {
            path,
            positions: Vec::new(),
            colors: Vec::new(),
            n_vt: 0,
            n_vn: 0,
            mats: Vec::new(),
            done: Vec::new(),
            cur: Pending {
                name: "unnamed_object".into(),
                material: None,
                tris: Vec::new(),
            },
            load_mtl,
            corners: Vec::new(),
        }
    }

    /// One line (without its terminator and one trailing `\r`), the `line`th of the file:
    /// the reference reading of every statement, which the block reader
    /// (`obj_block`) reproduces for the lines it reads itself and hands the rest to.
    pub fn line(&mut self, buf: &[u8], line: usize) -> Result<()> {
        let path = self.path;
        let text = std::str::from_utf8(buf)
            .map_err(|_| TraceError::format(path, format!("line {line}: not UTF-8")))?;
        let text = text.trim();
        let mut it = text.split_ascii_whitespace();
        let Some(key) = it.next() else {
            return Ok(());
        };
        let rest = || text[key.len()..].trim();
        match key {
            "v" => {
                let mut vals = [0f32; 7];
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
                self.positions.push(p);
                self.colors.push(c);
            }
            "vt" => self.n_vt += 1,
            "vn" => self.n_vn += 1,
            "f" => {
                let corners = &mut self.corners;
                corners.clear();
                for c in it {
                    let mut parts = c.split('/');
                    let v = parts.next().unwrap_or("");
                    corners.push(resolve(v, self.positions.len(), "vertex", path, line)? as u32);
                    if let Some(t) = parts.next().filter(|t| !t.is_empty()) {
                        resolve(t, self.n_vt, "texture", path, line)?;
                    }
                    if let Some(t) = parts.next().filter(|t| !t.is_empty()) {
                        resolve(t, self.n_vn, "normal", path, line)?;
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
                    self.cur.tris.push([corners[0], corners[k], corners[k + 1]]);
                }
            }
            "o" | "g" => self.object(rest()),
            "usemtl" => self.usemtl(rest()),
            "mtllib" => self.mtllib(rest()),
            _ => {}
        }
        Ok(())
    }

    /// `o NAME` or `g NAME` (trimmed).
    pub fn object(&mut self, name: &str) {
        if !self.cur.tris.is_empty() {
            let next = Pending {
                name: String::new(),
                material: self.cur.material,
                tris: Vec::new(),
            };
            self.done.push(std::mem::replace(&mut self.cur, next));
        }
        self.cur.name = name.to_owned();
        if self.cur.name.is_empty() {
            self.cur.name = "unnamed_object".into();
        }
    }

    /// `usemtl NAME` (trimmed).
    pub fn usemtl(&mut self, name: &str) {
        let m = self.mats.iter().position(|m| m.name == name);
        if m != self.cur.material && !self.cur.tris.is_empty() {
            let next = Pending {
                name: self.cur.name.clone(),
                material: m,
                tris: Vec::new(),
            };
            self.done.push(std::mem::replace(&mut self.cur, next));
        }
        self.cur.material = m;
    }

    /// `mtllib NAME` (trimmed).
    pub fn mtllib(&mut self, name: &str) {
        if let Some(mut m) = (self.load_mtl)(name) {
            self.mats.append(&mut m);
        }
    }

    /// The objects, each with its vertices renumbered from 0 in first-use order (through one
    /// shared table), and the materials.
    pub fn finish(self) -> (Vec<ObjObject>, Vec<ObjMaterial>) {
        let ObjState {
            positions,
            colors,
            mut done,
            cur,
            mats,
            ..
        } = self;
        if !cur.tris.is_empty() {
            done.push(cur);
        }
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
        (objects, mats)
    }
}

/// Parse an OBJ stream. `load_mtl` is called with each `mtllib` argument and returns that
/// library's materials (or nothing, when it cannot be read: geometry stays usable).
///
/// Blocks of whole lines are parsed in parallel (`obj_block`); the result, and the first
/// error with its line, are those of [`read_obj_lines`], the line-by-line reading.
pub fn read_obj(
    r: &mut impl BufRead,
    path: &Path,
    load_mtl: impl FnMut(&str) -> Option<Vec<ObjMaterial>>,
) -> Result<(Vec<ObjObject>, Vec<ObjMaterial>)> {
    crate::obj_block::read_blocks(r, path, load_mtl, crate::obj_block::BLOCK)
}

/// [`read_obj`] one line at a time: the reference the block reader is checked against.
pub fn read_obj_lines(
    r: &mut impl BufRead,
    path: &Path,
    load_mtl: impl FnMut(&str) -> Option<Vec<ObjMaterial>>,
) -> Result<(Vec<ObjObject>, Vec<ObjMaterial>)> {
    let mut state = ObjState::new(path, load_mtl);
    let mut buf = Vec::new();
    let mut line = 0usize;
    while next_line(r, &mut buf, path, line + 1)? {
        line += 1;
        state.line(&buf, line)?;
    }
    Ok(state.finish())
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
