//! 3D Tiles output with measured geometric errors: `convert SCENE --tiles DIR`.
//!
//! The tileset itself is written by `splatbridge_convert::tiles`; what needs a renderer lives
//! here, because the convert crate cannot depend on `hybrid`.
//!
//! An inner tile's geometric error is measured by rendering its merged content and the union
//! of its children's contents with native splatting, through one oblique camera looking down
//! at the tile (45° above the horizon of the capture's up axis, [`MEASURE_FOV_DEG`] vertical
//! field of view) from the distance at which the tile's footprint sphere fills the view, in
//! square views of sides [`MIN_SIDE`]·√2ᵏ up to [`MAX_SIDE`] pixels. The finest view in which
//! the two renders agree within [`LOD_PSNR_DB`] (PSNR over the view) gives the error: the
//! world size of one of its pixels, `2·d·tan(fov/2)/side`. A client that shows the parent
//! while its screen-space error (`geometricError · H / (2·d·tan(fov/2))`) is at most 1 pixel
//! therefore draws it at that pixel size or coarser, where it was measured within
//! `LOD_PSNR_DB` of its children; CesiumJS's default `maximumScreenSpaceError` of 16 accepts
//! 16 such pixels.
//!
//! Varying the view's resolution at a fixed framing, rather than the distance at a fixed
//! resolution, keeps the tile filling the view: with a fixed view the receding tile's error
//! is diluted by background, and over the covered pixels alone it does not converge (a
//! distant tile shrinks to a dozen pixels dominated by the children's own sub-pixel
//! dilation, 24–25 dB on `plant` at any distance).

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use glam::DVec3;
use splatbridge_convert::tiles::shard::{write_from_shards, write_shard, ShardReport};
use splatbridge_convert::tiles::{
    write_tileset, write_tileset_from_ply, TileOptions, TilesetReport,
};
use splatbridge_convert::{ConvertError, UpAxis};
use splatbridge_hybrid::native::{RenderOptions, Renderer};
use splatbridge_scene::blocks::Aabb;
use splatbridge_scene::camera::Camera;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::GaussianCloud;

use crate::batch::shard::{Fnv1a, Shard};

/// The agreement that makes a parent good enough: 30 dB is about 3% RMS of full scale,
/// below what the viewer check measures between two correct splat renderers of one file
/// (Babylon.js against native, 35 dB) less a margin for the coarser level.
pub const LOD_PSNR_DB: f64 = 30.0;
/// Sides of the measuring views, in steps of √2: from a tile drawn 8 pixels across to 512
/// (beyond, two renders of a leaf-level parent's children take most of a second each).
pub const MIN_SIDE: u32 = 8;
pub const MAX_SIDE: u32 = 512;
pub const MEASURE_FOV_DEG: f64 = 60.0;

/// The capture's up vector for an input up axis.
pub fn up_vector(up: UpAxis) -> DVec3 {
    match up {
        UpAxis::Y => DVec3::Y,
        UpAxis::Z => DVec3::Z,
        UpAxis::NegY => DVec3::NEG_Y,
    }
}

/// The measuring camera for a tile at distance `d` from its centre, `side` pixels square.
fn camera(bounds: &Aabb, up: DVec3, d: f64, side: u32) -> Result<Camera, ConvertError> {
    let target = bounds.centre().as_dvec3();
    let across = if up.x.abs() < 0.5 { DVec3::X } else { DVec3::Z };
    let dir = (up + across).normalize();
    Camera::look_at(target + d * dir, target, up, MEASURE_FOV_DEG, side, side)
        .map_err(ConvertError::from)
}

/// One measurement (see the module documentation): the world size of a pixel at the
/// finest view in which `parent` renders within [`LOD_PSNR_DB`] of `children`.
pub fn measure_error(
    renderer: &mut Renderer,
    parent: &GaussianCloud,
    children: &GaussianCloud,
    bounds: &Aabb,
    up: DVec3,
) -> Result<f64, ConvertError> {
    let tan = (MEASURE_FOV_DEG.to_radians() / 2.0).tan();
    let radius = (bounds.half_extent().length() as f64).max(1e-6);
    let d = radius / tan;
    let opts = RenderOptions::default();
    let mut agrees = |side: u32| -> Result<bool, ConvertError> {
        let cam = camera(bounds, up, d, side)?;
        let render = |r: &mut Renderer, c: &GaussianCloud| {
            r.render(c, &cam, &opts)
                .map(|(f, _)| f)
                .map_err(|e| ConvertError::Invalid(format!("measuring a tile's error: {e}")))
        };
        let a = render(renderer, parent)?;
        let b = render(renderer, children)?;
        Ok(splatbridge_scene::metrics::psnr(&a, &b)? >= LOD_PSNR_DB)
    };
    // Sides MIN_SIDE·√2^k up to MAX_SIDE, coarse to fine; a client shows the parent at every
    // pixel size above its error, so the error is set by the finest side up to which every
    // side passes. Agreement need not fall with resolution: 3DGS's 0.3-pixel dilation adds
    // more mass to many small children than to their few merged parents, so coarse views can
    // be the worst (measured on `plant`: a root merged 6:1 fails at 8 pixels). Without any
    // passing side the error is a pixel of half the smallest view.
    let mut best = MIN_SIDE as f64 / 2.0;
    let mut k = 0;
    loop {
        let side = (MIN_SIDE as f64 * 2f64.powf(k as f64 / 2.0)).round();
        if side > MAX_SIDE as f64 || !agrees(side as u32)? {
            break;
        }
        best = side;
        k += 1;
    }
    Ok(2.0 * d * tan / best)
}

/// The error meter of a tileset: [`measure_error`] on the worker threads, each measurement
/// with a renderer from a pool (a renderer holds only scratch buffers, so which one is used
/// does not change the result).
struct Meter {
    pool: Mutex<Vec<Renderer>>,
    up: DVec3,
}

impl Meter {
    fn new(opts: &TileOptions) -> Meter {
        Meter {
            pool: Mutex::new(Vec::new()),
            up: up_vector(opts.convert.up),
        }
    }

    fn measure(&self, p: &GaussianCloud, c: &GaussianCloud, b: &Aabb) -> Result<f64, ConvertError> {
        let poisoned = || ConvertError::Invalid("a tile worker panicked".into());
        let mut r = self
            .pool
            .lock()
            .map_err(|_| poisoned())?
            .pop()
            .unwrap_or_default();
        let out = measure_error(&mut r, p, c, b, self.up);
        self.pool.lock().map_err(|_| poisoned())?.push(r);
        out
    }
}

/// Write `scene` as a 3D Tiles 1.1 tileset into `dir` with measured geometric errors.
pub fn write_tiles(
    dir: &Path,
    scene: &DynamicScene,
    opts: &TileOptions,
) -> Result<TilesetReport, ConvertError> {
    let m = Meter::new(opts);
    write_tileset(dir, scene, opts, &|p, c, b| m.measure(p, c, b))
}

/// [`write_tiles`] of a binary PLY read in two streaming passes, memory bounded by the
/// partition and a tile rather than the cloud (`splatbridge_convert::tiles` streaming);
/// `Ok(None)` for an ASCII PLY. The tileset is byte-identical to [`write_tiles`] of the
/// same file read whole.
pub fn write_tiles_from_ply(
    dir: &Path,
    ply: &Path,
    drop_invalid: bool,
    opts: &TileOptions,
) -> Result<Option<TilesetReport>, ConvertError> {
    let m = Meter::new(opts);
    write_tileset_from_ply(dir, ply, drop_invalid, opts, &|p, c, b| m.measure(p, c, b))
}

/// The shard of `count` that owns a leaf of a sharded tileset: FNV-1a 64 of its octree
/// path (`splatbridge_convert::tiles::shard::leaf_keys`) modulo the count, the hash of
/// [`crate::batch::shard`], so every machine agrees.
pub fn leaf_owner(key: &str, count: u32) -> u32 {
    let mut h = Fnv1a::new();
    h.write(key.as_bytes());
    (h.finish() % u64::from(count.max(1))) as u32
}

/// `convert PLY --tiles DIR --shard I/N`: the leaves shard I owns, with their records, into
/// `dir` (`splatbridge_convert::tiles::shard`).
pub fn write_tiles_shard(
    dir: &Path,
    ply: &Path,
    drop_invalid: bool,
    opts: &TileOptions,
    shard: Shard,
) -> Result<ShardReport, ConvertError> {
    write_shard(
        dir,
        ply,
        drop_invalid,
        opts,
        (shard.index, shard.count),
        &leaf_owner,
    )
}

/// `convert PLY --tiles DIR --from-shards SHARD_DIR…`: the tileset one run writes, from the
/// leaves of every shard of a sharded run.
pub fn write_tiles_from_shards(
    dir: &Path,
    ply: &Path,
    drop_invalid: bool,
    opts: &TileOptions,
    shards: &[PathBuf],
) -> Result<TilesetReport, ConvertError> {
    let m = Meter::new(opts);
    write_from_shards(
        dir,
        ply,
        drop_invalid,
        opts,
        shards,
        &leaf_owner,
        &|p, c, b| m.measure(p, c, b),
    )
}
