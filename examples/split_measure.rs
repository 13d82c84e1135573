//! The hybrid against native splatting per orbit camera, for several surfel splits: the
//! measurement behind `docs/split.md`.
//!
//! `cargo run --release --example split_measure -- OUT_DIR WIDTH HEIGHT RIGS CONFIGS SCENE [SCENE …]`
//! loads each scene once, renders native splatting and the GES hybrid (default options) at
//! every camera of the rigs (`RIGS` is a comma-separated list of orbit sizes, e.g. `4,8`) with
//! each configuration of `CONFIGS`, a comma-separated list of `SPLIT:BLEND` (SPLIT `unguarded`,
//! the split before the guards, or `guarded`, the default; BLEND `sorted` or `unsorted`) or
//! `auto` (`--split auto`: split and blend measured), and prints one line per (scene, rig,
//! camera, configuration); `SPLIT:BLEND:eps=F:fp=S` also sets the ε factor and the surfel
//! footprint in σ): PSNR, surfels, the guard counts, the split and render milliseconds.
//! The worst camera of each (scene, configuration) is written as PNGs (native, hybrid) into
//! `OUT_DIR` for a person to look at.
//!
//! An example rather than a CLI subcommand: it is an instrument of the documentation.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use splatbridge::pipeline::split_auto::{blend_name, choose, AutoConfig, DISC_FOOTPRINT_SIGMAS};
use splatbridge_hybrid::ges::{render_ges, Blend, GesOptions};
use splatbridge_hybrid::{render, RenderOptions};
use splatbridge_scene::camera_spec::{CameraRequest, CameraSource, CameraSpec};
use splatbridge_scene::metrics::psnr;
use splatbridge_scene::surfels::{split_counted, SplitParams};
use splatbridge_scene::Frame;

fn run(args: &[String]) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.len() >= 6,
        "usage: OUT_DIR WIDTH HEIGHT RIGS CONFIGS SCENE [SCENE …]"
    );
    let out = PathBuf::from(&args[0]);
    std::fs::create_dir_all(&out)?;
    let (w, h): (u32, u32) = (args[1].parse()?, args[2].parse()?);
    let rigs: Vec<usize> = args[3]
        .split(',')
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    let configs: Vec<String> = args[4].split(',').map(str::to_string).collect();
    let ges = GesOptions::default();
    for path in &args[5..] {
        let scene = splatbridge::pipeline::load_scene_warn(Path::new(path), false, &|m| {
            eprintln!("warning: {m}")
        })?;
        let cloud = scene.composite(scene.time.start);
        let name = Path::new(path)
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        let d = SplitParams::default();
        let mut splits = Vec::new();
        for c in &configs {
            if c == "auto" {
                let t0 = std::time::Instant::now();
                // As `hybrid --split auto` with its default footprint (the √2σ disc).
                let base = GesOptions {
                    footprint_sigmas: DISC_FOOTPRINT_SIGMAS,
                    ..ges
                };
                let auto = choose(&cloud, &base, &AutoConfig::default())?;
                eprint!("{name}: {}", auto.summary());
                eprintln!("{name}: auto in {:.0} ms", t0.elapsed().as_secs_f64() * 1e3);
                let label = format!(
                    "auto ({}, fp {:.2})",
                    blend_name(auto.blend()),
                    auto.footprint()
                );
                let o = auto.apply(&ges);
                splits.push((label, auto.params(), o));
                continue;
            }
            let mut fields = c.split(':');
            let (split, blend) = (
                fields.next().unwrap_or_default(),
                fields
                    .next()
                    .ok_or_else(|| anyhow::anyhow!("'{c}': expected SPLIT:BLEND or auto"))?,
            );
            let mut o = ges;
            for f in fields {
                match f.split_once('=') {
                    Some(("eps", v)) => o.epsilon_factor = v.parse()?,
                    Some(("fp", v)) => o.footprint_sigmas = v.parse()?,
                    _ => anyhow::bail!("'{f}': eps=F or fp=S"),
                }
            }
            let p = match split {
                "unguarded" => SplitParams::unguarded(d.min_opacity, d.max_flatness),
                "guarded" => d,
                "none" => SplitParams::none(),
                _ => anyhow::bail!("'{split}': unguarded, guarded or none"),
            };
            let b = match blend {
                "sorted" => Blend::Sorted,
                "unsorted" => Blend::Unsorted,
                _ => anyhow::bail!("'{blend}': sorted or unsorted"),
            };
            splits.push((c.clone(), p, GesOptions { blend: b, ..o }));
        }
        let mut cams = Vec::new();
        for &n in &rigs {
            for index in 0..n {
                let req = CameraRequest {
                    width: Some(w),
                    height: Some(h),
                    ..CameraRequest::new(CameraSpec::Orbit { n, index })
                };
                cams.push((
                    n,
                    index,
                    req.resolve(CameraSource {
                        cloud: &cloud,
                        own: &[],
                    })?,
                ));
            }
        }
        let nopts = RenderOptions::default();
        let natives: Vec<Frame> = cams
            .iter()
            .map(|(_, _, c)| Ok(render(&cloud, c, &nopts)?.0))
            .collect::<anyhow::Result<_>>()?;
        for (label, p, opts) in splits {
            let ts = std::time::Instant::now();
            let (s, g, k) = split_counted(&cloud, &p);
            let split_ms = ts.elapsed().as_secs_f64() * 1e3;
            let mut worst: Option<(f64, usize, Frame)> = None;
            for (ci, ((n, i, cam), reference)) in cams.iter().zip(&natives).enumerate() {
                let tr = std::time::Instant::now();
                let (img, _) = render_ges(&s, &g, cam, &opts)?;
                let render_ms = tr.elapsed().as_secs_f64() * 1e3;
                let db = psnr(reference, &img)?;
                println!(
                    "{name}\t{label}\torbit:{n}:{i}\t{db:.2}\t{}\t{}\t{}\t{}\t{}\t{split_ms:.0}\t{render_ms:.0}",
                    s.len(),
                    k.candidates,
                    k.too_large_for_scene,
                    k.too_large_for_neighbours,
                    k.isolated
                );
                if worst.as_ref().is_none_or(|w| db < w.0) {
                    worst = Some((db, ci, img));
                }
            }
            if let Some((db, ci, img)) = worst {
                let (n, i, _) = &cams[ci];
                let stem = format!(
                    "{name}-{}-orbit{n}_{i}",
                    label.replace([':', ' ', '(', ')'], "_")
                );
                splatbridge_scene::image_io::save_frame(
                    &out.join(format!("{stem}-hybrid-{db:.1}dB.png")),
                    &img,
                )?;
                splatbridge_scene::image_io::save_frame(
                    &out.join(format!("{name}-orbit{n}_{i}-native.png")),
                    &natives[ci],
                )?;
            }
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
