//! Front-to-back compositing of recorded hits with per-vertex RGBA, and its analytic
//! gradient.
//!
//! A hit on triangle (v0, v1, v2) at barycentrics b has the colour and opacity the mesh
//! tracer shades (`raytrace::model::Mesh::shade`, `MeshTracer::trace`): `x = Σ b_k·L_k`
//! (linear vertex colours) clamped to [0, 1] and sRGB-encoded per channel, `c = srgb(x)`;
//! `α = clamp(f·Σ b_k·A_k, 0, 1)` with `f` the material and texture alpha at the hit. The
//! pixel is `C = Σ c_i·α_i·T_i + bg·T_n` with `T_0 = 1`, `T_{i+1} = T_i·(1 − α_i)`.
//!
//! Backward pass from the back: with `R_i` the colour behind hit i seen through nothing
//! (`R_{n−1} = bg`, `R_{i−1} = c_i·α_i + (1 − α_i)·R_i`), `∂C/∂c_i = α_i·T_i` and
//! `∂C/∂α_i = T_i·(c_i − R_i)`, which needs no division by `1 − α_i` (stable at α = 1).
//!
//! A hit is 20 bytes (its triangle, barycentrics and alpha factor), so a fit keeps its views'
//! hits in memory rather than re-tracing them each step. A step shades each hit once: the
//! forward pass keeps what it shaded ([`render_shaded_into`]) for the backward pass
//! ([`hit_gradients_into`]), the same numbers [`hit_gradients`] computes again.
//!
//! Each view numbers its own triangles and vertices in the order its hits first reach them
//! ([`ViewHits::new`]). A pass copies the view's vertices' parameters (or gradients) out of
//! the mesh's arrays once, works on that compact copy, and the scatter writes the gradients
//! back: a pixel's hits and its neighbours' then read a few nearby cache lines instead of a
//! triangle table and vertex arrays of the whole mesh, each hit's loads waiting on memory.
//! The numbers are the same: every value read is the mesh's own, and each vertex's gradient
//! receives the same additions in the same order, starting from its value in the mesh's
//! array (tested against passes over the global arrays).

use glam::Vec3;
use rayon::prelude::*;
use splatbridge_raytrace::prefetch;

use crate::shade::{self, shade, shade_with, Lanes};
pub use crate::shade::{Shaded, Shading};

/// One recorded hit: its triangle (an index into [`ViewHits::tris`]), barycentrics and the
/// material × texture alpha at the hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rec {
    pub tri: u32,
    pub bary: [f32; 3],
    /// Material × texture alpha at the hit.
    pub fa: f32,
}

/// Hit lists of one view, row-major pixels, with the view's own numbering of the triangles
/// and vertices its hits reach.
#[derive(Clone, Debug, Default)]
pub struct ViewHits {
    pub width: u32,
    pub height: u32,
    /// Pixel p's hits are `hits[offsets[p]..offsets[p + 1]]`, from `offsets[0] = 0` to
    /// `hits.len()` (what the passes' per-hit buffers are indexed by).
    pub offsets: Vec<u64>,
    pub hits: Vec<Rec>,
    /// The view's triangles in the order its hits first reach them, each as three indices
    /// into `verts`.
    tris: Vec<[u32; 3]>,
    /// The mesh's vertex of each of the view's vertices, in the order its triangles first
    /// reach them.
    verts: Vec<u32>,
}

impl ViewHits {
    /// A view's lists from hits whose `tri` indexes the mesh's triangles `mesh_tris` (global
    /// vertex indices; `vertices` of them): renumbered in the order the hits reach them.
    pub fn new(
        width: u32,
        height: u32,
        offsets: Vec<u64>,
        mut hits: Vec<Rec>,
        mesh_tris: &[[u32; 3]],
        vertices: usize,
    ) -> Self {
        const NEW: u32 = u32::MAX;
        let mut tri_at = vec![NEW; mesh_tris.len()];
        let mut vert_at = vec![NEW; vertices];
        let (mut tris, mut verts) = (Vec::new(), Vec::new());
        for h in &mut hits {
            let t = &mut tri_at[h.tri as usize];
            if *t == NEW {
                *t = tris.len() as u32;
                tris.push(mesh_tris[h.tri as usize].map(|v| {
                    let at = &mut vert_at[v as usize];
                    if *at == NEW {
                        *at = verts.len() as u32;
                        verts.push(v);
                    }
                    *at
                }));
            }
            h.tri = *t;
        }
        ViewHits {
            width,
            height,
            offsets,
            hits,
            tris,
            verts,
        }
    }

    /// Bytes of this view's own hit lists and numbering.
    pub fn bytes(&self) -> u64 {
        (self.hits.len() * std::mem::size_of::<Rec>()
            + self.offsets.len() * 8
            + self.tris.len() * 12
            + self.verts.len() * 4) as u64
    }

    /// The mesh's vertices of a hit's triangle.
    #[inline]
    pub fn verts(&self, h: &Rec) -> [u32; 3] {
        self.local(h).map(|v| self.verts[v as usize])
    }

    /// The view's vertices of a hit's triangle.
    #[inline]
    fn local(&self, h: &Rec) -> [u32; 3] {
        self.tris[h.tri as usize]
    }

    /// The mesh's values (parameters or gradients) of the view's vertices.
    fn gather(&self, of: &[[f32; 4]]) -> Vec<[f32; 4]> {
        self.verts.iter().map(|&v| of[v as usize]).collect()
    }

    /// Pixel p's hits' indices.
    fn range(&self, p: usize) -> std::ops::Range<usize> {
        self.offsets[p] as usize..self.offsets[p + 1] as usize
    }

    /// Hint the cache to fetch what the hit `AHEAD` after hit `i` reads (its triangle's entry)
    /// and the view's vertex values of the hit `AHEAD / 2` after it (whose triangle entry was
    /// asked for earlier): most are near the ones just read, the first reach of a triangle
    /// is not.
    #[inline(always)]
    fn prefetch(&self, i: usize, local: &[[f32; 4]]) {
        const AHEAD: usize = 16;
        if let Some(h) = self.hits.get(i + AHEAD) {
            prefetch::at(&self.tris, h.tri as usize);
        }
        if let Some(h) = self.hits.get(i + AHEAD / 2) {
            for v in self.local(h) {
                prefetch::at(local, v as usize);
            }
        }
    }
}

/// Shade hit `i` of a view (`h`), its next hits' loads asked for first, with `channels` (the
/// scalar or the AVX2 build, [`shade::Lanes`]). Inlined into the pass's loop: as a call its
/// four-float halves of [`Shaded`] went back through the stack, written by scalar stores and
/// read by a vector load that cannot take them forwarded.
#[inline(always)]
fn shade_at(
    view: &ViewHits,
    i: usize,
    h: &Rec,
    params: &[[f32; 4]],
    s: &Shading,
    channels: impl Fn([f32; 4], bool) -> ([f32; 4], [f32; 4]),
) -> Shaded {
    view.prefetch(i, params);
    shade_with(h, view.local(h), params, s, channels)
}

/// The pixel colour of one pixel's shaded hits.
fn pixel(hits: impl Iterator<Item = Shaded>, s: &Shading) -> Vec3 {
    let mut acc = Vec3::ZERO;
    let mut t = 1.0f32;
    for h in hits {
        acc += h.c * (h.a * t);
        t *= 1.0 - h.a;
    }
    acc + s.background * t
}

/// Per hit of one pixel (shaded), the loss gradient with respect to its interpolated linear
/// RGB (through the clamp and encoding) and its interpolated vertex alpha `Σ b·A`, given
/// `g = ∂L/∂C`, into `out` (one entry per hit); `tr` is scratch.
fn pixel_backward(
    shaded: &[Shaded],
    s: &Shading,
    g: Vec3,
    tr: &mut Vec<f32>,
    out: &mut [[f32; 4]],
) {
    tr.clear();
    let mut t = 1.0f32;
    for h in shaded {
        tr.push(t);
        t *= 1.0 - h.a;
    }
    let mut behind = s.background;
    for ((h, &ti), o) in shaded.iter().zip(tr.iter()).zip(out.iter_mut()).rev() {
        let dcol = g * (h.a * ti) * h.dc;
        let dalpha = ti * g.dot(h.c - behind) * h.da;
        *o = [dcol.x, dcol.y, dcol.z, dalpha];
        behind = h.c * h.a + behind * (1.0 - h.a);
    }
}

/// The image of a view (interleaved RGB).
pub fn render(view: &ViewHits, params: &[[f32; 4]], s: &Shading) -> Vec<f32> {
    render_rows(view, params, s, None, Lanes::best())
}

/// Views with more hits than this are shaded twice a step instead of keeping their shaded
/// hits (32 bytes each) between the passes: 8 Mi hits, 256 MiB a view in flight, three
/// times the 240×180 fitting windows of a deep street capture (`fourth_st`: 2.4 M hits).
pub const MAX_SHADED_HITS: usize = 8 << 20;

/// Split `buf` (one entry per hit of `view`) into the ranges of its rows: a row's hits are
/// contiguous.
fn row_slices<'a, T>(view: &ViewHits, buf: &'a mut [T]) -> Vec<&'a mut [T]> {
    let (w, h) = (view.width as usize, view.height as usize);
    let mut rows = Vec::with_capacity(h);
    let mut rest = buf;
    for row in 0..h {
        let (a, b) = (view.offsets[row * w], view.offsets[(row + 1) * w]);
        let (mine, tail) = rest.split_at_mut((b - a) as usize);
        rows.push(mine);
        rest = tail;
    }
    rows
}

/// [`render`], also leaving every hit shaded (in hit order) in `shaded` for
/// [`hit_gradients_into`]; the buffer's allocation is reused (a fit's steps would otherwise
/// fault in a fresh one for every view).
pub fn render_shaded_into(
    view: &ViewHits,
    params: &[[f32; 4]],
    s: &Shading,
    shaded: &mut Vec<Shaded>,
) -> Vec<f32> {
    render_rows(view, params, s, Some(shaded), Lanes::best())
}

/// Rows composited in parallel, each pixel's hits shaded into `shaded` when given.
fn render_rows(
    view: &ViewHits,
    params: &[[f32; 4]],
    s: &Shading,
    shaded: Option<&mut Vec<Shaded>>,
    lanes: Lanes,
) -> Vec<f32> {
    let w = view.width as usize;
    let h = view.height as usize;
    let local = view.gather(params);
    let params = &local[..];
    let mut img = vec![0.0f32; 3 * w * h];
    let rows: Vec<Option<&mut [Shaded]>> = match shaded {
        Some(buf) => {
            // Every entry is written below, so only growth past the last view's length is
            // initialised (clearing it all was 7 % of a step).
            buf.resize(view.hits.len(), Shaded::default());
            row_slices(view, buf).into_iter().map(Some).collect()
        }
        None => (0..h).map(|_| None).collect(),
    };
    img.par_chunks_mut(3 * w.max(1))
        .zip(rows.into_par_iter())
        .enumerate()
        .for_each(|(row, (out, sh))| {
            let r = Row {
                view,
                row,
                params,
                s,
            };
            match lanes {
                Lanes::Scalar => r.composite(out, sh, shade::channels),
                // SAFETY: `Lanes::Avx2` is made only where the CPU has AVX2 (`Lanes::best`).
                #[cfg(target_arch = "x86_64")]
                Lanes::Avx2(t) => unsafe { r.composite_avx2(out, sh, &t) },
            }
        });
    img
}

/// One row of a view's forward pass.
struct Row<'a> {
    view: &'a ViewHits,
    row: usize,
    params: &'a [[f32; 4]],
    s: &'a Shading,
}

impl Row<'_> {
    /// Composite the row's pixels into `out` (interleaved RGB), each hit shaded by
    /// `channels` and kept in `sh` (the row's range of the shaded buffer) when given.
    #[inline(always)]
    fn composite(
        &self,
        out: &mut [f32],
        mut sh: Option<&mut [Shaded]>,
        channels: impl Fn([f32; 4], bool) -> ([f32; 4], [f32; 4]) + Copy,
    ) {
        let Row {
            view,
            row,
            params,
            s,
        } = *self;
        let w = view.width as usize;
        let first = view.offsets[row * w] as usize;
        for col in 0..w {
            let std::ops::Range { start: a, end: b } = view.range(row * w + col);
            let hits = &view.hits[a..b];
            let c = match sh.as_deref_mut() {
                Some(sh) => {
                    let px = &mut sh[a - first..b - first];
                    for (k, (slot, h)) in px.iter_mut().zip(hits).enumerate() {
                        *slot = shade_at(view, a + k, h, params, s, channels);
                    }
                    pixel(px.iter().copied(), s)
                }
                None => pixel(
                    hits.iter()
                        .enumerate()
                        .map(|(k, h)| shade_at(view, a + k, h, params, s, channels)),
                    s,
                ),
            };
            out[3 * col..3 * col + 3].copy_from_slice(&c.to_array());
        }
    }

    /// [`Row::composite`] compiled for AVX2, the channels in four lanes
    /// ([`shade::channels_avx2`]): the same bits.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn composite_avx2(
        &self,
        out: &mut [f32],
        sh: Option<&mut [Shaded]>,
        t: &splatbridge_scene::srgb::EncodeTables,
    ) {
        // SAFETY: AVX2 is present (this function's contract).
        self.composite(out, sh, |x, e| unsafe { shade::channels_avx2(x, e, t) });
    }
}

/// Per hit of a view, in hit order, the loss gradient with respect to its interpolated linear
/// RGB and vertex alpha, given `dimg = ∂L/∂image` (interleaved RGB). Rows are differentiated
/// in parallel, each into its own range of the output.
pub fn hit_gradients(
    view: &ViewHits,
    params: &[[f32; 4]],
    s: &Shading,
    dimg: &[f32],
) -> Vec<[f32; 4]> {
    let mut out = Vec::new();
    hit_gradients_into(view, params, None, s, dimg, &mut out);
    out
}

/// [`hit_gradients`] into `out` (its allocation reused), each pixel's hits taken from
/// `shaded` ([`render_shaded_into`] with the same parameters) or shaded again.
pub fn hit_gradients_into(
    view: &ViewHits,
    params: &[[f32; 4]],
    shaded: Option<&[Shaded]>,
    s: &Shading,
    dimg: &[f32],
    out: &mut Vec<[f32; 4]>,
) {
    let w = view.width as usize;
    // Every entry is written below (each pixel's hits by its backward pass).
    out.resize(view.hits.len(), [0.0; 4]);
    // Parameters are read only to shade again.
    let local = match shaded {
        Some(_) => Vec::new(),
        None => view.gather(params),
    };
    row_slices(view, out)
        .into_par_iter()
        .enumerate()
        .for_each(|(row, dst)| {
            let first = view.offsets[row * w] as usize;
            let (mut tr, mut scratch) = (Vec::new(), Vec::new());
            for col in 0..w {
                let p = row * w + col;
                let std::ops::Range { start: a, end: b } = view.range(p);
                let px: &[Shaded] = match shaded {
                    Some(sh) => &sh[a..b],
                    None => {
                        scratch.clear();
                        let hits = &view.hits[a..b];
                        scratch.extend(hits.iter().map(|h| shade(h, view.local(h), &local, s)));
                        &scratch
                    }
                };
                let g = Vec3::new(dimg[3 * p], dimg[3 * p + 1], dimg[3 * p + 2]);
                pixel_backward(px, s, g, &mut tr, &mut dst[a - first..b - first]);
            }
        });
}

/// Add the gradient of the loss with respect to every vertex's RGBA to `grad`, given the
/// per-hit gradients of [`hit_gradients`]. The scatter to vertices runs in hit order, so the
/// sum does not depend on the thread count; it adds into a copy of the view's vertices'
/// gradients and writes them back, the same additions in the same order as into `grad`.
pub fn scatter(view: &ViewHits, dh: &[[f32; 4]], grad: &mut [[f32; 4]]) {
    let mut local = view.gather(grad);
    for (i, (hit, d)) in view.hits.iter().zip(dh).enumerate() {
        // The same two dependent loads as shading, into the gradient's rows.
        view.prefetch(i, &local);
        for (&v, &b) in view.local(hit).iter().zip(&hit.bary) {
            for (gc, dc) in local[v as usize].iter_mut().zip(d) {
                *gc += b * dc;
            }
        }
    }
    for (&v, g) in view.verts.iter().zip(local) {
        grad[v as usize] = g;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type RandomView = (ViewHits, Vec<[f32; 4]>, Vec<Rec>, Vec<[u32; 3]>);

    /// A view of random hits over random triangles (of 50 vertices, some repeated within a
    /// triangle), with colours and alphas outside [0, 1] (both clamps), empty pixels and
    /// pixels of one and many hits: the view, the parameters, and the hits as numbered by
    /// the mesh with its triangles.
    fn random_view(seed: u64) -> RandomView {
        let mut state = seed;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 33) as f64 / (1u64 << 31) as f64) as f32
        };
        let nv = 50;
        let params: Vec<[f32; 4]> = (0..nv)
            .map(|_| [0.0; 4].map(|_: f32| next() * 1.4 - 0.2))
            .collect();
        let tris: Vec<[u32; 3]> = (0..40)
            .map(|_| [0u32; 3].map(|_| (next() * nv as f32) as u32 % nv as u32))
            .collect();
        let (w, h) = (7u32, 5u32);
        let mut offsets = vec![0u64];
        let mut hits = Vec::new();
        for p in 0..(w * h) as usize {
            let n = match p % 4 {
                0 => 0,
                1 => 1,
                _ => (next() * 12.0) as usize,
            };
            for _ in 0..n {
                let (b0, b1) = (next(), next());
                let (b0, b1) = if b0 + b1 > 1.0 {
                    (1.0 - b0, 1.0 - b1)
                } else {
                    (b0, b1)
                };
                hits.push(Rec {
                    tri: (next() * tris.len() as f32) as u32 % tris.len() as u32,
                    bary: [b0, b1, 1.0 - b0 - b1],
                    fa: next() * 1.2,
                });
            }
            offsets.push(hits.len() as u64);
        }
        let view = ViewHits::new(w, h, offsets, hits.clone(), &tris, nv);
        (view, params, hits, tris)
    }

    /// The per-pixel formula, written out: C = Σ c_i·α_i·Π_{j<i}(1 − α_j) + bg·Π(1 − α_j).
    fn reference_pixel(view: &ViewHits, p: usize, params: &[[f32; 4]], s: &Shading) -> [f64; 3] {
        let mut out = [0.0f64; 3];
        let hits = &view.hits[view.range(p)];
        for (i, h) in hits.iter().enumerate() {
            let alpha = |h: &Rec| {
                let v = view.verts(h);
                let x: f64 = (0..3)
                    .map(|k| h.bary[k] as f64 * params[v[k] as usize][3] as f64)
                    .sum();
                (h.fa as f64 * x).clamp(0.0, 1.0)
            };
            let t: f64 = hits[..i].iter().map(|g| 1.0 - alpha(g)).product();
            let v = view.verts(h);
            for (c, o) in out.iter_mut().enumerate() {
                let x: f64 = (0..3)
                    .map(|k| h.bary[k] as f64 * params[v[k] as usize][c] as f64)
                    .sum();
                let x = x.clamp(0.0, 1.0);
                let enc = if s.encode && x > 0.003_130_8 {
                    1.055 * x.powf(1.0 / 2.4) - 0.055
                } else if s.encode {
                    12.92 * x
                } else {
                    x
                };
                *o += enc * alpha(h) * t;
            }
        }
        let t: f64 = hits
            .iter()
            .map(|h| {
                let v = view.verts(h);
                let x: f64 = (0..3)
                    .map(|k| h.bary[k] as f64 * params[v[k] as usize][3] as f64)
                    .sum();
                1.0 - (h.fa as f64 * x).clamp(0.0, 1.0)
            })
            .product();
        for (c, o) in out.iter_mut().enumerate() {
            *o += s.background[c] as f64 * t;
        }
        out
    }

    /// The shaded forward pass and backward pass are bit for bit the passes that shade again,
    /// and the image is the per-pixel formula's.
    #[test]
    fn shaded_passes_equal_the_plain_ones_and_the_formula() {
        for (seed, encode) in [(1, true), (2, false), (3, true)] {
            let (view, params, _, _) = random_view(seed);
            let s = Shading {
                encode,
                background: Vec3::new(0.2, 0.5, 0.9),
            };
            let img = render(&view, &params, &s);
            let mut shaded = Vec::new();
            let img2 = render_shaded_into(&view, &params, &s, &mut shaded);
            assert_eq!(shaded.len(), view.hits.len());
            assert!(img
                .iter()
                .zip(&img2)
                .all(|(a, b)| a.to_bits() == b.to_bits()));
            for p in 0..(view.width * view.height) as usize {
                let r = reference_pixel(&view, p, &params, &s);
                for c in 0..3 {
                    // f32 compositing of up to 12 hits against f64: a few ulps of 1.
                    assert!(
                        (img[3 * p + c] as f64 - r[c]).abs() < 1e-5,
                        "seed {seed} pixel {p} channel {c}: {} vs {}",
                        img[3 * p + c],
                        r[c]
                    );
                }
            }
            let dimg: Vec<f32> = (0..img.len())
                .map(|i| ((i * 37 % 11) as f32 - 5.0) / 7.0)
                .collect();
            let a = hit_gradients(&view, &params, &s, &dimg);
            let mut b = Vec::new();
            hit_gradients_into(&view, &params, Some(&shaded), &s, &dimg, &mut b);
            assert_eq!(a.len(), view.hits.len());
            assert!(a
                .iter()
                .flatten()
                .zip(b.iter().flatten())
                .all(|(x, y)| x.to_bits() == y.to_bits()));
            assert!(a.iter().flatten().any(|x| *x != 0.0));
        }
    }

    /// The forward pass with its channels in AVX2 lanes gives the scalar pass's image and
    /// shaded hits, bit for bit: random views whose colours and alphas lie beyond both clamps,
    /// with and without the encode, keeping the shaded hits and not.
    #[test]
    fn avx2_forward_is_the_scalar_forward() {
        let lanes = Lanes::best();
        if matches!(lanes, Lanes::Scalar) {
            eprintln!("skipped: no AVX2 on this CPU");
            return;
        }
        let bits =
            |x: &Shaded| [x.c.x, x.c.y, x.c.z, x.dc.x, x.dc.y, x.dc.z, x.a, x.da].map(f32::to_bits);
        for (seed, encode) in [(11, true), (12, false), (13, true)] {
            let (view, params, _, _) = random_view(seed);
            let s = Shading {
                encode,
                background: Vec3::new(0.3, 0.1, 0.7),
            };
            let (mut a, mut b) = (Vec::new(), Vec::new());
            let ia = render_rows(&view, &params, &s, Some(&mut a), Lanes::Scalar);
            let ib = render_rows(&view, &params, &s, Some(&mut b), lanes);
            assert!(same_bits(&ia, &ib), "seed {seed}");
            assert_eq!(a.len(), b.len());
            assert!(
                a.iter().zip(&b).all(|(x, y)| bits(x) == bits(y)),
                "seed {seed}"
            );
            let ic = render_rows(&view, &params, &s, None, lanes);
            assert!(same_bits(&ia, &ic), "seed {seed}");
            // The views hold clamped channels (slope 0) and unclamped ones.
            assert!(a.iter().any(|x| x.dc.x == 0.0) && a.iter().any(|x| x.dc.x > 0.0));
        }
    }

    /// The passes as they read the mesh's own arrays, hit by hit: every hit's triangle and
    /// vertices looked up in the mesh's tables (the slow reference of the view's numbering).
    struct Global<'a> {
        view: &'a ViewHits,
        hits: &'a [Rec],
        tris: &'a [[u32; 3]],
    }

    impl Global<'_> {
        fn shaded(&self, p: usize, params: &[[f32; 4]], s: &Shading) -> Vec<Shaded> {
            self.hits[self.view.range(p)]
                .iter()
                .map(|h| shade(h, self.tris[h.tri as usize], params, s))
                .collect()
        }

        fn render(&self, params: &[[f32; 4]], s: &Shading) -> Vec<f32> {
            let n = (self.view.width * self.view.height) as usize;
            (0..n)
                .flat_map(|p| pixel(self.shaded(p, params, s).into_iter(), s).to_array())
                .collect()
        }

        fn hit_gradients(&self, params: &[[f32; 4]], s: &Shading, dimg: &[f32]) -> Vec<[f32; 4]> {
            let mut out = vec![[0.0; 4]; self.hits.len()];
            let n = (self.view.width * self.view.height) as usize;
            for p in 0..n {
                let g = Vec3::new(dimg[3 * p], dimg[3 * p + 1], dimg[3 * p + 2]);
                let r = self.view.range(p);
                pixel_backward(
                    &self.shaded(p, params, s),
                    s,
                    g,
                    &mut Vec::new(),
                    &mut out[r],
                );
            }
            out
        }

        fn scatter(&self, dh: &[[f32; 4]], grad: &mut [[f32; 4]]) {
            for (hit, d) in self.hits.iter().zip(dh) {
                for (&v, &b) in self.tris[hit.tri as usize].iter().zip(&hit.bary) {
                    for (gc, dc) in grad[v as usize].iter_mut().zip(d) {
                        *gc += b * dc;
                    }
                }
            }
        }
    }

    fn same_bits(a: &[f32], b: &[f32]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
    }

    /// Through the view's own numbering, the image, the per-hit gradients and the scatter
    /// (into a gradient already holding other views' sums) are bit for bit those of the
    /// passes over the mesh's arrays; vertices the view does not reach keep their gradient.
    #[test]
    fn the_view_numbering_changes_no_bit() {
        for (seed, encode) in [(4, true), (5, false), (6, true), (7, true)] {
            let (view, params, hits, tris) = random_view(seed);
            let global = Global {
                view: &view,
                hits: &hits,
                tris: &tris,
            };
            // Renumbered: fewer or as many triangles and vertices as the mesh has.
            assert!(view.tris.len() <= tris.len() && view.verts.len() <= params.len());
            for (h, g) in view.hits.iter().zip(&hits) {
                assert_eq!(view.verts(h), tris[g.tri as usize]);
            }
            let s = Shading {
                encode,
                background: Vec3::new(0.1, 0.3, 0.8),
            };
            let img = global.render(&params, &s);
            assert!(same_bits(&render(&view, &params, &s), &img));
            // Buffers of an earlier, longer view: every entry the passes read is written.
            let stale = Shaded {
                c: Vec3::splat(f32::NAN),
                dc: Vec3::splat(7.0),
                a: 0.5,
                da: f32::NAN,
            };
            let mut shaded = vec![stale; view.hits.len() + 9];
            assert!(same_bits(
                &render_shaded_into(&view, &params, &s, &mut shaded),
                &img
            ));
            let dimg: Vec<f32> = (0..img.len())
                .map(|i| ((i * 29 % 13) as f32 - 6.0) / 5.0)
                .collect();
            let want = global.hit_gradients(&params, &s, &dimg);
            assert_eq!(shaded.len(), view.hits.len());
            let mut got = vec![[f32::NAN; 4]; view.hits.len() + 5];
            hit_gradients_into(&view, &params, Some(&shaded), &s, &dimg, &mut got);
            assert!(same_bits(want.as_flattened(), got.as_flattened()));
            let got = hit_gradients(&view, &params, &s, &dimg);
            assert!(same_bits(want.as_flattened(), got.as_flattened()));
            // A gradient holding earlier views' sums, some of them large enough that the
            // order of the additions shows in the last bits.
            let before: Vec<[f32; 4]> = (0..params.len())
                .map(|i| [0.0f32; 4].map(|_| ((i * 7919 % 97) as f32 - 48.0) * 0.37))
                .collect();
            let (mut a, mut b) = (before.clone(), before.clone());
            global.scatter(&want, &mut a);
            scatter(&view, &want, &mut b);
            assert!(same_bits(a.as_flattened(), b.as_flattened()));
            let reached: std::collections::HashSet<u32> = view.verts.iter().copied().collect();
            for (v, (x, y)) in before.iter().zip(&b).enumerate() {
                if !reached.contains(&(v as u32)) {
                    assert_eq!(x, y);
                }
            }
            assert!(reached.len() < params.len(), "some vertex is not reached");
        }
    }
}
