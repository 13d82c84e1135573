//! The animated exports of a 4D capture played in three.js: the decomposed export (static mesh,
//! objects as animated nodes, per-frame content) and the `--frames` export (every frame a node
//! switched by stepped scale keys), each loaded by three.js's `GLTFLoader`, its clips played
//! by an `AnimationMixer` set to two times (`scripts/client-render.sh three … --time`), and
//! measured against native splatting of the true frame next to our tracer on the same file at
//! the same times. Goal: three.js within 1 dB of our tracer at both times.
//!
//! Ignored unless chromium and the npm packages are installed (`cfg(web_clients)`,
//! `scripts/setup.sh`).

use std::path::Path;
use std::process::Command;

use splatbridge::pipeline::motion::{decompose_scene, frames_scene};
use splatbridge_convert::motion::DecomposeOptions;
use splatbridge_convert::ConvertOptions;
use splatbridge_hybrid::native::render;
use splatbridge_raytrace::{BackendKind, BuildPreset, MeshTracer, RenderOptions};
use splatbridge_scene::camera::{Camera, OrbitRig};
use splatbridge_scene::fixtures::moving::{moving_cutouts, MovingParams};
use splatbridge_scene::image_io::{load_png, save_frame};
use splatbridge_scene::metrics::psnr;
use splatbridge_scene::Frame;

const W: u32 = 128;
const H: u32 = 96;

/// Two times inside the clips (a mixer set to a clip's full duration wraps to its start), one
/// between frames 2 and 3 (the tracks interpolate, the per-frame content holds frame 2) and one
/// on frame 6's own time (its step key has switched).
const TIMES: [&str; 2] = ["0.25", "0.6"];

fn tracer(path: &Path) -> MeshTracer {
    let mut tri = splatbridge_raytrace::scene_load::load_path(path).unwrap();
    tri.to_capture_frame();
    MeshTracer::new(tri, BackendKind::Obvhs, BuildPreset::Medium).unwrap()
}

/// three.js renders of `glb`'s camera 0 at each of [`TIMES`] (one load).
#[cfg_attr(not(web_clients), allow(dead_code))]
fn three(glb: &Path, dir: &Path, tag: &str) -> Vec<Frame> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/client-render.sh");
    let out = dir.join(format!("{tag}_three_{{time}}.png"));
    let r = Command::new(script)
        .args(["three", glb.to_str().unwrap(), out.to_str().unwrap()])
        .args(["--camera", "0", "--size", &format!("{W}x{H}")])
        .args(["--time", &TIMES.join(",")])
        .output()
        .unwrap();
    assert!(
        r.status.success(),
        "three.js: exit {:?}\n{}",
        r.status.code(),
        String::from_utf8_lossy(&r.stderr)
    );
    TIMES
        .iter()
        .map(|t| load_png(&dir.join(format!("{tag}_three_{t}.png"))).unwrap())
        .collect()
}

#[cfg_attr(not(web_clients), allow(dead_code))]
fn check(glb: &Path, natives: &[Frame], cam: &Camera, dir: &Path, tag: &str) {
    let tr = tracer(glb);
    let traced: Vec<Frame> = TIMES
        .iter()
        .map(|t| {
            tr.render(cam, t.parse().unwrap(), &RenderOptions::default())
                .unwrap()
                .0
        })
        .collect();
    let played = three(glb, dir, tag);
    for (k, t) in TIMES.iter().enumerate() {
        let (db_three, db_trace) = (
            psnr(&natives[k], &played[k]).unwrap(),
            psnr(&natives[k], &traced[k]).unwrap(),
        );
        let agree = psnr(&traced[k], &played[k]).unwrap();
        let other = psnr(&traced[1 - k], &played[k]).unwrap();
        println!(
            "{tag} t = {t} s: three.js {db_three:.2} dB, our tracer {db_trace:.2} dB against native; \
             three.js vs tracer {agree:.2} dB (vs the tracer at the other time {other:.2} dB)"
        );
        if std::env::var_os("MOTION_KEEP").is_some() {
            save_frame(&dir.join(format!("{tag}_trace_{t}.png")), &traced[k]).unwrap();
            save_frame(&dir.join(format!("native_{t}.png")), &natives[k]).unwrap();
        }
        // The goal as stated.
        assert!(
            db_three >= db_trace - 1.0,
            "{tag} at {t} s: three.js {db_three:.2} dB is more than 1 dB below our tracer's {db_trace:.2} dB"
        );
        // The animation is what is compared: the frame three.js shows at this time matches
        // the tracer at this time better than at the other time (measured in docs/motion.md,
        // "Viewers"; the smallest gap, 5.2 dB, is the animated export at 0.25 s, where the
        // moving balls cover a small part of the view). 2 dB is well above the two renderers'
        // noise on one frame and below every measured gap.
        assert!(
            agree >= other + 2.0,
            "{tag} at {t} s: three.js matches the tracer's {t} s ({agree:.2} dB) not clearly better than its other time ({other:.2} dB)"
        );
    }
}

#[test]
#[cfg_attr(
    not(all(web_clients, real_data)),
    ignore = "needs chromium and the npm packages of scripts/package.json (scripts/setup.sh) and ../shared/data/real"
)]
fn three_js_plays_both_animated_exports_like_our_tracer() {
    // The capture of the export test (tests/motion_export.rs): fourth_st cut to every fifth
    // Gaussian, three rigid balls and a deforming one, here eight frames at 10 fps.
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real/fourth_st.ply");
    let (mut base, _) =
        splatbridge_scene::ply::read_ply(&real, &splatbridge_scene::ply::ReadOptions::default())
            .unwrap();
    base.retain_indices(|i| i % 5 == 0);
    let params = MovingParams {
        objects: 3,
        frames: 8,
        ..MovingParams::default()
    };
    let (frames, times, _) = moving_cutouts(&base, &params);
    let keep = std::env::var_os("MOTION_KEEP");
    let tmp = tempfile::tempdir().unwrap();
    let dir = keep
        .as_ref()
        .map_or(tmp.path().to_path_buf(), std::path::PathBuf::from);
    std::fs::create_dir_all(&dir).unwrap();
    let cam = OrbitRig {
        width: W,
        height: H,
        ..OrbitRig::default()
    }
    .cameras(&frames[0], 4)
    .unwrap()
    .remove(1);
    let natives: Vec<Frame> = TIMES
        .iter()
        .map(|t| {
            let f =
                splatbridge_scene::fourd::frame_index(t.parse().unwrap(), params.fps, frames.len());
            render(&frames[f], &cam, &Default::default()).unwrap().0
        })
        .collect();
    let opts = ConvertOptions::default();
    let (mut animated, report) =
        decompose_scene(&frames, &times, params.fps, &DecomposeOptions::default()).unwrap();
    assert!(
        !animated.objects.is_empty() && !animated.frames.is_empty(),
        "{report:?}"
    );
    animated.cameras = vec![cam.clone()];
    let a = dir.join("animated.glb");
    splatbridge_convert::convert_to_file(&a, &animated, None, &opts, false).unwrap();
    let mut whole = frames_scene(frames, &times, params.fps).unwrap();
    whole.cameras = vec![cam.clone()];
    let p = dir.join("frames.glb");
    splatbridge_convert::convert_to_file(&p, &whole, None, &opts, false).unwrap();
    drop(whole);
    check(&a, &natives, &cam, &dir, "animated");
    check(&p, &natives, &cam, &dir, "frames");
}
