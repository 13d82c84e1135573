//! The Gaussian cloud: structure of arrays, values kept as 3DGS stores them.
//!
//! Stored (pre-activation) values are what a trained PLY holds: `log_scales` (activate with
//! `exp`), `opacity_logits` (activate with the sigmoid) and `rotations` as written (w, x, y, z,
//! possibly not unit length; activate by normalising). Keeping the stored values makes a
//! write-then-read round trip bit-exact; the accessors [`GaussianCloud::scale`],
//! [`GaussianCloud::opacity`] and [`GaussianCloud::unit_rotation`] give activated values.
//!
//! SH coefficients are coefficient-major: Gaussian `i` owns `sh[i*k .. (i+1)*k]` with
//! `k = (degree+1)²`, each entry an RGB triple; entry 0 is the DC term (`f_dc`).

use glam::{Mat3, Quat, Vec3};

use crate::error::{Result, SceneError};

/// Number of SH coefficients per colour channel for a degree.
pub const fn sh_coeffs(degree: u8) -> usize {
    let d = degree as usize + 1;
    d * d
}

/// A cloud of 3D Gaussians, structure of arrays. All vectors have `len()` entries except `sh`
/// (`len() * sh_coeffs(sh_degree)`) and `object_ids` (absent, or `len()`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GaussianCloud {
    pub means: Vec<Vec3>,
    /// Natural log of the per-axis standard deviations (stored value).
    pub log_scales: Vec<Vec3>,
    /// Rotations as stored (w, x, y, z in the PLY), not necessarily unit length.
    pub rotations: Vec<Quat>,
    /// Opacity before the sigmoid (stored value); ±inf is allowed (fully opaque / transparent).
    pub opacity_logits: Vec<f32>,
    /// SH degree 0..=3.
    pub sh_degree: u8,
    /// Coefficient-major SH coefficients, `sh_coeffs(sh_degree)` RGB triples per Gaussian.
    pub sh: Vec<Vec3>,
    /// Optional per-Gaussian object id (0 = static background in a composite).
    pub object_ids: Option<Vec<u32>>,
}

/// How far a Gaussian's drawn footprint reaches, in its largest standard deviations: the
/// 3σ extent 3DGS bounds its splats by. [`GaussianCloud::view_bounds`] frames at least this.
pub const VIEW_REACH_SIGMAS: f32 = 3.0;

/// The logistic sigmoid, exact at ±inf (returns 1 and 0).
#[inline]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// Inverse of [`sigmoid`]; 0 and 1 map to −inf and +inf.
#[inline]
pub fn logit(p: f32) -> f32 {
    (p / (1.0 - p)).ln()
}

impl GaussianCloud {
    /// An empty cloud of the given SH degree.
    pub fn new(sh_degree: u8) -> Self {
        GaussianCloud {
            sh_degree,
            ..Default::default()
        }
    }

    /// An empty cloud with room for `n` Gaussians.
    pub fn with_capacity(sh_degree: u8, n: usize) -> Self {
        GaussianCloud {
            means: Vec::with_capacity(n),
            log_scales: Vec::with_capacity(n),
            rotations: Vec::with_capacity(n),
            opacity_logits: Vec::with_capacity(n),
            sh_degree,
            sh: Vec::with_capacity(n * sh_coeffs(sh_degree)),
            object_ids: None,
        }
    }

    pub fn len(&self) -> usize {
        self.means.len()
    }

    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    /// SH coefficients per Gaussian.
    pub fn coeffs(&self) -> usize {
        sh_coeffs(self.sh_degree)
    }

    /// Append one Gaussian from stored values. `sh` must hold `coeffs()` triples (coefficient-major).
    pub fn push(
        &mut self,
        mean: Vec3,
        log_scale: Vec3,
        rotation: Quat,
        opacity_logit: f32,
        sh: &[Vec3],
    ) {
        debug_assert_eq!(sh.len(), self.coeffs());
        self.means.push(mean);
        self.log_scales.push(log_scale);
        self.rotations.push(rotation);
        self.opacity_logits.push(opacity_logit);
        self.sh.extend_from_slice(sh);
        if let Some(ids) = &mut self.object_ids {
            ids.push(0);
        }
    }

    /// Append one Gaussian from activated values (scale, opacity in [0,1], any rotation, RGB base
    /// colour in [0,1] turned into a DC coefficient; higher-order coefficients zero).
    pub fn push_activated(
        &mut self,
        mean: Vec3,
        scale: Vec3,
        rotation: Quat,
        opacity: f32,
        rgb: Vec3,
    ) {
        let k = self.coeffs();
        let mut sh = vec![Vec3::ZERO; k];
        sh[0] = (rgb - Vec3::splat(0.5)) / crate::sh::SH_C0;
        self.means.push(mean);
        self.log_scales
            .push(Vec3::new(scale.x.ln(), scale.y.ln(), scale.z.ln()));
        self.rotations.push(rotation);
        self.opacity_logits.push(logit(opacity));
        self.sh.extend_from_slice(&sh);
        if let Some(ids) = &mut self.object_ids {
            ids.push(0);
        }
    }

    /// Activated opacity, sigmoid of the stored logit, in [0, 1].
    #[inline]
    pub fn opacity(&self, i: usize) -> f32 {
        sigmoid(self.opacity_logits[i])
    }

    /// Activated per-axis standard deviations, `exp` of the stored log-scales.
    #[inline]
    pub fn scale(&self, i: usize) -> Vec3 {
        let l = self.log_scales[i];
        Vec3::new(l.x.exp(), l.y.exp(), l.z.exp())
    }

    /// Unit rotation (the stored quaternion normalised). Validated clouds never hold a zero
    /// quaternion; should one appear anyway, the identity is returned rather than NaN.
    #[inline]
    pub fn unit_rotation(&self, i: usize) -> Quat {
        let q = self.rotations[i];
        let n = q.length();
        if n > 0.0 && n.is_finite() {
            q / n
        } else {
            Quat::IDENTITY
        }
    }

    /// The SH coefficients of Gaussian `i` (coefficient-major RGB triples).
    #[inline]
    pub fn sh_of(&self, i: usize) -> &[Vec3] {
        let k = self.coeffs();
        &self.sh[i * k..(i + 1) * k]
    }

    /// World-space covariance `R·S²·Rᵀ` of Gaussian `i` (f32).
    pub fn covariance(&self, i: usize) -> Mat3 {
        let r = Mat3::from_quat(self.unit_rotation(i));
        let s = self.scale(i);
        let m = r * Mat3::from_diagonal(s);
        m * m.transpose()
    }

    /// Check the structure-of-arrays invariants (equal lengths, SH count, degree ≤ 3).
    pub fn check_shape(&self) -> Result<()> {
        let n = self.len();
        let ok = self.log_scales.len() == n
            && self.rotations.len() == n
            && self.opacity_logits.len() == n
            && self.sh_degree <= 3
            && self.sh.len() == n * self.coeffs()
            && self.object_ids.as_ref().is_none_or(|v| v.len() == n);
        if ok {
            Ok(())
        } else {
            Err(SceneError::Invalid(format!(
                "inconsistent Gaussian cloud: {n} means, {} log-scales, {} rotations, {} opacities, {} SH triples for degree {}",
                self.log_scales.len(),
                self.rotations.len(),
                self.opacity_logits.len(),
                self.sh.len(),
                self.sh_degree
            )))
        }
    }

    /// A conservative screen for [`Self::invalid_reason`]: false means no Gaussian is
    /// invalid, true means some may be (the per-Gaussian pass then decides). One pass over
    /// each array with no early exit and only integer ORs, so it runs at memory speed: a float
    /// is ±∞ or NaN exactly when its 8 exponent bits are all ones (IEEE 754 binary32).
    pub fn may_have_invalid(&self) -> bool {
        const EXP: u32 = 0x7f80_0000;
        // Over flat f32 slices, so the compare-and-OR vectorises.
        let any = |v: &[f32]| v.iter().fold(false, |a, x| a | (x.to_bits() & EXP == EXP));
        // ±∞ opacity logits are valid; NaN is not.
        let opacity = self
            .opacity_logits
            .iter()
            .fold(false, |a, &o| a | o.is_nan());
        let zero_rotation = self
            .rotations
            .iter()
            .fold(false, |a, q| a | (q.length_squared() == 0.0));
        any(bytemuck::cast_slice(&self.means))
            || any(bytemuck::cast_slice(&self.log_scales))
            || any(bytemuck::cast_slice(&self.sh))
            || any(bytemuck::cast_slice(&self.rotations))
            || opacity
            || zero_rotation
    }

    /// Why Gaussian `i` is invalid under the project's policy, if it is: NaN in any value,
    /// infinite means/log-scales/SH, or a zero (or non-finite) quaternion. ±inf opacity logits
    /// are valid (fully opaque / fully transparent); so are tiny log-scales such as −23.
    pub fn invalid_reason(&self, i: usize) -> Option<&'static str> {
        let q = self.rotations[i];
        if !self.means[i].is_finite() {
            return Some("non-finite position");
        }
        if !self.log_scales[i].is_finite() {
            return Some("non-finite log-scale");
        }
        if self.opacity_logits[i].is_nan() {
            return Some("NaN opacity");
        }
        if q.is_nan() || !q.is_finite() {
            return Some("non-finite rotation");
        }
        if q.length_squared() == 0.0 {
            return Some("zero quaternion");
        }
        if self.sh_of(i).iter().any(|c| !c.is_finite()) {
            return Some("non-finite SH coefficient");
        }
        None
    }

    /// Keep only the Gaussians for which `keep(i)` is true, preserving order.
    pub fn retain_indices(&mut self, mut keep: impl FnMut(usize) -> bool) {
        let k = self.coeffs();
        let mut w = 0;
        for r in 0..self.len() {
            if keep(r) {
                if w != r {
                    self.means[w] = self.means[r];
                    self.log_scales[w] = self.log_scales[r];
                    self.rotations[w] = self.rotations[r];
                    self.opacity_logits[w] = self.opacity_logits[r];
                    self.sh.copy_within(r * k..(r + 1) * k, w * k);
                    if let Some(ids) = &mut self.object_ids {
                        ids[w] = ids[r];
                    }
                }
                w += 1;
            }
        }
        self.means.truncate(w);
        self.log_scales.truncate(w);
        self.rotations.truncate(w);
        self.opacity_logits.truncate(w);
        self.sh.truncate(w * k);
        if let Some(ids) = &mut self.object_ids {
            ids.truncate(w);
        }
    }

    /// Append all of `other` (converted to this cloud's SH degree: higher orders dropped or
    /// zero-filled), tagging it with `object_id` when this cloud carries ids.
    pub fn extend_from(&mut self, other: &GaussianCloud, object_id: Option<u32>) {
        let k = self.coeffs();
        let ko = other.coeffs();
        if self.object_ids.is_none() && object_id.is_some() {
            self.object_ids = Some(vec![0; self.len()]);
        }
        self.means.extend_from_slice(&other.means);
        self.log_scales.extend_from_slice(&other.log_scales);
        self.rotations.extend_from_slice(&other.rotations);
        self.opacity_logits.extend_from_slice(&other.opacity_logits);
        for i in 0..other.len() {
            let src = &other.sh[i * ko..(i + 1) * ko];
            for j in 0..k {
                self.sh.push(if j < ko { src[j] } else { Vec3::ZERO });
            }
        }
        if let Some(ids) = &mut self.object_ids {
            match (&other.object_ids, object_id) {
                (_, Some(id)) => ids.extend(std::iter::repeat_n(id, other.len())),
                (Some(o), None) => ids.extend_from_slice(o),
                (None, None) => ids.extend(std::iter::repeat_n(0, other.len())),
            }
        }
    }

    /// Axis-aligned bounds of the means (min, max); `None` when empty.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.means.iter();
        let first = *it.next()?;
        Some(it.fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))))
    }

    /// The bounds views are placed around (orbits, distillation's view sphere):
    /// [`GaussianCloud::robust_bounds`], grown about their centre where their half-diagonal is
    /// below [`VIEW_REACH_SIGMAS`] times the median Gaussian's largest standard deviation.
    /// A scene whose means nearly coincide (one Gaussian, a tight cluster of large ones) is
    /// then framed by what its Gaussians cover, and no camera is placed inside them (around
    /// the means alone, an orbit's camera sat 2e-6 from a lone Gaussian, inside it and
    /// within native splatting's near plane). A scene spread wider than its Gaussians keeps
    /// its robust bounds bit for bit. `None` when empty.
    pub fn view_bounds(&self, p: f32) -> Option<(Vec3, Vec3)> {
        let (lo, hi) = self.robust_bounds(p)?;
        let half = 0.5 * (hi - lo).length();
        let reach = VIEW_REACH_SIGMAS * self.median_largest_sigma();
        if !(reach.is_finite() && half < reach) {
            return Some((lo, hi));
        }
        // A cube of half-side r/√3 has the half-diagonal r.
        let (c, r) = (0.5 * (lo + hi), Vec3::splat(reach / 3f32.sqrt()));
        Some((c - r, c + r))
    }

    /// The median over the Gaussians of the largest of their three standard deviations
    /// (finite ones only); 0 when there is none.
    pub fn median_largest_sigma(&self) -> f32 {
        let mut v: Vec<f32> = self
            .log_scales
            .iter()
            .map(|l| l.max_element().exp())
            .filter(|s| s.is_finite())
            .collect();
        if v.is_empty() {
            return 0.0;
        }
        let mid = v.len() / 2;
        *v.select_nth_unstable_by(mid, f32::total_cmp).1
    }

    /// Robust bounds: per-axis percentiles `p` and `1 − p` of the means (e.g. p = 0.02), so far
    /// outliers (floaters, sky Gaussians) do not decide the framing. `None` when empty.
    pub fn robust_bounds(&self, p: f32) -> Option<(Vec3, Vec3)> {
        if self.is_empty() {
            return None;
        }
        let mut lo = Vec3::ZERO;
        let mut hi = Vec3::ZERO;
        let mut v: Vec<f32> = Vec::with_capacity(self.len());
        for axis in 0..3 {
            v.clear();
            v.extend(self.means.iter().map(|m| m[axis]).filter(|x| x.is_finite()));
            if v.is_empty() {
                return None;
            }
            v.sort_by(f32::total_cmp);
            let at = |q: f32| v[((v.len() - 1) as f32 * q).round() as usize];
            lo[axis] = at(p.clamp(0.0, 0.5));
            hi[axis] = at(1.0 - p.clamp(0.0, 0.5));
        }
        Some((lo, hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigmoid_limits_are_exact() {
        assert_eq!(sigmoid(f32::INFINITY), 1.0);
        assert_eq!(sigmoid(f32::NEG_INFINITY), 0.0);
        assert_eq!(logit(1.0), f32::INFINITY);
        assert_eq!(logit(0.0), f32::NEG_INFINITY);
    }

    #[test]
    fn retain_and_extend_keep_arrays_consistent() {
        let mut a = GaussianCloud::new(1);
        for i in 0..5 {
            a.push_activated(
                Vec3::splat(i as f32),
                Vec3::ONE,
                Quat::IDENTITY,
                0.5,
                Vec3::ONE,
            );
        }
        a.retain_indices(|i| i % 2 == 0);
        assert_eq!(a.len(), 3);
        assert_eq!(a.means[2], Vec3::splat(4.0));
        let mut b = GaussianCloud::new(3);
        b.extend_from(&a, Some(7));
        b.check_shape().unwrap();
        assert_eq!(b.object_ids.as_deref(), Some(&[7, 7, 7][..]));
        assert_eq!(b.sh_of(1)[0], a.sh_of(1)[0]);
        assert_eq!(b.sh_of(1)[15], Vec3::ZERO);
    }

    #[test]
    fn zero_quaternion_is_invalid_and_activates_to_identity() {
        let mut a = GaussianCloud::new(0);
        a.push(
            Vec3::ZERO,
            Vec3::ZERO,
            Quat::from_xyzw(0.0, 0.0, 0.0, 0.0),
            0.0,
            &[Vec3::ZERO],
        );
        assert_eq!(a.invalid_reason(0), Some("zero quaternion"));
        assert_eq!(a.unit_rotation(0), Quat::IDENTITY);
    }

    /// The screen against the per-Gaussian rule it stands in for: every poisoned value in
    /// every array is caught (no false negative), and a clean cloud (±∞ opacities included,
    /// which are valid) is not flagged.
    #[test]
    fn invalid_screen_never_misses_what_the_per_gaussian_rule_finds() {
        let clean = || {
            let mut a = GaussianCloud::new(1);
            for i in 0..9 {
                a.push_activated(
                    Vec3::new(i as f32, -1.0, 2.0),
                    Vec3::splat(0.1),
                    Quat::from_rotation_y(i as f32),
                    0.5,
                    Vec3::new(0.2, 0.3, 0.4),
                );
            }
            a.opacity_logits[1] = f32::INFINITY;
            a.opacity_logits[2] = f32::NEG_INFINITY;
            a
        };
        let base = clean();
        assert!((0..base.len()).all(|i| base.invalid_reason(i).is_none()));
        assert!(!base.may_have_invalid());
        let bad_values = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        type Poison = fn(&mut GaussianCloud, usize, f32);
        let poisons: [Poison; 7] = [
            |c, i, x| c.means[i].y = x,
            |c, i, x| c.log_scales[i].z = x,
            |c, i, x| c.rotations[i].w = x,
            |c, i, x| c.opacity_logits[i] = x,
            |c, i, x| c.sh[i * 4 + 3].x = x,
            |c, i, _| c.rotations[i] = Quat::from_xyzw(0.0, 0.0, 0.0, 0.0),
            |c, i, x| c.means[i] = Vec3::new(x, -x, 0.0),
        ];
        for poison in poisons {
            for x in bad_values {
                for i in [0, 4, 8] {
                    let mut c = clean();
                    poison(&mut c, i, x);
                    if c.invalid_reason(i).is_some() {
                        assert!(
                            c.may_have_invalid(),
                            "missed Gaussian {i} poisoned with {x}"
                        );
                    }
                }
            }
        }
    }

    /// A cloud of `n` Gaussians with means `mean(i)` and the same largest σ `sigma`.
    fn cloud_of(n: usize, mean: impl Fn(usize) -> Vec3, sigma: f32) -> GaussianCloud {
        let mut c = GaussianCloud::new(0);
        for i in 0..n {
            c.push(
                mean(i),
                Vec3::new(sigma.ln(), (0.1 * sigma).ln(), (0.5 * sigma).ln()),
                Quat::IDENTITY,
                2.0,
                &[Vec3::ZERO],
            );
        }
        c
    }

    /// Means that nearly coincide are framed by the Gaussians' 3σ: the half-diagonal becomes
    /// exactly 3 × the median largest σ, about the same centre; a cloud spread wider than
    /// that keeps its robust bounds bit for bit, and an empty one has none.
    #[test]
    fn view_bounds_frame_what_the_gaussians_cover() {
        let one = cloud_of(1, |_| Vec3::new(1.0, -2.0, 3.0), 0.05);
        let (lo, hi) = one.view_bounds(0.02).unwrap();
        let half = 0.5 * (hi - lo).length();
        // 1e-6 relative: the cube's side is reach/√3 rounded once, and its diagonal
        // recomputed in f32.
        assert!((half - 0.15).abs() <= 0.15 * 1e-6, "{half}");
        assert!(
            (0.5 * (lo + hi) - Vec3::new(1.0, -2.0, 3.0))
                .abs()
                .max_element()
                < 1e-6
        );

        // A tight cluster of large Gaussians: the median σ decides, not the outlier.
        let mut tight = cloud_of(9, |i| Vec3::splat(i as f32 * 1e-4), 0.2);
        tight.log_scales[0] = Vec3::splat(50.0f32.ln());
        let (lo, hi) = tight.view_bounds(0.02).unwrap();
        assert!((0.5 * (hi - lo).length() - 0.6).abs() < 1e-5);

        let spread = cloud_of(50, |i| Vec3::new(i as f32, (i * i) as f32 * 0.1, 0.0), 0.05);
        assert_eq!(spread.view_bounds(0.02), spread.robust_bounds(0.02));

        // Non-finite scales are left out of the median; none at all keeps the means' bounds.
        let mut bad = cloud_of(1, |_| Vec3::ZERO, 0.05);
        bad.log_scales[0] = Vec3::splat(f32::INFINITY);
        assert_eq!(bad.view_bounds(0.02), bad.robust_bounds(0.02));
        assert_eq!(GaussianCloud::new(0).view_bounds(0.02), None);
    }
}
