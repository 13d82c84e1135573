//! Least-squares rigid fits: Horn's closed form (B. K. P. Horn, "Closed-form solution of
//! absolute orientation using unit quaternions", JOSA A 4(4), 1987), the quaternion
//! counterpart of Kabsch/Umeyama without scale. The rotation is the eigenvector of the
//! largest eigenvalue of Horn's symmetric 4×4 matrix, found by cyclic Jacobi rotations, so no
//! reflection can come out (a unit quaternion is always a proper rotation) and no SVD crate is
//! needed. Everything is f64: captures sit far from the origin and fits sum many points.

use glam::{DMat3, DQuat, DVec3};

/// A rigid motion in f64: `x ↦ rotation · x + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid {
    pub rotation: DQuat,
    pub translation: DVec3,
}

impl Rigid {
    pub const IDENTITY: Rigid = Rigid {
        rotation: DQuat::IDENTITY,
        translation: DVec3::ZERO,
    };

    #[inline]
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.rotation * p + self.translation
    }

    /// The inverse motion.
    pub fn inverse(&self) -> Rigid {
        let r = self.rotation.conjugate();
        Rigid {
            rotation: r,
            translation: -(r * self.translation),
        }
    }
}

/// The rigid motion minimising `Σ |R·a_i + t − b_i|²` over the pairs `(a_i, b_i)`. Fewer than
/// one pair gives the identity; one pair (or collinear points) fixes the translation and
/// leaves the unconstrained part of the rotation at whatever the eigenvector gives, which is
/// still a proper rotation with the least error.
pub fn fit(pairs: impl Iterator<Item = (DVec3, DVec3)> + Clone) -> Rigid {
    let mut n = 0.0;
    let (mut ca, mut cb) = (DVec3::ZERO, DVec3::ZERO);
    for (a, b) in pairs.clone() {
        ca += a;
        cb += b;
        n += 1.0;
    }
    if n == 0.0 {
        return Rigid::IDENTITY;
    }
    ca /= n;
    cb /= n;
    // S[x][y] = Σ a'_x b'_y, in Horn's notation.
    let mut s = [[0.0f64; 3]; 3];
    for (a, b) in pairs {
        let a = a - ca;
        let b = b - cb;
        let (a, b) = (a.to_array(), b.to_array());
        for (row, ai) in s.iter_mut().zip(a) {
            for (v, bj) in row.iter_mut().zip(b) {
                *v += ai * bj;
            }
        }
    }
    let rotation = horn_rotation(&s);
    Rigid {
        rotation,
        translation: cb - rotation * ca,
    }
}

/// The unit quaternion of Horn's method for the cross-covariance `s` (`s[x][y] = Σ a_x b_y`).
fn horn_rotation(s: &[[f64; 3]; 3]) -> DQuat {
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = *s;
    let mut m = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    let scale = m.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
    if !(scale > 0.0) || !scale.is_finite() {
        return DQuat::IDENTITY;
    }
    for v in m.iter_mut().flatten() {
        *v /= scale;
    }
    let (values, vectors) = jacobi4(m);
    let k = (0..4).fold(0, |b, i| if values[i] > values[b] { i } else { b });
    let q = DQuat::from_xyzw(vectors[1][k], vectors[2][k], vectors[3][k], vectors[0][k]);
    let len = q.length();
    if len > 0.0 && len.is_finite() {
        q / len
    } else {
        DQuat::IDENTITY
    }
}

/// Eigenvalues and eigenvectors (columns) of a symmetric 4×4 matrix by cyclic Jacobi
/// rotations (Golub & Van Loan §8.5). Converges quadratically; 32 sweeps is far beyond what a
/// 4×4 needs (typically 5–6), so the loop always ends.
fn jacobi4(mut a: [[f64; 4]; 4]) -> ([f64; 4], [[f64; 4]; 4]) {
    let mut v = [[0.0; 4]; 4];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _ in 0..32 {
        let off: f64 = (0..4)
            .flat_map(|i| (0..4).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i][j] * a[i][j])
            .sum();
        if off < 1e-30 {
            break;
        }
        for p in 0..3 {
            for q in p + 1..4 {
                if a[p][q].abs() < 1e-300 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..4 {
                    let (akp, akq) = (a[k][p], a[k][q]);
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for k in 0..4 {
                    let (apk, aqk) = (a[p][k], a[q][k]);
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for row in v.iter_mut() {
                    let (vkp, vkq) = (row[p], row[q]);
                    row[p] = c * vkp - s * vkq;
                    row[q] = s * vkp + c * vkq;
                }
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2], a[3][3]], v)
}

/// The rotation matrix of a unit quaternion (for tests and reports).
pub fn matrix(q: DQuat) -> DMat3 {
    DMat3::from_quat(q)
}

#[cfg(test)]
mod tests {
    use super::*;
    use splatbridge_scene::rng::Rng;

    fn cost(r: &Rigid, a: &[DVec3], b: &[DVec3]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(&a, &b)| (r.apply(a) - b).length_squared())
            .sum()
    }

    fn random_rigid(rng: &mut Rng) -> Rigid {
        let axis = DVec3::new(
            rng.normal() as f64,
            rng.normal() as f64,
            rng.normal() as f64,
        )
        .normalize();
        Rigid {
            rotation: DQuat::from_axis_angle(axis, rng.range(-3.0, 3.0) as f64),
            translation: DVec3::new(
                rng.range(-50.0, 50.0) as f64,
                rng.range(-50.0, 50.0) as f64,
                rng.range(-50.0, 50.0) as f64,
            ),
        }
    }

    #[test]
    fn exact_motions_are_recovered() {
        let mut rng = Rng::new(3);
        for _ in 0..200 {
            let truth = random_rigid(&mut rng);
            let a: Vec<DVec3> = (0..7)
                .map(|_| {
                    DVec3::new(
                        rng.range(-2.0, 2.0) as f64,
                        rng.range(-2.0, 2.0) as f64,
                        rng.range(-2.0, 2.0) as f64,
                    ) + DVec3::splat(100.0)
                })
                .collect();
            let b: Vec<DVec3> = a.iter().map(|&p| truth.apply(p)).collect();
            let r = fit(a.iter().copied().zip(b.iter().copied()));
            // f64 on coordinates of ~100: 1e-9 is ~1e5 ulps of room, far below any use.
            assert!(r.rotation.dot(truth.rotation).abs() > 1.0 - 1e-12);
            assert!((r.translation - truth.translation).length() < 1e-9);
            assert!(cost(&r, &a, &b) < 1e-16);
        }
    }

    /// The slow reference: no small rotation or translation step from the fit lowers the
    /// least-squares cost (the fit is a minimum), on noisy pairs where the cost is not zero.
    #[test]
    fn noisy_fit_is_a_least_squares_minimum() {
        let mut rng = Rng::new(9);
        for _ in 0..50 {
            let truth = random_rigid(&mut rng);
            let a: Vec<DVec3> = (0..20)
                .map(|_| {
                    DVec3::new(
                        rng.range(-1.0, 1.0) as f64,
                        rng.range(-1.0, 1.0) as f64,
                        rng.range(-1.0, 1.0) as f64,
                    )
                })
                .collect();
            let b: Vec<DVec3> = a
                .iter()
                .map(|&p| {
                    truth.apply(p)
                        + 0.05
                            * DVec3::new(
                                rng.normal() as f64,
                                rng.normal() as f64,
                                rng.normal() as f64,
                            )
                })
                .collect();
            let r = fit(a.iter().copied().zip(b.iter().copied()));
            let c0 = cost(&r, &a, &b);
            for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
                for step in [1e-3, -1e-3] {
                    let rot = Rigid {
                        rotation: DQuat::from_axis_angle(axis, step) * r.rotation,
                        translation: r.translation,
                    };
                    let tr = Rigid {
                        rotation: r.rotation,
                        translation: r.translation + axis * step,
                    };
                    // A minimum: moving away raises the cost (1e-12 allows for rounding).
                    assert!(cost(&rot, &a, &b) >= c0 - 1e-12);
                    assert!(cost(&tr, &a, &b) >= c0 - 1e-12);
                }
            }
        }
    }

    #[test]
    fn degenerate_inputs_give_finite_rotations() {
        assert_eq!(fit(std::iter::empty()), Rigid::IDENTITY);
        let one = [(DVec3::ONE, DVec3::new(3.0, 4.0, 5.0))];
        let r = fit(one.iter().copied());
        assert!(r.rotation.is_finite() && (r.rotation.length() - 1.0).abs() < 1e-12);
        assert!((r.apply(DVec3::ONE) - DVec3::new(3.0, 4.0, 5.0)).length() < 1e-12);
        let line: Vec<(DVec3, DVec3)> = (0..5)
            .map(|i| (DVec3::X * i as f64, DVec3::Y * i as f64 + DVec3::Z))
            .collect();
        let r = fit(line.iter().copied());
        for (a, b) in line {
            assert!((r.apply(a) - b).length() < 1e-9);
        }
    }
}
