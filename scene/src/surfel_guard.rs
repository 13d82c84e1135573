//! Guards of the surfel split ([`crate::surfels::split`]): a Gaussian that passes the local
//! opacity and flatness test becomes an opaque surfel only where a hard disc is a fair stand-in
//! for what native splatting draws there. Three rules, each a field of
//! [`crate::surfels::SplitParams`]:
//!
//! - **Scene scale** (`max_scene_fraction`): the disc's footprint radius `3.33·s_u` must be at
//!   most this fraction of the scene's robust extent (the diagonal of the 2 %–98 % percentile
//!   box of the means, [`GaussianCloud::robust_bounds`]). Failure prevented: a large, flat,
//!   opaque background or floater Gaussian — soft and half hidden in native splatting, where the
//!   Gaussians in front of it are blended over its fading tail — becomes a wall-sized hard disc
//!   that occludes everything behind it and cuts the Gaussians in front off at `D_S + ε`.
//! - **Neighbourhood size** (`max_neighbour_ratio`): `s_u` must be at most this multiple of the
//!   median largest scale of its [`NEIGHBOURS_K`] nearest Gaussians whose centres lie inside the
//!   footprint radius. Failure prevented: one Gaussian much larger than the detail around it (a
//!   coarse "fill" under fine geometry) turns into a disc that paints over that detail, since
//!   the residual Gaussians within `ε` of it are averaged with its colour and those behind it
//!   are culled.
//! - **Isolation** (`min_neighbours`): at least this many other Gaussian centres must lie within
//!   the footprint radius. Failure prevented: an isolated floater (a lone opaque Gaussian in
//!   the air, faint in native splatting because it is small on screen or blended over by
//!   nothing) becomes a hard-edged disc in front of the surface.
//!
//! A candidate the rules cannot judge (no neighbour to compare with while the neighbourhood
//! rule is on; a scene without robust bounds while the scene rule is on) stays a Gaussian.
//!
//! Neighbours are found in a uniform grid of cell size `extent / cbrt(n)`, its cells sorted by
//! key (O(n log n) to build); each candidate's query visits the cells its footprint ball
//! touches (or, when that box has more cells than the grid has occupied cells, the occupied
//! cells). Queries run in parallel and each result depends on its candidate only, so the split
//! is the same at any thread count.

use std::collections::HashMap;

use glam::Vec3;
use rayon::prelude::*;

use crate::gaussians::GaussianCloud;
use crate::surfels::FOOTPRINT_SIGMAS;

/// Neighbours whose largest scales give the neighbourhood size (their median). 16 is the
/// customary k of a point cloud's local-scale estimate (3DGS initialises each scale from the
/// 3 nearest; 16 makes the median robust to a few large neighbours).
pub const NEIGHBOURS_K: usize = 16;

/// Percentile of the robust bounds behind the scene-scale rule (as the orbit cameras' framing).
pub const ROBUST_PERCENTILE: f32 = 0.02;

/// Cells of one grid axis are clamped to ±2²⁰ so keys fit and far outliers share edge cells.
const MAX_CELL: i64 = 1 << 20;

/// The thresholds of the three rules (copied from `SplitParams`).
#[derive(Clone, Copy, Debug)]
pub struct GuardParams {
    pub max_scene_fraction: f32,
    pub max_neighbour_ratio: f32,
    pub min_neighbours: u32,
}

impl GuardParams {
    /// Whether any rule needs the neighbour grid.
    fn needs_grid(&self) -> bool {
        self.min_neighbours > 0 || self.max_neighbour_ratio.is_finite()
    }

    /// Whether every rule is off (no guard work at all).
    pub fn is_off(&self) -> bool {
        !self.needs_grid() && !self.max_scene_fraction.is_finite()
    }
}

/// Why a candidate stayed a Gaussian (counts, for reports and tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GuardCounts {
    /// Candidates that passed the opacity and flatness test.
    pub candidates: usize,
    /// Rejected as too large for the scene.
    pub too_large_for_scene: usize,
    /// Rejected as isolated.
    pub isolated: usize,
    /// Rejected as much larger than their neighbours (or without neighbours to compare with).
    pub too_large_for_neighbours: usize,
}

/// Robust extent of a cloud: the diagonal of its 2 %–98 % box of means.
pub fn robust_extent(cloud: &GaussianCloud) -> Option<f32> {
    let (lo, hi) = cloud.robust_bounds(ROBUST_PERCENTILE)?;
    let d = (hi - lo).length();
    (d.is_finite() && d > 0.0).then_some(d)
}

/// Uniform grid over the finite means, cells sorted by key.
struct Grid {
    origin: Vec3,
    inv_cell: f32,
    /// Gaussian indices grouped by cell.
    order: Vec<u32>,
    /// Cell → range in `order`.
    cells: HashMap<[i32; 3], (u32, u32)>,
}

impl Grid {
    fn new(cloud: &GaussianCloud, extent: f32) -> Grid {
        let n = cloud.len().max(1) as f32;
        let cell = (extent / n.cbrt()).max(f32::MIN_POSITIVE);
        let origin = cloud
            .robust_bounds(ROBUST_PERCENTILE)
            .map(|(lo, _)| lo)
            .unwrap_or(Vec3::ZERO);
        let mut g = Grid {
            origin,
            inv_cell: 1.0 / cell,
            order: Vec::new(),
            cells: HashMap::new(),
        };
        let mut keyed: Vec<([i32; 3], u32)> = cloud
            .means
            .iter()
            .enumerate()
            .filter(|(_, m)| m.is_finite())
            .map(|(i, &m)| (g.key(m), i as u32))
            .collect();
        keyed.par_sort_unstable();
        g.order = keyed.iter().map(|&(_, i)| i).collect();
        let mut start = 0usize;
        while start < keyed.len() {
            let k = keyed[start].0;
            let mut end = start + 1;
            while end < keyed.len() && keyed[end].0 == k {
                end += 1;
            }
            g.cells.insert(k, (start as u32, end as u32));
            start = end;
        }
        g
    }

    fn coord(&self, x: f32) -> i32 {
        let c = (x * self.inv_cell).floor();
        // NaN cannot reach here (means are filtered, radii are finite); ±inf clamp.
        (c as i64).clamp(-MAX_CELL, MAX_CELL) as i32
    }

    fn key(&self, p: Vec3) -> [i32; 3] {
        let q = p - self.origin;
        [self.coord(q.x), self.coord(q.y), self.coord(q.z)]
    }

    /// Calls `f(j)` for every Gaussian `j` in a cell the ball (centre, radius) touches.
    fn for_each_near(&self, centre: Vec3, radius: f32, mut f: impl FnMut(u32)) {
        let lo = self.key(centre - Vec3::splat(radius));
        let hi = self.key(centre + Vec3::splat(radius));
        let span = |a: usize| (hi[a] as i64 - lo[a] as i64 + 1) as u128;
        let boxed = span(0) * span(1) * span(2);
        let mut visit = |range: &(u32, u32)| {
            for &j in &self.order[range.0 as usize..range.1 as usize] {
                f(j);
            }
        };
        if boxed > self.cells.len() as u128 {
            for (k, range) in &self.cells {
                if (0..3).all(|a| (lo[a]..=hi[a]).contains(&k[a])) {
                    visit(range);
                }
            }
            return;
        }
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    if let Some(r) = self.cells.get(&[x, y, z]) {
                        visit(r);
                    }
                }
            }
        }
    }
}

/// Verdict on one candidate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Verdict {
    Surfel,
    TooLargeForScene,
    Isolated,
    TooLargeForNeighbours,
}

fn judge(
    cloud: &GaussianCloud,
    grid: Option<&Grid>,
    extent: Option<f32>,
    p: &GuardParams,
    i: usize,
    su: f32,
) -> Verdict {
    let radius = FOOTPRINT_SIGMAS * su;
    if p.max_scene_fraction.is_finite() {
        match extent {
            Some(e) if radius <= p.max_scene_fraction * e => {}
            _ => return Verdict::TooLargeForScene,
        }
    }
    let Some(grid) = grid else {
        return Verdict::Surfel;
    };
    let c = cloud.means[i];
    let r2 = radius * radius;
    let mut near: Vec<(f32, u32)> = Vec::new();
    grid.for_each_near(c, radius, |j| {
        if j as usize == i {
            return;
        }
        let d2 = (cloud.means[j as usize] - c).length_squared();
        if d2 <= r2 {
            near.push((d2, j));
        }
    });
    if near.len() < p.min_neighbours as usize {
        return Verdict::Isolated;
    }
    if p.max_neighbour_ratio.is_finite() {
        if near.is_empty() {
            return Verdict::TooLargeForNeighbours;
        }
        let k = near.len().min(NEIGHBOURS_K);
        if near.len() > k {
            // Ties broken by index so the set does not depend on the visiting order.
            near.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        }
        let mut sizes: Vec<f32> = near[..k]
            .iter()
            .map(|&(_, j)| cloud.scale(j as usize).max_element())
            .collect();
        sizes.sort_by(f32::total_cmp);
        let median = sizes[k / 2];
        let limit = p.max_neighbour_ratio * median;
        // A NaN neighbour size cannot vouch for the surfel.
        if su.is_nan() || limit.is_nan() || su > limit {
            return Verdict::TooLargeForNeighbours;
        }
    }
    Verdict::Surfel
}

/// Judge the candidates (`(index, s_u)`: Gaussians that passed the local test, with their
/// largest scale); returns per candidate whether it stays a surfel, and the counts.
pub fn guard(
    cloud: &GaussianCloud,
    candidates: &[(usize, f32)],
    p: &GuardParams,
) -> (Vec<bool>, GuardCounts) {
    let mut counts = GuardCounts {
        candidates: candidates.len(),
        ..Default::default()
    };
    if p.is_off() || candidates.is_empty() {
        return (vec![true; candidates.len()], counts);
    }
    let extent = robust_extent(cloud);
    let grid = match (p.needs_grid(), extent) {
        (true, Some(e)) => Some(Grid::new(cloud, e)),
        // Without an extent there is no grid scale: nothing can be judged, so nothing passes.
        (true, None) => {
            counts.isolated = candidates.len();
            return (vec![false; candidates.len()], counts);
        }
        (false, _) => None,
    };
    let verdicts: Vec<Verdict> = candidates
        .par_iter()
        .map(|&(i, su)| judge(cloud, grid.as_ref(), extent, p, i, su))
        .collect();
    let keep = verdicts
        .iter()
        .map(|v| {
            match v {
                Verdict::Surfel => {}
                Verdict::TooLargeForScene => counts.too_large_for_scene += 1,
                Verdict::Isolated => counts.isolated += 1,
                Verdict::TooLargeForNeighbours => counts.too_large_for_neighbours += 1,
            }
            *v == Verdict::Surfel
        })
        .collect();
    (keep, counts)
}
