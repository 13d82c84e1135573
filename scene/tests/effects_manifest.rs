//! Training-free editing in the manifest: inserted objects with trajectory rules, removal and
//! retiming, and the validation errors each gives; the edited street fixture.

use serde_json::json;
use splatbridge_scene::fixtures::{street_edited, StreetEdits, StreetParams};
use splatbridge_scene::manifest::{load_manifest, parse_manifest, save_manifest};
use splatbridge_scene::ply::ReadOptions;

/// A saved small street and its manifest as JSON.
fn saved() -> (tempfile::TempDir, serde_json::Value) {
    let dir = tempfile::tempdir().unwrap();
    let scene = splatbridge_scene::fixtures::street_with(&StreetParams::new(5, 1500));
    let s = save_manifest(dir.path(), &scene).unwrap();
    let v = serde_json::from_str(&std::fs::read_to_string(s.manifest).unwrap()).unwrap();
    (dir, v)
}

fn load(
    dir: &tempfile::TempDir,
    v: &serde_json::Value,
) -> Result<splatbridge_scene::dynamic::DynamicScene, String> {
    let p = dir.path().join("edited.json");
    std::fs::write(&p, serde_json::to_string_pretty(v).unwrap()).unwrap();
    load_manifest(&p, &ReadOptions::default())
        .map(|(s, _)| s)
        .map_err(|e| e.to_string())
}

/// The load error (a scene's Debug output is too large to print on an unexpected success).
fn fail(dir: &tempfile::TempDir, v: &serde_json::Value) -> String {
    match load(dir, v) {
        Ok(_) => panic!("the edited manifest loaded"),
        Err(e) => e,
    }
}

#[test]
fn removed_objects_are_left_out_and_need_no_file() {
    let (dir, mut v) = saved();
    v["objects"][0]["remove"] = json!(true);
    v["objects"][0]["gaussians"] = json!("does_not_exist.ply");
    let s = load(&dir, &v).unwrap();
    assert_eq!(s.objects.len(), 1);
    assert_eq!(s.objects[0].name, "car_1");
    // Removal needs no track either.
    v["objects"][0].as_object_mut().unwrap().remove("track");
    assert_eq!(load(&dir, &v).unwrap().objects.len(), 1);
    // But an object that is not removed still needs its file.
    v["objects"][0]["remove"] = json!(false);
    let e = fail(&dir, &v);
    assert!(e.contains("objects[0] ('car_0')"), "{e}");
}

#[test]
fn retimed_objects_replay_their_motion() {
    let (dir, mut v) = saved();
    let original = load(&dir, &v).unwrap();
    v["objects"][1]["retime"] = json!({"offset": 0.5, "scale": 2.0});
    let s = load(&dir, &v).unwrap();
    let (a, b) = (&original.objects[1].track, &s.objects[1].track);
    // Pose at scene time t = original pose at (t − 0.5)·2 (the scene starts at 0).
    for t in [0.0, 0.5, 0.8, 1.1, 1.7, 2.4, 3.0] {
        let want = a.sample(((t - 0.5) * 2.0f64).max(0.0));
        let got = b.sample(t);
        assert!(
            (want.translation - got.translation).length() < 1e-4,
            "t = {t}: {} vs {}",
            got.translation,
            want.translation
        );
        assert!(want.rotation.dot(got.rotation).abs() > 1.0 - 1e-6);
    }
    // The other object is untouched.
    assert_eq!(original.objects[0].track, s.objects[0].track);
}

#[test]
fn edit_errors_name_the_object_and_the_field() {
    let (dir, v) = saved();
    let cases = [
        (json!({"offset": 0.0, "scale": 0.0}), "retime.scale"),
        (json!({"offset": 0.0, "scale": -1.0}), "retime.scale"),
        (json!({"offset": 0.0, "speed": 2.0}), "speed"),
    ];
    for (retime, needle) in cases {
        let mut w = v.clone();
        w["objects"][1]["retime"] = retime.clone();
        let e = fail(&dir, &w);
        assert!(e.contains(needle), "{retime}: {e}");
    }
    let mut w = v.clone();
    w["objects"][1]["retime"] = json!({"offset": 0.0, "scale": 1.0});
    w["objects"][1]["remove"] = json!(true);
    let e = fail(&dir, &w);
    assert!(
        e.contains("objects[1] ('car_1')") && e.contains("contradict"),
        "{e}"
    );
    let mut w = v.clone();
    w["objects"][0]["remove"] = json!("yes");
    assert!(load(&dir, &w).is_err());
    // An offset so large that f64 rounds neighbouring keys onto one time (ulp(1e17) = 16 s).
    let mut w = v.clone();
    w["objects"][1]["retime"] = json!({"offset": 1e17, "scale": 1.0});
    let e = fail(&dir, &w);
    assert!(e.contains("collapse"), "{e}");
    // Inserted objects: a rule with a bad parameter and both a track and a rule.
    let mut w = v.clone();
    w["objects"][1].as_object_mut().unwrap().remove("track");
    w["objects"][1]["trajectory"] = json!({"kind": "turn", "start": [0, 0, 0], "speed": 5,
                                           "radius": -1, "angle_deg": 90, "begin": 0});
    let e = fail(&dir, &w);
    assert!(
        e.contains("objects[1] ('car_1')") && e.contains("radius"),
        "{e}"
    );
    let mut w = v.clone();
    w["objects"][1]["trajectory"] = json!({"kind": "straight", "start": [0, 0, 0], "speed": 5});
    let e = fail(&dir, &w);
    assert!(e.contains("not both"), "{e}");
}

#[test]
fn edited_street_declares_effects_and_inserts_rule_driven_cars() {
    let edits = StreetEdits {
        effects: vec!["rain".into(), "shadows".into(), "lidar".into()],
        inserts: vec![("lane_change".into(), None), ("turn".into(), None)],
    };
    let (scene, inserted) = street_edited(&StreetParams::new(2, 2000), &edits).unwrap();
    assert_eq!(scene.objects.len(), 4);
    assert_eq!(inserted.len(), 2);
    let mut keys: Vec<&str> = scene.effects.keys().map(|k| k.as_str()).collect();
    keys.sort();
    assert_eq!(keys, ["lidar", "shadows", "weather"]);
    // The lane change ends in the +x lane heading +z, as the rule says.
    let lc = &scene.objects[2].track;
    let end = lc.sample(4.0);
    assert!(
        (end.translation.x - 2.0).abs() < 1e-4,
        "{}",
        end.translation
    );
    let fwd = end.rotation * glam::Vec3::X;
    assert!((fwd - glam::Vec3::Z).length() < 1e-4, "{fwd}");
    // The generated scene saves and loads back with its effects.
    let dir = tempfile::tempdir().unwrap();
    let s = save_manifest(dir.path(), &scene).unwrap();
    let text = std::fs::read_to_string(&s.manifest).unwrap();
    parse_manifest(&s.manifest, &text).unwrap();
    // Errors: unknown effect, unknown rule, two weathers.
    for (e, i, needle) in [
        (vec!["fog"], vec![], "fog"),
        (vec![], vec!["teleport"], "teleport"),
        (vec!["rain", "snow"], vec![], "already declared"),
    ] {
        let edits = StreetEdits {
            effects: e.into_iter().map(String::from).collect(),
            inserts: i.into_iter().map(|r| (r.to_string(), None)).collect(),
        };
        let err = match street_edited(&StreetParams::new(2, 2000), &edits) {
            Ok(_) => panic!("edits were accepted"),
            Err(e) => e,
        };
        assert!(err.contains(needle), "{err}");
    }
}
