//! Rotation of real SH coefficients (degrees 1–3) with an object, so a moving object's
//! view-dependent colour follows it.
//!
//! Convention: the basis of [`crate::sh`] (the reference 3DGS `computeColorFromSH`, with its
//! signs). An object whose local-to-world rotation is `R` shows, in world direction `d`, the
//! colour its local coefficients give in the local direction `Rᵀ·d`. Each band `l` is closed
//! under rotation, so `Y_l(Rᵀ·d) = D_l · Y_l(d)` for a (2l+1)×(2l+1) matrix `D_l`, and the
//! world-space coefficients are `c_world = D_lᵀ · c_local` per band and colour channel; the DC
//! term never changes.
//!
//! `D_l` is obtained numerically in f64, independent of any sign convention: with `B` the band's
//! basis evaluated at N = 32 fixed, well-spread directions `u_s` (a Fibonacci sphere) and `B'` the
//! basis at `Rᵀ·u_s`, `B' = D_l·B` holds exactly, so `D_l = B'·P` with the precomputed
//! right-inverse `P = Bᵀ(B·Bᵀ)⁻¹`. The over-determined fit with well-spread directions keeps
//! `B·Bᵀ` close to `(N/4π)·I` (the basis is orthonormal), hence well conditioned. Building an
//! [`ShRotation`] costs a few thousand flops; callers build one per object and time, then apply it
//! to every Gaussian of the object.

use std::sync::OnceLock;

use glam::{DMat3, DQuat, DVec3, Quat, Vec3};

use crate::sh::basis_f64;

/// Number of fitting directions (more than the 7 of the largest band; see the module docs).
const FIT_DIRS: usize = 32;

/// Per-band coefficient rotation matrices for one rotation `R`, row-major:
/// `c_world[l][i] = Σ_j band_l[i][j] · c_local[l][j]` (band indices `m` in the order of
/// [`crate::sh::basis`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShRotation {
    pub band1: [[f32; 3]; 3],
    pub band2: [[f32; 5]; 5],
    pub band3: [[f32; 7]; 7],
    /// True when `R` is exactly the identity: applying is then a no-op (bit-exact).
    pub identity: bool,
}

/// The fixed fitting directions and, per band, the right-inverse `P` (N × (2l+1)).
struct Fit {
    dirs: [DVec3; FIT_DIRS],
    /// `p[l-1][s][k]`, only the first `2l+1` columns used.
    p: [[[f64; 7]; FIT_DIRS]; 3],
}

fn fit() -> &'static Fit {
    static FIT: OnceLock<Fit> = OnceLock::new();
    FIT.get_or_init(|| {
        // Fibonacci sphere: near-uniform coverage without clustering at the poles.
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let mut dirs = [DVec3::ZERO; FIT_DIRS];
        for (s, d) in dirs.iter_mut().enumerate() {
            let z = 1.0 - 2.0 * (s as f64 + 0.5) / FIT_DIRS as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * s as f64;
            *d = DVec3::new(r * phi.cos(), r * phi.sin(), z);
        }
        let basis: Vec<[f64; 16]> = dirs.iter().map(|&d| basis_f64(3, d)).collect();
        let mut p = [[[0.0; 7]; FIT_DIRS]; 3];
        for l in 1..=3usize {
            let m = 2 * l + 1;
            let off = l * l;
            // G = B·Bᵀ (m × m), then P = Bᵀ·G⁻¹.
            let mut g = [[0.0f64; 7]; 7];
            for i in 0..m {
                for j in 0..m {
                    g[i][j] = basis.iter().map(|b| b[off + i] * b[off + j]).sum();
                }
            }
            let ginv =
                invert(&g, m).expect("SH fitting directions are well spread: B·Bᵀ is invertible");
            for s in 0..FIT_DIRS {
                for k in 0..m {
                    p[l - 1][s][k] = (0..m).map(|i| basis[s][off + i] * ginv[i][k]).sum();
                }
            }
        }
        Fit { dirs, p }
    })
}

/// Gauss–Jordan inverse with partial pivoting of the leading `m`×`m` block.
fn invert(a: &[[f64; 7]; 7], m: usize) -> Option<[[f64; 7]; 7]> {
    let mut a = *a;
    let mut inv = [[0.0f64; 7]; 7];
    for i in 0..m {
        inv[i][i] = 1.0;
    }
    for col in 0..m {
        let piv = (col..m).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))?;
        if a[piv][col].abs() < 1e-12 {
            return None;
        }
        a.swap(col, piv);
        inv.swap(col, piv);
        let d = a[col][col];
        for j in 0..m {
            a[col][j] /= d;
            inv[col][j] /= d;
        }
        for r in 0..m {
            if r != col {
                let f = a[r][col];
                if f != 0.0 {
                    for j in 0..m {
                        a[r][j] -= f * a[col][j];
                        inv[r][j] -= f * inv[col][j];
                    }
                }
            }
        }
    }
    Some(inv)
}

impl ShRotation {
    /// The coefficient rotation for a unit quaternion (normalised here, in f64).
    pub fn from_quat(q: Quat) -> Self {
        if q == Quat::IDENTITY {
            return Self::identity();
        }
        let q = q.as_dquat();
        let n = q.length();
        let q = if n > 0.0 && n.is_finite() {
            q / n
        } else {
            DQuat::IDENTITY
        };
        let mut r = Self::from_dmat3(&DMat3::from_quat(q));
        r.identity = false;
        r
    }

    /// The identity (no change to any coefficient).
    pub fn identity() -> Self {
        let mut r = ShRotation {
            band1: [[0.0; 3]; 3],
            band2: [[0.0; 5]; 5],
            band3: [[0.0; 7]; 7],
            identity: true,
        };
        for i in 0..3 {
            r.band1[i][i] = 1.0;
        }
        for i in 0..5 {
            r.band2[i][i] = 1.0;
        }
        for i in 0..7 {
            r.band3[i][i] = 1.0;
        }
        r
    }

    /// The coefficient rotation for a rotation matrix `rot` (local-to-world, orthonormal).
    pub fn from_dmat3(rot: &DMat3) -> Self {
        let m = Self::bands_f64(rot);
        let mut r = ShRotation {
            band1: [[0.0; 3]; 3],
            band2: [[0.0; 5]; 5],
            band3: [[0.0; 7]; 7],
            identity: false,
        };
        for i in 0..3 {
            for j in 0..3 {
                r.band1[i][j] = m[0][i][j] as f32;
            }
        }
        for i in 0..5 {
            for j in 0..5 {
                r.band2[i][j] = m[1][i][j] as f32;
            }
        }
        for i in 0..7 {
            for j in 0..7 {
                r.band3[i][j] = m[2][i][j] as f32;
            }
        }
        r
    }

    /// The f64 matrices `M_l = D_lᵀ` (band l at index l−1; leading (2l+1)² block used).
    pub fn bands_f64(rot: &DMat3) -> [[[f64; 7]; 7]; 3] {
        let f = fit();
        let rt = rot.transpose();
        // B'[s] = basis at Rᵀ·u_s.
        let rotated: Vec<[f64; 16]> = f.dirs.iter().map(|&u| basis_f64(3, rt * u)).collect();
        let mut out = [[[0.0f64; 7]; 7]; 3];
        for l in 1..=3usize {
            let m = 2 * l + 1;
            let off = l * l;
            for j in 0..m {
                for k in 0..m {
                    // D[j][k] = Σ_s B'[j][s]·P[s][k]; M[k][j] = D[j][k].
                    let d: f64 = (0..FIT_DIRS)
                        .map(|s| rotated[s][off + j] * f.p[l - 1][s][k])
                        .sum();
                    out[l - 1][k][j] = d;
                }
            }
        }
        out
    }

    /// Rotate one Gaussian's coefficient-major coefficients (`(degree+1)²` RGB triples, DC
    /// first) in place. Bands above `degree` (or beyond the slice) are untouched.
    #[inline]
    pub fn apply(&self, degree: u8, coeffs: &mut [Vec3]) {
        if self.identity {
            return;
        }
        if degree >= 1 && coeffs.len() >= 4 {
            apply_band(&self.band1, &mut coeffs[1..4]);
        }
        if degree >= 2 && coeffs.len() >= 9 {
            apply_band(&self.band2, &mut coeffs[4..9]);
        }
        if degree >= 3 && coeffs.len() >= 16 {
            apply_band(&self.band3, &mut coeffs[9..16]);
        }
    }
}

#[inline]
fn apply_band<const M: usize>(m: &[[f32; M]; M], c: &mut [Vec3]) {
    let mut src = [Vec3::ZERO; M];
    src.copy_from_slice(&c[..M]);
    for i in 0..M {
        let mut acc = Vec3::ZERO;
        for j in 0..M {
            acc += src[j] * m[i][j];
        }
        c[i] = acc;
    }
}

/// Rotate coefficient-major coefficients by the unit quaternion `q` (builds the matrices each
/// call; for many Gaussians build one [`ShRotation`] and reuse it).
pub fn rotate_sh(degree: u8, coeffs: &mut [Vec3], q: Quat) {
    ShRotation::from_quat(q).apply(degree, coeffs);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_directions_reconstruct_identity() {
        let m = ShRotation::bands_f64(&DMat3::IDENTITY);
        for (l, band) in m.iter().enumerate() {
            let n = 2 * l + 3;
            for i in 0..n {
                for j in 0..n {
                    let want = if i == j { 1.0 } else { 0.0 };
                    // Pure f64 round-off of a 32-term fit: 1e-12 is ~10⁴ ulps of margin.
                    assert!(
                        (band[i][j] - want).abs() < 1e-12,
                        "band {} [{i}][{j}] = {}",
                        l + 1,
                        band[i][j]
                    );
                }
            }
        }
    }
}
