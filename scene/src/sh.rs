//! Real spherical harmonics as the reference 3DGS `computeColorFromSH` evaluates them
//! (degree 0–3, the same constants and sign conventions), in f32 and f64.
//!
//! Colour = SH(dir) + 0.5, clamped at 0 only (the rasterizer has no upper clamp); `dir` is
//! `normalize(mean − camera_position)` in world space.

use glam::{DVec3, Vec3};

pub const SH_C0: f32 = 0.282_094_8;
pub const SH_C1: f32 = 0.488_602_5;
pub const SH_C2: [f32; 5] = [
    1.092_548_4,
    -1.092_548_4,
    0.315_391_57,
    -1.092_548_4,
    0.546_274_2,
];
pub const SH_C3: [f32; 7] = [
    -0.590_043_6,
    2.890_611_4,
    -0.457_045_8,
    0.373_176_34,
    -0.457_045_8,
    1.445_305_7,
    -0.590_043_6,
];

/// The real SH basis values (the reference's sign convention) for a unit direction, degree ≤ 3.
/// Returns `(degree+1)²` values; unused entries of the array are zero.
#[inline]
pub fn basis(degree: u8, d: Vec3) -> [f32; 16] {
    let mut b = [0.0f32; 16];
    b[0] = SH_C0;
    if degree == 0 {
        return b;
    }
    let (x, y, z) = (d.x, d.y, d.z);
    b[1] = -SH_C1 * y;
    b[2] = SH_C1 * z;
    b[3] = -SH_C1 * x;
    if degree == 1 {
        return b;
    }
    let (xx, yy, zz, xy, yz, xz) = (x * x, y * y, z * z, x * y, y * z, x * z);
    b[4] = SH_C2[0] * xy;
    b[5] = SH_C2[1] * yz;
    b[6] = SH_C2[2] * (2.0 * zz - xx - yy);
    b[7] = SH_C2[3] * xz;
    b[8] = SH_C2[4] * (xx - yy);
    if degree == 2 {
        return b;
    }
    b[9] = SH_C3[0] * y * (3.0 * xx - yy);
    b[10] = SH_C3[1] * xy * z;
    b[11] = SH_C3[2] * y * (4.0 * zz - xx - yy);
    b[12] = SH_C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
    b[13] = SH_C3[4] * x * (4.0 * zz - xx - yy);
    b[14] = SH_C3[5] * z * (xx - yy);
    b[15] = SH_C3[6] * x * (xx - 3.0 * yy);
    b
}

/// f64 twin of [`basis`], for slow references.
pub fn basis_f64(degree: u8, d: DVec3) -> [f64; 16] {
    let c0 = SH_C0 as f64;
    let c1 = SH_C1 as f64;
    let c2 = SH_C2.map(|c| c as f64);
    let c3 = SH_C3.map(|c| c as f64);
    let mut b = [0.0f64; 16];
    b[0] = c0;
    if degree == 0 {
        return b;
    }
    let (x, y, z) = (d.x, d.y, d.z);
    b[1] = -c1 * y;
    b[2] = c1 * z;
    b[3] = -c1 * x;
    if degree == 1 {
        return b;
    }
    let (xx, yy, zz, xy, yz, xz) = (x * x, y * y, z * z, x * y, y * z, x * z);
    b[4] = c2[0] * xy;
    b[5] = c2[1] * yz;
    b[6] = c2[2] * (2.0 * zz - xx - yy);
    b[7] = c2[3] * xz;
    b[8] = c2[4] * (xx - yy);
    if degree == 2 {
        return b;
    }
    b[9] = c3[0] * y * (3.0 * xx - yy);
    b[10] = c3[1] * xy * z;
    b[11] = c3[2] * y * (4.0 * zz - xx - yy);
    b[12] = c3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
    b[13] = c3[4] * x * (4.0 * zz - xx - yy);
    b[14] = c3[5] * z * (xx - yy);
    b[15] = c3[6] * x * (xx - 3.0 * yy);
    b
}

/// Raw SH sum (no +0.5, no clamp) of `coeffs` (coefficient-major) in unit direction `d`,
/// using at most `degree` (callers pass `min(cloud degree, cap)`).
#[inline]
pub fn eval_raw(degree: u8, coeffs: &[Vec3], d: Vec3) -> Vec3 {
    let b = basis(degree, d);
    let k = crate::gaussians::sh_coeffs(degree).min(coeffs.len());
    let mut c = Vec3::ZERO;
    for j in 0..k {
        c += coeffs[j] * b[j];
    }
    c
}

/// Colour as the rasterizer computes it: SH(d) + 0.5, clamped at 0 (no upper clamp).
#[inline]
pub fn eval_color(degree: u8, coeffs: &[Vec3], d: Vec3) -> Vec3 {
    (eval_raw(degree, coeffs, d) + Vec3::splat(0.5)).max(Vec3::ZERO)
}

/// f64 reference of [`eval_color`].
pub fn eval_color_f64(degree: u8, coeffs: &[Vec3], d: DVec3) -> DVec3 {
    let b = basis_f64(degree, d);
    let k = crate::gaussians::sh_coeffs(degree).min(coeffs.len());
    let mut c = DVec3::ZERO;
    for j in 0..k {
        c += coeffs[j].as_dvec3() * b[j];
    }
    (c + DVec3::splat(0.5)).max(DVec3::ZERO)
}

/// The view-independent base colour: `SH_C0·f_dc + 0.5` clamped to [0, 1] (what glTF's
/// `COLOR_0` can carry and what MeshSplats writes).
#[inline]
pub fn dc_color(coeffs: &[Vec3]) -> Vec3 {
    (coeffs[0] * SH_C0 + Vec3::splat(0.5)).clamp(Vec3::ZERO, Vec3::ONE)
}

/// Funk–Hecke factors `∫₀¹ P_l(t) dt` of degrees 0…3 (1, 1/2, 0, −1/8): the mean of a
/// degree-l harmonic over the hemisphere of directions about a unit axis `a` is this factor
/// times the harmonic's value at `a`.
pub const HEMISPHERE_FACTORS: [f32; 4] = [1.0, 0.5, 0.0, -0.125];

/// The mean of the raw SH sum ([`eval_raw`]) over the hemisphere of unit directions `d` with
/// `d·a > 0` (`a` unit length): what one colour for every view from one side of a plane
/// through the Gaussian (normal `a`) would take, as the DC term is the mean over the sphere.
pub fn hemisphere_mean_raw(degree: u8, coeffs: &[Vec3], a: Vec3) -> Vec3 {
    let b = basis(degree, a);
    let k = crate::gaussians::sh_coeffs(degree).min(coeffs.len());
    let mut c = Vec3::ZERO;
    for (j, (coeff, bj)) in coeffs[..k].iter().zip(b).enumerate() {
        // Coefficient j is of degree ⌊√j⌋.
        let l = (1..4).take_while(|l| l * l <= j).count();
        c += *coeff * (bj * HEMISPHERE_FACTORS[l]);
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hemisphere_mean_equals_quadrature() {
        // The midpoint rule over (cos θ, φ) about the axis, 400 × 800 cells in f64: the
        // integrand is a cubic polynomial of the direction, so the rule's error is O(1/n²),
        // ~1e-6 here, far below the 1e-4 tolerance (f32 coefficients of order one). Random
        // coefficients of every degree; an axis off every coordinate plane.
        let mut rng = crate::rng::Rng::new(7);
        let coeffs: Vec<Vec3> = (0..16)
            .map(|_| {
                Vec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                )
            })
            .collect();
        let a = DVec3::new(0.3, -0.7, 0.45).normalize();
        let t1 = a.any_orthonormal_vector();
        let t2 = a.cross(t1);
        for degree in 0..=3u8 {
            let (nu, nphi) = (400, 800);
            let mut sum = DVec3::ZERO;
            for i in 0..nu {
                let u = (i as f64 + 0.5) / nu as f64;
                let s = (1.0 - u * u).sqrt();
                for j in 0..nphi {
                    let phi = std::f64::consts::TAU * (j as f64 + 0.5) / nphi as f64;
                    let d = a * u + (t1 * phi.cos() + t2 * phi.sin()) * s;
                    let b = basis_f64(degree, d);
                    for (k, c) in coeffs.iter().enumerate().take((degree as usize + 1).pow(2)) {
                        sum += c.as_dvec3() * b[k];
                    }
                }
            }
            let mean = sum / (nu * nphi) as f64;
            let got = hemisphere_mean_raw(degree, &coeffs, a.as_vec3()).as_dvec3();
            assert!(
                (got - mean).abs().max_element() < 1e-4,
                "degree {degree}: {got} against {mean}"
            );
        }
    }

    #[test]
    fn f32_and_f64_bases_agree() {
        let d = Vec3::new(0.3, -0.5, 0.81).normalize();
        let a = basis(3, d);
        let b = basis_f64(3, d.as_dvec3());
        for j in 0..16 {
            assert!((a[j] as f64 - b[j]).abs() < 1e-6, "coefficient {j}");
        }
    }

    #[test]
    fn dc_only_colour_is_direction_independent() {
        let c = [Vec3::new(1.0, -1.0, 0.0)];
        let a = eval_color(0, &c, Vec3::X);
        let b = eval_color(0, &c, Vec3::Y);
        assert_eq!(a, b);
        assert!((a.x - (0.5 + SH_C0)).abs() < 1e-7);
    }
}
