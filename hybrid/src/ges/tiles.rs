//! Tile lists without sorting: a stable counting sort of items (surfels or Gaussians, in input
//! order) by the tiles their rectangles touch, with an optional per-(item, tile) filter so that
//! Gaussians hidden behind a tile's surfels never enter its list (the hierarchical depth test
//! that gives the hybrid most of its speed).
//!
//! Every tile's list is in item order, whatever the thread count: pass 1 counts (integer sums),
//! pass 2 lets bands of tile rows walk the items in order and append to their own slices.

use rayon::prelude::*;

use crate::bin::Bins;

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
    let (gx, gy) = (grid[0] as usize, grid[1] as usize);
    let ntiles = gx * gy;
    let chunk = 16_384;
    let counts = rects
        .par_chunks(chunk)
        .enumerate()
        .map(|(c, rs)| {
            let mut n = vec![0u32; ntiles];
            for (j, r) in rs.iter().enumerate() {
                let k = c * chunk + j;
                for ty in r[1] as usize..r[3] as usize {
                    for tx in r[0] as usize..r[2] as usize {
                        let t = ty * gx + tx;
                        n[t] += keep(k, t) as u32;
                    }
                }
            }
            n
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
        for (k, r) in rects.iter().enumerate() {
            let y0 = (r[1] as usize).max(r0);
            let y1 = (r[3] as usize).min(r1);
            for ty in y0..y1 {
                for tx in r[0] as usize..r[2] as usize {
                    let t = ty * gx + tx;
                    if keep(k, t) {
                        let c = &mut cursor[(ty - r0) * gx + tx];
                        out[*c] = k as u32;
                        *c += 1;
                    }
                }
            }
        }
    });
    Ok(Bins { offsets, list })
}
