//! The one chunked mesher: how a mesh source (a classified Gaussian cloud, [`crate::Mesher`],
//! or a part's surfels, [`crate::surfels::SurfelMesher`]) is generated chunk by chunk.
//!
//! A source says, per item (Gaussian or surfel), how many vertices it makes and which index
//! pattern it repeats, and how to emit a range of items into a [`VertexSink`]. Everything a
//! writer needs is built on that here, once: exact bounds (a first pass into
//! [`Bounds`]), vertices streamed in order a few chunks at a time in parallel, the index
//! buffer without regenerating geometry, and the whole mesh in memory. Generation is
//! deterministic, so the bounds pass and the data pass produce bit-identical vertices.

use std::ops::Range;

use rayon::prelude::*;

use crate::mesh::{Bounds, MeshSoup, VertexSink};

/// Items (Gaussians or surfels) per generated chunk.
pub const CHUNK: usize = 8192;

/// A mesh source generated in chunks of [`CHUNK`] items.
pub trait ChunkedMesh: Sync {
    /// Scratch space one worker reuses between items of a chunk.
    type Scratch: Default;

    /// Items in the source (kept or not).
    fn items(&self) -> usize;

    /// Vertices item `i` produces (0 when it is dropped).
    fn vertices_of(&self, i: usize) -> u64;

    /// Append item `i`'s triangles, with its first vertex at absolute index `first`, to `idx`;
    /// return its vertex count. `reverse`: the copy written in the second index pass (see
    /// [`ChunkedMesh::index_passes`]).
    fn indices_of(&self, i: usize, first: u32, reverse: bool, idx: &mut Vec<u32>) -> u32;

    /// Copies of every triangle in the index buffer: 1, or 2 when the source writes each
    /// triangle once more in a second pass (items in reverse order, the other winding), as
    /// the viewer arrangement does (`order.rs`). Vertices are never duplicated.
    fn index_passes(&self) -> usize {
        1
    }

    /// Emit the vertices and triangles of `range` (indices relative to the sink's start).
    fn emit_range<S: VertexSink>(&self, range: Range<usize>, out: &mut S, s: &mut Self::Scratch);

    /// Whether the vertices carry texture coordinates ([`MeshSoup::uvs`] is empty otherwise).
    fn has_uv(&self) -> bool;

    fn chunk_count(&self) -> usize {
        self.items().div_ceil(CHUNK)
    }

    fn chunk_range(&self, c: usize) -> Range<usize> {
        c * CHUNK..((c + 1) * CHUNK).min(self.items())
    }

    /// Vertices chunk `c` will produce (from the classification alone).
    fn chunk_vertices(&self, c: usize) -> usize {
        self.chunk_range(c)
            .map(|i| self.vertices_of(i) as usize)
            .sum()
    }

    /// Generate the vertices in order, a few chunks at a time in parallel: `make(vertices)`
    /// creates the sink for a chunk of that many vertices, `finish` turns it into what `f`
    /// consumes (in order).
    fn map_chunks_with<S: VertexSink, T: Send, E>(
        &self,
        make: impl Fn(usize) -> S + Sync + Send,
        finish: impl Fn(S) -> T + Sync + Send,
        f: impl FnMut(T) -> Result<(), E>,
    ) -> Result<(), E> {
        in_order(
            self.chunk_count(),
            |k| {
                let mut sink = make(self.chunk_vertices(k));
                let mut s = Self::Scratch::default();
                self.emit_range(self.chunk_range(k), &mut sink, &mut s);
                finish(sink)
            },
            f,
        )
    }

    /// [`ChunkedMesh::map_chunks_with`] into [`MeshSoup`] chunks (indices relative to the
    /// chunk): `map` turns each into whatever the writer needs, in parallel.
    fn map_chunks<T: Send, E>(
        &self,
        map: impl Fn(MeshSoup) -> T + Sync + Send,
        f: impl FnMut(T) -> Result<(), E>,
    ) -> Result<(), E> {
        let uv = self.has_uv();
        self.map_chunks_with(
            |n| MeshSoup {
                positions: Vec::with_capacity(n),
                normals: Vec::with_capacity(n),
                colors: Vec::with_capacity(n),
                uvs: Vec::with_capacity(n),
                gaussian_ids: Vec::with_capacity(n),
                indices: Vec::new(),
            },
            |mut soup| {
                if !uv {
                    soup.uvs = Vec::new();
                }
                map(soup)
            },
            f,
        )
    }

    /// Generate the index buffer in order without regenerating geometry: every kept item
    /// repeats its index pattern, offset by the vertices before it (`base` is added to all).
    /// `map` gets each chunk's absolute indices.
    fn map_index_chunks<T: Send, E>(
        &self,
        base: u32,
        map: impl Fn(&[u32]) -> T + Sync + Send,
        f: impl FnMut(T) -> Result<(), E>,
    ) -> Result<(), E> {
        let chunks = self.chunk_count();
        // Vertex offset of every chunk (prefix sums of the per-item counts).
        let mut starts = Vec::with_capacity(chunks);
        let mut acc = base as u64;
        for c in 0..chunks {
            starts.push(acc);
            acc += self
                .chunk_range(c)
                .map(|i| self.vertices_of(i))
                .sum::<u64>();
        }
        // With two passes, chunks 0..chunks are the first copies, then the same chunks in
        // reverse with every item reversed and every triangle in the other winding.
        let passes = self.index_passes();
        in_order(
            chunks * passes,
            |k| {
                let (c, second) = if k < chunks {
                    (k, false)
                } else {
                    (2 * chunks - 1 - k, true)
                };
                let mut idx = Vec::new();
                let mut v = starts[c] as u32;
                if !second {
                    for i in self.chunk_range(c) {
                        v += self.indices_of(i, v, false, &mut idx);
                    }
                } else {
                    let mut firsts = Vec::with_capacity(self.chunk_range(c).len());
                    for i in self.chunk_range(c) {
                        let n = self.vertices_of(i) as u32;
                        if n > 0 {
                            firsts.push((i, v));
                        }
                        v += n;
                    }
                    for &(i, v) in firsts.iter().rev() {
                        self.indices_of(i, v, true, &mut idx);
                    }
                }
                map(&idx)
            },
            f,
        )
    }

    /// Exact per-axis min and max of the generated positions (`None` when empty).
    fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let b = (0..self.chunk_count())
            .into_par_iter()
            .map(|k| {
                let mut b = Bounds::default();
                let mut s = Self::Scratch::default();
                self.emit_range(self.chunk_range(k), &mut b, &mut s);
                b
            })
            .reduce(Bounds::default, |a, b| Bounds {
                lo: a.lo.min(b.lo),
                hi: a.hi.max(b.hi),
                count: a.count + b.count,
            });
        (b.count > 0).then(|| (b.lo.to_array(), b.hi.to_array()))
    }

    /// The whole mesh in memory (tests, small scenes, in-memory consumers).
    fn build(&self) -> MeshSoup {
        let mut all = MeshSoup::default();
        let _ = self.map_chunks::<MeshSoup, ()>(
            |c| c,
            |c| {
                all.append(&c);
                Ok(())
            },
        );
        all
    }
}

/// Map `0..chunks` in parallel, a few chunks per batch, and hand the results to `f` in order:
/// the writers stream chunk by chunk without holding the whole mesh, and still use every core.
pub(crate) fn in_order<T: Send, E>(
    chunks: usize,
    map: impl Fn(usize) -> T + Sync + Send,
    mut f: impl FnMut(T) -> Result<(), E>,
) -> Result<(), E> {
    let batch = (rayon::current_num_threads() * 2).max(1);
    let mut c = 0;
    while c < chunks {
        let end = (c + batch).min(chunks);
        let out: Vec<T> = (c..end).into_par_iter().map(&map).collect();
        for t in out {
            f(t)?;
        }
        c = end;
    }
    Ok(())
}
