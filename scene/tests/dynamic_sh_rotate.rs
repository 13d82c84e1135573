//! SH rotation: rotating the coefficients with an object must equal evaluating the original
//! coefficients with the view direction expressed in the object's frame.

use glam::{DMat3, DQuat, DVec3, Quat, Vec3};
use splatbridge_scene::rng::Rng;
use splatbridge_scene::sh::{basis_f64, eval_color_f64};
use splatbridge_scene::sh_rotate::{rotate_sh, ShRotation};

fn random_unit_quat(rng: &mut Rng) -> Quat {
    loop {
        let q = Quat::from_xyzw(rng.normal(), rng.normal(), rng.normal(), rng.normal());
        if q.length() > 1e-3 {
            return q.normalize();
        }
    }
}

fn random_dir(rng: &mut Rng) -> DVec3 {
    loop {
        let d = DVec3::new(
            rng.normal() as f64,
            rng.normal() as f64,
            rng.normal() as f64,
        );
        if d.length() > 1e-3 {
            return d.normalize();
        }
    }
}

/// Raw SH sum in f64 (no +0.5 offset, no clamp), so the comparison is not masked by clamping.
fn eval_raw_f64(degree: u8, c: &[Vec3], d: DVec3) -> DVec3 {
    let b = basis_f64(degree, d);
    let k = (degree as usize + 1).pow(2);
    (0..k).map(|j| c[j].as_dvec3() * b[j]).sum()
}

#[test]
fn rotated_coefficients_match_object_frame_evaluation() {
    let mut rng = Rng::new(11);
    let mut worst = 0.0f64;
    for _case in 0..200 {
        let q = random_unit_quat(&mut rng);
        let r = DMat3::from_quat(q.as_dquat());
        for degree in 1..=3u8 {
            let k = (degree as usize + 1).pow(2);
            let local: Vec<Vec3> = (0..k)
                .map(|_| Vec3::new(rng.normal(), rng.normal(), rng.normal()))
                .collect();
            let mut world = local.clone();
            rotate_sh(degree, &mut world, q);
            assert_eq!(world[0], local[0], "the DC term never changes");
            for _ in 0..50 {
                let d = random_dir(&mut rng);
                let want = eval_raw_f64(degree, &local, r.transpose() * d);
                let got = eval_raw_f64(degree, &world, d);
                worst = worst.max((want - got).abs().max_element());
            }
        }
    }
    // Coefficients of size ~N(0,1); the f32 matrices carry ~6e-8 relative error per entry and a
    // band-3 sum has 7 terms of basis value ≤ ~0.75 per output: total error of order 1e-6.
    // 1e-5 allows 10× that; a wrong sign or transposed matrix gives errors of order 1.
    assert!(worst < 1e-5, "worst raw SH mismatch {worst}");
}

#[test]
fn rotated_colour_matches_for_every_degree_in_f64_reference() {
    // Same property through the clamped colour the rasterizer uses.
    let mut rng = Rng::new(5);
    let q = Quat::from_axis_angle(Vec3::new(1.0, -2.0, 0.5).normalize(), 2.3);
    let r = DMat3::from_quat(q.as_dquat());
    let local: Vec<Vec3> = (0..16)
        .map(|_| Vec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.3)
        .collect();
    let mut world = local.clone();
    rotate_sh(3, &mut world, q);
    for _ in 0..500 {
        let d = random_dir(&mut rng);
        let a = eval_color_f64(3, &local, r.transpose() * d);
        let b = eval_color_f64(3, &world, d);
        // See the tolerance argument above (coefficients are 0.3× smaller here).
        assert!((a - b).abs().max_element() < 1e-5, "{a} vs {b}");
    }
}

#[test]
fn band_matrices_are_orthogonal_and_compose() {
    // The 3DGS basis is orthonormal, so each band's rotation is an orthogonal matrix, and
    // rotating by q1 then q2 equals rotating by q2·q1.
    let mut rng = Rng::new(3);
    for _ in 0..50 {
        let q1 = random_unit_quat(&mut rng).as_dquat().normalize();
        let q2 = random_unit_quat(&mut rng).as_dquat().normalize();
        let m1 = ShRotation::bands_f64(&DMat3::from_quat(q1));
        let m2 = ShRotation::bands_f64(&DMat3::from_quat(q2));
        let m12 = ShRotation::bands_f64(&DMat3::from_quat(q2 * q1));
        for l in 0..3 {
            let n = 2 * l + 3;
            for i in 0..n {
                for j in 0..n {
                    let mmt: f64 = (0..n).map(|k| m1[l][i][k] * m1[l][j][k]).sum();
                    let want = if i == j { 1.0 } else { 0.0 };
                    // The basis constants are the reference's f32 values (relative error up to
                    // ~6e-8), so the basis is orthonormal, and D orthogonal, only to ~1e-7.
                    assert!(
                        (mmt - want).abs() < 1e-6,
                        "band {} not orthogonal: {mmt}",
                        l + 1
                    );
                    let comp: f64 = (0..n).map(|k| m2[l][i][k] * m1[l][k][j]).sum();
                    // Composition is exact for any basis of the band: only f64 fit round-off.
                    assert!(
                        (comp - m12[l][i][j]).abs() < 1e-10,
                        "band {} does not compose",
                        l + 1
                    );
                }
            }
        }
    }
}

#[test]
fn degree_one_rotates_like_a_vector_in_the_reference_sign_convention() {
    // Band 1 of the reference is (−C1·y, C1·z, −C1·x): coefficients (a, b, c) are the vector
    // v = (−c, −a, b)·C1 dotted with d. A rotation maps v to R·v.
    let q = DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2);
    let mut c = vec![Vec3::ZERO, Vec3::splat(1.0), Vec3::ZERO, Vec3::ZERO];
    // v = (0, −1, 0)·C1; rotated 90° about z: (1, 0, 0)·C1 → coefficients a = 0, b = 0, c = −1.
    rotate_sh(1, &mut c, q.as_quat());
    // f32 matrices: 1e-6 is ~10 ulps of 1.
    assert!((c[1] - Vec3::ZERO).abs().max_element() < 1e-6, "{:?}", c);
    assert!((c[2] - Vec3::ZERO).abs().max_element() < 1e-6, "{:?}", c);
    assert!(
        (c[3] - Vec3::splat(-1.0)).abs().max_element() < 1e-6,
        "{:?}",
        c
    );
}

#[test]
fn identity_and_lower_degrees_leave_coefficients_alone() {
    let mut rng = Rng::new(9);
    let c: Vec<Vec3> = (0..16)
        .map(|_| Vec3::new(rng.normal(), rng.normal(), rng.normal()))
        .collect();
    let mut a = c.clone();
    rotate_sh(3, &mut a, Quat::IDENTITY);
    assert_eq!(a, c, "identity is bit-exact");
    // Degree 1: bands 2 and 3 of the slice are not touched.
    let mut b = c.clone();
    rotate_sh(1, &mut b, Quat::from_rotation_y(1.0));
    assert_eq!(&b[4..], &c[4..]);
    assert_ne!(&b[1..4], &c[1..4]);
    // Degree 0 never changes.
    let mut d = c[..1].to_vec();
    rotate_sh(0, &mut d, Quat::from_rotation_y(1.0));
    assert_eq!(d[0], c[0]);
}
