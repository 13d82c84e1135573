//! Per-Gaussian meshing profiles: the 2-D layout of one fan in σ units (positions, vertex
//! alphas, texture coordinates, triangles), before it is placed on a Gaussian's axes.
//!
//! * `meshsplats` reproduces MeshSplats (arXiv 2502.07754, `gwilczynski95/meshsplats`): rim
//!   vertices `θ_k = −π + 2πk/n` at 2.7σ, centre alpha = opacity, rim alpha = 0.2·opacity.
//! * `rings` follows the rasterizer's own footprint `α(r) = o·exp(−r²/2)`, cut where it falls
//!   below 1/255, i.e. out to `r_max = sqrt(2·ln(255·o))` (in σ). A Gaussian with
//!   `o < 1/255` never passes the cut and gives no triangles.
//! * `texture` is one polygon circumscribing the `r_max` disc, textured with the shared
//!   falloff image of [`crate::texture`]; its vertex alpha is the opacity.
//!
//! ## The `rings` profile and its error bound
//! Ring `j` (1..=m) sits at radius `x_j` with vertex alpha `o·g(x_j)`, `g(r) = exp(−r²/2)`,
//! `x_m = r_max` (so the outer ring carries exactly 1/255). Along a spoke the mesh is the
//! piecewise-linear interpolant of `g` through `0 = x_0 < x_1 < … < x_m`. The knots are
//! chosen to make the *maximum* interpolation error `ε_m(r_max)` small: bisection on ε with
//! a greedy "longest interval within ε" sweep. That is exactly minimax where an interval's
//! error grows with its length; across g's inflection at r = 1 it need not, so the knots
//! are near-minimax and the bound below uses the error actually achieved. For `o = 1`
//! (`r_max = 3.33σ`):
//!
//! | rings m | 1 | 2 | 3 | 4 | 6 | 8 |
//! |---|---|---|---|---|---|---|
//! | ε_m (× o) | 0.267 | 0.108 | 0.050 | 0.020 | 0.011 | 0.0068 |
//!
//! (the values are asserted by `rings_minimax_error_table` in the tests).
//!
//! Between spokes an n-gon is not a circle: a polygon ring of circumradius `R` reaches only
//! `R·cos(π/n)` at mid-edge. All ring radii are scaled by the area-preserving factor
//! `k_n = sqrt(2π / (n·sin(2π/n)))` (1.054 for n = 8), so each ring polygon covers the same
//! area as its circle and the radial error is split between spokes (radius too large by
//! `k_n`) and mid-edges (too small by `k_n·cos(π/n)`). A radius error factor `s` changes the
//! profile by at most `max_r |g(r/s) − g(r)| ≤ max_r r·|g'(r)|·|1/s − 1| = (2/e)·|1/s − 1|`,
//! so the total head-on error is bounded by
//!
//! `|α_mesh − o·g| ≤ o·(ε_m + (2/e)·δ_n) + 1/255`, with
//! `δ_n = max(1 − 1/k_n, 1/(k_n·cos(π/n)) − 1)` (0.051 for n = 8, 0.013 for n = 16),
//!
//! where the last term is the cut-off ring itself (the rasterizer drops α < 1/255). The test
//! `rings_profile_error_is_within_the_documented_bound` rasterises fans in f64 and checks it.

use std::f64::consts::PI;

use crate::options::Profile;

/// The rasterizer's alpha cut-off (3DGS skips a Gaussian at a pixel when α < 1/255).
pub const ALPHA_MIN: f32 = 1.0 / 255.0;
/// MeshSplats' rim distance in σ (every published experiment).
pub const MESHSPLATS_EXTENT: f32 = 2.7;
/// MeshSplats' rim alpha as a fraction of the opacity.
pub const MESHSPLATS_RIM_ALPHA: f32 = 0.2;
/// Radius (σ) of the falloff texture's edge: where a fully opaque Gaussian reaches 1/255.
pub fn texture_radius() -> f32 {
    (2.0 * 255f32.ln()).sqrt()
}

/// `r_max = sqrt(2·ln(255·o))`: where `o·exp(−r²/2)` falls to 1/255; `None` when `o < 1/255`.
pub fn cutoff_radius(opacity: f32) -> Option<f32> {
    let v = 255.0 * opacity as f64;
    if !(v >= 1.0) {
        return None;
    }
    Some((2.0 * v.ln()).sqrt() as f32)
}

/// Which shared vertex a layout vertex is, so the three fans of a volumetric Gaussian can
/// share the centre and the vertices on the principal axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VertexKey {
    Centre,
    /// On a principal axis: ring index and direction (0: +x, 1: +y, 2: −x, 3: −y).
    Axis {
        ring: u8,
        dir: u8,
    },
    Own,
}

#[derive(Clone, Copy, Debug)]
pub struct FanVertex {
    /// Position in the fan plane, in σ units of the plane's two axes.
    pub x: f32,
    pub y: f32,
    pub alpha: f32,
    pub uv: [f32; 2],
    pub key: VertexKey,
}

/// One fan's layout; reused between Gaussians to avoid allocation.
#[derive(Clone, Debug, Default)]
pub struct FanLayout {
    pub verts: Vec<FanVertex>,
    pub tris: Vec<[u16; 3]>,
}

/// A profile with its knobs resolved and its tables computed once per conversion.
#[derive(Clone, Debug)]
pub struct ProfileShape {
    pub profile: Profile,
    pub segments: usize,
    pub rings: usize,
    /// Rings: knot fractions `x_j / r_max` for `LEVELS` values of `r_max` in (0, r_max(1)].
    ring_table: Vec<Vec<f32>>,
    /// Area-preserving polygon factor `k_n`.
    area_factor: f32,
    cos_sin: Vec<(f32, f32)>,
}

const LEVELS: usize = 96;

/// `k_n = sqrt(2π / (n·sin(2π/n)))`: circumradius of the n-gon with the unit circle's area.
pub fn area_factor(n: usize) -> f64 {
    let n = n as f64;
    (2.0 * PI / (n * (2.0 * PI / n).sin())).sqrt()
}

/// `δ_n` of the module docs: the worst relative radius error of an area-preserving n-gon.
pub fn polygon_radius_error(n: usize) -> f64 {
    let k = area_factor(n);
    (1.0 - 1.0 / k).max(1.0 / (k * (PI / n as f64).cos()) - 1.0)
}

fn g(r: f64) -> f64 {
    (-0.5 * r * r).exp()
}

/// Max |linear interpolant − g| on [a, b] (dense sampling; g is smooth, 64 samples resolve
/// the error's single interior extremum to well under 1e-4 relative).
fn interval_error(a: f64, b: f64) -> f64 {
    let (ga, gb) = (g(a), g(b));
    let mut e: f64 = 0.0;
    for i in 1..64 {
        let t = i as f64 / 64.0;
        let x = a + (b - a) * t;
        e = e.max((ga + (gb - ga) * t - g(x)).abs());
    }
    e
}

/// Greedy: the fewest intervals covering [0, r_max] each within `eps`; `None` above `m`.
fn greedy(r_max: f64, eps: f64, m: usize) -> Option<Vec<f64>> {
    let mut knots = Vec::with_capacity(m);
    let mut x = 0.0;
    while x < r_max {
        if knots.len() == m {
            return None;
        }
        let y = if interval_error(x, r_max) <= eps {
            r_max
        } else {
            let (mut lo, mut hi) = (x, r_max);
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if interval_error(x, mid) <= eps {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            lo
        };
        if y <= x {
            return None;
        }
        knots.push(y);
        x = y;
    }
    Some(knots)
}

/// Minimax knots `x_1 < … < x_m = r_max` for the piecewise-linear interpolant of
/// `exp(−r²/2)` on [0, r_max], and the achieved maximum error.
pub fn minimax_knots(r_max: f64, m: usize) -> (Vec<f64>, f64) {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if greedy(r_max, mid, m).is_some() {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let mut knots = greedy(r_max, hi, m).unwrap_or_else(|| vec![r_max]);
    // Fewer intervals than rings (tiny r_max): split the widest until there are m.
    while knots.len() < m {
        let mut prev = 0.0;
        let mut best = (0, 0.0);
        for (i, &k) in knots.iter().enumerate() {
            if k - prev > best.1 {
                best = (i, k - prev);
            }
            prev = k;
        }
        let a = if best.0 == 0 { 0.0 } else { knots[best.0 - 1] };
        knots.insert(best.0, 0.5 * (a + knots[best.0]));
    }
    let mut err: f64 = 0.0;
    let mut a = 0.0;
    for &k in &knots {
        err = err.max(interval_error(a, k));
        a = k;
    }
    (knots, err)
}

impl ProfileShape {
    pub fn new(profile: Profile, segments: usize, rings: usize) -> Self {
        let ring_table = if profile == Profile::Rings {
            let top = texture_radius() as f64;
            (0..LEVELS)
                .map(|l| {
                    let r = top * (l + 1) as f64 / LEVELS as f64;
                    minimax_knots(r, rings)
                        .0
                        .iter()
                        .map(|k| (k / r) as f32)
                        .collect()
                })
                .collect()
        } else {
            Vec::new()
        };
        // Texture polygons put their vertices between the spokes so the edges touch the disc.
        let phase = if profile == Profile::Texture {
            PI / segments as f64
        } else {
            0.0
        };
        let cos_sin = (0..segments)
            .map(|k| {
                let t = -PI + phase + 2.0 * PI * k as f64 / segments as f64;
                // Exact zeros on the axes keep shared axis vertices bit-identical.
                let snap = |v: f64| if v.abs() < 1e-12 { 0.0 } else { v as f32 };
                (snap(t.cos()), snap(t.sin()))
            })
            .collect();
        ProfileShape {
            profile,
            segments,
            rings,
            ring_table,
            area_factor: area_factor(segments) as f32,
            cos_sin,
        }
    }

    /// The knot fractions used for a given `r_max` (nearest tabulated level).
    fn fractions(&self, r_max: f32) -> &[f32] {
        let top = texture_radius();
        let l = ((r_max / top) * LEVELS as f32).round() as isize - 1;
        &self.ring_table[l.clamp(0, LEVELS as isize - 1) as usize]
    }

    fn axis_key(&self, k: usize, ring: usize) -> VertexKey {
        let n = self.segments;
        if self.profile != Profile::Texture && n.is_multiple_of(4) && k.is_multiple_of(n / 4) {
            // θ_k = −π + 2πk/n: k = 0 → −x, n/4 → −y, n/2 → +x, 3n/4 → +y.
            let dir = [2u8, 3, 0, 1][k / (n / 4)];
            VertexKey::Axis {
                ring: ring as u8,
                dir,
            }
        } else {
            VertexKey::Own
        }
    }

    /// Fill `out` with the fan for opacity `o`. Returns false when the Gaussian gives no
    /// triangles (`o < 1/255` for the opacity-aware profiles).
    pub fn layout(&self, o: f32, out: &mut FanLayout) -> bool {
        out.verts.clear();
        out.tris.clear();
        let n = self.segments;
        match self.profile {
            Profile::MeshSplats => {
                out.verts.push(centre(o));
                for (k, &(c, s)) in self.cos_sin.iter().enumerate() {
                    let r = MESHSPLATS_EXTENT;
                    out.verts.push(FanVertex {
                        x: r * c,
                        y: r * s,
                        alpha: MESHSPLATS_RIM_ALPHA * o,
                        uv: [0.0; 2],
                        key: self.axis_key(k, 0),
                    });
                }
                for k in 0..n {
                    out.tris.push([0, 1 + k as u16, 1 + ((k + 1) % n) as u16]);
                }
                true
            }
            Profile::Rings => {
                let Some(r_max) = cutoff_radius(o) else {
                    return false;
                };
                out.verts.push(centre(o));
                for (j, &f) in self.fractions(r_max).iter().enumerate() {
                    let x = f * r_max;
                    let a = if j + 1 == self.rings {
                        ALPHA_MIN.min(o)
                    } else {
                        o * (-0.5 * x * x).exp()
                    };
                    let r = x * self.area_factor;
                    for (k, &(c, s)) in self.cos_sin.iter().enumerate() {
                        out.verts.push(FanVertex {
                            x: r * c,
                            y: r * s,
                            alpha: a,
                            uv: [0.0; 2],
                            key: self.axis_key(k, j),
                        });
                    }
                }
                let v = |j: usize, k: usize| (1 + j * n + k % n) as u16;
                for k in 0..n {
                    out.tris.push([0, v(0, k), v(0, k + 1)]);
                }
                for j in 0..self.rings - 1 {
                    for k in 0..n {
                        out.tris.push([v(j, k), v(j + 1, k), v(j + 1, k + 1)]);
                        out.tris.push([v(j, k), v(j + 1, k + 1), v(j, k + 1)]);
                    }
                }
                true
            }
            Profile::Texture => {
                let Some(r_max) = cutoff_radius(o) else {
                    return false;
                };
                let rc = r_max / (std::f32::consts::PI / n as f32).cos();
                let tr = texture_radius();
                for &(c, s) in &self.cos_sin {
                    let (x, y) = (rc * c, rc * s);
                    out.verts.push(FanVertex {
                        x,
                        y,
                        alpha: o,
                        uv: [0.5 + 0.5 * x / tr, 0.5 + 0.5 * y / tr],
                        key: VertexKey::Own,
                    });
                }
                for k in 1..n - 1 {
                    out.tris.push([0, k as u16, (k + 1) as u16]);
                }
                true
            }
        }
    }

    /// Whether this profile carries texture coordinates.
    pub fn has_uv(&self) -> bool {
        self.profile == Profile::Texture
    }
}

fn centre(o: f32) -> FanVertex {
    FanVertex {
        x: 0.0,
        y: 0.0,
        alpha: o,
        uv: [0.5, 0.5],
        key: VertexKey::Centre,
    }
}

/// Head-on alpha of a fan layout at plane point (x, y) (σ units), in f64: the
/// barycentric interpolation a rasterizer or ray tracer performs, for tests and error
/// measurement. Overlapping triangles (none in a valid fan) would be counted once.
pub fn layout_alpha_at(
    layout: &FanLayout,
    x: f64,
    y: f64,
    texture: Option<&dyn Fn(f64, f64) -> f64>,
) -> f64 {
    for t in &layout.tris {
        let [a, b, c] = t.map(|i| layout.verts[i as usize]);
        let (ax, ay, bx, by, cx, cy) = (
            a.x as f64, a.y as f64, b.x as f64, b.y as f64, c.x as f64, c.y as f64,
        );
        let d = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay);
        if d.abs() < 1e-30 {
            continue;
        }
        let l1 = ((x - ax) * (cy - ay) - (cx - ax) * (y - ay)) / d;
        let l2 = ((bx - ax) * (y - ay) - (x - ax) * (by - ay)) / d;
        let l0 = 1.0 - l1 - l2;
        let tol = -1e-12;
        if l0 >= tol && l1 >= tol && l2 >= tol {
            let alpha = l0 * a.alpha as f64 + l1 * b.alpha as f64 + l2 * c.alpha as f64;
            return match texture {
                Some(tex) => {
                    let u = l0 * a.uv[0] as f64 + l1 * b.uv[0] as f64 + l2 * c.uv[0] as f64;
                    let v = l0 * a.uv[1] as f64 + l1 * b.uv[1] as f64 + l2 * c.uv[1] as f64;
                    alpha * tex(u, v)
                }
                None => alpha,
            };
        }
    }
    0.0
}
