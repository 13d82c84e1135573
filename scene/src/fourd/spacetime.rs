//! SpacetimeGaussians (Li et al., CVPR 2024) "lite" models: each Gaussian has a polynomial
//! trajectory, a rotation velocity and a temporal radial basis opacity, all about its own
//! centre in time. Read from the PLY the authors' `GaussianModel.save_ply` writes
//! (oppo-us-research/SpacetimeGaussians, `thirdparty/gaussian_splatting/scene/ourslite.py`,
//! `construct_list_of_attributes`):
//!
//! `x y z trbf_center trbf_scale nx ny nz motion_0..8 f_dc_0..2 opacity scale_0..2 rot_0..3
//! omega_0..3`, every property `float`.
//!
//! Evaluation at time `t` follows `renderer/__init__.py::train_ours_lite` with the model's
//! accessors in `ourslite.py`, operation for operation in f32:
//!
//! - `dt = t − trbf_center`
//! - mean: `xyz + motion[0:3]·dt + motion[3:6]·dt·dt + motion[6:9]·dt·dt·dt`
//! - rotation: `get_rotation(dt) = normalize(rot + dt·omega)` (`F.normalize`: divide by
//!   `max(‖q‖, 1e-12)`), w,x,y,z as in 3DGS
//! - opacity: `sigmoid(opacity) · trbfunction(dt / exp(trbf_scale))` with
//!   `helper_train.py::trbfunction(x) = exp(−x²)`
//! - scale: `exp(scale)`, constant in time
//! - colour: `get_features(dt) = f_dc`, passed to the rasteriser as `colors_precomp`: the
//!   three values *are* the RGB colour (no SH, no activation); stored here as the SH DC
//!   coefficient that gives that colour.
//!
//! Time is the training timestamp, `(frame − start)/duration`, so a model covers [0, 1).
//!
//! The "full" variant stores nine feature channels (`f_dc_0..8`) that only the authors' MLP
//! (`rgbdecoder`) turns into colour; it is refused by name rather than shown in false colours.
//!
//! The same model in splaTV's packed form is read by [`super::splatv`]; its viewer cuts
//! Gaussians whose temporal opacity is below 0.02 ([`SpacetimeModel::cutoff`]).

use std::io::{BufReader, Read};
use std::path::Path;

use glam::{Quat, Vec3};

use crate::error::{Result, SceneError};
use crate::gaussians::{logit, sigmoid};
use crate::ply::header::{parse_header, Encoding, ScalarType};
use crate::GaussianCloud;

/// Per-Gaussian parameters of a spacetime model, as stored (opacity activated, scales as
/// logarithms).
#[derive(Clone, Debug, Default)]
pub struct SpacetimeModel {
    pub means: Vec<Vec3>,
    /// Polynomial coefficients of `dt`, `dt²`, `dt³` (`motion_0..2`, `3..5`, `6..8`).
    pub motion: Vec<[Vec3; 3]>,
    /// Raw rotation w,x,y,z at the centre time.
    pub rotations: Vec<Quat>,
    /// Rotation velocity w,x,y,z (`omega_0..3`), added as `dt·omega` before normalising.
    pub omegas: Vec<Quat>,
    pub trbf_center: Vec<f32>,
    /// The temporal RBF's width `exp(trbf_scale)` (splaTV stores it activated).
    pub trbf_width: Vec<f32>,
    pub log_scales: Vec<Vec3>,
    /// Base opacity in [0, 1] (`sigmoid(opacity)`).
    pub opacity: Vec<f32>,
    /// Rendered RGB colour.
    pub colors: Vec<Vec3>,
    /// Temporal opacity below which a Gaussian is not drawn (splaTV: 0.02); `None` draws all.
    pub cutoff: Option<f32>,
}

impl SpacetimeModel {
    pub fn len(&self) -> usize {
        self.means.len()
    }

    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    /// The Gaussians at time `t` (see the module docs for the formulas).
    pub fn sample(&self, t: f32) -> GaussianCloud {
        let n = self.len();
        let mut c = GaussianCloud::with_capacity(0, n);
        for i in 0..n {
            let dt = t - self.trbf_center[i];
            let [m1, m2, m3] = self.motion[i];
            let mean = self.means[i] + m1 * dt + m2 * dt * dt + m3 * dt * dt * dt;
            let q = self.rotations[i] + self.omegas[i] * dt;
            let rot = Quat::from_vec4(glam::Vec4::from(q) / q.length().max(1e-12));
            let x = dt / self.trbf_width[i];
            let mut temporal = (-(x * x)).exp();
            // 0/0 (a zero-width RBF at its own centre) has no value in the reference either;
            // such a Gaussian is hidden rather than given a NaN opacity.
            if temporal.is_nan() || self.cutoff.is_some_and(|c| temporal < c) {
                temporal = 0.0;
            }
            let alpha = self.opacity[i] * temporal;
            c.means.push(mean);
            c.log_scales.push(self.log_scales[i]);
            c.rotations.push(rot);
            c.opacity_logits.push(logit(alpha));
            c.sh.push(super::rgb_to_dc(self.colors[i]));
        }
        c
    }
}

/// Does a PLY header (text of the first bytes) declare a spacetime model? `Some(false)` for the
/// lite layout, `Some(true)` for the full one (nine feature channels), `None` for neither.
pub fn spacetime_header(head: &[u8]) -> Option<bool> {
    let end = find(head, b"end_header").unwrap_or(head.len());
    let text = &head[..end];
    let has = |name: &str| {
        text.split(|&b| b == b'\n').any(|line| {
            let line = line.strip_suffix(b"\r").unwrap_or(line);
            line.starts_with(b"property ")
                && line.split(|&b| b == b' ').next_back() == Some(name.as_bytes())
        })
    };
    if !(has("trbf_center") && has("trbf_scale")) {
        return None;
    }
    Some(has("f_dc_8") || (!has("omega_0") && has("f_dc_3")))
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Properties of the lite layout, in the order the values are gathered.
const NAMES: [&str; USED] = [
    "x",
    "y",
    "z",
    "trbf_center",
    "trbf_scale",
    "motion_0",
    "motion_1",
    "motion_2",
    "motion_3",
    "motion_4",
    "motion_5",
    "motion_6",
    "motion_7",
    "motion_8",
    "f_dc_0",
    "f_dc_1",
    "f_dc_2",
    "opacity",
    "scale_0",
    "scale_1",
    "scale_2",
    "rot_0",
    "rot_1",
    "rot_2",
    "rot_3",
    "omega_0",
    "omega_1",
    "omega_2",
    "omega_3",
];
const USED: usize = 29;

/// Read a SpacetimeGaussians lite PLY (binary, little- or big-endian; `float` or `double`
/// properties). The vertex count is checked against the file's length before anything is
/// allocated.
pub fn read_spacetime_ply(path: &Path) -> Result<SpacetimeModel> {
    let err = |what: String| SceneError::format(path, what);
    let (file, file_len) = crate::input::open_regular(path)?;
    let mut r = BufReader::with_capacity(64 << 10, file);
    let header = parse_header(&mut r, path)?;
    let prop = |name: &str| header.properties.iter().find(|p| p.name == name);
    if prop("f_dc_8").is_some() || (prop("f_dc_3").is_some() && prop("omega_0").is_none()) {
        return Err(err(
            "SpacetimeGaussians full model (nine feature channels f_dc_0..8 that only the \
             authors' MLP decodes into colour) is not supported; export the lite model \
             (x y z trbf_center trbf_scale motion_0..8 f_dc_0..2 opacity scale_0..2 rot_0..3 \
             omega_0..3)"
                .into(),
        ));
    }
    let le = match header.encoding {
        Encoding::BinaryLe => true,
        Encoding::BinaryBe => false,
        Encoding::Ascii => {
            return Err(err(
                "ASCII SpacetimeGaussians PLY is not supported (the authors write binary)".into(),
            ))
        }
    };
    let mut slots = Vec::with_capacity(USED);
    for name in &NAMES {
        let p = prop(name).ok_or_else(|| {
            err(format!(
                "SpacetimeGaussians lite PLY has no vertex property '{name}'"
            ))
        })?;
        if !matches!(p.ty, ScalarType::F32 | ScalarType::F64) {
            return Err(err(format!(
                "vertex property '{name}' is {}, expected float or double",
                p.ty.name()
            )));
        }
        slots.push((p.offset, p.ty));
    }
    let stride = header.stride as u64;
    let count = header.vertex_count;
    let data_len = file_len.saturating_sub(header.len);
    let need = count.checked_mul(stride);
    if need.is_none_or(|b| b > data_len) {
        return Err(err(format!(
            "header declares {count} vertices of {stride} bytes but only {data_len} bytes follow \
             the header (truncated file or wrong count)"
        )));
    }
    let n = count as usize;
    let mut m = SpacetimeModel {
        means: Vec::with_capacity(n),
        motion: Vec::with_capacity(n),
        rotations: Vec::with_capacity(n),
        omegas: Vec::with_capacity(n),
        trbf_center: Vec::with_capacity(n),
        trbf_width: Vec::with_capacity(n),
        log_scales: Vec::with_capacity(n),
        opacity: Vec::with_capacity(n),
        colors: Vec::with_capacity(n),
        cutoff: None,
    };
    let stride = header.stride;
    let per_chunk = ((1usize << 20) / stride.max(1)).clamp(1, n.max(1));
    let mut buf = vec![0u8; per_chunk * stride];
    let mut v = [0f32; USED];
    let mut done = 0;
    while done < n {
        let k = per_chunk.min(n - done);
        let bytes = &mut buf[..k * stride];
        r.read_exact(bytes).map_err(|e| {
            err(format!(
                "vertex data ends early (reading vertices {done}..{}): {e}",
                done + k
            ))
        })?;
        for rec in bytes.chunks_exact(stride) {
            for (dst, &(off, ty)) in v.iter_mut().zip(&slots) {
                *dst = scalar(&rec[off..], ty, le);
            }
            let i = m.means.len();
            push_lite(&mut m, &v, path, i)?;
        }
        done += k;
    }
    Ok(m)
}

fn scalar(b: &[u8], ty: ScalarType, le: bool) -> f32 {
    match (ty, le) {
        (ScalarType::F64, true) => f64::from_le_bytes(b[..8].try_into().unwrap()) as f32,
        (ScalarType::F64, false) => f64::from_be_bytes(b[..8].try_into().unwrap()) as f32,
        (_, true) => f32::from_le_bytes(b[..4].try_into().unwrap()),
        (_, false) => f32::from_be_bytes(b[..4].try_into().unwrap()),
    }
}

/// Append one Gaussian from the values in [`NAMES`] order. Non-finite values are an error
/// naming the vertex (a model with NaN parameters has no defined position at any time).
fn push_lite(m: &mut SpacetimeModel, v: &[f32; USED], path: &Path, i: usize) -> Result<()> {
    if let Some(k) = v.iter().position(|x| !x.is_finite()) {
        return Err(SceneError::format(
            path,
            format!("vertex {i}: '{}' is {} (not finite)", NAMES[k], v[k]),
        ));
    }
    let v3 = |k: usize| Vec3::new(v[k], v[k + 1], v[k + 2]);
    m.means.push(v3(0));
    m.trbf_center.push(v[3]);
    m.trbf_width.push(v[4].exp());
    m.motion.push([v3(5), v3(8), v3(11)]);
    m.colors.push(v3(14));
    m.opacity.push(sigmoid(v[17]));
    m.log_scales.push(v3(18));
    m.rotations
        .push(Quat::from_xyzw(v[22], v[23], v[24], v[21]));
    m.omegas.push(Quat::from_xyzw(v[26], v[27], v[28], v[25]));
    Ok(())
}
