//! Surfels for the GES-style hybrid (Gaussian-enhanced Surfels, arXiv 2504.17545,
//! `YessionCC/GES`): which Gaussians of a trained 3DGS cloud become opaque surfels, what a surfel
//! is, and how GES's own PLY files mark them.
//!
//! **A surfel** is an opaque ellipse: centre μ, two unit tangent axes a_u, a_v with standard
//! deviations s_u, s_v, covered where `−½(u² + v²) ≥ ln(1/255)` for the local coordinates
//! `u = a_u·(x − μ)/s_u`, `v = a_v·(x − μ)/s_v` (GES's surfel fragment test), i.e. out to
//! `r = sqrt(2·ln 255) ≈ 3.33` standard deviations ([`FOOTPRINT_SIGMAS`]). Its colour is the
//! Gaussian's SH colour (all degrees, evaluated toward the camera like a Gaussian's).
//!
//! **Depth tolerance.** GES lets a Gaussian through at a pixel covered by a surfel only if its
//! centre depth is within `ε = 5·mean(scales)` of the surfel depth, the surfel's third scale
//! being `0.1·mean` of its two (`GaussianModel.change_scale2D_2_3D` then `calc_mod_depth`). A
//! surfel therefore carries `mean_scale = mean(s_u, s_v, 0.1·mean(s_u, s_v)) = 0.35·(s_u + s_v)`
//! and the renderer uses `ε = F·mean_scale` with the factor F a knob (GES: 5).
//!
//! **Split of a trained 3DGS cloud** ([`split`]): Gaussian i becomes a surfel when its opacity is
//! at least `min_opacity` and its flatness `s_min/s_mid` is at most `max_flatness`; the surfel
//! spans the two largest axes. GES itself turns Gaussians with opacity > 0.8 into surfels after
//! its 2D training stage; an ordinary 3DGS scene has no such stage, so both thresholds are
//! knobs. The defaults ([`DEFAULT_MIN_OPACITY`], [`DEFAULT_MAX_FLATNESS`]) come from the sweep of
//! `splatbridge bench hybrid` on real scenes (see the constants). A Gaussian that passes this
//! local test is then judged against its neighbourhood and the scene's scale
//! ([`crate::surfel_guard`]: too large for the scene, much larger than its neighbours, or
//! isolated, it stays a Gaussian); `docs/split.md` has the failures each guard prevents and
//! the measurements behind their defaults.
//!
//! **GES PLY convention** ([`split_ges`]), read from GES's `GaussianModel.save_ply` and its viewer
//! (`ges_viewer/src/gaussianCloud.cpp`): after training, opacities are linear (the joint stage
//! switches the opacity activation to ReLU); a surfel's `opacity` property holds
//! `1000 + mod_depth` where `mod_depth` is its ε in world units (`5·mean(scales)`); the viewer
//! reads `alpha = max(opacity, 0)`, treats `alpha > 1000` as a surfel and subtracts 1000; a
//! surfel's tangent axes are the first two columns of its rotation scaled by `exp(scale_0)`,
//! `exp(scale_1)`. Residual Gaussians keep their rotation and scales; their linear opacity is
//! clamped to [0, 1] (the sigmoid-based cloud cannot hold more; the count is reported).

use glam::{Mat3, Vec3};

use crate::gaussians::{logit, sh_coeffs, GaussianCloud};
use crate::surfel_guard::{guard, GuardCounts, GuardParams};

/// Surfel footprint radius in standard deviations: `sqrt(2·ln 255)`, where a unit-peak Gaussian
/// falls to 1/255 (GES's `−½|uv|² ≥ ln(1/255)`).
pub const FOOTPRINT_SIGMAS: f32 = 3.329_043;

/// GES marks surfels by storing `1000 + mod_depth` in the `opacity` property.
pub const GES_SURFEL_FLAG: f32 = 1000.0;

/// GES's depth-tolerance factor: `ε = 5·mean(scales)`.
pub const GES_EPSILON_FACTOR: f32 = 5.0;

/// Default opacity threshold of [`split`]: 0.8, GES's own surfel rule. Measured with
/// `splatbridge bench hybrid` (1920×1080, `orbit:8:0`, PSNR against the native renderer; the sweep
/// is A ∈ {0.5, 0.8, 0.9, 0.95, 0.99} × R ∈ {0.1, 0.2, 0.3, 0.5, 1}): A = 0.8, R = 0.3 gives
/// 30.97 dB on `fourth_st.ply` (3828 surfels; no surfels at all: 28.83 dB) and 29.03 dB on
/// `plant.ply` (453 surfels; none: 28.49 dB), within 0.25 dB of the best setting on each scene
/// (A = 0.95, R = 1: 31.19 / 28.94 dB, which ignores flatness), while culling more tile pairs.
/// Looser thresholds (A = 0.5, or R = 1 with A ≤ 0.8) turn soft Gaussians into hard discs and
/// lose 1–5 dB.
pub const DEFAULT_MIN_OPACITY: f32 = 0.8;

/// Default flatness threshold (smallest over middle scale) of [`split`]; see
/// [`DEFAULT_MIN_OPACITY`] for the measurement.
pub const DEFAULT_MAX_FLATNESS: f32 = 0.3;

/// Default of [`SplitParams::max_scene_fraction`]; see `docs/split.md` for the measurement.
pub const DEFAULT_MAX_SCENE_FRACTION: f32 = 0.05;

/// Default of [`SplitParams::max_neighbour_ratio`]; see `docs/split.md` for the measurement.
pub const DEFAULT_MAX_NEIGHBOUR_RATIO: f32 = 4.0;

/// Default of [`SplitParams::min_neighbours`]; see `docs/split.md` for the measurement.
pub const DEFAULT_MIN_NEIGHBOURS: u32 = 4;

/// Split thresholds: the local test (opacity, flatness) and the guards of
/// [`crate::surfel_guard`] (each one off at its "off" value).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplitParams {
    /// Activated opacity at or above which a Gaussian may become a surfel.
    pub min_opacity: f32,
    /// Largest `s_min / s_mid` of a surfel (0 = only perfectly flat, 1 = any shape).
    pub max_flatness: f32,
    /// Largest footprint radius (`FOOTPRINT_SIGMAS·s_u`) as a fraction of the scene's robust
    /// extent. Prevents large flat opaque background or floater Gaussians from becoming
    /// wall-sized hard discs. Off: `f32::INFINITY`.
    pub max_scene_fraction: f32,
    /// Largest `s_u` over the median largest scale of its nearest Gaussians inside the
    /// footprint. Prevents a coarse Gaussian from painting a hard disc over the finer detail
    /// around it. Off: `f32::INFINITY`.
    pub max_neighbour_ratio: f32,
    /// Fewest other Gaussian centres inside the footprint radius. Prevents isolated floaters
    /// from becoming hard discs in the air. Off: 0.
    pub min_neighbours: u32,
}

impl Default for SplitParams {
    fn default() -> Self {
        SplitParams {
            min_opacity: DEFAULT_MIN_OPACITY,
            max_flatness: DEFAULT_MAX_FLATNESS,
            max_scene_fraction: DEFAULT_MAX_SCENE_FRACTION,
            max_neighbour_ratio: DEFAULT_MAX_NEIGHBOUR_RATIO,
            min_neighbours: DEFAULT_MIN_NEIGHBOURS,
        }
    }
}

impl SplitParams {
    /// The local test alone (every guard off): the split before the guards existed.
    pub fn unguarded(min_opacity: f32, max_flatness: f32) -> Self {
        SplitParams {
            min_opacity,
            max_flatness,
            max_scene_fraction: f32::INFINITY,
            max_neighbour_ratio: f32::INFINITY,
            min_neighbours: 0,
        }
    }

    /// The local thresholds with the default guards.
    pub fn guarded(min_opacity: f32, max_flatness: f32) -> Self {
        SplitParams {
            min_opacity,
            max_flatness,
            ..SplitParams::default()
        }
    }

    /// No surfels at all (everything stays a Gaussian).
    pub fn none() -> Self {
        SplitParams::unguarded(2.0, 0.0)
    }

    /// The guard thresholds.
    pub fn guard(&self) -> GuardParams {
        GuardParams {
            max_scene_fraction: self.max_scene_fraction,
            max_neighbour_ratio: self.max_neighbour_ratio,
            min_neighbours: self.min_neighbours,
        }
    }

    /// Checked: `None` when every value is usable, else the offending field's name and why.
    pub fn check(&self) -> Option<(&'static str, &'static str)> {
        if !(self.min_opacity >= 0.0 && self.min_opacity.is_finite()) {
            return Some((
                "min_opacity",
                "must be finite and ≥ 0 (above 1: no surfels)",
            ));
        }
        if !(self.max_flatness >= 0.0 && self.max_flatness.is_finite()) {
            return Some(("max_flatness", "must be finite and ≥ 0"));
        }
        if self.max_scene_fraction.is_nan() || self.max_scene_fraction <= 0.0 {
            return Some(("max_scene_fraction", "must be > 0 (inf: off)"));
        }
        if self.max_neighbour_ratio.is_nan() || self.max_neighbour_ratio <= 0.0 {
            return Some(("max_neighbour_ratio", "must be > 0 (inf: off)"));
        }
        None
    }
}

/// Opaque ellipses, structure of arrays. SH layout as [`GaussianCloud`] (coefficient-major).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfelCloud {
    pub means: Vec<Vec3>,
    /// Unit tangent axes (orthogonal).
    pub axes_u: Vec<Vec3>,
    pub axes_v: Vec<Vec3>,
    /// Standard deviations along `axes_u`, `axes_v` (the ellipse reaches [`FOOTPRINT_SIGMAS`]·s).
    pub scales: Vec<[f32; 2]>,
    /// `ε / F` in world units: the renderer's depth tolerance is `F·mean_scale` (GES: F = 5).
    pub mean_scales: Vec<f32>,
    pub sh_degree: u8,
    pub sh: Vec<Vec3>,
}

impl SurfelCloud {
    pub fn new(sh_degree: u8) -> Self {
        SurfelCloud {
            sh_degree,
            ..Default::default()
        }
    }

    pub fn len(&self) -> usize {
        self.means.len()
    }

    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    pub fn coeffs(&self) -> usize {
        sh_coeffs(self.sh_degree)
    }

    pub fn sh_of(&self, i: usize) -> &[Vec3] {
        let k = self.coeffs();
        &self.sh[i * k..(i + 1) * k]
    }

    /// Unit normal `a_u × a_v`.
    pub fn normal(&self, i: usize) -> Vec3 {
        self.axes_u[i].cross(self.axes_v[i])
    }

    /// Append a surfel; `sh` must hold `coeffs()` triples.
    pub fn push(
        &mut self,
        mean: Vec3,
        axis_u: Vec3,
        axis_v: Vec3,
        scales: [f32; 2],
        mean_scale: f32,
        sh: &[Vec3],
    ) {
        debug_assert_eq!(sh.len(), self.coeffs());
        self.means.push(mean);
        self.axes_u.push(axis_u);
        self.axes_v.push(axis_v);
        self.scales.push(scales);
        self.mean_scales.push(mean_scale);
        self.sh.extend_from_slice(sh);
    }

    /// Rim point at angle θ on the footprint ellipse (`m` standard deviations out).
    pub fn rim_point(&self, i: usize, theta: f32, m: f32) -> Vec3 {
        let [su, sv] = self.scales[i];
        self.means[i] + m * (theta.cos() * su * self.axes_u[i] + theta.sin() * sv * self.axes_v[i])
    }
}

/// GES's `mean(s_u, s_v, 0.1·mean(s_u, s_v))`.
pub fn ges_mean_scale(su: f32, sv: f32) -> f32 {
    let m2 = 0.5 * (su + sv);
    (su + sv + 0.1 * m2) / 3.0
}

/// Axis order of Gaussian `i`'s scales, largest first, and the flatness `s_min / s_mid`
/// (0 when both are 0).
fn sorted_axes(s: Vec3) -> ([usize; 3], f32) {
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&a, &b| s[b].total_cmp(&s[a]));
    let (mid, min) = (s[idx[1]], s[idx[2]]);
    let flat = if mid > 0.0 { min / mid } else { 0.0 };
    (idx, flat)
}

/// Does Gaussian `i` become a surfel under `params`? Non-finite scales never do.
pub fn is_surfel(cloud: &GaussianCloud, i: usize, params: &SplitParams) -> bool {
    let s = cloud.scale(i);
    if !s.is_finite() {
        return false;
    }
    let (_, flat) = sorted_axes(s);
    cloud.opacity(i) >= params.min_opacity && flat <= params.max_flatness
}

/// Copy Gaussian `i` (stored values) into `out`.
fn push_gaussian(out: &mut GaussianCloud, cloud: &GaussianCloud, i: usize) {
    out.push(
        cloud.means[i],
        cloud.log_scales[i],
        cloud.rotations[i],
        cloud.opacity_logits[i],
        cloud.sh_of(i),
    );
}

/// Split a trained 3DGS cloud: surfels from the Gaussians passing [`is_surfel`] and the guards
/// of [`crate::surfel_guard`] (on their two largest axes), the rest as residual Gaussians in
/// input order with stored values unchanged.
pub fn split(cloud: &GaussianCloud, params: &SplitParams) -> (SurfelCloud, GaussianCloud) {
    let (s, g, _) = split_counted(cloud, params);
    (s, g)
}

/// As [`split`], also returning why candidates stayed Gaussians.
pub fn split_counted(
    cloud: &GaussianCloud,
    params: &SplitParams,
) -> (SurfelCloud, GaussianCloud, GuardCounts) {
    let candidates: Vec<(usize, f32)> = (0..cloud.len())
        .filter(|&i| is_surfel(cloud, i, params))
        .map(|i| (i, cloud.scale(i).max_element()))
        .collect();
    let (keep, counts) = guard(cloud, &candidates, &params.guard());
    let mut is_s = vec![false; cloud.len()];
    for (&(i, _), &k) in candidates.iter().zip(&keep) {
        is_s[i] = k;
    }
    let mut surfels = SurfelCloud::new(cloud.sh_degree);
    let mut rest = GaussianCloud::new(cloud.sh_degree);
    for (i, &surfel) in is_s.iter().enumerate() {
        if !surfel {
            push_gaussian(&mut rest, cloud, i);
            continue;
        }
        let s = cloud.scale(i);
        let (idx, _) = sorted_axes(s);
        let r = Mat3::from_quat(cloud.unit_rotation(i));
        let (su, sv) = (s[idx[0]], s[idx[1]]);
        let au = r.col(idx[0]);
        let av = r.col(idx[1]);
        surfels.push(
            cloud.means[i],
            au,
            av,
            [su, sv],
            ges_mean_scale(su, sv),
            cloud.sh_of(i),
        );
    }
    (surfels, rest, counts)
}

/// What [`split_ges`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GesReport {
    pub surfels: usize,
    pub gaussians: usize,
    /// Residual Gaussians whose linear opacity exceeded 1 and was clamped to 1.
    pub clamped_opacity: usize,
}

/// Read a cloud loaded from a GES PLY (by `scene::ply::read_ply`, which keeps the stored
/// `opacity` property in `opacity_logits` as it is): stored opacity above 1000 marks a surfel
/// whose depth tolerance is `stored − 1000`; everything else is a residual Gaussian with linear
/// opacity `clamp(stored, 0, 1)` (re-encoded as a logit). See the module docs.
pub fn split_ges(cloud: &GaussianCloud) -> (SurfelCloud, GaussianCloud, GesReport) {
    let mut surfels = SurfelCloud::new(cloud.sh_degree);
    let mut rest = GaussianCloud::new(cloud.sh_degree);
    let mut report = GesReport::default();
    for i in 0..cloud.len() {
        let stored = cloud.opacity_logits[i];
        if stored > GES_SURFEL_FLAG {
            let r = Mat3::from_quat(cloud.unit_rotation(i));
            let s = cloud.scale(i);
            let mod_depth = stored - GES_SURFEL_FLAG;
            surfels.push(
                cloud.means[i],
                r.col(0),
                r.col(1),
                [s.x, s.y],
                mod_depth / GES_EPSILON_FACTOR,
                cloud.sh_of(i),
            );
        } else {
            let o = stored.max(0.0);
            if o > 1.0 {
                report.clamped_opacity += 1;
            }
            rest.push(
                cloud.means[i],
                cloud.log_scales[i],
                cloud.rotations[i],
                logit(o.min(1.0)),
                cloud.sh_of(i),
            );
        }
    }
    report.surfels = surfels.len();
    report.gaussians = rest.len();
    (surfels, rest, report)
}

/// Does this cloud look like a GES PLY (any stored opacity above 1000)? A sigmoid logit above
/// 1000 means an opacity of exactly 1 in f32 anyway, so ordinary 3DGS files never need it.
pub fn looks_like_ges(cloud: &GaussianCloud) -> bool {
    cloud
        .opacity_logits
        .iter()
        .any(|&o| o > GES_SURFEL_FLAG && o.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn footprint_constant_is_sqrt_2_ln_255() {
        assert!((FOOTPRINT_SIGMAS as f64 - (2.0 * 255f64.ln()).sqrt()).abs() < 1e-6);
    }

    #[test]
    fn split_picks_flat_opaque_gaussians_and_their_two_largest_axes() {
        let mut c = GaussianCloud::new(0);
        // Flat (0.01/0.5 = 0.02) and opaque: a surfel; its largest axis is z, then x.
        c.push_activated(
            Vec3::ZERO,
            Vec3::new(0.5, 0.01, 2.0),
            Quat::IDENTITY,
            0.99,
            Vec3::ONE,
        );
        // Opaque but round: stays a Gaussian.
        c.push_activated(Vec3::ONE, Vec3::splat(0.3), Quat::IDENTITY, 0.99, Vec3::ONE);
        // Flat but faint: stays a Gaussian.
        c.push_activated(
            Vec3::X,
            Vec3::new(1.0, 1.0, 0.001),
            Quat::IDENTITY,
            0.2,
            Vec3::ONE,
        );
        let p = SplitParams::unguarded(0.9, 0.1);
        let (s, g) = split(&c, &p);
        assert_eq!((s.len(), g.len()), (1, 2));
        assert!((s.axes_u[0] - Vec3::Z).length() < 1e-6);
        assert!((s.axes_v[0] - Vec3::X).length() < 1e-6);
        assert!((s.scales[0][0] - 2.0).abs() < 1e-5 && (s.scales[0][1] - 0.5).abs() < 1e-5);
        assert!((s.mean_scales[0] - 0.35 * 2.5).abs() < 1e-5);
        assert_eq!(g.means, vec![Vec3::ONE, Vec3::X]);
    }

    #[test]
    fn ges_ply_convention_from_a_hand_built_file() {
        // Two residual Gaussians (linear opacities 0.6 and 1.3) and one surfel (1000 + ε with
        // ε = 0.25), rotated 90° about z: its axes are the rotation's first two columns.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let text = format!(
            "ply\nformat ascii 1.0\nelement vertex 3\n{}end_header\n\
             0 0 0 0.1 0.2 0.3 0.6 -1 -1 -1 1 0 0 0\n\
             1 2 3 0 0 0 1.3 -2 -2 -2 1 0 0 0\n\
             5 6 7 0.5 0.5 0.5 1000.25 {} {} {} {h} 0 0 {h}\n",
            [
                "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1",
                "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"
            ]
            .iter()
            .map(|n| format!("property float {n}\n"))
            .collect::<String>(),
            0.1f32.ln(),
            0.2f32.ln(),
            0.01f32.ln(),
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ges.ply");
        std::fs::write(&path, text).unwrap();
        let (cloud, _) = crate::ply::read_ply(&path, &Default::default()).unwrap();
        assert!(looks_like_ges(&cloud));
        let (s, g, rep) = split_ges(&cloud);
        assert_eq!(
            rep,
            GesReport {
                surfels: 1,
                gaussians: 2,
                clamped_opacity: 1
            }
        );
        assert_eq!(s.means, vec![Vec3::new(5.0, 6.0, 7.0)]);
        // Rotation by 90° about z maps x to y and y to −x.
        assert!((s.axes_u[0] - Vec3::Y).length() < 1e-6, "{:?}", s.axes_u[0]);
        assert!((s.axes_v[0] + Vec3::X).length() < 1e-6, "{:?}", s.axes_v[0]);
        assert!((s.scales[0][0] - 0.1).abs() < 1e-6 && (s.scales[0][1] - 0.2).abs() < 1e-6);
        // ε = F·mean_scale must give back the stored 0.25 (f32 rounding of 1000.25 − 1000 is exact).
        assert_eq!(s.mean_scales[0] * GES_EPSILON_FACTOR, 0.25);
        assert_eq!(s.sh_of(0)[0], Vec3::splat(0.5));
        // Linear opacities: 0.6 kept (through the logit round trip), 1.3 clamped to 1.
        assert!((g.opacity(0) - 0.6).abs() < 1e-6);
        assert_eq!(g.opacity(1), 1.0);
        assert_eq!(g.means[1], Vec3::new(1.0, 2.0, 3.0));
        // A plain 3DGS cloud is not mistaken for a GES one.
        let mut plain = GaussianCloud::new(0);
        plain.push_activated(Vec3::ZERO, Vec3::ONE, Quat::IDENTITY, 0.9, Vec3::ONE);
        plain.opacity_logits.push(f32::INFINITY);
        plain.means.push(Vec3::ZERO);
        assert!(!looks_like_ges(&plain));
    }
}
