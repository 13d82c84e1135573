//! PLY header parsing and the mapping from the file's vertex properties to the 3DGS values.
//!
//! The header grammar follows the PLY format (Turk, 1994): a `ply` magic line, one `format`
//! line, `element NAME COUNT` lines each followed by its `property TYPE NAME` lines, comments,
//! and `end_header`. 3DGS files hold a single `vertex` element; this reader requires it to be
//! the first element (elements after it are reported and ignored) and requires its properties
//! to be scalars, since list properties have no fixed record size.

use std::io::{BufRead, Read};
use std::path::Path;

use crate::error::{Result, SceneError};

/// Longest header accepted; real 3DGS headers are about 1.5 KB, so anything past this is not a
/// header (a binary file without newlines, for instance) and is rejected before it is buffered.
const MAX_HEADER_BYTES: u64 = 1 << 20;

/// Data encoding named by the `format` line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Encoding {
    Ascii,
    BinaryLe,
    BinaryBe,
}

/// PLY scalar types (both the classic and the sized spellings).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ScalarType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl ScalarType {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => ScalarType::I8,
            "uchar" | "uint8" => ScalarType::U8,
            "short" | "int16" => ScalarType::I16,
            "ushort" | "uint16" => ScalarType::U16,
            "int" | "int32" => ScalarType::I32,
            "uint" | "uint32" => ScalarType::U32,
            "float" | "float32" => ScalarType::F32,
            "double" | "float64" => ScalarType::F64,
            _ => return None,
        })
    }

    pub(crate) fn size(self) -> usize {
        match self {
            ScalarType::I8 | ScalarType::U8 => 1,
            ScalarType::I16 | ScalarType::U16 => 2,
            ScalarType::I32 | ScalarType::U32 | ScalarType::F32 => 4,
            ScalarType::F64 => 8,
        }
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            ScalarType::I8 => "char",
            ScalarType::U8 => "uchar",
            ScalarType::I16 => "short",
            ScalarType::U16 => "ushort",
            ScalarType::I32 => "int",
            ScalarType::U32 => "uint",
            ScalarType::F32 => "float",
            ScalarType::F64 => "double",
        }
    }
}

/// One scalar property of the vertex element, with its byte offset in a binary record.
#[derive(Clone, Debug)]
pub(crate) struct Property {
    pub name: String,
    pub ty: ScalarType,
    pub offset: usize,
}

/// The parsed header.
#[derive(Clone, Debug)]
pub(crate) struct Header {
    pub encoding: Encoding,
    pub vertex_count: u64,
    pub properties: Vec<Property>,
    /// Bytes per binary vertex record.
    pub stride: usize,
    /// Bytes from the start of the file through the `end_header` line's newline.
    pub len: u64,
    /// Number of header lines (ASCII data line numbers continue from here).
    pub lines: usize,
    /// Elements declared after `vertex` (name, count); not read.
    pub trailing_elements: Vec<(String, u64)>,
}

/// Parse the header from the start of `r`, leaving `r` positioned at the first data byte.
pub(crate) fn parse_header(r: &mut impl BufRead, path: &Path) -> Result<Header> {
    let err = |what: String| SceneError::format(path, what);
    let mut line = Vec::new();
    let mut len = 0u64;
    let mut lineno = 0usize;
    let mut encoding = None;
    // Declared elements in order; properties belong to the last one.
    let mut elements: Vec<(String, u64)> = Vec::new();
    let mut properties: Vec<Property> = Vec::new();
    let mut stride = 0usize;

    loop {
        line.clear();
        let n = (&mut *r)
            .take(MAX_HEADER_BYTES - len)
            .read_until(b'\n', &mut line)
            .map_err(|e| SceneError::io(path, e))? as u64;
        len += n;
        lineno += 1;
        if n == 0 {
            if lineno == 1 {
                return Err(err("empty file (no PLY header)".into()));
            }
            if len >= MAX_HEADER_BYTES {
                return Err(err(format!(
                    "no end_header line in the first {MAX_HEADER_BYTES} bytes (not a PLY header)"
                )));
            }
            return Err(err(format!(
                "header has no end_header line (file ends after {lineno_read} header lines)",
                lineno_read = lineno - 1
            )));
        }
        if line.last() != Some(&b'\n') && len >= MAX_HEADER_BYTES {
            return Err(err(format!(
                "no end_header line in the first {MAX_HEADER_BYTES} bytes (not a PLY header)"
            )));
        }
        let text = match std::str::from_utf8(&line) {
            Ok(t) => t.trim_end_matches(['\n', '\r']),
            Err(_) if lineno == 1 => {
                return Err(err("not a PLY file: the first line is not 'ply'".into()));
            }
            Err(_) => return Err(err(format!("header line {lineno} is not text"))),
        };
        if lineno == 1 {
            if text.trim() != "ply" {
                let preview: String = text.chars().take(24).collect();
                return Err(err(format!(
                    "not a PLY file: the first line is '{}', not 'ply'",
                    preview.escape_debug()
                )));
            }
            continue;
        }
        let mut tok = text.split_ascii_whitespace();
        // Names and counts are echoed in messages; a megabyte-long token is shown clipped.
        let clip = crate::input::clip;
        let Some(keyword) = tok.next() else {
            continue; // blank lines are tolerated
        };
        let rest: Vec<&str> = tok.collect();
        match keyword {
            "comment" | "obj_info" => {}
            "format" => {
                if encoding.is_some() {
                    return Err(err(format!("header line {lineno}: second format line")));
                }
                let enc = match rest.first().copied() {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::BinaryLe,
                    Some("binary_big_endian") => Encoding::BinaryBe,
                    other => {
                        return Err(err(format!(
                            "header line {lineno}: unknown format '{}' (expected ascii, binary_little_endian or binary_big_endian)",
                            crate::input::clip(other.unwrap_or(""))
                        )))
                    }
                };
                if rest.get(1).copied() != Some("1.0") || rest.len() != 2 {
                    return Err(err(format!(
                        "header line {lineno}: format line must be 'format {} 1.0', found '{}'",
                        rest[0],
                        crate::input::clip(text)
                    )));
                }
                encoding = Some(enc);
            }
            "element" => {
                let [name, count] = rest[..] else {
                    return Err(err(format!(
                        "header line {lineno}: expected 'element NAME COUNT', found '{}'",
                        crate::input::clip(text)
                    )));
                };
                let count: u64 = count.parse().map_err(|_| {
                    err(format!(
                        "header line {lineno}: element '{}' count '{}' is not a non-negative integer",
                        clip(name),
                        clip(count)
                    ))
                })?;
                if elements.is_empty() && name != "vertex" {
                    return Err(err(format!(
                        "header line {lineno}: the first element is '{}'; a 3DGS PLY starts with the 'vertex' element",
                        clip(name)
                    )));
                }
                if name == "vertex" && !elements.is_empty() {
                    return Err(err(format!(
                        "header line {lineno}: second 'vertex' element"
                    )));
                }
                elements.push((name.to_string(), count));
            }
            "property" => {
                if elements.is_empty() {
                    return Err(err(format!(
                        "header line {lineno}: property declared before any element"
                    )));
                }
                let in_vertex = elements.len() == 1;
                if rest.first().copied() == Some("list") {
                    if in_vertex {
                        let name = rest.last().copied().unwrap_or("?");
                        return Err(err(format!(
                            "header line {lineno}: vertex property '{}' is a list; 3DGS vertex properties are scalars",
                            clip(name)
                        )));
                    }
                    continue;
                }
                let [ty, name] = rest[..] else {
                    return Err(err(format!(
                        "header line {lineno}: expected 'property TYPE NAME', found '{}'",
                        crate::input::clip(text)
                    )));
                };
                if !in_vertex {
                    continue;
                }
                let ty = ScalarType::parse(ty).ok_or_else(|| {
                    err(format!(
                        "header line {lineno}: property '{}' has unsupported type '{}'",
                        clip(name),
                        clip(ty)
                    ))
                })?;
                if properties.iter().any(|p| p.name == name) {
                    return Err(err(format!(
                        "header line {lineno}: vertex property '{}' declared twice",
                        clip(name)
                    )));
                }
                properties.push(Property {
                    name: name.to_string(),
                    ty,
                    offset: stride,
                });
                stride += ty.size();
            }
            "end_header" => {
                let encoding =
                    encoding.ok_or_else(|| err("header has no format line".to_string()))?;
                let Some((_, vertex_count)) = elements.first().cloned() else {
                    return Err(err("header declares no 'vertex' element".to_string()));
                };
                return Ok(Header {
                    encoding,
                    vertex_count,
                    properties,
                    stride,
                    len,
                    lines: lineno,
                    trailing_elements: elements.split_off(1),
                });
            }
            other => {
                let preview: String = other.chars().take(24).collect();
                return Err(err(format!(
                    "header line {lineno}: unknown keyword '{}'",
                    preview.escape_debug()
                )));
            }
        }
    }
}

/// Canonical slot order of the 3DGS values a record is decoded into.
pub(crate) const SLOT_X: usize = 0;
pub(crate) const SLOT_SCALE: usize = 3;
pub(crate) const SLOT_ROT: usize = 6;
pub(crate) const SLOT_OPACITY: usize = 10;
pub(crate) const SLOT_DC: usize = 11;
pub(crate) const SLOT_REST: usize = 14;
/// Slots for SH degree 3 (45 `f_rest`).
pub(crate) const MAX_SLOTS: usize = SLOT_REST + 45;

/// Property name of a canonical slot.
pub(crate) fn slot_name(slot: usize) -> String {
    const FIXED: [&str; SLOT_REST] = [
        "x", "y", "z", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
        "opacity", "f_dc_0", "f_dc_1", "f_dc_2",
    ];
    if slot < SLOT_REST {
        FIXED[slot].to_string()
    } else {
        format!("f_rest_{}", slot - SLOT_REST)
    }
}

/// Where each canonical slot lives in a record.
#[derive(Clone, Debug)]
pub(crate) struct Layout {
    pub sh_degree: u8,
    /// Per slot: (byte offset in a binary record, property index, type). Length `14 + n_rest`.
    pub slots: Vec<(usize, usize, ScalarType)>,
    /// Vertex properties not used (normals excluded: they are part of the standard layout and
    /// carry no information for splatting).
    pub ignored: Vec<String>,
    /// A non-standard layout (colours, 2DGS, Mip-Splatting, points), read by the general
    /// path; `slots` is then empty.
    pub variant: Option<Box<super::variant::Variant>>,
}

/// Map the vertex properties to canonical slots by name, inferring the SH degree from the
/// number of `f_rest_*` properties.
pub(crate) fn layout(header: &Header, path: &Path) -> Result<Layout> {
    let err = |what: String| SceneError::format(path, what);
    let mut rest: Vec<(usize, usize)> = Vec::new(); // (f_rest index, property index)
    let mut fixed: [Option<usize>; SLOT_REST] = [None; SLOT_REST];
    let mut ignored = Vec::new();
    for (pi, p) in header.properties.iter().enumerate() {
        if let Some(slot) = (0..SLOT_REST).find(|&s| slot_name(s) == p.name) {
            fixed[slot] = Some(pi);
        } else if let Some(idx) = p
            .name
            .strip_prefix("f_rest_")
            .and_then(|s| s.parse::<usize>().ok())
        {
            rest.push((idx, pi));
        } else if !matches!(p.name.as_str(), "nx" | "ny" | "nz") {
            ignored.push(p.name.clone());
        }
    }
    let n_rest = rest.len();
    let sh_degree = match n_rest {
        0 => 0,
        9 => 1,
        24 => 2,
        45 => 3,
        k => {
            return Err(err(format!(
                "the vertex has {k} f_rest properties; 3DGS needs 0, 9, 24 or 45 (SH degree 0 to 3)"
            )))
        }
    };
    rest.sort_unstable();
    for (want, &(idx, _)) in rest.iter().enumerate() {
        if idx != want {
            return Err(err(format!(
                "f_rest properties must be numbered 0..{}: f_rest_{want} is missing",
                n_rest - 1
            )));
        }
    }
    let rest_pis: Vec<usize> = rest.iter().map(|&(_, pi)| pi).collect();
    if let Some(v) = super::variant::variant(header, &fixed, &rest_pis, path)? {
        let used = |name: &String| {
            v.props
                .iter()
                .any(|&(pi, _, _)| &header.properties[pi].name == name)
        };
        ignored.retain(|n| !used(n));
        return Ok(Layout {
            sh_degree,
            slots: Vec::new(),
            ignored,
            variant: Some(Box::new(v)),
        });
    }
    let mut slots = Vec::with_capacity(SLOT_REST + n_rest);
    for (slot, pi) in fixed.iter().enumerate() {
        let pi =
            pi.ok_or_else(|| err(format!("vertex property '{}' is missing", slot_name(slot))))?;
        slots.push(pi);
    }
    slots.extend(rest.iter().map(|&(_, pi)| pi));
    let slots = slots
        .into_iter()
        .map(|pi| {
            let p = &header.properties[pi];
            match p.ty {
                ScalarType::F32 | ScalarType::F64 => Ok((p.offset, pi, p.ty)),
                t => Err(err(format!(
                    "vertex property '{}' has type {}; 3DGS values must be float (float32) or double (float64)",
                    p.name,
                    t.name()
                ))),
            }
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(Layout {
        sh_degree,
        slots,
        ignored,
        variant: None,
    })
}
