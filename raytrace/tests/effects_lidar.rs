//! The spinning LiDAR against analytic geometry: ranges to a ground plane and to the inside of
//! a box (mode mesh), ranges to a plane of flat Gaussians (mode gaussian) within a derived
//! tolerance, the range cut, timestamps, determinism and the PLY output.

use glam::{DVec3, Quat, Vec3, Vec4};
use splatbridge_raytrace::lidar::{read_ply, scan, write_ply, LidarSensor};
use splatbridge_raytrace::model::{Material, Mesh, TriScene};
use splatbridge_raytrace::{BackendKind, BuildPreset, GaussianTracer, MeshTracer};
use splatbridge_scene::effects::{Lidar, LidarMount};
use splatbridge_scene::{Camera, GaussianCloud};

fn quad(m: &mut Mesh, c: [Vec3; 4]) {
    let base = m.positions.len() as u32;
    for p in c {
        m.positions.push(p);
        m.colors.push(Vec4::ONE);
    }
    for t in [[0, 1, 2], [0, 2, 3]] {
        m.tris.push(t.map(|i| base + i));
        m.tri_material.push(0);
        m.tri_gaussian.push(m.tri_gaussian.len() as u32 / 2);
    }
}

fn mesh_tracer(m: Mesh) -> MeshTracer {
    MeshTracer::new(
        TriScene::single(m, vec![Material::default()], Vec::new()),
        BackendKind::Obvhs,
        BuildPreset::Medium,
    )
    .unwrap()
}

fn lidar(channels: u32, fov: [f32; 2], steps: u32, range: f32, pos: [f32; 3]) -> Lidar {
    Lidar {
        channels,
        vertical_fov_deg: fov,
        rotation_hz: 10.0,
        azimuth_steps: steps,
        range,
        mount: LidarMount::Pose {
            position: pos,
            rotation: [1.0, 0.0, 0.0, 0.0],
        },
        hit_threshold: 0.5,
    }
}

fn ground_mesh(half: f32) -> Mesh {
    let mut m = Mesh {
        has_gaussian_ids: true,
        ..Mesh::default()
    };
    quad(
        &mut m,
        [
            Vec3::new(-half, 0.0, -half),
            Vec3::new(half, 0.0, -half),
            Vec3::new(half, 0.0, half),
            Vec3::new(-half, 0.0, half),
        ],
    );
    m
}

#[test]
fn ranges_to_a_ground_plane_match_the_analytic_distance_and_stop_at_the_range() {
    let tracer = mesh_tracer(ground_mesh(100.0));
    let frozen = tracer.at(0.0);
    // Sensor 2 above the ground (y-down: y = −2). Elevations −30, −25, …, 10: a beam at
    // e < 0 meets the ground at 2/sin(−e); e ≥ 0 never does.
    for range in [40.0f32, 15.0] {
        let l = lidar(9, [-30.0, 10.0], 90, range, [0.0, -2.0, 0.0]);
        let sensor = LidarSensor::from_effect(&l, &[]).unwrap();
        let s = scan(&frozen, &sensor, 0.25);
        assert_eq!(s.rays, 9 * 90);
        let mut expected_points = 0;
        for e in sensor.elevations.iter() {
            let d = 2.0 / (-e).sin();
            if *e < 0.0 && d <= range as f64 {
                expected_points += 90;
            }
        }
        assert_eq!(s.points.len(), expected_points, "range {range}");
        for p in &s.points {
            let e = sensor.elevations[p.ring as usize];
            let want = 2.0 / (-e).sin();
            // Hit distances come from the f64 plane of the hit group, rounded to f32: relative
            // 1e-7 of ≤ 23 units, far inside 1e-5.
            assert!((p.range - want).abs() < 1e-5, "{} vs {want}", p.range);
            assert!(p.range <= range as f64);
            assert!(p.position.y.abs() < 1e-5, "on the ground: {}", p.position);
            // Intensity: opaque (α = 1) × |cos| between the beam and the ground normal = sin(−e).
            assert!((p.intensity as f64 - (-e).sin()).abs() < 1e-5);
        }
    }
}

/// Ray–box exit distance from an inside point, f64 slab test.
fn exit_distance(o: DVec3, d: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    (0..3)
        .filter(|&a| d[a] != 0.0)
        .map(|a| {
            if d[a] > 0.0 {
                (hi[a] - o[a]) / d[a]
            } else {
                (lo[a] - o[a]) / d[a]
            }
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn ranges_inside_a_box_match_the_slab_exit_distance() {
    let (lo, hi) = (Vec3::new(-5.0, -4.0, -6.0), Vec3::new(5.0, 1.0, 6.0));
    let c = |x: bool, y: bool, z: bool| {
        Vec3::new(
            if x { hi.x } else { lo.x },
            if y { hi.y } else { lo.y },
            if z { hi.z } else { lo.z },
        )
    };
    let mut m = Mesh {
        has_gaussian_ids: true,
        ..Mesh::default()
    };
    for axis in 0..3 {
        for side in [false, true] {
            let corner = |u: bool, v: bool| match axis {
                0 => c(side, u, v),
                1 => c(u, side, v),
                _ => c(u, v, side),
            };
            quad(
                &mut m,
                [
                    corner(false, false),
                    corner(true, false),
                    corner(true, true),
                    corner(false, true),
                ],
            );
        }
    }
    let tracer = mesh_tracer(m);
    let frozen = tracer.at(0.0);
    let l = lidar(16, [-60.0, 60.0], 120, 100.0, [0.5, -1.0, 0.3]);
    let sensor = LidarSensor::from_effect(&l, &[]).unwrap();
    let s = scan(&frozen, &sensor, 0.0);
    assert_eq!(s.points.len(), 16 * 120, "every beam hits a wall");
    for p in &s.points {
        let d = (p.position - sensor.origin).normalize();
        let want = exit_distance(sensor.origin, d, lo.as_dvec3(), hi.as_dvec3());
        // f32 plane distances of ≤ 10 units: 1e-5 as above.
        assert!((p.range - want).abs() < 1e-5, "{} vs {want}", p.range);
    }
}

#[test]
fn ranges_to_a_plane_of_gaussians_are_within_the_derived_tolerance() {
    let (half, spacing, sn) = (12.0f32, 0.15f32, 1e-4f32);
    let n = (2.0 * half / spacing).round() as i32;
    let mut cloud = GaussianCloud::with_capacity(0, (n * n) as usize);
    for a in 0..n {
        for b in 0..n {
            cloud.push_activated(
                Vec3::new(
                    -half + (a as f32 + 0.5) * spacing,
                    0.0,
                    -half + (b as f32 + 0.5) * spacing,
                ),
                Vec3::new(spacing, sn, spacing),
                Quat::IDENTITY,
                0.99,
                Vec3::splat(0.5),
            );
        }
    }
    let tracer = GaussianTracer::new(cloud, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let l = lidar(5, [-30.0, -10.0], 72, 15.0, [0.3, -2.0, -0.2]);
    let sensor = LidarSensor::from_effect(&l, &[]).unwrap();
    let s = scan(&tracer, &sensor, 0.0);
    // Every beam meets the plane within 2/sin(10°) ≈ 11.5 < 12 (the tiled half-size) and 15.
    assert_eq!(s.points.len(), 5 * 72);
    let r = (2.0 * (255.0f64 * 0.99).ln()).sqrt();
    for p in &s.points {
        let e = sensor.elevations[p.ring as usize];
        let dn = (-e).sin();
        let want = 2.0 / dn;
        // A disc's point of maximum response t* lies within δ of the plane crossing t_p:
        // f(t) = f* + A(t − t*)² with A ≥ d_n²/σ_n², and √f(t_p) ≤ r + δ/σ_u (the in-plane part
        // grows at most 1/σ_u per unit), so δ ≤ r / (d_n/σ_n − 1/σ_u); plus 1e-4 for f32.
        let tol = r / (dn / sn as f64 - 1.0 / spacing as f64) + 1e-4;
        assert!(
            (p.range - want).abs() < tol,
            "ring {} range {} vs {want} (tol {tol})",
            p.ring,
            p.range
        );
    }
}

#[test]
fn scans_are_deterministic_timestamped_and_round_trip_through_ply() {
    let tracer = mesh_tracer(ground_mesh(50.0));
    let frozen = tracer.at(0.0);
    let l = lidar(8, [-25.0, -5.0], 64, 30.0, [0.0, -1.8, 0.0]);
    let sensor = LidarSensor::from_effect(&l, &[]).unwrap();
    let a = scan(&frozen, &sensor, 1.0);
    let b = scan(&frozen, &sensor, 1.0);
    assert_eq!(a.points, b.points);
    // One revolution per frame: step j fires at t + j/(10 Hz · 64).
    let first = a.points.first().unwrap();
    let last = a.points.last().unwrap();
    assert_eq!(first.time, 1.0);
    assert!((last.time - (1.0 + 63.0 / 640.0)).abs() < 1e-12);
    assert!(a.points.windows(2).all(|w| w[1].time >= w[0].time));
    // At t = 1 s a 10 Hz head has made 10 whole turns: the sweep starts at azimuth 0 (+z).
    let d0 = (first.position - sensor.origin).normalize();
    assert!(d0.x.abs() < 1e-6 && d0.z > 0.0, "{d0}");

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lidar_0000.ply");
    write_ply(&path, &a).unwrap();
    let back = read_ply(&std::fs::read(&path).unwrap()).unwrap();
    assert_eq!(back.len(), a.points.len());
    for (p, q) in a.points.iter().zip(&back) {
        assert_eq!(p.position.as_vec3(), q.position.as_vec3());
        assert_eq!((p.intensity, p.time, p.ring), (q.intensity, q.time, q.ring));
    }
}

#[test]
fn camera_mount_and_bad_parameters() {
    let cam = Camera::look_at(
        DVec3::new(1.0, -2.0, 3.0),
        DVec3::new(1.0, -2.0, 10.0),
        DVec3::NEG_Y,
        50.0,
        64,
        48,
    )
    .unwrap();
    let mut l = lidar(1, [0.0, 0.0], 4, 10.0, [0.0; 3]);
    l.mount = LidarMount::Camera { index: 0 };
    let s = LidarSensor::from_effect(&l, std::slice::from_ref(&cam)).unwrap();
    assert_eq!(s.origin, cam.centre);
    // Azimuth 0 at elevation 0 is the camera's forward axis.
    assert!((s.direction(0, 0.0) - DVec3::Z).length() < 1e-12);
    let err = LidarSensor::from_effect(&l, &[]).unwrap_err().to_string();
    assert!(err.contains("camera.index"), "{err}");
    let mut bad = lidar(0, [0.0, 0.0], 4, 10.0, [0.0; 3]);
    assert!(LidarSensor::from_effect(&bad, &[]).is_err());
    bad.channels = 4;
    bad.range = f32::NAN;
    assert!(LidarSensor::from_effect(&bad, &[]).is_err());
}

#[test]
fn per_frame_scans_of_a_scene_write_one_ply_per_frame_deterministically() {
    use splatbridge_raytrace::lidar::scan_scene_gaussian;
    use splatbridge_scene::dynamic::{DynamicScene, TimeRange};
    let mut cloud = GaussianCloud::with_capacity(0, 6400);
    for a in 0..80 {
        for b in 0..80 {
            cloud.push_activated(
                Vec3::new(-6.0 + a as f32 * 0.15, 0.0, -6.0 + b as f32 * 0.15),
                Vec3::new(0.15, 1e-3, 0.15),
                Quat::IDENTITY,
                0.99,
                Vec3::splat(0.5),
            );
        }
    }
    let mut scene = DynamicScene::from_static(cloud);
    scene.time = TimeRange {
        start: 0.0,
        end: 0.2,
        fps: 10.0,
    };
    let dir = tempfile::tempdir().unwrap();
    assert!(
        scan_scene_gaussian(&scene, dir.path(), BackendKind::Obvhs, BuildPreset::Medium)
            .unwrap()
            .is_none(),
        "no LiDAR declared: nothing cast, nothing written"
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    let l = lidar(4, [-30.0, -15.0], 32, 10.0, [0.0, -1.5, 0.0]);
    scene
        .effects
        .insert("lidar".into(), serde_json::to_value(&l).unwrap());
    let run = scan_scene_gaussian(&scene, dir.path(), BackendKind::Obvhs, BuildPreset::Medium)
        .unwrap()
        .unwrap();
    assert_eq!(run.files.len(), 3);
    assert_eq!(run.rays, 3 * 4 * 32);
    // Every beam meets the ground within 1.5/sin(15°) ≈ 5.8 < 6 (the tiled half-size) and 10.
    assert_eq!(run.points, run.rays);
    let first: Vec<Vec<u8>> = run
        .files
        .iter()
        .map(|f| std::fs::read(f).unwrap())
        .collect();
    let again = scan_scene_gaussian(&scene, dir.path(), BackendKind::Obvhs, BuildPreset::Medium)
        .unwrap()
        .unwrap();
    for (f, bytes) in again.files.iter().zip(&first) {
        assert_eq!(&std::fs::read(f).unwrap(), bytes, "{}", f.display());
    }
    // Frame k's points carry timestamps from its own revolution.
    let pts = read_ply(&first[2]).unwrap();
    assert!(pts
        .iter()
        .all(|p| p.time >= 0.2 - 1e-12 && p.time < 0.2 + 0.1));
}
