//! Effects reports end to end, through the library the commands call
//! (`splatbridge::pipeline`): native splatting, the hybrid, both tracers and the exporter run
//! on the street fixture with and without declared effects (rain, shadows, LiDAR and a
//! lane-changing inserted car), and their counters say what ran: zero work when nothing is
//! declared, particles (every renderer and the exporter), shadow rays and LiDAR scans
//! (tracers) when declared, and the ray-traced effects listed as not simulated by the
//! splatting renderers. A manifest with `"effects": {}` renders bit-identically to one
//! without the key, and to the plain composite rendered by the stage crate; an unknown effect
//! fails naming the file.
//!
//! Two smoke tests run the binary: its reports print these counters (`--json` and the summary
//! line), and an unknown effect exits with status 2, naming the file, writing nothing.
//!
//! Scenes are kept small (1000 Gaussians, 64×48 images, the effects scene cut to 4 frames with
//! 300 rain particles and a 256-step LiDAR) so the whole file runs in seconds.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;
use splatbridge::pipeline::export::{export_scene, load_export_input, ExportKind};
use splatbridge::pipeline::{
    load_scene_warn, render_frame, FrameRequest, LidarRequest, RenderedFrame, Renderer,
    SurfelSplit, TraceMode, TraceSource,
};
use splatbridge_convert::ConvertOptions;
use splatbridge_hybrid::ges::GesOptions;
use splatbridge_raytrace::{BackendKind, BuildPreset, RenderOptions as TraceOptions};
use splatbridge_scene::camera_spec::{CameraRequest, CameraSource, CameraSpec};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::EffectCounters;
use splatbridge_scene::effects_run::effects_of;
use splatbridge_scene::fixtures::{street_edited, StreetEdits, StreetParams};
use splatbridge_scene::manifest::save_manifest;
use splatbridge_scene::surfels::{SplitParams, DEFAULT_MAX_FLATNESS, DEFAULT_MIN_OPACITY};
use splatbridge_scene::Camera;

const BIN: &str = env!("CARGO_BIN_EXE_splatbridge");
/// Small images: `--camera scene:0` resized.
const SIZE: [&str; 6] = ["--camera", "scene:0", "--width", "64", "--height", "48"];
/// Rain particles per frame in the cut-down effects scene.
const RAIN: u64 = 300;
/// Frames of the cut-down effects scene: 0, 0.1, 0.2, 0.3 s at the street's 10 fps.
const FRAMES: u64 = 4;

fn no_warnings(w: &str) {
    panic!("unexpected warning: {w}");
}

fn read_json(p: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

fn write_json(p: &Path, v: &Value) {
    std::fs::write(p, serde_json::to_vec_pretty(v).unwrap()).unwrap();
}

/// The street fixture (seed 1, 1000 Gaussians, as `fixture street --count 1000`) with the
/// given effects and inserted cars, saved into `dir/name`; returns the manifest.
fn street(dir: &Path, name: &str, effects: &[&str], cars: &[&str]) -> PathBuf {
    let edits = StreetEdits {
        effects: effects.iter().map(|e| e.to_string()).collect(),
        inserts: cars.iter().map(|r| (r.to_string(), None)).collect(),
    };
    let (scene, _) = street_edited(&StreetParams::new(1, 1000), &edits).unwrap();
    let out = dir.join(name);
    save_manifest(&out, &scene).unwrap().manifest
}

/// The street with rain, shadows, LiDAR and a lane-changing inserted car, cut down for speed.
fn effects_street(dir: &Path) -> PathBuf {
    let m = street(
        dir,
        "effects",
        &["rain", "shadows", "lidar"],
        &["lane_change"],
    );
    let mut v = read_json(&m);
    v["time"]["end"] = 0.3.into();
    v["effects"]["weather"]["count"] = RAIN.into();
    v["effects"]["lidar"]["azimuth_steps"] = 256.into();
    write_json(&m, &v);
    m
}

fn load(m: &Path) -> DynamicScene {
    load_scene_warn(m, false, &no_warnings).unwrap()
}

/// `--camera scene:0 --width 64 --height 48`, resolved as the commands do.
fn request() -> CameraRequest {
    let mut req = CameraRequest::new(CameraSpec::Scene(0));
    req.width = Some(64);
    req.height = Some(48);
    req
}

fn camera(scene: &DynamicScene, t: f64) -> Camera {
    let cloud = scene.composite(t);
    request()
        .resolve(CameraSource {
            cloud: &cloud,
            own: &scene.cameras,
        })
        .unwrap()
}

/// Native splatting or the hybrid, as `render` and `hybrid` run them, at `t` (default: the
/// scene's start).
fn splat(m: &Path, hybrid: bool, t: Option<f64>) -> RenderedFrame {
    let scene = load(m);
    let t = t.unwrap_or(scene.time.start);
    splat_at(&scene, hybrid, t, &camera(&scene, t))
}

fn splat_at(scene: &DynamicScene, hybrid: bool, t: f64, cam: &Camera) -> RenderedFrame {
    let effects = effects_of(scene).unwrap();
    let mut r = if hybrid {
        Renderer::hybrid(
            GesOptions::default(),
            SurfelSplit {
                params: SplitParams::guarded(DEFAULT_MIN_OPACITY, DEFAULT_MAX_FLATNESS),
                ges_ply: false,
                detect_ges: true,
            },
        )
    } else {
        Renderer::native(Default::default())
    }
    .unwrap();
    let req = FrameRequest {
        scene: Some(scene),
        effects: &effects,
        camera: cam,
        time: t,
        content: EffectCounters::default(),
        lidar: None,
    };
    render_frame(&mut r, &req).unwrap()
}

/// What `trace` is given.
struct Trace<'a> {
    input: &'a Path,
    mode: TraceMode,
    time: Option<f64>,
    effects_from: Option<&'a Path>,
    lidar_dir: &'a Path,
    lidar_all_frames: bool,
}

impl<'a> Trace<'a> {
    fn new(input: &'a Path, mode: TraceMode, lidar_dir: &'a Path) -> Self {
        Trace {
            input,
            mode,
            time: None,
            effects_from: None,
            lidar_dir,
            lidar_all_frames: false,
        }
    }

    /// The source and frame as `trace` prepares and renders them.
    fn try_run(&self) -> anyhow::Result<RenderedFrame> {
        let source = TraceSource {
            input: self.input.to_path_buf(),
            camera: request(),
            // The command's default time.
            time: self.time.unwrap_or(0.0),
            mode: self.mode,
            options: TraceOptions::default(),
            gltf_frame: false,
            profile: None,
            drop_invalid: false,
            effects_from: self.effects_from.map(Path::to_path_buf),
        };
        let all = self.lidar_all_frames && self.mode == TraceMode::Mesh;
        let p = source.prepare(all, &no_warnings)?;
        let (backend, preset) = (BackendKind::default(), BuildPreset::default());
        let mut tracer = Renderer::tracer(&p, backend, preset)?;
        let req = FrameRequest {
            scene: p.effects_scene.as_ref(),
            effects: &p.effects,
            camera: &p.camera,
            time: p.time,
            content: p.counters.clone(),
            lidar: Some(LidarRequest {
                dir: self.lidar_dir.to_path_buf(),
                all_frames: self.lidar_all_frames,
                backend,
                preset,
                shard: None,
            }),
        };
        render_frame(&mut tracer, &req)
    }

    fn run(&self) -> RenderedFrame {
        self.try_run().unwrap()
    }
}

/// `convert M -o OUT` (`frames`: one OBJ per frame), with small fans.
fn try_convert(m: &Path, out: &Path, frames: bool) -> anyhow::Result<EffectCounters> {
    let scene = load_export_input(m, false, &no_warnings)?;
    let opts = ConvertOptions {
        segments: Some(4),
        rings: 1,
        ..ConvertOptions::default()
    };
    let (_, effects) = export_scene(&scene, m, out, &opts, ExportKind::Mesh { frames })?;
    Ok(effects)
}

fn convert(m: &Path, out: &Path, frames: bool) -> EffectCounters {
    try_convert(m, out, frames).unwrap()
}

fn assert_zero_work(e: &EffectCounters, what: &str) {
    let counts = [
        ("particles", e.particles),
        ("shadow_rays", e.shadow_rays),
        ("lidar_points", e.lidar_points),
        ("lidar_rays", e.lidar_rays),
        ("extra_time_samples", e.extra_time_samples),
    ];
    for (key, n) in counts {
        assert_eq!(n, 0, "{what}: {key} without declared effects");
    }
    assert!(e.simulated.is_empty(), "{what}: {e:?}");
    assert!(e.not_simulated.is_empty(), "{what}: {e:?}");
    assert_eq!(e.milliseconds, 0.0, "{what}: {e:?}");
    // The summary every command prints says so too.
    assert!(
        e.summary().starts_with("effects: none | particles 0"),
        "{what}: {}",
        e.summary()
    );
}

/// Points in a LiDAR PLY, from its header (and the body length it implies: 3 position floats,
/// intensity float, time double, ring ushort = 26 bytes per point).
fn ply_points(p: &Path) -> u64 {
    let bytes = std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("a PLY header")
        + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    let n: u64 = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .expect("element vertex")
        .parse()
        .unwrap();
    assert_eq!((bytes.len() - end) as u64, 26 * n, "{}", p.display());
    n
}

#[test]
fn no_declared_effects_report_zero_work_in_every_renderer() {
    let dir = tempfile::tempdir().unwrap();
    let m = street(dir.path(), "plain", &[], &[]);
    assert_zero_work(&splat(&m, false, None).counters, "render");
    assert_zero_work(&splat(&m, true, None).counters, "hybrid");
    for mode in [TraceMode::Gaussian, TraceMode::Mesh] {
        let r = Trace::new(&m, mode, dir.path()).run();
        assert!(r.lidar.is_none(), "trace {mode:?}");
        assert_zero_work(&r.counters, &format!("trace {mode:?}"));
    }
    let glb = dir.path().join("plain.glb");
    assert_zero_work(&convert(&m, &glb, false), "convert");
    // No LiDAR scan is written into the LiDAR folder when none is declared.
    assert!(!dir.path().join("lidar_0000.ply").exists());
}

#[test]
fn declared_effects_report_their_work() {
    let dir = tempfile::tempdir().unwrap();
    let m = effects_street(dir.path());

    // Splatting renderers: the frame's particles, shadows and LiDAR said to be not simulated.
    for (cmd, hybrid) in [("render", false), ("hybrid", true)] {
        for t in [Some(0.1), None] {
            let e = splat(&m, hybrid, t).counters;
            assert_eq!(e.particles, RAIN, "{cmd}: {e:?}");
            assert_eq!(e.simulated, ["weather"], "{cmd}: {e:?}");
            assert_eq!(e.not_simulated, ["shadows", "lidar"], "{cmd}: {e:?}");
            let counts = [
                ("shadow_rays", e.shadow_rays),
                ("lidar_points", e.lidar_points),
                ("lidar_rays", e.lidar_rays),
                ("extra_time_samples", e.extra_time_samples),
            ];
            for (key, n) in counts {
                assert_eq!(n, 0, "{cmd}: {key}");
            }
            let line = e.summary();
            assert!(
                line.starts_with(&format!("effects: weather | particles {RAIN},")),
                "{line}"
            );
            assert!(
                line.ends_with("declared but not simulated here: shadows, lidar"),
                "{line}"
            );
        }
    }
    // render --frames: every frame's particles.
    let scene = load(&m);
    let times = scene.frame_times();
    assert_eq!(times.len() as u64, FRAMES);
    let cam = camera(&scene, times[0]);
    let mut total = EffectCounters::default();
    for &t in &times {
        total.add(&splat_at(&scene, false, t, &cam).counters);
    }
    assert_eq!(total.particles, RAIN * FRAMES);

    // The ray tracer simulates everything: shadow rays, and the frame's LiDAR scan (t = 0.1 s
    // is frame 1) written to the LiDAR folder.
    for mode in [TraceMode::Gaussian, TraceMode::Mesh] {
        let lidar = dir.path().join(format!("lidar_{mode:?}"));
        let r = Trace {
            time: Some(0.1),
            ..Trace::new(&m, mode, &lidar)
        }
        .run();
        let e = &r.counters;
        assert_eq!(e.particles, RAIN, "trace {mode:?}: {e:?}");
        assert!(e.shadow_rays > 0, "trace {mode:?}: {e:?}");
        // One shadow ray at most per pixel (shadows.rs casts one per surface pixel).
        assert!(e.shadow_rays <= 64 * 48, "trace {mode:?}: {e:?}");
        assert_eq!(e.lidar_rays, 32 * 256, "trace {mode:?}: {e:?}");
        assert_eq!(
            e.simulated,
            ["weather", "shadows", "lidar"],
            "trace {mode:?}: {e:?}"
        );
        assert!(e.not_simulated.is_empty(), "trace {mode:?}: {e:?}");
        let file = lidar.join("lidar_0001.ply");
        let points = ply_points(&file);
        assert!(points > 0, "{}", file.display());
        assert_eq!(e.lidar_points, points, "trace {mode:?}");
        assert_eq!(r.lidar.as_ref().map(|l| &l.files[0]), Some(&file));
    }
    // Every frame scanned. Particles: mode mesh converts every frame's once; mode gaussian
    // generates the traced frame's and each scanned frame's.
    let sub = dir.path().join("all");
    std::fs::create_dir_all(&sub).unwrap();
    for (mode, particles) in [
        (TraceMode::Mesh, RAIN * FRAMES),
        (TraceMode::Gaussian, RAIN * (FRAMES + 1)),
    ] {
        for i in 0..FRAMES {
            let _ = std::fs::remove_file(sub.join(format!("lidar_{i:04}.ply")));
        }
        let r = Trace {
            lidar_all_frames: true,
            ..Trace::new(&m, mode, &sub)
        }
        .run();
        let mut total = 0;
        for i in 0..FRAMES {
            total += ply_points(&sub.join(format!("lidar_{i:04}.ply")));
        }
        let e = &r.counters;
        assert_eq!(e.lidar_points, total, "{mode:?}");
        assert_eq!(e.lidar_rays, FRAMES * 32 * 256, "{mode:?}");
        assert_eq!(e.particles, particles, "{mode:?}");
    }
    let e = Trace::new(&m, TraceMode::Mesh, &sub).run().counters;
    assert!(
        e.summary().contains(&format!(
            "effects: weather, shadows, lidar | particles {RAIN},"
        )),
        "{}",
        e.summary()
    );

    // convert: every frame's particles exported; the rest not simulated.
    let glb = dir.path().join("street.glb");
    let e = convert(&m, &glb, false);
    assert_eq!(e.particles, RAIN * FRAMES, "{e:?}");
    assert_eq!(e.simulated, ["weather"]);
    assert_eq!(e.not_simulated, ["shadows", "lidar"]);
    // OBJ per frame: frame k's particles in OBJ k only.
    convert(&m, &dir.path().join("street.obj"), true);
    for k in 0..FRAMES {
        let text = std::fs::read_to_string(dir.path().join(format!("street_{k:04}.obj"))).unwrap();
        let frames: Vec<&str> = text.lines().filter(|l| l.starts_with("o frame_")).collect();
        assert_eq!(frames, [format!("o frame_{k}")], "OBJ frame {k}");
    }

    // An exported file carries no effects of its own; an effects manifest supplies them.
    let plain = Trace {
        time: Some(0.1),
        ..Trace::new(&glb, TraceMode::Mesh, dir.path())
    }
    .run();
    assert_zero_work(&plain.counters, "trace GLB");
    let lidar = dir.path().join("lidar_glb");
    let r = Trace {
        time: Some(0.1),
        effects_from: Some(&m),
        ..Trace::new(&glb, TraceMode::Mesh, &lidar)
    }
    .run();
    assert!(r.counters.shadow_rays > 0, "{:?}", r.counters);
    assert!(ply_points(&lidar.join("lidar_0001.ply")) > 0);
    // The file's particles are drawn as exported, not generated again.
    assert_eq!(r.counters.particles, 0, "{:?}", r.counters);
    assert!(r.exported_weather);
}

#[test]
fn motion_blur_adds_only_its_time_samples() {
    let dir = tempfile::tempdir().unwrap();
    let m = street(dir.path(), "blur", &["motion_blur"], &["straight"]);
    let v = read_json(&m);
    let samples = v["effects"]["motion_blur"]["samples"].as_u64().unwrap_or(8);
    let runs = [
        ("render", splat(&m, false, Some(1.0))),
        ("hybrid", splat(&m, true, Some(1.0))),
        ("trace gaussian", {
            let t = Trace {
                time: Some(1.0),
                ..Trace::new(&m, TraceMode::Gaussian, dir.path())
            };
            t.run()
        }),
        ("trace mesh", {
            let t = Trace {
                time: Some(1.0),
                ..Trace::new(&m, TraceMode::Mesh, dir.path())
            };
            t.run()
        }),
    ];
    for (what, r) in &runs {
        let e = &r.counters;
        assert_eq!(e.extra_time_samples, samples - 1, "{what}: {e:?}");
        assert_eq!(e.simulated, ["motion_blur"], "{what}: {e:?}");
        let counts = [
            ("particles", e.particles),
            ("shadow_rays", e.shadow_rays),
            ("lidar_points", e.lidar_points),
            ("lidar_rays", e.lidar_rays),
        ];
        for (key, n) in counts {
            assert_eq!(n, 0, "{what}: {key}");
        }
        assert!(e.not_simulated.is_empty(), "{what}: {e:?}");
    }
}

#[test]
fn empty_effects_object_renders_bit_identically_to_no_key() {
    let dir = tempfile::tempdir().unwrap();
    let m = street(dir.path(), "plain", &[], &["lane_change"]);
    let mut with = read_json(&m);
    with["effects"] = serde_json::json!({});
    let mut without = with.clone();
    without.as_object_mut().unwrap().remove("effects");
    let a = m.with_file_name("with_key.json");
    let b = m.with_file_name("without_key.json");
    write_json(&a, &with);
    write_json(&b, &without);
    type Run = fn(&Path, &Path) -> RenderedFrame;
    let runs: [(&str, Run); 4] = [
        ("render", |m, _| splat(m, false, Some(1.5))),
        ("hybrid", |m, _| splat(m, true, Some(1.5))),
        ("trace gaussian", |m, d| {
            Trace {
                time: Some(1.5),
                ..Trace::new(m, TraceMode::Gaussian, d)
            }
            .run()
        }),
        ("trace mesh", |m, d| {
            Trace {
                time: Some(1.5),
                ..Trace::new(m, TraceMode::Mesh, d)
            }
            .run()
        }),
    ];
    let mut native = None;
    for (i, (what, run)) in runs.iter().enumerate() {
        let mut bytes = Vec::new();
        for (tag, manifest) in [("a", &a), ("b", &b)] {
            let r = run(manifest, dir.path());
            assert_zero_work(&r.counters, &format!("{what} {tag}"));
            // PNG as the commands write it, and EXR (float RGBA and depth) for native.
            let exts: &[&str] = if i == 0 { &["png", "exr"] } else { &["png"] };
            let mut files = Vec::new();
            for ext in exts {
                let out = dir.path().join(format!("{i}_{tag}.{ext}"));
                splatbridge_scene::image_io::save_frame(&out, &r.frame).unwrap();
                files.push(std::fs::read(&out).unwrap());
            }
            bytes.push(files);
            if i == 0 && tag == "a" {
                native = Some(r.frame);
            }
        }
        assert!(
            bytes[0] == bytes[1],
            "{what}: \"effects\": {{}} and no key differ"
        );
    }

    // And the pipeline's frame is the plain composite rendered by the stage crate.
    let scene = load(&a);
    let cam = scene.cameras[0].resized(64, 48);
    let (frame, _) =
        splatbridge_hybrid::native::render(&scene.composite(1.5), &cam, &Default::default())
            .unwrap();
    let lib = dir.path().join("library.png");
    splatbridge_scene::image_io::save_frame(&lib, &frame).unwrap();
    let ours = dir.path().join("pipeline.png");
    splatbridge_scene::image_io::save_frame(&ours, &native.unwrap()).unwrap();
    assert!(
        std::fs::read(&lib).unwrap() == std::fs::read(&ours).unwrap(),
        "render differs from the library's composite render"
    );
}

/// The plain street manifest under `dir`, and a copy beside it declaring an unknown effect
/// (`fog`).
fn fog_manifest(dir: &Path) -> (PathBuf, PathBuf) {
    let m = street(dir, "plain", &[], &[]);
    let mut v = read_json(&m);
    v["effects"] = serde_json::json!({"fog": {"density": 0.1}});
    let bad = m.with_file_name("fog.json");
    write_json(&bad, &v);
    (m, bad)
}

#[test]
fn unknown_effect_fails_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let (m, bad) = fog_manifest(dir.path());
    let glb = dir.path().join("out.glb");
    let name = bad.display().to_string();
    let check = |what: &str, err: anyhow::Error| {
        let err = format!("{err:#}");
        assert!(err.contains(&name), "{what}: {err}");
        assert!(err.contains("fog"), "{what}: {err}");
    };
    // `render` and `hybrid`: the scene is loaded, then its effects are read.
    let splat_err = match load_scene_warn(&bad, false, &no_warnings) {
        Err(e) => e,
        Ok(scene) => match effects_of(&scene) {
            Err(e) => anyhow::Error::new(e).context(name.clone()),
            Ok(_) => panic!("an unknown effect was accepted"),
        },
    };
    check("render", splat_err);
    for mode in [TraceMode::Gaussian, TraceMode::Mesh] {
        let r = Trace::new(&bad, mode, dir.path()).try_run();
        check("trace", r.err().expect("an unknown effect fails"));
    }
    check("convert", try_convert(&bad, &glb, false).unwrap_err());
    assert!(!glb.exists(), "nothing written on error");
    // An exported file traced with a bad effects manifest names the manifest.
    convert(&m, &glb, false);
    let r = Trace {
        effects_from: Some(&bad),
        ..Trace::new(&glb, TraceMode::Mesh, dir.path())
    }
    .try_run();
    check(
        "trace --effects-from",
        r.err().expect("a bad manifest fails"),
    );
}

// ---------------------------------------------------------------- CLI smoke tests

fn run(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("the splatbridge binary runs")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 temp path")
}

/// The commands print the counters: `--json` reports carry them under `effects`, and the text
/// output ends with the summary line.
#[test]
fn cli_reports_print_the_effect_counters() {
    let dir = tempfile::tempdir().unwrap();
    let m = effects_street(dir.path());
    let img = dir.path().join("img.png");
    let ok = |args: &[&str]| {
        let out = run(args);
        assert!(
            out.status.success(),
            "splatbridge {} failed ({:?}):\nstdout: {}\nstderr: {}",
            args.join(" "),
            out.status.code(),
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).expect("UTF-8 stdout")
    };
    let args = [
        &["render", s(&m), "--time", "0.1", "-o", s(&img)][..],
        &SIZE,
    ]
    .concat();
    let json = ok(&[&args[..], &["--json"]].concat());
    let r: Value =
        serde_json::from_str(&json).unwrap_or_else(|e| panic!("not JSON ({e}):\n{json}"));
    assert_eq!(r["effects"]["particles"].as_u64(), Some(RAIN), "{r}");
    assert_eq!(
        r["effects"]["not_simulated"],
        serde_json::json!(["shadows", "lidar"])
    );
    let text = ok(&args);
    assert!(
        text.lines()
            .any(|l| l.starts_with(&format!("effects: weather | particles {RAIN},"))),
        "{text}"
    );
    // Every frame scanned, by default into the output image's folder.
    let sub = dir.path().join("all");
    std::fs::create_dir_all(&sub).unwrap();
    ok(&[
        &[
            "trace",
            s(&m),
            "--lidar-all-frames",
            "-o",
            s(&sub.join("t.png")),
        ][..],
        &SIZE,
    ]
    .concat());
    let points: u64 = (0..FRAMES)
        .map(|i| ply_points(&sub.join(format!("lidar_{i:04}.ply"))))
        .sum();
    assert!(points > 0);
    let glb = dir.path().join("street.glb");
    let text = ok(&["convert", s(&m), "-o", s(&glb)]);
    assert!(
        text.contains(&format!("effects: weather | particles {},", RAIN * FRAMES)),
        "{text}"
    );
}

#[test]
fn cli_unknown_effect_exits_2_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let (m, bad) = fog_manifest(dir.path());
    let img = dir.path().join("img.png");
    let glb = dir.path().join("out.glb");
    for args in [
        vec!["render", s(&bad), "-o", s(&img)],
        vec!["hybrid", s(&bad), "-o", s(&img)],
        vec!["trace", s(&bad), "-o", s(&img)],
        vec!["convert", s(&bad), "-o", s(&glb)],
    ] {
        let out = run(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{}: {err}", args.join(" "));
        assert!(err.starts_with("error: "), "{}: {err}", args[0]);
        assert!(err.contains(s(&bad)), "{}: {err}", args[0]);
        assert!(err.contains("fog"), "{}: {err}", args[0]);
    }
    assert!(!img.exists() && !glb.exists(), "nothing written on error");
    // An exported file traced with a bad --effects-from names the manifest.
    let out = run(&["convert", s(&m), "-o", s(&glb)]);
    assert!(out.status.success());
    let out = run(&["trace", s(&glb), "--effects-from", s(&bad), "-o", s(&img)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.starts_with("error: ") && err.contains(s(&bad)), "{err}");
}
