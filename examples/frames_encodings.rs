//! `convert --frames` encoded two ways, for the measurement in docs/motion.md ("Per-frame nodes
//! or morph targets"): per-frame nodes switched by STEP scale keys
//! (`splatbridge_convert::frames_gltf`, what `convert --frames` writes) or one mesh with a
//! morph target per frame and a STEP weights animation
//! (`splatbridge_convert::frames_morph`), from the same 4D input with the same options.
//!
//! `cargo run --release --example frames_encodings -- IN OUT.glb --encoding nodes|morph
//! [--layout input|viewer] [--normals] [--fps F] [--camera WxH]`
//!
//! The options are `convert`'s for a `.glb` (texture profile, coplanar offset, ids) in the
//! input layout (`--layout input`: one primitive per frame, in input order), without normals
//! (the unlit material does not read them; `--normals` keeps them); `--layout viewer` is the
//! arrangement `convert --frames` uses by default, for the per-frame nodes only (morph targets
//! need each frame in input order). `--camera WxH` adds a glTF camera (orbit camera 1 of 4 around
//! frame 0, `OrbitRig` at W×H), for rendering in viewers; the per-frame nodes are then written
//! by the in-memory writer, which writes the streamed writer's file byte for byte plus the
//! camera (convert/tests/frames_stream.rs), so hold the frames. Prints the writer's bytes and
//! seconds as JSON. Exit status 2 on bad arguments or an input the writer refuses.
//!
//! `convert --frames --frames-encoding nodes|morph` writes both encodings from the CLI (input
//! layout for morph targets); this example keeps the measurement's fixed options, the viewer
//! layout for the nodes and the optional glTF camera.

use std::path::PathBuf;
use std::process::ExitCode;

use splatbridge::pipeline::motion::{frames_scene, open_model, total_gaussians, ModelFrames};
use splatbridge_convert::frames_gltf::{write_frames_file, FramesLimits};
use splatbridge_convert::frames_morph::write_frames_morph;
use splatbridge_convert::{ConvertOptions, Profile};
use splatbridge_scene::camera::OrbitRig;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

const USAGE: &str = "usage: frames_encodings IN OUT.glb --encoding nodes|morph [--layout input|viewer] [--normals] [--fps F] [--camera WxH]";

fn run() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let (mut input, mut output, mut encoding, mut viewer, mut normals, mut fps) =
        (None, None, None, false, false, 30.0f64);
    let mut camera: Option<(u32, u32)> = None;
    while let Some(a) = args.next() {
        let mut value = |name: &str| {
            args.next()
                .ok_or_else(|| format!("{name}: expected a value"))
        };
        match a.as_str() {
            "--encoding" => {
                let v = value("--encoding")?;
                encoding = Some(match v.as_str() {
                    "nodes" => false,
                    "morph" => true,
                    _ => return Err(format!("--encoding: '{v}' is not nodes or morph")),
                });
            }
            "--layout" => {
                let v = value("--layout")?;
                viewer = match v.as_str() {
                    "input" => false,
                    "viewer" => true,
                    _ => return Err(format!("--layout: '{v}' is not input or viewer")),
                };
            }
            "--normals" => normals = true,
            "--camera" => {
                let v = value("--camera")?;
                camera = v
                    .split_once('x')
                    .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)))
                    .filter(|&(w, h): &(u32, u32)| w > 0 && h > 0)
                    .map(Some)
                    .ok_or(format!("--camera: '{v}' is not WxH"))?;
            }
            "--fps" => {
                let v = value("--fps")?;
                fps = v
                    .parse()
                    .ok()
                    .filter(|f: &f64| f.is_finite() && *f > 0.0)
                    .ok_or(format!("--fps: '{v}' is not a positive number"))?;
            }
            _ if !a.starts_with("--") && input.is_none() => input = Some(PathBuf::from(a)),
            _ if !a.starts_with("--") && output.is_none() => output = Some(PathBuf::from(a)),
            _ => return Err(format!("unexpected argument '{a}' ({USAGE})")),
        }
    }
    let (Some(input), Some(output), Some(morph)) = (input, output, encoding) else {
        return Err(USAGE.into());
    };
    let mut opts = ConvertOptions {
        profile: Profile::Texture,
        coplanar_offset: true,
        normals,
        ..ConvertOptions::default()
    };
    if viewer {
        opts = opts.for_viewers();
        opts.normals = normals;
    }
    let (model, times) = open_model(&input, fps, false).map_err(|e| format!("{e:#}"))?;
    let src = ModelFrames {
        model: &model,
        times: &times,
    };
    let limits = FramesLimits {
        total_gaussians: Some(total_gaussians(&model, times.len())),
        ..FramesLimits::default()
    };
    let cameras = match camera {
        Some((width, height)) => {
            let first = model.sample(times[0]).map_err(|e| e.to_string())?;
            let rig = OrbitRig {
                width,
                height,
                ..OrbitRig::default()
            };
            vec![rig.cameras(&first, 4).map_err(|e| e.to_string())?.remove(1)]
        }
        None => Vec::new(),
    };
    let r = if morph {
        write_frames_morph(&output, &src, &times, &opts, &limits, &cameras)
            .map_err(|e| e.to_string())?
    } else if cameras.is_empty() {
        write_frames_file(&output, &src, &times, &opts, &limits).map_err(|e| e.to_string())?
    } else {
        let t0 = std::time::Instant::now();
        let frames = times
            .iter()
            .map(|&t| model.sample(t))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| e.to_string())?;
        let mut scene = frames_scene(frames, &times, fps).map_err(|e| format!("{e:#}"))?;
        scene.cameras = cameras;
        let mut r = splatbridge_convert::convert_to_file(&output, &scene, None, &opts, false)
            .map_err(|e| e.to_string())?;
        r.seconds = t0.elapsed().as_secs_f64();
        r
    };
    println!(
        "{{\"encoding\": \"{}\", \"layout\": \"{}\", \"normals\": {normals}, \"frames\": {}, \"bytes\": {}, \"seconds\": {:.3}, \"vertices\": {}, \"triangles\": {}}}",
        if morph { "morph" } else { "nodes" },
        if viewer { "viewer" } else { "input" },
        times.len(),
        r.bytes,
        r.seconds,
        r.vertices,
        r.triangles
    );
    Ok(())
}
