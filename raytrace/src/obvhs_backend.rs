//! The obvhs backend: a compressed wide BVH (CWBVH, Ylitie et al. 2017) built with PLOC
//! (Meister & Bittner 2018) from the pure-Rust `obvhs` crate.
//!
//! Presets never pre-split triangles (see `BuildPreset`), so each primitive sits in exactly one
//! leaf. Traversal goes through `ray_traverse`, whose closure returns a distance that shrinks
//! the ray's `tmax`: that is how the k-nearest query culls nodes beyond the k-th hit.
//!
//! The CWBVH's traversal keeps its pending node groups on a fixed stack of 32 entries that,
//! when full, overwrites its top (`obvhs::faststack::StackStack::push`), and obvhs's debug
//! build refuses a wide tree of 32 or more levels: deeper, a ray could silently lose subtrees.
//! Degenerate inputs build such trees (boxes that all contain one another, as the grown proxies
//! of a nearly 180° view do). Every build therefore measures its wide tree's depth, and a tree
//! too deep for that stack is kept as the binary BVH it was made from, whose traversal sizes
//! its stack from the tree's depth.

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ploc::PlocBuilder;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::{Boundable, BvhBuildParams};

use crate::backend::{Accel, BuildPreset};

fn params(p: BuildPreset) -> BvhBuildParams {
    let mut b = match p {
        BuildPreset::Fastest => BvhBuildParams::fastest_build(),
        BuildPreset::VeryFast => BvhBuildParams::very_fast_build(),
        BuildPreset::Fast => BvhBuildParams::fast_build(),
        BuildPreset::Medium => BvhBuildParams::medium_build(),
    };
    b.pre_split = false;
    b
}

/// The traversal ray. Two departures from `Ray::new`: −0.0 direction components become +0.0
/// (the node test takes the octant from the sign of the direction but slab order from the sign
/// of its inverse, and `safe_inverse(−0.0)` is negative while `−0.0 < 0.0` is false, so every
/// node was missed), and the inverse is exact down to |d| = 1e-18 (clamped to ±1e18 below, which
/// keeps node arithmetic finite) instead of being clamped at f32::EPSILON, which turned nearly
/// grazing rays into steeper ones and could miss flat boxes.
fn make_ray(origin: Vec3, dir: Vec3, tmax: f32) -> Ray {
    let dir = dir + Vec3::ZERO;
    let inv = |x: f32| {
        if x.abs() < 1e-18 {
            1e18f32.copysign(x)
        } else {
            1.0 / x
        }
    };
    Ray {
        origin: Vec3A::from(origin),
        direction: Vec3A::from(dir),
        inv_direction: Vec3A::new(inv(dir.x), inv(dir.y), inv(dir.z)),
        tmin: 0.0,
        tmax,
    }
}

/// The CWBVH's traversal stack (`obvhs::cwbvh::TRAVERSAL_STACK_SIZE`, private there): a tree
/// of this many levels or more may overflow it.
const WIDE_STACK: u32 = 32;

/// A built tree, with its leaf order (`primitive_indices`) mapping to the caller's primitives.
enum Tree {
    /// The compressed wide BVH (every tree shallower than [`WIDE_STACK`]).
    Wide(CwBvh),
    /// The binary BVH it was made from, for a tree too deep for the wide traversal's stack.
    Binary(Bvh2),
}

/// An obvhs BVH over the caller's primitives.
pub struct ObvhsAccel {
    tree: Tree,
}

impl ObvhsAccel {
    pub fn triangles(preset: BuildPreset, verts: &[Vec3], tris: &[[u32; 3]]) -> Self {
        let t: Vec<Triangle> = tris
            .iter()
            .map(|&[a, b, c]| Triangle {
                v0: Vec3A::from(verts[a as usize]),
                v1: Vec3A::from(verts[b as usize]),
                v2: Vec3A::from(verts[c as usize]),
            })
            .collect();
        ObvhsAccel::build(preset, &t)
    }

    pub fn boxes(preset: BuildPreset, boxes: &[(Vec3, Vec3)]) -> Self {
        let b: Vec<Aabb> = boxes
            .iter()
            .map(|(lo, hi)| Aabb::new(Vec3A::from(*lo), Vec3A::from(*hi)))
            .collect();
        ObvhsAccel::build(preset, &b)
    }

    /// obvhs's `build_cwbvh` (PLOC, reinsertion, conversion to the wide tree; no pre-splits),
    /// step by step, so that a tree too deep for the wide traversal stays binary (and so that
    /// a debug build does not stop at obvhs's own assertion of that depth).
    fn build<T: Boundable>(preset: BuildPreset, prims: &[T]) -> Self {
        let (mut bvh2, wide) = trees(preset, prims);
        if wide_depth(&wide) < WIDE_STACK {
            return ObvhsAccel::kept(wide);
        }
        // The binary traversal picks its stack by `max_depth` (a heap one past 192 levels); the
        // builder's figure predates the reinsertion, which can deepen the tree.
        bvh2.max_depth = binary_depth(&bvh2) + 1;
        bvh2.primitive_indices.shrink_to_fit();
        ObvhsAccel {
            tree: Tree::Binary(bvh2),
        }
    }

    /// The built structure as it is kept: obvhs reserves one wide node per primitive for the
    /// conversion from its binary tree (80 bytes each) and fills a fraction of them, so the
    /// spare capacity is released (a few hundred MB over tens of millions of primitives).
    fn kept(mut bvh: CwBvh) -> Self {
        bvh.nodes.shrink_to_fit();
        bvh.primitive_indices.shrink_to_fit();
        ObvhsAccel {
            tree: Tree::Wide(bvh),
        }
    }

    /// Whether the tree is the binary fallback (for the tests).
    #[cfg(test)]
    fn is_binary(&self) -> bool {
        matches!(self.tree, Tree::Binary(_))
    }

    fn primitive_indices(&self) -> &[u32] {
        match &self.tree {
            Tree::Wide(b) => &b.primitive_indices,
            Tree::Binary(b) => &b.primitive_indices,
        }
    }
}

/// The binary tree and the wide tree obvhs's `build_cwbvh` makes of `prims`.
fn trees<T: Boundable>(preset: BuildPreset, prims: &[T]) -> (Bvh2, CwBvh) {
    let config = params(preset);
    let mut bvh2 = PlocBuilder::with_capacity(prims.len()).build(
        config.ploc_search_distance,
        prims,
        (0..prims.len() as u32).collect(),
        config.sort_precision,
        config.search_depth_threshold,
    );
    ReinsertionOptimizer::default().run(&mut bvh2, config.reinsertion_batch_ratio, None);
    let wide = bvh2_to_cwbvh(&bvh2, config.max_prims_per_leaf.clamp(1, 3), true, false);
    (bvh2, wide)
}

/// Levels below the root on the longest path of inner nodes of a wide tree (the root alone: 0,
/// as obvhs's `calculate_max_depth` counts for its own assertion).
fn wide_depth(bvh: &CwBvh) -> u32 {
    longest_path(bvh.nodes.len(), |i, out| {
        let node = &bvh.nodes[i];
        for &meta in &node.child_meta {
            // obvhs's layout: an inner child's meta is 24 + its slot, and the inner children
            // are stored in slot order from `child_base_idx`.
            if meta != 0 && (meta & 0b11111) >= 24 {
                let slot = (meta & 0b11111) as u32 - 24;
                let rank = (node.imask as u32 & !(u32::MAX << slot)).count_ones();
                out.push(node.child_base_idx as usize + rank as usize);
            }
        }
    })
    .saturating_sub(1) as u32
}

/// Nodes on the longest root-to-leaf path of a binary tree.
fn binary_depth(bvh: &Bvh2) -> usize {
    longest_path(bvh.nodes.len(), |i, out| {
        let node = &bvh.nodes[i];
        if !node.is_leaf() {
            out.extend([node.first_index as usize, node.first_index as usize + 1]);
        }
    })
}

/// Nodes on the longest path from node 0 of a tree of `nodes` nodes (0 when empty), whose node
/// `i`'s children `children(i, out)` pushes; walked with an explicit stack, since a degenerate
/// tree can be thousands of levels deep.
fn longest_path(nodes: usize, children: impl Fn(usize, &mut Vec<usize>)) -> usize {
    if nodes == 0 {
        return 0;
    }
    let (mut deepest, mut stack, mut kids) = (0, vec![(0usize, 1usize)], Vec::new());
    while let Some((i, depth)) = stack.pop() {
        deepest = deepest.max(depth);
        kids.clear();
        children(i, &mut kids);
        stack.extend(kids.iter().map(|&c| (c, depth + 1)));
    }
    deepest
}

impl ObvhsAccel {
    /// Traverse. obvhs's CWBVH node test clamps a node's entry distance to at least 1e-4 ray
    /// units (`cwbvh::node::EPSILON`), so a node the ray leaves within 1e-4 of its origin is
    /// skipped. Nodes are therefore tested against a ray whose origin sits 2e-4 units before
    /// `tmin` (before the real origin when resuming from 0: hits right at the camera are kept),
    /// while the caller's closure tests primitives against its own unmoved ray, so hit values
    /// never depend on the shift. Resuming from the last hit this skips the nodes behind it.
    fn walk(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        map: Option<&[u32]>,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    ) {
        let tmin = if tmin.is_finite() { tmin.max(0.0) } else { 0.0 };
        // 1e-5 relative covers the f32 rounding of `origin + dir·shift` at large tmin.
        let shift = tmin - tmin * 1e-5 - 2e-4;
        let ray = make_ray(origin + dir * shift, dir, tmax - shift);
        let mut hit = RayHit::none();
        let mut cull = tmax;
        let mut test = |id: usize| {
            let before = cull;
            let prim = match map {
                Some(m) => m[id],
                None => id as u32,
            };
            visit(prim, false, &mut cull);
            if cull < before {
                cull - shift
            } else {
                f32::INFINITY
            }
        };
        // Both traversals shrink the ray's `tmax` to what the closure returns.
        match &self.tree {
            Tree::Wide(b) => {
                b.ray_traverse(ray, &mut hit, |_, id| test(id));
            }
            Tree::Binary(b) => {
                b.ray_traverse(ray, &mut hit, |_, id| test(id));
            }
        }
    }
}

impl Accel for ObvhsAccel {
    fn traverse(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    ) {
        self.walk(
            origin,
            dir,
            0.0,
            tmax,
            Some(self.primitive_indices()),
            visit,
        );
    }

    fn slots(&self) -> Option<&[u32]> {
        Some(self.primitive_indices())
    }

    fn traverse_slots(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    ) {
        self.walk(origin, dir, tmin, tmax, None, visit);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use splatbridge_scene::rng::Rng;

    /// Every primitive a traversal reports, sorted (nothing culled: the closure never lowers
    /// the cull distance).
    fn reported(accel: &ObvhsAccel, o: Vec3, d: Vec3) -> Vec<u32> {
        let mut got = Vec::new();
        accel.traverse(o, d, f32::INFINITY, &mut |p, _, _| got.push(p));
        got.sort_unstable();
        got.dedup();
        got
    }

    /// Boxes the ray enters ahead of its origin, by the reference slab test.
    fn brute(boxes: &[(Vec3, Vec3)], o: Vec3, d: Vec3) -> Vec<u32> {
        (0..boxes.len() as u32)
            .filter(|&i| {
                let (lo, hi) = boxes[i as usize];
                crate::geom::ray_box(o.as_dvec3(), d.as_dvec3(), lo.as_dvec3(), hi.as_dvec3())
                    .is_some_and(|(_, t1)| t1 >= 0.0)
            })
            .collect()
    }

    /// A thousand boxes each holding the next (sizes 1.01^i, centres jittered): the wide
    /// tree is deeper than its traversal stack, so the binary tree is kept, and it reports
    /// exactly the boxes a ray enters. Ordinary random boxes keep the wide tree, with the same
    /// check.
    #[test]
    fn trees_too_deep_for_the_wide_stack_stay_binary() {
        let mut r = Rng::new(1);
        // Nested clusters: at each of 150 sizes, 24 boxes jittered about the centre, so that
        // every level of the tree has several inner children a ray from inside enters.
        let nested: Vec<(Vec3, Vec3)> = (0..3600)
            .map(|i| {
                let s = 1.05f32.powi(i / 24);
                let c = Vec3::new(r.range(-0.1, 0.1), r.range(-0.1, 0.1), r.range(-0.1, 0.1)) * s;
                (c - Vec3::splat(s), c + Vec3::splat(s))
            })
            .collect();
        let scattered: Vec<(Vec3, Vec3)> = (0..3000)
            .map(|_| {
                let c = Vec3::new(r.range(-5.0, 5.0), r.range(-5.0, 5.0), r.range(-5.0, 5.0));
                let h = Vec3::new(r.range(0.01, 0.5), r.range(0.01, 0.5), r.range(0.01, 0.5));
                (c - h, c + h)
            })
            .collect();
        let rays: Vec<(Vec3, Vec3)> = (0..300)
            .map(|_| {
                // Origins inside and outside the boxes, any direction.
                let o = Vec3::new(r.range(-8.0, 8.0), r.range(-8.0, 8.0), r.range(-8.0, 8.0));
                (o, Vec3::new(r.normal(), r.normal(), r.normal()).normalize())
            })
            .collect();
        // Boxes a ray enters that the traversal does not report (a BVH may report more: its
        // nodes are conservative, and the caller tests each primitive).
        let lost = |a: &ObvhsAccel, boxes: &[(Vec3, Vec3)]| -> usize {
            rays.iter()
                .map(|&(o, d)| {
                    let got = reported(a, o, d);
                    brute(boxes, o, d)
                        .iter()
                        .filter(|i| got.binary_search(i).is_err())
                        .count()
                })
                .sum()
        };
        for (boxes, binary) in [(&nested, true), (&scattered, false)] {
            let a = ObvhsAccel::boxes(BuildPreset::Medium, boxes);
            assert_eq!(a.is_binary(), binary);
            let entered: usize = rays.iter().map(|&(o, d)| brute(boxes, o, d).len()).sum();
            assert!(entered > 300, "too few boxes entered to tell: {entered}");
            assert_eq!(lost(&a, boxes), 0, "binary: {binary}");
        }
        // That set's wide tree is beyond the stack obvhs sizes for it (its debug build refuses
        // it). Traversed anyway, these rays lose nothing from it: a group is pushed only where
        // a node leaves two or more hit children behind, which these trees rarely do; the
        // fallback keeps to obvhs's own limit rather than to what a given ray happens to need.
        let (_, wide) = trees(
            BuildPreset::Medium,
            &nested
                .iter()
                .map(|(lo, hi)| Aabb::new(Vec3A::from(*lo), Vec3A::from(*hi)))
                .collect::<Vec<_>>(),
        );
        assert!(wide_depth(&wide) >= WIDE_STACK);
    }
}
