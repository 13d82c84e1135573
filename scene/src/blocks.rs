//! Spatial blocks: an adaptive octree over Gaussian centres, split by Gaussian count, for
//! tiled outputs (3D Tiles) and for `info --blocks`.
//!
//! Partition rule: a block with more than `max_per_block` Gaussians is split at the midpoint
//! of its cell, along every axis whose extent is at least half the cell's longest extent
//! (an octree cell in a cube-like region, a quadtree on the ground plane of a flat region,
//! a binary split along a street). Axis-adaptive splitting keeps blocks near-cubic in any
//! capture shape, so a street-length scene does not fill an octree with empty thin cells;
//! empty children are dropped. A Gaussian goes to the child whose half-open octant holds
//! its centre (`c < mid` is the low side), so each Gaussian is in exactly one leaf.
//! Splitting stops at [`MAX_DEPTH`] (many Gaussians at one centre cannot be separated),
//! where a leaf may exceed the budget; the report counts such leaves.
//!
//! Overlap rule: a Gaussian belongs to the block of its centre only; its 3σ footprint (the
//! axis-aligned box of its 3σ ellipsoid, half extent `3·sqrt(Σ_aa)` per axis) may cross the
//! cell border, so each block carries a `footprint` box that contains every footprint of its
//! subtree: bounding volumes grow to contain what the block draws, and neighbours' volumes
//! may overlap. Invalid Gaussians (NaN, zero quaternion) are left out and counted.

use glam::Vec3;

use crate::gaussians::GaussianCloud;

/// Default Gaussian budget of a block.
pub const DEFAULT_MAX_PER_BLOCK: usize = 65_536;
/// Depth at which splitting stops: a cell 2⁻²⁰ of the scene is below f32 resolution of
/// positions far from the origin anyway.
pub const MAX_DEPTH: u32 = 20;
/// Footprint radius in standard deviations (the kernel's visible extent, as 3DGS's 3σ cut).
pub const FOOTPRINT_SIGMAS: f32 = 3.0;

/// An axis-aligned box; empty when `min > max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn is_empty(&self) -> bool {
        !(self.min.cmple(self.max).all())
    }

    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    pub fn centre(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    pub fn half_extent(&self) -> Vec3 {
        0.5 * (self.max - self.min)
    }
}

/// The 3σ footprint box of Gaussian `i` (see the module's overlap rule).
pub fn footprint(cloud: &GaussianCloud, i: usize) -> Aabb {
    let c = cloud.covariance(i);
    let r = FOOTPRINT_SIGMAS
        * Vec3::new(
            c.x_axis.x.max(0.0).sqrt(),
            c.y_axis.y.max(0.0).sqrt(),
            c.z_axis.z.max(0.0).sqrt(),
        );
    let m = cloud.means[i];
    Aabb {
        min: m - r,
        max: m + r,
    }
}

/// One block of the partition.
#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    /// The octree cell (a box of the partition; cells of siblings do not overlap).
    pub cell: Aabb,
    pub depth: u32,
    /// Child blocks (indices into [`Blocks::blocks`]); empty for a leaf.
    pub children: Vec<usize>,
    /// The Gaussians of the subtree: `order[range]`.
    pub range: std::ops::Range<usize>,
    /// Box of the subtree's centres.
    pub centres: Aabb,
    /// Box of the subtree's 3σ footprints (contains `centres`).
    pub footprint: Aabb,
}

impl Block {
    pub fn is_leaf(&self) -> bool {
        self.children.is_empty()
    }

    pub fn count(&self) -> usize {
        self.range.len()
    }
}

/// The partition: blocks in depth-first pre-order (root first, a parent before its
/// children) and a permutation of the valid Gaussians in which every block's Gaussians are
/// contiguous.
#[derive(Clone, Debug, PartialEq)]
pub struct Blocks {
    pub blocks: Vec<Block>,
    pub order: Vec<u32>,
    /// Gaussians left out as invalid.
    pub invalid: usize,
    pub max_per_block: usize,
}

impl Blocks {
    /// Partition `cloud` with at most `max_per_block` Gaussians per leaf (1 at least).
    pub fn build(cloud: &GaussianCloud, max_per_block: usize) -> Blocks {
        let max_per_block = max_per_block.max(1);
        let mut order: Vec<u32> = (0..cloud.len() as u32)
            .filter(|&i| cloud.invalid_reason(i as usize).is_none())
            .collect();
        let invalid = cloud.len() - order.len();
        let mut blocks = Vec::new();
        if !order.is_empty() {
            let mut cell = Aabb::EMPTY;
            order
                .iter()
                .for_each(|&i| cell.grow(cloud.means[i as usize]));
            let mut scratch = vec![0u32; order.len()];
            let n = order.len();
            split(
                cloud,
                &mut order,
                &mut scratch,
                0..n,
                cell,
                0,
                max_per_block,
                &mut blocks,
            );
        }
        Blocks {
            blocks,
            order,
            invalid,
            max_per_block,
        }
    }

    /// The leaves in pre-order.
    pub fn leaves(&self) -> impl Iterator<Item = &Block> {
        self.blocks.iter().filter(|b| b.is_leaf())
    }

    /// The Gaussians of block `b`.
    pub fn indices(&self, b: &Block) -> &[u32] {
        &self.order[b.range.clone()]
    }

    /// A summary for reports: counts, depths, leaf sizes and the root's bounds.
    pub fn summary(&self) -> serde_json::Value {
        let leaves: Vec<&Block> = self.leaves().collect();
        let mut sizes: Vec<usize> = leaves.iter().map(|b| b.count()).collect();
        sizes.sort_unstable();
        let q = |p: f64| -> usize {
            if sizes.is_empty() {
                0
            } else {
                sizes[((sizes.len() - 1) as f64 * p).round() as usize]
            }
        };
        let max_depth = self.blocks.iter().map(|b| b.depth).max().unwrap_or(0);
        let mut per_depth = vec![0usize; max_depth as usize + 1];
        leaves.iter().for_each(|b| per_depth[b.depth as usize] += 1);
        let root = self.blocks.first();
        let bx = |a: Option<Aabb>| match a {
            Some(a) if !a.is_empty() => {
                serde_json::json!({"min": a.min.to_array(), "max": a.max.to_array()})
            }
            _ => serde_json::Value::Null,
        };
        serde_json::json!({
            "max_per_block": self.max_per_block,
            "gaussians": self.order.len(),
            "invalid_left_out": self.invalid,
            "blocks": self.blocks.len(),
            "leaves": leaves.len(),
            "max_depth": max_depth,
            "leaves_per_depth": per_depth,
            "leaf_size": {"min": q(0.0), "median": q(0.5), "max": q(1.0)},
            "leaves_over_budget": sizes.iter().filter(|&&s| s > self.max_per_block).count(),
            "cell": bx(root.map(|r| r.cell)),
            "footprint": bx(root.map(|r| r.footprint)),
        })
    }
}

/// Which half-open octant of `mid` holds `p`, over the split axes (`axes[a]`).
fn octant(p: Vec3, mid: Vec3, axes: [bool; 3]) -> usize {
    let mut k = 0;
    for a in 0..3 {
        if axes[a] && p[a] >= mid[a] {
            k |= 1 << a;
        }
    }
    k
}

/// Recursive split of `order[range]` (cell `cell`) into blocks; returns the block index.
#[allow(clippy::too_many_arguments)]
fn split(
    cloud: &GaussianCloud,
    order: &mut [u32],
    scratch: &mut [u32],
    range: std::ops::Range<usize>,
    cell: Aabb,
    depth: u32,
    max: usize,
    blocks: &mut Vec<Block>,
) -> usize {
    let me = blocks.len();
    blocks.push(Block {
        cell,
        depth,
        children: Vec::new(),
        range: range.clone(),
        centres: Aabb::EMPTY,
        footprint: Aabb::EMPTY,
    });
    let ext = cell.max - cell.min;
    let longest = ext.max_element();
    let axes = [0, 1, 2].map(|a| ext[a] >= 0.5 * longest && ext[a] > 0.0);
    if range.len() <= max || depth >= MAX_DEPTH || !axes.iter().any(|&a| a) {
        let (mut c, mut f) = (Aabb::EMPTY, Aabb::EMPTY);
        for &i in &order[range.clone()] {
            c.grow(cloud.means[i as usize]);
            f = f.union(&footprint(cloud, i as usize));
        }
        blocks[me].centres = c;
        blocks[me].footprint = f;
        return me;
    }
    let mid = cell.centre();
    // Counting sort of the range by octant: stable, so the order inside a block stays the
    // input order (deterministic output).
    let mut counts = [0usize; 8];
    for &i in &order[range.clone()] {
        counts[octant(cloud.means[i as usize], mid, axes)] += 1;
    }
    let mut starts = [0usize; 8];
    for k in 1..8 {
        starts[k] = starts[k - 1] + counts[k - 1];
    }
    let mut next = starts;
    for &i in &order[range.clone()] {
        let k = octant(cloud.means[i as usize], mid, axes);
        scratch[range.start + next[k]] = i;
        next[k] += 1;
    }
    order[range.clone()].copy_from_slice(&scratch[range.clone()]);
    let (mut c, mut f) = (Aabb::EMPTY, Aabb::EMPTY);
    for k in 0..8 {
        if counts[k] == 0 {
            continue;
        }
        let mut sub = cell;
        for a in 0..3 {
            if axes[a] {
                if k & (1 << a) != 0 {
                    sub.min[a] = mid[a];
                } else {
                    sub.max[a] = mid[a];
                }
            }
        }
        let r = range.start + starts[k]..range.start + starts[k] + counts[k];
        let child = split(cloud, order, scratch, r, sub, depth + 1, max, blocks);
        c = c.union(&blocks[child].centres);
        f = f.union(&blocks[child].footprint);
        blocks[me].children.push(child);
    }
    blocks[me].centres = c;
    blocks[me].footprint = f;
    me
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    fn cloud(points: &[Vec3]) -> GaussianCloud {
        let mut c = GaussianCloud::new(0);
        for &p in points {
            c.push_activated(p, Vec3::splat(0.05), Quat::IDENTITY, 0.5, Vec3::splat(0.5));
        }
        c
    }

    #[test]
    fn every_gaussian_in_exactly_one_leaf_inside_its_cell() {
        let mut rng = crate::rng::Rng::new(7);
        let pts: Vec<Vec3> = (0..5000)
            .map(|_| Vec3::new(rng.f32() * 100.0, rng.f32() * 3.0, rng.f32() * 10.0))
            .collect();
        let c = cloud(&pts);
        let b = Blocks::build(&c, 100);
        let mut seen = vec![0u32; pts.len()];
        for leaf in b.leaves() {
            assert!(leaf.count() <= 100);
            for &i in b.indices(leaf) {
                seen[i as usize] += 1;
                assert!(leaf.cell.contains(pts[i as usize]));
                assert!(leaf
                    .footprint
                    .contains(pts[i as usize] + Vec3::splat(0.149)));
            }
        }
        assert!(seen.iter().all(|&s| s == 1));
        // A street-like extent splits along its long axis first, not into 8 thin cells.
        assert_eq!(b.blocks[0].children.len(), 2);
    }

    #[test]
    fn duplicates_stop_at_max_depth() {
        let c = cloud(&[Vec3::ONE; 50]);
        let b = Blocks::build(&c, 4);
        assert_eq!(b.blocks.len(), 1);
        assert_eq!(b.summary()["leaves_over_budget"], 1);
    }
}
