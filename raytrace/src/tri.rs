//! Watertight ray–triangle intersection (Woop, Benthin, Wald: "Watertight Ray/Triangle
//! Intersection", JCGT 2013), double-sided.
//!
//! The ray is sheared so that it runs along +z from the origin; the 2D edge functions U, V, W
//! of the sheared vertices decide coverage. A point on an edge shared by two triangles gets the
//! same edge-function value (with opposite roles) in both, so a ray through an edge or vertex is
//! never lost between triangles; it may be reported by both, which the compositor resolves by
//! counting each planar fan once. Edge functions that evaluate to exactly 0 in f32 are
//! recomputed in f64, as the paper prescribes.

use glam::Vec3;

/// A ray prepared for the watertight test: the shear constants and axis permutation.
#[derive(Clone, Copy, Debug)]
pub struct WRay {
    pub origin: Vec3,
    pub dir: Vec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

/// Why [`WRay::intersect_or`] found no hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Miss {
    /// The edge functions' signs put the ray outside the triangle.
    Outside,
    /// The ray lies in the triangle's plane, the triangle is degenerate, or `t` is outside
    /// the accepted range.
    Other,
}

/// A hit: the ray parameter and the barycentric weights of the triangle's vertices 0, 1, 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    pub t: f32,
    pub bary: [f32; 3],
}

impl WRay {
    /// Prepare a ray. `dir` need not be unit length (instanced rays keep the world parameter);
    /// it must be finite and non-zero, which callers guarantee.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        let a = dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Swapping keeps the winding of the sheared triangle independent of the ray's sign.
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        WRay {
            origin,
            dir,
            kx,
            ky,
            kz,
            sx: dir[kx] / dir[kz],
            sy: dir[ky] / dir[kz],
            sz: 1.0 / dir[kz],
        }
    }

    /// Intersect the triangle (a, b, c), both faces, accepting `tmin ≤ t ≤ tmax`.
    #[inline]
    pub fn intersect(&self, a: Vec3, b: Vec3, c: Vec3, tmin: f32, tmax: f32) -> Option<TriHit> {
        self.intersect_or(a, b, c, tmin, tmax).ok()
    }

    /// [`WRay::intersect`], saying why a ray misses: [`Miss::Outside`] when the edge
    /// functions' signs decide it. Those are the same numbers, permuted (and negated for the
    /// other winding), for the triangle with its vertices in any other order: each edge
    /// function is one product less another, and exchanging two vertices exchanges the two
    /// products, which f32 (and the f64 recomputation) round alike; so a ray outside a
    /// triangle is outside it in the other winding too.
    #[inline]
    pub fn intersect_or(
        &self,
        a: Vec3,
        b: Vec3,
        c: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Result<TriHit, Miss> {
        let cov = self.edges(a, b, c)?;
        let t = cov.num / cov.det;
        if !(t >= tmin && t <= tmax) {
            return Err(Miss::Other);
        }
        Ok(cov.hit_at(t))
    }

    /// [`WRay::intersect_or`] over every `t` (`−∞ ≤ t ≤ +∞`), without its divisions: the
    /// outcome is the same (`t` is NaN exactly where its numerator is, the determinant being
    /// finite and non-zero), and [`Covered::hit`] gives the same hit where it is needed.
    #[inline]
    pub fn cover(&self, a: Vec3, b: Vec3, c: Vec3) -> Result<Covered, Miss> {
        let cov = self.edges(a, b, c)?;
        if cov.num.is_nan() {
            return Err(Miss::Other);
        }
        Ok(cov)
    }

    /// The edge functions, determinant and distance numerator of the test.
    #[inline(always)]
    fn edges(&self, a: Vec3, b: Vec3, c: Vec3) -> Result<Covered, Miss> {
        // Arrays, not `Vec3`s: glam indexes a `Vec3` by a `match`, a branch per coordinate
        // (3 % of a mesh frame's instructions). The indices are below 3 (`WRay::new`); `min`
        // says so to the compiler, which then drops the bounds checks.
        let (kx, ky, kz) = (self.kx.min(2), self.ky.min(2), self.kz.min(2));
        let a = (a - self.origin).to_array();
        let b = (b - self.origin).to_array();
        let c = (c - self.origin).to_array();
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            let (ax, ay, bx, by, cx, cy) = (
                ax as f64, ay as f64, bx as f64, by as f64, cx as f64, cy as f64,
            );
            u = (cx * by - cy * bx) as f32;
            v = (ax * cy - ay * cx) as f32;
            w = (bx * ay - by * ax) as f32;
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return Err(Miss::Outside);
        }
        let det = u + v + w;
        // det == 0: the ray lies in the triangle's plane (or the triangle is degenerate).
        if det == 0.0 || !det.is_finite() {
            return Err(Miss::Other);
        }
        let az = self.sz * a[kz];
        let bz = self.sz * b[kz];
        let cz = self.sz * c[kz];
        Ok(Covered {
            u,
            v,
            w,
            det,
            num: u * az + v * bz + w * cz,
        })
    }
}

/// A ray the watertight test found inside a triangle: its edge functions, their sum and the
/// numerator of the distance, before the divisions ([`WRay::cover`]).
#[derive(Clone, Copy, Debug)]
pub struct Covered {
    u: f32,
    v: f32,
    w: f32,
    det: f32,
    num: f32,
}

impl Covered {
    /// The hit [`WRay::intersect_or`] reports, from the same operations.
    #[inline]
    pub fn hit(&self) -> TriHit {
        self.hit_at(self.num / self.det)
    }

    #[inline(always)]
    fn hit_at(&self, t: f32) -> TriHit {
        let inv = 1.0 / self.det;
        TriHit {
            t,
            bary: [self.u * inv, self.v * inv, self.w * inv],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_inside_misses_outside_both_faces() {
        let (a, b, c) = (
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        );
        let r = WRay::new(Vec3::new(0.25, 0.25, 0.0), Vec3::Z);
        let h = r.intersect(a, b, c, 0.0, f32::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        assert!((h.bary[0] - 0.5).abs() < 1e-6 && (h.bary[1] - 0.25).abs() < 1e-6);
        // Reversed winding: still hit (double-sided).
        assert!(r.intersect(a, c, b, 0.0, f32::INFINITY).is_some());
        let back = WRay::new(Vec3::new(0.25, 0.25, 2.0), -Vec3::Z);
        assert!(back.intersect(a, b, c, 0.0, f32::INFINITY).is_some());
        let miss = WRay::new(Vec3::new(0.75, 0.75, 0.0), Vec3::Z);
        assert!(miss.intersect(a, b, c, 0.0, f32::INFINITY).is_none());
        // Behind the origin.
        assert!(r.intersect(a, b, c, 1.5, f32::INFINITY).is_none());
    }

    #[test]
    fn shared_edge_is_never_missed() {
        // Two triangles sharing the diagonal of the unit square; rays along the diagonal.
        let p = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        for i in 1..100 {
            let s = i as f32 / 100.0 + 1e-3 * (i as f32).sin();
            let r = WRay::new(
                Vec3::new(s, s, 0.0),
                Vec3::new(1e-3 * (i as f32).cos(), 0.0, 1.0).normalize(),
            );
            let h1 = r.intersect(p[0], p[1], p[2], 0.0, f32::INFINITY).is_some();
            let h2 = r.intersect(p[0], p[2], p[3], 0.0, f32::INFINITY).is_some();
            assert!(h1 || h2, "ray {i} slipped through the shared edge");
        }
    }

    #[test]
    fn coplanar_ray_misses() {
        let r = WRay::new(Vec3::new(-1.0, 0.2, 1.0), Vec3::X);
        assert!(r
            .intersect(
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(1.0, 0.0, 1.0),
                Vec3::new(0.0, 1.0, 1.0),
                0.0,
                f32::INFINITY
            )
            .is_none());
    }
    /// [`WRay::cover`] and [`Covered::hit`] give what [`WRay::intersect_or`] over every `t`
    /// gives, bit for bit: random rays and triangles (small, huge, slivers, repeated
    /// vertices, vertices at ±1e30 whose distance numerator overflows or is NaN).
    #[test]
    fn cover_equals_the_whole_range_test() {
        let mut draw = crate::test_rng::unit(5);
        let mut next = move || draw() as f32 * 2.0 - 1.0;
        let (mut hits, mut outside, mut other) = (0, 0, 0);
        for i in 0..20_000 {
            let scale = [1.0f32, 1e-3, 1e3, 1e30][i % 4];
            let mut v = || Vec3::new(next(), next(), next() + 2.0) * scale;
            let (a, b, mut c) = (v(), v(), v());
            if i % 7 == 0 {
                c = a;
            }
            if i % 11 == 0 {
                c = Vec3::new(f32::INFINITY, 0.0, 1.0);
            }
            let r = WRay::new(
                Vec3::new(next(), next(), 0.0) * 0.5,
                Vec3::new(next() * 0.3, next() * 0.3, 1.0),
            );
            let want = r.intersect_or(a, b, c, f32::NEG_INFINITY, f32::INFINITY);
            let got = r.cover(a, b, c).map(|c| c.hit());
            match (want, got) {
                (Ok(w), Ok(g)) => {
                    hits += 1;
                    assert_eq!(w.t.to_bits(), g.t.to_bits());
                    assert!(w
                        .bary
                        .iter()
                        .zip(g.bary)
                        .all(|(p, q)| p.to_bits() == q.to_bits()));
                }
                (Err(w), Err(g)) => {
                    assert_eq!(w, g);
                    match w {
                        Miss::Outside => outside += 1,
                        Miss::Other => other += 1,
                    }
                }
                (w, g) => panic!("{w:?} vs {g:?}"),
            }
        }
        assert!(
            hits > 1000 && outside > 1000 && other > 100,
            "{hits} {outside} {other}"
        );
    }
}
