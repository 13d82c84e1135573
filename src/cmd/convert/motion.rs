//! `convert SEQUENCE --objects auto|none` and `convert SEQUENCE --frames -o OUT.glb`: a frame
//! sequence decomposed (`splatbridge::pipeline::motion`) into a manifest or a glTF, or kept
//! whole per frame; this module checks the options and prints the report.

use std::time::Instant;

use anyhow::bail;
use clap::ValueEnum;
use splatbridge::pipeline::export::is_gltf;
use splatbridge::pipeline::motion::{
    decompose_path, export_frames, frames_scene, open_model, FramesEncoding, FramesWritten,
    MotionReport,
};
use splatbridge_convert::motion::DecomposeOptions;

use super::Args;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ObjectsArg {
    /// Static background, rigid objects with tracks, per-frame content for the rest.
    Auto,
    /// Static background and per-frame content (no rigid objects).
    None,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FramesEncodingArg {
    /// A node per frame, switched by stepped scale keys.
    Nodes,
    /// One mesh with a morph target per frame after the first, stepped weights.
    Morph,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    if let Some(t) = args.motion_tolerance {
        if !(t > 0.0 && t.is_finite()) {
            bail!("--motion-tolerance: {t} is not a positive distance");
        }
    }
    let gltf = is_gltf(&args.output);
    if args.objects.is_some() && args.frames {
        bail!("--frames keeps every frame whole; --objects decomposes them: give one");
    }
    if args.splats {
        bail!("--splats: a frame sequence exports as a mesh glTF (per-frame content is meshed)");
    }
    let t0 = Instant::now();
    let fps = splatbridge_scene::fourd::frame_rate();
    let Some(mode) = args.objects else {
        if !args.frames {
            bail!(
                "{}: a frame sequence converts with --objects auto|none (-o DIR or a .glb/.gltf) or with --frames (-o OUT.glb, or -o DIR/ for one GLB per frame)",
                args.scene.display()
            );
        }
        return run_frames(args, t0, fps);
    };
    let opts = DecomposeOptions {
        objects: mode == ObjectsArg::Auto,
        tolerance: args.motion_tolerance,
        min_group: args.min_group.max(1),
        ..DecomposeOptions::default()
    };
    // Frames streamed: read one at a time, a few passes over them.
    let (scene, report) = decompose_path(&args.scene, fps, &opts)?;
    let report = Some(report);
    if let Some(r) = &report {
        print_motion(args, r, gltf);
    }
    if !gltf {
        if args.output.extension().is_some() && !args.output.is_dir() {
            bail!(
                "{}: --objects writes a manifest into a folder (-o DIR) or a .glb/.gltf",
                args.output.display()
            );
        }
        let saved = splatbridge_scene::manifest::save_manifest(&args.output, &scene)?;
        // The report beside the manifest (what `--json` prints), written after it.
        if let Some(r) = &report {
            let path = args.output.join(REPORT_FILE);
            let tmp = args
                .output
                .join(format!(".{REPORT_FILE}.tmp{}", std::process::id()));
            std::fs::write(&tmp, serde_json::to_string_pretty(r)? + "\n")
                .and_then(|()| std::fs::rename(&tmp, &path))
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        }
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

/// `--frames`: one animated glTF (`-o OUT.glb|.gltf`) or one GLB per frame and an index
/// (`-o DIR/`), the frames read one at a time.
fn run_frames(args: &Args, t0: Instant, fps: f64) -> anyhow::Result<()> {
    let out = &args.output;
    let dir = !is_gltf(out)
        && (out.extension().is_none()
            || out.is_dir()
            || out.as_os_str().to_string_lossy().ends_with('/'));
    if !is_gltf(out) && !dir {
        bail!(
            "{}: --frames writes one animated .glb/.gltf, or one GLB per frame into a folder (-o DIR/)",
            out.display()
        );
    }
    if args.shard.is_some() {
        bail!("--shard: a frame sequence's --frames is written whole (one frame at a time)");
    }
    let (model, times) = open_model(&args.scene, fps, false)?;
    let mut req = args.request()?;
    if dir {
        // Each frame is a GLB: the options a .glb output gets.
        req.output = out.join("frame.glb");
        if args.profile.is_none() {
            req.mesh.options.profile =
                splatbridge::pipeline::export_request::default_profile(&req.output);
        }
    }
    // The options are resolved against the first frame (what orbit cameras frame).
    let first = frames_scene(vec![model.sample(times[0])?], &times[..1], fps)?;
    let opts = req.mesh_options(&first, splatbridge_scene::ply::GaussianKind::default())?;
    drop(first);
    let encoding = match args.frames_encoding {
        FramesEncodingArg::Nodes => FramesEncoding::Nodes,
        FramesEncodingArg::Morph => FramesEncoding::Morph,
    };
    if encoding == FramesEncoding::Morph && opts.arranged() {
        bail!(
            "--frames-encoding morph keeps each frame whole in input order: give --layout input (the default viewer layout arranges chunks, orders and both windings), and no --chunk-size, --chunk-order normal, --windings both or --view-order"
        );
    }
    match export_frames(&model, &times, fps, out, &opts, dir, encoding)? {
        FramesWritten::File(mut conv) => {
            conv.seconds = t0.elapsed().as_secs_f64();
            if args.json {
                println!("{}", serde_json::to_string_pretty(&conv)?);
            } else {
                super::print::print_summary(args, &conv);
            }
        }
        FramesWritten::Dir(index, mut conv) => {
            conv.seconds = t0.elapsed().as_secs_f64();
            if args.json {
                let mut v = serde_json::to_value(&conv)?;
                v["index"] = serde_json::to_value(&index)?;
                println!("{}", serde_json::to_string_pretty(&v)?);
            } else {
                super::print::print_summary(args, &conv);
                println!(
                    "wrote {} frame GLBs and {} ({} bytes) in {:.2} s",
                    index.frames.len(),
                    out.join(splatbridge_convert::frames_gltf::FRAMES_INDEX)
                        .display(),
                    conv.bytes,
                    conv.seconds
                );
            }
        }
    }
    Ok(())
}

/// The decomposition's report written beside a manifest.
pub const REPORT_FILE: &str = "motion.json";

/// Print the report: as text, or with `--json` as JSON (on stdout for a manifest; on stderr
/// for a glTF, whose export summary is the JSON on stdout).
fn print_motion(args: &Args, r: &MotionReport, gltf: bool) {
    if args.json {
        if let Ok(s) = serde_json::to_string_pretty(r) {
            if gltf {
                eprintln!("{s}");
            } else {
                println!("{s}");
            }
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
        let at: Vec<String> = g
            .psnr
            .iter()
            .map(|p| format!("{:.1} dB at {:.2} s", p.psnr, p.t))
            .collect();
        println!(
            "  {:<11} {:>9} Gaussians, rigid fit RMS {:.3e}, max {:.3e}; fit vs true: {}",
            g.name,
            g.gaussians,
            g.rms,
            g.max,
            at.join(", ")
        );
    }
    println!(
        "  per frame   {:>9} Gaussians ({} change opacity or scale, {} move without a rigid fit; RMS {:.3e} from their first position), {} × {} frames = {} kept",
        r.per_frame_gaussians,
        r.per_frame_appearance,
        r.per_frame_gaussians - r.per_frame_appearance,
        r.per_frame_motion_rms,
        r.per_frame_gaussians,
        r.frames,
        r.frames * r.per_frame_gaussians
    );
}
