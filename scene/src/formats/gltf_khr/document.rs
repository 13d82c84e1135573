//! The glTF container: a GLB's JSON and BIN chunks or a `.gltf` with external buffers, and
//! accessors read as f32 tuples. Every size in the JSON is checked against the bytes that
//! exist before anything sized by it is allocated.

use std::path::Path;

use serde_json::Value;

use crate::error::{Result, SceneError};

pub(super) const FLOAT: u64 = 5126;
pub(super) const UNSIGNED_BYTE: u64 = 5121;
pub(super) const UNSIGNED_SHORT: u64 = 5123;

/// A loaded document: the JSON and every buffer's bytes.
pub(super) struct Document {
    pub json: Value,
    pub buffers: Vec<Vec<u8>>,
}

/// The largest glTF file read whole: GLB holds its binary chunk in a u32 length, so 4 GiB.
const MAX_FILE: u64 = u32::MAX as u64;

/// Split a GLB into its JSON and BIN chunks, or read a `.gltf` and its buffers.
pub(super) fn load(path: &Path) -> Result<Document> {
    let bad = |what: String| SceneError::format(path, what);
    let data = super::super::read_file_capped(path, MAX_FILE)?;
    let (json, mut bin) = if data.starts_with(b"glTF") {
        let u32at = |o: usize| -> Result<u32> {
            data.get(o..o + 4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .ok_or_else(|| bad(format!("GLB truncated at byte {o}")))
        };
        let version = u32at(4)?;
        if version != 2 {
            return Err(bad(format!(
                "GLB version {version}; glTF 2.0 GLB is version 2"
            )));
        }
        let declared = u32at(8)? as usize;
        if declared != data.len() {
            return Err(bad(format!(
                "GLB header length {declared} is not the file's {} bytes",
                data.len()
            )));
        }
        let mut o = 12usize;
        let (mut json, mut bin) = (None, None);
        while o + 8 <= data.len() {
            let len = u32at(o)? as usize;
            let ty = &data[o + 4..o + 8];
            let body = o
                .checked_add(8 + len)
                .and_then(|end| data.get(o + 8..end))
                .ok_or_else(|| bad(format!("GLB chunk at byte {o} runs past the end")))?;
            match ty {
                b"JSON" if json.is_none() => json = Some(body),
                b"BIN\0" if bin.is_none() => bin = Some(body.to_vec()),
                _ => {}
            }
            o += 8 + len;
        }
        (
            json.ok_or_else(|| bad("GLB has no JSON chunk".into()))?
                .to_vec(),
            bin,
        )
    } else {
        (data, None)
    };
    let v: Value = serde_json::from_slice(&json).map_err(|e| bad(format!("glTF JSON: {e}")))?;
    drop(json);
    let mut buffers = Vec::new();
    for (i, b) in v["buffers"].as_array().into_iter().flatten().enumerate() {
        let declared = b["byteLength"].as_u64().unwrap_or(0);
        match b["uri"].as_str() {
            None => buffers.push(bin.take().ok_or_else(|| {
                bad(format!(
                    "buffer {i} has no uri and there is no (unused) GLB BIN chunk"
                ))
            })?),
            Some(uri) if uri.starts_with("data:") => {
                return Err(bad(format!("buffer {i}: data URIs are not supported")))
            }
            Some(uri) => {
                let p = path.parent().unwrap_or(Path::new(".")).join(uri);
                // A buffer file may be padded; anything much longer than declared is not it.
                let cap = declared.saturating_add(4096);
                buffers.push(super::super::read_file_capped(&p, cap)?);
            }
        }
    }
    Ok(Document { json: v, buffers })
}

impl Document {
    /// The bytes of buffer view `view`, bounds-checked.
    pub(super) fn view_bytes(&self, path: &Path, view: u64) -> Result<&[u8]> {
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
            .filter(|&end| end <= buf.len() as u64)
            .map(|end| &buf[off as usize..end as usize])
            .ok_or_else(|| {
                bad(format!(
                    "bufferView {view} (bytes {off}..{}) lies outside buffer {b} ({} bytes)",
                    off.saturating_add(len),
                    buf.len()
                ))
            })
    }

    /// An accessor's declared element count.
    pub(super) fn accessor_count(&self, path: &Path, a: u64) -> Result<u64> {
        self.json["accessors"]
            .get(a as usize)
            .and_then(|acc| acc["count"].as_u64())
            .ok_or_else(|| SceneError::format(path, format!("accessor {a} has no count")))
    }

    /// Read accessor `a` as f32 tuples of `comps` (FLOAT, or normalized u8/u16). The whole
    /// extent is checked against the buffer view before the output is allocated, so a lying
    /// `count` cannot allocate more than the buffer holds.
    pub(super) fn read_accessor(&self, path: &Path, a: u64, comps: usize) -> Result<Vec<f32>> {
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
        let bytes = self.view_bytes(path, view)?;
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
            .filter(|&e| e <= bytes.len() as u64)
            .ok_or_else(|| {
                bad(format!(
                    "accessor {a}: {count} elements do not fit in bufferView {view} ({} bytes)",
                    bytes.len()
                ))
            })?;
        let (base, stride) = (base as usize, stride as usize);
        let mut out = Vec::with_capacity(count as usize * comps);
        for i in 0..count as usize {
            let e = &bytes[base + i * stride..base + i * stride + elem as usize];
            for c in 0..comps {
                let b = &e[c * size..(c + 1) * size];
                out.push(match size {
                    4 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                    1 => b[0] as f32 / 255.0,
                    _ => u16::from_le_bytes([b[0], b[1]]) as f32 / 65535.0,
                });
            }
        }
        Ok(out)
    }
}
