//! What the screen-tile path of mode `mesh` (`mesh_tiles`) prepares per triangle once a frame,
//! so that a ray rejects most of its cell's triangles without the exact test and tests the
//! rest without reading the index buffer:
//!
//! - [`Edges`], a conservative screen-space pre-test: the triangle's projected edges as three
//!   normalised edge functions (signed distances in pixels), each moved outwards by the margin
//!   that already widens the triangle's screen rectangle (covering the f32 watertight test's
//!   rounding) and by a bound on the pre-test's own f32 rounding. A ray whose pixel is outside
//!   one of them cannot be reported by the watertight test (Pineda, "A Parallel Algorithm for
//!   Polygon Rasterization", SIGGRAPH 1988, for the edge functions; the margin argument is the
//!   rectangle's, `mesh_tiles`).
//! - [`mirror_pairs`]: the viewer layout writes every triangle twice, once per winding (the
//!   same three vertex indices in the opposite order, same Gaussian and planar group). Such a
//!   pair is binned once: the ray tests the lower-indexed triangle and tests the other only
//!   where the first's outcome leaves it open (`mesh_hit::Tested`), which gives the
//!   brute-force reference's hits exactly.

use glam::Vec3;

/// A vertex index triple up to rotation, and whether it was in the canonical winding.
#[inline]
fn canonical([a, b, c]: [u32; 3]) -> Option<([u32; 3], bool)> {
    if a == b || b == c || a == c {
        return None;
    }
    // Rotate the smallest index first (a rotation keeps the winding).
    let r = if a < b && a < c {
        [a, b, c]
    } else if b < c {
        [b, c, a]
    } else {
        [c, a, b]
    };
    Some(if r[1] < r[2] {
        (r, true)
    } else {
        ([r[0], r[2], r[1]], false)
    })
}

/// For each triangle, its other winding's index where its planar group (`group`) holds
/// exactly two triangles over the same three vertex indices with the same Gaussian, in
/// opposite windings; `u32::MAX` otherwise. Pairs are found within groups (a few triangles
/// each in exports); a copy in another group is another key, tested on its own.
pub(crate) fn mirror_pairs(tris: &[[u32; 3]], gaussian: &[u32], group: &[u32]) -> Vec<u32> {
    let n = tris.len();
    let mut partner = vec![u32::MAX; n];
    let groups = group.iter().map(|&g| g as usize + 1).max().unwrap_or(0);
    // Triangles by group (counting sort).
    let mut start = vec![0u32; groups + 1];
    for &g in group {
        start[g as usize + 1] += 1;
    }
    for k in 1..start.len() {
        start[k] += start[k - 1];
    }
    let mut next = start.clone();
    let mut order = vec![0u32; n];
    for (t, &g) in group.iter().enumerate() {
        order[next[g as usize] as usize] = t as u32;
        next[g as usize] += 1;
    }
    drop(next);
    let mut keyed: Vec<([u32; 3], u32, bool, u32)> = Vec::new();
    for w in start.windows(2) {
        let members = &order[w[0] as usize..w[1] as usize];
        if members.len() < 2 {
            continue;
        }
        keyed.clear();
        keyed.extend(members.iter().filter_map(|&t| {
            let (k, same) = canonical(tris[t as usize])?;
            Some((k, gaussian[t as usize], same, t))
        }));
        keyed.sort_unstable();
        let mut i = 0;
        while i < keyed.len() {
            let mut j = i + 1;
            while j < keyed.len() && keyed[j].0 == keyed[i].0 && keyed[j].1 == keyed[i].1 {
                j += 1;
            }
            // Exactly two triangles over these indices, in opposite windings.
            if j - i == 2 && keyed[i].2 != keyed[i + 1].2 {
                let (a, b) = (keyed[i].3, keyed[i + 1].3);
                partner[a as usize] = b;
                partner[b as usize] = a;
            }
            i = j;
        }
    }
    partner
}

/// Whether triangle `t` is binned (and tested first) for its winding pair: it has no other
/// winding (`mirror[t] == u32::MAX`) or has the lower index of the two.
#[inline]
pub(crate) fn leads(mirror: &[u32], t: usize) -> bool {
    mirror[t] == u32::MAX || mirror[t] > t as u32
}

/// The pre-test's data: `[a, b, c]` per edge, `a·u + b·v + c ≥ 0` for every pixel whose ray
/// the watertight test may report; `[0, 0, +∞]` where no edge can be formed (a triangle
/// reaching the camera plane, a degenerate edge).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Edges(pub [[f32; 3]; 3]);

/// Relative bound on the pre-test's own rounding: the coefficients are rounded to f32 (2⁻²⁴
/// each) and `a·u + b·v + c` takes three f32 roundings of terms no larger than the sum of
/// their magnitudes; 2⁻¹⁸ of that sum is 64 times the two together.
const EVAL_SLACK: f64 = 1.0 / 262_144.0;

impl Edges {
    /// Every pixel passes.
    pub(crate) const ALL: Edges = Edges([[0.0, 0.0, f32::INFINITY]; 3]);

    /// The edge functions of the projected triangle `p` (image coordinates), each moved out
    /// by `margin` pixels, for pixels within `[0, extent]` in both coordinates.
    pub(crate) fn new(p: [(f64, f64); 3], margin: f64, extent: f64) -> Self {
        let mut out = [[0.0f32, 0.0, f32::INFINITY]; 3];
        for (i, e) in out.iter_mut().enumerate() {
            let (pj, pk, pi) = (p[(i + 1) % 3], p[(i + 2) % 3], p[i]);
            let (dx, dy) = (pk.0 - pj.0, pk.1 - pj.1);
            // Not `hypot`: a length off by an ulp scales the whole edge function (its sign is
            // unchanged) far below `EVAL_SLACK`, and an overflow or underflow to 0 leaves the
            // edge admitting every pixel (below).
            let len = (dx * dx + dy * dy).sqrt();
            if !(len > 0.0 && len.is_finite()) {
                continue;
            }
            // One division: the normal's length is 1 to within an ulp or two either way.
            let inv = 1.0 / len;
            let (mut a, mut b) = (-dy * inv, dx * inv);
            let mut c = -(a * pj.0 + b * pj.1);
            // Oriented so the opposite vertex is inside; a vertex on the line (a sliver)
            // leaves either orientation valid, since the triangle lies on the line.
            if a * pi.0 + b * pi.1 + c < 0.0 {
                (a, b, c) = (-a, -b, -c);
            }
            let slack = EVAL_SLACK * (a.abs() * extent + b.abs() * extent + c.abs() + margin);
            let c = c + margin + slack;
            if !c.is_finite() {
                continue;
            }
            let cu = c as f32;
            let cu = if (cu as f64) < c { cu.next_up() } else { cu };
            *e = [a as f32, b as f32, cu];
        }
        Edges(out)
    }

    /// Whether the pixel `(u, v)` may be reported by the watertight test (the walk tests eight
    /// records at once, [`HotChunk::mask`]; this is its reference, and binning's test of
    /// whether any sample can pass).
    #[inline]
    pub(crate) fn admit(&self, u: f32, v: f32) -> bool {
        let e = &self.0;
        (e[0][0] * u + e[0][1] * v + e[0][2] >= 0.0)
            & (e[1][0] * u + e[1][1] * v + e[1][2] >= 0.0)
            & (e[2][0] * u + e[2][1] * v + e[2][2] >= 0.0)
    }
}

/// A triangle of a tile's cell, as a ray tests it: the list key, screen rectangle and edge
/// functions, then the anchor-relative vertices the exact test reads, its instance, index,
/// group, and its other winding's index (`u32::MAX`: none binned with it).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cand {
    pub zmin: f32,
    pub rect: [f32; 4],
    pub edges: Edges,
    pub verts: [Vec3; 3],
    pub inst: u32,
    pub tri: u32,
    pub group: u32,
    pub mirror: u32,
}

/// The part of a [`Cand`] every ray of a cell reads: key, rectangle, edges (56 bytes).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Hot {
    pub zmin: f32,
    pub rect: [f32; 4],
    pub edges: Edges,
}

/// The part of a [`Cand`] only the triangles a ray tests read.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cold {
    pub verts: [Vec3; 3],
    pub inst: u32,
    pub tri: u32,
    pub group: u32,
    pub mirror: u32,
}

/// Records per [`HotChunk`].
pub(crate) const LANES: usize = 8;

/// Eight consecutive [`Hot`] records of a cell, field by field, so that a ray tests eight
/// records' keys, rectangles and edges without a branch per record; lanes past the cell's
/// end are [`HotChunk::EMPTY`]'s, whose rectangle no pixel is in. Each lane performs the
/// scalar tests' float operations in their order (no fused multiply-add), so a lane passes
/// exactly where the scalar walk would test the triangle (checked lane by lane in the
/// tests).
#[derive(Clone, Copy, Debug)]
pub(crate) struct HotChunk {
    pub zmin: [f32; LANES],
    rect: [[f32; LANES]; 4],
    edges: [[[f32; LANES]; 3]; 3],
}

impl HotChunk {
    /// No record: an empty rectangle and a key beyond every cull distance.
    pub(crate) const EMPTY: HotChunk = HotChunk {
        zmin: [f32::INFINITY; LANES],
        rect: [
            [f32::INFINITY; LANES],
            [f32::INFINITY; LANES],
            [f32::NEG_INFINITY; LANES],
            [f32::NEG_INFINITY; LANES],
        ],
        edges: [[[0.0; LANES]; 3]; 3],
    };

    /// Lane `l` set to record `h`.
    pub(crate) fn set(&mut self, l: usize, h: &Hot) {
        self.zmin[l] = h.zmin;
        for c in 0..4 {
            self.rect[c][l] = h.rect[c];
        }
        for (e, he) in self.edges.iter_mut().zip(&h.edges.0) {
            for c in 0..3 {
                e[c][l] = he[c];
            }
        }
    }

    /// Bit `l` set where lane `l`'s record is not keyed beyond `cull`, its rectangle holds
    /// the pixel `(u, v)` and its edges admit it ([`Edges::admit`]).
    #[inline(always)]
    pub(crate) fn mask(&self, u: f32, v: f32, cull: f32) -> u32 {
        let mut ok = [false; LANES];
        for (l, slot) in ok.iter_mut().enumerate() {
            let r = &self.rect;
            let e = &self.edges;
            let inside = !(self.zmin[l] > cull)
                & (u >= r[0][l])
                & (u <= r[2][l])
                & (v >= r[1][l])
                & (v <= r[3][l]);
            let edges = (e[0][0][l] * u + e[0][1][l] * v + e[0][2][l] >= 0.0)
                & (e[1][0][l] * u + e[1][1][l] * v + e[1][2][l] >= 0.0)
                & (e[2][0][l] * u + e[2][1][l] * v + e[2][2][l] >= 0.0);
            *slot = inside & edges;
        }
        ok.iter()
            .enumerate()
            .fold(0u32, |m, (l, &b)| m | ((b as u32) << l))
    }
}

impl Cand {
    /// A placeholder (never walked: every slot of a tile's cells is overwritten).
    pub(crate) const BLANK: Cand = Cand {
        zmin: 0.0,
        rect: [0.0; 4],
        edges: Edges::ALL,
        verts: [Vec3::ZERO; 3],
        inst: 0,
        tri: 0,
        group: 0,
        mirror: u32::MAX,
    };

    #[inline]
    pub(crate) fn hot(&self) -> Hot {
        Hot {
            zmin: self.zmin,
            rect: self.rect,
            edges: self.edges,
        }
    }

    #[inline]
    pub(crate) fn cold(&self) -> Cold {
        Cold {
            verts: self.verts,
            inst: self.inst,
            tri: self.tri,
            group: self.group,
            mirror: self.mirror,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn canonical_keeps_winding_and_rejects_repeats() {
        // The three rotations of one winding, then of the other.
        assert_eq!(canonical([2, 5, 9]), Some(([2, 5, 9], true)));
        assert_eq!(canonical([5, 9, 2]), Some(([2, 5, 9], true)));
        assert_eq!(canonical([9, 2, 5]), Some(([2, 5, 9], true)));
        assert_eq!(canonical([2, 9, 5]), Some(([2, 5, 9], false)));
        assert_eq!(canonical([9, 5, 2]), Some(([2, 5, 9], false)));
        assert_eq!(canonical([5, 2, 9]), Some(([2, 5, 9], false)));
        assert_eq!(canonical([2, 2, 9]), None);
    }

    #[test]
    fn pairs_only_opposite_windings_alone_on_their_indices() {
        let tris = [
            [0, 1, 2],
            [3, 4, 5],
            [1, 0, 2], // the other winding of 0
            [4, 5, 3], // a rotation of 1: same winding, not a pair
            [6, 7, 8],
            [8, 7, 6], // the other winding of 4...
            [7, 6, 8], // ...twice: three triangles over one triple, no pair
            [0, 2, 1], // the other winding of 0 in another group: not a pair
        ];
        let gaussian = [0, 0, 0, 0, 1, 1, 1, 0];
        let group = [0, 0, 0, 0, 1, 1, 1, 2];
        let p = mirror_pairs(&tris, &gaussian, &group);
        assert_eq!(
            p,
            vec![
                2,
                u32::MAX,
                0,
                u32::MAX,
                u32::MAX,
                u32::MAX,
                u32::MAX,
                u32::MAX
            ]
        );
    }

    #[test]
    fn edges_admit_the_inside_and_reject_beyond_the_margin() {
        let p = [(10.0, 10.0), (20.0, 10.0), (10.0, 20.0)];
        for q in [p, [p[0], p[2], p[1]]] {
            let e = Edges::new(q, 0.5, 64.0);
            assert!(e.admit(12.0, 12.0));
            // On the hypotenuse and 0.4 px beyond it (inside the margin).
            assert!(e.admit(15.0, 15.0));
            assert!(e.admit(15.0 + 0.28, 15.0 + 0.28));
            // 0.6 px beyond it, and beyond the other edges.
            assert!(!e.admit(15.0 + 0.43, 15.0 + 0.43));
            assert!(!e.admit(9.4, 12.0));
            assert!(!e.admit(12.0, 9.4));
        }
        assert!(Edges::ALL.admit(-1e6, 1e6));
        // A degenerate triangle (all three at one point) keeps only what its edges can say.
        let e = Edges::new([(5.0, 5.0); 3], 0.5, 64.0);
        assert!(e.admit(40.0, 40.0));
    }
    /// Each lane of a chunk passes exactly where the scalar walk's tests pass (key at or
    /// before the cull distance, rectangle, [`Edges::admit`]): random triangles, pixels on
    /// and beside their edges and rectangle sides, cull distances equal to keys, every
    /// partial chunk, and the empty lanes, which no pixel passes.
    #[test]
    fn chunk_lanes_equal_the_scalar_tests() {
        let mut next = crate::test_rng::unit(11);
        let mut passed = 0;
        for round in 0..400 {
            let n = round % LANES + 1;
            let hots: Vec<Hot> = (0..n)
                .map(|_| {
                    let p = [0, 1, 2].map(|_| (next() * 16.0, next() * 16.0));
                    let rect = [0, 1].map(|c| {
                        let v = p.map(|q| if c == 0 { q.0 } else { q.1 });
                        (
                            v.iter().cloned().fold(f64::INFINITY, f64::min) as f32,
                            v.iter().cloned().fold(f64::NEG_INFINITY, f64::max) as f32,
                        )
                    });
                    Hot {
                        zmin: (next() * 4.0) as f32,
                        rect: [rect[0].0, rect[1].0, rect[0].1, rect[1].1],
                        edges: if next() < 0.1 {
                            Edges::ALL
                        } else {
                            Edges::new(p, 0.05, 16.0)
                        },
                    }
                })
                .collect();
            let mut chunk = HotChunk::EMPTY;
            for (l, h) in hots.iter().enumerate() {
                chunk.set(l, h);
            }
            for _ in 0..64 {
                // Pixels anywhere, on a rectangle's side, and at a vertex of the edges.
                let h = &hots[(next() * n as f64) as usize % n];
                let (u, v) = match (next() * 3.0) as u32 {
                    0 => ((next() * 18.0 - 1.0) as f32, (next() * 18.0 - 1.0) as f32),
                    1 => (h.rect[0], (next() * 16.0) as f32),
                    _ => (h.rect[2], h.rect[3]),
                };
                let cull = if next() < 0.5 {
                    h.zmin
                } else {
                    (next() * 4.0) as f32
                };
                let m = chunk.mask(u, v, cull);
                for l in 0..LANES {
                    let want = hots.get(l).is_some_and(|h| {
                        !(h.zmin > cull)
                            && u >= h.rect[0]
                            && u <= h.rect[2]
                            && v >= h.rect[1]
                            && v <= h.rect[3]
                            && h.edges.admit(u, v)
                    });
                    assert_eq!(m >> l & 1 == 1, want, "lane {l} of {n} at ({u}, {v})");
                    passed += want as u32;
                }
            }
        }
        // The rounds exercise both outcomes (a test that never passes a lane checks little).
        assert!(passed > 1000, "{passed}");
    }
}
