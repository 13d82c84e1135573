//! Per-Gaussian parameters: the vertices of one Gaussian's fan (or quad) share a colour
//! shift and an opacity scale, so the fit moves a Gaussian as a whole and keeps the
//! profile's falloff across it.
//!
//! Vertex v of Gaussian g, with its undistilled linear RGB `c₀` and alpha `a₀`, takes
//! `rgb = clamp(c₀ + d_g, 0, 1)` and `α = clamp(s_g·a₀, 0, 1)`. Four numbers per Gaussian
//! instead of four per vertex (the `meshsplats` profile has about 17 vertices per Gaussian,
//! `texture` 4), which is what keeps the fit determined when the vertices' parameters
//! outnumber the target pixels' values (see docs/distill.md). The gradient is the chain
//! rule through the clamp: `∂L/∂d_g = Σ_v ∂L/∂rgb_v` over the vertices not clamped,
//! `∂L/∂s_g = Σ_v a₀_v·∂L/∂α_v`.

use std::collections::HashMap;

/// Which parameters the fit moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamMode {
    /// Every vertex's RGBA (the default: see docs/distill.md for the comparison).
    Vertex,
    /// A colour shift and an opacity scale per Gaussian.
    Gaussian,
    /// Per Gaussian where the vertices' parameters outnumber the fitting pixels' values,
    /// per vertex otherwise.
    Auto,
}

impl std::fmt::Display for ParamMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ParamMode::Vertex => "vertex",
            ParamMode::Gaussian => "gaussian",
            ParamMode::Auto => "auto",
        })
    }
}

/// The per-Gaussian parametrisation of a vertex array.
#[derive(Clone, Debug)]
pub struct Tied {
    /// The group (Gaussian of a mesh) of every vertex.
    pub group: Vec<u32>,
    /// Undistilled vertex RGBA.
    pub init: Vec<[f32; 4]>,
    /// Per group: colour shift (RGB) and opacity scale.
    pub theta: Vec<[f32; 4]>,
}

/// Upper bound of the opacity scale: beyond it every vertex with a₀ ≥ 1/64 is at α = 1
/// already (the fan's rim vertices, near 0, stay transparent whatever the scale).
pub const MAX_SCALE: f32 = 64.0;

impl Tied {
    /// Group vertices by `(mesh, Gaussian id)`; `gaussian[v]` is `(mesh, id)` of vertex v.
    pub fn new(init: Vec<[f32; 4]>, gaussian: impl Iterator<Item = (u32, u32)>) -> Self {
        let mut ids: HashMap<(u32, u32), u32> = HashMap::new();
        let group: Vec<u32> = gaussian
            .map(|k| {
                let n = ids.len() as u32;
                *ids.entry(k).or_insert(n)
            })
            .collect();
        let theta = vec![[0.0, 0.0, 0.0, 1.0]; ids.len()];
        Tied { group, init, theta }
    }

    pub fn groups(&self) -> usize {
        self.theta.len()
    }

    /// The vertex RGBA of the current `theta`.
    pub fn expand(&self, out: &mut [[f32; 4]]) {
        for ((o, c0), &g) in out.iter_mut().zip(&self.init).zip(&self.group) {
            let t = self.theta[g as usize];
            *o = [
                (c0[0] + t[0]).clamp(0.0, 1.0),
                (c0[1] + t[1]).clamp(0.0, 1.0),
                (c0[2] + t[2]).clamp(0.0, 1.0),
                (c0[3] * t[3]).clamp(0.0, 1.0),
            ];
        }
    }

    /// The gradient with respect to `theta` of a loss whose vertex gradient is `vgrad`.
    pub fn reduce(&self, vgrad: &[[f32; 4]]) -> Vec<[f32; 4]> {
        let mut out = vec![[0.0f32; 4]; self.theta.len()];
        for ((g, c0), &grp) in vgrad.iter().zip(&self.init).zip(&self.group) {
            let t = self.theta[grp as usize];
            let o = &mut out[grp as usize];
            for c in 0..3 {
                let x = c0[c] + t[c];
                if (0.0..=1.0).contains(&x) {
                    o[c] += g[c];
                }
            }
            if (0.0..=1.0).contains(&(c0[3] * t[3])) {
                o[3] += g[3] * c0[3];
            }
        }
        out
    }

    /// Keep `theta` where it means something: shifts within [−1, 1], scales within
    /// [0, MAX_SCALE].
    pub fn project(t: &mut [f32; 4]) {
        for x in &mut t[..3] {
            *x = x.clamp(-1.0, 1.0);
        }
        t[3] = t[3].clamp(0.0, MAX_SCALE);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_by_mesh_and_gaussian() {
        let keys = [(0, 5), (0, 5), (1, 5), (0, 7), (0, 5)];
        let t = Tied::new(vec![[0.5; 4]; 5], keys.into_iter());
        assert_eq!(t.group, vec![0, 0, 1, 2, 0]);
        assert_eq!(t.groups(), 3);
    }

    #[test]
    fn reduce_is_the_chain_rule_of_expand() {
        // A linear functional of the vertex values, differentiated numerically through
        // expand, against reduce of its (constant) vertex gradient.
        let init = vec![
            [0.2, 0.9, 0.5, 0.3],
            [0.4, 0.1, 0.95, 0.8],
            [0.6, 0.5, 0.5, 0.0],
        ];
        let mut t = Tied::new(init, [(0, 0), (0, 0), (0, 1)].into_iter());
        t.theta = vec![[0.05, 0.05, -0.02, 1.1], [0.1, -0.2, 0.3, 2.0]];
        let w = [
            [0.3, -1.0, 0.7, 2.0],
            [-0.4, 0.5, 1.5, -0.6],
            [0.9, 0.2, -0.3, 1.0],
        ];
        let f = |t: &Tied| {
            let mut v = vec![[0.0; 4]; 3];
            t.expand(&mut v);
            v.iter()
                .zip(&w)
                .map(|(v, w)| (0..4).map(|c| (v[c] * w[c]) as f64).sum::<f64>())
                .sum::<f64>()
        };
        let g = t.reduce(&w);
        // 1e-3 steps keep every perturbed value on the same side of the clamps (the nearest
        // is 0.9 + 0.05 = 0.95, 0.05 from 1); f32 rounding of values near 1 bounds the error
        // of the central difference at about 1e-7 / 1e-3 = 1e-4.
        let h = 1e-3f32;
        for gi in 0..2 {
            for c in 0..4 {
                let mut p = t.clone();
                p.theta[gi][c] += h;
                let mut m = t.clone();
                m.theta[gi][c] -= h;
                let fd = (f(&p) - f(&m)) / (2.0 * h as f64);
                assert!(
                    (fd - g[gi][c] as f64).abs() < 1e-3,
                    "group {gi} lane {c}: {fd} vs {}",
                    g[gi][c]
                );
            }
        }
        // Vertex 2's transparent alpha (a₀ = 0) contributes nothing to its group's scale.
        assert_eq!(g[1][3], 0.0);
    }
}
