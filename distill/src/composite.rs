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
//! A hit is 20 bytes (the global triangle, its barycentrics and alpha factor; the triangle's
//! vertices are looked up in the view's shared table), so a fit keeps its views' hits in
//! memory rather than re-tracing them each step. A step shades each hit once: the forward
//! pass keeps what it shaded ([`render_shaded_into`]) for the backward pass
//! ([`hit_gradients_into`]), the same numbers [`hit_gradients`] computes again.

use std::sync::Arc;

use glam::Vec3;
use rayon::prelude::*;
use splatbridge_raytrace::prefetch;
use splatbridge_scene::srgb;

/// One recorded hit: the global triangle (an index into [`ViewHits::tris`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rec {
    pub tri: u32,
    pub bary: [f32; 3],
    /// Material × texture alpha at the hit.
    pub fa: f32,
}

/// Hit lists of one view, row-major pixels.
#[derive(Clone, Debug, Default)]
pub struct ViewHits {
    pub width: u32,
    pub height: u32,
    /// Pixel p's hits are `hits[offsets[p]..offsets[p + 1]]`, from `offsets[0] = 0` to
    /// `hits.len()` (what the passes' per-hit buffers are indexed by).
    pub offsets: Vec<u64>,
    pub hits: Vec<Rec>,
    /// Global vertex indices of every triangle of the mesh, shared by all views.
    pub tris: Arc<Vec<[u32; 3]>>,
}

impl ViewHits {
    /// Bytes of this view's own hit lists (the shared triangle table not counted).
    pub fn bytes(&self) -> u64 {
        (self.hits.len() * std::mem::size_of::<Rec>() + self.offsets.len() * 8) as u64
    }

    /// The global vertices of a hit's triangle.
    #[inline]
    pub fn verts(&self, h: &Rec) -> [u32; 3] {
        self.tris[h.tri as usize]
    }

    /// Pixel p's hits' indices.
    fn range(&self, p: usize) -> std::ops::Range<usize> {
        self.offsets[p] as usize..self.offsets[p + 1] as usize
    }

    /// Hint the cache to fetch what the hit `AHEAD` after hit `i` reads (its triangle's entry)
    /// and the vertex parameters of the hit `AHEAD / 2` after it (whose triangle entry was
    /// asked for earlier). Hits of neighbouring pixels land on scattered triangles of a mesh
    /// whose parameters do not fit in the cache, so each hit's two dependent loads would
    /// otherwise wait on memory in turn.
    #[inline(always)]
    fn prefetch(&self, i: usize, params: &[[f32; 4]]) {
        const AHEAD: usize = 16;
        if let Some(h) = self.hits.get(i + AHEAD) {
            prefetch::at(&self.tris, h.tri as usize);
        }
        if let Some(h) = self.hits.get(i + AHEAD / 2) {
            for v in self.verts(h) {
                prefetch::at(params, v as usize);
            }
        }
    }
}

/// How the hit colours are encoded for blending.
#[derive(Clone, Copy, Debug)]
pub struct Shading {
    /// Vertex colours are linear and each hit is sRGB-encoded before blending.
    pub encode: bool,
    pub background: Vec3,
}

/// One shaded hit: display colour, its slope per channel (∂c/∂x, 0 where clamped), α, and
/// the unclamped α's slope `∂α/∂(Σ b·A)` (0 where clamped).
#[derive(Clone, Copy, Debug, Default)]
pub struct Shaded {
    c: Vec3,
    dc: Vec3,
    a: f32,
    da: f32,
}

/// Shade one hit whose triangle's vertices are `verts`.
#[inline]
fn shade(h: &Rec, verts: [u32; 3], params: &[[f32; 4]], s: &Shading) -> Shaded {
    let mut x = [0.0f32; 4];
    for (&v, &b) in verts.iter().zip(&h.bary) {
        for (xc, pc) in x.iter_mut().zip(&params[v as usize]) {
            *xc += b * pc;
        }
    }
    let mut c = [0.0f32; 3];
    let mut dc = [0.0f32; 3];
    for ((&v, cc), dd) in x.iter().zip(c.iter_mut()).zip(dc.iter_mut()) {
        let inside = (0.0..=1.0).contains(&v);
        let v = v.clamp(0.0, 1.0);
        // Each branch's value is computed and one selected: colours near black and at the
        // clamps would mispredict branches in this loop over every hit of every view.
        let (enc, slope) = if s.encode {
            // Within one ulp of the encode rounded once (`scene::srgb` tests it on every
            // float), at a fraction of `powf`'s cost. The slope from the encoded value: above
            // the linear toe, d/dx (1.055·x^(1/2.4) − 0.055) = (c + 0.055) / (2.4·x), without
            // a second powf.
            let enc = srgb::encode_unit(v);
            let power = (enc + 0.055) / (2.4 * v);
            (enc, if v <= 0.003_130_8 { 12.92 } else { power })
        } else {
            (v, 1.0)
        };
        *cc = enc;
        *dd = if inside { slope } else { 0.0 };
    }
    let a = h.fa * x[3];
    Shaded {
        c: Vec3::from_array(c),
        dc: Vec3::from_array(dc),
        a: a.clamp(0.0, 1.0),
        da: if (0.0..=1.0).contains(&a) { h.fa } else { 0.0 },
    }
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
    render_rows(view, params, s, None)
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
    render_rows(view, params, s, Some(shaded))
}

/// Rows composited in parallel, each pixel's hits shaded into `shaded` when given.
fn render_rows(
    view: &ViewHits,
    params: &[[f32; 4]],
    s: &Shading,
    shaded: Option<&mut Vec<Shaded>>,
) -> Vec<f32> {
    let w = view.width as usize;
    let h = view.height as usize;
    let mut img = vec![0.0f32; 3 * w * h];
    let rows: Vec<Option<&mut [Shaded]>> = match shaded {
        Some(buf) => {
            buf.clear();
            buf.resize(view.hits.len(), Shaded::default());
            row_slices(view, buf).into_iter().map(Some).collect()
        }
        None => (0..h).map(|_| None).collect(),
    };
    img.par_chunks_mut(3 * w.max(1))
        .zip(rows.into_par_iter())
        .enumerate()
        .for_each(|(row, (out, mut sh))| {
            let first = view.offsets[row * w] as usize;
            for col in 0..w {
                let std::ops::Range { start: a, end: b } = view.range(row * w + col);
                let hits = &view.hits[a..b];
                let shade_hit = |(k, h): (usize, &Rec)| {
                    view.prefetch(a + k, params);
                    shade(h, view.verts(h), params, s)
                };
                let c = match sh.as_deref_mut() {
                    Some(sh) => {
                        let px = &mut sh[a - first..b - first];
                        for (slot, hit) in px.iter_mut().zip(hits.iter().enumerate()) {
                            *slot = shade_hit(hit);
                        }
                        pixel(px.iter().copied(), s)
                    }
                    None => pixel(hits.iter().enumerate().map(shade_hit), s),
                };
                out[3 * col..3 * col + 3].copy_from_slice(&c.to_array());
            }
        });
    img
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
    out.clear();
    out.resize(view.hits.len(), [0.0; 4]);
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
                        scratch.extend(hits.iter().map(|h| shade(h, view.verts(h), params, s)));
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
/// sum does not depend on the thread count.
pub fn scatter(view: &ViewHits, dh: &[[f32; 4]], grad: &mut [[f32; 4]]) {
    for (i, (hit, d)) in view.hits.iter().zip(dh).enumerate() {
        // The same two dependent loads as shading, into the gradient's rows.
        view.prefetch(i, grad);
        for (&v, &b) in view.verts(hit).iter().zip(&hit.bary) {
            for (gc, dc) in grad[v as usize].iter_mut().zip(d) {
                *gc += b * dc;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A view of random hits over random triangles, with colours and alphas outside [0, 1]
    /// (both clamps), empty pixels and pixels of one and many hits.
    fn random_view(seed: u64) -> (ViewHits, Vec<[f32; 4]>) {
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
        let view = ViewHits {
            width: w,
            height: h,
            offsets,
            hits,
            tris: Arc::new(tris),
        };
        (view, params)
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
            let (view, params) = random_view(seed);
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
}
