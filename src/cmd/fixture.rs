//! `splatbridge fixture`: generate deterministic synthetic scenes (street, large, hard) from a
//! seed, and print what was written.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use splatbridge_scene::fixtures::{self, StreetParams, DEFAULT_STREET_GAUSSIANS};
use splatbridge_scene::manifest::save_manifest;
use splatbridge_scene::ply::{write_ply, PlyFormat};

#[derive(clap::Args)]
pub struct Args {
    /// street (a dynamic manifest scene), large (one big PLY) or hard (one PLY per hard case).
    pub name: String,
    /// Output directory (created if needed).
    #[arg(short, long)]
    pub out: PathBuf,
    /// Number of Gaussians: total for street (default 16000), exact for large (default 1000000).
    #[arg(long)]
    pub count: Option<usize>,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

fn describe(path: &Path, what: &str) {
    let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    println!("wrote {} ({size} bytes){what}", path.display());
}

pub fn run(args: Args) -> anyhow::Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create directory", args.out.display()))?;
    match args.name.as_str() {
        "street" => {
            let n = args.count.unwrap_or(DEFAULT_STREET_GAUSSIANS);
            let scene = fixtures::street_with(&StreetParams::new(args.seed, n));
            let saved = save_manifest(&args.out, &scene)?;
            for f in &saved.files {
                let name = f
                    .file_name()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
                let what = match name.as_str() {
                    "static.ply" => format!(": {} static Gaussians", scene.static_gaussians.len()),
                    "cameras.json" => format!(": {} cameras", scene.cameras.len()),
                    "scene.json" => format!(
                        ": manifest, {} objects, {} frames over {}..{} s",
                        scene.objects.len(),
                        scene.frame_times().len(),
                        scene.time.start,
                        scene.time.end
                    ),
                    _ => scene
                        .objects
                        .iter()
                        .find(|o| format!("{}.ply", o.name) == name)
                        .map(|o| {
                            format!(": object {} with {} Gaussians", o.name, o.gaussians.len())
                        })
                        .unwrap_or_default(),
                };
                describe(f, &what);
            }
        }
        "large" => {
            let n = args.count.unwrap_or(1_000_000);
            let cloud = fixtures::large(n, args.seed);
            let p = args.out.join("large.ply");
            write_ply(&p, &cloud, PlyFormat::BinaryLittleEndian)?;
            describe(&p, &format!(": {n} Gaussians, SH degree 3"));
        }
        "hard" => {
            if args.count.is_some() {
                bail!("fixture hard: --count does not apply (the hard cases have fixed sizes)");
            }
            for (name, cloud) in fixtures::hard() {
                let p = args.out.join(format!("{name}.ply"));
                write_ply(&p, &cloud, PlyFormat::BinaryLittleEndian)?;
                describe(&p, &format!(": {} Gaussians", cloud.len()));
            }
        }
        other => bail!("unknown fixture '{other}' (known: street, large, hard)"),
    }
    Ok(())
}
