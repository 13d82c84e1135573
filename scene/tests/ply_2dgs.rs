//! 2DGS surfel files written and read back, and 3D Gaussians flattened into surfels.

use glam::{Mat3, Quat, Vec3};
use splatbridge_scene::ply::{
    flatten_to_surfels, read_ply, write_ply_2dgs, GaussianKind, ReadOptions, SURFEL_THICKNESS,
};
use splatbridge_scene::rng::Rng;
use splatbridge_scene::GaussianCloud;

fn random_cloud(n: usize, degree: u8, seed: u64) -> GaussianCloud {
    let mut rng = Rng::new(seed);
    let mut c = GaussianCloud::new(degree);
    for _ in 0..n {
        let sh: Vec<Vec3> = (0..c.coeffs())
            .map(|_| Vec3::new(rng.normal(), rng.normal(), rng.normal()))
            .collect();
        c.push(
            Vec3::new(rng.normal(), rng.normal(), rng.normal()),
            Vec3::new(
                rng.range(-6.0, 0.0),
                rng.range(-6.0, 0.0),
                rng.range(-6.0, 0.0),
            ),
            Quat::from_xyzw(rng.normal(), rng.normal(), rng.normal(), rng.normal()),
            rng.range(-5.0, 5.0),
            &sh,
        );
    }
    c
}

#[test]
fn a_2dgs_ply_survives_write_and_read() {
    let tmp = tempfile::tempdir().unwrap();
    for degree in [0u8, 3] {
        let c = flatten_to_surfels(&random_cloud(50, degree, degree as u64 + 1));
        let p = tmp.path().join(format!("s{degree}.ply"));
        write_ply_2dgs(&p, &c).unwrap();
        let head = std::fs::read(&p).unwrap();
        // The header alone (degree 3 lists 45 f_rest properties before the scales).
        let end = head
            .windows(10)
            .position(|w| w == b"end_header")
            .expect("a PLY header");
        let head = String::from_utf8_lossy(&head[..end]);
        assert!(
            head.contains("property float scale_1\nproperty float rot_0"),
            "{head}"
        );
        assert!(!head.contains("scale_2"));
        let (r, report) = read_ply(&p, &ReadOptions::default()).unwrap();
        assert_eq!(report.kind, GaussianKind::Surfels2D);
        // Everything stored comes back bit for bit, the derived third log-scale included
        // (flatten_to_surfels sets it as the reader derives it).
        assert_eq!(r, c);
        // And a second round trip writes the same bytes.
        let p2 = tmp.path().join(format!("t{degree}.ply"));
        write_ply_2dgs(&p2, &r).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(&p2).unwrap());
    }
}

#[test]
fn flattening_keeps_the_two_largest_axes_and_the_normal() {
    let c = random_cloud(500, 0, 9);
    let f = flatten_to_surfels(&c);
    for i in 0..c.len() {
        let r = Mat3::from_quat(c.unit_rotation(i));
        let s = c.scale(i);
        let mut axes = [(s.x, r.x_axis), (s.y, r.y_axis), (s.z, r.z_axis)];
        axes.sort_by(|a, b| b.0.total_cmp(&a.0));
        let rf = Mat3::from_quat(f.unit_rotation(i));
        let sf = f.scale(i);
        // Scales: the two largest, in order (f32 exp of the same stored log-scales).
        assert_eq!((sf.x, sf.y), (axes[0].0, axes[1].0), "Gaussian {i}");
        // Axes: the same directions (1e-5: quaternion round trip of a rotation matrix in f32).
        for (got, want) in [(rf.x_axis, axes[0].1), (rf.y_axis, axes[1].1)] {
            assert!(
                (got - want).length() < 1e-5,
                "Gaussian {i}: {got} vs {want}"
            );
        }
        // The normal is the smallest axis up to sign, the frame right-handed.
        assert!(rf.z_axis.dot(axes[2].1).abs() > 1.0 - 1e-5);
        assert!(rf.determinant() > 0.0);
        // The third scale is the reader's thin axis.
        let want = f.log_scales[i].x.min(f.log_scales[i].y) + SURFEL_THICKNESS.ln();
        assert_eq!(f.log_scales[i].z, want);
        assert_eq!(f.means[i], c.means[i]);
        assert_eq!(f.opacity_logits[i], c.opacity_logits[i]);
    }
}
