//! Levels of detail for tiles: a parent's reduced set of Gaussians, made by merging spatial
//! neighbours into one Gaussian each (in the spirit of ProtoGS's prototypes and of the
//! hierarchical 3DGS merge, Kerbl et al. 2024).
//!
//! Grouping: the Gaussians are split recursively at a median of their centres along the
//! longest axis of the group's centre box, into groups of at most `g = ceil(n / target)`
//! (the left part of every split is a multiple of `g`, so there are exactly `ceil(n / g)`
//! groups, never more than `target`).
//!
//! Merge of a group, with weights `wᵢ = αᵢ · det(Σᵢ)^{1/3}` (opacity times the isotropic
//! surrogate of projected area, `(s₁s₂s₃)^{2/3}`: what a Gaussian contributes to a splatted
//! image grows with its opacity and its screen area):
//! - mean `μ = Σ wᵢ μᵢ / W`;
//! - covariance by moment matching, `Σ = Σ wᵢ (Σᵢ + (μᵢ − μ)(μᵢ − μ)ᵀ) / W`;
//! - colour: every SH coefficient is the `w`-weighted mean;
//! - mass: the merged opacity is `α = W / det(Σ)^{1/3}`, so `α · det(Σ)^{1/3}` (the mass in
//!   the weight's own measure) equals the group's `W`; α is capped just below 1, where mass
//!   can no longer be kept (a group denser than one opaque Gaussian).
//!
//! When every weight is zero (all transparent) the weights fall back to equal ones. The
//! covariance is turned back into scales and a rotation by a Jacobi eigen-decomposition in
//! f64; eigenvalues are floored at `1e-12` of the largest so log-scales stay finite.

use glam::{DMat3, DVec3, Mat3, Quat, Vec3};
use rayon::prelude::*;
use splatbridge_scene::gaussians::logit;
use splatbridge_scene::GaussianCloud;

/// The largest merged opacity: the sigmoid's logit stays finite.
pub const MAX_MERGED_OPACITY: f32 = 0.999;

/// The merge weight of Gaussian `i` (see the module documentation).
pub fn weight(cloud: &GaussianCloud, i: usize) -> f64 {
    let s = cloud.scale(i).as_dvec3();
    cloud.opacity(i) as f64 * (s.x * s.y * s.z).abs().powf(2.0 / 3.0)
}

/// Groups of at most `ceil(n / target)` neighbours covering `0..cloud.len()`.
pub fn groups(cloud: &GaussianCloud, target: usize) -> Vec<Vec<u32>> {
    let n = cloud.len();
    if n == 0 {
        return Vec::new();
    }
    let g = n.div_ceil(target.max(1));
    let mut idx: Vec<u32> = (0..n as u32).collect();
    let mut out = Vec::with_capacity(n.div_ceil(g));
    let mut stack = vec![&mut idx[..]];
    while let Some(s) = stack.pop() {
        if s.len() <= g {
            out.push(s.to_vec());
            continue;
        }
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for &i in s.iter() {
            lo = lo.min(cloud.means[i as usize]);
            hi = hi.max(cloud.means[i as usize]);
        }
        let ext = hi - lo;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let m = g * s.len().div_ceil(g).div_ceil(2);
        s.select_nth_unstable_by(m, |&a, &b| {
            let (pa, pb) = (cloud.means[a as usize][axis], cloud.means[b as usize][axis]);
            pa.total_cmp(&pb).then(a.cmp(&b))
        });
        let (l, r) = s.split_at_mut(m);
        stack.push(r);
        stack.push(l);
    }
    out
}

/// Reduce `cloud` to at most `target` Gaussians by merging neighbours.
pub fn reduce(cloud: &GaussianCloud, target: usize) -> GaussianCloud {
    let gs = groups(cloud, target);
    // Each group's merge is independent: computed on all cores, appended in group order,
    // so the result is the one [`merge_into`] gives group by group.
    let merged: Vec<Merged> = gs.par_iter().map(|g| merge(cloud, g)).collect();
    let mut out = GaussianCloud::with_capacity(cloud.sh_degree, gs.len());
    for m in &merged {
        out.push(m.mean, m.log_scale, m.rotation, m.logit_opacity, &m.sh);
    }
    out
}

/// The moments of a group: total weight, mean, covariance and weighted SH (f64).
pub struct Moments {
    pub weight: f64,
    pub mean: DVec3,
    pub cov: DMat3,
    pub sh: Vec<DVec3>,
}

/// The weighted moments of `group` (see the module documentation).
pub fn moments(cloud: &GaussianCloud, group: &[u32]) -> Moments {
    let mut w: Vec<f64> = group.iter().map(|&i| weight(cloud, i as usize)).collect();
    let mut total: f64 = w.iter().sum();
    if !(total > 0.0) || !total.is_finite() {
        w.iter_mut().for_each(|x| *x = 1.0);
        total = w.len() as f64;
    }
    let mut mean = DVec3::ZERO;
    for (&i, &wi) in group.iter().zip(&w) {
        mean += wi * cloud.means[i as usize].as_dvec3();
    }
    mean /= total;
    let mut cov = DMat3::ZERO;
    let mut sh = vec![DVec3::ZERO; cloud.coeffs()];
    for (&i, &wi) in group.iter().zip(&w) {
        let i = i as usize;
        let d = cloud.means[i].as_dvec3() - mean;
        let ci = cloud.covariance(i).as_dmat3();
        cov += (ci + outer(d, d)) * wi;
        for (acc, c) in sh.iter_mut().zip(cloud.sh_of(i)) {
            *acc += wi * c.as_dvec3();
        }
    }
    Moments {
        weight: total,
        mean,
        cov: cov * (1.0 / total),
        sh: sh.into_iter().map(|c| c / total).collect(),
    }
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// One merged Gaussian, in [`GaussianCloud::push`]'s parameters.
struct Merged {
    mean: Vec3,
    log_scale: Vec3,
    rotation: Quat,
    logit_opacity: f32,
    sh: Vec<Vec3>,
}

/// Append the merge of `group` to `out`.
pub fn merge_into(cloud: &GaussianCloud, group: &[u32], out: &mut GaussianCloud) {
    let m = merge(cloud, group);
    out.push(m.mean, m.log_scale, m.rotation, m.logit_opacity, &m.sh);
}

/// The merge of `group` (see the module documentation).
fn merge(cloud: &GaussianCloud, group: &[u32]) -> Merged {
    let m = moments(cloud, group);
    let (vals, vecs) = symmetric_eigen(m.cov);
    let top = vals.max_element().max(0.0);
    let floor = (top * 1e-12).max(f64::MIN_POSITIVE);
    let vals = vals.max(DVec3::splat(floor));
    let scale = DVec3::new(vals.x.sqrt(), vals.y.sqrt(), vals.z.sqrt());
    let mut r = vecs;
    if r.determinant() < 0.0 {
        r.z_axis = -r.z_axis;
    }
    let area = (vals.x * vals.y * vals.z).powf(1.0 / 3.0);
    // Equal-weight fallback groups (all transparent) stay transparent.
    let alpha = if group.iter().any(|&i| weight(cloud, i as usize) > 0.0) {
        (m.weight / area).min(MAX_MERGED_OPACITY as f64) as f32
    } else {
        0.0
    };
    let sh: Vec<Vec3> = m.sh.iter().map(|c| c.as_vec3()).collect();
    let log_scale = Vec3::new(
        scale.x.ln() as f32,
        scale.y.ln() as f32,
        scale.z.ln() as f32,
    );
    let q = Quat::from_mat3(&Mat3::from_cols(
        r.x_axis.as_vec3(),
        r.y_axis.as_vec3(),
        r.z_axis.as_vec3(),
    ))
    .normalize();
    Merged {
        mean: m.mean.as_vec3(),
        log_scale,
        rotation: q,
        logit_opacity: logit(alpha),
        sh,
    }
}

/// Eigenvalues and unit eigenvectors (columns) of a symmetric matrix, by cyclic Jacobi
/// rotations (Golub & Van Loan §8.5); 3×3 converges in a few sweeps.
pub fn symmetric_eigen(m: DMat3) -> (DVec3, DMat3) {
    let mut a = m.to_cols_array_2d(); // a[col][row]; symmetric, so a[i][j] = a[j][i]
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0f64]];
    for _ in 0..32 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        let diag = a[0][0].powi(2) + a[1][1].powi(2) + a[2][2].powi(2);
        if !(off > diag * 1e-30) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A ← Jᵀ A J with J the rotation in the (p, q) plane.
            for k in 0..3 {
                let (akp, akq) = (a[k][p], a[k][q]);
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for k in 0..3 {
                let (apk, aqk) = (a[p][k], a[q][k]);
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
            for row in &mut v {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    // v[row][col]: eigenvector k is column k.
    let col = |k: usize| DVec3::new(v[0][k], v[1][k], v[2][k]);
    (
        DVec3::new(a[0][0], a[1][1], a[2][2]),
        DMat3::from_cols(col(0), col(1), col(2)),
    )
}

#[cfg(test)]
mod parallel_tests {
    use super::*;
    use splatbridge_scene::rng::Rng;

    /// The parallel [`reduce`] is [`merge_into`] applied group by group (the sequential
    /// reference), exactly.
    #[test]
    fn reduce_is_merge_into_group_by_group() {
        let mut rng = Rng::new(7);
        let mut cloud = GaussianCloud::with_capacity(1, 500);
        for _ in 0..500 {
            let p = Vec3::new(rng.f32() * 10.0, rng.f32() * 3.0, rng.f32());
            let s = Vec3::splat(-2.0 - rng.f32());
            let q = Quat::from_rotation_y(rng.f32() * 3.0);
            let sh = [Vec3::splat(rng.f32()); 4];
            cloud.push(p, s, q, rng.f32() * 4.0 - 2.0, &sh);
        }
        let fast = reduce(&cloud, 60);
        let mut slow = GaussianCloud::with_capacity(1, 60);
        for g in &groups(&cloud, 60) {
            merge_into(&cloud, g, &mut slow);
        }
        assert_eq!(fast.len(), slow.len());
        assert!(fast.len() <= 60 && fast.len() > 30);
        assert_eq!(fast.means, slow.means);
        assert_eq!(fast.rotations, slow.rotations);
        assert_eq!(format!("{fast:?}"), format!("{slow:?}"));
    }
}
