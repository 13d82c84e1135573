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

/// Sort key of a projected Gaussian: f32 view depth above, its index below. Depths are
/// > near ≥ 0, so the f32 bit patterns order like the values.
#[inline]
pub fn depth_key(depth: f32, index: u32) -> u64 {
    ((depth.to_bits() as u64) << 32) | index as u64
}

/// Sort `keys` ([`depth_key`]s) and write the Gaussian indices front to back into `order`:
/// by f32 view depth, exact ties by [`stored_cmp`] (see the module docs).
pub fn depth_order(keys: &mut [u64], cloud: &GaussianCloud, order: &mut Vec<u32>) {
    depth_order_mapped(keys, cloud, order, |k| k);
}

/// [`depth_order`] for keys whose low words are not Gaussian indices but positions in a
/// subset: `gaussian(k)` maps a key's position to its Gaussian in `cloud`, which ties compare.
/// `order` receives the positions.
pub fn depth_order_mapped(
    keys: &mut [u64],
    cloud: &GaussianCloud,
    order: &mut Vec<u32>,
    gaussian: impl Fn(usize) -> usize,
) {
    keys.par_sort_unstable();
    order.clear();
    order.par_extend(keys.par_iter().map(|&k| k as u32));
    let mut start = 0;
    while start < keys.len() {
        let hi = keys[start] >> 32;
        let mut end = start + 1;
        while end < keys.len() && keys[end] >> 32 == hi {
            end += 1;
        }
        if end - start > 1 {
            order[start..end]
                .sort_by(|&a, &b| stored_cmp(cloud, gaussian(a as usize), gaussian(b as usize)));
        }
        start = end;
    }
}

/// A slice written from several threads at positions proven disjoint by the caller.
struct Scatter(*mut u32);
// SAFETY: only used by `bin_filtered`, where every position is written by exactly one chunk.
unsafe impl Sync for Scatter {}

/// Items per chunk of the counting sort (fixed, so the split never depends on threads;
/// the result would not either: counting sorts are exact).
pub(crate) const CHUNK: usize = 16_384;

/// Calls `f(t)` for every tile `t` of rectangle `r` (`[x0, y0, x1, y1)` in tiles), row-major.
#[inline(always)]
fn for_tiles(r: &[u32; 4], gx: usize, mut f: impl FnMut(usize)) {
    for ty in r[1] as usize..r[3] as usize {
        let row = ty * gx;
        for tx in r[0] as usize..r[2] as usize {
            f(row + tx);
        }
    }
}

/// Tile lists for a grid of `grid[0] × grid[1]` tiles from the tile rectangles `[x0, y0, x1, y1)`
/// of the Gaussians in depth order (`rects[rank]`): a stable counting sort by tile, so each
/// tile's list is in depth order. Fails (returning the pair count) beyond `max_pairs`.
pub fn bin_tiles(
    rects: &[[u32; 4]],
    grid: [u32; 2],
    max_pairs: usize,
    bins: &mut Bins,
) -> Result<(), usize> {
    bin_filtered(rects, grid, max_pairs, |_, _| true, bins)
}

/// The one counting sort of items by the tiles their rectangles touch, shared by the native
/// renderer and the GES passes (`ges::tiles`): item `k` (its index in `rects`) enters tile `t`
/// only if `keep(k, t)`, and every tile's list is in item order whatever the thread count.
///
/// The items are cut into chunks of a fixed size; pass 1 counts each chunk's kept entries per
/// tile, the offsets reserve each (tile, chunk) its own range (tile-major, then chunk), and
/// pass 2 lets every chunk write its items, in order, into its ranges. `bins` keeps its
/// allocations across calls. Fails (returning the pair count) beyond `max_pairs`.
pub fn bin_filtered<F>(
    rects: &[[u32; 4]],
    grid: [u32; 2],
    max_pairs: usize,
    keep: F,
    bins: &mut Bins,
) -> Result<(), usize>
where
    F: Fn(usize, usize) -> bool + Sync,
{
    let gx = grid[0] as usize;
    let ntiles = gx * grid[1] as usize;
    // Pass 1: per-chunk, per-tile counts of kept entries.
    let chunks = rects.len().div_ceil(CHUNK).max(1);
    let mut counts = vec![0u32; chunks * ntiles];
    counts
        .par_chunks_mut(ntiles)
        .zip(rects.par_chunks(CHUNK))
        .enumerate()
        .for_each(|(c, (n, rs))| {
            for (j, r) in rs.iter().enumerate() {
                let k = c * CHUNK + j;
                for_tiles(r, gx, |t| n[t] += keep(k, t) as u32);
            }
        });
    // Offsets: tile-major, then chunk, so chunk c's entries of a tile follow chunk c−1's.
    bins.offsets.clear();
    bins.offsets.reserve(ntiles + 1);
    let mut total = 0usize;
    let mut starts = vec![0usize; chunks * ntiles];
    for t in 0..ntiles {
        bins.offsets.push(total);
        for c in 0..chunks {
            starts[c * ntiles + t] = total;
            total += counts[c * ntiles + t] as usize;
        }
    }
    bins.offsets.push(total);
    if total > max_pairs {
        return Err(total);
    }
    drop(counts);
    // Pass 2: every chunk writes its items into its own reserved ranges.
    bins.list.clear();
    bins.list.resize(total, 0);
    let out = Scatter(bins.list.as_mut_ptr());
    starts
        .par_chunks_mut(ntiles)
        .zip(rects.par_chunks(CHUNK))
        .enumerate()
        .for_each(|(c, (cur, rs))| {
            let out = &out;
            for (j, r) in rs.iter().enumerate() {
                let k = c * CHUNK + j;
                for_tiles(r, gx, |t| {
                    if keep(k, t) {
                        // SAFETY: `cur[t]` runs over the range reserved for (tile t, chunk c),
                        // which no other chunk touches and which lies inside `list` (pass 1
                        // counted exactly these entries, `keep` being a pure function).
                        unsafe { out.0.add(cur[t]).write(k as u32) };
                        cur[t] += 1;
                    }
                });
            }
        });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use splatbridge_scene::rng::Rng;

    /// The parallel counting sort equals the obvious per-tile filter, across chunk boundaries.
    #[test]
    fn counting_sort_matches_naive_lists() {
        let grid = [13u32, 7u32];
        let mut rng = Rng::new(1);
        let rects: Vec<[u32; 4]> = (0..3 * CHUNK + 17)
            .map(|_| {
                let x0 = rng.below(13) as u32;
                let y0 = rng.below(7) as u32;
                [
                    x0,
                    y0,
                    (x0 + 1 + rng.below(3) as u32).min(13),
                    (y0 + 1 + rng.below(2) as u32).min(7),
                ]
            })
            .collect();
        let mut bins = Bins::default();
        bin_tiles(&rects, grid, usize::MAX, &mut bins).unwrap();
        for ty in 0..7u32 {
            for tx in 0..13u32 {
                let want: Vec<u32> = (0..rects.len() as u32)
                    .filter(|&k| {
                        let r = rects[k as usize];
                        r[0] <= tx && tx < r[2] && r[1] <= ty && ty < r[3]
                    })
                    .collect();
                assert_eq!(
                    bins.tile((ty * 13 + tx) as usize),
                    &want[..],
                    "tile {tx},{ty}"
                );
            }
        }
        assert!(bin_tiles(&rects, grid, 10, &mut bins).is_err());
    }
}
