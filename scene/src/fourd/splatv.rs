//! `.splatv`, the splaTV viewer's packed form of a SpacetimeGaussians lite model
//! (antimatter15/splaTV, `hybrid.js`: `main`'s `chunkHandler` and `readChunks`, the vertex
//! shader).
//!
//! Layout: `u32 0x674b` (magic), `u32` length of a UTF-8 JSON array of chunk descriptions
//! (`{"type": "splat", "size": BYTES, "texwidth": W, "texheight": H, "cameras": [...]}`),
//! then each chunk's bytes in order. A `splat` chunk is an RGBA32UI texture of 16 little-endian
//! `u32` (64 bytes) per Gaussian (`vertexCount = byteLength / 4 / 16` in the worker):
//!
//! | words | field |
//! |---|---|
//! | 0..3 | position x, y, z (f32 bits) |
//! | 3, 4 | rotation (half2: `rot_0, rot_1`), (half2: `rot_2, rot_3`) |
//! | 5, 6 | linear scales (half2: `exp(scale_0), exp(scale_1)`), (half2: `exp(scale_2), 0`) |
//! | 7 | RGBA bytes: `clamp(f_dc·255)`, `sigmoid(opacity)·255` |
//! | 8..12 | motion_0..7 (half2 each), 12: (half2: `motion_8, 0`) |
//! | 13, 14 | omega_0..3 (half2 each) |
//! | 15 | (half2: `trbf_center, exp(trbf_scale)`) |
//!
//! The shader at time `t` (the viewer plays `t = sin(now)/2 + 1/2`, so [0, 1]):
//! `dt = t − trbf.x`, `topacity = exp(−(dt/trbf.y)²)` and the Gaussian is skipped when
//! `topacity < 0.02`; position `xyz + (m0,m1,m2)·dt + (m3,m4,m5)·dt·dt + (m6,m7,m8)·dt·dt·dt`;
//! rotation `(rot + omega·dt)/‖·‖`; alpha `A/255 · topacity`; colour `RGB/255` directly.
//! Those are [`SpacetimeModel::sample`]'s formulas with [`SpacetimeModel::cutoff`] = 0.02.
//!
//! All-zero records (the padding of the texture's last row) are skipped. Other chunk types
//! are skipped by their declared size.

use std::path::Path;

use glam::{Quat, Vec3};
use half::f16;

use super::SpacetimeModel;
use crate::error::{Result, SceneError};

/// The first `u32` of a `.splatv` file.
pub const MAGIC: u32 = 0x674b;
/// Bytes per Gaussian.
pub const RECORD: usize = 64;
/// Longest JSON chunk list accepted (real files: well under 100 KB with cameras).
const MAX_JSON: u64 = 16 << 20;
/// The temporal opacity under which splaTV's shader does not draw a Gaussian.
pub const CUTOFF: f32 = 0.02;

/// Does a buffer start like a `.splatv`?
pub fn plausible(head: &[u8]) -> bool {
    head.len() >= 9 && head[..4] == MAGIC.to_le_bytes() && head[8] == b'['
}

/// Read a `.splatv` file. Sizes (JSON length, chunk sizes) are checked against the file's
/// length before anything is allocated.
pub fn read_splatv(path: &Path) -> Result<SpacetimeModel> {
    let err = |what: String| SceneError::format(path, what);
    let len = super::super::formats::regular_file_len(path)?;
    let bytes = super::super::formats::read_file_capped(path, len)?;
    if bytes.len() < 8 || bytes[..4] != MAGIC.to_le_bytes() {
        return Err(err(format!(
            "not a .splatv file (expected magic 0x{MAGIC:x} in the first 4 bytes)"
        )));
    }
    let json_len = u32::from_le_bytes(bytes[4..8].try_into().unwrap()) as u64;
    if json_len > MAX_JSON || 8 + json_len > bytes.len() as u64 {
        return Err(err(format!(
            "chunk list declared as {json_len} bytes but the file has {} bytes after the magic",
            bytes.len() - 8
        )));
    }
    let json = &bytes[8..8 + json_len as usize];
    let chunks: serde_json::Value = serde_json::from_slice(json)
        .map_err(|e| err(format!("chunk list is not valid JSON: {e}")))?;
    let chunks = chunks
        .as_array()
        .ok_or_else(|| err("chunk list is not a JSON array".into()))?;
    let mut at = 8 + json_len;
    let mut model = None;
    for (k, c) in chunks.iter().enumerate() {
        let size = c
            .get("size")
            .and_then(|s| s.as_u64())
            .ok_or_else(|| err(format!("chunks[{k}] has no integer 'size'")))?;
        let end = at.checked_add(size).filter(|&e| e <= bytes.len() as u64);
        let Some(end) = end else {
            return Err(err(format!(
                "chunks[{k}] declares {size} bytes at offset {at} but the file has {} bytes",
                bytes.len()
            )));
        };
        if c.get("type").and_then(|t| t.as_str()) == Some("splat") {
            if model.is_some() {
                return Err(err(format!("chunks[{k}]: a second 'splat' chunk")));
            }
            if size % RECORD as u64 != 0 {
                return Err(err(format!(
                    "chunks[{k}]: splat chunk of {size} bytes is not a whole number of \
                     {RECORD}-byte Gaussians"
                )));
            }
            model = Some(decode(&bytes[at as usize..end as usize], path)?);
        }
        at = end;
    }
    model.ok_or_else(|| err("no 'splat' chunk in the chunk list".into()))
}

fn decode(data: &[u8], path: &Path) -> Result<SpacetimeModel> {
    let mut m = SpacetimeModel {
        cutoff: Some(CUTOFF),
        ..Default::default()
    };
    let word = |r: &[u8], i: usize| u32::from_le_bytes(r[4 * i..4 * i + 4].try_into().unwrap());
    let halves = |w: u32| {
        (
            f16::from_bits(w as u16).to_f32(),
            f16::from_bits((w >> 16) as u16).to_f32(),
        )
    };
    for (i, r) in data.chunks_exact(RECORD).enumerate() {
        if r.iter().all(|&b| b == 0) {
            continue;
        }
        let pos = Vec3::new(
            f32::from_bits(word(r, 0)),
            f32::from_bits(word(r, 1)),
            f32::from_bits(word(r, 2)),
        );
        let (r0, r1) = halves(word(r, 3));
        let (r2, r3) = halves(word(r, 4));
        let (s0, s1) = halves(word(r, 5));
        let (s2, _) = halves(word(r, 6));
        let rgba = word(r, 7).to_le_bytes();
        let mut mo = [0f32; 10];
        for j in 0..5 {
            let (a, b) = halves(word(r, 8 + j));
            mo[2 * j] = a;
            mo[2 * j + 1] = b;
        }
        let (o0, o1) = halves(word(r, 13));
        let (o2, o3) = halves(word(r, 14));
        let (center, width) = halves(word(r, 15));
        let values = [
            pos.x, pos.y, pos.z, r0, r1, r2, r3, s0, s1, s2, mo[0], mo[1], mo[2], mo[3], mo[4],
            mo[5], mo[6], mo[7], mo[8], o0, o1, o2, o3, center, width,
        ];
        if values.iter().any(|v| !v.is_finite()) {
            return Err(SceneError::format(
                path,
                format!("Gaussian {i}: a value is not finite"),
            ));
        }
        if !(s0 > 0.0 && s1 > 0.0 && s2 > 0.0) {
            return Err(SceneError::format(
                path,
                format!("Gaussian {i}: scales {s0}, {s1}, {s2} are not all positive"),
            ));
        }
        m.means.push(pos);
        m.rotations.push(Quat::from_xyzw(r1, r2, r3, r0));
        m.log_scales.push(Vec3::new(s0.ln(), s1.ln(), s2.ln()));
        m.colors
            .push(Vec3::new(rgba[0] as f32, rgba[1] as f32, rgba[2] as f32) / 255.0);
        m.opacity.push(rgba[3] as f32 / 255.0);
        m.motion.push([
            Vec3::new(mo[0], mo[1], mo[2]),
            Vec3::new(mo[3], mo[4], mo[5]),
            Vec3::new(mo[6], mo[7], mo[8]),
        ]);
        m.omegas.push(Quat::from_xyzw(o1, o2, o3, o0));
        m.trbf_center.push(center);
        m.trbf_width.push(width);
    }
    Ok(m)
}
