//! A GLB file read back one accessor at a time: the tracer's loader holds the triangle scene it
//! builds and the bytes of the one accessor it is reading, never the whole BIN chunk beside the
//! scene (an export's BIN chunk is most of its gigabytes, and the scene built from it is about
//! as large again).
//!
//! The document is rewritten before the `gltf` crate sees it (glTF 2.0 §3.6): every accessor
//! gets a buffer view and a buffer of its own that span exactly its bytes in the BIN chunk
//! (the view keeps the original byte stride, the accessor's offset becomes 0), and every image
//! stored in a buffer view gets its own buffer likewise. The values read are therefore the
//! values of the original document, byte for byte; [`Buffers::with_accessors`] reads an
//! accessor's span from the file just before it is read and drops it after.
//!
//! Only the plain case is streamed: a GLB whose single buffer is its BIN chunk, or a `.gltf`
//! whose single buffer is one external file (what `convert -o x.gltf` writes, and the only
//! form of a mesh over GLB's 4 GiB), with no sparse accessors, no matrix accessors (their
//! columns are padded) and no buffer-view extensions (meshopt). Anything else, and every glTF
//! given as bytes, is read whole by [`crate::gltf_check`], whose checks run first on the
//! original document in every case.
//!
//! The whole-file size cap (`input::Cap::Mesh`) bounds what one read allocates; a streamed
//! external buffer is never read whole, and each accessor's span is checked against the
//! buffer's declared length, which must fit in the file, so it is not held to that cap.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use gltf::json::accessor::Type;
use gltf::json::validation::Checked;
use gltf::json::{buffer, Index, Root};
use splatbridge_scene::input::{self, Cap};

use crate::error::{Result, TraceError};
use crate::gltf_check::{self, bad, le32, Import, CHUNK_BIN, CHUNK_JSON, GLB_MAGIC};

/// Where a streamed buffer's bytes are in the file.
struct Source {
    file: File,
    name: PathBuf,
    /// Per buffer of the rewritten document: (offset in the file, length).
    spans: Vec<(u64, u64)>,
}

/// The buffers of a document: all in memory, or read from the file one accessor at a time.
pub struct Buffers {
    data: Vec<gltf::buffer::Data>,
    source: Option<Source>,
}

impl Buffers {
    /// Buffers held whole (in memory, shared by any number of accessors).
    pub fn whole(data: Vec<gltf::buffer::Data>) -> Self {
        Buffers { data, source: None }
    }

    /// Make buffer `b` readable (a streamed buffer is read from the file).
    fn ensure(&mut self, b: usize) -> Result<()> {
        let Some(src) = &mut self.source else {
            return Ok(());
        };
        let (Some(&(at, len)), Some(slot)) = (src.spans.get(b), self.data.get_mut(b)) else {
            return Ok(());
        };
        if slot.0.len() as u64 == len {
            return Ok(());
        }
        let fail = |e: std::io::Error| {
            TraceError::format(
                &src.name,
                format!("cannot read buffer bytes {at}+{len}: {e}"),
            )
        };
        let mut bytes = vec![0u8; len as usize];
        src.file.seek(SeekFrom::Start(at)).map_err(fail)?;
        src.file.read_exact(&mut bytes).map_err(fail)?;
        slot.0 = bytes;
        Ok(())
    }

    /// Drop a streamed buffer's bytes (no-op for buffers held whole).
    fn release(&mut self, b: usize) {
        if self.source.is_some() {
            if let Some(slot) = self.data.get_mut(b) {
                slot.0 = Vec::new();
            }
        }
    }

    /// Run `read` with the buffers of `accs` readable, then drop what was streamed for them
    /// (also when `read` fails): every accessor read goes through here.
    pub fn with_accessors<T>(
        &mut self,
        accs: &[&gltf::Accessor],
        read: impl FnOnce(&Buffers) -> Result<T>,
    ) -> Result<T> {
        let ids: Vec<usize> = accs
            .iter()
            .filter_map(|a| a.view().map(|v| v.buffer().index()))
            .collect();
        let out = ids
            .iter()
            .try_for_each(|&b| self.ensure(b))
            .and_then(|()| read(self));
        for b in ids {
            self.release(b);
        }
        out
    }

    /// Whether the buffers are read from the file an accessor at a time (not held whole).
    pub fn is_streamed(&self) -> bool {
        self.source.is_some()
    }

    /// Buffer `b`'s bytes, if readable.
    pub fn get(&self, b: usize) -> Option<&[u8]> {
        self.data.get(b).map(|d| &d.0[..])
    }
}

/// A checked document with its buffers and decoded images.
pub type StreamedImport = (gltf::Document, Buffers, Vec<gltf::image::Data>);

/// Import a glTF/GLB file: a plain GLB or `.gltf` streamed (see the module documentation),
/// anything else read whole with [`gltf_check`]'s checks. A file that is not a plain GLB is
/// read once: its bytes go to the whole-file reader, or its parsed JSON to [`open_gltf`].
pub fn import_path(path: &Path) -> Result<StreamedImport> {
    if let Some(x) = open_glb(path)? {
        return Ok(x);
    }
    let bytes = input::read_bounded(path, Cap::Mesh)?;
    let base = gltf_check::folder(path);
    if bytes.starts_with(GLB_MAGIC) {
        return Ok(whole(gltf_check::import_vec(bytes, Some(&base), path)?));
    }
    let root = gltf_check::parse_root(&bytes, path)?;
    drop(bytes);
    open_gltf(root, &base, path)
}

/// A JSON glTF: streamed when its one buffer is an external file (and the document is plain),
/// else read whole.
fn open_gltf(root: Root, base: &Path, path: &Path) -> Result<StreamedImport> {
    match external_buffer(&root, base, path)? {
        Some((file, bin)) => stream(root, path, base, file, &bin, 0),
        None => Ok(whole(gltf_check::import_root(
            root,
            None,
            Some(base),
            path,
        )?)),
    }
}

/// The opened file of a checked, plain document's one external buffer, or `None` for any
/// other layout.
fn external_buffer(root: &Root, base: &Path, path: &Path) -> Result<Option<(File, PathBuf)>> {
    let uri = match &root.buffers[..] {
        [b] => match &b.uri {
            Some(u) if !u.starts_with("data:") => u,
            _ => return Ok(None),
        },
        _ => return Ok(None),
    };
    gltf_check::check_document(root, Some(base), path)?;
    let Some(bin) = gltf_check::external_path(uri, Some(base), path, "buffer 0")? else {
        return Ok(None);
    };
    let (file, bin_len) =
        input::open_regular(&bin).map_err(|e| bad(path, format!("buffer 0: {e}")))?;
    Ok(plain(root, bin_len, true).then_some((file, bin)))
}

fn whole(import: Import) -> StreamedImport {
    (import.0, Buffers::whole(import.1), import.2)
}

/// The streamed import, or `None` when the file is not a plain GLB.
fn open_glb(path: &Path) -> Result<Option<StreamedImport>> {
    let (mut file, len) = input::open_regular(path)?;
    input::check_size(path, len, Cap::Mesh)?;
    let io = |e: std::io::Error| bad(path, format!("cannot read: {e}"));
    let mut head = [0u8; 20];
    if len < 28 {
        return Ok(None);
    }
    file.read_exact(&mut head).map_err(io)?;
    // Anything unusual in the container is left to the whole-file reader's checks and errors.
    if &head[..4] != GLB_MAGIC || le32(&head, 4) != 2 || le32(&head, 8) as u64 != len {
        return Ok(None);
    }
    let json_len = le32(&head, 12) as u64;
    if le32(&head, 16) != CHUNK_JSON || 20 + json_len + 8 > len {
        return Ok(None);
    }
    let mut json = vec![0u8; json_len as usize];
    file.read_exact(&mut json).map_err(io)?;
    let mut chunk = [0u8; 8];
    file.read_exact(&mut chunk).map_err(io)?;
    let bin_len = le32(&chunk, 0) as u64;
    let bin_start = 20 + json_len + 8;
    if le32(&chunk, 4) != CHUNK_BIN || bin_len > len - bin_start {
        return Ok(None);
    }
    let root = gltf_check::parse_root(&json, path)?;
    let base = gltf_check::folder(path);
    gltf_check::check_document(&root, Some(&base), path)?;
    if !plain(&root, bin_len, false) {
        // Rare layouts: read whole, with the whole reader's own checks.
        let bytes = input::read_bounded(path, Cap::Mesh)?;
        return Ok(Some(whole(gltf_check::import_vec(
            bytes,
            Some(&base),
            path,
        )?)));
    }
    stream(root, path, &base, file, path, bin_start).map(Some)
}

/// The streamed import of a checked, plain document whose buffer's bytes start at `bin_start`
/// in `file` (named `file_name` in read errors).
fn stream(
    root: Root,
    path: &Path,
    base: &Path,
    file: File,
    file_name: &Path,
    bin_start: u64,
) -> Result<StreamedImport> {
    let (root, spans) = rewrite(root, bin_start);
    let doc = gltf_check::document(root, path)?;
    let mut buffers = Buffers {
        data: (0..spans.len())
            .map(|_| gltf::buffer::Data(Vec::new()))
            .collect(),
        source: Some(Source {
            file,
            name: file_name.to_path_buf(),
            spans,
        }),
    };
    // Images stored in buffer views are decoded now (the importer needs their bytes), then
    // their buffers are dropped.
    let image_buffers: Vec<usize> = doc
        .images()
        .filter_map(|i| match i.source() {
            gltf::image::Source::View { view, .. } => Some(view.buffer().index()),
            gltf::image::Source::Uri { .. } => None,
        })
        .collect();
    for &b in &image_buffers {
        buffers.ensure(b)?;
    }
    let images = gltf_check::import_images(&doc, Some(base), &buffers.data, path)?;
    for &b in &image_buffers {
        buffers.release(b);
    }
    Ok((doc, buffers, images))
}

/// Whether the document can be streamed: one buffer (the BIN chunk, or an external file when
/// `external`) holding its declared length; no sparse or matrix accessors; no buffer-view
/// extensions.
fn plain(root: &Root, bin_len: u64, external: bool) -> bool {
    let [b] = &root.buffers[..] else {
        return false;
    };
    b.uri.is_some() == external
        && b.byte_length.0 <= bin_len
        && root.buffer_views.iter().all(|v| v.extensions.is_none())
        && root.accessors.iter().all(|a| {
            a.sparse.is_none()
                && matches!(
                    a.type_,
                    Checked::Valid(Type::Scalar | Type::Vec2 | Type::Vec3 | Type::Vec4)
                )
                && matches!(a.component_type, Checked::Valid(_))
        })
}

/// Give every accessor and every buffer-view image a view and buffer of their own spanning
/// exactly their bytes; returns the document and each new buffer's (file offset, length).
/// The caller checked the document first (`gltf_check`), so every span lies in the BIN chunk.
fn rewrite(mut root: Root, bin_start: u64) -> (Root, Vec<(u64, u64)>) {
    let views = std::mem::take(&mut root.buffer_views);
    let mut spans = Vec::new();
    let mut new_views = Vec::new();
    let mut add = |view: &buffer::View, start: u64, len: u64| -> Index<buffer::View> {
        let b = spans.len();
        spans.push((bin_start + start, len));
        let mut v = view.clone();
        v.buffer = Index::new(b as u32);
        v.byte_offset = None;
        // A zero-length buffer is not valid glTF; a one-byte buffer is never read (count 0).
        v.byte_length = len.max(1).into();
        new_views.push(v);
        Index::new(new_views.len() as u32 - 1)
    };
    for a in &mut root.accessors {
        let Some(vi) = a.buffer_view else { continue };
        let view = &views[vi.value()];
        let (Checked::Valid(ct), Checked::Valid(ty)) = (&a.component_type, &a.type_) else {
            continue;
        };
        let elem = (ct.0.size() * ty.multiplicity()) as u64;
        let stride = view.byte_stride.map_or(elem, |s| s.0 as u64);
        let count = a.count.0;
        let len = if count == 0 {
            0
        } else {
            (count - 1) * stride + elem
        };
        let start = view.byte_offset.map_or(0, |o| o.0) + a.byte_offset.map_or(0, |o| o.0);
        a.buffer_view = Some(add(view, start, len));
        a.byte_offset = None;
    }
    for img in &mut root.images {
        let Some(vi) = img.buffer_view else { continue };
        let view = &views[vi.value()];
        let start = view.byte_offset.map_or(0, |o| o.0);
        let mut v = view.clone();
        v.byte_stride = None;
        img.buffer_view = Some(add(&v, start, view.byte_length.0));
    }
    let bin = root.buffers[0].clone();
    root.buffers = spans
        .iter()
        .map(|&(_, len)| buffer::Buffer {
            byte_length: len.max(1).into(),
            ..bin.clone()
        })
        .collect();
    root.buffer_views = new_views;
    (root, spans)
}
