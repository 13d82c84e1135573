//! A screen tile's depth-ordered candidate list split into `cell`×`cell`-pixel cells, shared
//! by the two tile paths (`gaussian::tiles` for Gaussians, `mesh_tiles` for triangles): a ray
//! then scans only the entries whose screen rectangles reach its cell, in the tile's order.

use crate::geom::floor;

/// Tile `(tx, ty)`'s `list` (tiles of `tile` pixels) split into its cells, row-major, each in
/// the list's order; `rect(e)` is an entry's `[x0, y0, x1, y1]` in image coordinates. Both
/// tile paths lay their cells out flat with [`cell_span`]; this is their tests' reference.
#[cfg(test)]
pub(crate) fn split_cells<E: Copy>(
    list: &[E],
    rect: impl Fn(&E) -> [f32; 4],
    (tx, ty): (u32, u32),
    tile: u32,
    cell: u32,
) -> Vec<Vec<E>> {
    let (x0, y0) = ((tx * tile) as f64, (ty * tile) as f64);
    let n = (tile / cell) as usize;
    let mut cells: Vec<Vec<E>> = vec![Vec::new(); n * n];
    for e in list {
        let r = rect(e);
        let (cx0, cx1) = cell_span(r[0], r[2], x0, cell, n);
        let (cy0, cy1) = cell_span(r[1], r[3], y0, cell, n);
        for cy in cy0..=cy1 {
            for cx in cx0..=cx1 {
                cells[cy * n + cx].push(*e);
            }
        }
    }
    cells
}

/// The first and last of `n` cells of `cell` pixels from image coordinate `origin` that the
/// span `[lo, hi]` (image coordinates) reaches, clamped to the `n` cells.
#[inline]
pub(crate) fn cell_span(lo: f32, hi: f32, origin: f64, cell: u32, n: usize) -> (usize, usize) {
    // Cell c spans [origin + c·cell, origin + (c + 1)·cell] in image coordinates; in f64
    // the offset of an f32 coordinate is exact, so no rectangle loses its cell.
    let c = |x: f32| floor((x as f64 - origin) / cell as f64).clamp(0.0, (n - 1) as f64);
    (c(lo) as usize, c(hi) as usize)
}
