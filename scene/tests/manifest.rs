//! The `splatbridge-scene/1` manifest: round trip through save_manifest/load_scene, and invalid
//! manifests each giving an error that names the file and the field.

use std::path::Path;

use glam::{DVec3, Quat, Vec3};
use splatbridge_scene::camera::Camera;
use splatbridge_scene::dynamic::{DynamicScene, PoseKey, SceneObject, TimeRange, Track};
use splatbridge_scene::manifest::{load_scene, save_manifest};
use splatbridge_scene::ply::{write_ply, PlyFormat, ReadOptions};
use splatbridge_scene::GaussianCloud;

fn small_cloud(n: usize, degree: u8, seed: f32) -> GaussianCloud {
    let mut c = GaussianCloud::new(degree);
    let k = c.coeffs();
    for i in 0..n {
        let f = i as f32 + seed;
        let sh: Vec<Vec3> = (0..k)
            .map(|j| Vec3::new(0.1 * f, -0.01 * j as f32, 0.3))
            .collect();
        c.push(
            Vec3::new(f, -f, 2.0 * f),
            Vec3::splat(-2.0 - 0.1 * f),
            Quat::from_xyzw(0.1, 0.2, 0.3, 1.0 + f),
            0.5 - f,
            &sh,
        );
    }
    c
}

fn small_scene() -> DynamicScene {
    let track = Track::new(vec![
        PoseKey::new(0.0, Vec3::ZERO, Quat::IDENTITY),
        PoseKey::new(1.0, Vec3::new(1.0, 0.0, 2.0), Quat::from_rotation_y(0.5)),
        PoseKey::new(2.5, Vec3::new(3.0, 0.0, 2.0), Quat::from_rotation_y(1.5)),
    ]);
    let cam = Camera::look_at(
        DVec3::new(0.0, -2.0, -10.0),
        DVec3::ZERO,
        DVec3::NEG_Y,
        50.0,
        64,
        48,
    )
    .unwrap();
    let mut effects = serde_json::Map::new();
    effects.insert(
        "shadows".into(),
        serde_json::json!({"sun_direction": [0.3, 1.0, 0.2], "strength": 0.6}),
    );
    DynamicScene {
        time: TimeRange {
            start: 0.0,
            end: 2.5,
            fps: 4.0,
        },
        static_gaussians: small_cloud(5, 3, 0.0),
        objects: vec![
            SceneObject {
                name: "car 0".into(),
                gaussians: small_cloud(3, 3, 10.0),
                track,
            },
            SceneObject {
                name: "car/1".into(),
                gaussians: small_cloud(2, 1, 20.0),
                track: Track::constant(splatbridge_scene::dynamic::Pose::new(
                    Vec3::X,
                    Quat::IDENTITY,
                )),
            },
        ],
        frames: Vec::new(),
        cameras: vec![cam],
        effects,
        four_d: None,
    }
}

#[test]
fn save_then_load_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let scene = small_scene();
    let saved = save_manifest(dir.path(), &scene).unwrap();
    assert_eq!(saved.manifest, dir.path().join("scene.json"));
    for f in [
        "static.ply",
        "car_0.ply",
        "car_1.ply",
        "cameras.json",
        "scene.json",
    ] {
        assert!(dir.path().join(f).is_file(), "{f} written");
    }
    let (back, warnings) = load_scene(&saved.manifest, &ReadOptions::default()).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(back.time, scene.time);
    assert_eq!(
        back.effects, scene.effects,
        "declared effects kept as written"
    );
    assert_eq!(back.static_gaussians, scene.static_gaussians);
    assert_eq!(back.objects.len(), 2);
    for (a, b) in back.objects.iter().zip(&scene.objects) {
        assert_eq!(a.name, b.name);
        assert_eq!(a.gaussians, b.gaussians);
        assert_eq!(
            a.track, b.track,
            "tracks round-trip exactly (f32 values, shortest JSON repr)"
        );
    }
    assert_eq!(back.cameras.len(), 1);
    assert!((back.cameras[0].centre - scene.cameras[0].centre).length() < 1e-12);
    // Composites agree bit for bit.
    for t in [0.0, 0.7, 2.5] {
        assert_eq!(back.composite(t), scene.composite(t));
    }
}

#[test]
fn plain_ply_is_a_static_scene() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("s.ply");
    let c = small_cloud(4, 2, 0.0);
    write_ply(&p, &c, PlyFormat::BinaryLittleEndian).unwrap();
    let (scene, _) = load_scene(&p, &ReadOptions::default()).unwrap();
    assert_eq!(scene.static_gaussians, c);
    assert!(scene.objects.is_empty());
    assert_eq!(scene.frame_times(), vec![0.0]);
}

#[test]
fn trajectory_rules_generate_tracks() {
    let dir = tempfile::tempdir().unwrap();
    write_ply(
        &dir.path().join("car.ply"),
        &small_cloud(2, 0, 0.0),
        PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    let m = r#"{"format": "splatbridge-scene/1", "time": {"start": 0, "end": 2, "fps": 5},
        "objects": [{"name": "ins", "gaussians": "car.ply",
                     "trajectory": {"kind": "straight", "start": [0, 0, 0], "heading_deg": 0, "speed": 3}}]}"#;
    let p = dir.path().join("scene.json");
    std::fs::write(&p, m).unwrap();
    let (scene, _) = load_scene(&p, &ReadOptions::default()).unwrap();
    let tr = &scene.objects[0].track;
    assert_eq!(tr.keys.len(), 11);
    // 3 units/s along heading 0 for 2 s: 6 units from the start.
    assert!((tr.sample(2.0).translation.length() - 6.0).abs() < 1e-4);
}

/// Write `manifest` next to valid `a.ply`, `b.ply` and `cameras.json`, load it, return the error.
fn load_err(manifest: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    write_files(dir.path());
    let p = dir.path().join("scene.json");
    std::fs::write(&p, manifest).unwrap();
    let err = load_scene(&p, &ReadOptions::default()).expect_err("manifest must be rejected");
    let msg = err.to_string();
    assert!(
        msg.contains("scene.json"),
        "error names the manifest: {msg}"
    );
    msg
}

fn write_files(dir: &Path) {
    write_ply(
        &dir.join("a.ply"),
        &small_cloud(3, 3, 0.0),
        PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    write_ply(
        &dir.join("b.ply"),
        &small_cloud(2, 3, 1.0),
        PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    std::fs::write(dir.join("garbage.ply"), b"ply\nformat nonsense\n").unwrap();
    std::fs::write(dir.join("cameras.json"), b"[]").unwrap();
}

/// A valid manifest with `object` as its only object and `extra` top-level members.
fn with_object(object: &str, extra: &str) -> String {
    format!(
        r#"{{"format": "splatbridge-scene/1", "time": {{"start": 0, "end": 4, "fps": 10}},
            "static": "a.ply", "objects": [{object}] {extra}}}"#
    )
}

const GOOD_OBJECT: &str = r#"{"name": "car_0", "gaussians": "b.ply",
    "track": [{"t": 0, "translation": [0,0,0], "rotation": [1,0,0,0]},
              {"t": 1, "translation": [1,0,0], "rotation": [0,0,1,0]}]}"#;

#[test]
fn valid_baseline_loads() {
    // The invalid cases below differ from this one in a single place.
    let dir = tempfile::tempdir().unwrap();
    write_files(dir.path());
    let p = dir.path().join("scene.json");
    std::fs::write(
        &p,
        with_object(GOOD_OBJECT, r#", "cameras": "cameras.json", "effects": {}"#),
    )
    .unwrap();
    let (scene, _) = load_scene(&p, &ReadOptions::default()).unwrap();
    assert_eq!(scene.gaussian_count(), 5);
    assert_eq!(scene.frame_times().len(), 41);
}

#[test]
fn unknown_format() {
    let m = with_object(GOOD_OBJECT, "").replace("splatbridge-scene/1", "splatbridge-scene/2");
    let e = load_err(&m);
    assert!(
        e.contains("unknown format") && e.contains("splatbridge-scene/2"),
        "{e}"
    );
}

#[test]
fn missing_format() {
    let e = load_err(r#"{"time": {"start": 0, "end": 1, "fps": 1}}"#);
    assert!(e.contains("\"format\""), "{e}");
}

#[test]
fn not_json() {
    let e = load_err("{\"format\": \"splatbridge-scene/1\",\n \"time\": }");
    assert!(e.contains("not valid JSON") && e.contains("line 2"), "{e}");
}

#[test]
fn missing_files_are_all_named() {
    let obj = GOOD_OBJECT.replace("b.ply", "nowhere/car.ply");
    let m = with_object(&obj, "").replace("\"a.ply\"", "\"bg.ply\"");
    let e = load_err(&m);
    assert!(e.contains("missing files"), "{e}");
    assert!(e.contains("static \"bg.ply\""), "{e}");
    assert!(
        e.contains("objects[0] ('car_0').gaussians \"nowhere/car.ply\""),
        "{e}"
    );
    let e = load_err(&with_object(GOOD_OBJECT, r#", "cameras": "cams.json""#));
    assert!(e.contains("cameras \"cams.json\""), "{e}");
}

#[test]
fn times_not_increasing() {
    let obj = GOOD_OBJECT.replace("\"t\": 1", "\"t\": 0");
    let e = load_err(&with_object(&obj, ""));
    assert!(
        e.contains("objects[0] ('car_0')")
            && e.contains("track[1].t = 0 is not after track[0].t = 0"),
        "{e}"
    );
}

#[test]
fn empty_track() {
    let e = load_err(&with_object(
        r#"{"name": "car_0", "gaussians": "b.ply", "track": []}"#,
        "",
    ));
    assert!(
        e.contains("objects[0] ('car_0')") && e.contains("track is empty"),
        "{e}"
    );
    let e = load_err(&with_object(
        r#"{"name": "car_0", "gaussians": "b.ply"}"#,
        "",
    ));
    assert!(e.contains("no \"track\""), "{e}");
}

#[test]
fn non_finite_values() {
    // 1e39 overflows f32: the translation becomes infinite and is rejected.
    let obj = GOOD_OBJECT.replace("[1,0,0]", "[1e39,0,0]");
    let e = load_err(&with_object(&obj, ""));
    assert!(
        e.contains("track[1].translation") && e.contains("not finite"),
        "{e}"
    );
    let obj = GOOD_OBJECT.replace("[0,0,1,0]", "[0,1e39,1,0]");
    let e = load_err(&with_object(&obj, ""));
    assert!(
        e.contains("track[1].rotation") && e.contains("not finite"),
        "{e}"
    );
    // f64 overflow is caught by the JSON parser, with the line.
    let e = load_err(&with_object(GOOD_OBJECT, "").replace("\"end\": 4", "\"end\": 1e400"));
    assert!(e.contains("line 1"), "{e}");
}

#[test]
fn zero_quaternion_in_track() {
    let obj = GOOD_OBJECT.replace("[0,0,1,0]", "[0,0,0,0]");
    let e = load_err(&with_object(&obj, ""));
    assert!(
        e.contains("track[1].rotation is the zero quaternion"),
        "{e}"
    );
}

#[test]
fn unknown_effect_name() {
    let e = load_err(&with_object(GOOD_OBJECT, r#", "effects": {"fog": {}}"#));
    assert!(
        e.contains("unknown effect \"fog\"") && e.contains("weather, motion_blur, shadows, lidar"),
        "{e}"
    );
    let e = load_err(&with_object(GOOD_OBJECT, r#", "effects": {"shadows": 3}"#));
    assert!(e.contains("effects.shadows: expected an object"), "{e}");
}

#[test]
fn unknown_keys_are_errors() {
    let e = load_err(&with_object(GOOD_OBJECT, r#", "statics": "a.ply""#));
    assert!(e.contains("unknown field `statics`"), "{e}");
    let obj = GOOD_OBJECT.replace("\"track\"", "\"trak\"");
    let e = load_err(&with_object(&obj, ""));
    assert!(e.contains("unknown field `trak`"), "{e}");
}

#[test]
fn bad_time_range() {
    let e = load_err(&with_object(GOOD_OBJECT, "").replace("\"end\": 4", "\"end\": -1"));
    assert!(e.contains("time.end = -1 is before time.start = 0"), "{e}");
    let e = load_err(&with_object(GOOD_OBJECT, "").replace("\"fps\": 10", "\"fps\": 0"));
    assert!(e.contains("time.fps = 0 must be positive"), "{e}");
    let e = load_err(r#"{"format": "splatbridge-scene/1", "static": "a.ply"}"#);
    assert!(e.contains("missing field `time`"), "{e}");
}

#[test]
fn duplicate_object_names() {
    let m = with_object(&format!("{GOOD_OBJECT}, {GOOD_OBJECT}"), "");
    let e = load_err(&m);
    assert!(
        e.contains("objects[1] ('car_0'): name already used by objects[0]"),
        "{e}"
    );
}

#[test]
fn broken_referenced_files_name_both_files() {
    let obj = GOOD_OBJECT.replace("b.ply", "garbage.ply");
    let e = load_err(&with_object(&obj, ""));
    assert!(
        e.contains("objects[0] ('car_0').gaussians") && e.contains("garbage.ply"),
        "{e}"
    );
    let dir = tempfile::tempdir().unwrap();
    write_files(dir.path());
    std::fs::write(dir.path().join("cameras.json"), b"{\"not\": \"cameras\"}").unwrap();
    let p = dir.path().join("scene.json");
    std::fs::write(
        &p,
        with_object(GOOD_OBJECT, r#", "cameras": "cameras.json""#),
    )
    .unwrap();
    let e = load_scene(&p, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("scene.json") && e.contains("cameras") && e.contains("cameras.json"),
        "{e}"
    );
}

#[test]
fn save_rejects_invalid_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = small_scene();
    scene.objects[0].track.keys.clear();
    let e = save_manifest(dir.path(), &scene).unwrap_err().to_string();
    assert!(
        e.contains("objects[0] ('car 0')") && e.contains("empty"),
        "{e}"
    );
    assert!(!dir.path().join("scene.json").exists());
}

#[test]
fn save_rejects_unknown_effects() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = small_scene();
    scene.effects.clear();
    scene.effects.insert("fog".into(), serde_json::json!({}));
    let e = save_manifest(dir.path(), &scene).unwrap_err().to_string();
    assert!(e.contains("unknown effect \"fog\""), "{e}");
    assert!(!dir.path().join("static.ply").exists(), "nothing written");
}
