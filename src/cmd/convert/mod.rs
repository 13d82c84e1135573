//! `splatbridge convert`: Gaussians to triangle meshes (GLB/glTF/OBJ/PLY), native glTF
//! splats (`KHR_gaussian_splatting`) or single-cloud splat files (3DGS PLY, compressed PLY,
//! `.splat`, `.spz`). The work is done by `splatbridge::pipeline::export_request` (over
//! `splatbridge-convert` and `splatbridge_scene::formats`); this module defines the command
//! line ([`options`]: its value enums and the request they make) and prints ([`print`]).

mod motion;
mod options;
mod print;

use std::path::PathBuf;
use std::time::Instant;

pub use options::*;

use crate::cmd::common;

#[derive(clap::Args)]
#[command(after_long_help = "Formats follow the extension of -o, or --format:\n\
  meshes: .glb, .gltf (+ .bin), .obj (+ .mtl), .ply with --mesh or --profile;\n\
  splats: .splat, .spz and .ksplat always; *.compressed.ply always (compressed PLY); .ply unless --mesh or\n\
  --profile (3DGS PLY); .glb/.gltf with --splats (KHR_gaussian_splatting, dynamic objects as animated nodes).\n\
Single-cloud splat files (.ply, .compressed.ply, .splat, .spz, .ksplat) hold one cloud: a dynamic scene\n\
is composited at --time (default: the scene's start). .splat keeps SH degree 0 only.\n\
OBJ cannot carry per-vertex alpha: every OBJ triangle is opaque, so soft splat edges and\n\
translucent Gaussians are lost. OBJ and PLY have no node hierarchy: the up rotation and the\n\
objects' poses (at the scene's start, or per frame with --frames) are baked into vertices.\n\
glTF COLOR_0 is linear: display colours are sRGB-decoded unless --color-encoding display.")]
pub struct Args {
    #[arg(help = concat!("The scene: ", scene_formats!(), "."))]
    pub scene: PathBuf,
    /// Output file: .glb, .gltf, .obj, .ply, .compressed.ply, .splat, .spz or .ksplat.
    #[arg(
        short,
        long = "out",
        alias = "output",
        required_unless_present = "tiles",
        default_value = ".",
        hide_default_value = true
    )]
    pub output: PathBuf,
    /// Output format, instead of the one -o's extension implies. Mesh and glTF formats must
    /// agree with the extension; splat formats may be written under any name.
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// Time at which a dynamic scene is composited for single-cloud splat outputs (default:
    /// the scene's start).
    #[arg(long)]
    pub time: Option<f64>,
    /// SPZ version written (3, the default: read by every SPZ reader; 4: zstd streams,
    /// splat-transform's default, for readers of version 4; 2: for older readers).
    #[arg(long, default_value_t = splatbridge_scene::formats::spz::WRITE_VERSION, value_parser = clap::value_parser!(u32).range(2..=4))]
    pub spz_version: u32,
    /// .ksplat compression level (0: float32; 1, the default: half floats, positions in
    /// buckets; 2: as 1 with 8-bit SH).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(0..=2))]
    pub ksplat_level: u8,
    /// Single-cloud splat outputs: keep only the first N Gaussians of the composite (small
    /// test files cut from a real scene).
    #[arg(long, value_name = "N")]
    pub first: Option<usize>,
    /// Meshing profile (default: texture for glTF, rings for OBJ/PLY, which carry no texture).
    #[arg(long, value_enum)]
    pub profile: Option<ProfileArg>,
    /// Segments per fan (default 8; 4 for texture).
    #[arg(long, value_parser = super::ranges::segments)]
    pub segments: Option<usize>,
    /// Rings per fan (profile rings).
    #[arg(long, default_value_t = 3, value_parser = super::ranges::rings)]
    pub rings: usize,
    /// Non-flat Gaussians: three orthogonal fans, or one flat fan.
    #[arg(long, value_enum, default_value = "three-fans")]
    pub volumetric: VolumetricArg,
    /// Smallest/middle scale ratio at or above which a Gaussian is volumetric.
    #[arg(long, default_value_t = splatbridge_convert::options::DEFAULT_FLAT_RATIO)]
    pub flat_ratio: f32,
    /// The input's up axis; a root node rotates it onto glTF's +Y (vertices untouched).
    #[arg(long, value_enum, default_value = "-y", allow_hyphen_values = true)]
    pub up: UpArg,
    /// OBJ: write one OBJ per frame of a dynamic scene (OUT_0000.obj, …). A 4D input: one
    /// glTF whose per-frame nodes are switched by stepped scale keys (-o OUT.glb), or one GLB
    /// per frame and DIR/frames.json (-o DIR/); frames read one at a time.
    #[arg(long)]
    pub frames: bool,
    /// With --frames -o OUT.glb|.gltf: `nodes` writes a node per frame switched by stepped
    /// scale keys (any 4D input, any layout); `morph` one mesh, frame 0 as its base and a morph
    /// target per later frame (1/3 to 1/20 of the size, docs/motion.md), for frames that mesh
    /// to frame 0's topology, with --layout input.
    #[arg(
        long,
        value_enum,
        default_value = "nodes",
        value_name = "ENCODING",
        requires = "frames"
    )]
    pub frames_encoding: motion::FramesEncodingArg,
    /// Find what moves in a 4D input (numbered frames, SpacetimeGaussians PLY, .splatv, params.npz): `auto` splits it
    /// into a static background, rigid objects with one pose per frame and per-frame content
    /// for the rest; `none` keeps everything that moves per frame. With -o DIR (no glTF
    /// extension) writes the manifest DIR/scene.json; with a .glb/.gltf exports it directly.
    #[arg(long, value_enum, value_name = "MODE")]
    pub objects: Option<motion::ObjectsArg>,
    /// With --objects: largest RMS distance (world units) of a Gaussian from its group's
    /// rigid motion (default: 10× the noise estimated from the trajectories).
    #[arg(long, value_name = "D", requires = "objects")]
    pub motion_tolerance: Option<f64>,
    /// With --objects: fewest Gaussians of a rigid group.
    #[arg(long, value_name = "N", default_value_t = 32, requires = "objects")]
    pub min_group: usize,
    /// With --frames: write only shard I of N (0 ≤ I < N) of the frames and a partial
    /// report.json for `splatbridge merge` (see docs/scale.md). With --tiles: write only the
    /// leaves shard I owns, for --from-shards (see docs/tiles.md).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<splatbridge::batch::shard::Shard>,
    /// Write native splats (KHR_gaussian_splatting, .glb/.gltf) instead of a mesh.
    #[arg(long)]
    pub splats: bool,
    /// A .ply output is a triangle mesh PLY instead of the 3DGS PLY (also implied by --profile).
    #[arg(long, conflicts_with = "splats")]
    pub mesh: bool,
    /// With --splats: `spz` stores each primitive's Gaussians as one SPZ stream
    /// (KHR_gaussian_splatting_compression_spz_2; about 10× smaller, SPZ v3's quantisation);
    /// `none` writes float accessors (lossless).
    #[arg(long, value_enum, default_value = "none")]
    pub khr_compression: KhrCompressionArg,
    /// Keep the Gaussians with the largest opacity·s_max·s_mid within this many triangles.
    #[arg(long)]
    pub max_triangles: Option<u64>,
    /// Bake view-dependent colour for this camera (orbit:N:I, scene:I, PATH.json:I).
    #[arg(long, value_name = "CAMERA")]
    pub bake_view: Option<String>,
    /// Vertex colour encoding of glTF outputs.
    #[arg(long, value_enum, default_value = "linear")]
    pub color_encoding: ColorArg,
    /// Keep exactly coplanar splats exactly coplanar. By default each Gaussian's fans move
    /// along its normal by a hashed step of ≤ 1.2e-4 of its coordinates' magnitude, so that
    /// Cycles (which continues a ray from its last transparent hit) sees every splat of a
    /// flat surface, not one; without it such surfaces render far too transparent in Blender.
    #[arg(long)]
    pub no_coplanar_offset: bool,
    /// Do not write the _GAUSSIAN_ID attribute.
    #[arg(long)]
    pub no_ids: bool,
    /// Drop invalid Gaussians (NaN, zero quaternions) while loading instead of failing.
    #[arg(long)]
    pub drop_invalid: bool,
    /// Split off opaque surfels (GES): Gaussians with opacity ≥ --surfel-opacity and
    /// smallest/middle scale ≤ --surfel-flatness become opaque fans out to their 1/255 footprint
    /// with an OPAQUE unlit material; the rest use --profile (BLEND). glTF only.
    #[arg(long)]
    pub surfels: bool,
    /// Surfel opacity threshold (with --surfels).
    #[arg(long, value_name = "A", default_value_t = splatbridge_scene::surfels::DEFAULT_MIN_OPACITY, requires = "surfels")]
    pub surfel_opacity: f32,
    /// Surfel flatness threshold, smallest/middle scale (with --surfels).
    #[arg(long, value_name = "R", default_value_t = splatbridge_scene::surfels::DEFAULT_MAX_FLATNESS, requires = "surfels")]
    pub surfel_flatness: f32,
    /// Triangles per surfel fan (with --surfels).
    #[arg(long, value_name = "N", default_value_t = splatbridge_convert::surfels::DEFAULT_SURFEL_SEGMENTS, requires = "surfels", value_parser = super::ranges::surfel_segments)]
    pub surfel_segments: usize,
    /// How surfels are chosen (with --surfels): guarded (the hybrid's scene-scale,
    /// neighbourhood and isolation guards after the thresholds, the default) or thresholds
    /// (opacity and flatness alone).
    #[arg(long, value_enum, default_value = "guarded", requires = "surfels")]
    pub surfel_split: super::hybrid::SplitMode,
    /// Embed these cameras in glTF outputs (replacing the scene's own), in order: orbit:N,
    /// orbit:N:I, scene (the input's cameras), scene:I, PATH.json (all its cameras) or
    /// PATH.json:I; repeatable and comma-separated. Orbit cameras are 640×480 (50° field of
    /// view, up −y), as `render --camera` makes them.
    #[arg(long, value_name = "SPEC")]
    pub camera: Vec<String>,
    /// Make the mesh for this resolution: widen every Gaussian by native splatting's 0.3 px²
    /// low-pass at its depth in the cameras (--camera or the scene's own) resized to WxH, so
    /// the mesh blurs there as native does instead of aliasing. A 2DGS file's surfels are raised
    /// to 2DGS's own filter instead (σ at least √½ px, in their plane). Mesh outputs only.
    #[arg(long, value_name = "WxH", value_parser = parse_wxh, conflicts_with = "distill")]
    pub footprint_for: Option<(u32, u32)>,
    /// Mesh layout of glTF outputs (mesh profiles; not OBJ/PLY).
    #[arg(long, value_enum, default_value = "viewer")]
    pub layout: LayoutArg,
    /// Gaussians per static mesh node (0: one node); default 256 with --layout viewer.
    #[arg(long, value_name = "N")]
    pub chunk_size: Option<usize>,
    /// Order inside each mesh node; default normal with --layout viewer.
    #[arg(long, value_enum)]
    pub chunk_order: Option<ChunkOrderArg>,
    /// Triangle windings; default both with --layout viewer.
    #[arg(long, value_enum)]
    pub windings: Option<WindingsArg>,
    /// Write NORMAL (true/false); default false with --layout viewer.
    #[arg(long, value_name = "BOOL")]
    pub normals: Option<bool>,
    /// Write each part exactly far to near for this camera (orbit:N:I, scene:I, PATH.json:I),
    /// one node per part; overrides the chunking.
    #[arg(long, value_name = "CAMERA")]
    pub view_order: Option<String>,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub distill: super::distill_args::DistillArgs,
    #[command(flatten)]
    pub tiles: super::tiles::TileArgs,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.tiles.tiles.is_some() {
        return super::tiles::run(&args);
    }
    let four_d = matches!(
        splatbridge_scene::formats::detect(&args.scene),
        Ok(splatbridge_scene::formats::SplatFormat::FourD(_))
    );
    if args.objects.is_some() || (four_d && (args.frames || args.scene.is_dir())) {
        return motion::run(&args);
    }
    if args.frames_encoding == motion::FramesEncodingArg::Morph {
        anyhow::bail!(
            "{}: --frames-encoding morph takes a 4D input (numbered frames, SpacetimeGaussians PLY, .splatv, params.npz)",
            args.scene.display()
        );
    }
    let req = args.request()?;
    let t0 = Instant::now();
    let pb = common::progress(3, "loading");
    let input = req.load(&common::print_warning)?;
    pb.inc(1);
    let mut scene = input.scene;
    if let (Some((w, h)), Some(done)) = (args.footprint_for, &input.widened) {
        eprintln!(
            "footprint for {w}×{h}: {} Gaussians widened by {} (filter σ up to {:.3e} world units), {} behind every camera left as they are",
            done.widened,
            done.low_pass.name(),
            done.max_sigma,
            done.unseen
        );
    }
    if let Some(format) = input.cloud {
        pb.finish_and_clear();
        let objects = scene.objects.len();
        let c = req.write_cloud(scene, format, input.kind)?;
        return print::print_cloud(&args, &c, objects, t0.elapsed().as_secs_f64());
    }
    let mut opts = req.mesh_options(&scene, input.kind)?;
    // The --camera views' sizes name the sizes a distilled export is made for.
    let sizes: Vec<(u32, u32)> = if args.camera.is_empty() {
        Vec::new()
    } else {
        let mut s: Vec<(u32, u32)> = Vec::new();
        for c in &scene.cameras {
            if !s.contains(&(c.width, c.height)) {
                s.push((c.width, c.height));
            }
        }
        s
    };
    args.distill
        .apply(&mut scene, &mut opts, &args.scene, &sizes)?;
    pb.set_message("converting");
    pb.inc(1);
    let (mut report, effects) = req.export(&scene, &opts)?;
    pb.inc(1);
    pb.finish_and_clear();
    report.seconds = t0.elapsed().as_secs_f64();
    if args.json {
        let mut v = serde_json::to_value(&report)?;
        v["effects"] = serde_json::to_value(&effects)?;
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print::print_summary(&args, &report);
        println!("{}", effects.summary());
    }
    Ok(())
}

/// `WxH` with both sides at least 1 and at most 16384 (the renderers' limit).
pub(super) fn parse_wxh(v: &str) -> Result<(u32, u32), String> {
    let (w, h) = v
        .split_once(['x', '×'])
        .ok_or_else(|| format!("'{v}' is not WxH (e.g. 480x360)"))?;
    let side = |t: &str| -> Result<u32, String> {
        match t.trim().parse::<u32>() {
            Ok(n) if (1..=16384).contains(&n) => Ok(n),
            _ => Err(format!("'{v}': each side must be 1 to 16384 pixels")),
        }
    };
    Ok((side(w)?, side(h)?))
}
