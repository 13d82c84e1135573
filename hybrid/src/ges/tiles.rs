//! Tile lists without sorting: a stable counting sort of items (surfels or Gaussians, in input
//! order) by the tiles their rectangles touch, with an optional per-(item, tile) filter so that
//! Gaussians hidden behind a tile's surfels never enter its list (the hierarchical depth test
//! that gives the hybrid most of its speed).
//!
//! Every tile's list is in item order, whatever the thread count: the items are cut into chunks
//! of a fixed size; pass 1 counts each chunk's kept entries per tile, the offsets reserve each
//! (tile, chunk) its own range (tile-major, then chunk), and pass 2 lets every chunk write its
//! items, in order, into its ranges: the native renderer's counting sort ([`crate::bin`]) with
//! the filter.

use rayon::prelude::*;

use crate::bin::Bins;

/// Items per chunk of the counting sort (fixed, so the split never depends on threads; the
/// result would not either: counting sorts are exact).
const CHUNK: usize = 16_384;

/// A slice written from several threads at positions proven disjoint by the caller.
struct Scatter(*mut u32);
// SAFETY: only used by `bin_rects`, where every position is written by exactly one chunk.
unsafe impl Sync for Scatter {}

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

/// Tile lists of `rects` (`[x0, y0, x1, y1)` in tiles) on a `grid[0] × grid[1]` grid; item `k`
/// enters tile `t` only if `keep(k, t)`. Fails (returns the pair count) above `max_pairs`.
pub fn bin_rects<F>(
    rects: &[[u32; 4]],
    grid: [u32; 2],
    max_pairs: usize,
    keep: F,
) -> Result<Bins, usize>
where
    F: Fn(usize, usize) -> bool + Sync,
{
    let gx = grid[0] as usize;
    let ntiles = gx * grid[1] as usize;
    let chunks = rects.len().div_ceil(CHUNK).max(1);
    // Pass 1: per-chunk, per-tile counts of kept entries.
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
    let mut offsets = Vec::with_capacity(ntiles + 1);
    let mut starts = vec![0usize; chunks * ntiles];
    let mut total = 0usize;
    for t in 0..ntiles {
        offsets.push(total);
        for c in 0..chunks {
            starts[c * ntiles + t] = total;
            total += counts[c * ntiles + t] as usize;
        }
    }
    offsets.push(total);
    if total > max_pairs {
        return Err(total);
    }
    drop(counts);
    // Pass 2: every chunk writes its items into its own reserved ranges.
    let mut list = vec![0u32; total];
    let out = Scatter(list.as_mut_ptr());
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
    Ok(Bins { offsets, list })
}

#[cfg(test)]
mod tests {
    use super::*;
    use splatbridge_scene::rng::Rng;

    /// The chunked counting sort equals the obvious per-tile filter, across chunk boundaries.
    #[test]
    fn filtered_lists_match_naive_lists() {
        let (gx, gy) = (11u32, 6u32);
        let mut rng = Rng::new(5);
        let rects: Vec<[u32; 4]> = (0..2 * CHUNK + 123)
            .map(|_| {
                let x0 = rng.below(gx as u64) as u32;
                let y0 = rng.below(gy as u64) as u32;
                [
                    x0,
                    y0,
                    (x0 + rng.below(4) as u32).min(gx),
                    (y0 + 1 + rng.below(3) as u32).min(gy),
                ]
            })
            .collect();
        let keep = |k: usize, t: usize| (k * 7 + t * 13) % 5 != 0;
        let bins = bin_rects(&rects, [gx, gy], usize::MAX, keep).unwrap();
        let mut pairs = 0;
        for ty in 0..gy {
            for tx in 0..gx {
                let t = (ty * gx + tx) as usize;
                let want: Vec<u32> = (0..rects.len() as u32)
                    .filter(|&k| {
                        let r = rects[k as usize];
                        r[0] <= tx && tx < r[2] && r[1] <= ty && ty < r[3] && keep(k as usize, t)
                    })
                    .collect();
                assert_eq!(bins.tile(t), &want[..], "tile {tx},{ty}");
                pairs += want.len();
            }
        }
        assert_eq!(bins.pairs(), pairs);
        assert_eq!(
            bin_rects(&rects, [gx, gy], pairs - 1, keep).err(),
            Some(pairs)
        );
        let empty = bin_rects(&[], [gx, gy], 0, keep).unwrap();
        assert_eq!(
            (empty.pairs(), empty.offsets.len()),
            (0, (gx * gy) as usize + 1)
        );
    }
}
