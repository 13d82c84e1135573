//! Front-to-back compositing of recorded hits with per-vertex RGBA, and its analytic
//! gradient.
//!
//! A hit on triangle (v0, v1, v2) at barycentrics b has the colour and opacity the mesh
//! tracer shades (`raytrace::model::Mesh::shade`, `MeshTracer::trace`): `x = Σ b_k·L_k`
//! (linear vertex colours) clamped to [0, 1] and sRGB-encoded per channel, `c = srgb(x)`;
//! `α = clamp(f·Σ b_k·A_k, 0, 1)` with `f` the material and texture alpha at the hit. The
//! pixel is `C = Σ c_i·α_i·T_i + bg·T_n` with `T_0 = 1`, `T_{i+1} = T_i·(1 − α_i)`.
//!
//! Backward pass from the back: with `R_i` the colour behind hit i seen through nothing
//! (`R_{n−1} = bg`, `R_{i−1} = c_i·α_i + (1 − α_i)·R_i`), `∂C/∂c_i = α_i·T_i` and
//! `∂C/∂α_i = T_i·(c_i − R_i)`, which needs no division by `1 − α_i` (stable at α = 1).

use glam::Vec3;
use rayon::prelude::*;
use splatbridge_convert::mesh::linear_to_srgb;

/// One recorded hit, resolved to global vertex indices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rec {
    pub v: [u32; 3],
    pub bary: [f32; 3],
    /// Material × texture alpha at the hit.
    pub fa: f32,
}

/// Hit lists of one view, row-major pixels.
#[derive(Clone, Debug, Default)]
pub struct ViewHits {
    pub width: u32,
    pub height: u32,
    pub offsets: Vec<u64>,
    pub hits: Vec<Rec>,
}

impl ViewHits {
    pub fn bytes(&self) -> u64 {
        (self.hits.len() * std::mem::size_of::<Rec>() + self.offsets.len() * 8) as u64
    }
}

/// The derivative of the sRGB encoding at linear value x (x in [0, 1]).
#[inline]
pub fn srgb_slope(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92
    } else {
        1.055 / 2.4 * x.powf(1.0 / 2.4 - 1.0)
    }
}

/// How the hit colours are encoded for blending.
#[derive(Clone, Copy, Debug)]
pub struct Shading {
    /// Vertex colours are linear and each hit is sRGB-encoded before blending.
    pub encode: bool,
    pub background: Vec3,
}

/// Colour (display), its slope per channel (∂c/∂x, 0 where clamped) and α of one hit, with
/// the unclamped α's slope `∂α/∂(Σ b·A)` (0 where clamped).
#[inline]
fn shade(h: &Rec, params: &[[f32; 4]], s: &Shading) -> (Vec3, Vec3, f32, f32) {
    let mut x = [0.0f32; 4];
    for (&v, &b) in h.v.iter().zip(&h.bary) {
        for (xc, pc) in x.iter_mut().zip(&params[v as usize]) {
            *xc += b * pc;
        }
    }
    let mut c = [0.0f32; 3];
    let mut dc = [0.0f32; 3];
    for ((&v, cc), dd) in x.iter().zip(c.iter_mut()).zip(dc.iter_mut()) {
        let inside = (0.0..=1.0).contains(&v);
        let v = v.clamp(0.0, 1.0);
        if s.encode {
            *cc = linear_to_srgb(v);
            // The slope from the encoded value: above the linear toe,
            // d/dx (1.055·x^(1/2.4) − 0.055) = (c + 0.055) / (2.4·x), without a second powf.
            *dd = if !inside {
                0.0
            } else if v <= 0.003_130_8 {
                12.92
            } else {
                (*cc + 0.055) / (2.4 * v)
            };
        } else {
            *cc = v;
            *dd = if inside { 1.0 } else { 0.0 };
        }
    }
    let (c, dc) = (Vec3::from_array(c), Vec3::from_array(dc));
    let a = h.fa * x[3];
    let da = if (0.0..=1.0).contains(&a) { h.fa } else { 0.0 };
    (c, dc, a.clamp(0.0, 1.0), da)
}

/// The pixel colour of one hit list.
pub fn pixel(hits: &[Rec], params: &[[f32; 4]], s: &Shading) -> Vec3 {
    let mut acc = Vec3::ZERO;
    let mut t = 1.0f32;
    for h in hits {
        let (c, _, a, _) = shade(h, params, s);
        acc += c * (a * t);
        t *= 1.0 - a;
    }
    acc + s.background * t
}

/// Per hit of one pixel, the loss gradient with respect to its interpolated linear RGB
/// (through the clamp and encoding) and its interpolated vertex alpha `Σ b·A`, given
/// `g = ∂L/∂C`; `tr` is scratch.
fn pixel_backward(
    hits: &[Rec],
    params: &[[f32; 4]],
    s: &Shading,
    g: Vec3,
    shaded: &mut Vec<(Vec3, Vec3, f32, f32, f32)>,
    out: &mut Vec<[f32; 4]>,
) {
    shaded.clear();
    let mut t = 1.0f32;
    for h in hits {
        let (c, dc, a, da) = shade(h, params, s);
        shaded.push((c, dc, a, da, t));
        t *= 1.0 - a;
    }
    let base = out.len();
    out.resize(base + hits.len(), [0.0; 4]);
    let mut behind = s.background;
    for (i, &(c, dc, a, da, ti)) in shaded.iter().enumerate().rev() {
        let dcol = g * (a * ti) * dc;
        let dalpha = ti * g.dot(c - behind) * da;
        out[base + i] = [dcol.x, dcol.y, dcol.z, dalpha];
        behind = c * a + behind * (1.0 - a);
    }
}

/// The image of a view (interleaved RGB).
pub fn render(view: &ViewHits, params: &[[f32; 4]], s: &Shading) -> Vec<f32> {
    let w = view.width as usize;
    let h = view.height as usize;
    let mut img = vec![0.0f32; 3 * w * h];
    img.par_chunks_mut(3 * w.max(1))
        .enumerate()
        .for_each(|(row, out)| {
            for col in 0..w {
                let p = row * w + col;
                let hits = &view.hits[view.offsets[p] as usize..view.offsets[p + 1] as usize];
                let c = pixel(hits, params, s);
                out[3 * col..3 * col + 3].copy_from_slice(&c.to_array());
            }
        });
    img
}

/// Per hit of a view, in hit order, the loss gradient with respect to its interpolated linear
/// RGB and vertex alpha, given `dimg = ∂L/∂image` (interleaved RGB). Rows are differentiated
/// in parallel and joined in row order.
pub fn hit_gradients(
    view: &ViewHits,
    params: &[[f32; 4]],
    s: &Shading,
    dimg: &[f32],
) -> Vec<[f32; 4]> {
    let w = view.width as usize;
    let h = view.height as usize;
    let rows: Vec<Vec<[f32; 4]>> = (0..h)
        .into_par_iter()
        .map(|row| {
            let mut out = Vec::new();
            let mut tr = Vec::new();
            for col in 0..w {
                let p = row * w + col;
                let hits = &view.hits[view.offsets[p] as usize..view.offsets[p + 1] as usize];
                let g = Vec3::new(dimg[3 * p], dimg[3 * p + 1], dimg[3 * p + 2]);
                pixel_backward(hits, params, s, g, &mut tr, &mut out);
            }
            out
        })
        .collect();
    rows.concat()
}

/// Add the gradient of the loss with respect to every vertex's RGBA to `grad`, given the
/// per-hit gradients of [`hit_gradients`]. The scatter to vertices runs in hit order, so the
/// sum does not depend on the thread count.
pub fn scatter(view: &ViewHits, dh: &[[f32; 4]], grad: &mut [[f32; 4]]) {
    for (hit, d) in view.hits.iter().zip(dh) {
        for (&v, &b) in hit.v.iter().zip(&hit.bary) {
            for (gc, dc) in grad[v as usize].iter_mut().zip(d) {
                *gc += b * dc;
            }
        }
    }
}

/// Add the gradient of the loss with respect to every vertex's RGBA to `grad`, given
/// `dimg = ∂L/∂image` (interleaved RGB).
pub fn backward(
    view: &ViewHits,
    params: &[[f32; 4]],
    s: &Shading,
    dimg: &[f32],
    grad: &mut [[f32; 4]],
) {
    let dh = hit_gradients(view, params, s, dimg);
    scatter(view, &dh, grad);
}
