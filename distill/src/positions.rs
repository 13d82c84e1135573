//! Fitting vertex positions (`--distill-positions`, off by default), beside colour and
//! opacity.
//!
//! A hit on triangle (p₀, p₁, p₂) at barycentrics b solves `o + t·d = Σ bₖ·pₖ`, i.e.
//! `M·(t, b₁, b₂)ᵀ = o − p₀` with `M = [−d | p₁ − p₀ | p₂ − p₀]`. Differentiating,
//! `∂(t, b₁, b₂)/∂pₖ = −bₖ·M⁻¹` for every vertex k (the hit point moves with the vertex in
//! proportion to its weight), and `b₀ = 1 − b₁ − b₂`. With `Gⱼ = ∂L/∂bⱼ = ∂L/∂x · Pⱼ` (x the
//! interpolated RGBA, Pⱼ vertex j's parameters), `∂L/∂pₖ = −bₖ·((G₁ − G₀)·r₁ + (G₂ − G₀)·r₂)`
//! with r₁, r₂ the second and third rows of M⁻¹. This is the gradient of the image with the
//! hit lists fixed: which triangles a ray hits, and their order, change in steps as vertices
//! move, and those steps have no gradient (as in rasterisers without edge sampling). So every
//! step re-traces the views it uses with the moved mesh (a BVH rebuild per step: the cost of
//! the option), and the gradient is checked against finite differences of the re-traced loss.
//!
//! Each vertex moves in units of its Gaussian's size (the mean distance of the Gaussian's
//! vertices from their centre), so one step size fits Gaussians of every scale. The
//! texture profile is refused: its opacity comes from a texture sampled at the hit's
//! coordinates, which this gradient does not carry.

use glam::{DAffine3, DMat3, DVec3};
use rayon::prelude::*;
use splatbridge_raytrace::model::TriScene;
use splatbridge_raytrace::render::camera_ray;
use splatbridge_scene::Camera;

use super::composite::ViewHits;

/// The fitted positions: per vertex (in the tracer's global vertex order) its converted
/// position, its offset in units of its Gaussian's size (the parameter Adam moves; the fourth
/// lane unused) and that size; Adam's moments of the offsets and the last gradient ∂L/∂p.
#[derive(Clone, Debug)]
pub struct Positions {
    pub start: Vec<[f32; 3]>,
    pub offset: Vec<[f32; 4]>,
    pub size: Vec<f32>,
    pub(super) m: Vec<[f32; 4]>,
    pub(super) v: Vec<[f32; 4]>,
    pub(super) grad: Vec<[f32; 4]>,
}

impl Positions {
    /// The positions of `scene`'s vertices as converted, each sized by its Gaussian (the
    /// `_GAUSSIAN_ID` the distiller derives per vertex from the triangles).
    pub fn new(scene: &TriScene) -> Self {
        let per_vertex = super::vertex_gaussians(scene);
        let mut start = Vec::new();
        let mut size = Vec::new();
        for (m, ids) in scene.meshes.iter().zip(&per_vertex) {
            let (index, centres) = super::mesh::gaussian_centres(m, ids);
            // Per Gaussian: the summed distance of its vertices from its centre, and their count.
            let mut spread = vec![(0.0f64, 0u32); centres.len()];
            for (p, g) in m.positions.iter().zip(ids) {
                let k = index[g];
                spread[k].0 += (p.as_dvec3() - centres[k]).length();
                spread[k].1 += 1;
            }
            for (p, g) in m.positions.iter().zip(ids) {
                let (d, n) = spread[index[g]];
                let r = d / n as f64;
                start.push(p.to_array());
                // A Gaussian of size 0 (all its vertices at one point) does not move, nor one
                // whose size is not finite.
                size.push(if r.is_finite() { r as f32 } else { 0.0 });
            }
        }
        let zero = vec![[0.0; 4]; start.len()];
        Positions {
            start,
            offset: zero.clone(),
            size,
            m: zero.clone(),
            v: zero.clone(),
            grad: zero,
        }
    }

    /// Vertex `i`'s current position.
    #[inline]
    pub fn at(&self, i: usize) -> [f32; 3] {
        let (p, o, s) = (self.start[i], self.offset[i], self.size[i]);
        [p[0] + s * o[0], p[1] + s * o[1], p[2] + s * o[2]]
    }

    /// Write the current positions into `scene` (`base`: first global vertex of each mesh).
    pub fn write(&self, scene: &mut TriScene, base: &[usize]) {
        for (mi, m) in scene.meshes.iter_mut().enumerate() {
            let b = base[mi];
            for (j, p) in m.positions.iter_mut().enumerate() {
                *p = glam::Vec3::from_array(self.at(b + j));
            }
        }
    }
}

/// The gradient of the loss with respect to a hit's three vertex positions, given
/// `g[j] = ∂L/∂bⱼ`, for a ray of direction `d` in the triangle's frame (its origin does not
/// enter: M holds only directions); None where the ray runs along the triangle's plane (M
/// singular: no finite derivative).
pub fn hit_position_gradient(
    d: DVec3,
    p: [DVec3; 3],
    bary: [f32; 3],
    g: [f64; 3],
) -> Option<[DVec3; 3]> {
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let m = DMat3::from_cols(-d, e1, e2);
    let det = m.determinant();
    let scale = d.length() * e1.length() * e2.length();
    // |det| is scale·|sin| of the ray's angle to the plane (times the triangle's shape
    // factor); below 1e-9 of the scale the inverse is dominated by rounding.
    if !(det.is_finite() && det.abs() > 1e-9 * scale) {
        return None;
    }
    let inv = m.inverse();
    let r1 = inv.row(1);
    let r2 = inv.row(2);
    let w = r1 * (g[1] - g[0]) + r2 * (g[2] - g[0]);
    Some([0, 1, 2].map(|k| -w * bary[k] as f64))
}

/// What the position gradient of one view needs besides its hits: the camera and each
/// mesh's world-to-local transform at the view's time (None: not drawn then).
pub struct ViewRays<'a> {
    pub camera: &'a Camera,
    pub to_local: Vec<Option<DAffine3>>,
    pub scene: &'a TriScene,
    /// First global vertex of each mesh.
    pub base: &'a [usize],
}

/// Add the loss gradient with respect to every vertex position (fourth lane unused) to
/// `grad`, given the view's per-hit gradients `dh` ([`super::composite::hit_gradients`]) and
/// the parameters the hits were composited with. Rows in parallel, the scatter in hit order.
pub fn gradient(
    view: &ViewHits,
    dh: &[[f32; 4]],
    params: &[[f32; 4]],
    rays: &ViewRays<'_>,
    grad: &mut [[f32; 4]],
) {
    let w = view.width as usize;
    let h = view.height as usize;
    let rows: Vec<Vec<(u32, [f32; 3])>> = (0..h)
        .into_par_iter()
        .map(|row| {
            let mut out = Vec::new();
            for col in 0..w {
                let px = row * w + col;
                let (a, b) = (view.offsets[px] as usize, view.offsets[px + 1] as usize);
                if a == b {
                    continue;
                }
                let (_, d) = camera_ray(rays.camera, col as f64 + 0.5, row as f64 + 0.5);
                for (hit, dhh) in view.hits[a..b].iter().zip(&dh[a..b]) {
                    let hv = view.verts(hit);
                    let v0 = hv[0] as usize;
                    let mi = rays.base.partition_point(|&s| s <= v0).saturating_sub(1);
                    let Some(t) = rays.to_local.get(mi).copied().flatten() else {
                        continue;
                    };
                    let mesh = &rays.scene.meshes[mi];
                    let local = |v: u32| mesh.positions[v as usize - rays.base[mi]].as_dvec3();
                    let p = hv.map(local);
                    let g = hv.map(|v| {
                        let q = params[v as usize];
                        (0..4).map(|c| dhh[c] as f64 * q[c] as f64).sum::<f64>()
                    });
                    if let Some(gp) = hit_position_gradient(t.transform_vector3(d), p, hit.bary, g)
                    {
                        for (k, &v) in hv.iter().enumerate() {
                            out.push((v, gp[k].as_vec3().to_array()));
                        }
                    }
                }
            }
            out
        })
        .collect();
    for row in rows {
        for (v, g) in row {
            let d = &mut grad[v as usize];
            d[0] += g[0];
            d[1] += g[1];
            d[2] += g[2];
        }
    }
}
