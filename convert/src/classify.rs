//! Flat vs volumetric, what is dropped and why, the triangle-budget score, and the opacity
//! correction of three-fan Gaussians.
//!
//! ## Flat or volumetric
//! A Gaussian is volumetric when `s_min / s_mid ≥ flat_ratio` (default
//! [`crate::options::DEFAULT_FLAT_RATIO`]); otherwise one fan in the plane of its two largest
//! axes stands for it.
//!
//! ## Three fans and their opacity
//! Fan `k` lies in the plane spanned by two principal axes, perpendicular to the third.
//! A ray *along* principal axis `k` crosses only the fan perpendicular to `k` (the other two
//! contain the ray's direction and are seen edge-on), so there the uncorrected fan already
//! reproduces the Gaussian's head-on opacity `o·exp(−½·m²)` exactly. Off-axis rays cross two
//! or three fans. In the low-opacity limit the screen-space integral of a projected fan is
//! proportional to `|n_k·w|·s_i·s_j` (w the view direction) while that of the true Gaussian
//! is proportional to `s₀s₁s₂·sqrt(Σ w_k²/s_k²)`: with `v_k = w_k/s_k`, the three fans
//! over-count the coverage by `‖v‖₁/‖v‖₂ ∈ [1, √3]` — exact along the axes, +73 % along the
//! body diagonal of the whitened frame.
//!
//! We correct in optical depth: every vertex alpha `α` of a three-fan Gaussian becomes
//! `1 − (1 − α)^c` (for small α, `c·α`), with `c = 2/(1 + √3) = 0.732`, the minimax choice
//! over all view directions: the coverage error is then within ±26.8 % for every direction
//! (−26.8 % head-on along an axis, +26.8 % along the diagonal) instead of 0 … +73 %.
//! A ray through the very centre crosses all three fans at full alpha whatever its
//! direction (except exactly along an axis), so the peak is over-counted
//! (`1 − (1 − o)^{3c}` instead of `o`) on a sliver whose area vanishes as the direction
//! approaches an axis; that residual is not corrected. `meshsplats` applies no correction
//! (faithful to the published converter).
//!
//! ## Coplanar separation
//! Fans that lie exactly in one plane (splats of a flat wall or road, common in synthetic
//! scenes and in surface-aligned captures) are invisible to each other in a ray tracer that
//! continues a ray from its last transparent hit: Cycles starts the continuation ray on the
//! hit point and skips that primitive, so every other fan in the same plane sits at t = 0 and
//! is never hit; only one of the overlapping splats shows per sample and the surface renders
//! far too transparent (the street fixture in Blender 3.4: 16.5 dB against native, 24.8 dB
//! once the planes are broken). [`coplanar_offset`] therefore moves every Gaussian's fans along
//! its normal by `ℓ·2⁻²⁰·R`, with `ℓ ∈ [−128, 127]` a hash of the Gaussian's id and `R` a bound
//! on the magnitude of its world coordinates rounded up to a power of two: one step is 16
//! f32 ulps of the largest coordinates below `R` (enough for the continuation ray to find the
//! next fan), Gaussians in one binade share the step exactly (distinct levels never land
//! within a step of each other), the whole spread is at most ±2.4·10⁻⁴ of the coordinates
//! (±3.7 mm at 20–30 m), and two overlapping coplanar Gaussians still share a level with
//! probability 1/256. The shift is along the normal only: head-on footprints are
//! unchanged; depth order among Gaussians closer than the spread follows the hash instead of
//! the view (native splatting orders them by centre depth).
//!
//! What it costs: rasterising viewers draw coplanar layers in index order whatever their
//! depth, so they do not change; the in-repo ray tracer breaks exact ties by Gaussian id, which
//! on the grid-built street fixture happens to follow native's depth order, so there the
//! hashed order loses 0.5–3.3 dB per camera (320×240, texture profile: street 24.88 → 24.34,
//! side 29.78 → 26.43, elevated 26.47 → 25.11, reverse 23.13 → 24.17); on `fourth_st.ply`,
//! which has no exactly coplanar Gaussians, 27.25 → 27.26 dB. Hence the separation is off in
//! [`crate::ConvertOptions::default`] (in-memory conversions for the tracer and the parity
//! floors measured with it) and on in `splatbridge convert`, whose files are the ones opened in
//! Blender.
//!
//! ## Budget score
//! `--max-triangles` keeps the Gaussians with the largest `opacity · s_max · s_mid`
//! (opacity times the area of the 1σ ellipse of the fan's plane, up to π): a proxy for
//! the Gaussian's integrated contribution to an image seen head-on.

use glam::{Mat3, Vec3};
use splatbridge_scene::GaussianCloud;

/// What becomes of one Gaussian.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Kind {
    Flat,
    Volumetric,
    Invalid,
    Transparent,
    Overflow,
    Budget,
}

impl Kind {
    pub fn kept(self) -> bool {
        matches!(self, Kind::Flat | Kind::Volumetric)
    }
}

/// `c = 2/(1+√3)`: the minimax optical-depth scale of three-fan Gaussians (module docs).
pub const THREE_FAN_DEPTH_SCALE: f32 = 0.732_050_8;

/// Apply the three-fan optical-depth correction to one alpha.
#[inline]
pub fn corrected_alpha(alpha: f32) -> f32 {
    if alpha >= 1.0 {
        return 1.0;
    }
    1.0 - (1.0 - alpha).powf(THREE_FAN_DEPTH_SCALE)
}

/// A Gaussian's principal frame: axes sorted by decreasing scale.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub mean: Vec3,
    /// Unit axes, largest scale first.
    pub axes: [Vec3; 3],
    /// Scales in the same order.
    pub scales: [f32; 3],
    pub opacity: f32,
}

impl Frame {
    pub fn of(cloud: &GaussianCloud, i: usize) -> Frame {
        let r = Mat3::from_quat(cloud.unit_rotation(i));
        let s = cloud.scale(i);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| s[b].total_cmp(&s[a]));
        Frame {
            mean: cloud.means[i],
            axes: order.map(|k| r.col(k)),
            scales: order.map(|k| s[k]),
            opacity: cloud.opacity(i),
        }
    }

    /// Unit normal of the main fan: ± the shortest axis, oriented as `axes[0] × axes[1]` so the
    /// fan's winding is counter-clockwise around it.
    pub fn normal(&self) -> Vec3 {
        let n = self.axes[0].cross(self.axes[1]);
        let l = n.length();
        if l > 0.0 && l.is_finite() {
            n / l
        } else {
            self.axes[2]
        }
    }
}

/// Classify Gaussian `i`. `opacity_aware` profiles drop Gaussians below 1/255.
pub fn classify(
    cloud: &GaussianCloud,
    i: usize,
    flat_ratio: f32,
    three_fans: bool,
    opacity_aware: bool,
) -> Kind {
    if cloud.invalid_reason(i).is_some() {
        return Kind::Invalid;
    }
    let f = Frame::of(cloud, i);
    // Vertices reach a few σ (at most r_max/cos(π/3) ≈ 6.7σ) from the mean: keep them well
    // inside f32's range.
    let reach = f.scales[0] * 8.0 + f.mean.abs().max_element();
    if !reach.is_finite() || reach > 1e30 {
        return Kind::Overflow;
    }
    if opacity_aware && !(f.opacity >= crate::profile::ALPHA_MIN) {
        return Kind::Transparent;
    }
    if three_fans && f.scales[2] >= flat_ratio * f.scales[1] && f.scales[1] > 0.0 {
        Kind::Volumetric
    } else {
        Kind::Flat
    }
}

/// Levels of the coplanar separation (module docs).
pub const COPLANAR_LEVELS: i64 = 256;
/// One level's step as a fraction of the coordinate magnitude: 2⁻²⁰ (8–16 f32 ulps).
pub const COPLANAR_STEP: f32 = 1.0 / 1_048_576.0;

/// The shift along the normal of the Gaussian with global id `id` whose world coordinates
/// are bounded by `reach` (module docs): `ℓ(id)·2⁻²⁰·R`, `R` = `reach` rounded up to a power
/// of two. Zero for a zero or non-finite `reach`.
#[inline]
pub fn coplanar_offset(id: u32, reach: f32) -> f32 {
    // splitmix64 finaliser: neighbouring ids get unrelated levels.
    let mut z = (id as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    let level = (z % COPLANAR_LEVELS as u64) as i64 - COPLANAR_LEVELS / 2;
    if !(reach > 0.0 && reach.is_finite()) {
        return 0.0;
    }
    // Round up to a power of two (exact: clear the mantissa after carrying into the exponent).
    let r = f32::from_bits((reach.max(f32::MIN_POSITIVE).to_bits() + 0x007f_ffff) & 0xff80_0000);
    let d = level as f32 * COPLANAR_STEP * r;
    if d.is_finite() {
        d
    } else {
        0.0
    }
}

/// The budget score of Gaussian `i` (module docs).
pub fn score(cloud: &GaussianCloud, i: usize) -> f32 {
    let f = Frame::of(cloud, i);
    let v = f.opacity * f.scales[0] * f.scales[1];
    if v.is_finite() {
        v
    } else {
        0.0
    }
}
