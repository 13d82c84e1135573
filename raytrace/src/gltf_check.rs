//! Reading glTF 2.0 safely: the container (GLB header and chunks), the JSON (through
//! `gltf-json` and the `gltf` crate's own validation) and then every bound the `gltf` crate's
//! readers rely on without checking, before any of its readers runs. The checks follow the
//! glTF 2.0 specification, sections 3.6 (buffers, buffer views, accessors and their data
//! alignment), 3.7 (mesh attribute types), 3.8 (textures/images), 3.11 (animations) and 3.5
//! (node hierarchy: a forest, one parent per node).
//!
//! Buffers are loaded here, not by the `gltf` importer: GLB chunks are checked against the file
//! size, `data:` URIs are decoded, and external files go through
//! [`splatbridge_scene::input`] (regular files only, bounded size). External images are
//! checked the same way before the importer decodes them.
//!
//! Limits (each documented where it is declared): [`MAX_NODE_DEPTH`] and
//! [`MAX_TEXTURE_PIXELS`].

use std::path::{Path, PathBuf};

use gltf::json::accessor::{ComponentType, Type};
use gltf::json::validation::Checked;
use gltf::json::Root;
use splatbridge_scene::input::{self, Cap};

use crate::error::{Result, TraceError};

/// Deepest node hierarchy accepted (root = depth 1). World transforms are resolved
/// recursively, and no exporter we know nests scenes deeper than a few dozen levels; 1 024
/// keeps the recursion far from the stack limit.
pub const MAX_NODE_DEPTH: usize = 1024;

/// Largest texture accepted, in texels (8192²). The tracer keeps four f32 per texel, so one
/// texture costs at most 1 GiB.
pub const MAX_TEXTURE_PIXELS: u64 = 8192 * 8192;

pub(crate) const GLB_MAGIC: &[u8; 4] = b"glTF";
pub(crate) const CHUNK_JSON: u32 = 0x4E4F_534A;
pub(crate) const CHUNK_BIN: u32 = 0x004E_4942;

/// What the `gltf` importer returns, checked.
pub type Import = (
    gltf::Document,
    Vec<gltf::buffer::Data>,
    Vec<gltf::image::Data>,
);

pub(crate) fn bad(name: &Path, what: impl Into<String>) -> TraceError {
    TraceError::format(name, what)
}

pub(crate) fn le32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Split a GLB into its JSON and BIN chunks, checking every length against the bytes present;
/// anything that does not start with the GLB magic is taken as glTF JSON.
fn split_glb<'a>(bytes: &'a [u8], name: &Path) -> Result<(&'a [u8], Option<&'a [u8]>)> {
    if bytes.len() < 4 || &bytes[..4] != GLB_MAGIC {
        return Ok((bytes, None));
    }
    if bytes.len() < 20 {
        return Err(bad(name, "GLB: file is shorter than its 20-byte headers"));
    }
    let version = le32(bytes, 4);
    if version != 2 {
        return Err(bad(name, format!("GLB: version {version}, expected 2")));
    }
    let total = le32(bytes, 8) as usize;
    if total != bytes.len() {
        return Err(bad(
            name,
            format!(
                "GLB: header length {total} differs from the file's {} bytes",
                bytes.len()
            ),
        ));
    }
    let json_len = le32(bytes, 12) as usize;
    if le32(bytes, 16) != CHUNK_JSON {
        return Err(bad(name, "GLB: the first chunk is not JSON"));
    }
    let json_end = 20usize.saturating_add(json_len);
    if json_end > total {
        return Err(bad(
            name,
            format!("GLB: JSON chunk of {json_len} bytes runs past the end of the file"),
        ));
    }
    let json = &bytes[20..json_end];
    let rest = &bytes[json_end..];
    if rest.len() < 8 {
        return Ok((json, None));
    }
    let bin_len = le32(rest, 0) as usize;
    if le32(rest, 4) != CHUNK_BIN {
        // Unknown chunk types are to be ignored (spec 4.4.3.3).
        return Ok((json, None));
    }
    if bin_len > rest.len() - 8 {
        return Err(bad(
            name,
            format!("GLB: BIN chunk of {bin_len} bytes runs past the end of the file"),
        ));
    }
    Ok((json, Some(&rest[8..8 + bin_len])))
}

/// Percent-decode a relative URI to a path (RFC 3986 section 2.1); `None` when an escape is
/// malformed or the result is not UTF-8.
fn percent_decode(uri: &str) -> Option<String> {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Where an external URI points, or an error naming it; `data:` URIs give `None`.
pub(crate) fn external_path(
    uri: &str,
    base: Option<&Path>,
    name: &Path,
    what: &str,
) -> Result<Option<PathBuf>> {
    if uri.starts_with("data:") {
        return Ok(None);
    }
    let shown = input::clip(uri);
    let rel = if let Some(p) = uri.strip_prefix("file://").or(uri.strip_prefix("file:")) {
        PathBuf::from(p)
    } else if uri.contains(':') {
        return Err(bad(
            name,
            format!("{what}: URI '{shown}' has an unsupported scheme"),
        ));
    } else {
        let p = percent_decode(uri).ok_or_else(|| {
            bad(
                name,
                format!("{what}: URI '{shown}' is not valid percent-encoded UTF-8"),
            )
        })?;
        PathBuf::from(p)
    };
    let Some(base) = base else {
        return Err(bad(
            name,
            format!("{what}: external file '{shown}' cannot be resolved for an in-memory glTF"),
        ));
    };
    Ok(Some(base.join(rel)))
}

fn decode_data_uri(uri: &str, name: &Path, what: &str) -> Result<Vec<u8>> {
    let rest = &uri["data:".len()..];
    let Some((_, b64)) = rest.split_once(";base64,") else {
        return Err(bad(name, format!("{what}: data URI is not base64")));
    };
    base64::decode(b64).map_err(|e| bad(name, format!("{what}: data URI: {e}")))
}

/// Load every buffer (GLB blob, data URI or external file) and check it holds its
/// `byteLength`.
///
/// The BIN chunk is moved into the first buffer that uses it, not copied (a GLB's blob is
/// most of the file, and a mesh export's runs to gigabytes); a later buffer naming it too
/// gets a copy of that buffer's bytes.
fn load_buffers(
    root: &Root,
    mut bin: Option<Vec<u8>>,
    base: Option<&Path>,
    name: &Path,
) -> Result<Vec<gltf::buffer::Data>> {
    let mut out: Vec<gltf::buffer::Data> = Vec::with_capacity(root.buffers.len());
    // (buffer holding the BIN chunk, the chunk's length before padding)
    let mut bin_at: Option<(usize, usize)> = None;
    for (i, b) in root.buffers.iter().enumerate() {
        let what = format!("buffer {i}");
        let mut data = match &b.uri {
            None => match (bin.take(), bin_at) {
                (Some(v), _) => {
                    bin_at = Some((i, v.len()));
                    v
                }
                (None, Some((j, len))) => out[j].0[..len].to_vec(),
                (None, None) => {
                    return Err(bad(name, format!("{what}: no URI and no GLB BIN chunk")))
                }
            },
            Some(uri) => match external_path(uri, base, name, &what)? {
                None => decode_data_uri(uri, name, &what)?,
                Some(p) => input::read_bounded(&p, Cap::Mesh)
                    .map_err(|e| bad(name, format!("{what}: {e}")))?,
            },
        };
        let need = b.byte_length.0;
        if (data.len() as u64) < need {
            return Err(bad(
                name,
                format!(
                    "{what}: byteLength {need} but only {} bytes are present",
                    data.len()
                ),
            ));
        }
        while data.len() % 4 != 0 {
            data.push(0);
        }
        out.push(gltf::buffer::Data(data));
    }
    Ok(out)
}

/// Check the bounds and types the `gltf` readers assume; see the module docs.
pub(crate) fn check_document(root: &Root, base: Option<&Path>, name: &Path) -> Result<()> {
    for (i, v) in root.buffer_views.iter().enumerate() {
        let buf = root
            .buffers
            .get(v.buffer.value())
            .ok_or_else(|| bad(name, format!("bufferView {i}: missing buffer")))?;
        let off = v.byte_offset.map_or(0, |o| o.0);
        let end = off.checked_add(v.byte_length.0);
        if end.is_none_or(|e| e > buf.byte_length.0) {
            return Err(bad(
                name,
                format!(
                    "bufferView {i}: bytes {off}..+{} run past buffer {} ({} bytes)",
                    v.byte_length.0,
                    v.buffer.value(),
                    buf.byte_length.0
                ),
            ));
        }
    }
    for i in 0..root.accessors.len() {
        accessor_bounds(root, i, name)?;
    }
    for (mi, m) in root.meshes.iter().enumerate() {
        for (pi, p) in m.primitives.iter().enumerate() {
            use gltf::json::mesh::{Mode, Semantic};
            let what = format!("mesh {mi} primitive {pi}");
            // Every mode: the `gltf` validation indexes attribute accessors unchecked.
            let named = p
                .attributes
                .iter()
                .map(|(sem, acc)| {
                    let attr = match sem {
                        Checked::Valid(sem) => sem.to_string(),
                        Checked::Invalid => "attribute".to_string(),
                    };
                    (attr, acc)
                })
                .chain(p.indices.as_ref().map(|acc| ("indices".to_string(), acc)));
            for (attr, acc) in named {
                if acc.value() >= root.accessors.len() {
                    return Err(bad(
                        name,
                        format!("{what}: {attr}: missing accessor {}", acc.value()),
                    ));
                }
            }
            if !matches!(
                p.mode,
                Checked::Valid(Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan)
            ) {
                continue;
            }
            use ComponentType::{F32, U16, U32, U8};
            if let Some(ix) = &p.indices {
                want(
                    root,
                    ix.value(),
                    name,
                    &format!("{what} indices"),
                    &[Type::Scalar],
                    &[U8, U16, U32],
                )?;
            }
            let mut has_pos = false;
            for (sem, acc) in &p.attributes {
                let at = acc.value();
                match sem {
                    Checked::Valid(Semantic::Positions) => {
                        has_pos = true;
                        want(
                            root,
                            at,
                            name,
                            &format!("{what} POSITION"),
                            &[Type::Vec3],
                            &[F32],
                        )?
                    }
                    Checked::Valid(Semantic::Colors(0)) => want(
                        root,
                        at,
                        name,
                        &format!("{what} COLOR_0"),
                        &[Type::Vec3, Type::Vec4],
                        &[F32, U8, U16],
                    )?,
                    Checked::Valid(Semantic::TexCoords(0)) => want(
                        root,
                        at,
                        name,
                        &format!("{what} TEXCOORD_0"),
                        &[Type::Vec2],
                        &[F32, U8, U16],
                    )?,
                    Checked::Valid(Semantic::Extras(n)) if n == "GAUSSIAN_ID" => want(
                        root,
                        at,
                        name,
                        &format!("{what} _GAUSSIAN_ID"),
                        &[Type::Scalar],
                        &[],
                    )?,
                    _ => {}
                }
            }
            if !has_pos {
                return Err(bad(name, format!("{what}: no POSITION")));
            }
        }
    }
    check_images(root, base, name)?;
    check_nodes(root, name)?;
    check_animations(root, name)
}

fn accessor_bounds(root: &Root, i: usize, name: &Path) -> Result<()> {
    let a = &root.accessors[i];
    let (Checked::Valid(ct), Checked::Valid(ty)) = (&a.component_type, &a.type_) else {
        return Err(bad(
            name,
            format!("accessor {i}: invalid componentType or type"),
        ));
    };
    let Some(view_ix) = &a.buffer_view else {
        return Ok(()); // checked where it is used
    };
    let view = root
        .buffer_views
        .get(view_ix.value())
        .ok_or_else(|| bad(name, format!("accessor {i}: missing bufferView")))?;
    let elem = (ct.0.size() * ty.multiplicity()) as u64;
    let stride = view.byte_stride.map_or(elem, |s| s.0 as u64);
    if stride < elem {
        return Err(bad(
            name,
            format!("accessor {i}: byteStride {stride} is smaller than its {elem}-byte element"),
        ));
    }
    let off = a.byte_offset.map_or(0, |o| o.0);
    let count = a.count.0;
    let need = count
        .checked_sub(1)
        .map_or(Some(0), |c| {
            c.checked_mul(stride).and_then(|x| x.checked_add(elem))
        })
        .and_then(|x| x.checked_add(off));
    if need.is_none_or(|n| n > view.byte_length.0) {
        return Err(bad(
            name,
            format!(
                "accessor {i}: {count} elements of {elem} bytes (stride {stride}, offset {off}) run past bufferView {} ({} bytes)",
                view_ix.value(),
                view.byte_length.0
            ),
        ));
    }
    Ok(())
}

/// An accessor used by a reader: present, backed by a buffer view, not sparse, not empty, of
/// one of the given types and component types (`cts` empty = any).
fn want(
    root: &Root,
    at: usize,
    name: &Path,
    what: &str,
    types: &[Type],
    cts: &[ComponentType],
) -> Result<()> {
    let a = root
        .accessors
        .get(at)
        .ok_or_else(|| bad(name, format!("{what}: missing accessor {at}")))?;
    if a.buffer_view.is_none() || a.sparse.is_some() {
        return Err(bad(
            name,
            format!("{what}: accessor {at} has no bufferView or is sparse (not supported)"),
        ));
    }
    if a.count.0 == 0 {
        return Err(bad(name, format!("{what}: accessor {at} is empty")));
    }
    let ok_ty = matches!(&a.type_, Checked::Valid(t) if types.contains(t));
    let ok_ct =
        matches!(&a.component_type, Checked::Valid(c) if cts.is_empty() || cts.contains(&c.0));
    if !ok_ty || !ok_ct {
        let ty = match &a.type_ {
            Checked::Valid(t) => format!("{t:?}").to_uppercase(),
            Checked::Invalid => "invalid".into(),
        };
        let ct = match &a.component_type {
            Checked::Valid(c) => format!("{:?}", c.0),
            Checked::Invalid => "invalid".into(),
        };
        return Err(bad(
            name,
            format!("{what}: accessor {at} is {ty} of {ct}, expected {types:?} of {cts:?}"),
        ));
    }
    Ok(())
}

fn check_images(root: &Root, base: Option<&Path>, name: &Path) -> Result<()> {
    for (i, img) in root.images.iter().enumerate() {
        let what = format!("image {i}");
        match (&img.uri, &img.buffer_view) {
            (Some(uri), None) => {
                if let Some(p) = external_path(uri, base, name, &what)? {
                    let len =
                        input::check_regular(&p).map_err(|e| bad(name, format!("{what}: {e}")))?;
                    input::check_size(&p, len, Cap::Mesh)
                        .map_err(|e| bad(name, format!("{what}: {e}")))?;
                }
            }
            (None, Some(v)) => {
                if v.value() >= root.buffer_views.len() {
                    return Err(bad(name, format!("{what}: missing bufferView")));
                }
                if img.mime_type.is_none() {
                    return Err(bad(
                        name,
                        format!("{what}: a bufferView image needs a mimeType"),
                    ));
                }
            }
            _ => {
                return Err(bad(
                    name,
                    format!("{what}: needs exactly one of uri and bufferView"),
                ))
            }
        }
    }
    for (i, t) in root.textures.iter().enumerate() {
        if t.source.value() >= root.images.len() {
            return Err(bad(
                name,
                format!("texture {i}: missing image {}", t.source.value()),
            ));
        }
    }
    Ok(())
}

/// The node graph is a forest of bounded depth: children exist, one parent each, no cycle.
/// Linear in the number of nodes.
fn check_nodes(root: &Root, name: &Path) -> Result<()> {
    let n = root.nodes.len();
    let mut parent: Vec<Option<usize>> = vec![None; n];
    for (i, node) in root.nodes.iter().enumerate() {
        for c in node.children.iter().flatten() {
            let c = c.value();
            if c >= n {
                return Err(bad(name, format!("node {i}: child {c} does not exist")));
            }
            if parent[c].is_some() || c == i {
                return Err(bad(
                    name,
                    format!("node {c} has more than one parent or is its own child"),
                ));
            }
            parent[c] = Some(i);
        }
    }
    // Depth by walking down from the roots; nodes never reached are on a cycle.
    let mut depth = vec![0usize; n];
    let mut stack: Vec<usize> = (0..n).filter(|&i| parent[i].is_none()).collect();
    for &r in &stack {
        depth[r] = 1;
    }
    while let Some(i) = stack.pop() {
        if depth[i] > MAX_NODE_DEPTH {
            return Err(bad(
                name,
                format!("node {i}: hierarchy deeper than {MAX_NODE_DEPTH} levels"),
            ));
        }
        for c in root.nodes[i].children.iter().flatten() {
            depth[c.value()] = depth[i] + 1;
            stack.push(c.value());
        }
    }
    if let Some(i) = depth.iter().position(|&d| d == 0) {
        return Err(bad(name, format!("node {i} is part of a parent cycle")));
    }
    Ok(())
}

fn check_animations(root: &Root, name: &Path) -> Result<()> {
    use gltf::json::animation::Property;
    use ComponentType::{F32, I16, I8, U16, U8};
    for (ai, a) in root.animations.iter().enumerate() {
        for (ci, ch) in a.channels.iter().enumerate() {
            let what = format!("animation {ai} channel {ci}");
            let s = a.samplers.get(ch.sampler.value()).ok_or_else(|| {
                bad(
                    name,
                    format!("{what}: missing sampler {}", ch.sampler.value()),
                )
            })?;
            let node = ch.target.node.value();
            if node >= root.nodes.len() {
                return Err(bad(
                    name,
                    format!("{what}: target node {node} does not exist"),
                ));
            }
            let (types, cts): (&[Type], &[ComponentType]) = match &ch.target.path {
                Checked::Valid(Property::Translation | Property::Scale) => (&[Type::Vec3], &[F32]),
                Checked::Valid(Property::Rotation) => (&[Type::Vec4], &[F32, I8, U8, I16, U16]),
                Checked::Valid(Property::MorphTargetWeights) => {
                    (&[Type::Scalar], &[F32, I8, U8, I16, U16])
                }
                Checked::Invalid => {
                    return Err(bad(name, format!("{what}: unknown target path")));
                }
            };
            if !matches!(s.interpolation, Checked::Valid(_)) {
                return Err(bad(name, format!("{what}: unknown interpolation")));
            }
            want(
                root,
                s.input.value(),
                name,
                &format!("{what} input"),
                &[Type::Scalar],
                &[F32],
            )?;
            want(
                root,
                s.output.value(),
                name,
                &format!("{what} output"),
                types,
                cts,
            )?;
        }
    }
    Ok(())
}

/// Parse, validate and import a glTF/GLB held in memory. `base` resolves external URIs (the
/// file's folder; `None` refuses them); `name` names the file in errors.
pub fn import(bytes: &[u8], base: Option<&Path>, name: &Path) -> Result<Import> {
    let (json, bin) = split_glb(bytes, name)?;
    let root = parse_root(json, name)?;
    import_root(root, bin.map(<[u8]>::to_vec), base, name)
}

pub(crate) fn parse_root(json: &[u8], name: &Path) -> Result<Root> {
    Root::from_slice(json).map_err(|e| {
        bad(
            name,
            format!(
                "not a readable glTF: {}",
                input::clip_to(&e.to_string(), 400)
            ),
        )
    })
}

/// The checks, the document and its buffers and images, from the parsed JSON and the GLB's
/// BIN chunk (moved into its buffer).
pub(crate) fn import_root(
    root: Root,
    bin: Option<Vec<u8>>,
    base: Option<&Path>,
    name: &Path,
) -> Result<Import> {
    // Our checks run first: they only use checked lookups, while the `gltf` crate's own
    // validation indexes accessors by attribute without a bound check.
    check_document(&root, base, name)?;
    let doc = document(root, name)?;
    let buffers = load_buffers(doc.as_json(), bin, base, name)?;
    let images = import_images(&doc, base, &buffers, name)?;
    Ok((doc, buffers, images))
}

/// The `gltf` crate's validation of a checked document, except one rule the crate adds to the
/// specification: an accessor with neither `bufferView` nor `sparse` is all zeros (glTF 2.0
/// §3.6.2.1, "When undefined, the accessor MUST be initialized with zeros"), as a morph target
/// of a frame equal to the base is written; the crate reports its `bufferView` missing.
pub(crate) fn document(root: Root, name: &Path) -> Result<gltf::Document> {
    use gltf::json::validation::{Error, Validate};
    let zero = |i: usize| {
        root.accessors
            .get(i)
            .is_some_and(|a| a.buffer_view.is_none() && a.sparse.is_none())
    };
    let mut errors = Vec::new();
    root.validate(&root, gltf::json::Path::new, &mut |path, error| {
        let p = path();
        let exempt = matches!(error, Error::Missing)
            && p.as_str()
                .strip_prefix("accessors[")
                .and_then(|r| r.strip_suffix("].bufferView"))
                .and_then(|i| i.parse::<usize>().ok())
                .is_some_and(zero);
        if !exempt {
            errors.push((p, error));
        }
    });
    if !errors.is_empty() {
        let e = gltf::Error::Validation(errors);
        return Err(bad(
            name,
            format!("not a valid glTF: {}", input::clip_to(&e.to_string(), 400)),
        ));
    }
    Ok(gltf::Document::from_json_without_validation(root))
}

/// Decode the document's images (the `gltf` importer), refusing textures over
/// [`MAX_TEXTURE_PIXELS`].
pub(crate) fn import_images(
    doc: &gltf::Document,
    base: Option<&Path>,
    buffers: &[gltf::buffer::Data],
    name: &Path,
) -> Result<Vec<gltf::image::Data>> {
    let images = gltf::import_images(doc, base, buffers).map_err(|e| {
        bad(
            name,
            format!("image: {}", input::clip_to(&e.to_string(), 400)),
        )
    })?;
    for (i, img) in images.iter().enumerate() {
        if img.width as u64 * img.height as u64 > MAX_TEXTURE_PIXELS {
            return Err(bad(
                name,
                format!(
                    "image {i}: {}×{} texels, more than the {MAX_TEXTURE_PIXELS} accepted",
                    img.width, img.height
                ),
            ));
        }
    }
    Ok(images)
}

/// The folder external URIs of `path` resolve in (`.` for a bare name).
pub(crate) fn folder(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// [`import`] for a file: read it (regular file, bounded) and resolve URIs beside it.
pub fn import_path(path: &Path) -> Result<Import> {
    let bytes = input::read_bounded(path, Cap::Mesh)?;
    import_vec(bytes, Some(&folder(path)), path)
}

/// [`import`] taking the bytes over: a GLB's BIN chunk becomes its buffer in place (the blob
/// is shifted to the front of the allocation and the rest cut off), so the file is held once,
/// not twice; an export's blob is most of its gigabytes.
pub fn import_vec(mut bytes: Vec<u8>, base: Option<&Path>, name: &Path) -> Result<Import> {
    let (root, bin) = {
        let (json, bin) = split_glb(&bytes, name)?;
        let at = |s: &[u8]| s.as_ptr() as usize - bytes.as_ptr() as usize;
        (parse_root(json, name)?, bin.map(|b| (at(b), b.len())))
    };
    let bin = bin.map(|(start, len)| {
        bytes.copy_within(start..start + len, 0);
        bytes.truncate(len);
        bytes
    });
    import_root(root, bin, base, name)
}
