//! `splatbridge fixture`: generate deterministic synthetic scenes (street, large, hard) from a
//! seed, and print what was written.
//!
//! The street takes training-free edits: `--effects rain,shadows,lidar` declares effects,
//! `--insert car:lane_change` (or `ASSET.ply:RULE`) inserts an object whose manifest entry keeps
//! its trajectory rule, `--remove NAME` marks an object removed, `--retime NAME:OFFSET:SCALE`
//! replays an object's motion. The written manifest is loaded back before the command succeeds.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use splatbridge_scene::fixtures::{
    self, StreetEdits, StreetParams, DEFAULT_STREET_GAUSSIANS, STREET_RULES,
};
use splatbridge_scene::image_io::write_atomic;
use splatbridge_scene::manifest::{load_manifest, parse_manifest, save_manifest};
use splatbridge_scene::ply::{read_ply, write_ply, PlyFormat, ReadOptions};
use splatbridge_scene::trajectory::Retime;

#[derive(clap::Args)]
pub struct Args {
    /// street (a dynamic manifest scene), large (one big PLY) or hard (one PLY per hard case).
    pub name: String,
    /// Output directory (created if needed).
    #[arg(short, long, alias = "output")]
    pub out: PathBuf,
    /// Number of Gaussians: total for street (default 16000), exact for large (default 1000000).
    #[arg(long)]
    pub count: Option<usize>,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Street: effects to declare, comma-separated (rain, snow, motion_blur, shadows, lidar).
    #[arg(long, value_delimiter = ',')]
    pub effects: Vec<String>,
    /// Street: insert an object, `car:RULE` or `ASSET.ply:RULE` with RULE one of straight,
    /// lane_change, turn, stop (repeatable).
    #[arg(long)]
    pub insert: Vec<String>,
    /// Street: mark an object removed in the manifest (repeatable).
    #[arg(long)]
    pub remove: Vec<String>,
    /// Street: retime an object, `NAME:OFFSET:SCALE` (motion SCALE× as fast, OFFSET s later).
    #[arg(long)]
    pub retime: Vec<String>,
}

fn parse_retime(s: &str) -> anyhow::Result<(String, Retime)> {
    let parts: Vec<&str> = s.rsplitn(3, ':').collect();
    let [scale, offset, name] = parts[..] else {
        bail!("--retime '{s}': expected NAME:OFFSET:SCALE");
    };
    let offset: f64 = offset
        .parse()
        .with_context(|| format!("--retime '{s}': offset '{offset}' is not a number"))?;
    let scale: f64 = scale
        .parse()
        .with_context(|| format!("--retime '{s}': scale '{scale}' is not a number"))?;
    let r = Retime { offset, scale };
    r.check().with_context(|| format!("--retime '{s}'"))?;
    Ok((name.to_string(), r))
}

fn street_edits(args: &Args) -> anyhow::Result<StreetEdits> {
    let mut edits = StreetEdits {
        effects: args.effects.iter().map(|e| e.trim().to_string()).collect(),
        inserts: Vec::new(),
    };
    for spec in &args.insert {
        let Some((asset, rule)) = spec.rsplit_once(':') else {
            bail!(
                "--insert '{spec}': expected car:RULE or ASSET.ply:RULE (rules: {})",
                STREET_RULES.join(", ")
            );
        };
        let cloud = if asset == "car" {
            None
        } else {
            let (c, report) = read_ply(Path::new(asset), &ReadOptions::default())?;
            for w in report.warnings {
                eprintln!("warning: {asset}: {w}");
            }
            Some(c)
        };
        edits.inserts.push((rule.to_string(), cloud));
    }
    Ok(edits)
}

/// Rewrite the saved manifest: inserted objects keep their rule instead of explicit keys,
/// removed and retimed objects get their edits; then load it back to validate.
fn patch_manifest(
    path: &Path,
    inserted: &[fixtures::Inserted],
    remove: &[String],
    retime: &[(String, Retime)],
) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let mut m = parse_manifest(path, &text)?;
    let find = |name: &str, what: &str| -> anyhow::Result<usize> {
        m.objects
            .iter()
            .position(|o| o.name == name)
            .with_context(|| {
                let names: Vec<&str> = m.objects.iter().map(|o| o.name.as_str()).collect();
                format!(
                    "{what} '{name}': no such object (objects: {})",
                    names.join(", ")
                )
            })
    };
    let mut edits = Vec::new();
    for ins in inserted {
        edits.push((
            find(&ins.name, "insert")?,
            Some(ins.rule.clone()),
            false,
            None,
        ));
    }
    for name in remove {
        edits.push((find(name, "--remove")?, None, true, None));
    }
    for (name, r) in retime {
        edits.push((find(name, "--retime")?, None, false, Some(*r)));
    }
    for (k, rule, rm, rt) in edits {
        let o = &mut m.objects[k];
        if let Some(rule) = rule {
            o.track = None;
            o.trajectory = Some(rule);
        }
        o.remove |= rm;
        if rt.is_some() {
            o.retime = rt;
        }
    }
    let mut text = serde_json::to_string_pretty(&m)?;
    text.push('\n');
    write_atomic(path, text.as_bytes())?;
    load_manifest(path, &ReadOptions::default())?;
    Ok(())
}

fn describe(path: &Path, what: &str) {
    let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    println!("wrote {} ({size} bytes){what}", path.display());
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let edited = !(args.effects.is_empty()
        && args.insert.is_empty()
        && args.remove.is_empty()
        && args.retime.is_empty());
    if edited && args.name != "street" {
        bail!("fixture {}: --effects, --insert, --remove and --retime apply to the street fixture only", args.name);
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create directory", args.out.display()))?;
    match args.name.as_str() {
        "street" => {
            let n = args.count.unwrap_or(DEFAULT_STREET_GAUSSIANS);
            let retime: Vec<(String, Retime)> = args
                .retime
                .iter()
                .map(|s| parse_retime(s))
                .collect::<anyhow::Result<_>>()?;
            let edits = street_edits(&args)?;
            let (scene, inserted) =
                fixtures::street_edited(&StreetParams::new(args.seed, n), &edits)
                    .map_err(|e| anyhow::anyhow!("fixture street: {e}"))?;
            // Name checks before anything is written.
            let names: Vec<&str> = scene.objects.iter().map(|o| o.name.as_str()).collect();
            for name in args.remove.iter().chain(retime.iter().map(|(n, _)| n)) {
                if !names.contains(&name.as_str()) {
                    bail!(
                        "fixture street: no object '{name}' to edit (objects: {})",
                        names.join(", ")
                    );
                }
            }
            let saved = save_manifest(&args.out, &scene)?;
            if !inserted.is_empty() || !args.remove.is_empty() || !retime.is_empty() {
                patch_manifest(&saved.manifest, &inserted, &args.remove, &retime)?;
            }
            for f in &saved.files {
                let name = f
                    .file_name()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
                let what = match name.as_str() {
                    "static.ply" => format!(": {} static Gaussians", scene.static_gaussians.len()),
                    "cameras.json" => format!(": {} cameras", scene.cameras.len()),
                    "scene.json" => format!(
                        ": manifest, {} objects, {} frames over {}..{} s{}",
                        scene.objects.len(),
                        scene.frame_times().len(),
                        scene.time.start,
                        scene.time.end,
                        if scene.effects.is_empty() {
                            String::new()
                        } else {
                            format!(
                                ", effects: {}",
                                scene.effects.keys().cloned().collect::<Vec<_>>().join(", ")
                            )
                        }
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
