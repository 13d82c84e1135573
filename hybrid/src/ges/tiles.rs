//! Tile lists without sorting: a stable counting sort of items (surfels or Gaussians, in input
//! order) by the tiles their rectangles touch, with an optional per-(item, tile) filter so that
//! Gaussians hidden behind a tile's surfels never enter its list (the hierarchical depth test
//! that gives the hybrid most of its speed).
//!
//! Every tile's list is in item order, whatever the thread count: the items are cut into chunks
//! of a fixed size; pass 1 counts each chunk's kept entries per tile, the offsets reserve each
//! (tile, chunk) its own range (tile-major, then chunk), and pass 2 lets every chunk write its
//! items, in order, into its ranges. The sort is the native renderer's
//! ([`crate::bin::bin_filtered`]); this module gives it a fresh `Bins` per frame.

use crate::bin::{bin_filtered, Bins};

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
    let mut bins = Bins::default();
    bin_filtered(rects, grid, max_pairs, keep, &mut bins)?;
    Ok(bins)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bin::CHUNK;
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
        let keep = |k: usize, t: usize| !(k * 7 + t * 13).is_multiple_of(5);
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
