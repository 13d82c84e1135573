//! Effects end to end on the street fixture: a manifest declaring no effects renders
//! bit-identically (native splatting and the Gaussian ray tracer) to the same manifest without
//! the `effects` key, with zero counters; each effect switched on alone adds only its own
//! counters; the street with rain, an inserted car and shadows exports to a GLB with its
//! per-frame particle nodes and animations, which passes the glTF validator and imports into
//! Blender (those two ignored, with the reason, when the tool is missing).

mod cli_common;

use std::path::Path;

use serde_json::json;
use splatbridge_convert::{ConvertOptions, FrameClouds};
use splatbridge_raytrace::lidar::{scan, LidarSensor};
use splatbridge_raytrace::shadows::{gaussian_bounds, render_gaussian_shadowed, SunShadows};
use splatbridge_raytrace::{BackendKind, BuildPreset, GaussianTracer, RenderOptions};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::EffectCounters;
use splatbridge_scene::effects_run::{blend_frames, build_blur_frames, effects_of, weather_frames};
use splatbridge_scene::fixtures::{street_edited, street_with, StreetEdits, StreetParams};
use splatbridge_scene::manifest::{load_manifest, save_manifest};
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::{Camera, Frame};

/// One frame through every renderer the way the CLI runs them: native splatting over the
/// motion-blur samples (blended), the Gaussian ray tracer at the frame time with shadows when
/// declared, and the LiDAR when declared. Returns (native, traced, counters).
fn run_frame(scene: &DynamicScene, t: f64, cam: &Camera) -> (Frame, Frame, EffectCounters) {
    let effects = effects_of(scene).unwrap();
    let blur = build_blur_frames(scene, t, Some(cam)).unwrap();
    let mut counters = blur.counters.clone();
    let natives: Vec<Frame> = blur
        .samples
        .iter()
        .map(|s| {
            splatbridge_hybrid::native::render(&s.cloud, cam, &Default::default())
                .unwrap()
                .0
        })
        .collect();
    let weights: Vec<f32> = blur.samples.iter().map(|s| s.weight).collect();
    let native = blend_frames(&natives, &weights).unwrap();
    // The tracer sees the frame at t (the first sample when nothing is blurred).
    let cloud = splatbridge_scene::effects_run::build_frame(scene, t, Some(cam))
        .unwrap()
        .cloud;
    let tracer = GaussianTracer::new(cloud, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let opts = RenderOptions::default();
    let traced = match &effects.shadows {
        Some(s) => {
            let (lo, hi) = gaussian_bounds(&tracer);
            let sun = SunShadows::from_effect(s, lo, hi).unwrap();
            let (f, _, st) = render_gaussian_shadowed(&tracer, cam, &opts, &sun).unwrap();
            counters.shadow_rays += st.shadow_rays;
            counters.simulated.push("shadows".into());
            f
        }
        None => tracer.render(cam, &opts).unwrap().0,
    };
    if let Some(l) = &effects.lidar {
        let sensor = LidarSensor::from_effect(l, &scene.cameras).unwrap();
        let s = scan(&tracer, &sensor, t);
        counters.lidar_points += s.points.len() as u64;
        counters.lidar_rays += s.rays;
        counters.simulated.push("lidar".into());
    }
    (native, traced, counters)
}

fn small_street() -> DynamicScene {
    street_with(&StreetParams::new(3, 2500))
}

fn camera(scene: &DynamicScene) -> Camera {
    scene.cameras[0].resized(96, 72)
}

#[test]
fn no_declared_effects_render_bit_identically_to_no_effects_key() {
    let dir = tempfile::tempdir().unwrap();
    let saved = save_manifest(dir.path(), &small_street()).unwrap();
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&saved.manifest).unwrap()).unwrap();
    v["effects"] = json!({});
    let a_path = dir.path().join("empty_effects.json");
    std::fs::write(&a_path, v.to_string()).unwrap();
    v.as_object_mut().unwrap().remove("effects");
    let b_path = dir.path().join("no_effects_key.json");
    std::fs::write(&b_path, v.to_string()).unwrap();
    let (a, _) = load_manifest(&a_path, &ReadOptions::default()).unwrap();
    let (b, _) = load_manifest(&b_path, &ReadOptions::default()).unwrap();
    let cam = camera(&a);
    for t in [0.0, 1.5] {
        let (na, ta, ca) = run_frame(&a, t, &cam);
        let (nb, tb, cb) = run_frame(&b, t, &cam);
        assert_eq!(na, nb, "native, t = {t}");
        assert_eq!(ta, tb, "traced, t = {t}");
        // And identical to rendering the plain composite: the effects path adds nothing.
        let plain = splatbridge_hybrid::native::render(&a.composite(t), &cam, &Default::default())
            .unwrap()
            .0;
        assert_eq!(na, plain);
        for c in [&ca, &cb] {
            assert_eq!(*c, EffectCounters::default(), "zero work: {c:?}");
        }
    }
}

#[test]
fn each_effect_switched_on_alone_adds_only_its_own_work() {
    let cases = [
        (
            "weather",
            json!({"kind": "rain", "count": 800, "seed": 2, "fall_speed": 8.0, "size": 0.01}),
        ),
        ("motion_blur", json!({"shutter": 0.04, "samples": 3})),
        (
            "shadows",
            json!({"sun_direction": [0.5, -1.0, 0.3], "strength": 0.6}),
        ),
        (
            "lidar",
            json!({"channels": 8, "vertical_fov_deg": [-20.0, 5.0], "rotation_hz": 10.0,
                   "azimuth_steps": 90, "range": 40.0,
                   "mount": {"pose": {"position": [0.0, -1.9, -10.0],
                                      "rotation": [1.0, 0.0, 0.0, 0.0]}}}),
        ),
    ];
    let base = small_street();
    let cam = camera(&base);
    let t = 1.0;
    let (n0, t0, _) = run_frame(&base, t, &cam);
    // Shadow rays go to pixels whose opacity reaches ½ (the sky above the facades gets none).
    let surface_pixels = t0.alpha.iter().filter(|&&a| a >= 0.5).count() as u64;
    assert!(surface_pixels > 96 * 72 / 2);
    for (key, value) in cases {
        let mut s = base.clone();
        s.effects.insert(key.into(), value);
        let (n, tr, c) = run_frame(&s, t, &cam);
        assert_eq!(c.simulated, [key], "{key}: {c:?}");
        let own = |k: &str| key == k;
        assert_eq!(c.particles > 0, own("weather"), "{key}: {c:?}");
        assert_eq!(c.particles, if own("weather") { 800 } else { 0 });
        assert_eq!(
            c.extra_time_samples,
            if own("motion_blur") { 2 } else { 0 },
            "{key}"
        );
        assert_eq!(
            c.shadow_rays,
            if own("shadows") { surface_pixels } else { 0 },
            "{key}"
        );
        assert_eq!(c.lidar_rays, if own("lidar") { 8 * 90 } else { 0 }, "{key}");
        assert_eq!(c.lidar_points > 0, own("lidar"), "{key}");
        // The images change only where the effect acts: LiDAR changes neither, shadows only the
        // traced image, blur only the native (blended) one.
        match key {
            "lidar" => assert!(n == n0 && tr == t0),
            "shadows" => assert!(n == n0 && tr != t0),
            "motion_blur" => assert!(n != n0 && tr == t0),
            _ => assert!(n != n0 && tr != t0),
        }
    }
}

/// The street with rain, an inserted car and shadows, exported with its per-frame particles:
/// the GLB bytes and where they were written.
fn effects_export(dir: &Path) -> (Vec<u8>, std::path::PathBuf) {
    let edits = StreetEdits {
        effects: vec!["rain".into(), "shadows".into()],
        inserts: vec![("lane_change".into(), None)],
    };
    let (mut scene, _) = street_edited(&StreetParams::new(1, 3000), &edits).unwrap();
    // Fewer particles keep the file small: 41 frames (4 s at 10 fps) of 300.
    scene.effects["weather"]["count"] = json!(300);
    let (times, clouds) = weather_frames(&scene).unwrap().unwrap();
    assert_eq!(times.len(), 41);
    assert!(clouds.iter().all(|c| c.len() == 300));
    let frames = FrameClouds { times, clouds };
    let (bytes, _) =
        splatbridge_convert::glb_bytes(&scene, Some(&frames), &ConvertOptions::default()).unwrap();
    let path = dir.join("street-effects.glb");
    std::fs::write(&path, &bytes).unwrap();
    (bytes, path)
}

#[test]
fn street_with_rain_inserted_car_and_shadows_exports_per_frame_particles() {
    let dir = tempfile::tempdir().unwrap();
    let (bytes, path) = effects_export(dir.path());
    // What a viewer loads: one node per frame, visible only at its frame (STEP), and the
    // moving objects (two cars and the inserted one) animated.
    let tri = splatbridge_raytrace::scene_load::load_glb_bytes(&bytes, &path).unwrap();
    let frame_nodes = tri
        .nodes
        .iter()
        .filter(|n| n.name.starts_with("frame_"))
        .count();
    assert_eq!(frame_nodes, 41);
    let visible_at = |t: f64| {
        tri.instances(t)
            .iter()
            .filter(|i| tri.nodes[i.node].name.starts_with("frame_"))
            .count()
    };
    assert_eq!(visible_at(0.0), 1);
    assert_eq!(visible_at(0.55), 1);
    let animated: std::collections::HashSet<usize> = tri.channels.iter().map(|c| c.node).collect();
    assert!(
        animated.len() >= 3 + 41,
        "{} animated nodes",
        animated.len()
    );
}

#[test]
#[cfg_attr(
    not(gltf_tools),
    ignore = "needs the glTF validator wrapper (../shared/tools), node and npm"
)]
fn street_effects_export_is_validator_clean() {
    let dir = tempfile::tempdir().unwrap();
    let (_, path) = effects_export(dir.path());
    cli_common::client_check("validate-exports.sh", &["--mesh"], &path);
}

#[test]
#[cfg_attr(not(blender), ignore = "needs Blender on PATH")]
fn street_effects_export_imports_into_blender() {
    let dir = tempfile::tempdir().unwrap();
    let (_, path) = effects_export(dir.path());
    let stdout = cli_common::client_check("blender-check.sh", &[], &path);
    // Moving objects and the 41 per-frame particle nodes (STEP scale visibility) are all
    // animated objects in Blender; the check accounts for both kinds.
    assert!(stdout.contains("\"problems\": []"), "{stdout}");
}
