//! A mesh's planar fan groups ([`Mesh::planar_groups`]): the triangles of one Gaussian that
//! lie in one plane, which a ray crosses at most once. The BVH keys every hit of a group by
//! the group plane's distance, and the screen tiles bin a large group as one record.

use glam::DVec3;
use rayon::prelude::*;

use super::Mesh;

impl Mesh {
    /// Planar fan groups: triangles of one Gaussian (or component) that lie in one plane form a
    /// group, which a ray crosses at most once, so a hit on a shared edge or vertex counts once.
    /// Two triangles share a group when their normals are parallel (|cos| > 0.99, within ~8°)
    /// and the second's vertices lie within `1e-3 × extent + 1e-6 × |coordinate|` of the first's
    /// plane: fans written in f32 are planar up to f32 rounding (~6e-8 of the coordinate
    /// magnitude, which dominates far from the origin), while the fans of one volumetric
    /// Gaussian are orthogonal and parallel faces of a solid are offset by their separation.
    /// Returns (per-triangle group, group count).
    pub fn planar_groups(&self) -> (Vec<u32>, u32) {
        self.planar_groups_in(1 << 16)
    }

    /// [`Mesh::planar_groups`] with stretches of at least `stretch` triangles.
    pub(crate) fn planar_groups_in(&self, stretch: usize) -> (Vec<u32>, u32) {
        // Exports list a Gaussian's triangles together, in ascending order: then the order is
        // the identity and is not materialised (4 bytes a triangle), and stretches of whole
        // Gaussians are grouped side by side, each numbering its groups from 0, then offset
        // by the groups of the stretches before it: the numbers one pass in this order gives.
        // Otherwise a stable sort, which gives the same order on ascending input, so groups
        // do not depend on the path.
        let ascending = self.tri_gaussian.windows(2).all(|w| w[0] <= w[1]);
        if !ascending {
            let mut order: Vec<u32> = (0..self.tris.len() as u32).collect();
            order.sort_by_key(|&t| self.tri_gaussian[t as usize]);
            let mut group = vec![u32::MAX; self.tris.len()];
            let next = self.group_pass(order.into_iter(), 0, &mut group);
            return (group, next);
        }
        let n = self.tris.len();
        // Stretches of at least `stretch` triangles, ending where a Gaussian does.
        let mut cuts = vec![0usize];
        while let Some(&last) = cuts.last() {
            let mut end = (last + stretch.max(1)).min(n);
            while end < n && self.tri_gaussian[end] == self.tri_gaussian[end - 1] {
                end += 1;
            }
            cuts.push(end);
            if end == n {
                break;
            }
        }
        let mut group = vec![u32::MAX; n];
        let mut parts: Vec<&mut [u32]> = Vec::with_capacity(cuts.len());
        let mut rest = &mut group[..];
        for w in cuts.windows(2) {
            let (mine, tail) = std::mem::take(&mut rest).split_at_mut(w[1] - w[0]);
            parts.push(mine);
            rest = tail;
        }
        let counts: Vec<u32> = parts
            .into_par_iter()
            .zip(cuts.par_windows(2))
            .map(|(part, w)| self.group_pass(w[0] as u32..w[1] as u32, w[0], part))
            .collect();
        let mut offsets = Vec::with_capacity(counts.len());
        let mut next = 0u32;
        for c in counts {
            offsets.push(next);
            next += c;
        }
        for (w, &off) in cuts.windows(2).zip(&offsets) {
            if off != 0 {
                group[w[0]..w[1]].par_iter_mut().for_each(|g| *g += off);
            }
        }
        (group, next)
    }

    /// One pass of [`Mesh::planar_groups`] over the triangles `order` (a Gaussian's
    /// triangles together), numbering groups from 0 in order of first appearance: triangle
    /// `t`'s into `group[t - offset]`. Returns the number of groups.
    fn group_pass(
        &self,
        order: impl Iterator<Item = u32>,
        offset: usize,
        group: &mut [u32],
    ) -> u32 {
        let mut next = 0u32;
        // Representatives of the current Gaussian's groups: (normal, point, tolerance, id).
        let mut reps: Vec<(DVec3, DVec3, f64, u32)> = Vec::new();
        let mut cur = u32::MAX;
        for t in order {
            let t = t as usize;
            let g = self.tri_gaussian[t];
            if g != cur {
                reps.clear();
                cur = g;
            }
            let [a, b, c] = self.tris[t].map(|i| self.positions[i as usize].as_dvec3());
            let n = (b - a).cross(c - a);
            // The longest side: the root of the largest squared side is the largest of the
            // roots (a correctly rounded square root is monotone), one root instead of three.
            let ext = (b - a)
                .length_squared()
                .max((c - a).length_squared())
                .max((c - b).length_squared())
                .sqrt();
            let nn = n.normalize_or_zero();
            let found = if nn == DVec3::ZERO {
                None
            } else {
                reps.iter().find(|(rn, rp, tol, _)| {
                    rn.dot(nn).abs() > 0.99
                        && [a, b, c].iter().all(|p| {
                            rn.dot(*p - *rp).abs()
                                <= tol.max(1e-3 * ext) + 1e-6 * p.abs().max_element()
                        })
                })
            };
            group[t - offset] = match found {
                Some(r) => r.3,
                None => {
                    let id = next;
                    next += 1;
                    if nn != DVec3::ZERO {
                        reps.push((nn, a, 1e-3 * ext, id));
                    }
                    id
                }
            };
        }
        next
    }
}
