//! PLY vertex layouts other than the standard 3DGS one, mapped onto the same canonical slots:
//!
//! - **Colour instead of `f_dc_*`** (point-cloud-style exports): `red green blue` as `uchar`
//!   (divided by 255), `ushort` (by 65535) or `float`/`double` (taken as is, 0..1), turned
//!   into the DC coefficient `(c − 0.5)/C0` with `C0 = 0.28209479177387814` (the inverse of
//!   3DGS's `SH2RGB`). `f_dc_*` win when both are present.
//! - **2D Gaussian surfels** (2DGS, Huang et al. 2024, `hbb1/2d-gaussian-splatting`,
//!   `scene/gaussian_model.py`: `scale_0 scale_1` only, the surfel's normal being the
//!   rotation's third axis): the third log-scale is the smaller in-plane log-scale plus
//!   `ln(`[`SURFEL_THICKNESS`]`)`, a disc a thousand times thinner than wide, so every 3DGS
//!   path renders it; [`GaussianKind::Surfels2D`] records where it came from.
//! - **Mip-Splatting's 3D filter** (Yu et al. 2024, `autonomousvision/mip-splatting`,
//!   `scene/gaussian_model.py`: `get_scaling_with_3D_filter`, `get_opacity_with_3D_filter`):
//!   a `filter_3D` property (a standard deviation, stored as is) is folded into the plain
//!   3DGS parameters at load, exactly as that loader evaluates them: `s' = sqrt(s² + f²)` per
//!   axis and `α' = α·sqrt(Π s² / Π (s² + f²))`, computed in f64 and stored back as
//!   log-scales and an opacity logit.
//! - **Points without Gaussian parameters** (`x y z` and a colour, no `scale_*`, `rot_*`):
//!   [`GaussianKind::Points`], defaults documented on [`POINT_OPACITY`] and in
//!   `super::point_defaults`.

use std::path::Path;

use super::header::{
    slot_name, Header, ScalarType, MAX_SLOTS, SLOT_DC, SLOT_OPACITY, SLOT_REST, SLOT_ROT,
    SLOT_SCALE,
};
use crate::error::{Result, SceneError};

/// The degree-0 SH basis constant `1/(2√π)`, in f64 (3DGS's `C0` in `utils/sh_utils.py`).
const C0: f64 = 0.282_094_791_773_878_14;

/// What the vertices of a PLY are, as read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GaussianKind {
    /// 3D Gaussians (3DGS, and Mip-Splatting once its filter is folded in).
    #[default]
    Gaussians3D,
    /// 2DGS surfels: flat discs, the third scale made thin on read.
    Surfels2D,
    /// Coloured points given Gaussian defaults on read.
    Points,
}

impl GaussianKind {
    /// A short name for reports (`info`).
    pub fn name(self) -> &'static str {
        match self {
            GaussianKind::Gaussians3D => "3D Gaussians",
            GaussianKind::Surfels2D => "2D Gaussian surfels (2DGS)",
            GaussianKind::Points => "coloured points (Gaussian defaults)",
        }
    }
}

/// The third standard deviation of a 2DGS surfel, as a fraction of its smaller in-plane one.
/// 2DGS's surfels have none; a thousandth keeps the covariance invertible in f32 (condition
/// number 10⁶ in the variances) while no renderer can tell it from a flat disc at any angle
/// short of exactly edge-on.
pub const SURFEL_THICKNESS: f32 = 1e-3;

/// The opacity given to points without one: nearly opaque, so a sampled surface reads as one
/// surface. (3DGS's initialisation from points, `create_from_pcd`, uses 0.1 because training
/// raises it; nothing raises it here.)
pub const POINT_OPACITY: f32 = 0.99;

/// Where one canonical slot's value comes from.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Source {
    /// `raw · mul + add` of the property with this index.
    Prop { pi: usize, mul: f64, add: f64 },
    /// A constant.
    Const(f32),
    /// The 2DGS third log-scale, derived from the other two.
    ThinAxis,
}

/// A non-standard layout.
#[derive(Clone, Debug)]
pub(crate) struct Variant {
    pub kind: GaussianKind,
    /// Per canonical slot, `SLOT_REST + n_rest` of them.
    pub slots: Vec<Source>,
    /// The `filter_3D` property's index.
    pub filter_3d: Option<usize>,
    /// The properties read: (index, byte offset, type).
    pub props: Vec<(usize, usize, ScalarType)>,
    /// One line per default or conversion applied, for the read report.
    pub notes: Vec<String>,
}

impl Variant {
    /// Build the canonical record `v` from the raw values of the properties (`raw[pi]`, only
    /// the entries of `props` are read).
    #[inline]
    pub(crate) fn assemble(&self, raw: &[f64], v: &mut [f32; MAX_SLOTS]) {
        for (dst, s) in v.iter_mut().zip(&self.slots) {
            *dst = match *s {
                // Taken as is (keeps −0.0, which `· 1 + 0` would turn into +0.0).
                Source::Prop { pi, mul, add } if mul == 1.0 && add == 0.0 => raw[pi] as f32,
                Source::Prop { pi, mul, add } => (raw[pi] * mul + add) as f32,
                Source::Const(c) => c,
                Source::ThinAxis => 0.0,
            };
        }
        self.finish(v, self.filter_3d.map(|pi| raw[pi]));
    }

    /// What follows the per-slot values: the 2DGS thin axis from the two scales, and
    /// Mip-Splatting's `filter` (the `filter_3D` value) folded in.
    #[inline]
    pub(crate) fn finish(&self, v: &mut [f32; MAX_SLOTS], filter: Option<f64>) {
        if matches!(self.slots[SLOT_SCALE + 2], Source::ThinAxis) {
            v[SLOT_SCALE + 2] = v[SLOT_SCALE].min(v[SLOT_SCALE + 1]) + SURFEL_THICKNESS.ln();
        }
        if let Some(f) = filter {
            fold_filter_3d(v, f);
        }
    }
}

/// Mip-Splatting's 3D filter folded into the record's log-scales and opacity logit (see the
/// module docs). A NaN or infinite filter leaves NaN or infinite values, which the
/// invalid-Gaussian policy then names.
pub(crate) fn fold_filter_3d(v: &mut [f32; MAX_SLOTS], filter: f64) {
    let f2 = filter * filter;
    let mut det_ratio = 1.0f64;
    for k in 0..3 {
        let s2 = (2.0 * v[SLOT_SCALE + k] as f64).exp();
        let after = s2 + f2;
        det_ratio *= s2 / after;
        v[SLOT_SCALE + k] = (0.5 * after.ln()) as f32;
    }
    let logit = v[SLOT_OPACITY] as f64;
    let alpha = 1.0 / (1.0 + (-logit).exp()) * det_ratio.sqrt();
    v[SLOT_OPACITY] = (alpha / (1.0 - alpha)).ln() as f32;
}

/// The non-standard layout of a vertex element, or `None` when it is the standard 3DGS one.
/// `fixed[slot]` is the index of the property named as the slot, `rest` the `f_rest_*`
/// properties in order.
pub(crate) fn variant(
    header: &Header,
    fixed: &[Option<usize>; SLOT_REST],
    rest: &[usize],
    path: &Path,
) -> Result<Option<Variant>> {
    let err = |what: String| SceneError::format(path, what);
    let find = |name: &str| header.properties.iter().position(|p| p.name == name);
    let filter_3d = find("filter_3D");
    let has = |slots: std::ops::Range<usize>| slots.clone().filter(|&s| fixed[s].is_some()).count();
    let dc_present = has(SLOT_DC..SLOT_DC + 3);
    let scales = has(SLOT_SCALE..SLOT_SCALE + 3);
    let rots = has(SLOT_ROT..SLOT_ROT + 4);
    let standard = dc_present == 3 && scales == 3 && filter_3d.is_none();
    if standard {
        return Ok(None);
    }
    let mut notes = Vec::new();
    let mut props: Vec<(usize, usize, ScalarType)> = Vec::new();
    let mut slots = vec![Source::Const(0.0); SLOT_REST + rest.len()];
    let float = |pi: usize| -> Result<()> {
        let p = &header.properties[pi];
        match p.ty {
            ScalarType::F32 | ScalarType::F64 => Ok(()),
            t => Err(err(format!(
                "vertex property '{}' has type {}; 3DGS values must be float (float32) or double (float64)",
                p.name,
                t.name()
            ))),
        }
    };
    let use_prop = |pi: usize, mul: f64, add: f64, props: &mut Vec<_>| {
        let p = &header.properties[pi];
        props.push((pi, p.offset, p.ty));
        Source::Prop { pi, mul, add }
    };
    let missing = |slot: usize| err(format!("vertex property '{}' is missing", slot_name(slot)));

    for s in 0..3 {
        let pi = fixed[s].ok_or_else(|| missing(s))?;
        float(pi)?;
        slots[s] = use_prop(pi, 1.0, 0.0, &mut props);
    }
    for (k, &pi) in rest.iter().enumerate() {
        float(pi)?;
        slots[SLOT_REST + k] = use_prop(pi, 1.0, 0.0, &mut props);
    }
    // Colour: f_dc, else red green blue.
    if dc_present == 3 {
        for s in SLOT_DC..SLOT_DC + 3 {
            let pi = fixed[s].expect("counted");
            float(pi)?;
            slots[s] = use_prop(pi, 1.0, 0.0, &mut props);
        }
    } else {
        let rgb = [find("red"), find("green"), find("blue")];
        let [Some(r), Some(g), Some(b)] = rgb else {
            let first = (SLOT_DC..SLOT_DC + 3)
                .find(|&s| fixed[s].is_none())
                .expect("missing");
            return Err(err(format!(
                "vertex property '{}' is missing (and there is no 'red green blue' colour to take instead)",
                slot_name(first)
            )));
        };
        let ty = header.properties[r].ty;
        for (k, pi) in [r, g, b].into_iter().enumerate() {
            let p = &header.properties[pi];
            if p.ty != ty {
                return Err(err(format!(
                    "colour properties 'red green blue' have different types ({} and {})",
                    ty.name(),
                    p.ty.name()
                )));
            }
            let full = match p.ty {
                ScalarType::U8 => 255.0,
                ScalarType::U16 => 65535.0,
                ScalarType::F32 | ScalarType::F64 => 1.0,
                t => {
                    return Err(err(format!(
                    "colour property '{}' has type {}; colours are uchar, ushort, float or double",
                    p.name,
                    t.name()
                )))
                }
            };
            // DC = (c/full − 0.5)/C0.
            slots[SLOT_DC + k] = use_prop(pi, 1.0 / (full * C0), -0.5 / C0, &mut props);
        }
        notes.push(format!(
            "colour from 'red green blue' ({}), as the SH DC term (c - 0.5)/C0",
            ty.name()
        ));
    }
    let kind = if scales == 3 {
        GaussianKind::Gaussians3D
    } else if scales == 2 && fixed[SLOT_SCALE + 2].is_none() {
        GaussianKind::Surfels2D
    } else if scales == 0 && rots == 0 {
        GaussianKind::Points
    } else {
        let first = (SLOT_SCALE..SLOT_SCALE + 3)
            .find(|&s| fixed[s].is_none())
            .expect("fewer than three scales");
        return Err(missing(first));
    };
    match kind {
        GaussianKind::Points => {
            // Scales are filled after reading (nearest neighbours); identity rotation.
            slots[SLOT_ROT] = Source::Const(1.0);
            notes.push(format!(
                "no scale_*/rot_*: points given 3DGS's initial Gaussians (isotropic scale from \
                 the 3 nearest neighbours, identity rotation){}",
                if fixed[SLOT_OPACITY].is_none() {
                    format!(", opacity {POINT_OPACITY}")
                } else {
                    String::new()
                }
            ));
        }
        _ => {
            let n_scales = if kind == GaussianKind::Surfels2D {
                2
            } else {
                3
            };
            for s in SLOT_SCALE..SLOT_SCALE + n_scales {
                let pi = fixed[s].expect("counted");
                float(pi)?;
                slots[s] = use_prop(pi, 1.0, 0.0, &mut props);
            }
            if kind == GaussianKind::Surfels2D {
                slots[SLOT_SCALE + 2] = Source::ThinAxis;
            }
            for s in SLOT_ROT..SLOT_ROT + 4 {
                let pi = fixed[s].ok_or_else(|| missing(s))?;
                float(pi)?;
                slots[s] = use_prop(pi, 1.0, 0.0, &mut props);
            }
        }
    }
    match fixed[SLOT_OPACITY] {
        Some(pi) => {
            float(pi)?;
            slots[SLOT_OPACITY] = use_prop(pi, 1.0, 0.0, &mut props);
        }
        None if kind == GaussianKind::Points => {
            slots[SLOT_OPACITY] = Source::Const(crate::gaussians::logit(POINT_OPACITY));
        }
        None => return Err(missing(SLOT_OPACITY)),
    }
    if let Some(pi) = filter_3d {
        if kind != GaussianKind::Gaussians3D {
            return Err(err(format!(
                "'filter_3D' (Mip-Splatting's 3D filter) on {}: the filter is defined for 3D Gaussians",
                kind.name()
            )));
        }
        float(pi)?;
        let p = &header.properties[pi];
        props.push((pi, p.offset, p.ty));
        notes.push(
            "Mip-Splatting's filter_3D folded into the scales and opacities, as its loader does"
                .into(),
        );
    }
    Ok(Some(Variant {
        kind,
        slots,
        filter_3d,
        props,
        notes,
    }))
}
