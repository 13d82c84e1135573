//! Primary rays of a pinhole camera traced tile by tile: the Gaussians a 16×16-pixel tile can
//! see are gathered once, in the order of their hits' keys, and each of the tile's rays runs
//! the per-ray test, hit and compositing code of [`GaussianTracer::trace_fp`] on that list.
//!
//! The binning is native splatting's (Kerbl et al. 2023, `duplicateWithKeys` and the per-tile
//! ranges of a global depth sort), with the tracer's own proxies and responses: a proxy goes
//! into every tile its box's screen rectangle touches, and the tile's list is ordered by the
//! key every one of its hits will have. That key is the mean's view depth along the ray,
//! `z / (d·f)` with `z = (μ − o)·f` the same f32 number for every ray of the camera and
//! `d·f > 0` per ray; a correctly rounded division by a positive number is monotone, so a
//! list sorted by `(z, Gaussian index)` yields each ray's hits in non-decreasing `t`. Hits
//! whose `t` rounds equal are put in Gaussian-index order before they are composited, which is
//! the k-buffer's key order exactly. A ray therefore composites the same hits with the same
//! float operations in the same order as through the BVH and the k-buffer, and stops at the
//! same hit: images are bit-identical (`tile_tests`), with no traversal, no k-buffer round
//! and no per-camera BVH.
//!
//! Which renders take this path: one part fixed in the world (a plain cloud, no moving
//! objects or particles), primary rays keyed at the mean's depth (`--order mean-depth`, the
//! footprint's default, or `--footprint projected`), `near ≥ 0` (keys then are non-negative,
//! where their bits order like them). Everything else keeps the per-ray BVH path.

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use splatbridge_scene::{sh, Camera};

use super::camera::{LocalFootprint, Padded, PixelSplat};
use super::exp_lanes;
use super::lanes::{colors_from_basis, prefetch, Chunk, Products, LANES};
use super::part::{alpha_of, alpha_of_exp};
use super::{GaussianHit, GaussianPayload, GaussianTracer};
use crate::footprint::{Footprint, HitOrder, RayFootprint, ShDirection};
use crate::geom::order_bits;
use crate::kbuffer::{Accum, Hit};
use crate::render::{PixelOut, RenderOptions};
use crate::screen_cells::cell_span;
pub(super) use walk::vector_exp_supported;
use walk::{chunk_pass, in_exp_range, RayComposite};

mod walk;

/// Tile edge in pixels (native's `BLOCK_X = BLOCK_Y`).
pub(super) const TILE: u32 = 16;

/// Widening of a proxy's screen rectangle, in pixels, beyond its corners' projection: the f32
/// rounding of the ray's direction moves its pixel by about 1e-4 px at focal lengths of
/// 1e3 px, and the response's by less (its proxies are padded by a relative 1e-5); 0.05 px
/// plus a relative 1e-5 of the coordinate is a wide margin over both, and costs a candidate
/// only on the rectangle's rim.
const RECT_MARGIN: f64 = 0.05;

/// Edge in pixels of the cells a tile's list is split into before its rays are traced.
pub(super) const CELL: u32 = 4;

/// How many entries ahead of the one being placed [`Cells::build`] asks for a pixel record:
/// far enough for a load from memory to arrive (about 100 ns against some 10 ns an entry).
const PREFETCH_AHEAD: usize = 8;

/// A tile's list split by cell (see [`TileLists::cells`]), each cell's list in [`Chunk`]s.
#[derive(Default)]
pub(super) struct Cells {
    x0: u32,
    y0: u32,
    chunks: Vec<Chunk>,
    /// `ranges[c]..ranges[c + 1]`: cell `c`'s chunks (cells row-major).
    ranges: Vec<usize>,
}

impl Cells {
    /// The chunks of the cell holding pixel `(i, j)` (a pixel of the tile).
    pub(super) fn of(&self, i: u32, j: u32) -> &[Chunk] {
        let n = TILE / CELL;
        let (cx, cy) = ((i - self.x0) / CELL, (j - self.y0) / CELL);
        let c = (cy * n + cx) as usize;
        &self.chunks[self.ranges[c]..self.ranges[c + 1]]
    }
}

/// A tile's per-ray scratch space: the hits of one key distance awaiting compositing, and the
/// composited hits' Gaussians (or colours) and weights awaiting their colours.
#[derive(Default)]
pub(super) struct Scratch {
    pending: Vec<GaussianHit>,
    composited: Vec<(u32, f32)>,
    colors: Vec<Vec3>,
    products: Products,
}

/// One proxy in a tile's list.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Entry {
    /// `[u0, v0, u1, v1]`: the continuous image coordinates whose rays can enter the proxy's
    /// box and, with the footprint on, its screen ellipse (infinite for a box around the
    /// camera plane).
    pub(super) rect: [f32; 4],
    /// The screen ellipse of [`super::camera::PixelSplat::bound`] (centred pixels): a ray passes only if
    /// `δᵀ·k·δ ≤ amax`, `δ = mu − p` (`k = 0`, `amax = ∞` where there is none).
    pub(super) mu: [f32; 2],
    pub(super) k: [f32; 3],
    pub(super) amax: f32,
    /// The mean's view depth `(μ − o)·f`, the numerator of every hit's key.
    pub(super) z: f32,
    /// The proxy's index in its part.
    pub(super) p: u32,
}

/// Every tile's proxies, in key order.
pub(super) struct TileLists {
    /// Tiles across.
    tw: usize,
    /// `starts[k]..starts[k + 1]` is tile `k`'s range of `entries`.
    starts: Vec<usize>,
    entries: Vec<Entry>,
}

/// The screen rectangle of a box (anchor-relative corners `lo`, `hi` of a part fixed in the
/// world at `anchor`), widened by [`RECT_MARGIN`]; None when a corner is not in front of the
/// camera (the box's rays then span more than a projection bounds).
fn screen_rect(cam: &Camera, anchor: DVec3, (lo, hi): (Vec3, Vec3)) -> Option<[f64; 4]> {
    let (lo, hi) = (lo.as_dvec3() + anchor, hi.as_dvec3() + anchor);
    let mut r = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for c in 0..8 {
        let x = DVec3::new(
            if c & 1 == 0 { lo.x } else { hi.x },
            if c & 2 == 0 { lo.y } else { hi.y },
            if c & 4 == 0 { lo.z } else { hi.z },
        );
        let q = cam.world_to_cam * (x - cam.centre);
        if !(q.z > 0.0) {
            return None;
        }
        let (u, v) = (cam.fx * q.x / q.z + cam.cx, cam.fy * q.y / q.z + cam.cy);
        r = [r[0].min(u), r[1].min(v), r[2].max(u), r[3].max(v)];
    }
    let m = |x: f64| RECT_MARGIN + 1e-5 * x.abs();
    let r = [
        r[0] - m(r[0]),
        r[1] - m(r[1]),
        r[2] + m(r[2]),
        r[3] + m(r[3]),
    ];
    r.iter().all(|x| x.is_finite()).then_some(r)
}

impl TileLists {
    /// Bin part 0's proxies with boxes `boxes` for `cam`: every proxy whose mean is beyond the
    /// near cull (the per-ray test, on the same f32 numbers) into the tiles its rectangle
    /// touches, each tile's list in `(z, Gaussian index)` order.
    pub(super) fn build(
        tracer: &GaussianTracer,
        cam: &Camera,
        boxes: &[(Vec3, Vec3)],
        pad: Option<&Padded>,
        near: f32,
    ) -> TileLists {
        // The pixel records' screen ellipses (footprint on).
        let pixels = pad
            .filter(|p| p.mode == Footprint::On)
            .map(|p| (p.pixels[0].as_slice(), p.variance, p.principal));
        let part = &tracer.parts[0];
        let ro = tracer.local_point(0, cam.centre);
        let fwd = tracer.local_dir(0, cam.world_to_cam.row(2));
        let (w, h) = (cam.width as f64, cam.height as f64);
        let t = TILE as f64;
        let tw = cam.width.div_ceil(TILE) as usize;
        let th = cam.height.div_ceil(TILE) as usize;
        // (key, entry, tile rectangle) of each proxy the camera can see.
        let mut items: Vec<(u64, Entry, [u32; 4])> = (0..part.proxy.len())
            .into_par_iter()
            .filter_map(|p| {
                let z = (part.proxy[p].mean - ro).dot(fwd);
                if z <= near {
                    return None;
                }
                let key = ((order_bits(z) as u64) << 32) | (part.id_offset + part.index[p]) as u64;
                let bound = pixels.and_then(|(px, s, _)| px[p].bound(s));
                let mut entry = Entry {
                    z,
                    p: p as u32,
                    amax: f32::INFINITY,
                    ..Entry::default()
                };
                let rect = screen_rect(cam, part.anchor, boxes[p]);
                let rect = match (rect, bound, pixels) {
                    (Some(r), Some((mu, k, amax, half)), Some((_, _, (cx, cy)))) => {
                        (entry.mu, entry.k, entry.amax) = (mu, k, amax);
                        let (u, v) = (cx + mu[0] as f64, cy + mu[1] as f64);
                        let e = [u - half[0], v - half[1], u + half[0], v + half[1]];
                        let m = |x: f64| RECT_MARGIN + 1e-5 * x.abs();
                        Some([
                            r[0].max(e[0] - m(e[0])),
                            r[1].max(e[1] - m(e[1])),
                            r[2].min(e[2] + m(e[2])),
                            r[3].min(e[3] + m(e[3])),
                        ])
                    }
                    (r, _, _) => r,
                };
                let (rect, tiles) = match rect {
                    Some(r) => {
                        // Off screen, or no ray both enters the box and meets the ellipse.
                        if r[2] < 0.0 || r[3] < 0.0 || r[0] > w || r[1] > h {
                            return None;
                        }
                        if r[0] > r[2] || r[1] > r[3] {
                            return None;
                        }
                        let tile = |x: f64, n: usize| (x / t).floor().clamp(0.0, (n - 1) as f64);
                        let tiles = [
                            tile(r[0], tw) as u32,
                            tile(r[1], th) as u32,
                            tile(r[2], tw) as u32,
                            tile(r[3], th) as u32,
                        ];
                        // Rounded outward to f32.
                        let down = |x: f64| {
                            let f = x as f32;
                            if f as f64 > x {
                                f.next_down()
                            } else {
                                f
                            }
                        };
                        let up = |x: f64| {
                            let f = x as f32;
                            if (f as f64) < x {
                                f.next_up()
                            } else {
                                f
                            }
                        };
                        ([down(r[0]), down(r[1]), up(r[2]), up(r[3])], tiles)
                    }
                    None => (
                        [
                            f32::NEG_INFINITY,
                            f32::NEG_INFINITY,
                            f32::INFINITY,
                            f32::INFINITY,
                        ],
                        [0, 0, tw as u32 - 1, th as u32 - 1],
                    ),
                };
                entry.rect = rect;
                Some((key, entry, tiles))
            })
            .collect();
        // Keys are unique (the Gaussian index is in them), so the order is total.
        items.par_sort_unstable_by_key(|x| x.0);
        let mut count = vec![0usize; tw * th + 1];
        for (_, _, r) in &items {
            for ty in r[1]..=r[3] {
                for tx in r[0]..=r[2] {
                    count[ty as usize * tw + tx as usize + 1] += 1;
                }
            }
        }
        for k in 1..count.len() {
            count[k] += count[k - 1];
        }
        let starts = count.clone();
        let mut next = count;
        let mut entries = vec![Entry::default(); *starts.last().unwrap_or(&0)];
        // In key order into each tile: every tile's list comes out sorted.
        for (_, e, r) in &items {
            for ty in r[1]..=r[3] {
                for tx in r[0]..=r[2] {
                    let k = ty as usize * tw + tx as usize;
                    entries[next[k]] = *e;
                    next[k] += 1;
                }
            }
        }
        TileLists {
            tw,
            starts,
            entries,
        }
    }

    /// Tile `(tx, ty)`'s list.
    pub(super) fn tile(&self, tx: u32, ty: u32) -> &[Entry] {
        let k = ty as usize * self.tw + tx as usize;
        &self.entries[self.starts[k]..self.starts[k + 1]]
    }

    /// Tile `(tx, ty)`'s list split into its [`CELL`]×[`CELL`]-pixel cells, each in the
    /// tile's order: a ray then scans only the proxies whose rectangles reach its cell.
    /// `pad`'s pixel records (mode `on`) go into the chunks beside their entries.
    pub(super) fn cells(&self, tx: u32, ty: u32, pad: Option<&Padded>) -> Cells {
        let records = pad
            .filter(|p| p.mode == Footprint::On)
            .map(|p| p.pixels[0].as_slice());
        Cells::build(self.tile(tx, ty), records, (tx, ty))
    }
}

impl Cells {
    /// Tile `(tx, ty)`'s `list` split into cells, each cell's entries in [`Chunk`]s with their
    /// proxies' `records` (the default record without them): the cells of
    /// `screen_cells::split_cells` (`cell_span`), each in the list's order, without the
    /// intermediate lists.
    pub(super) fn build(
        list: &[Entry],
        records: Option<&[PixelSplat]>,
        (tx, ty): (u32, u32),
    ) -> Cells {
        let n = (TILE / CELL) as usize;
        let (x0, y0) = ((tx * TILE) as f64, (ty * TILE) as f64);
        let spans: Vec<[usize; 4]> = list
            .iter()
            .map(|e| {
                let (cx0, cx1) = cell_span(e.rect[0], e.rect[2], x0, CELL, n);
                let (cy0, cy1) = cell_span(e.rect[1], e.rect[3], y0, CELL, n);
                [cx0, cy0, cx1, cy1]
            })
            .collect();
        let mut count = vec![0usize; n * n];
        for s in &spans {
            for cy in s[1]..=s[3] {
                for c in &mut count[cy * n + s[0]..=cy * n + s[2]] {
                    *c += 1;
                }
            }
        }
        let mut ranges = Vec::with_capacity(n * n + 1);
        ranges.push(0);
        for c in &count {
            ranges.push(ranges[ranges.len() - 1] + c.div_ceil(LANES));
        }
        let mut chunks = vec![Chunk::EMPTY; ranges[n * n]];
        // Entries placed so far in each cell.
        count.fill(0);
        for (i, (e, s)) in list.iter().zip(&spans).enumerate() {
            if let (Some(r), Some(ahead)) = (records, list.get(i + PREFETCH_AHEAD)) {
                // The records are read in the list's depth order, scattered over the frame's
                // proxies: their loads were 40 % of this function (`perf annotate`).
                crate::prefetch::lines(std::slice::from_ref(&r[ahead.p as usize]));
            }
            let px = records.map_or_else(PixelSplat::default, |r| r[e.p as usize]);
            for cy in s[1]..=s[3] {
                for cx in s[0]..=s[2] {
                    let c = cy * n + cx;
                    let at = count[c];
                    count[c] += 1;
                    chunks[ranges[c] + at / LANES].set(at % LANES, e, &px);
                }
            }
        }
        Cells {
            x0: tx * TILE,
            y0: ty * TILE,
            chunks,
            ranges,
        }
    }
}

/// [`sh::eval_color`] of `coeffs` with the direction's basis `b` already computed: the same
/// float operations in the same order, so the same bits (`tile_tests`).
#[inline]
#[cfg(test)]
pub(super) fn color_from_basis(coeffs: &[Vec3], b: &[f32; 16]) -> Vec3 {
    let mut c = Vec3::ZERO;
    for (x, b) in coeffs.iter().zip(b) {
        c += *x * *b;
    }
    (c + Vec3::splat(0.5)).max(Vec3::ZERO)
}

/// One primary ray of the tile path: the cell list `list` it walks, its origin `o`, direction
/// `d`, continuous image coordinate `uv` and the camera's `forward` axis, its footprint `fp`
/// (None with the footprint off) with the camera's grown boxes, and `mean_colors`, the colours
/// toward the means seen from the frame's origin (with [`ShDirection::Mean`]; a ray from
/// elsewhere evaluates its own).
#[derive(Clone, Copy)]
pub(super) struct TileRay<'a> {
    pub list: &'a [Chunk],
    pub o: DVec3,
    pub d: DVec3,
    pub uv: (f64, f64),
    pub forward: DVec3,
    pub fp: Option<(RayFp<'a>, &'a Padded)>,
    pub mean_colors: Option<(DVec3, &'a [Vec3])>,
}

/// A primary ray's footprint as the tile path is given it.
#[derive(Clone, Copy, Debug)]
pub(super) enum RayFp<'a> {
    /// Worked out whole ([`RayFootprint::pinhole`]).
    Whole(RayFootprint),
    /// Only its pixel ([`crate::footprint::pinhole_pixel`], the same numbers): the frame passed
    /// [`crate::footprint::covers_frame`], so `pinhole` gives every one of its rays a
    /// footprint, and the rest of it, which mode `on` reads only for a lane without a usable
    /// pixel record, is worked out when such a lane comes. (A record is unusable only when its
    /// numbers are not finite at a positive view depth, so that rarely happens; every other
    /// ray is the same numbers as with [`RayFp::Whole`], checked against brute force by the
    /// tile tests, which now take this path.)
    Pixel {
        cam: &'a Camera,
        d: DVec3,
        variance: f64,
        pixel: (f64, f64),
    },
}

impl RayFp<'_> {
    /// The ray's continuous pixel.
    fn pixel(&self) -> (f64, f64) {
        match self {
            RayFp::Whole(f) => f.pixel,
            RayFp::Pixel { pixel, .. } => *pixel,
        }
    }
}

/// The ray's whole footprint in part 0's frame, worked out on first use and kept in `local`.
fn whole<'l>(
    local: &'l mut Option<LocalFootprint>,
    tracer: &GaussianTracer,
    f: RayFp<'_>,
    pad: &Padded,
) -> Option<&'l LocalFootprint> {
    if local.is_none() {
        let full = match f {
            RayFp::Whole(f) => f,
            RayFp::Pixel {
                cam, d, variance, ..
            } => RayFootprint::pinhole(cam, d, variance)?,
        };
        *local = Some(LocalFootprint::new(tracer, 0, &full, pad));
    }
    local.as_ref()
}

impl GaussianTracer {
    /// Whether [`GaussianTracer::render`] takes the tile path (see the module documentation).
    pub(super) fn tiles_apply(&self, opts: &RenderOptions) -> bool {
        self.parts.len() == 1
            && self.placed[0].is_none()
            && opts.near >= 0.0
            && (opts.footprint == Footprint::Projected || opts.order == HitOrder::MeanDepth)
    }

    /// One primary ray ([`TileRay`]): what [`GaussianTracer::trace_fp`] returns for it (its
    /// statistics aside: one traversal, and the candidates its rectangle and ellipse tests
    /// passed); `scratch` is the tile's scratch space.
    ///
    /// Hits are composited as they come (transmittance, depth and where the ray stops need no
    /// colour); their colours are evaluated together at the end and added in the hits' order,
    /// the same float operations in the same order as blending each hit's colour as it comes.
    pub(super) fn trace_tile(
        &self,
        ray: TileRay<'_>,
        opts: &RenderOptions,
        scratch: &mut Scratch,
    ) -> PixelOut {
        #[cfg(target_arch = "x86_64")]
        if vector_exp_supported() {
            // SAFETY: AVX2 and FMA are present.
            return unsafe {
                if exp_lanes::matches_platform() {
                    self.trace_tile_avx2::<true>(ray, opts, scratch)
                } else {
                    self.trace_tile_avx2::<false>(ray, opts, scratch)
                }
            };
        }
        self.trace_tile_with::<false, false>(ray, opts, scratch)
    }

    /// [`GaussianTracer::trace_tile`] compiled for AVX2 and FMA: the eight-lane rectangle,
    /// ellipse and `q` of a chunk ([`Chunk::pass`], [`Chunk::q`]) in one 256-bit register each
    /// instead of two 128-bit ones, and with `VEXP` the lanes' `exp(−q/2)` together
    /// ([`exp_lanes`]: the platform's `expf` bits, checked by `matches_platform`). The same
    /// IEEE operations in the same order (Rust fuses a multiply and an add only where
    /// `mul_add` says so: in `exp_lanes`, where glibc's FMA build fuses them too), so the
    /// same bits.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn trace_tile_avx2<const VEXP: bool>(
        &self,
        ray: TileRay<'_>,
        opts: &RenderOptions,
        scratch: &mut Scratch,
    ) -> PixelOut {
        self.trace_tile_with::<true, VEXP>(ray, opts, scratch)
    }

    /// The body of [`GaussianTracer::trace_tile`], inlined into each of its builds; `AVX2`:
    /// the build compiled for AVX2 and FMA (chunks pass by [`Chunk::pass_avx2`]); `VEXP`: take
    /// α's exponential from [`exp_lanes`] (only in that build).
    #[inline(always)]
    fn trace_tile_with<const AVX2: bool, const VEXP: bool>(
        &self,
        ray: TileRay<'_>,
        opts: &RenderOptions,
        scratch: &mut Scratch,
    ) -> PixelOut {
        let TileRay {
            list,
            o,
            d,
            uv,
            forward,
            fp,
            mean_colors,
        } = ray;
        let part = &self.parts[0];
        let (ro, rd) = (self.local_point(0, o), self.local_dir(0, d));
        let fwd = self.local_dir(0, forward);
        let forward_cos = rd.dot(fwd);
        let mode = fp.map_or(Footprint::Off, |(_, p)| p.mode);
        // The ray's whole footprint in the part's frame, where it is at hand; a pixel-only
        // footprint is completed the first time a lane needs the 3-D form.
        let mut local = fp.and_then(|(f, pad)| match f {
            RayFp::Whole(f) => Some(LocalFootprint::new(self, 0, &f, pad)),
            RayFp::Pixel { .. } => None,
        });
        // What every lane needs: the centred pixel and the low-pass `s`, `s²`.
        let pixel = fp.map(|(f, pad)| {
            let s = pad.variance as f32;
            let p = f.pixel();
            (
                (
                    (p.0 - pad.principal.0) as f32,
                    (p.1 - pad.principal.1) as f32,
                ),
                s,
                s * s,
            )
        });
        let (u, v) = (uv.0 as f32, uv.1 as f32);
        let (cu, cv) = pixel.map_or((0.0, 0.0), |(c, _, _)| c);
        let mut candidates = 0u32;
        let Scratch {
            pending,
            composited,
            colors,
            products,
        } = scratch;
        let by_ray = opts.sh_direction == ShDirection::Ray;
        // The frame's table holds this ray's colours only when it starts where the table was
        // made.
        let table = mean_colors.and_then(|(at, c)| (at == o).then_some(c));
        composited.clear();
        colors.clear();
        let mut comp = RayComposite {
            acc: Accum::default(),
            hits: 0,
            composited,
            opts,
            mean: (opts.sh_direction == ShDirection::Mean).then_some((table, o)),
        };
        pending.clear();
        let mut held: Option<GaussianHit> = None;
        let mut stopped = false;
        'walk: for chunk in list {
            let mut pass = chunk_pass::<AVX2>(chunk, u, v, cu, cv);
            if pass == 0 {
                continue;
            }
            // Mode `on`: the eight lanes' `q` from the pixel records (`Part::response_fp`).
            let lanes_q = match pixel {
                Some((c, s, s2)) if mode == Footprint::On => Some(chunk.q(c, s, s2)),
                _ => None,
            };
            // `alpha_of`'s exponential of every lane at once, where the lanes have its bits.
            let lanes_e = match lanes_q {
                Some((q, _)) if VEXP => Some(exp_lanes::exp_lanes(q.map(|q| -0.5 * q))),
                _ => None,
            };
            while pass != 0 {
                let l = pass.trailing_zeros() as usize;
                pass &= pass - 1;
                candidates += 1;
                let p = chunk.p[l] as usize;
                let r = match fp {
                    Some((f, pad)) if mode == Footprint::Projected => {
                        whole(&mut local, self, f, pad)
                            .and_then(|f| part.response_projected(p, ro, rd, f, &pad.splats[0][p]))
                    }
                    Some((f, pad)) => {
                        // `Part::response_fp` keyed at the mean's depth, lane `l`'s share.
                        let q = match lanes_q {
                            Some((q, ok)) if chunk.ok[l] => (ok >> l & 1 == 1).then_some(q[l]),
                            _ => whole(&mut local, self, f, pad)
                                .and_then(|f| part.widened_q_3d(p, ro, f)),
                        };
                        q.filter(|q| *q <= chunk.r2[l])
                            .and_then(|q| match lanes_e {
                                Some(e) if in_exp_range(-0.5 * q) => {
                                    alpha_of_exp(chunk.opacity[l], e[l])
                                }
                                _ => alpha_of(chunk.opacity[l], q),
                            })
                            .map(|alpha| (0.0, alpha))
                    }
                    _ => part.response(p, ro, rd),
                };
                let Some((mut t, alpha)) = r else {
                    continue;
                };
                if mode != Footprint::Projected {
                    // `camera::mean_depth_key`, its numerator computed once per camera.
                    t = chunk.z[l] / forward_cos;
                }
                if by_ray {
                    // Its colour is evaluated after the walk.
                    prefetch(part.cloud.sh_of(part.index[p] as usize));
                }
                let hit = Hit {
                    t,
                    gaussian: part.id_offset + part.index[p],
                    instance: 0,
                    group: 0,
                    payload: GaussianPayload {
                        index: part.index[p],
                        alpha,
                    },
                };
                // The hits of one key distance wait until a hit keyed beyond them comes: one
                // alone in `held`; several (rare: keys rounding equal) in `pending`, sorted.
                let same = |h: &GaussianHit| h.t.to_bits() == t.to_bits();
                let stop = match held {
                    Some(h) if same(&h) => {
                        pending.extend([h, hit]);
                        held = None;
                        false
                    }
                    Some(h) => {
                        held = Some(hit);
                        comp.composite(self, &h)
                    }
                    None if pending.first().is_some_and(same) => {
                        pending.push(hit);
                        false
                    }
                    None => {
                        held = Some(hit);
                        comp.flush(self, pending)
                    }
                };
                if stop {
                    stopped = true;
                    break 'walk;
                }
            }
        }
        if !stopped {
            match held {
                Some(h) => {
                    comp.composite(self, &h);
                }
                None => {
                    comp.flush(self, pending);
                }
            }
        }
        let RayComposite {
            mut acc,
            hits,
            composited,
            ..
        } = comp;
        if by_ray && !composited.is_empty() {
            // The SH basis of the ray's direction: every hit is seen along it (`hit_color`).
            let b = sh::basis(part.cloud.sh_degree, rd);
            for group in composited.chunks(LANES) {
                let mut coeffs = [[].as_slice(); LANES];
                for (c, (g, _)) in coeffs.iter_mut().zip(group) {
                    *c = part.cloud.sh_of(*g as usize);
                }
                colors_from_basis(&coeffs[..group.len()], &b, products, colors);
            }
        }
        // The ray's colours after the walk, in the hits' order (empty with `mean`, whose
        // colours were added as they came).
        for (c, (_, w)) in colors.iter().zip(composited.iter()) {
            acc.rgb += *c * *w;
        }
        PixelOut {
            rgb: acc.rgb + opts.background * acc.tr,
            alpha: 1.0 - acc.tr,
            depth: acc.depth(),
            hits,
            traversals: 1,
            candidates,
        }
    }
}
