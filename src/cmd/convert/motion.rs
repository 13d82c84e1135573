//! `convert SEQUENCE --objects auto|none` and `convert SEQUENCE --frames -o OUT.glb`: a frame
//! sequence decomposed (`splatbridge::pipeline::motion`) into a manifest or a glTF, or kept
//! whole per frame; this module checks the options and prints the report.

use std::time::Instant;

use anyhow::bail;
use clap::ValueEnum;
use splatbridge::pipeline::export::is_gltf;
use splatbridge::pipeline::motion::{decompose_scene, frames_scene, read_frames, MotionReport};
use splatbridge_convert::motion::DecomposeOptions;

use super::Args;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ObjectsArg {
    /// Static background, rigid objects with tracks, per-frame content for the rest.
    Auto,
    /// Static background and per-frame content (no rigid objects).
    None,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    if let Some(t) = args.motion_tolerance {
        if !(t > 0.0 && t.is_finite()) {
            bail!("--motion-tolerance: {t} is not a positive distance");
        }
    }
    let gltf = is_gltf(&args.output);
    if args.objects.is_none() && !(gltf && args.frames) {
        bail!(
            "{}: a frame sequence converts with --objects auto|none (-o DIR or a .glb/.gltf) or with --frames and a .glb/.gltf output",
            args.scene.display()
        );
    }
    if args.objects.is_some() && args.frames {
        bail!("--frames keeps every frame whole; --objects decomposes them: give one");
    }
    if args.splats {
        bail!("--splats: a frame sequence exports as a mesh glTF (per-frame content is meshed)");
    }
    let t0 = Instant::now();
    let fps = splatbridge_scene::fourd::frame_rate();
    let (frames, times) = read_frames(&args.scene, fps, args.objects.is_some())?;
    let (scene, report) = match args.objects {
        Some(mode) => {
            let opts = DecomposeOptions {
                objects: mode == ObjectsArg::Auto,
                tolerance: args.motion_tolerance,
                min_group: args.min_group.max(1),
                ..DecomposeOptions::default()
            };
            let (scene, report) = decompose_scene(&frames, &times, fps, &opts)?;
            (scene, Some(report))
        }
        None => (frames_scene(frames, &times, fps)?, None),
    };
    if let Some(r) = &report {
        print_motion(args, r);
    }
    if !gltf {
        if args.output.extension().is_some() && !args.output.is_dir() {
            bail!(
                "{}: --objects writes a manifest into a folder (-o DIR) or a .glb/.gltf",
                args.output.display()
            );
        }
        let saved = splatbridge_scene::manifest::save_manifest(&args.output, &scene)?;
        if !args.json {
            println!(
                "wrote {} ({} files) in {:.2} s",
                saved.manifest.display(),
                saved.files.len(),
                t0.elapsed().as_secs_f64()
            );
        }
        return Ok(());
    }
    let req = args.request()?;
    let opts = req.mesh_options(&scene, splatbridge_scene::ply::GaussianKind::default())?;
    let (mut conv, _) = req.export(&scene, &opts)?;
    conv.seconds = t0.elapsed().as_secs_f64();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&conv)?);
    } else {
        super::print::print_summary(args, &conv);
    }
    Ok(())
}

fn print_motion(args: &Args, r: &MotionReport) {
    if args.json {
        if let Ok(s) = serde_json::to_string_pretty(r) {
            eprintln!("{s}");
        }
        return;
    }
    println!(
        "{} frames of {} Gaussians: noise σ ≈ {:.3e}, tolerance {:.3e} (world units), {:.2} s",
        r.frames, r.gaussians, r.noise, r.tolerance, r.seconds
    );
    println!(
        "  static      {:>9} Gaussians, RMS {:.3e} from their mean",
        r.static_gaussians, r.static_rms
    );
    for g in &r.groups {
        println!(
            "  {:<11} {:>9} Gaussians, rigid fit RMS {:.3e}, max {:.3e}",
            g.name, g.gaussians, g.rms, g.max
        );
    }
    println!(
        "  per frame   {:>9} Gaussians ({} frames × {} = {} kept per frame)",
        r.per_frame_gaussians,
        r.frames,
        r.per_frame_gaussians,
        r.frames * r.per_frame_gaussians
    );
}
