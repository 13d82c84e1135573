//! Gaussian scales for points read without any (`super::variant`, [`super::GaussianKind::Points`]),
//! by 3DGS's own initialisation from a point cloud (graphdeco-inria `gaussian-splatting`,
//! `scene/gaussian_model.py`, `create_from_pcd`): each point's scale is isotropic, the square
//! root of the mean squared distance to its 3 nearest neighbours (`simple_knn`'s `distCUDA2`),
//! floored at a squared distance of 1e-7 as there (`torch.clamp_min(dist2, 0.0000001)`).
//!
//! Neighbours are found in a uniform grid whose cell is halved until occupied cells hold 8
//! points or fewer on average; each query visits shells of cells outwards until the third
//! nearest distance is closer than the next shell can be. Bounds that keep every input finite
//! and fast: at most [`MAX_CANDIDATES`] points examined and [`MAX_SHELLS`] shells visited per
//! point (in a pile of identical points the distances found are then upper bounds, floored
//! anyway; a point with no neighbour within the shells gets the shells' radius, a lower
//! bound). The brute-force reference in the tests checks the grid against every pair.

use std::collections::HashMap;

use glam::Vec3;
use rayon::prelude::*;

use crate::GaussianCloud;

/// 3DGS's floor on the mean squared neighbour distance.
const MIN_DIST2: f64 = 1e-7;
/// Neighbours averaged (3DGS's `distCUDA2`).
const K: usize = 3;
/// Points examined per query at most.
const MAX_CANDIDATES: usize = 512;
/// Shells of cells visited per query at most.
const MAX_SHELLS: i64 = 16;
/// Average points per occupied cell the grid is refined to.
const TARGET_OCCUPANCY: usize = 8;

/// Set every Gaussian's log-scales to the 3DGS initial scale of its point.
pub(crate) fn neighbour_scales(cloud: &mut GaussianCloud) {
    let d2 = mean_sq_dist_knn(&cloud.means);
    for (l, d) in cloud.log_scales.iter_mut().zip(d2) {
        *l = Vec3::splat((0.5 * d.max(MIN_DIST2).ln()) as f32);
    }
}

type Key = (i64, i64, i64);

struct Grid {
    lo: Vec3,
    cell: f32,
    /// Point indices sorted by cell.
    order: Vec<u32>,
    /// Cell → range of `order`.
    cells: HashMap<Key, (u32, u32)>,
}

impl Grid {
    fn key(&self, p: Vec3) -> Key {
        let k = ((p - self.lo) / self.cell).floor();
        (k.x as i64, k.y as i64, k.z as i64)
    }

    fn build(points: &[Vec3], lo: Vec3, cell: f32) -> Grid {
        let mut g = Grid {
            lo,
            cell,
            order: Vec::new(),
            cells: HashMap::new(),
        };
        let mut keyed: Vec<(Key, u32)> = points
            .iter()
            .enumerate()
            .filter(|(_, p)| p.is_finite())
            .map(|(i, &p)| (g.key(p), i as u32))
            .collect();
        keyed.sort_unstable();
        let mut start = 0;
        for i in 1..=keyed.len() {
            if i == keyed.len() || keyed[i].0 != keyed[start].0 {
                g.cells.insert(keyed[start].0, (start as u32, i as u32));
                start = i;
            }
        }
        g.order = keyed.into_iter().map(|(_, i)| i).collect();
        g
    }
}

/// Mean squared distance of each point to its `K` nearest others (see the module docs for
/// the bounds); non-finite points get the floor (the invalid-Gaussian policy names them).
pub(crate) fn mean_sq_dist_knn(points: &[Vec3]) -> Vec<f64> {
    let finite: Vec<Vec3> = points.iter().copied().filter(|p| p.is_finite()).collect();
    let (Some(lo), Some(hi)) = (
        finite.iter().copied().reduce(Vec3::min),
        finite.iter().copied().reduce(Vec3::max),
    ) else {
        return vec![MIN_DIST2; points.len()];
    };
    let extent = (hi - lo).max_element();
    if finite.len() < 2 || !(extent > 0.0) || !extent.is_finite() {
        return vec![MIN_DIST2; points.len()];
    }
    let mut cell = extent / (finite.len() as f32).cbrt();
    let mut grid = Grid::build(points, lo, cell);
    for _ in 0..12 {
        if finite.len() <= TARGET_OCCUPANCY * grid.cells.len() {
            break;
        }
        cell *= 0.5;
        grid = Grid::build(points, lo, cell);
    }
    points
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            if !p.is_finite() {
                return MIN_DIST2;
            }
            query(&grid, points, i, p)
        })
        .collect()
}

fn query(g: &Grid, points: &[Vec3], i: usize, p: Vec3) -> f64 {
    let mut best = [f64::INFINITY; K];
    let (cx, cy, cz) = g.key(p);
    let mut examined = 0;
    let mut r = 0i64;
    loop {
        for dx in -r..=r {
            for dy in -r..=r {
                for dz in -r..=r {
                    if dx.abs().max(dy.abs()).max(dz.abs()) != r {
                        continue;
                    }
                    let Some(&(a, b)) = g.cells.get(&(cx + dx, cy + dy, cz + dz)) else {
                        continue;
                    };
                    for &j in &g.order[a as usize..b as usize] {
                        if j as usize == i || examined >= MAX_CANDIDATES {
                            continue;
                        }
                        examined += 1;
                        let d = (points[j as usize] - p).as_dvec3().length_squared();
                        if d < best[K - 1] {
                            best[K - 1] = d;
                            best.sort_unstable_by(f64::total_cmp);
                        }
                    }
                }
            }
        }
        // Every point beyond shell r is at least r cells away.
        let reach = r as f64 * g.cell as f64;
        if best[K - 1] <= reach * reach || examined >= MAX_CANDIDATES || r >= MAX_SHELLS {
            break;
        }
        r += 1;
    }
    let found: Vec<f64> = best.into_iter().filter(|d| d.is_finite()).collect();
    if found.is_empty() {
        let reach = r as f64 * g.cell as f64;
        return reach * reach;
    }
    found.iter().sum::<f64>() / found.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The obviously correct reference: every pair.
    fn brute(points: &[Vec3]) -> Vec<f64> {
        points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let mut d: Vec<f64> = points
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != i)
                    .map(|(_, q)| (*q - *p).as_dvec3().length_squared())
                    .collect();
                d.sort_by(f64::total_cmp);
                let k = d.len().min(K);
                d[..k].iter().sum::<f64>() / k as f64
            })
            .collect()
    }

    #[test]
    fn grid_matches_brute_force_on_clouds_and_surfaces() {
        let mut rng = crate::rng::Rng::new(7);
        // A volume, a plane and two far clusters of different densities.
        let mut clouds: Vec<Vec<Vec3>> = Vec::new();
        clouds.push(
            (0..2000)
                .map(|_| Vec3::new(rng.f32(), rng.f32(), rng.f32()))
                .collect(),
        );
        clouds.push(
            (0..2000)
                .map(|_| Vec3::new(rng.f32(), 0.0, rng.f32()))
                .collect(),
        );
        clouds.push(
            (0..1000)
                .map(|k| {
                    let c = if k % 2 == 0 {
                        Vec3::ZERO
                    } else {
                        Vec3::splat(50.0)
                    };
                    c + Vec3::new(rng.f32(), rng.f32(), rng.f32()) * (1.0 + (k % 2) as f32 * 4.0)
                })
                .collect(),
        );
        for pts in &clouds {
            let fast = mean_sq_dist_knn(pts);
            let slow = brute(pts);
            for (a, b) in fast.iter().zip(&slow) {
                // Same f64 sums of the same distances, possibly in another order: 1e-12
                // relative covers the reordering.
                assert!((a - b).abs() <= 1e-12 * b.max(1e-30), "{a} vs {b}");
            }
        }
    }

    #[test]
    fn degenerate_clouds_are_finite_and_floored() {
        for pts in [
            vec![],
            vec![Vec3::ONE],
            vec![Vec3::ONE; 5000],
            vec![Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X],
        ] {
            let mut c = GaussianCloud::new(0);
            for &p in &pts {
                c.push(p, Vec3::ZERO, glam::Quat::IDENTITY, 0.0, &[Vec3::ZERO]);
            }
            neighbour_scales(&mut c);
            for l in &c.log_scales {
                assert!(l.is_finite(), "{pts:?}");
                assert!(l.x >= (0.5 * MIN_DIST2.ln()) as f32);
            }
        }
    }
}
