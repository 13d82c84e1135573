//! The CLI's effects reports end to end: `render`, `hybrid`, `trace` and `convert` run on the
//! street fixture with and without declared effects (`fixture street --effects
//! rain,shadows,lidar --insert car:lane_change`), and their JSON reports carry the counters:
//! zero work when nothing is declared, particles (every command), shadow rays and LiDAR scans
//! (trace) when declared, and the ray-traced effects listed as not simulated by the splatting
//! renderers. A manifest with `"effects": {}` renders bit-identically to one without the key,
//! and to the plain composite rendered through the library; an unknown effect name fails with
//! exit status 2 naming the file.
//!
//! Scenes are kept small (1000 Gaussians, 64×48 images, the effects scene cut to 4 frames with
//! 300 rain particles and a 256-step LiDAR) so the whole file runs in seconds.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_splatbridge");
/// Small images: `--camera scene:0` resized.
const SIZE: [&str; 6] = ["--camera", "scene:0", "--width", "64", "--height", "48"];
/// Rain particles per frame in the cut-down effects scene.
const RAIN: u64 = 300;
/// Frames of the cut-down effects scene: 0, 0.1, 0.2, 0.3 s at the street's 10 fps.
const FRAMES: u64 = 4;

fn run(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("the splatbridge binary runs")
}

/// Run and require exit status 0, printing the command's output when it fails.
fn ok(args: &[&str]) -> String {
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
}

/// Run with `--json` and parse the one JSON object on stdout.
fn json(args: &[&str]) -> Value {
    let mut a = args.to_vec();
    a.push("--json");
    let s = ok(&a);
    serde_json::from_str(&s).unwrap_or_else(|e| panic!("{}: not JSON ({e}):\n{s}", a.join(" ")))
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 temp path")
}

fn read_json(p: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

fn write_json(p: &Path, v: &Value) {
    std::fs::write(p, serde_json::to_vec_pretty(v).unwrap()).unwrap();
}

/// `fixture street` into `dir/name` with the given extra arguments; returns the manifest.
fn street(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let mut args = vec!["fixture", "street", "--count", "1000", "-o", s(&out)];
    args.extend_from_slice(extra);
    ok(&args);
    out.join("scene.json")
}

/// The street with rain, shadows, LiDAR and a lane-changing inserted car, cut down for speed.
fn effects_street(dir: &Path) -> PathBuf {
    let m = street(
        dir,
        "effects",
        &[
            "--effects",
            "rain,shadows,lidar",
            "--insert",
            "car:lane_change",
        ],
    );
    let mut v = read_json(&m);
    v["time"]["end"] = 0.3.into();
    v["effects"]["weather"]["count"] = RAIN.into();
    v["effects"]["lidar"]["azimuth_steps"] = 256.into();
    write_json(&m, &v);
    m
}

fn effects(report: &Value) -> &Value {
    report
        .get("effects")
        .unwrap_or_else(|| panic!("no effects in the report: {report}"))
}

fn count(e: &Value, key: &str) -> u64 {
    e[key]
        .as_u64()
        .unwrap_or_else(|| panic!("effects.{key} is not a count: {e}"))
}

fn names(e: &Value, key: &str) -> Vec<String> {
    e[key]
        .as_array()
        .unwrap_or_else(|| panic!("effects.{key} is not a list: {e}"))
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect()
}

fn assert_zero_work(e: &Value, what: &str) {
    for key in [
        "particles",
        "shadow_rays",
        "lidar_points",
        "lidar_rays",
        "extra_time_samples",
    ] {
        assert_eq!(count(e, key), 0, "{what}: {key} without declared effects");
    }
    assert!(names(e, "simulated").is_empty(), "{what}: {e}");
    assert!(names(e, "not_simulated").is_empty(), "{what}: {e}");
    assert_eq!(e["milliseconds"].as_f64(), Some(0.0), "{what}: {e}");
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
fn no_declared_effects_report_zero_work_in_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let m = street(dir.path(), "plain", &[]);
    let m = s(&m);
    let img = dir.path().join("img.png");
    let img = s(&img);

    let mut reports = Vec::new();
    reports.push((
        "render",
        json(&[&["render", m, "-o", img][..], &SIZE].concat()),
    ));
    reports.push((
        "hybrid",
        json(&[&["hybrid", m, "-o", img][..], &SIZE].concat()),
    ));
    for mode in ["gaussian", "mesh"] {
        let r = json(&[&["trace", m, "--mode", mode, "-o", img][..], &SIZE].concat());
        assert!(r["lidar"].is_null(), "trace {mode}: {r}");
        reports.push(("trace", r));
    }
    let glb = dir.path().join("plain.glb");
    reports.push(("convert", json(&["convert", m, "-o", s(&glb)])));
    for (what, r) in &reports {
        assert_zero_work(effects(r), what);
    }
    // No LiDAR scan is written next to the image when none is declared.
    assert!(!dir.path().join("lidar_0000.ply").exists());

    // The human summaries say so too.
    for cmd in ["render", "hybrid", "trace"] {
        let out = ok(&[&[cmd, m, "-o", img][..], &SIZE].concat());
        assert!(
            out.lines()
                .any(|l| l.starts_with("effects: none | particles 0")),
            "{cmd}: {out}"
        );
    }
    let out = ok(&["convert", m, "-o", s(&glb)]);
    assert!(
        out.contains("effects: none | particles 0"),
        "convert: {out}"
    );
}

#[test]
fn declared_effects_report_their_work() {
    let dir = tempfile::tempdir().unwrap();
    let m = effects_street(dir.path());
    let m = s(&m);
    let img = dir.path().join("img.png");
    let img = s(&img);

    // Splatting renderers: the frame's particles, shadows and LiDAR said to be not simulated.
    for cmd in ["render", "hybrid"] {
        let r = json(&[&[cmd, m, "--time", "0.1", "-o", img][..], &SIZE].concat());
        let e = effects(&r);
        assert_eq!(count(e, "particles"), RAIN, "{cmd}: {e}");
        assert_eq!(names(e, "simulated"), ["weather"], "{cmd}: {e}");
        assert_eq!(
            names(e, "not_simulated"),
            ["shadows", "lidar"],
            "{cmd}: {e}"
        );
        for key in [
            "shadow_rays",
            "lidar_points",
            "lidar_rays",
            "extra_time_samples",
        ] {
            assert_eq!(count(e, key), 0, "{cmd}: {key}");
        }
        let out = ok(&[&[cmd, m, "-o", img][..], &SIZE].concat());
        let line = out
            .lines()
            .find(|l| l.starts_with("effects:"))
            .unwrap_or_else(|| panic!("{cmd}: no effects line in {out}"));
        assert!(
            line.starts_with(&format!("effects: weather | particles {RAIN},")),
            "{line}"
        );
        assert!(
            line.ends_with("declared but not simulated here: shadows, lidar"),
            "{line}"
        );
    }
    // render --frames: every frame's particles.
    let r = json(&[&["render", m, "--frames", "-o", img][..], &SIZE].concat());
    assert_eq!(count(effects(&r), "particles"), RAIN * FRAMES);
    assert_eq!(r["frames"].as_array().unwrap().len() as u64, FRAMES);

    // The ray tracer simulates everything: shadow rays, and the frame's LiDAR scan (t = 0.1 s
    // is frame 1) written to --lidar-out.
    for mode in ["gaussian", "mesh"] {
        let lidar = dir.path().join(format!("lidar_{mode}"));
        let r = json(
            &[
                &[
                    "trace",
                    m,
                    "--mode",
                    mode,
                    "--time",
                    "0.1",
                    "--lidar-out",
                    s(&lidar),
                    "-o",
                    img,
                ][..],
                &SIZE,
            ]
            .concat(),
        );
        let e = effects(&r);
        assert_eq!(count(e, "particles"), RAIN, "trace {mode}: {e}");
        assert!(count(e, "shadow_rays") > 0, "trace {mode}: {e}");
        // One shadow ray at most per pixel (shadows.rs casts one per surface pixel).
        assert!(count(e, "shadow_rays") <= 64 * 48, "trace {mode}: {e}");
        assert_eq!(count(e, "lidar_rays"), 32 * 256, "trace {mode}: {e}");
        assert_eq!(
            names(e, "simulated"),
            ["weather", "shadows", "lidar"],
            "trace {mode}: {e}"
        );
        assert!(names(e, "not_simulated").is_empty(), "trace {mode}: {e}");
        let file = lidar.join("lidar_0001.ply");
        let points = ply_points(&file);
        assert!(points > 0, "{}", file.display());
        assert_eq!(count(e, "lidar_points"), points, "trace {mode}");
        assert_eq!(r["lidar"]["files"][0].as_str(), Some(s(&file)));
    }
    // Every frame scanned; default directory: next to the output image. Particles: mode mesh
    // converts every frame's once; mode gaussian generates the traced frame's and each scanned
    // frame's.
    let sub = dir.path().join("all");
    std::fs::create_dir_all(&sub).unwrap();
    let out_img = sub.join("t.png");
    for (mode, particles) in [("mesh", RAIN * FRAMES), ("gaussian", RAIN * (FRAMES + 1))] {
        for i in 0..FRAMES {
            let _ = std::fs::remove_file(sub.join(format!("lidar_{i:04}.ply")));
        }
        let r = json(
            &[
                &[
                    "trace",
                    m,
                    "--mode",
                    mode,
                    "--lidar-all-frames",
                    "-o",
                    s(&out_img),
                ][..],
                &SIZE,
            ]
            .concat(),
        );
        let mut total = 0;
        for i in 0..FRAMES {
            total += ply_points(&sub.join(format!("lidar_{i:04}.ply")));
        }
        let e = effects(&r);
        assert_eq!(count(e, "lidar_points"), total, "{mode}");
        assert_eq!(count(e, "lidar_rays"), FRAMES * 32 * 256, "{mode}");
        assert_eq!(count(e, "particles"), particles, "{mode}");
    }
    let out = ok(&[&["trace", m, "-o", s(&out_img)][..], &SIZE].concat());
    assert!(
        out.contains(&format!(
            "effects: weather, shadows, lidar | particles {RAIN},"
        )),
        "{out}"
    );

    // convert: every frame's particles exported; the rest not simulated.
    let glb = dir.path().join("street.glb");
    let r = json(&["convert", m, "-o", s(&glb)]);
    let e = effects(&r);
    assert_eq!(count(e, "particles"), RAIN * FRAMES, "{e}");
    assert_eq!(names(e, "simulated"), ["weather"]);
    assert_eq!(names(e, "not_simulated"), ["shadows", "lidar"]);
    // OBJ per frame: frame k's particles in OBJ k only.
    let obj = dir.path().join("street.obj");
    ok(&[
        "convert",
        m,
        "-o",
        s(&obj),
        "--frames",
        "--segments",
        "4",
        "--rings",
        "1",
    ]);
    for k in 0..FRAMES {
        let text = std::fs::read_to_string(dir.path().join(format!("street_{k:04}.obj"))).unwrap();
        let frames: Vec<&str> = text.lines().filter(|l| l.starts_with("o frame_")).collect();
        assert_eq!(frames, [format!("o frame_{k}")], "OBJ frame {k}");
    }

    // An exported file carries no effects of its own; --effects-from supplies them.
    let plain = json(&[&["trace", s(&glb), "--time", "0.1", "-o", img][..], &SIZE].concat());
    assert_zero_work(effects(&plain), "trace GLB");
    let lidar = dir.path().join("lidar_glb");
    let r = json(
        &[
            &[
                "trace",
                s(&glb),
                "--effects-from",
                m,
                "--time",
                "0.1",
                "--lidar-out",
                s(&lidar),
                "-o",
                img,
            ][..],
            &SIZE,
        ]
        .concat(),
    );
    let e = effects(&r);
    assert!(count(e, "shadow_rays") > 0, "{e}");
    assert!(ply_points(&lidar.join("lidar_0001.ply")) > 0);
    // The file's particles are drawn as exported, not generated again.
    assert_eq!(count(e, "particles"), 0, "{e}");
    assert_eq!(r["exported_weather"], Value::Bool(true));
}

#[test]
fn motion_blur_adds_only_its_time_samples() {
    let dir = tempfile::tempdir().unwrap();
    let m = street(
        dir.path(),
        "blur",
        &["--effects", "motion_blur", "--insert", "car:straight"],
    );
    let v = read_json(&m);
    let samples = v["effects"]["motion_blur"]["samples"].as_u64().unwrap_or(8);
    let m = s(&m);
    let img = dir.path().join("img.png");
    let img = s(&img);
    for (cmd, extra) in [
        ("render", &[][..]),
        ("hybrid", &[][..]),
        ("trace", &["--mode", "gaussian"][..]),
        ("trace", &["--mode", "mesh"][..]),
    ] {
        let r = json(&[&[cmd, m, "--time", "1", "-o", img][..], extra, &SIZE].concat());
        let e = effects(&r);
        assert_eq!(count(e, "extra_time_samples"), samples - 1, "{cmd}: {e}");
        assert_eq!(names(e, "simulated"), ["motion_blur"], "{cmd}: {e}");
        for key in ["particles", "shadow_rays", "lidar_points", "lidar_rays"] {
            assert_eq!(count(e, key), 0, "{cmd}: {key}");
        }
        assert!(names(e, "not_simulated").is_empty(), "{cmd}: {e}");
    }
}

#[test]
fn empty_effects_object_renders_bit_identically_to_no_key() {
    let dir = tempfile::tempdir().unwrap();
    let m = street(dir.path(), "plain", &["--insert", "car:lane_change"]);
    let mut with = read_json(&m);
    with["effects"] = serde_json::json!({});
    let mut without = with.clone();
    without.as_object_mut().unwrap().remove("effects");
    let a = m.with_file_name("with_key.json");
    let b = m.with_file_name("without_key.json");
    write_json(&a, &with);
    write_json(&b, &without);
    let runs: [&[&str]; 5] = [
        &["render", "--time", "1.5"],
        &["hybrid", "--time", "1.5"],
        &["trace", "--time", "1.5", "--mode", "gaussian"],
        &["trace", "--time", "1.5", "--mode", "mesh"],
        &["render", "--time", "1.5"],
    ];
    for (i, cmd) in runs.iter().enumerate() {
        // The last run writes EXR (float RGBA and depth), the others PNG.
        let ext = if i == runs.len() - 1 { "exr" } else { "png" };
        let mut bytes = Vec::new();
        for (tag, manifest) in [("a", &a), ("b", &b)] {
            let out = dir.path().join(format!("{i}_{tag}.{ext}"));
            let args = [
                &cmd[..1],
                &[s(manifest)],
                &cmd[1..],
                &["-o", s(&out)],
                &SIZE,
            ]
            .concat();
            let r = json(&args);
            assert_zero_work(effects(&r), &args.join(" "));
            bytes.push(std::fs::read(&out).unwrap());
        }
        assert!(
            bytes[0] == bytes[1],
            "{}: \"effects\": {{}} and no key differ",
            cmd.join(" ")
        );
    }

    // And the CLI's frame is the plain composite rendered through the library.
    let scene = splatbridge_scene::manifest::load_scene(
        &a,
        &splatbridge_scene::ply::ReadOptions::default(),
    )
    .unwrap()
    .0;
    let cam = scene.cameras[0].resized(64, 48);
    let (frame, _) =
        splatbridge_hybrid::native::render(&scene.composite(1.5), &cam, &Default::default())
            .unwrap();
    let lib = dir.path().join("library.png");
    splatbridge_scene::image_io::save_frame(&lib, &frame).unwrap();
    assert!(
        std::fs::read(&lib).unwrap() == std::fs::read(dir.path().join("0_a.png")).unwrap(),
        "render differs from the library's composite render"
    );
}

#[test]
fn unknown_effect_exits_2_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let m = street(dir.path(), "plain", &[]);
    let mut v = read_json(&m);
    v["effects"] = serde_json::json!({"fog": {"density": 0.1}});
    let bad = m.with_file_name("fog.json");
    write_json(&bad, &v);
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
    ok(&["convert", s(&m), "-o", s(&glb)]);
    let out = run(&["trace", s(&glb), "--effects-from", s(&bad), "-o", s(&img)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.starts_with("error: ") && err.contains(s(&bad)), "{err}");
}
