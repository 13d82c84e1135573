//! Pose tracks and the world-space composite: slerp properties, hand-computed poses, extremes.

use glam::{DMat3, Quat, Vec3};
use proptest::prelude::*;
use splatbridge_scene::dynamic::{
    slerp_shortest, DynamicScene, Pose, PoseKey, SceneObject, TimeRange, Track,
};
use splatbridge_scene::sh::eval_color_f64;
use splatbridge_scene::GaussianCloud;

/// Angle in radians between two rotations (sign of the quaternion ignored). From the chord
/// |a − b| = 2 sin(φ/2) between the unit quaternions (rotation angle 2φ), not from
/// `acos(a·b)`: acos is ill-conditioned near 1, where one f32 rounding of the dot product
/// (≈1e-7) already reads as 2·√(2e-7) ≈ 1e-3 rad.
fn angle_between(a: Quat, b: Quat) -> f64 {
    let (a, b) = (a.normalize().as_dquat(), b.normalize().as_dquat());
    let b = if a.dot(b) < 0.0 { -b } else { b };
    4.0 * ((a - b).length() / 2.0).min(1.0).asin()
}

fn quat_strategy() -> impl Strategy<Value = Quat> {
    (
        -1.0f32..1.0,
        -1.0f32..1.0,
        -1.0f32..1.0,
        -1.0f32..1.0,
        0.1f32..10.0,
    )
        .prop_filter("non-degenerate", |(w, x, y, z, _)| {
            (w * w + x * x + y * y + z * z) > 0.01
        })
        .prop_map(|(w, x, y, z, s)| Quat::from_xyzw(x * s, y * s, z * s, w * s))
}

fn vec_strategy() -> impl Strategy<Value = Vec3> {
    (-100.0f32..100.0, -100.0f32..100.0, -100.0f32..100.0).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn two_key_track(t0: f64, t1: f64, a: Vec3, qa: Quat, b: Vec3, qb: Quat) -> Track {
    Track::new(vec![PoseKey::new(t0, a, qa), PoseKey::new(t1, b, qb)])
}

proptest! {
    #[test]
    fn slerp_is_unit_and_hits_endpoints(a in quat_strategy(), b in quat_strategy(), s in 0.0f64..=1.0) {
        let q = slerp_shortest(a, b, s);
        // f32 rounding of a unit f64 quaternion: |q| within a few ulps of 1.
        prop_assert!((q.length() - 1.0).abs() < 1e-6);
        prop_assert!(angle_between(slerp_shortest(a, b, 0.0), a) < 1e-3);
        prop_assert!(angle_between(slerp_shortest(a, b, 1.0), b) < 1e-3);
    }

    #[test]
    fn slerp_ignores_the_sign_of_either_key(a in quat_strategy(), b in quat_strategy(), s in 0.0f64..=1.0) {
        let q = slerp_shortest(a, b, s);
        let q_neg = slerp_shortest(a, -b, s);
        let q_neg2 = slerp_shortest(-a, b, s);
        // Same rotation (up to sign); f32 output rounding gives ~1e-7 rad, 1e-3 is far below any
        // real mismatch (which would be of the order of the key angle).
        prop_assert!(angle_between(q, q_neg) < 1e-3);
        prop_assert!(angle_between(q, q_neg2) < 1e-3);
    }

    #[test]
    fn slerp_takes_the_short_arc_at_constant_speed(a in quat_strategy(), b in quat_strategy(), s in 0.0f64..=1.0) {
        let total = angle_between(a, b);
        let q = slerp_shortest(a, b, s);
        // The rotation angle grows linearly along the shortest arc (≤ π). The f32 output limits
        // angle resolution to ~1e-3 rad near small angles (acos of a number near 1).
        prop_assert!(total <= std::f64::consts::PI + 1e-6);
        prop_assert!((angle_between(a, q) - s * total).abs() < 2e-3, "{} vs {}", angle_between(a, q), s * total);
    }

    #[test]
    fn track_sampling_is_continuous_and_held_outside(
        a in vec_strategy(), b in vec_strategy(), qa in quat_strategy(), qb in quat_strategy(),
        t0 in -10.0f64..10.0, dt in 0.01f64..10.0, u in 0.0f64..1.0,
    ) {
        let t1 = t0 + dt;
        let tr = two_key_track(t0, t1, a, qa, b, qb);
        let t = t0 + u * dt;
        let p = tr.sample(t);
        let p2 = tr.sample(t + dt * 1e-6);
        prop_assert!((p.rotation.length() - 1.0).abs() < 1e-6);
        // A step of 1e-6 of the span moves at most 1e-6·|b−a| (≤ 3.5e-4 here) plus f32 rounding
        // of coordinates up to 100 (~1e-5), and turns at most 1e-6·π plus output rounding.
        prop_assert!((p.translation - p2.translation).length() < 1e-3);
        prop_assert!(angle_between(p.rotation, p2.rotation) < 2e-3);
        // Translation is linear in time.
        let want = a.as_dvec3() + (b - a).as_dvec3() * u;
        prop_assert!((p.translation.as_dvec3() - want).length() < 1e-4 * (1.0 + want.length()));
        // Held constant outside the keyed range.
        prop_assert_eq!(tr.sample(t0 - 5.0), tr.sample(t0));
        prop_assert_eq!(tr.sample(t1 + 5.0), tr.sample(t1));
        prop_assert_eq!(tr.sample(1e5), tr.sample(t1));
    }

    #[test]
    fn sampling_at_a_key_returns_the_key(qs in prop::collection::vec(quat_strategy(), 2..6), ts in prop::collection::vec(0.01f64..2.0, 2..6)) {
        let n = qs.len().min(ts.len());
        let mut t = 0.0;
        let keys: Vec<PoseKey> = (0..n).map(|i| {
            t += ts[i];
            PoseKey::new(t, Vec3::splat(i as f32), qs[i])
        }).collect();
        let tr = Track::new(keys.clone());
        for k in &keys {
            prop_assert_eq!(tr.sample(k.t), k.pose);
        }
    }
}

#[test]
fn antipodal_and_identical_keys_stay_finite() {
    let q = Quat::from_rotation_y(0.7);
    for (qa, qb) in [
        (q, -q),
        (q, q),
        (q, Quat::from_rotation_y(0.7 + 1e-7)),
        (Quat::IDENTITY, Quat::from_xyzw(0.0, 1.0, 0.0, 0.0)),
    ] {
        let tr = two_key_track(0.0, 1.0, Vec3::ZERO, qa, Vec3::ONE, qb);
        for &t in &[
            0.0,
            1e-12,
            0.25,
            0.5,
            0.999_999,
            1.0,
            1e5,
            -1e5,
            f64::NAN,
            f64::INFINITY,
        ] {
            let p = tr.sample(t);
            assert!(
                p.rotation.is_finite() && p.translation.is_finite(),
                "t = {t}: {p:?}"
            );
            assert!((p.rotation.length() - 1.0).abs() < 1e-6);
        }
    }
    // q and −q are the same rotation: the interpolated rotation never moves.
    let tr = two_key_track(0.0, 1.0, Vec3::ZERO, q, Vec3::ZERO, -q);
    // f32 output: ~1e-7 rad rounding; 1e-3 because acos near 1 amplifies it.
    assert!(angle_between(tr.sample(0.5).rotation, q) < 1e-3);
    // 180° apart (w = 1 vs x = 1... dot 0): halfway is 90°.
    let tr = two_key_track(
        0.0,
        1.0,
        Vec3::ZERO,
        Quat::IDENTITY,
        Vec3::ZERO,
        Quat::from_xyzw(1.0, 0.0, 0.0, 0.0),
    );
    assert!(
        (angle_between(tr.sample(0.5).rotation, Quat::IDENTITY) - std::f64::consts::FRAC_PI_2)
            .abs()
            < 1e-3
    );
}

#[test]
fn empty_and_single_key_tracks() {
    assert_eq!(Track::default().sample(3.0), Pose::IDENTITY);
    let p = Pose::new(Vec3::new(1.0, 2.0, 3.0), Quat::from_rotation_x(0.3));
    let tr = Track::constant(p);
    assert_eq!(tr.sample(-1.0), p);
    assert_eq!(tr.sample(1e5), p);
    assert!(tr.is_constant());
    assert!(Track::default().validate().is_err());
}

#[test]
fn validate_names_the_bad_key() {
    let k = |t| PoseKey::new(t, Vec3::ZERO, Quat::IDENTITY);
    let err = Track::new(vec![k(0.0), k(1.0), k(1.0)])
        .validate()
        .unwrap_err();
    assert!(err.contains("track[2].t"), "{err}");
    let mut bad = k(2.0);
    bad.pose.rotation = Quat::from_xyzw(0.0, 0.0, 0.0, 0.0);
    let err = Track::new(vec![k(0.0), bad]).validate().unwrap_err();
    assert!(
        err.contains("track[1].rotation") && err.contains("zero"),
        "{err}"
    );
    let mut bad = k(2.0);
    bad.pose.translation.x = f32::NAN;
    let err = Track::new(vec![k(0.0), bad]).validate().unwrap_err();
    assert!(err.contains("track[1].translation"), "{err}");
}

/// One object with three Gaussians, SH degree 3, and a track rotating 90° about y while moving
/// from the origin to (2, 0, 0) over two seconds.
fn one_object_scene() -> DynamicScene {
    let mut stat = GaussianCloud::new(3);
    stat.push_activated(
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::splat(0.1),
        Quat::IDENTITY,
        0.5,
        Vec3::new(0.2, 0.3, 0.4),
    );
    let mut obj = GaussianCloud::new(3);
    let sh: Vec<Vec3> = (0..16)
        .map(|j| Vec3::new(0.1 * j as f32, -0.05 * j as f32, 0.02))
        .collect();
    obj.push(
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(-1.0, -2.0, -3.0),
        Quat::IDENTITY,
        1.5,
        &sh,
    );
    obj.push(
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::ZERO,
        Quat::from_xyzw(0.0, 0.0, 0.0, 2.0),
        -0.5,
        &sh,
    );
    obj.push(
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::ZERO,
        Quat::from_rotation_z(0.4),
        f32::INFINITY,
        &sh,
    );
    let track = two_key_track(
        0.0,
        2.0,
        Vec3::ZERO,
        Quat::IDENTITY,
        Vec3::new(2.0, 0.0, 0.0),
        Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
    );
    DynamicScene {
        time: TimeRange {
            start: 0.0,
            end: 2.0,
            fps: 10.0,
        },
        static_gaussians: stat,
        objects: vec![SceneObject {
            name: "box".into(),
            gaussians: obj,
            track,
        }],
        frames: Vec::new(),
        cameras: vec![],
        effects: Default::default(),
        four_d: None,
    }
}

#[test]
fn composite_matches_hand_computed_pose() {
    let scene = one_object_scene();
    scene.validate().unwrap();
    let c = scene.composite(1.0);
    c.check_shape().unwrap();
    assert_eq!(c.len(), 4);
    assert_eq!(c.object_ids.as_deref(), Some(&[0, 1, 1, 1][..]));
    // Static Gaussian untouched (bit-exact).
    assert_eq!(c.means[0], scene.static_gaussians.means[0]);
    assert_eq!(c.sh_of(0), scene.static_gaussians.sh_of(0));
    // At t = 1: 45° about y, translation (1, 0, 0). Rotation about +y by θ maps
    // (1,0,0) → (cos θ, 0, −sin θ) and (0,0,1) → (sin θ, 0, cos θ).
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let want = [
        Vec3::new(1.0 + h, 0.0, -h),
        Vec3::new(1.0 + h, 0.0, h),
        Vec3::new(1.0, -1.0, 0.0),
    ];
    for (i, w) in want.iter().enumerate() {
        // f32 arithmetic on values ≤ 2: 1e-6 is ~10 ulps.
        assert!(
            (c.means[i + 1] - *w).length() < 1e-6,
            "mean {}: {} vs {w}",
            i + 1,
            c.means[i + 1]
        );
    }
    let q45 = Quat::from_rotation_y(std::f32::consts::FRAC_PI_4);
    let obj = &scene.objects[0].gaussians;
    for i in 0..3 {
        let want = q45 * obj.unit_rotation(i);
        assert!(angle_between(c.rotations[i + 1], want) < 1e-3);
        assert!(
            (c.rotations[i + 1].length() - 1.0).abs() < 1e-6,
            "composed rotation stored unit"
        );
        assert_eq!(c.log_scales[i + 1], obj.log_scales[i]);
        assert_eq!(c.opacity_logits[i + 1], obj.opacity_logits[i]);
    }
    // View-dependent colour follows the object: world direction d shows what the object frame
    // showed in direction Rᵀd.
    let r = DMat3::from_quat(q45.as_dquat());
    for d in [
        glam::DVec3::X,
        glam::DVec3::new(0.3, -0.4, 0.866).normalize(),
        glam::DVec3::NEG_Z,
    ] {
        let a = eval_color_f64(3, c.sh_of(1), d);
        let b = eval_color_f64(3, obj.sh_of(0), r.transpose() * d);
        // See dynamic_sh_rotate.rs for the tolerance argument.
        assert!((a - b).abs().max_element() < 1e-5, "{a} vs {b}");
    }
}

#[test]
fn composite_at_the_ends_and_beyond() {
    let scene = one_object_scene();
    let obj = &scene.objects[0].gaussians;
    let c0 = scene.composite(0.0);
    assert_eq!(
        c0.means[1..],
        obj.means[..],
        "identity pose at t = 0 leaves means exact"
    );
    assert_eq!(c0.sh_of(1), obj.sh_of(0), "identity pose leaves SH exact");
    let end = scene.composite(2.0);
    let far = scene.composite(1e5);
    assert_eq!(end, far, "pose held after the last key");
    // (1,0,0) rotated 90° about y is (0,0,−1), plus (2,0,0).
    assert!((end.means[1] - Vec3::new(2.0, 0.0, -1.0)).length() < 1e-6);
    let before = scene.composite(-1e5);
    assert_eq!(before, c0);
    for c in [&end, &far, &before] {
        assert!(c.means.iter().all(|m| m.is_finite()) && c.sh.iter().all(|s| s.is_finite()));
    }
}

#[test]
fn composite_mixes_sh_degrees_and_tags_objects() {
    let mut scene = one_object_scene();
    let mut low = GaussianCloud::new(0);
    low.push_activated(Vec3::ZERO, Vec3::ONE, Quat::IDENTITY, 0.5, Vec3::ONE);
    scene.objects.push(SceneObject {
        name: "low".into(),
        gaussians: low,
        track: Track::constant(Pose::new(Vec3::X, Quat::from_rotation_z(1.0))),
    });
    let c = scene.composite(0.5);
    assert_eq!(c.sh_degree, 3);
    assert_eq!(c.object_ids.as_deref(), Some(&[0, 1, 1, 1, 2][..]));
    assert_eq!(
        c.sh_of(4)[1..],
        [Vec3::ZERO; 15],
        "degree-0 object zero-filled"
    );
    assert_eq!(c.means[4], Vec3::X);
}

#[test]
fn frame_times_cover_the_range_inclusive() {
    let scene = one_object_scene();
    let t = scene.frame_times();
    assert_eq!(t.len(), 21);
    assert_eq!(t[0], 0.0);
    assert!((t[20] - 2.0).abs() < 1e-12);
    let s = DynamicScene::from_static(GaussianCloud::new(0));
    assert_eq!(s.frame_times(), vec![0.0]);
    let r = TimeRange {
        start: 0.0,
        end: 4.0,
        fps: 10.0,
    };
    assert_eq!(
        r.frame_count(),
        41,
        "0.1·40 rounding must not drop the last frame"
    );
    assert!(TimeRange {
        start: 0.0,
        end: 1.0,
        fps: 0.0
    }
    .validate()
    .is_err());
    assert!(TimeRange {
        start: 1.0,
        end: 0.0,
        fps: 1.0
    }
    .validate()
    .is_err());
    assert!(TimeRange {
        start: 0.0,
        end: 1e9,
        fps: 1e9
    }
    .validate()
    .is_err());
}

#[test]
fn composite_far_from_origin_and_far_in_time_is_finite() {
    let mut scene = one_object_scene();
    scene.objects[0].track = Track::new(vec![
        PoseKey::new(0.0, Vec3::splat(1e5), Quat::from_rotation_x(3.0)),
        PoseKey::new(1e-9, Vec3::splat(-1e5), -Quat::from_rotation_x(3.0)),
        PoseKey::new(1e5, Vec3::ZERO, Quat::from_xyzw(1e-20, 0.0, 0.0, 0.0)),
    ]);
    for t in [0.0, 5e-10, 1.0, 5e4, 1e5, 1e6] {
        let c = scene.composite(t);
        assert!(c.means.iter().all(|m| m.is_finite()), "t = {t}");
        assert!(
            c.rotations
                .iter()
                .all(|q| q.is_finite() && (q.length() - 1.0).abs() < 1e-5),
            "t = {t}"
        );
        assert!(c.sh.iter().all(|s| s.is_finite()), "t = {t}");
    }
}

#[test]
fn composite_into_reuses_a_cloud_and_matches_composite() {
    let scene = one_object_scene();
    // Start from an unrelated cloud of another degree with ids: everything must be replaced.
    let mut out = GaussianCloud::new(1);
    out.object_ids = Some(vec![]);
    out.push_activated(Vec3::ONE, Vec3::ONE, Quat::IDENTITY, 0.5, Vec3::ONE);
    for t in [0.3, 1.7, 0.3] {
        scene.composite_into(t, &mut out);
        assert_eq!(out, scene.composite(t));
    }
}

#[test]
fn into_composite_equals_composite() {
    // With objects: the copying path. Without: the static cloud handed over, which must be
    // the same cloud (values, degree and object ids) as the copy.
    let scene = one_object_scene();
    assert_eq!(scene.clone().into_composite(0.7), scene.composite(0.7));
    let mut stat = scene.static_gaussians.clone();
    stat.object_ids = Some(vec![5]);
    let only = DynamicScene::from_static(stat);
    let want = only.composite(0.0);
    assert_eq!(want.object_ids, Some(vec![0]));
    assert_eq!(only.into_composite(0.0), want);
}
