//! OGC 3D Tiles 1.1 tilesets of a scene's Gaussians (moving objects placed at the scene's
//! start): `tileset.json` plus one GLB per
//! tile, each with `KHR_gaussian_splatting` splats (our [`crate::splats_gltf`] writer) or our
//! mesh profile, written as one set (a staging directory committed with
//! [`OutputSet`]).
//!
//! - Partition: [`splatbridge_scene::blocks`] (adaptive octree by Gaussian count, each
//!   Gaussian in one leaf by its centre, bounding volumes grown to contain 3σ footprints).
//! - Splat tiles: leaves hold their Gaussians as they are; every inner tile holds a reduced
//!   set merged from its children's contents ([`lod`], at most half of them and at most the
//!   tile budget) and refines with `REPLACE`. Its `geometricError` is measured by the
//!   caller's [`ErrorMeter`] (the root crate renders parent and children natively) and added
//!   to the largest child error, so errors strictly decrease towards the leaves (whose error
//!   is 0).
//! - Mesh tiles: leaves hold their Gaussians meshed; inner tiles hold nothing and refine with
//!   `ADD`; an empty tile's error is its footprint box's diagonal (what is missing when
//!   nothing is drawn), which is larger than any of its children's.
//! - Frames: glTF content is Y-up and 3D Tiles applies the Y-up → Z-up rotation (+90° about
//!   X, 3D Tiles 1.1 §"glTF transforms") after the content's own nodes; our content keeps
//!   the capture frame under the `splatbridge_root` node, so bounding volumes are expressed
//!   through `M = R_x(+90°) · R_up` (the capture's up axis becomes the tileset's +Z). The root
//!   `transform` is the identity, or with an origin (longitude, latitude, height on WGS84)
//!   the east-north-up frame there, so the capture stands upright on the globe.
//! - Memory: the cloud is read once; the partition is a permutation of indices; tiles are
//!   visited depth first and a tile's content is dropped once its parent is merged, so beyond
//!   the input cloud each worker thread holds at most (tree depth × 8) tile contents.
//! - Threads: a tile's children are visited on the rayon pool (subtrees are independent:
//!   leaves are encoded, parents merged, measured and encoded while other subtrees run) and
//!   their results are joined in child order, so every file and `tileset.json` are those of
//!   one thread.
//! - Shards ([`shard`]): `--shard I/N` runs write the leaves they own with their contents;
//!   a final run reads them back instead of encoding leaves and writes what one run writes.

pub mod lod;
pub mod shard;
mod stream;

pub use stream::write_tileset_from_ply;

use std::path::Path;

use glam::{DVec3, Mat3, Quat, Vec3};
use rayon::prelude::*;
use serde_json::{json, Value};
use splatbridge_scene::blocks::{footprint, Aabb, Block, Blocks};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::output::OutputSet;
use splatbridge_scene::GaussianCloud;

use crate::options::ConvertOptions;
use crate::splats_gltf::KhrCompression;
use crate::{ConvertError, Result};

/// What a tile's GLB holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TileContent {
    /// `KHR_gaussian_splatting` points, with merged levels of detail.
    Splats,
    /// The conversion profile's triangle meshes, leaves only (refine ADD).
    Mesh,
}

impl TileContent {
    pub fn name(self) -> &'static str {
        match self {
            TileContent::Splats => "splats",
            TileContent::Mesh => "mesh",
        }
    }
}

/// Options of a tileset.
#[derive(Clone, Debug)]
pub struct TileOptions {
    pub max_per_tile: usize,
    pub content: TileContent,
    /// (longitude°, latitude°, height m) of the capture's origin on WGS84, for the root
    /// transform; `None` writes the identity.
    pub origin: Option<[f64; 3]>,
    /// The conversion options of every tile's GLB (up axis, mesh profile, …).
    pub convert: ConvertOptions,
    /// Splat attribute storage. CesiumJS (1.134 on) reads `KHR_gaussian_splatting` only with
    /// `KHR_gaussian_splatting_compression_spz_2`, and decodes its stream without the
    /// extension's LUF conversion, so tilesets default to [`KhrCompression::SpzCesium`].
    pub compression: KhrCompression,
    /// gzip level (0–9) of the SPZ streams; [`TILE_GZIP_LEVEL`] by default.
    pub gzip_level: u32,
}

/// The tiles' SPZ gzip level: 2 (zlib-rs's `deflate_fast`). Measured on the 1 M fixture's
/// 89 tiles (docs/tiles.md, "gzip level"): against SPZ's usual 6 it cuts the run's CPU time
/// by about a third for 5 % more bytes; level 1 (`deflate_quick`) saves little more time
/// but writes 38 % more bytes.
pub const TILE_GZIP_LEVEL: u32 = 2;

/// Measures an inner tile's geometric error (world units): `parent` is its merged content,
/// `children` the union of its children's contents, `bounds` the tile's footprint box.
/// Called from the worker threads, for independent tiles at once.
pub type ErrorMeter<'a> = dyn Fn(&GaussianCloud, &GaussianCloud, &Aabb) -> Result<f64> + Sync + 'a;

/// What was written.
#[derive(Clone, Debug, Default)]
pub struct TilesetReport {
    pub tiles: usize,
    pub files: usize,
    pub bytes: u64,
    pub leaves: usize,
    pub max_depth: u32,
    pub gaussians: usize,
    /// Gaussians written in inner (level-of-detail) tiles.
    pub lod_gaussians: usize,
    pub invalid_left_out: usize,
    /// Moving objects written where they are at the scene's start.
    pub objects_at_start: usize,
    pub root_error: f64,
}

/// The tileset frame's map from the capture frame: glTF's Y-up → Z-up after the content's
/// up-axis root rotation.
pub fn capture_to_tileset(opts: &ConvertOptions) -> Mat3 {
    Mat3::from_quat(Quat::from_rotation_x(std::f32::consts::FRAC_PI_2))
        * Mat3::from_quat(opts.up.root_rotation())
}

/// A `boundingVolume.box` (centre, then the three half-axis vectors) of a capture-frame box.
pub fn box_volume(b: &Aabb, m: &Mat3) -> [f64; 12] {
    let c = (*m * b.centre()).as_dvec3();
    let h = b.half_extent();
    let ax = [Vec3::X * h.x, Vec3::Y * h.y, Vec3::Z * h.z].map(|v| (*m * v).as_dvec3());
    [
        c.x, c.y, c.z, ax[0].x, ax[0].y, ax[0].z, ax[1].x, ax[1].y, ax[1].z, ax[2].x, ax[2].y,
        ax[2].z,
    ]
}

/// The east-north-up → Earth-centred, Earth-fixed transform (column-major 4×4) at a WGS84
/// longitude, latitude (degrees) and ellipsoidal height (metres).
pub fn enu_to_ecef(lon_deg: f64, lat_deg: f64, height: f64) -> [f64; 16] {
    const A: f64 = 6_378_137.0;
    const E2: f64 = 6.694_379_990_141_316e-3;
    let (lon, lat) = (lon_deg.to_radians(), lat_deg.to_radians());
    let (sl, cl, sp, cp) = (lon.sin(), lon.cos(), lat.sin(), lat.cos());
    let n = A / (1.0 - E2 * sp * sp).sqrt();
    let p = DVec3::new(
        (n + height) * cp * cl,
        (n + height) * cp * sl,
        (n * (1.0 - E2) + height) * sp,
    );
    let east = DVec3::new(-sl, cl, 0.0);
    let north = DVec3::new(-sp * cl, -sp * sl, cp);
    let up = DVec3::new(cp * cl, cp * sl, sp);
    [
        east.x, east.y, east.z, 0.0, north.x, north.y, north.z, 0.0, up.x, up.y, up.z, 0.0, p.x,
        p.y, p.z, 1.0,
    ]
}

/// The Gaussians `idx` of `cloud` as a cloud of their own.
fn subset(cloud: &GaussianCloud, idx: &[u32]) -> GaussianCloud {
    let mut out = GaussianCloud::with_capacity(cloud.sh_degree, idx.len());
    for &i in idx {
        let i = i as usize;
        out.push(
            cloud.means[i],
            cloud.log_scales[i],
            cloud.rotations[i],
            cloud.opacity_logits[i],
            cloud.sh_of(i),
        );
    }
    out
}

/// The 3σ footprint box of a whole cloud.
fn cloud_footprint(c: &GaussianCloud) -> Aabb {
    (0..c.len()).fold(Aabb::EMPTY, |a, i| a.union(&footprint(c, i)))
}

/// Where leaves' Gaussians come from.
enum Source<'a> {
    /// A cloud in memory.
    Cloud(&'a GaussianCloud),
    /// Per-leaf buckets of raw PLY records.
    Buckets(&'a stream::Buckets<'a>),
    /// Leaves written by shards: their GLBs and contents (the final run of a sharded tileset).
    Shards(&'a shard::ShardLeaves<'a>),
}

/// The counts of a subtree, summed up the tree.
#[derive(Clone, Copy, Default)]
struct Counts {
    tiles: usize,
    files: usize,
    bytes: u64,
    leaves: usize,
    max_depth: u32,
    gaussians: usize,
    lod_gaussians: usize,
}

impl Counts {
    fn add(&mut self, o: &Counts) {
        self.tiles += o.tiles;
        self.files += o.files;
        self.bytes += o.bytes;
        self.leaves += o.leaves;
        self.max_depth = self.max_depth.max(o.max_depth);
        self.gaussians += o.gaussians;
        self.lod_gaussians += o.lod_gaussians;
    }
}

/// A visited subtree: its tile JSON, its error, its content (splats: the parent merges it)
/// and its counts.
struct Visited {
    tile: Value,
    error: f64,
    content: Option<GaussianCloud>,
    counts: Counts,
}

struct Writer<'a, 'm> {
    source: Source<'a>,
    blocks: &'a Blocks,
    opts: &'a TileOptions,
    meter: &'a ErrorMeter<'m>,
    stage: &'a Path,
    frame: Mat3,
}

/// Encode `content` as one tile's GLB in memory; returns the bytes and the content back
/// (the parent merges it).
pub(crate) fn encode_glb(
    content: GaussianCloud,
    opts: &TileOptions,
) -> Result<(Vec<u8>, GaussianCloud)> {
    let scene = DynamicScene::from_static(content);
    let mut bytes = Vec::new();
    match opts.content {
        TileContent::Splats => crate::splats_gltf::write_tile_glb(
            &mut bytes,
            &scene,
            &opts.convert,
            opts.compression,
            opts.gzip_level,
        )?,
        TileContent::Mesh => crate::write_glb(&mut bytes, &scene, None, &opts.convert)?,
    };
    Ok((bytes, scene.static_gaussians))
}

fn put(stage: &Path, name: &str, bytes: &[u8], counts: &mut Counts) -> Result<()> {
    let path = stage.join(name);
    std::fs::write(&path, bytes).map_err(|e| ConvertError::Io { path, err: e })?;
    counts.files += 1;
    counts.bytes += bytes.len() as u64;
    Ok(())
}

impl Writer<'_, '_> {
    /// Leaf `b`'s GLB bytes and Gaussians.
    fn leaf(&self, b: usize) -> Result<(Vec<u8>, GaussianCloud)> {
        match &self.source {
            Source::Cloud(cloud) => encode_glb(
                subset(cloud, self.blocks.indices(&self.blocks.blocks[b])),
                self.opts,
            ),
            Source::Buckets(buckets) => encode_glb(buckets.take(b)?, self.opts),
            Source::Shards(shards) => shards.take(b),
        }
    }

    /// Write block `b`'s subtree.
    fn visit(&self, b: usize) -> Result<Visited> {
        let block: &Block = &self.blocks.blocks[b];
        let mut counts = Counts {
            tiles: 1,
            max_depth: block.depth,
            ..Default::default()
        };
        let name = format!("tile_{b}.glb");
        if block.is_leaf() {
            counts.leaves = 1;
            let (bytes, content) = self.leaf(b)?;
            counts.gaussians = content.len();
            put(self.stage, &name, &bytes, &mut counts)?;
            drop(bytes);
            let tile = json!({
                "boundingVolume": {"box": box_volume(&block.footprint, &self.frame)},
                "geometricError": 0.0,
                "content": {"uri": name},
            });
            let content = (self.opts.content == TileContent::Splats).then_some(content);
            return Ok(Visited {
                tile,
                error: 0.0,
                content,
                counts,
            });
        }
        // Subtrees are independent: visited on all cores, joined in child order (the files
        // and the merge order are those of one thread).
        let visited: Vec<Result<Visited>> =
            block.children.par_iter().map(|&c| self.visit(c)).collect();
        let mut children = Vec::with_capacity(block.children.len());
        let mut child_error = 0.0f64;
        let mut union: Option<GaussianCloud> = None;
        for v in visited {
            let v = v?;
            children.push(v.tile);
            child_error = child_error.max(v.error);
            counts.add(&v.counts);
            if let Some(content) = v.content {
                match &mut union {
                    Some(u) => u.extend_from(&content, None),
                    None => union = Some(content),
                }
            }
        }
        let mut bounds = block.footprint;
        let (tile, error, content) = match (self.opts.content, union) {
            (TileContent::Splats, Some(union)) => {
                let target = self.opts.max_per_tile.min(union.len().div_ceil(2)).max(1);
                let parent = lod::reduce(&union, target);
                bounds = bounds.union(&cloud_footprint(&parent));
                let measured = (self.meter)(&parent, &union, &bounds)?;
                drop(union);
                if !measured.is_finite() || measured < 0.0 {
                    return Err(ConvertError::Invalid(format!(
                        "tile {b}: measured geometric error {measured} is not a finite non-negative number"
                    )));
                }
                // Errors add along a refinement chain; the parent's must exceed its children's.
                let error = next_above(child_error + measured, child_error);
                counts.lod_gaussians += parent.len();
                let (bytes, parent) = encode_glb(parent, self.opts)?;
                put(self.stage, &name, &bytes, &mut counts)?;
                let tile = json!({
                    "boundingVolume": {"box": box_volume(&bounds, &self.frame)},
                    "geometricError": error,
                    "refine": "REPLACE",
                    "content": {"uri": name},
                    "children": children,
                });
                (tile, error, Some(parent))
            }
            _ => {
                let d = 2.0 * bounds.half_extent().length() as f64;
                let error = next_above(d, child_error);
                let tile = json!({
                    "boundingVolume": {"box": box_volume(&bounds, &self.frame)},
                    "geometricError": error,
                    "refine": "ADD",
                    "children": children,
                });
                (tile, error, None)
            }
        };
        Ok(Visited {
            tile,
            error,
            content,
            counts,
        })
    }
}

/// `x` if it exceeds `floor`, else the smallest value that does (relative step 1e-9).
fn next_above(x: f64, floor: f64) -> f64 {
    if x > floor {
        x
    } else {
        floor + floor.abs().max(1e-9) * 1e-9
    }
}

/// Write the tileset of `scene` (objects at the scene's start) into `dir` (`tileset.json` and
/// `tile_N.glb`, N the block's index in pre-order), all or nothing.
pub fn write_tileset(
    dir: &Path,
    scene: &DynamicScene,
    opts: &TileOptions,
    meter: &ErrorMeter<'_>,
) -> Result<TilesetReport> {
    // Tiles are static content: moving objects are placed at the scene's start.
    let composite;
    let cloud = if scene.objects.is_empty() {
        &scene.static_gaussians
    } else {
        composite = scene.composite(scene.time.start);
        &composite
    };
    cloud.check_shape()?;
    let blocks = Blocks::build(cloud, opts.max_per_tile);
    write_blocks(
        dir,
        &blocks,
        Source::Cloud(cloud),
        scene.objects.len(),
        opts,
        meter,
    )
}

/// Write the tileset of a partition whose leaves' Gaussians come from `source`.
fn write_blocks(
    dir: &Path,
    blocks: &Blocks,
    source: Source<'_>,
    objects_at_start: usize,
    opts: &TileOptions,
    meter: &ErrorMeter<'_>,
) -> Result<TilesetReport> {
    if blocks.blocks.is_empty() {
        return Err(ConvertError::Format {
            path: dir.into(),
            what: "--tiles: the scene has no valid Gaussians".into(),
        });
    }
    let mut set = OutputSet::new();
    let stage = set.stage_dir(dir)?;
    let w = Writer {
        source,
        blocks,
        opts,
        meter,
        stage: &stage,
        frame: capture_to_tileset(&opts.convert),
    };
    let Visited {
        tile: mut root,
        error: root_error,
        counts: c,
        ..
    } = w.visit(0)?;
    let mut report = TilesetReport {
        tiles: c.tiles,
        files: c.files,
        bytes: c.bytes,
        leaves: c.leaves,
        max_depth: c.max_depth,
        gaussians: c.gaussians,
        lod_gaussians: c.lod_gaussians,
        invalid_left_out: blocks.invalid,
        objects_at_start,
        root_error,
    };
    root["transform"] = json!(match opts.origin {
        Some([lon, lat, h]) => enu_to_ecef(lon, lat, h),
        None => IDENTITY4,
    });
    let diag = 2.0 * blocks.blocks[0].footprint.half_extent().length() as f64;
    // The glTF extensions of the content, declared through `3DTILES_content_gltf` (CesiumJS
    // picks its splat renderer from this list, not from the GLBs).
    let gltf_ext: Vec<&str> = match (opts.content, opts.compression) {
        (TileContent::Splats, c) if c.is_spz() => {
            vec![
                "KHR_gaussian_splatting",
                "KHR_gaussian_splatting_compression_spz_2",
            ]
        }
        (TileContent::Splats, _) => vec!["KHR_gaussian_splatting"],
        (TileContent::Mesh, _) => vec![],
    };
    let required = if opts.compression.is_spz() {
        gltf_ext.clone()
    } else {
        vec![]
    };
    let mut doc = json!({
        "asset": {
            "version": "1.1",
            "generator": concat!("splatbridge ", env!("CARGO_PKG_VERSION")),
            "extras": {"splatbridge": {
                "content": opts.content.name(),
                "maxGaussiansPerTile": opts.max_per_tile,
                "up": opts.convert.up.name(),
                "khrCompression": opts.compression.name(),
                "gaussians": report.gaussians,
                "lodGaussians": report.lod_gaussians,
                "invalidLeftOut": report.invalid_left_out,
            }},
        },
        "geometricError": next_above(diag, root_error),
        "root": root,
    });
    if !gltf_ext.is_empty() {
        doc["extensionsUsed"] = json!(["3DTILES_content_gltf"]);
        doc["extensions"] = json!({"3DTILES_content_gltf": {"extensionsUsed": gltf_ext, "extensionsRequired": required}});
    }
    let bytes =
        serde_json::to_vec_pretty(&doc).map_err(|e| ConvertError::Invalid(e.to_string()))?;
    set.write(&dir.join("tileset.json"), &bytes)?;
    report.files += 1;
    report.bytes += bytes.len() as u64;
    set.commit()?;
    Ok(report)
}

const IDENTITY4: [f64; 16] = [
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];
