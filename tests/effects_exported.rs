//! Shadows and LiDAR on what the converter exports (mode mesh, the GLB loaded back) and on the
//! Gaussians (mode gaussian): an inserted, rule-driven car darkens the ground behind it towards
//! the sun at its pose of the frame and nowhere else, and LiDAR beams aimed through the car
//! return on the car, in both modes.

use std::path::Path;

use glam::{DVec3, Vec3};
use splatbridge_convert::ConvertOptions;
use splatbridge_raytrace::geom::ray_box;
use splatbridge_raytrace::lidar::{scan, LidarSensor, OpacityMarch};
use splatbridge_raytrace::shadows::{mesh_bounds, render_mesh_shadowed, SunShadows};
use splatbridge_raytrace::{BackendKind, BuildPreset, GaussianTracer, MeshTracer, RenderOptions};
use splatbridge_scene::dynamic::{DynamicScene, Pose};
use splatbridge_scene::effects::{Lidar, LidarMount, Shadows};
use splatbridge_scene::fixtures::{street_edited, StreetEdits, StreetParams};

/// The street with one car inserted by the lane-change rule (object 2): at t = 2 s it is half
/// way through the manoeuvre at (0, 0, −10); at t = 0 it is at z = −30.
fn scene() -> DynamicScene {
    let edits = StreetEdits {
        effects: Vec::new(),
        inserts: vec![("lane_change".into(), None)],
    };
    street_edited(&StreetParams::new(4, 3000), &edits)
        .unwrap()
        .0
}

fn exported(scene: &DynamicScene) -> MeshTracer {
    let (bytes, _) =
        splatbridge_convert::glb_bytes(scene, None, &ConvertOptions::default()).unwrap();
    let mut tri =
        splatbridge_raytrace::scene_load::load_glb_bytes(&bytes, Path::new("street.glb")).unwrap();
    tri.to_capture_frame();
    MeshTracer::new(tri, BackendKind::Obvhs, BuildPreset::Medium).unwrap()
}

const SHADOWS: Shadows = Shadows {
    sun_direction: [0.5, -1.0, 0.3],
    strength: 0.6,
};

/// The ground point whose shadow ray passes through the car body's centre (local (0, −0.65,
/// 0), the middle of the body box) at pose `p`.
fn shadow_point(p: &Pose) -> DVec3 {
    let c = p.transform_point(Vec3::new(0.0, -0.65, 0.0)).as_dvec3();
    let sun = Vec3::from(SHADOWS.sun_direction).as_dvec3().normalize();
    c + sun * (-c.y / sun.y)
}

#[test]
fn inserted_car_darkens_the_ground_behind_it_in_mesh_mode() {
    let scene = scene();
    let tracer = exported(&scene);
    let car = &scene.objects[2];
    let q = shadow_point(&car.track.sample(2.0));
    for (t, shadowed) in [(2.0, true), (0.0, false)] {
        let (lo, hi) = mesh_bounds(&tracer, t);
        let sun = SunShadows::from_effect(&SHADOWS, lo, hi).unwrap();
        let frozen = tracer.at(t);
        let f = sun.factor(&frozen, q);
        if shadowed {
            // The body is ~0.95-opaque Gaussians two thirds on its surface: the shadow ray
            // crosses two walls, T < ½, so f < 1 − 0.6·½.
            assert!(f < 0.7, "t = {t}: factor {f} at {q}");
        } else {
            // Nothing lies between q and the sun at t = 0 (the facade at x = 6 is 7 m high; the
            // ray reaches it 13 m up): exactly unshadowed.
            assert_eq!(f, 1.0, "t = {t}: factor {f} at {q}");
        }
    }
    // The whole frame from the elevated camera: one shadow ray per surface pixel, shading
    // only ever darkens, by at most the strength.
    let cam = scene.cameras[2].resized(96, 72);
    let opts = RenderOptions::default();
    let (plain, _) = tracer.render(&cam, 2.0, &opts).unwrap();
    let (lo, hi) = mesh_bounds(&tracer, 2.0);
    let sun = SunShadows::from_effect(&SHADOWS, lo, hi).unwrap();
    let (sh, _, st) = render_mesh_shadowed(&tracer, &cam, 2.0, &opts, &sun).unwrap();
    let surface = plain.alpha.iter().filter(|&&a| a >= 0.5).count() as u64;
    assert_eq!(st.shadow_rays, surface);
    let mut darker = 0;
    for (a, b) in plain.rgb.iter().zip(&sh.rgb) {
        // f32 rounding of (rgb − bg)·f + bg with a black background: a few ulps.
        assert!(*b <= *a + 1e-6 && *b >= *a * 0.4 - 1e-6, "{a} → {b}");
        if *b < *a * 0.99 {
            darker += 1;
        }
    }
    assert!(darker > 0, "some pixels are in shadow");
}

#[test]
fn lidar_beams_through_the_inserted_car_return_on_it_in_both_modes() {
    let scene = scene();
    let t = 2.0;
    let pose = scene.objects[2].track.sample(t);
    // Body and cabin boxes of the street's cars (local frame), and their union's bounds.
    let parts = [
        (Vec3::new(-2.1, -1.0, -0.9), Vec3::new(2.1, -0.3, 0.9)),
        (Vec3::new(-1.2, -1.5, -0.8), Vec3::new(0.9, -1.0, 0.8)),
    ];
    let (lo, hi) = (Vec3::new(-2.1, -1.5, -0.9), Vec3::new(2.1, -0.3, 0.9));
    let l = Lidar {
        channels: 9,
        vertical_fov_deg: [-10.0, 10.0],
        rotation_hz: 10.0,
        azimuth_steps: 720,
        range: 30.0,
        mount: LidarMount::Pose {
            position: [-5.0, -0.8, -10.0],
            rotation: [1.0, 0.0, 0.0, 0.0],
        },
        hit_threshold: 0.5,
    };
    let sensor = LidarSensor::from_effect(&l, &scene.cameras).unwrap();
    let inv = pose.rotation.inverse();
    let to_local = |p: DVec3| (inv * (p.as_vec3() - pose.translation)).as_dvec3();
    let mesh = exported(&scene);
    let frozen = mesh.at(t);
    let gauss =
        GaussianTracer::new(scene.composite(t), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let tracers: [(&str, &dyn OpacityMarch); 2] = [("mesh", &frozen), ("gaussian", &gauss)];
    for (mode, tracer) in tracers {
        let s = scan(tracer, &sensor, t);
        let mut through = 0;
        for j in 0..sensor.azimuth_steps {
            let (_, a) = sensor.step(t, j);
            for ring in 0..sensor.elevations.len() {
                let d = sensor.direction(ring, a);
                // Beams through the body or cabin box shrunk by 0.3 (well inside the dense
                // surface layer of Gaussians).
                let o_l = to_local(sensor.origin);
                let d_l = (inv * d.as_vec3()).as_dvec3();
                // ray_box intersects the whole line: only beams going towards the car count.
                let core = parts.iter().any(|(a, b)| {
                    ray_box(
                        o_l,
                        d_l,
                        (*a + Vec3::splat(0.3)).as_dvec3(),
                        (*b - Vec3::splat(0.3)).as_dvec3(),
                    )
                    .is_some_and(|(t0, _)| t0 > 0.0)
                });
                if !core {
                    continue;
                }
                through += 1;
                let time = sensor.step(t, j).0;
                let p = s
                    .points
                    .iter()
                    .find(|p| p.time == time && p.ring as usize == ring)
                    .unwrap_or_else(|| panic!("{mode}: no return for a beam through the car"));
                // The return lies on the car: inside its box grown by 0.45 (the Gaussians'
                // 3σ reach, σ ≤ 0.11·e^{0.35·2} ≈ 0.15 for all but a few).
                let pl = to_local(p.position);
                let m = 0.45;
                assert!(
                    pl.cmpge((lo - Vec3::splat(m)).as_dvec3()).all()
                        && pl.cmple((hi + Vec3::splat(m)).as_dvec3()).all(),
                    "{mode}: return at local {pl}, world {}, range {}",
                    p.position,
                    p.range
                );
            }
        }
        assert!(through > 20, "{mode}: {through} beams through the car");
    }
}
