//! `splatbridge convert`: Gaussians to triangle meshes (GLB/glTF/OBJ/PLY), native glTF
//! splats (`KHR_gaussian_splatting`) or single-cloud splat files (3DGS PLY, compressed PLY,
//! `.splat`, `.spz`). The work is done by `splatbridge::pipeline::export` (over
//! `splatbridge-convert` and `splatbridge_scene::formats`); this module parses the command
//! line, shows progress and prints the summary.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use clap::ValueEnum;
use splatbridge::pipeline::export::{
    cloud_format, embedded_cameras, export_scene, is_gltf, load_export_input, ply_holds_gaussians,
    write_cloud_export, ExportKind, OutputFormat,
};
use splatbridge_convert::options::ChunkOrder;
use splatbridge_convert::splats_gltf::KhrCompression;
use splatbridge_convert::{
    ColorEncoding, ConvertOptions, ConvertReport, Profile, UpAxis, VolumetricMode,
};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::formats::ksplat::KsplatOptions;
use splatbridge_scene::formats::CloudFormat;

use crate::cmd::common::{self, CameraArgs};

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ProfileArg {
    /// MeshSplats baseline: 8-vertex rim at 2.7σ, rim alpha 0.2·opacity.
    Meshsplats,
    /// Concentric rings following opacity·exp(−r²/2) out to the 1/255 footprint.
    Rings,
    /// One textured quad per fan; a shared radial falloff texture carries the profile.
    Texture,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum VolumetricArg {
    /// Three orthogonal fans with an optical-depth correction.
    ThreeFans,
    /// One fan in the plane of the two largest axes.
    Flat,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum UpArg {
    /// Input is Y-up already.
    Y,
    /// Input is Z-up.
    Z,
    /// Input up is −Y (COLMAP / 3DGS captures).
    #[value(name = "-y")]
    NegY,
}

/// Output formats for `--format` (overriding the extension of -o).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// The 3DGS PLY, or a mesh PLY with --mesh or --profile.
    Ply,
    /// The standard 3DGS PLY (lossless splats).
    SplatPly,
    /// SuperSplat/PlayCanvas compressed PLY.
    CompressedPly,
    /// antimatter15 .splat.
    Splat,
    /// Niantic SPZ (--spz-version).
    Spz,
    /// Binary glTF (mesh, or KHR_gaussian_splatting with --splats).
    Glb,
    /// glTF JSON + .bin (mesh, or KHR_gaussian_splatting with --splats).
    Gltf,
    /// Wavefront OBJ mesh.
    Obj,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LayoutArg {
    /// For stock viewers that blend in file order (three.js, Babylon.js, EEVEE): spatial
    /// chunks as nodes, each ordered along its normal, both windings single-sided, no NORMAL.
    Viewer,
    /// One node per scene part in the input's order, doubleSided material, with NORMAL.
    Input,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ChunkOrderArg {
    /// The input's order.
    Input,
    /// Along each chunk's dominant normal.
    Normal,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum WindingsArg {
    /// Every triangle twice (both windings) with a single-sided material.
    Both,
    /// One winding and a doubleSided material.
    Double,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ColorArg {
    /// glTF's linear COLOR_0 (display colours sRGB-decoded).
    Linear,
    /// 3DGS display values written as they are.
    Display,
}

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
    /// Input scene: a 3DGS PLY, a splatbridge-scene/1 manifest, or a KHR_gaussian_splatting glTF.
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
    /// OBJ only: write one OBJ per frame of a dynamic scene (OUT_0000.obj, …).
    #[arg(long)]
    pub frames: bool,
    /// With --frames: write only shard I of N (0 ≤ I < N) of the frames and a partial
    /// report.json for `splatbridge merge` (see docs/scale.md). With --tiles: write only the
    /// leaves shard I owns, for --from-shards (see docs/tiles.md).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<splatbridge::shard::Shard>,
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
    /// the mesh blurs there as native does instead of aliasing. Mesh outputs only.
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

impl From<FormatArg> for OutputFormat {
    fn from(f: FormatArg) -> Self {
        match f {
            FormatArg::Ply => OutputFormat::Ply,
            FormatArg::SplatPly => OutputFormat::SplatPly,
            FormatArg::CompressedPly => OutputFormat::CompressedPly,
            FormatArg::Splat => OutputFormat::Splat,
            FormatArg::Spz => OutputFormat::Spz,
            FormatArg::Glb => OutputFormat::Glb,
            FormatArg::Gltf => OutputFormat::Gltf,
            FormatArg::Obj => OutputFormat::Obj,
        }
    }
}

/// Write a single-cloud splat file and print what was written.
fn write_cloud_output(
    args: &Args,
    scene: DynamicScene,
    format: CloudFormat,
    t0: Instant,
) -> anyhow::Result<()> {
    for (set, name) in [
        (args.surfels, "--surfels"),
        (args.frames, "--frames"),
        (args.bake_view.is_some(), "--bake-view"),
        (args.max_triangles.is_some(), "--max-triangles"),
    ] {
        if set {
            bail!(
                "{}: {name} applies to meshes, not to a {} output",
                args.output.display(),
                format.name()
            );
        }
    }
    let objects = scene.objects.len();
    let c = write_cloud_export(scene, &args.output, format, args.time, args.first)?;
    let seconds = t0.elapsed().as_secs_f64();
    if args.json {
        let v = serde_json::json!({
            "input": args.scene.display().to_string(),
            "output": args.output.display().to_string(),
            "format": c.format,
            "gaussians": c.gaussians,
            "sh_degree": c.sh_degree,
            "time": c.time,
            "bytes": c.bytes,
            "seconds": seconds,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        eprintln!(
            "{} → {} ({}, {} Gaussians, SH degree {}{})",
            args.scene.display(),
            args.output.display(),
            c.format,
            c.gaussians,
            c.sh_degree,
            if objects == 0 {
                String::new()
            } else {
                format!(", composited at t = {}", c.time)
            }
        );
        eprintln!(
            "  bytes          {:>12}  ({:.1} MB)",
            c.bytes,
            c.bytes as f64 / 1e6
        );
        eprintln!("  time           {seconds:>12.3} s");
    }
    Ok(())
}

/// `--khr-compression`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum KhrCompressionArg {
    /// Float accessors.
    None,
    /// KHR_gaussian_splatting_compression_spz_2.
    Spz,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.tiles.tiles.is_some() {
        return super::tiles::run(&args);
    }
    if args.khr_compression != KhrCompressionArg::None && !args.splats {
        bail!("--khr-compression: applies to --splats glTF outputs only");
    }
    let surfel_guarded = match args.surfel_split {
        super::hybrid::SplitMode::Guarded => true,
        super::hybrid::SplitMode::Thresholds => false,
        super::hybrid::SplitMode::Auto => bail!(
            "--surfel-split auto: an export has no renderer to measure it with; use guarded or thresholds"
        ),
    };
    let t0 = Instant::now();
    let cloud_out = cloud_format(
        &args.output,
        args.format.map(OutputFormat::from),
        ply_holds_gaussians(args.splats, args.mesh || args.profile.is_some()),
        args.spz_version,
    )?
    .map(|f| match f {
        CloudFormat::Ksplat(o) => CloudFormat::Ksplat(KsplatOptions {
            level: args.ksplat_level,
            ..o
        }),
        f => f,
    });
    let pb = common::progress(3, "loading");
    let mut scene = load_export_input(&args.scene, args.drop_invalid, &common::print_warning)?;
    if !args.camera.is_empty() {
        scene.cameras = embedded_cameras(&args.camera, &scene)?;
    }
    pb.inc(1);
    if args.first.is_some() && cloud_out.is_none() {
        bail!("--first applies to single-cloud splat outputs (.ply without --mesh, .splat, .spz, .compressed.ply)");
    }
    if let Some((w, h)) = args.footprint_for {
        if cloud_out.is_some() {
            bail!("--footprint-for: widens Gaussians for a mesh export; a splat output keeps the Gaussians native splatting filters itself");
        }
        let done = splatbridge::footprint_export::widen_scene_for(&mut scene, w, h)
            .map_err(|e| anyhow::anyhow!("--footprint-for: {e}"))?;
        eprintln!(
            "footprint for {w}×{h}: {} Gaussians widened (largest σ added {:.3e}), {} behind every camera left as they are",
            done.widened, done.max_sigma, done.unseen
        );
    }
    if let Some(format) = cloud_out {
        pb.finish_and_clear();
        return write_cloud_output(&args, scene, format, t0);
    }
    let mut opts = ConvertOptions {
        profile: match args.profile {
            Some(ProfileArg::Meshsplats) => Profile::MeshSplats,
            Some(ProfileArg::Rings) => Profile::Rings,
            Some(ProfileArg::Texture) => Profile::Texture,
            None if is_gltf(&args.output) => Profile::Texture,
            None => Profile::Rings,
        },
        segments: args.segments,
        rings: args.rings,
        volumetric: match args.volumetric {
            VolumetricArg::ThreeFans => VolumetricMode::ThreeFans,
            VolumetricArg::Flat => VolumetricMode::Flat,
        },
        flat_ratio: args.flat_ratio,
        up: match args.up {
            UpArg::Y => UpAxis::Y,
            UpArg::Z => UpAxis::Z,
            UpArg::NegY => UpAxis::NegY,
        },
        max_triangles: args.max_triangles,
        color_encoding: match args.color_encoding {
            ColorArg::Linear => ColorEncoding::Linear,
            ColorArg::Display => ColorEncoding::Display,
        },
        gaussian_ids: !args.no_ids,
        coplanar_offset: !args.no_coplanar_offset,
        surfels: args
            .surfels
            .then_some(splatbridge_convert::surfels::SurfelOptions {
                min_opacity: args.surfel_opacity,
                max_flatness: args.surfel_flatness,
                segments: args.surfel_segments,
                guarded: surfel_guarded,
            }),
        ..Default::default()
    };
    if args.surfels && (args.splats || !is_gltf(&args.output)) {
        bail!(
            "{}: --surfels writes a mesh glTF (.glb or .gltf), not {}",
            args.output.display(),
            if args.splats {
                "--splats"
            } else {
                "OBJ or PLY"
            }
        );
    }
    let gltf_mesh = is_gltf(&args.output) && !args.splats;
    let viewer = gltf_mesh && args.layout == LayoutArg::Viewer && !args.surfels;
    if viewer {
        opts = opts.for_viewers();
    }
    if let Some(n) = args.chunk_size {
        opts.chunk_size = n;
    }
    if let Some(o) = args.chunk_order {
        opts.chunk_order = match o {
            ChunkOrderArg::Input => ChunkOrder::Input,
            ChunkOrderArg::Normal => ChunkOrder::Normal,
        };
    }
    if let Some(w) = args.windings {
        opts.both_windings = matches!(w, WindingsArg::Both);
    }
    if let Some(n) = args.normals {
        opts.normals = n;
    }
    if let Some(spec) = &args.view_order {
        let cam_args = CameraArgs {
            camera: Some(spec.clone()),
            ..Default::default()
        };
        let composite = scene.composite_view(scene.time.start);
        let cam = cam_args
            .resolve(&composite, &scene.cameras)
            .with_context(|| format!("--view-order {spec}"))?;
        opts.view_order_name = Some(format!("{spec} ({})", cam.name));
        opts.view_order = Some(cam);
        if args.windings.is_none() {
            opts.both_windings = true;
        }
    }
    if opts.arranged() && !gltf_mesh {
        bail!(
            "{}: --chunk-size, --chunk-order, --windings and --view-order arrange glTF meshes (.glb or .gltf without --splats)",
            args.output.display()
        );
    }
    if let Some(spec) = &args.bake_view {
        let cam_args = CameraArgs {
            camera: Some(spec.clone()),
            up: glam::DVec3::NEG_Y,
            fov: 50.0,
            ..Default::default()
        };
        let composite = scene.composite_view(scene.time.start);
        let cam = cam_args
            .resolve(&composite, &scene.cameras)
            .with_context(|| format!("--bake-view {spec}"))?;
        opts.bake_view_name = Some(format!("{spec} ({})", cam.name));
        opts.bake_view = Some(cam);
    }
    if args.frames
        && !args
            .output
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("obj"))
    {
        bail!(
            "{}: --frames writes one OBJ per frame; use an .obj output",
            args.output.display()
        );
    }
    if args.shard.is_some() && !args.frames {
        bail!("--shard: applies to --frames and --tiles");
    }
    if args.shard.is_some() && args.splats {
        bail!("--shard splits --frames OBJ exports, not --splats");
    }
    if args.distill.distill && (!gltf_mesh || args.frames) {
        bail!(
            "{}: --distill fits a mesh glTF (.glb or .gltf without --splats)",
            args.output.display()
        );
    }
    args.distill.apply(&mut scene, &mut opts)?;
    pb.set_message("converting");
    pb.inc(1);
    let kind = if args.splats {
        ExportKind::Splats(match args.khr_compression {
            KhrCompressionArg::None => KhrCompression::None,
            KhrCompressionArg::Spz => KhrCompression::Spz,
        })
    } else {
        ExportKind::Mesh {
            frames: args.frames,
        }
    };
    let (mut report, effects) = match args.shard {
        Some(shard) => splatbridge::pipeline::export_shard::export_obj_frames_shard(
            &scene,
            &args.scene,
            &args.output,
            &opts,
            shard,
        )?,
        None => export_scene(&scene, &args.scene, &args.output, &opts, kind)?,
    };
    pb.inc(1);
    pb.finish_and_clear();
    report.seconds = t0.elapsed().as_secs_f64();
    if args.json {
        let mut v = serde_json::to_value(&report)?;
        v["effects"] = serde_json::to_value(&effects)?;
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print_summary(&args, &report);
        println!("{}", effects.summary());
    }
    Ok(())
}

fn print_summary(args: &Args, r: &ConvertReport) {
    eprintln!(
        "{} → {} ({}, profile {}, {} segments, {} rings)",
        args.scene.display(),
        args.output.display(),
        r.format,
        r.profile,
        r.segments,
        r.rings
    );
    let kept: u64 = r.meshes.iter().map(|m| m.flat + m.volumetric).sum();
    let flat: u64 = r.meshes.iter().map(|m| m.flat).sum();
    eprintln!("  Gaussians in   {:>12}", r.gaussians_in);
    eprintln!(
        "  kept           {:>12}  ({} flat, {} volumetric)",
        kept,
        flat,
        kept - flat
    );
    for (what, n) in [
        ("invalid", r.dropped_invalid),
        ("below 1/255 opacity", r.dropped_transparent),
        ("scale overflow", r.dropped_overflow),
        ("triangle budget", r.dropped_budget),
    ] {
        if n > 0 {
            eprintln!("  dropped        {n:>12}  ({what})");
        }
    }
    if let Some(s) = &r.surfels {
        eprintln!(
            "  surfels        {:>12}  (opacity ≥ {}, flatness ≤ {}, {}, {}-segment opaque fans{})",
            s.surfels,
            s.min_opacity,
            s.max_flatness,
            if s.guarded {
                format!("guarded: {} kept as Gaussians", s.guarded_out)
            } else {
                "unguarded".to_string()
            },
            s.segments,
            if s.dropped_overflow > 0 {
                format!(", {} dropped: scale overflow", s.dropped_overflow)
            } else {
                String::new()
            }
        );
        eprintln!(
            "  residual       {:>12}  (Gaussians left to profile {})",
            s.residual, r.profile
        );
    }
    if r.triangles > 0 {
        eprintln!("  vertices       {:>12}", r.vertices);
        eprintln!("  triangles      {:>12}", r.triangles);
    }
    eprintln!(
        "  bytes          {:>12}  ({:.1} MB)",
        r.bytes,
        r.bytes as f64 / 1e6
    );
    eprintln!("  time           {:>12.3} s", r.seconds);
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
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
