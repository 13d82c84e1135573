//! The frame producer: undeclared effects cost nothing and change nothing, each declared
//! effect adds only its own work, particles are deterministic, motion-blur samples equal the
//! composite at their times, per-frame weather for export.

use glam::Vec3;
use serde_json::json;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::EffectCounters;
use splatbridge_scene::effects_run::{
    blend_frames, build_blur_frames, build_frame, time_samples, weather_frames, weather_object_id,
    weather_volume,
};
use splatbridge_scene::fixtures::{street_with, StreetParams};
use splatbridge_scene::manifest::{load_manifest, save_manifest};
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::Frame;

fn small_street() -> DynamicScene {
    street_with(&StreetParams::new(7, 2000))
}

fn with_effect(key: &str, value: serde_json::Value) -> DynamicScene {
    let mut s = small_street();
    s.effects.insert(key.into(), value);
    s
}

fn rain() -> serde_json::Value {
    json!({"kind": "rain", "count": 500, "seed": 3, "fall_speed": 8.0, "size": 0.01,
           "wind": [0.5, 0.0, 0.0], "turbulence": 0.02})
}

#[test]
fn empty_effects_key_and_no_key_load_to_identical_frames_with_zero_counters() {
    let dir = tempfile::tempdir().unwrap();
    let saved = save_manifest(dir.path(), &small_street()).unwrap();
    let text = std::fs::read_to_string(&saved.manifest).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["effects"] = json!({});
    let with_empty = dir.path().join("with_empty.json");
    std::fs::write(&with_empty, serde_json::to_string(&v).unwrap()).unwrap();
    v.as_object_mut().unwrap().remove("effects");
    let without = dir.path().join("without.json");
    std::fs::write(&without, serde_json::to_string(&v).unwrap()).unwrap();
    let (a, _) = load_manifest(&with_empty, &ReadOptions::default()).unwrap();
    let (b, _) = load_manifest(&without, &ReadOptions::default()).unwrap();
    for t in a.frame_times() {
        let fa = build_frame(&a, t, None).unwrap();
        let fb = build_frame(&b, t, None).unwrap();
        assert_eq!(fa.cloud, fb.cloud, "t = {t}");
        // Nothing declared: exactly the composite, and no work at all.
        assert_eq!(fa.cloud, a.composite(t));
        assert_eq!(fa.counters, EffectCounters::default());
        assert!(fa.counters.is_zero() && fb.counters.is_zero());
        let blur = build_blur_frames(&a, t, None).unwrap();
        assert_eq!(blur.samples.len(), 1);
        assert_eq!(blur.samples[0].cloud, fa.cloud);
        assert!(blur.counters.is_zero());
        assert_eq!(time_samples(&a, t).unwrap(), vec![(t, 1.0)]);
    }
    assert!(weather_frames(&a).unwrap().is_none());
}

#[test]
fn each_effect_alone_adds_only_its_own_work() {
    let t = 1.3;
    let base = small_street().composite(t);
    // Weather: particles, nothing else; the scene's Gaussians come first, unchanged.
    let s = with_effect("weather", rain());
    let f = build_frame(&s, t, None).unwrap();
    assert_eq!(f.counters.particles, 500);
    assert_eq!(f.counters.extra_time_samples, 0);
    assert_eq!((f.counters.shadow_rays, f.counters.lidar_points), (0, 0));
    assert_eq!(f.counters.simulated, ["weather"]);
    assert_eq!(f.cloud.len(), base.len() + 500);
    assert_eq!(&f.cloud.means[..base.len()], &base.means[..]);
    let ids = f.cloud.object_ids.as_ref().unwrap();
    assert!(ids[base.len()..]
        .iter()
        .all(|&i| i == weather_object_id(&s)));
    // Motion blur: extra time samples only, no particles.
    let s = with_effect("motion_blur", json!({"shutter": 0.05, "samples": 4}));
    let f = build_frame(&s, t, None).unwrap();
    assert_eq!(
        f.cloud, base,
        "blur is not content: the frame itself is unchanged"
    );
    assert!(f.counters.is_zero());
    let b = build_blur_frames(&s, t, None).unwrap();
    assert_eq!(b.samples.len(), 4);
    assert_eq!(b.counters.extra_time_samples, 3);
    assert_eq!(b.counters.particles, 0);
    assert_eq!(b.counters.simulated, ["motion_blur"]);
    // Shadows and LiDAR are the tracer's work: the frame content and its counters are untouched.
    for (key, value) in [
        (
            "shadows",
            json!({"sun_direction": [0.3, -1.0, 0.2], "strength": 0.5}),
        ),
        (
            "lidar",
            json!({"channels": 4, "vertical_fov_deg": [-10, 0], "rotation_hz": 10,
                   "azimuth_steps": 16, "range": 20, "mount": {"camera": {"index": 0}}}),
        ),
    ] {
        let s = with_effect(key, value);
        let f = build_frame(&s, t, None).unwrap();
        assert_eq!(f.cloud, base, "{key}");
        assert!(f.counters.is_zero(), "{key}");
        assert_eq!(build_blur_frames(&s, t, None).unwrap().samples.len(), 1);
    }
}

#[test]
fn particles_are_deterministic_for_a_seed_and_differ_between_seeds() {
    let s = with_effect("weather", rain());
    let a = build_frame(&s, 0.7, None).unwrap().cloud;
    let b = build_frame(&s, 0.7, None).unwrap().cloud;
    assert_eq!(a, b);
    let mut r = rain();
    r["seed"] = json!(4);
    let c = build_frame(&with_effect("weather", r), 0.7, None)
        .unwrap()
        .cloud;
    assert_ne!(a.means, c.means);
    // A frame's particles do not depend on which other frames were generated.
    let (times, clouds) = weather_frames(&s).unwrap().unwrap();
    assert_eq!(times, s.frame_times());
    let k = times.iter().position(|&t| t == 0.7).unwrap_or(7);
    let n = s.gaussian_count();
    let f = build_frame(&s, times[k], None).unwrap().cloud;
    assert_eq!(clouds[k].means[..], f.means[n..]);
    assert_eq!(clouds[k].len(), 500);
}

#[test]
fn scene_volume_contains_the_particles_and_flat_scenes_get_air() {
    let s = with_effect("weather", rain());
    let w: splatbridge_scene::effects::Weather = serde_json::from_value(rain()).unwrap();
    let (lo, hi) = weather_volume(&s, &w, 0.0, None).unwrap();
    let (rlo, rhi) = s.static_gaussians.robust_bounds(0.02).unwrap();
    assert_eq!((lo, hi), (rlo, rhi), "the street is not flat: no widening");
    let f = build_frame(&s, 2.0, None).unwrap().cloud;
    for m in &f.means[s.gaussian_count()..] {
        assert!(m.cmpge(lo).all() && m.cmple(hi).all());
    }
    // A ground-only cloud: the volume gets 1/10 of its largest extent of air above (−y).
    let mut flat = splatbridge_scene::GaussianCloud::new(0);
    for i in 0..100 {
        let (x, z) = ((i % 10) as f32, (i / 10) as f32);
        flat.push_activated(
            Vec3::new(x, 0.0, z),
            Vec3::splat(0.1),
            glam::Quat::IDENTITY,
            0.9,
            Vec3::ONE,
        );
    }
    let mut fs = DynamicScene::from_static(flat);
    fs.effects.insert("weather".into(), rain());
    let (lo, hi) = weather_volume(&fs, &w, 0.0, None).unwrap();
    assert_eq!(hi.y, 0.0);
    assert!((lo.y - (-0.1 * (hi.x - lo.x))).abs() < 1e-6, "{lo} {hi}");
    // The camera volume without any camera is a clear error.
    let mut cw = rain();
    cw["volume"] = json!({"camera": {"index": 9, "half_extent": [5, 5, 5]}});
    let cs = with_effect("weather", cw);
    let e = build_frame(&cs, 0.0, None).unwrap_err().to_string();
    assert!(e.contains("camera.index = 9"), "{e}");
    let cam = cs.cameras[0].clone();
    let f = build_frame(&cs, 0.0, Some(&cam)).unwrap();
    let c = cam.centre.as_vec3();
    for m in &f.cloud.means[cs.gaussian_count()..] {
        assert!((*m - c).abs().max_element() <= 5.0 + 1e-4);
    }
}

#[test]
fn blur_samples_equal_the_composite_at_their_times() {
    let mut s = with_effect("motion_blur", json!({"shutter": 0.1, "samples": 5}));
    s.effects.insert("weather".into(), rain());
    let t = 1.0;
    let samples = time_samples(&s, t).unwrap();
    assert_eq!(samples.len(), 5);
    let wsum: f32 = samples.iter().map(|x| x.1).sum();
    assert!((wsum - 1.0).abs() < 1e-6);
    assert!(samples.iter().all(|&(ts, _)| ts > t && ts < t + 0.1));
    let b = build_blur_frames(&s, t, None).unwrap();
    let particles = build_frame(&s, t, None).unwrap().cloud;
    let n = s.gaussian_count();
    for (smp, &(ts, w)) in b.samples.iter().zip(&samples) {
        assert_eq!((smp.time, smp.weight), (ts, w));
        let mut want = s.composite(ts);
        want.extend_from(
            &{
                let mut p = particles.clone();
                p.retain_indices(|i| i >= n);
                p
            },
            Some(weather_object_id(&s)),
        );
        assert_eq!(smp.cloud, want, "sample at {ts}");
    }
    assert_eq!(b.counters.extra_time_samples, 4);
    assert_eq!(
        b.counters.particles, 500,
        "particles once per frame, shared by samples"
    );
    // A scene where nothing moves is sampled once even with motion blur declared.
    let mut still = s.clone();
    for o in &mut still.objects {
        o.track = splatbridge_scene::dynamic::Track::constant(o.track.sample(0.0));
    }
    assert_eq!(time_samples(&still, t).unwrap().len(), 1);
    assert_eq!(
        build_blur_frames(&still, t, None)
            .unwrap()
            .counters
            .extra_time_samples,
        0
    );
}

#[test]
fn blend_frames_is_the_weighted_mean() {
    let mut a = Frame::new(2, 1);
    let mut b = Frame::new(2, 1);
    a.rgb = vec![1.0, 0.0, 0.0, 0.2, 0.2, 0.2];
    b.rgb = vec![0.0, 1.0, 0.0, 0.4, 0.4, 0.4];
    a.alpha = vec![1.0, 0.0];
    b.alpha = vec![1.0, 1.0];
    a.depth = vec![2.0, 0.0];
    b.depth = vec![4.0, 6.0];
    let c = blend_frames(&[a.clone(), b.clone()], &[3.0, 1.0]).unwrap();
    assert_eq!(c.rgb, vec![0.75, 0.25, 0.0, 0.25, 0.25, 0.25]);
    assert_eq!(c.alpha, vec![1.0, 0.25]);
    // Depth weighted by weight × alpha: (0.75·2 + 0.25·4)/1 and (0.25·6)/0.25.
    assert_eq!(c.depth, vec![2.5, 6.0]);
    assert!(blend_frames(&[a.clone()], &[1.0, 2.0]).is_err());
    assert!(blend_frames(&[a, b], &[0.0, 0.0]).is_err());
    assert!(blend_frames(&[], &[]).is_err());
}
