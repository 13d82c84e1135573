//! `splatbridge compare`: every renderer and converter profile against native splatting at the
//! same cameras and times; images, heat-maps, `report.json` and `report.md`. The run is
//! `splatbridge::measure::compare`'s; this module parses the options and prints.

use std::path::PathBuf;

use anyhow::Context;
use splatbridge::batch::merge;
use splatbridge::batch::shard::Shard;
use splatbridge::measure::compare::{
    default_times, parse_profiles, run_compare, scene_cameras, Compared,
};
use splatbridge::measure::parity::CompareConfig;

use super::common;

#[derive(clap::Args)]
pub struct Args {
    #[arg(help = concat!("The scene: ", scene_formats!(), "."))]
    pub scene: PathBuf,
    /// Cameras, comma-separated: `orbit:N` (all N), `orbit:N:I`, `scene` (all of the scene's),
    /// `scene:I`, `PATH.json:I`.
    #[arg(long, default_value = "orbit:4")]
    pub cameras: String,
    /// Times in seconds, comma-separated (default: start, middle and end of a dynamic scene; 0
    /// for a static one).
    #[arg(long, value_delimiter = ',')]
    pub times: Vec<f64>,
    /// Converter profiles to export and trace.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "meshsplats,rings,texture"
    )]
    pub profiles: Vec<String>,
    /// Image width (orbit cameras; the scene's own cameras are resized to it).
    #[arg(long, default_value_t = 320)]
    pub width: u32,
    /// Image height.
    #[arg(long, default_value_t = 240)]
    pub height: u32,
    /// BVH backend for the traced images: obvhs or embree.
    #[arg(long, default_value = "obvhs")]
    pub backend: String,
    /// k-buffer size of the tracer.
    #[arg(long, default_value_t = 16, value_parser = super::ranges::k_buffer)]
    pub k: usize,
    /// Skip the OBJ exports (which show what losing per-vertex alpha costs).
    #[arg(long)]
    pub no_obj: bool,
    /// Drop invalid Gaussians instead of failing.
    #[arg(long)]
    pub drop_invalid: bool,
    /// Viewer clients to render the exports in, comma-separated: three, babylon, three-splats,
    /// three-splats-linear, spark, spark-native (headless chromium), eevee, cycles (Blender);
    /// through `scripts/client-render.sh`, at the first time. A client that is not installed
    /// is reported as skipped with the reason.
    #[arg(long, value_name = "LIST")]
    pub clients: Option<String>,
    /// The client dispatcher script (default: the repository's scripts/client-render.sh).
    #[arg(long, value_name = "PATH")]
    pub client_script: Option<PathBuf>,
    /// Skip a Gaussian-trace or mesh stage whose estimated peak memory is over this: `auto`
    /// (the machine's physical memory), `none`, or a size such as `16G` or `512M`. A skipped
    /// stage is a note in the report with its size and estimate (docs/scale.md).
    #[arg(long, value_name = "SIZE", default_value = "auto")]
    pub max_memory: String,
    /// Do only shard I of N (0 ≤ I < N) of the (time, camera) items and write a partial
    /// report.json for `splatbridge merge` (see docs/scale.md).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<Shard>,
    /// The reference renderer: auto (2D Gaussian Splatting's rasterizer for 2DGS surfels, with
    /// their 3DGS splatting measured beside it; 3DGS splatting for everything else), 3dgs, or
    /// 2dgs (2DGS files only).
    #[arg(long, value_enum, default_value_t = super::render::ModelArg::Auto)]
    pub model: super::render::ModelArg,
    #[command(flatten)]
    pub hybrid_split: super::split_args::SplitArgs,
    /// Output folder.
    #[arg(short, long, alias = "output")]
    pub out: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // Options first: a bad one is reported before a large scene is loaded.
    let max_memory = splatbridge::measure::budget::parse_budget(&args.max_memory)
        .map_err(|e| anyhow::anyhow!("--max-memory: {e}"))?;
    let (mut scene, kind) = splatbridge::pipeline::load_scene_kind(
        &args.scene,
        args.drop_invalid,
        &common::print_warning,
    )?;
    let surfels_2d =
        super::render::model_is_2dgs(args.model, kind, &args.scene.display().to_string())?;
    let times = if args.times.is_empty() {
        default_times(&scene)
    } else {
        args.times.clone()
    };
    let cams = scene_cameras(&args.cameras, &scene, &times, args.width, args.height)?;
    // The hybrid's split and blend; `--split auto` measures them on the first time's composite.
    let hybrid = args
        .hybrid_split
        .resolve(|| scene.composite(times[0]), CompareConfig::default().ges)
        .with_context(|| args.scene.display().to_string())?;
    if let Some(a) = &hybrid.auto {
        print!("{}", a.summary());
    }
    let cfg = CompareConfig {
        split: hybrid.params,
        ges: hybrid.ges,
        profiles: parse_profiles(&args.profiles)?,
        obj: !args.no_obj,
        backend: args.backend.parse()?,
        k: args.k,
        clients: match &args.clients {
            Some(l) => splatbridge::measure::clients::Client::parse_list(l)
                .map_err(|e| anyhow::anyhow!("--clients: {e}"))?,
            None => Vec::new(),
        },
        client_script: args
            .client_script
            .clone()
            .unwrap_or_else(splatbridge::measure::clients::default_script),
        max_memory,
        surfels_2d,
        ..CompareConfig::default()
    };
    let pb = common::progress(0, "compare");
    let progress = |m: &str| pb.set_message(m.to_string());
    let preamble = format!(
        "Scene `{}`: {} cameras × {} times, {}×{} pixels. Reference: {} with reference settings. \
         PSNR/SSIM against the reference; milliseconds are render times on this machine (BVH builds and exports excluded).",
        args.scene.display(),
        cams.len(),
        times.len(),
        args.width,
        args.height,
        if surfels_2d {
            "2DGS surfels by 2D Gaussian Splatting's rasterizer (native-2dgs)"
        } else {
            "native splatting"
        }
    );
    let options = options_text(&args, &times);
    let compared = run_compare(
        &mut scene, &cams, &times, &cfg, &args.out, args.shard, &options, preamble, &progress,
    )?;
    pb.finish_and_clear();
    let peak = splatbridge::measure::memory::peak_bytes().unwrap_or(0) as f64 / 1e6;
    match compared {
        Compared::Shard(shard, n) => {
            println!("shard {shard}: {n} records; peak memory {peak:.1} MB");
            println!("wrote {}", args.out.join(merge::REPORT).display());
        }
        Compared::Whole(records) => {
            print_summary(&records);
            println!("peak memory {peak:.1} MB");
            println!("wrote {}", args.out.join("report.md").display());
        }
    }
    Ok(())
}

/// Every option that changes a comparison's outputs, as text (hashed into a shard's report, so
/// shards of differently configured runs do not merge). `--shard` and `--out` are not in it.
fn options_text(args: &Args, times: &[f64]) -> String {
    format!(
        "compare\ncameras={}\ntimes={:?}\nprofiles={:?}\nsize={}x{}\nbackend={}\nk={}\nno_obj={}\ndrop_invalid={}\nclients={:?}\nhybrid={}\nmax_memory={}\nmodel={:?}",
        args.cameras,
        times.iter().map(|t| t.to_bits()).collect::<Vec<_>>(),
        args.profiles,
        args.width,
        args.height,
        args.backend,
        args.k,
        args.no_obj,
        args.drop_invalid,
        args.clients,
        args.hybrid_split.text(),
        args.max_memory,
        args.model
    )
}

/// Mean PSNR per renderer/profile/format, one line each.
pub fn print_summary(records: &[splatbridge::measure::report::Record]) {
    let mut keys: Vec<(String, String, String)> = Vec::new();
    for r in records {
        let k = (r.renderer.clone(), r.profile.clone(), r.format.clone());
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    for r in records.iter().filter(|r| !r.note.is_empty()) {
        println!("{}: {}", label(&r.renderer, &r.profile, &r.format), r.note);
    }
    let measured: Vec<_> = records.iter().filter(|r| r.note.is_empty()).collect();
    for (renderer, profile, format) in keys {
        if !measured
            .iter()
            .any(|r| r.renderer == renderer && r.profile == profile && r.format == format)
        {
            continue;
        }
        let sel: Vec<_> = measured
            .iter()
            .filter(|r| r.renderer == renderer && r.profile == profile && r.format == format)
            .copied()
            .collect();
        let finite: Vec<f64> = sel
            .iter()
            .map(|r| r.psnr)
            .filter(|p| p.is_finite())
            .collect();
        let psnr = if finite.is_empty() {
            "reference".to_string()
        } else {
            format!("{:.2} dB", finite.iter().sum::<f64>() / finite.len() as f64)
        };
        let ms = sel.iter().map(|r| r.milliseconds).sum::<f64>() / sel.len() as f64;
        let name = label(&renderer, &profile, &format);
        println!("{name:28} PSNR {psnr:>10}  {ms:8.1} ms/frame");
    }
}

/// "renderer profile format", empty parts left out.
fn label(renderer: &str, profile: &str, format: &str) -> String {
    [renderer, profile, format]
        .iter()
        .filter(|s| !s.is_empty())
        .copied()
        .collect::<Vec<_>>()
        .join(" ")
}
