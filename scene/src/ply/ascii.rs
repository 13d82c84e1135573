//! ASCII vertex data: one vertex per line, values separated by whitespace. Numbers parse with
//! Rust's float grammar, which also reads `inf`, `-inf` and `nan` in any case, so everything
//! the writer prints reads back.

use std::io::BufRead;
use std::path::Path;

use super::header::{Header, Layout, ScalarType, MAX_SLOTS, SLOT_REST};
use super::push_slots;
use crate::error::{Result, SceneError};
use crate::GaussianCloud;

/// Decode `n` vertex lines (the caller has bounded `n` by the data size). The flag is true
/// when some record may be invalid (see `push_slots`).
pub(crate) fn read_ascii(
    r: &mut impl BufRead,
    path: &Path,
    header: &Header,
    layout: &Layout,
    n: usize,
) -> Result<(GaussianCloud, bool)> {
    let err = |what: String| SceneError::format(path, what);
    let nprops = header.properties.len();
    // Per property: the canonical slot it fills, if used.
    let mut prop_slot: Vec<Option<usize>> = vec![None; nprops];
    for (slot, &(_, pi, _)) in layout.slots.iter().enumerate() {
        prop_slot[pi] = Some(slot);
    }
    let var = layout.variant.as_deref();
    // A non-standard layout reads its properties into `raw` and assembles the record.
    let mut raw = vec![0f64; nprops];
    if let Some(var) = var {
        for &(pi, _, _) in &var.props {
            prop_slot[pi] = Some(usize::MAX);
        }
    }
    let n_rest = match var {
        Some(var) => var.slots.len() - SLOT_REST,
        None => layout.slots.len() - SLOT_REST,
    };
    let mut cloud = GaussianCloud::with_capacity(layout.sh_degree, n);
    let mut v = [0f32; MAX_SLOTS];
    let mut line = Vec::new();
    let mut suspect = false;
    for i in 0..n {
        let lineno = header.lines + i + 1;
        line.clear();
        let got = r
            .read_until(b'\n', &mut line)
            .map_err(|e| SceneError::io(path, e))?;
        if got == 0 {
            return Err(err(format!(
                "line {lineno}: the file ends after {i} of {n} vertices"
            )));
        }
        let text = std::str::from_utf8(&line)
            .map_err(|_| err(format!("line {lineno} (vertex {i}) is not text")))?;
        let mut count = 0;
        for (pi, tok) in text.split_ascii_whitespace().enumerate() {
            count += 1;
            if pi >= nprops {
                continue;
            }
            if let Some(slot) = prop_slot[pi] {
                let p = &header.properties[pi];
                let value = match (p.ty, slot) {
                    (_, usize::MAX) => tok.parse::<f64>().ok().map(|x| {
                        raw[pi] = x;
                        0.0
                    }),
                    (ScalarType::F64, _) => tok.parse::<f64>().map(|x| x as f32).ok(),
                    _ => tok.parse::<f32>().ok(),
                };
                let value = value.ok_or_else(|| {
                    let preview: String = tok.chars().take(24).collect();
                    err(format!(
                        "line {lineno} (vertex {i}): property '{}': '{}' is not a number",
                        p.name,
                        preview.escape_debug()
                    ))
                })?;
                if slot != usize::MAX {
                    v[slot] = value;
                }
            }
        }
        if count != nprops {
            return Err(err(format!(
                "line {lineno} (vertex {i}): expected {nprops} values, found {count}"
            )));
        }
        if let Some(var) = var {
            var.assemble(&raw, &mut v);
        }
        suspect |= push_slots(&mut cloud, &v, n_rest);
    }
    Ok((cloud, suspect))
}
