//! Depth ordering and tile binning of projected Gaussians.
//!
//! The reference sorts `(tile, depth)` keys of every tile–Gaussian pair with a radix sort. Here
//! the projected Gaussians are sorted once by view depth, and a stable counting sort by tile then
//! distributes them: every tile's list comes out already in depth order, and the expensive sort
//! is over Gaussians, not over pairs.
//!
//! Ties: the reference's radix sort is stable, so equal depths keep input order. To make the
//! image independent of input order, equal f32 depths are ordered here by the bit patterns of
//! the Gaussians' stored values ([`stored_cmp`]); only exact duplicates then remain tied, and
//! their order cannot change a pixel. (Converted scenes, e.g. from quantised SPZ positions, hold
//! many exactly equal depths, so the tie rule is visible in real images.)

use std::cmp::Ordering;

use rayon::prelude::*;
use splatbridge_scene::GaussianCloud;

use crate::project::Projected;

/// Per-tile lists of Gaussians, front to back, as ranks in the depth order (indices into the
/// depth-sorted splat array, so a tile reads its splats in increasing memory order).
#[derive(Clone, Debug, Default)]
pub struct Bins {
    /// `offsets[t]..offsets[t + 1]` is tile `t`'s range in `list` (tiles row-major).
    pub offsets: Vec<usize>,
    pub list: Vec<u32>,
}

impl Bins {
    pub fn tile(&self, t: usize) -> &[u32] {
        &self.list[self.offsets[t]..self.offsets[t + 1]]
    }

    pub fn pairs(&self) -> usize {
        self.list.len()
    }
}

/// Total order on the stored values of two Gaussians (bit patterns of mean, log-scale,
/// rotation, opacity logit, SH), used to break exact depth ties independently of input order.
pub fn stored_cmp(cloud: &GaussianCloud, i: usize, j: usize) -> Ordering {
    let bits3 = |v: glam::Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
    let q = |v: glam::Quat| [v.w.to_bits(), v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
    bits3(cloud.means[i])
        .cmp(&bits3(cloud.means[j]))
        .then_with(|| bits3(cloud.log_scales[i]).cmp(&bits3(cloud.log_scales[j])))
        .then_with(|| q(cloud.rotations[i]).cmp(&q(cloud.rotations[j])))
        .then_with(|| {
            cloud.opacity_logits[i]
                .to_bits()
                .cmp(&cloud.opacity_logits[j].to_bits())
        })
        .then_with(|| {
            let (a, b) = (cloud.sh_of(i), cloud.sh_of(j));
            a.iter().map(|v| bits3(*v)).cmp(b.iter().map(|v| bits3(*v)))
        })
}

/// Order of the projected Gaussians, front to back: by f32 view depth, exact ties by
/// [`stored_cmp`] (see the module docs).
pub fn depth_order(proj: &[Projected], cloud: &GaussianCloud) -> Vec<u32> {
    // Depths are > near ≥ 0, so the f32 bit patterns order like the values.
    let mut keys: Vec<u64> = proj
        .par_iter()
        .enumerate()
        .map(|(k, p)| ((p.splat.depth.to_bits() as u64) << 32) | k as u64)
        .collect();
    keys.par_sort_unstable();
    let mut order: Vec<u32> = keys.iter().map(|&k| k as u32).collect();
    let mut start = 0;
    while start < keys.len() {
        let hi = keys[start] >> 32;
        let mut end = start + 1;
        while end < keys.len() && keys[end] >> 32 == hi {
            end += 1;
        }
        if end - start > 1 {
            order[start..end].sort_by(|&a, &b| {
                stored_cmp(
                    cloud,
                    proj[a as usize].index as usize,
                    proj[b as usize].index as usize,
                )
            });
        }
        start = end;
    }
    order
}

/// Tile lists for a grid of `grid[0] × grid[1]` tiles. `order` is [`depth_order`]'s result.
/// Fails (returns the pair count) when the lists would exceed `max_pairs`.
pub fn bin_tiles(
    proj: &[Projected],
    order: &[u32],
    grid: [u32; 2],
    max_pairs: usize,
) -> Result<Bins, usize> {
    let (gx, gy) = (grid[0] as usize, grid[1] as usize);
    let ntiles = gx * gy;
    let rects: Vec<[u32; 4]> = order.par_iter().map(|&k| proj[k as usize].rect).collect();

    // Pass 1: per-tile counts (integer sums: the same for any split).
    let chunk = 16_384;
    let counts = rects
        .par_chunks(chunk)
        .map(|rs| {
            let mut c = vec![0u32; ntiles];
            for r in rs {
                for ty in r[1]..r[3] {
                    let row = ty as usize * gx;
                    for tx in r[0]..r[2] {
                        c[row + tx as usize] += 1;
                    }
                }
            }
            c
        })
        .reduce(
            || vec![0u32; ntiles],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        );
    let mut offsets = Vec::with_capacity(ntiles + 1);
    let mut total = 0usize;
    offsets.push(0);
    for &c in &counts {
        total += c as usize;
        offsets.push(total);
    }
    if total > max_pairs {
        return Err(total);
    }

    // Pass 2: bands of tile rows own contiguous slices of the list; each band walks the
    // depth-sorted Gaussians and appends the ones touching its rows, so every tile's list is
    // in depth order.
    let mut list = vec![0u32; total];
    let rows_per_band = gy.div_ceil(32).max(1);
    let mut bands: Vec<(usize, usize, &mut [u32])> = Vec::new();
    let mut rest: &mut [u32] = &mut list;
    let mut row = 0;
    while row < gy {
        let end = (row + rows_per_band).min(gy);
        let len = offsets[end * gx] - offsets[row * gx];
        let (head, tail) = rest.split_at_mut(len);
        bands.push((row, end, head));
        rest = tail;
        row = end;
    }
    bands.into_par_iter().for_each(|(r0, r1, out)| {
        let base = offsets[r0 * gx];
        let mut cursor: Vec<usize> = offsets[r0 * gx..r1 * gx].iter().map(|o| o - base).collect();
        for (rank, r) in rects.iter().enumerate() {
            let y0 = (r[1] as usize).max(r0);
            let y1 = (r[3] as usize).min(r1);
            for ty in y0..y1 {
                let row = (ty - r0) * gx;
                for tx in r[0] as usize..r[2] as usize {
                    let c = &mut cursor[row + tx];
                    out[*c] = rank as u32;
                    *c += 1;
                }
            }
        }
    });
    Ok(Bins { offsets, list })
}
