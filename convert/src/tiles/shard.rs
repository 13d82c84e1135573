//! Sharded tilesets of a binary PLY: N processes each encode the leaves they own, and a final
//! run builds the parents and `tileset.json` from their outputs, byte for byte what one run
//! writes.
//!
//! - Work key: a leaf's octree path from the root ([`leaf_keys`]: the octant of each cell in
//!   its parent's, `5/2/0`), which names the same cell in every shard because every shard
//!   runs the same deterministic partition pass. Which shard owns a key is the caller's
//!   [`LeafOwner`] (the root crate hashes it with its fixed FNV-1a, `src/shard.rs`).
//! - A shard ([`write_shard`]) runs the partition pass, the bucket pass for its own leaves
//!   only, and writes per owned leaf `tile_B.glb` (the tile one run writes) and `leaf_B.rec`
//!   (the leaf's raw PLY records, which the parents are merged from), and [`MANIFEST`]
//!   listing them, into its own directory, all or nothing.
//! - The final run ([`write_from_shards`]) runs the partition pass again, checks that the
//!   shards are one run's complete set (same tool version, same partition of the same
//!   records under the same options, every index 0..N once, every leaf present once and in
//!   the shard that owns it, every file of the size listed), then walks the tree as one run
//!   does, taking each leaf's GLB and records from its shard instead of encoding it. Leaves
//!   decode through the same decoder from the same bytes, so parents, errors and
//!   `tileset.json` are those of one run.
//!
//! The partition fingerprint is a 64-bit FNV-1a over the kept records' bytes, the partition
//! (every block's depth, children, range and boxes) and the options' debug text; it guards
//! against mixing shards of different inputs or options, not against tampering.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use splatbridge_scene::blocks::Blocks;
use splatbridge_scene::output::OutputSet;
use splatbridge_scene::ply::PlyStream;
use splatbridge_scene::GaussianCloud;

use super::stream;
use super::{encode_glb, write_blocks, ErrorMeter, Source, TileOptions, TilesetReport};
use crate::{scene_err, ConvertError, Result};

/// The `format` of a shard's manifest.
pub const SHARD_FORMAT: &str = "splatbridge-tiles-shard/1";
/// The manifest's file name in a shard's directory.
pub const MANIFEST: &str = "shard.json";

/// The shard (0-based) of a count that owns a leaf, given its key.
pub type LeafOwner<'a> = dyn Fn(&str, u32) -> u32 + Sync + 'a;

/// One leaf a shard wrote.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq, Eq)]
pub struct ShardLeaf {
    /// Block index (pre-order), the `N` of `tile_N.glb`.
    pub block: usize,
    /// Octree path ([`leaf_keys`]).
    pub key: String,
    pub glb_bytes: u64,
    pub record_bytes: u64,
}

/// A shard's `shard.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ShardManifest {
    pub format: String,
    pub version: String,
    pub index: u32,
    pub count: u32,
    /// The partition fingerprint (module documentation), 16 hex digits.
    pub partition: String,
    pub leaves: Vec<ShardLeaf>,
}

/// 64-bit FNV-1a (offset basis 0xcbf29ce484222325, prime 0x100000001b3).
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

/// Every block's octree path: the root's is empty; a child's is its parent's followed by
/// the octant (0–7: bit a set when the child's cell lies on the high side of the parent's
/// centre along axis a) of its cell, joined by `/`.
pub fn leaf_keys(blocks: &Blocks) -> Vec<String> {
    let mut keys = vec![String::new(); blocks.blocks.len()];
    // Pre-order: a parent's key is set before its children's.
    for (b, block) in blocks.blocks.iter().enumerate() {
        let mid = block.cell.centre();
        for &c in &block.children {
            let cc = blocks.blocks[c].cell.centre();
            let octant = (0..3).fold(0u32, |k, a| k | (u32::from(cc[a] > mid[a]) << a));
            keys[c] = if keys[b].is_empty() {
                octant.to_string()
            } else {
                format!("{}/{octant}", keys[b])
            };
        }
    }
    keys
}

/// The partition pass with the fingerprint of the records, the partition and the options.
fn fingerprinted_partition(
    ply: &Path,
    drop_invalid: bool,
    opts: &TileOptions,
) -> Result<(Blocks, usize, String)> {
    let not_binary = || {
        ConvertError::Format {
        path: ply.into(),
        what: "--shard and --from-shards need a binary PLY (ASCII PLY and other formats are read whole: convert them without shards)".into(),
    }
    };
    let mut h = Fnv::new();
    let (blocks, kept) = stream::partition(
        ply,
        drop_invalid,
        opts.max_per_tile,
        Some(&mut |b| h.write(b)),
    )?
    .ok_or_else(not_binary)?;
    h.write(&(kept as u64).to_le_bytes());
    for b in &blocks.blocks {
        h.write(&b.depth.to_le_bytes());
        for &c in &b.children {
            h.write(&(c as u64).to_le_bytes());
        }
        h.write(&(b.range.start as u64).to_le_bytes());
        h.write(&(b.range.end as u64).to_le_bytes());
        for bx in [b.cell, b.centres, b.footprint] {
            for v in bx.min.to_array().into_iter().chain(bx.max.to_array()) {
                h.write(&v.to_bits().to_le_bytes());
            }
        }
    }
    h.write(format!("{opts:?}").as_bytes());
    Ok((blocks, kept, format!("{:016x}", h.0)))
}

/// What a shard wrote.
#[derive(Clone, Debug, Default)]
pub struct ShardReport {
    pub leaves: usize,
    pub total_leaves: usize,
    pub gaussians: usize,
    pub files: usize,
    pub bytes: u64,
}

fn io(path: PathBuf) -> impl FnOnce(std::io::Error) -> ConvertError {
    move |err| ConvertError::Io { path, err }
}

/// Shard `index` of `count` of the tileset of `ply` (see the module documentation), into
/// `dir`: the owned leaves' GLBs and records, and [`MANIFEST`].
pub fn write_shard(
    dir: &Path,
    ply: &Path,
    drop_invalid: bool,
    opts: &TileOptions,
    (index, count): (u32, u32),
    owner: &LeafOwner<'_>,
) -> Result<ShardReport> {
    let (blocks, kept, partition) = fingerprinted_partition(ply, drop_invalid, opts)?;
    let keys = leaf_keys(&blocks);
    let owned: Vec<usize> = (0..blocks.blocks.len())
        .filter(|&b| blocks.blocks[b].is_leaf() && owner(&keys[b], count) == index)
        .collect();
    let tmp = stream::scratch(dir)?;
    let mut s = stream::reopen(ply, drop_invalid)?;
    let is_owned = |b: usize| owned.binary_search(&b).is_ok();
    let buckets = stream::bucket_pass(
        tmp.path(),
        ply,
        &mut s,
        &blocks,
        kept,
        &is_owned,
        stream::BUCKET_MEMORY,
    )?;
    let mut set = OutputSet::new();
    let stage = set.stage_dir(dir)?;
    let written: Vec<Result<(ShardLeaf, usize)>> = owned
        .par_iter()
        .map(|&b| {
            let raw = buckets.take_raw(b)?;
            let rec = format!("leaf_{b}.rec");
            let cloud = buckets.decode(&raw, &stage.join(&rec))?;
            let n = cloud.len();
            let (glb, _) = encode_glb(cloud, opts)?;
            let path = stage.join(format!("tile_{b}.glb"));
            std::fs::write(&path, &glb).map_err(io(path))?;
            let path = stage.join(&rec);
            std::fs::write(&path, &raw).map_err(io(path))?;
            let leaf = ShardLeaf {
                block: b,
                key: keys[b].clone(),
                glb_bytes: glb.len() as u64,
                record_bytes: raw.len() as u64,
            };
            Ok((leaf, n))
        })
        .collect();
    let mut report = ShardReport {
        total_leaves: blocks.leaves().count(),
        ..Default::default()
    };
    let mut leaves = Vec::with_capacity(written.len());
    for w in written {
        let (leaf, n) = w?;
        report.leaves += 1;
        report.gaussians += n;
        report.files += 2;
        report.bytes += leaf.glb_bytes + leaf.record_bytes;
        leaves.push(leaf);
    }
    let manifest = ShardManifest {
        format: SHARD_FORMAT.into(),
        version: env!("CARGO_PKG_VERSION").into(),
        index,
        count,
        partition,
        leaves,
    };
    let json = serde_json::to_vec_pretty(&manifest)
        .map_err(|e| ConvertError::Invalid(format!("shard manifest: {e}")))?;
    let path = stage.join(MANIFEST);
    std::fs::write(&path, &json).map_err(io(path))?;
    report.files += 1;
    report.bytes += json.len() as u64;
    drop(buckets);
    drop(tmp);
    set.commit()?;
    Ok(report)
}

/// The shards' leaves, for the final run's walk.
pub(super) struct ShardLeaves<'a> {
    /// Per leaf block: the shard directory holding it and its listed sizes.
    at: BTreeMap<usize, (&'a Path, ShardLeaf)>,
    stream: &'a PlyStream,
}

/// Read exactly `len` bytes of `path`, a regular file of that size.
fn read_listed(path: &Path, len: u64, manifest: &Path) -> Result<Vec<u8>> {
    let (file, actual) = splatbridge_scene::input::open_regular(path).map_err(scene_err)?;
    if actual != len {
        return Err(ConvertError::Format {
            path: path.into(),
            what: format!(
                "{actual} bytes where {} lists {len} (a damaged or replaced shard)",
                manifest.display()
            ),
        });
    }
    let mut out = Vec::with_capacity(len as usize);
    file.take(len)
        .read_to_end(&mut out)
        .map_err(io(path.into()))?;
    if out.len() as u64 != len {
        return Err(ConvertError::Format {
            path: path.into(),
            what: "the file shrank while being read".into(),
        });
    }
    Ok(out)
}

impl ShardLeaves<'_> {
    /// Leaf `b`'s GLB bytes (as its shard wrote them) and Gaussians (decoded from its
    /// records).
    pub(super) fn take(&self, b: usize) -> Result<(Vec<u8>, GaussianCloud)> {
        let (dir, leaf) = self
            .at
            .get(&b)
            .ok_or_else(|| ConvertError::Invalid(format!("tile {b}: no shard holds this leaf")))?;
        let manifest = dir.join(MANIFEST);
        let rec = dir.join(format!("leaf_{b}.rec"));
        let raw = read_listed(&rec, leaf.record_bytes, &manifest)?;
        let cloud = self.stream.decode(&raw, &rec).map_err(scene_err)?;
        let glb = read_listed(
            &dir.join(format!("tile_{b}.glb")),
            leaf.glb_bytes,
            &manifest,
        )?;
        Ok((glb, cloud))
    }
}

/// An error in shard directory `dir`'s manifest.
fn manifest_err(dir: &Path, what: String) -> ConvertError {
    ConvertError::Format {
        path: dir.join(MANIFEST),
        what,
    }
}

/// Read and check one shard directory's manifest.
fn read_manifest(dir: &Path) -> Result<ShardManifest> {
    let path = dir.join(MANIFEST);
    let bad = |what: String| manifest_err(dir, what);
    let text = splatbridge_scene::input::read_bounded(&path, splatbridge_scene::input::Cap::Text)
        .map_err(|e| {
        bad(format!(
            "no shard manifest ({e}); was this directory written with --tiles DIR --shard I/N?"
        ))
    })?;
    let m: ShardManifest = serde_json::from_slice(&text)
        .map_err(|e| bad(format!("not a tile shard's manifest: {e}")))?;
    if m.format != SHARD_FORMAT {
        return Err(bad(format!(
            "format {:?}, expected {SHARD_FORMAT:?}",
            m.format
        )));
    }
    if m.version != env!("CARGO_PKG_VERSION") {
        return Err(bad(format!(
            "written by version {}, this is {}",
            m.version,
            env!("CARGO_PKG_VERSION")
        )));
    }
    if m.count == 0 || m.index >= m.count {
        return Err(bad(format!("shard {}/{} is not a shard", m.index, m.count)));
    }
    Ok(m)
}

/// The tileset of `ply` into `dir` from the directories of every shard of one sharded run
/// (see the module documentation), all or nothing; `owner` must be the shards' own.
pub fn write_from_shards(
    dir: &Path,
    ply: &Path,
    drop_invalid: bool,
    opts: &TileOptions,
    shard_dirs: &[PathBuf],
    owner: &LeafOwner<'_>,
    meter: &ErrorMeter<'_>,
) -> Result<TilesetReport> {
    let first = shard_dirs
        .first()
        .ok_or_else(|| ConvertError::Invalid("--from-shards: no shard directories given".into()))?;
    let manifests: Vec<ShardManifest> = shard_dirs
        .iter()
        .map(|d| read_manifest(d))
        .collect::<Result<_>>()?;
    let count = manifests[0].count;
    let mut seen: Vec<Option<&Path>> = vec![None; count as usize];
    for (m, d) in manifests.iter().zip(shard_dirs) {
        let bad = |what: String| manifest_err(d, what);
        if m.count != count {
            return Err(bad(format!(
                "shard {}/{} of another run: {} is a shard of {count}",
                m.index,
                m.count,
                first.display()
            )));
        }
        if let Some(other) = seen[m.index as usize].replace(d) {
            return Err(bad(format!(
                "shard {}/{count} given twice (also {})",
                m.index,
                other.display()
            )));
        }
    }
    let missing: Vec<String> = (seen.iter().enumerate())
        .filter(|(_, s)| s.is_none())
        .map(|(i, _)| i.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(ConvertError::Invalid(format!(
            "--from-shards: missing shard(s) {} of {count}",
            missing.join(", ")
        )));
    }
    let (blocks, _, partition) = fingerprinted_partition(ply, drop_invalid, opts)?;
    let keys = leaf_keys(&blocks);
    let mut at = BTreeMap::new();
    for (m, d) in manifests.iter().zip(shard_dirs) {
        let bad = |what: String| manifest_err(d, what);
        if m.partition != partition {
            return Err(bad(format!(
                "written for another input or other options (partition {}, this run's {partition})",
                m.partition
            )));
        }
        for leaf in &m.leaves {
            let ok = blocks.blocks.get(leaf.block).is_some_and(|b| b.is_leaf())
                && keys[leaf.block] == leaf.key
                && owner(&leaf.key, count) == m.index;
            if !ok {
                return Err(bad(format!(
                    "lists leaf {} ({:?}), which shard {}/{count} does not own",
                    leaf.block, leaf.key, m.index
                )));
            }
            if at.insert(leaf.block, (d.as_path(), leaf.clone())).is_some() {
                return Err(bad(format!("leaf {} listed twice", leaf.block)));
            }
        }
    }
    if let Some(b) =
        (0..blocks.blocks.len()).find(|&b| blocks.blocks[b].is_leaf() && !at.contains_key(&b))
    {
        return Err(ConvertError::Invalid(format!(
            "--from-shards: leaf {b} ({:?}) is in no shard (shard {} of {count} is incomplete)",
            keys[b],
            owner(&keys[b], count)
        )));
    }
    let s = stream::reopen(ply, drop_invalid)?;
    let leaves = ShardLeaves { at, stream: &s };
    write_blocks(dir, &blocks, Source::Shards(&leaves), 0, opts, meter)
}
