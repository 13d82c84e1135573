//! Tilesets of binary PLY files larger than memory: an external bucket sort by leaf, so
//! memory is bounded by the partition's per-Gaussian state and a tile, not the decoded cloud.
//!
//! 1. Partition pass: the file is read in chunks and only a skeleton of each valid Gaussian
//!    is kept (centre, scale, rotation, opacity, degree-0 colour: 56 bytes instead of 248 for
//!    SH degree 3), which is all [`Blocks::build`] reads (centres for the octree, covariances
//!    for the footprints).
//! 2. Bucket pass: the file is read again and each valid record's raw bytes are appended to
//!    its leaf's bucket file (buffered per leaf, [`BUCKET_BUFFERS`] in total).
//! 3. Tiles: the depth-first writer of the in-memory path, whose leaves decode their bucket
//!    (then delete it) instead of copying out of a cloud.
//!
//! Records reach a leaf in file order, which is the order the stable partition gives the
//! in-memory path, and they are decoded by the same decoder, so the tileset is byte-identical
//! to [`super::write_tileset`] on the same file.

use std::io::Write;
use std::path::{Path, PathBuf};

use splatbridge_scene::blocks::Blocks;
use splatbridge_scene::ply::PlyStream;
use splatbridge_scene::GaussianCloud;

use super::{write_blocks, ErrorMeter, Source, TileOptions, TilesetReport};
use crate::{scene_err, ConvertError, Result};

/// Records per chunk of the two passes (4 MB of SH-3 records).
const CHUNK: usize = 16_384;
/// Bytes of bucket data buffered over all leaves before appending to the bucket files.
const BUCKET_BUFFERS: usize = 256 << 20;

/// The bucket files of a streamed tileset.
pub(super) struct Buckets<'a> {
    dir: PathBuf,
    stream: &'a PlyStream,
}

impl Buckets<'_> {
    fn path(dir: &Path, block: usize) -> PathBuf {
        dir.join(format!("leaf_{block}"))
    }

    /// Leaf `block`'s Gaussians; its bucket file is deleted.
    pub(super) fn take(&self, block: usize) -> Result<GaussianCloud> {
        let path = Self::path(&self.dir, block);
        let bytes = std::fs::read(&path).map_err(|e| ConvertError::Io {
            path: path.clone(),
            err: e,
        })?;
        let cloud = self.stream.decode(&bytes, &path).map_err(scene_err)?;
        drop(bytes);
        std::fs::remove_file(&path).map_err(|e| ConvertError::Io { path, err: e })?;
        Ok(cloud)
    }
}

/// A scratch directory removed (with its contents) when dropped, on success and on error.
struct TempDir(PathBuf);

impl TempDir {
    fn new(path: PathBuf) -> Result<TempDir> {
        // A directory left by a killed run with the same process id is stale.
        let _ = std::fs::remove_dir_all(&path);
        std::fs::create_dir(&path).map_err(|e| ConvertError::Io {
            path: path.clone(),
            err: e,
        })?;
        Ok(TempDir(path))
    }

    fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn append(dir: &Path, block: usize, buf: &mut Vec<u8>) -> Result<()> {
    let path = Buckets::path(dir, block);
    std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .and_then(|mut f| f.write_all(buf))
        .map_err(|e| ConvertError::Io { path, err: e })?;
    buf.clear();
    Ok(())
}

/// [`super::write_tileset`] of a binary PLY read in two streaming passes (see the module
/// documentation); `Ok(None)` for an ASCII PLY (read it whole instead). Invalid Gaussians
/// are an error naming the vertex, or left out with `drop_invalid`, as when reading whole.
pub fn write_tileset_from_ply(
    dir: &Path,
    ply: &Path,
    drop_invalid: bool,
    opts: &TileOptions,
    meter: &mut ErrorMeter<'_>,
) -> Result<Option<TilesetReport>> {
    let Some(mut s) = PlyStream::open(ply, drop_invalid).map_err(scene_err)? else {
        return Ok(None);
    };
    let mut skeleton = GaussianCloud::with_capacity(0, s.len());
    while let Some(c) = s.next_chunk(CHUNK, None).map_err(scene_err)? {
        for i in 0..c.len() {
            skeleton.push(
                c.means[i],
                c.log_scales[i],
                c.rotations[i],
                c.opacity_logits[i],
                &c.sh_of(i)[..1],
            );
        }
    }
    let blocks = Blocks::build(&skeleton, opts.max_per_tile);
    let kept = skeleton.len();
    drop(skeleton);
    // Each kept Gaussian's leaf (its block index); u32::MAX for those the partition leaves out.
    let mut leaf_of = vec![u32::MAX; kept];
    for (b, block) in blocks.blocks.iter().enumerate() {
        if block.is_leaf() {
            for &i in blocks.indices(block) {
                leaf_of[i as usize] = b as u32;
            }
        }
    }
    std::fs::create_dir_all(dir).map_err(|e| ConvertError::Io {
        path: dir.into(),
        err: e,
    })?;
    let tmp = TempDir::new(dir.join(format!(".tile-buckets-{}", std::process::id())))?;
    let mut s = PlyStream::open(ply, drop_invalid)
        .map_err(scene_err)?
        .ok_or_else(|| ConvertError::Format {
            path: ply.into(),
            what: "the file changed between the partition and the bucket pass".into(),
        })?;
    let stride = s.stride();
    let leaves = blocks.leaves().count().max(1);
    let cap = (BUCKET_BUFFERS / leaves).max(stride);
    let mut bufs: Vec<Vec<u8>> = vec![Vec::new(); blocks.blocks.len()];
    let mut raw = Vec::new();
    let mut j = 0usize;
    while s
        .next_chunk(CHUNK, Some(&mut raw))
        .map_err(scene_err)?
        .is_some()
    {
        for rec in raw.chunks_exact(stride) {
            let b = leaf_of
                .get(j)
                .copied()
                .ok_or_else(|| ConvertError::Format {
                    path: ply.into(),
                    what: "the file changed between the partition and the bucket pass".into(),
                })?;
            j += 1;
            if b == u32::MAX {
                continue;
            }
            let b = b as usize;
            bufs[b].extend_from_slice(rec);
            if bufs[b].len() >= cap {
                append(tmp.path(), b, &mut bufs[b])?;
            }
        }
        raw.clear();
    }
    if j != kept {
        return Err(ConvertError::Format {
            path: ply.into(),
            what: "the file changed between the partition and the bucket pass".into(),
        });
    }
    for (b, buf) in bufs.iter_mut().enumerate() {
        if !buf.is_empty() {
            append(tmp.path(), b, buf)?;
        }
    }
    drop(bufs);
    drop(leaf_of);
    let buckets = Buckets {
        dir: tmp.path().to_path_buf(),
        stream: &s,
    };
    let report = write_blocks(dir, &blocks, Source::Buckets(&buckets), 0, opts, meter)?;
    Ok(Some(report))
}
