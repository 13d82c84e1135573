//! The level-of-detail merge of `splatbridge_convert::tiles::lod` against a slow reference
//! written from the definitions (f64, covariance from the activated scale and the rotation
//! matrix built by hand), and the grouping's counts.

use glam::{DMat3, DVec3, Quat, Vec3};
use splatbridge_convert::tiles::lod;
use splatbridge_scene::rng::Rng;
use splatbridge_scene::GaussianCloud;

fn random_cloud(n: usize, seed: u64) -> GaussianCloud {
    let mut rng = Rng::new(seed);
    let mut c = GaussianCloud::new(1);
    for _ in 0..n {
        let mean = Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-0.2, 0.2),
        );
        let ls = Vec3::new(
            rng.range(-4.0, -2.0),
            rng.range(-4.0, -2.0),
            rng.range(-5.0, -2.0),
        );
        let q = Quat::from_xyzw(rng.normal(), rng.normal(), rng.normal(), rng.normal());
        let sh: Vec<Vec3> = (0..4)
            .map(|_| Vec3::new(rng.normal(), rng.normal(), rng.normal()))
            .collect();
        // Logits in [-3, 1]: opacities 0.05..0.73, so merged groups stay below the cap.
        c.push(mean, ls, q, rng.range(-3.0, 1.0), &sh);
    }
    c
}

/// R·diag(s²)·Rᵀ from the stored values, with the rotation matrix written out.
fn slow_cov(log_scale: Vec3, q: Quat) -> DMat3 {
    let q = q.as_dquat();
    let n = (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z).sqrt();
    let (w, x, y, z) = (q.w / n, q.x / n, q.y / n, q.z / n);
    let r = [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ];
    let s = log_scale.as_dvec3();
    let s2 = [(2.0 * s.x).exp(), (2.0 * s.y).exp(), (2.0 * s.z).exp()];
    let mut m = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| r[i][k] * s2[k] * r[j][k]).sum();
        }
    }
    // DMat3 is column-major: column j holds m[·][j].
    DMat3::from_cols(
        DVec3::new(m[0][0], m[1][0], m[2][0]),
        DVec3::new(m[0][1], m[1][1], m[2][1]),
        DVec3::new(m[0][2], m[1][2], m[2][2]),
    )
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

fn max_abs(m: DMat3) -> f64 {
    m.to_cols_array().iter().fold(0.0, |a, x| a.max(x.abs()))
}

#[test]
fn merge_preserves_mass_mean_covariance_and_colour() {
    let c = random_cloud(40, 11);
    for group in [
        vec![0u32],
        vec![1, 2],
        (3..11).collect::<Vec<u32>>(),
        (0..40).collect(),
    ] {
        // Reference moments.
        let mut wsum = 0.0;
        let mut mean = DVec3::ZERO;
        let mut ws = Vec::new();
        for &i in &group {
            let i = i as usize;
            let s = c.log_scales[i].as_dvec3();
            let w = sigmoid(c.opacity_logits[i] as f64) * ((s.x + s.y + s.z) * 2.0 / 3.0).exp();
            ws.push(w);
            wsum += w;
            mean += w * c.means[i].as_dvec3();
        }
        mean /= wsum;
        let mut cov = DMat3::ZERO;
        let mut dc = DVec3::ZERO;
        for (k, &i) in group.iter().enumerate() {
            let i = i as usize;
            let d = c.means[i].as_dvec3() - mean;
            let outer = DMat3::from_cols(d * d.x, d * d.y, d * d.z);
            cov += (slow_cov(c.log_scales[i], c.rotations[i]) + outer) * ws[k];
            dc += ws[k] * c.sh_of(i)[0].as_dvec3();
        }
        cov *= 1.0 / wsum;
        dc /= wsum;

        let mut out = GaussianCloud::new(1);
        lod::merge_into(&c, &group, &mut out);
        assert_eq!(out.len(), 1);
        // f32 storage of the result: relative 1e-5 of the values' scale (2⁻¹⁷ ≈ 7.6e-6 is
        // f32's half-ulp relative, plus the log/exp round trip of the scales).
        let got_cov = slow_cov(out.log_scales[0], out.rotations[0]);
        assert!(
            max_abs(got_cov - cov) <= 1e-5 * max_abs(cov),
            "covariance {got_cov:?} vs {cov:?}"
        );
        assert!((out.means[0].as_dvec3() - mean).length() <= 1e-6);
        assert!((out.sh_of(0)[0].as_dvec3() - dc).length() <= 1e-5 * dc.length().max(1.0));
        let alpha = sigmoid(out.opacity_logits[0] as f64);
        let mass = alpha * cov.determinant().powf(1.0 / 3.0);
        assert!(
            alpha < lod::MAX_MERGED_OPACITY as f64,
            "test groups stay below the cap"
        );
        assert!((mass - wsum).abs() <= 1e-4 * wsum, "mass {mass} vs {wsum}");
    }
}

#[test]
fn single_gaussian_merges_to_itself() {
    let c = random_cloud(5, 3);
    for i in 0..5u32 {
        let mut out = GaussianCloud::new(1);
        lod::merge_into(&c, &[i], &mut out);
        let a = slow_cov(c.log_scales[i as usize], c.rotations[i as usize]);
        let b = slow_cov(out.log_scales[0], out.rotations[0]);
        assert!(max_abs(a - b) <= 1e-5 * max_abs(a));
        // The opacity comes back through the mass: α·det^{1/3} / det^{1/3}.
        let (x, y) = (c.opacity(i as usize), out.opacity(0));
        assert!((x - y).abs() <= 1e-5, "{x} vs {y}");
    }
}

#[test]
fn eigen_decomposition_reconstructs_the_matrix() {
    let mut rng = Rng::new(5);
    for _ in 0..200 {
        let a = DMat3::from_cols_array(&[(); 9].map(|_| rng.normal() as f64));
        let m = a * a.transpose();
        let (vals, vecs) = lod::symmetric_eigen(m);
        let back = vecs * DMat3::from_diagonal(vals) * vecs.transpose();
        assert!(max_abs(back - m) <= 1e-12 * max_abs(m).max(1.0));
        assert!(max_abs(vecs.transpose() * vecs - DMat3::IDENTITY) <= 1e-12);
    }
}

#[test]
fn groups_cover_every_gaussian_once_within_the_target() {
    let c = random_cloud(1000, 9);
    for target in [1, 7, 100, 333, 999, 1000, 5000] {
        let gs = lod::groups(&c, target);
        let g = 1000usize.div_ceil(target);
        assert!(gs.len() <= target);
        assert_eq!(gs.len(), 1000usize.div_ceil(g));
        let mut seen = vec![0; 1000];
        for grp in &gs {
            assert!(!grp.is_empty() && grp.len() <= g);
            grp.iter().for_each(|&i| seen[i as usize] += 1);
        }
        assert!(seen.iter().all(|&s| s == 1));
    }
}
