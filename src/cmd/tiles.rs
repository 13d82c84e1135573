//! `splatbridge convert SCENE --tiles DIR`: the 3D Tiles options and their summary. The work
//! is `splatbridge::pipeline::tiles::write_tiles`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use clap::ValueEnum;
use splatbridge::pipeline::export::load_export_input;
use splatbridge_convert::splats_gltf::KhrCompression;
use splatbridge_convert::tiles::{TileContent, TileOptions, TILE_GZIP_LEVEL};
use splatbridge_convert::Profile;
use splatbridge_scene::blocks::DEFAULT_MAX_PER_BLOCK;

use crate::cmd::common;
use crate::cmd::convert::Args;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TileContentArg {
    /// KHR_gaussian_splatting points with merged levels of detail (refine REPLACE).
    Splats,
    /// The mesh profile's triangles in the leaves (refine ADD).
    Mesh,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TileCompressionArg {
    /// SPZ as CesiumJS decodes it (the stream in the glTF mesh's own frame).
    Spz,
    /// SPZ packed from Left-Up-Front, as the extension's draft text asks (CesiumJS 1.145
    /// shows such tiles turned 180° about the up axis).
    SpzLuf,
    /// Float attribute accessors (CesiumJS does not read these).
    None,
}

#[derive(clap::Args, Debug, Default)]
pub struct TileArgs {
    /// Write a 3D Tiles 1.1 tileset (tileset.json and one GLB per tile) into DIR instead of -o.
    #[arg(long, value_name = "DIR")]
    pub tiles: Option<PathBuf>,
    /// What each tile's GLB holds (with --tiles).
    #[arg(long, value_enum)]
    pub tile_content: Option<TileContentArg>,
    /// Gaussian budget of a tile (with --tiles; also `info --blocks`).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=16_777_216))]
    pub max_gaussians_per_tile: Option<u32>,
    /// Splat attributes in each tile: SPZ (KHR_gaussian_splatting_compression_spz_2, what
    /// CesiumJS reads) or float accessors (with --tiles).
    #[arg(long, value_enum)]
    pub tile_compression: Option<TileCompressionArg>,
    /// Place the capture's origin at LON,LAT,HEIGHT (degrees, degrees, metres on WGS84) with
    /// its up axis along the ellipsoid normal (with --tiles; default: an identity root
    /// transform, the capture in its own Z-up frame).
    #[arg(long, value_name = "LON,LAT,HEIGHT", allow_hyphen_values = true)]
    pub tiles_origin: Option<String>,
    /// gzip level of the tiles' SPZ streams, 0–9 (with --tiles; default 2, see docs/tiles.md).
    #[arg(long, value_name = "0-9", value_parser = clap::value_parser!(u32).range(0..=9), requires = "tiles")]
    pub tile_gzip_level: Option<u32>,
    /// Build the tileset from the directories of every shard of a `--tiles DIR --shard I/N`
    /// run (with --tiles and the same binary PLY and options): the leaves are taken from
    /// them, the parents and tileset.json are made here.
    #[arg(long, value_name = "SHARD_DIR", num_args = 1.., conflicts_with = "shard", requires = "tiles")]
    pub from_shards: Vec<PathBuf>,
}

fn parse_origin(s: &str) -> anyhow::Result<[f64; 3]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--tiles-origin {s}: expected three numbers LON,LAT,HEIGHT"))?;
    match v[..] {
        [lon, lat, h]
            if (-180.0..=180.0).contains(&lon)
                && (-90.0..=90.0).contains(&lat)
                && h.is_finite()
                && h.abs() < 1e7 =>
        {
            Ok([lon, lat, h])
        }
        _ => bail!("--tiles-origin {s}: expected LON in [-180, 180], LAT in [-90, 90] and a height within 10,000 km"),
    }
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let Some(dir) = &args.tiles.tiles else {
        bail!("--tiles: no directory given");
    };
    if args.output != std::path::Path::new(".") {
        bail!("--tiles writes a directory of files; drop -o");
    }
    if args.splats || args.frames || args.surfels || args.first.is_some() {
        bail!(
            "--tiles: --splats, --frames, --surfels and --first do not apply (use --tile-content)"
        );
    }
    let origin = args
        .tiles
        .tiles_origin
        .as_deref()
        .map(parse_origin)
        .transpose()?;
    let t0 = Instant::now();
    let content = match args.tiles.tile_content {
        Some(TileContentArg::Mesh) => TileContent::Mesh,
        _ => TileContent::Splats,
    };
    let opts = TileOptions {
        max_per_tile: args
            .tiles
            .max_gaussians_per_tile
            .map_or(DEFAULT_MAX_PER_BLOCK, |n| n as usize),
        content,
        origin,
        compression: match args.tiles.tile_compression {
            Some(TileCompressionArg::None) => KhrCompression::None,
            Some(TileCompressionArg::SpzLuf) => KhrCompression::Spz,
            Some(TileCompressionArg::Spz) | None => KhrCompression::SpzCesium,
        },
        gzip_level: args.tiles.tile_gzip_level.unwrap_or(TILE_GZIP_LEVEL),
        convert: args.base_options(Profile::Texture),
    };
    let pb = common::progress(1, "writing tiles");
    // A binary PLY is streamed (two passes, memory bounded by the partition and a tile);
    // anything else is read whole.
    let is_ply = args
        .scene
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
    if (args.shard.is_some() || !args.tiles.from_shards.is_empty()) && !is_ply {
        bail!("--shard and --from-shards with --tiles need a binary .ply input");
    }
    if let Some(shard) = args.shard {
        let rep = splatbridge::pipeline::tiles::write_tiles_shard(
            dir,
            &args.scene,
            args.drop_invalid,
            &opts,
            shard,
        )?;
        pb.finish_and_clear();
        println!(
            "shard {shard}: wrote {} of {} leaves ({} Gaussians), {} files, {} bytes into {}; {:.2} s",
            rep.leaves,
            rep.total_leaves,
            rep.gaussians,
            rep.files,
            rep.bytes,
            dir.display(),
            t0.elapsed().as_secs_f64()
        );
        return Ok(());
    }
    let streamed = if !args.tiles.from_shards.is_empty() {
        Some(splatbridge::pipeline::tiles::write_tiles_from_shards(
            dir,
            &args.scene,
            args.drop_invalid,
            &opts,
            &args.tiles.from_shards,
        )?)
    } else if is_ply {
        // Errors name their file (the PLY or the tile written).
        splatbridge::pipeline::tiles::write_tiles_from_ply(
            dir,
            &args.scene,
            args.drop_invalid,
            &opts,
        )?
    } else {
        None
    };
    let rep = match streamed {
        Some(rep) => rep,
        None => {
            let scene = load_export_input(&args.scene, args.drop_invalid, &common::print_warning)?;
            splatbridge::pipeline::tiles::write_tiles(dir, &scene, &opts)
                .with_context(|| dir.display().to_string())?
        }
    };
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "tiles": dir, "content": content.name(), "tile_count": rep.tiles, "leaves": rep.leaves,
                "max_depth": rep.max_depth, "files": rep.files, "bytes": rep.bytes,
                "gaussians": rep.gaussians, "lod_gaussians": rep.lod_gaussians,
                "invalid_left_out": rep.invalid_left_out, "root_geometric_error": rep.root_error,
                "seconds": secs,
            })
        );
    } else {
        println!(
            "wrote {}: {} tiles ({} leaves, depth {}), {} files, {} bytes; {} Gaussians in leaves, {} in levels of detail; root geometric error {:.4}; {:.2} s",
            dir.join("tileset.json").display(),
            rep.tiles,
            rep.leaves,
            rep.max_depth,
            rep.files,
            rep.bytes,
            rep.gaussians,
            rep.lod_gaussians,
            rep.root_error,
            secs
        );
    }
    Ok(())
}
