//! The glTF container: a GLB's JSON and BIN chunks or a `.gltf` with external buffers, and
//! accessors read as f32 tuples. Every size in the JSON is checked against the bytes that
//! exist before anything sized by it is allocated.
//!
//! Only the JSON is held in memory. Binary buffers (a GLB's BIN chunk, a `.gltf`'s `.bin`
//! files) stay in their files: an accessor is read block by block from its byte range
//! (seek + read) and handed element by element to the caller, which stores it in its final
//! place, and an SPZ buffer view is read on its own. So a float GLB's peak is the cloud plus
//! one block, not the file plus the cloud.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::error::{Result, SceneError};
use crate::formats::regular_file_len;

pub(super) const FLOAT: u64 = 5126;
pub(super) const UNSIGNED_BYTE: u64 = 5121;
pub(super) const UNSIGNED_SHORT: u64 = 5123;

/// Bytes read per block of an accessor.
const BLOCK: usize = 256 << 10;

/// A binary buffer: `len` bytes of `file` from `offset`.
struct Buffer {
    file: File,
    /// The file, for errors.
    path: PathBuf,
    offset: u64,
    len: u64,
}

/// A loaded document: the JSON, and where every buffer's bytes are.
pub(super) struct Document {
    pub json: Value,
    buffers: Vec<Buffer>,
}

/// An accessor whose whole extent has been checked against its buffer view.
pub(super) struct Accessor {
    pub count: u64,
    /// Bytes per component (4: FLOAT, 1 or 2: normalized integers).
    size: usize,
    comps: usize,
    buffer: usize,
    /// Absolute offset of the first element within the buffer.
    start: u64,
    stride: usize,
}

/// The largest glTF file: GLB holds its length in a u32, so 4 GiB.
const MAX_FILE: u64 = u32::MAX as u64;

fn open(path: &Path) -> Result<File> {
    File::open(path).map_err(|e| SceneError::io(path, e))
}

fn read_at(file: &File, path: &Path, offset: u64, buf: &mut [u8]) -> Result<()> {
    let mut f = file;
    f.seek(SeekFrom::Start(offset))
        .and_then(|_| f.read_exact(buf))
        .map_err(|e| SceneError::io(path, e))
}

/// Split a GLB into its JSON and BIN chunks, or read a `.gltf` and find its buffers.
pub(super) fn load(path: &Path) -> Result<Document> {
    let bad = |what: String| SceneError::format(path, what);
    let file_len = regular_file_len(path)?;
    if file_len > MAX_FILE {
        return Err(bad(format!(
            "file is {file_len} bytes, more than the {MAX_FILE} bytes this format can need"
        )));
    }
    let file = open(path)?;
    let mut magic = [0u8; 4];
    let is_glb = file_len >= 4 && {
        read_at(&file, path, 0, &mut magic)?;
        &magic == b"glTF"
    };
    let (json, mut bin) = if is_glb {
        let u32at = |o: u64| -> Result<u32> {
            if o + 4 > file_len {
                return Err(bad(format!("GLB truncated at byte {o}")));
            }
            let mut b = [0u8; 4];
            read_at(&file, path, o, &mut b)?;
            Ok(u32::from_le_bytes(b))
        };
        let version = u32at(4)?;
        if version != 2 {
            return Err(bad(format!(
                "GLB version {version}; glTF 2.0 GLB is version 2"
            )));
        }
        let declared = u64::from(u32at(8)?);
        if declared != file_len {
            return Err(bad(format!(
                "GLB header length {declared} is not the file's {file_len} bytes"
            )));
        }
        let mut o = 12u64;
        let (mut json, mut bin) = (None, None);
        while o + 8 <= file_len {
            let len = u32at(o)? as u64;
            let mut ty = [0u8; 4];
            read_at(&file, path, o + 4, &mut ty)?;
            let body = o + 8;
            if body + len > file_len {
                return Err(bad(format!("GLB chunk at byte {o} runs past the end")));
            }
            match &ty {
                b"JSON" if json.is_none() => {
                    // Within the file (checked above), so its size is the file's to justify.
                    let mut j = vec![0u8; len as usize];
                    read_at(&file, path, body, &mut j)?;
                    json = Some(j);
                }
                b"BIN\0" if bin.is_none() => bin = Some((body, len)),
                _ => {}
            }
            o = body + len;
        }
        (
            json.ok_or_else(|| bad("GLB has no JSON chunk".into()))?,
            bin,
        )
    } else {
        drop(file);
        (super::super::read_file_capped(path, MAX_FILE)?, None)
    };
    let v: Value = serde_json::from_slice(&json).map_err(|e| bad(format!("glTF JSON: {e}")))?;
    drop(json);
    let mut buffers = Vec::new();
    for (i, b) in v["buffers"].as_array().into_iter().flatten().enumerate() {
        let declared = b["byteLength"].as_u64().unwrap_or(0);
        match b["uri"].as_str() {
            None => {
                let (offset, len) = bin.take().ok_or_else(|| {
                    bad(format!(
                        "buffer {i} has no uri and there is no (unused) GLB BIN chunk"
                    ))
                })?;
                buffers.push(Buffer {
                    file: open(path)?,
                    path: path.to_path_buf(),
                    offset,
                    len,
                });
            }
            Some(uri) if uri.starts_with("data:") => {
                return Err(bad(format!("buffer {i}: data URIs are not supported")))
            }
            Some(uri) => {
                let p = path.parent().unwrap_or(Path::new(".")).join(uri);
                // A buffer file may be padded; anything much longer than declared is not it.
                let cap = declared.saturating_add(4096);
                let len = regular_file_len(&p)?;
                if len > cap {
                    return Err(SceneError::format(
                        &p,
                        format!(
                            "file is {len} bytes, more than the {cap} bytes this format can need"
                        ),
                    ));
                }
                buffers.push(Buffer {
                    file: open(&p)?,
                    path: p,
                    offset: 0,
                    len,
                });
            }
        }
    }
    Ok(Document { json: v, buffers })
}

impl Document {
    /// Buffer view `view` as (buffer index, offset in the buffer, length), bounds-checked.
    fn view_range(&self, path: &Path, view: u64) -> Result<(usize, u64, u64)> {
        let bad = |what: String| SceneError::format(path, what);
        let bv = self.json["bufferViews"]
            .get(view as usize)
            .ok_or_else(|| bad(format!("bufferView {view} does not exist")))?;
        let b = bv["buffer"].as_u64().unwrap_or(0);
        let buf = self
            .buffers
            .get(b as usize)
            .ok_or_else(|| bad(format!("bufferView {view}: buffer {b} does not exist")))?;
        let off = bv["byteOffset"].as_u64().unwrap_or(0);
        let len = bv["byteLength"]
            .as_u64()
            .ok_or_else(|| bad(format!("bufferView {view} has no byteLength")))?;
        off.checked_add(len)
            .filter(|&end| end <= buf.len)
            .map(|_| (b as usize, off, len))
            .ok_or_else(|| {
                bad(format!(
                    "bufferView {view} (bytes {off}..{}) lies outside buffer {b} ({} bytes)",
                    off.saturating_add(len),
                    buf.len
                ))
            })
    }

    /// The bytes of buffer view `view`, bounds-checked and read from the file.
    pub(super) fn view_bytes(&self, path: &Path, view: u64) -> Result<Vec<u8>> {
        let (b, off, len) = self.view_range(path, view)?;
        let buf = &self.buffers[b];
        let mut out = Vec::new();
        out.try_reserve_exact(len as usize).map_err(|_| {
            SceneError::format(
                path,
                format!("cannot allocate bufferView {view}'s {len} bytes"),
            )
        })?;
        out.resize(len as usize, 0);
        read_at(&buf.file, &buf.path, buf.offset + off, &mut out)?;
        Ok(out)
    }

    /// An accessor's declared element count.
    pub(super) fn accessor_count(&self, path: &Path, a: u64) -> Result<u64> {
        self.json["accessors"]
            .get(a as usize)
            .and_then(|acc| acc["count"].as_u64())
            .ok_or_else(|| SceneError::format(path, format!("accessor {a} has no count")))
    }

    /// Accessor `a` read as tuples of `comps` (FLOAT, or normalized u8/u16), its whole extent
    /// checked against its buffer view, so a lying `count` is refused before the caller
    /// allocates anything for it.
    pub(super) fn accessor(&self, path: &Path, a: u64, comps: usize) -> Result<Accessor> {
        let bad = |what: String| SceneError::format(path, what);
        let acc = self.json["accessors"]
            .get(a as usize)
            .ok_or_else(|| bad(format!("accessor {a} does not exist")))?;
        let count = self.accessor_count(path, a)?;
        // The accessor's type must have the components the attribute needs (a VEC2 POSITION
        // would otherwise be read as VEC3 across element boundaries).
        let want = match comps {
            1 => "SCALAR",
            2 => "VEC2",
            3 => "VEC3",
            _ => "VEC4",
        };
        let ty = acc["type"].as_str().unwrap_or("");
        if ty != want {
            return Err(bad(format!(
                "accessor {a}: type {} where {want} is needed",
                crate::input::clip(ty)
            )));
        }
        let ct = acc["componentType"].as_u64().unwrap_or(0);
        let size = match ct {
            FLOAT => 4usize,
            UNSIGNED_BYTE => 1,
            UNSIGNED_SHORT => 2,
            _ => {
                return Err(bad(format!(
                    "accessor {a}: component type {ct} is not read (FLOAT, normalized u8/u16)"
                )))
            }
        };
        let view = acc["bufferView"]
            .as_u64()
            .ok_or_else(|| bad(format!("accessor {a} has no bufferView")))?;
        let (buffer, view_off, view_len) = self.view_range(path, view)?;
        let base = acc["byteOffset"].as_u64().unwrap_or(0);
        let elem = (size * comps) as u64;
        let stride = self.json["bufferViews"][view as usize]["byteStride"]
            .as_u64()
            .unwrap_or(elem);
        if stride < elem {
            return Err(bad(format!(
                "accessor {a}: byteStride {stride} is shorter than an element ({elem} bytes)"
            )));
        }
        count
            .checked_sub(1)
            .map_or(Some(0), |last| {
                last.checked_mul(stride)
                    .and_then(|x| x.checked_add(base))
                    .and_then(|x| x.checked_add(elem))
            })
            .filter(|&e| e <= view_len)
            .ok_or_else(|| {
                bad(format!(
                    "accessor {a}: {count} elements do not fit in bufferView {view} ({view_len} bytes)"
                ))
            })?;
        Ok(Accessor {
            count,
            size,
            comps,
            buffer,
            start: view_off + base,
            stride: stride as usize,
        })
    }

    /// Call `f` with each element of `acc` in order (`comps` values, normalized integers
    /// mapped to [0, 1]), reading the buffer block by block.
    pub(super) fn for_each(&self, acc: &Accessor, mut f: impl FnMut(&[f32])) -> Result<()> {
        let buf = &self.buffers[acc.buffer];
        let elem = acc.size * acc.comps;
        let per_block = (BLOCK / acc.stride).max(1);
        let mut block = Vec::new();
        let mut vals = [0.0f32; 4];
        let mut done = 0u64;
        while done < acc.count {
            let m = (per_block as u64).min(acc.count - done) as usize;
            // The last element of a block needs only its own bytes, not a whole stride.
            let len = (m - 1) * acc.stride + elem;
            block.resize(len, 0);
            let at = buf.offset + acc.start + done * acc.stride as u64;
            read_at(&buf.file, &buf.path, at, &mut block)?;
            for i in 0..m {
                let e = &block[i * acc.stride..i * acc.stride + elem];
                for (c, v) in vals[..acc.comps].iter_mut().enumerate() {
                    let b = &e[c * acc.size..(c + 1) * acc.size];
                    *v = match acc.size {
                        4 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                        1 => b[0] as f32 / 255.0,
                        _ => u16::from_le_bytes([b[0], b[1]]) as f32 / 65535.0,
                    };
                }
                f(&vals[..acc.comps]);
            }
            done += m as u64;
        }
        Ok(())
    }

    /// Read accessor `a` whole as f32 tuples of `comps` (small accessors: animation keys).
    pub(super) fn read_accessor(&self, path: &Path, a: u64, comps: usize) -> Result<Vec<f32>> {
        let acc = self.accessor(path, a, comps)?;
        let mut out = Vec::with_capacity(acc.count as usize * comps);
        self.for_each(&acc, |v| out.extend_from_slice(v))?;
        Ok(out)
    }
}
