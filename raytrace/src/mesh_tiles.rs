//! Mode `mesh`, primary rays of a pinhole camera traced tile by tile: the triangles a
//! 16×16-pixel tile can see are gathered once, ordered by a lower bound of their hits'
//! distances, and each of the tile's rays walks that list with the per-ray test, k-buffer and
//! compositing of [`MeshTracer::trace`] (`mesh_hit`), stopping where no later triangle can
//! come before the hit compositing stops at.
//!
//! The binning is native splatting's (Kerbl et al. 2023: a global depth sort, then per-tile
//! ranges), with triangles: each triangle's vertices, as the hit test sees them (anchor-relative
//! f32 values carried to the world in f64), are projected; the triangle goes into every tile
//! its widened screen rectangle touches. Its list key is the least view depth `z` of its planar
//! group (a fan's hits all take the group plane's distance) less a margin: along a unit
//! direction `d`, a point at view depth `z ≥ 0` is at ray distance `z / (d·f) ≥ z`, so no hit of
//! the triangle is nearer than its key, and a ray can stop walking at the first entry keyed
//! beyond its k-buffer's cull distance.
//!
//! Once a frame each binned triangle gets a record (`mesh_cands::Cand`): its rectangle, its
//! projected edges as a conservative screen-space pre-test with the rectangle's margin, and its
//! vertices as the exact test reads them (no index buffer on the ray's path); a tile copies its
//! records into its cells. A triangle the viewer layout writes twice (both windings) is binned
//! once and its other winding tested only where the first's outcome leaves it open
//! (`mesh_hit::Tested`).
//!
//! A ray collects all its hits up to compositing's stop in one unbounded buffer
//! ([`KBuffer::unbounded`]), ordered by the full key (distance, Gaussian, instance, group)
//! with the lowest triangle index kept among equal keys: exactly the brute-force reference
//! (every triangle tested, hits sorted, `mesh_tile_tests`). The per-ray BVH path fills buffers
//! of k hits round after round and keeps the first-found triangle for the k-th key of a full
//! buffer; the two can differ only there (a tie at the k-th key between triangles of one fan,
//! or the two windings of one triangle, whose barycentrics are the same numbers in another
//! order), in the last bits of the interpolated colour.
//!
//! Which renders take this path: obvhs (the default backend; an Embree build traces over
//! single triangles and may report a hit by its own edge rule, so it keeps its per-ray path),
//! every mesh over runs of triangles (`MeshTracer::new`'s default), and a scene of several
//! instances (the node layout of a viewer export, where the per-ray path's two-level traversal
//! was slowest), or, for fewer instances, images with rays enough to pay for binning every
//! triangle (a small image of a one-node mesh keeps its own BVH, see [`MeshTracer::tiles_pay`]).

use glam::DVec3;
use rayon::prelude::*;
use splatbridge_scene::{Camera, Frame};

use crate::backend::BackendKind;
use crate::error::Result;
use crate::geom::ray_box;
use crate::hit_record::{HitLists, RecordedHit};
use crate::kbuffer::{Accum, KBuffer};
use crate::mesh_cands::{mirror_pairs, Cand, Cold, Edges, HotChunk, LANES};
use crate::mesh_hit::{Compositor, LocalRay, Query, Tested};
use crate::mesh_tracer::{MeshTracer, PreparedInstance, TrianglePayload};
use crate::render::{camera_ray, render_frame_tiles, RenderOptions, Stats};
use crate::screen_cells::cell_span;

/// A scene of fewer than `MIN_INSTANCES` instances is traced through the tiles when its rays
/// are at least this fraction of its triangles. Measured on `fourth_st`'s one-node exports
/// (`--layout input`, 0.71 M and 2.83 M triangles) at 80×60 to 1920×1080, the per-ray path
/// was faster below about a 44th (texture) and a 32nd (meshsplats) of the triangles; a 25th
/// leaves the tiles only where they clearly pay (`docs/trace-speed.md`, "Every layout through
/// the tiles").
pub const TRIANGLES_PER_RAY: u64 = 25;

/// Runs of triangles binned together by one thread (`TileLists::build`).
const RUN_BLOCK: usize = 64;

/// Tile edge in pixels (native's `BLOCK_X = BLOCK_Y`).
pub const TILE: u32 = 16;

/// Edge in pixels of the cells a tile's list is split into before its rays are traced.
const CELL: u32 = 4;

/// Widening of a triangle's screen rectangle beyond its vertices' projection, in pixels: the
/// f32 rounding of the ray's direction moves its pixel by about 1e-4 px at focal lengths of
/// 1e3 px; 0.05 px plus a relative 1e-5 of the coordinate is a wide margin over it. The f32
/// hit test's own rounding (the ray origin and vertices relative to the mesh's anchor) is
/// covered by [`ORIGIN_MARGIN`].
const RECT_MARGIN: f64 = 0.05;

/// The watertight test runs on f32 coordinates relative to the mesh's anchor, which round by
/// 6e-8 of their magnitude `R` (the camera's distance from the anchor plus the mesh's size): a
/// crossing may move sideways by a few such ulps, `R / z · f` pixels at view depth `z` and
/// focal length `f`. 1e-6 (about 17 ulps) of it widens each rectangle.
const ORIGIN_MARGIN: f64 = 1e-6;

/// Every tile's triangles, each list in key order: per tile, indices into `cands` (one record
/// per binned triangle, in key order).
pub(crate) struct TileLists {
    /// Instances skipped whole: their box is behind the camera or off the image (`box_unseen`).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) skipped: usize,
    tw: usize,
    starts: Vec<usize>,
    /// Positions in `cands`, tile after tile, each tile's in list order.
    entries: Vec<u32>,
    /// One record per binned triangle, instance after instance.
    cands: Vec<Cand>,
    /// Positions in `cands` in list order.
    #[cfg(test)]
    order: Vec<u32>,
}

/// A total order on f32 as u32 (negative values below positive ones).
#[inline]
fn order_bits(z: f32) -> u32 {
    let b = z.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// `x` rounded to an f32 not above it.
fn down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x {
        f.next_down()
    } else {
        f
    }
}

/// `x` rounded to an f32 not below it.
fn up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f.next_up()
    } else {
        f
    }
}

/// A vertex seen from the camera: view depth and image coordinates (meaningful for z > 0).
#[derive(Clone, Copy)]
struct Projected {
    z: f64,
    u: f64,
    v: f64,
}

impl TileLists {
    /// Bin the triangles of `insts` for `cam`.
    pub(crate) fn build(tracer: &MeshTracer, insts: &[PreparedInstance], cam: &Camera) -> Self {
        Self::build_with(tracer, insts, cam, true)
    }

    /// [`TileLists::build`]; `skip_unseen: false` projects every instance's triangles, even
    /// those of an instance whose box the camera cannot see (the reference of `box_unseen`).
    pub(crate) fn build_with(
        tracer: &MeshTracer,
        insts: &[PreparedInstance],
        cam: &Camera,
        skip_unseen: bool,
    ) -> Self {
        let (w, h) = (cam.width as f64, cam.height as f64);
        let tw = cam.width.div_ceil(TILE) as usize;
        let th = cam.height.div_ceil(TILE) as usize;
        let focal = cam.fx.max(cam.fy);
        let mut blocks: Vec<Vec<Cand>> = Vec::new();
        let mut skipped = 0;
        for (ii, inst) in insts.iter().enumerate() {
            let blas = &tracer.blas[inst.mesh];
            let mesh = &tracer.scene.meshes[inst.mesh];
            if mesh.tris.is_empty() || blas.run_start.is_empty() {
                continue;
            }
            // A bound on how much the node's transform stretches a length (three times its
            // largest matrix entry), and the camera's distance from the anchor plus the mesh's
            // size, in world units.
            let scale = 3.0
                * inst
                    .to_world
                    .matrix3
                    .to_cols_array()
                    .iter()
                    .fold(0.0f64, |m, x| m.max(x.abs()));
            let reach = (inst.to_world.transform_point3(blas.anchor) - cam.centre).length()
                + scale * (blas.hi - blas.lo).length();
            let slack = 1e-6 * reach;
            // No triangle of an instance whose box lies behind the camera or off the image
            // would be binned: skip it before projecting its vertices (windows of a large view,
            // as distillation records them, see a small part of the scene).
            if skip_unseen && box_unseen(cam, inst, blas, focal, reach, slack) {
                skipped += 1;
                continue;
            }
            let proj: Vec<Projected> = mesh
                .positions
                .par_iter()
                .map(|&p| {
                    let x = inst
                        .to_world
                        .transform_point3(blas.anchor + blas.relative(p).as_dvec3());
                    let q = cam.world_to_cam * (x - cam.centre);
                    Projected {
                        z: q.z,
                        u: cam.fx * q.x / q.z + cam.cx,
                        v: cam.fy * q.y / q.z + cam.cy,
                    }
                })
                .collect();
            // The least view depth of each group, less its planarity tolerance (the plane a
            // fan's hits take may lie off a triangle by 1e-3 of its size, `planar_groups`):
            // taken against the group's largest triangle side, a bound at most the
            // per-triangle one (only the walk's early exit rests on keys; hits do not).
            let runs = blas.run_start.len() - 1;
            let gext = blas.group_extent.get_or_init(|| group_extents(mesh, blas));
            let mut gz = vec![f64::INFINITY; blas.planes.len()];
            for p in 0..runs {
                for t in blas.run_start[p] as usize..blas.run_start[p + 1] as usize {
                    let g = blas.group.get(p, t) as usize;
                    let z = mesh.tris[t]
                        .iter()
                        .map(|&i| proj[i as usize].z)
                        .fold(f64::INFINITY, f64::min);
                    gz[g] = gz[g].min(z);
                }
            }
            for (z, e) in gz.iter_mut().zip(gext) {
                *z -= 2e-3 * scale * e;
            }
            let mirror = blas.mirror.get_or_init(|| {
                let mut group = vec![0u32; mesh.tris.len()];
                for p in 0..runs {
                    for t in blas.run_start[p] as usize..blas.run_start[p + 1] as usize {
                        group[t] = blas.group.get(p, t);
                    }
                }
                mirror_pairs(&mesh.tris, &mesh.tri_gaussian, &group)
            });
            let tris = &mesh.tris;
            let extent = w.max(h) + 1.0;
            let make = |p: usize, t: usize| -> Option<Cand> {
                // The higher-indexed triangle of a winding pair goes with the lower one.
                let pair = mirror[t];
                if pair < t as u32 {
                    return None;
                }
                let v = tris[t].map(|i| proj[i as usize]);
                let zmax = v[0].z.max(v[1].z).max(v[2].z);
                // Wholly behind the camera: a hit at t ≥ 0 has view depth ≥ 0.
                if zmax < -slack {
                    return None;
                }
                let g = blas.group.get(p, t);
                let zg = gz[g as usize];
                let zmin = down(zg - 1e-5 * zg.abs() - slack);
                let zfront = v[0].z.min(v[1].z).min(v[2].z);
                let (rect, edges) = if zfront > slack {
                    let m = |x: f64| {
                        RECT_MARGIN + 1e-5 * x.abs() + ORIGIN_MARGIN * focal * reach / zfront
                    };
                    let mut r = [
                        f64::INFINITY,
                        f64::INFINITY,
                        f64::NEG_INFINITY,
                        f64::NEG_INFINITY,
                    ];
                    for p in &v {
                        r = [r[0].min(p.u), r[1].min(p.v), r[2].max(p.u), r[3].max(p.v)];
                    }
                    let ms = r.map(m);
                    let r = [r[0] - ms[0], r[1] - ms[1], r[2] + ms[2], r[3] + ms[3]];
                    if !r.iter().all(|x| x.is_finite()) {
                        everywhere()
                    } else {
                        if r[2] < 0.0 || r[3] < 0.0 || r[0] > w || r[1] > h {
                            return None;
                        }
                        // The rectangle's margin bounds how far along each axis the test's
                        // rounding moves a crossing; twice the largest bounds its distance.
                        let margin = 2.0 * ms.iter().fold(0.0f64, |a, &b| a.max(b));
                        (
                            [down(r[0]), down(r[1]), up(r[2]), up(r[3])],
                            Edges::new(v.map(|p| (p.u, p.v)), margin, extent),
                        )
                    }
                } else {
                    everywhere()
                };
                Some(Cand {
                    zmin,
                    rect,
                    edges,
                    verts: tris[t].map(|i| blas.relative(mesh.positions[i as usize])),
                    inst: ii as u32,
                    tri: t as u32,
                    group: g,
                    mirror: pair,
                })
            };
            // Blocks of runs side by side, each block's records in order into its own vector
            // (sized for all its triangles), joined once below: each record is written twice.
            let rs = &blas.run_start;
            blocks.par_extend((0..runs.div_ceil(RUN_BLOCK)).into_par_iter().map(|b| {
                let (p0, p1) = (b * RUN_BLOCK, ((b + 1) * RUN_BLOCK).min(runs));
                let mut v = Vec::with_capacity((rs[p1] - rs[p0]) as usize);
                for p in p0..p1 {
                    v.extend((rs[p] as usize..rs[p + 1] as usize).filter_map(|t| make(p, t)));
                }
                v
            }));
        }
        let mut cands = Vec::with_capacity(blocks.iter().map(Vec::len).sum());
        for b in &blocks {
            cands.extend_from_slice(b);
        }
        drop(blocks);
        // Tile lists name records by a u32 position: 2³² records would take 460 GB.
        debug_assert!(cands.len() <= u32::MAX as usize);
        let order = list_order(&cands);
        // Tiles a rectangle touches (an infinite one touches every tile), once per record.
        let span = |lo: f32, hi: f32, n: usize| {
            let tile = |x: f32| (x as f64 / TILE as f64).floor().clamp(0.0, (n - 1) as f64);
            (tile(lo) as u32, tile(hi) as u32)
        };
        let spans: Vec<[u32; 4]> = cands
            .par_iter()
            .map(|c| {
                let ((x0, x1), (y0, y1)) = (
                    span(c.rect[0], c.rect[2], tw),
                    span(c.rect[1], c.rect[3], th),
                );
                [x0, x1, y0, y1]
            })
            .collect();
        let mut count = vec![0usize; tw * th + 1];
        for &[x0, x1, y0, y1] in &spans {
            for ty in y0 as usize..=y1 as usize {
                for tx in x0 as usize..=x1 as usize {
                    count[ty * tw + tx + 1] += 1;
                }
            }
        }
        for k in 1..count.len() {
            count[k] += count[k - 1];
        }
        let starts = count.clone();
        let mut next = count;
        let mut entries = vec![0u32; *starts.last().unwrap_or(&0)];
        for &i in &order {
            let [x0, x1, y0, y1] = spans[i as usize];
            for ty in y0 as usize..=y1 as usize {
                for tx in x0 as usize..=x1 as usize {
                    let k = ty * tw + tx;
                    entries[next[k]] = i;
                    next[k] += 1;
                }
            }
        }
        TileLists {
            skipped,
            tw,
            starts,
            entries,
            cands,
            #[cfg(test)]
            order,
        }
    }

    /// Every binned record's key, rectangle, instance and triangle, in list order, as bits.
    #[cfg(test)]
    pub(crate) fn records(&self) -> Vec<[u32; 7]> {
        self.order
            .iter()
            .map(|&i| {
                let c = &self.cands[i as usize];
                let r = c.rect.map(f32::to_bits);
                [c.zmin.to_bits(), r[0], r[1], r[2], r[3], c.inst, c.tri]
            })
            .collect()
    }

    /// Tile `(tx, ty)`'s list.
    fn tile(&self, tx: u32, ty: u32) -> &[u32] {
        let k = ty as usize * self.tw + tx as usize;
        &self.entries[self.starts[k]..self.starts[k + 1]]
    }
}

/// The records' positions in list order: by key, then instance, then triangle (keys are
/// unique with instance and triangle in them, so the order is total). Records arrive instance
/// by instance, each instance's in triangle order, so a record's position orders as
/// (instance, triangle): the key's order bits and the position packed into one u64 sort as the
/// tuple does, and the 108-byte records are not moved (a tile's list names them by position).
fn list_order(cands: &[Cand]) -> Vec<u32> {
    debug_assert!(cands
        .windows(2)
        .all(|w| (w[0].inst, w[0].tri) < (w[1].inst, w[1].tri)));
    let mut keys: Vec<u64> = cands
        .par_iter()
        .enumerate()
        .map(|(i, c)| (order_bits(c.zmin) as u64) << 32 | i as u64)
        .collect();
    keys.par_sort_unstable();
    keys.par_iter().map(|&k| k as u32).collect()
}

/// Each group's largest triangle side, in the mesh's units (the planarity tolerance of its
/// list key, [`TileLists::build`]).
fn group_extents(mesh: &crate::model::Mesh, blas: &crate::mesh_tracer::Blas) -> Vec<f64> {
    let mut ext = vec![0.0f64; blas.planes.len()];
    for p in 0..blas.run_start.len().saturating_sub(1) {
        for t in blas.run_start[p] as usize..blas.run_start[p + 1] as usize {
            let [a, b, c] = mesh.tris[t].map(|i| mesh.positions[i as usize].as_dvec3());
            let e = (b - a).length().max((c - a).length()).max((c - b).length());
            let g = blas.group.get(p, t) as usize;
            ext[g] = ext[g].max(e);
        }
    }
    ext
}

/// The rectangle and edge functions of a triangle every ray may cross.
fn everywhere() -> ([f32; 4], Edges) {
    (
        [
            f32::NEG_INFINITY,
            f32::NEG_INFINITY,
            f32::INFINITY,
            f32::INFINITY,
        ],
        Edges::ALL,
    )
}

/// Whether no triangle of `inst` can be binned for `cam` (see [`TileLists::build`]'s tests on
/// each triangle: wholly behind the camera, or in front of it with a widened rectangle off the
/// image), judged from the eight corners of the mesh's box.
///
/// Why it is exact: a vertex as the hit test sees it, `anchor + f32(p − anchor)`, lies in the box
/// `lo..hi` widened by the f32 rounding of `p − anchor` (2⁻²⁴ of the box's extent; widened here
/// by 1e-6 of it); the node's transform and the camera's are affine, so its camera-space point
/// lies in the convex hull of the corners' points, and in front of the camera (every corner at
/// view depth above `slack`) its projection lies in the hull of the corners' projections. Every
/// triangle's rectangle is then inside the corners' rectangle widened by the largest margin a
/// triangle gets (`RECT_MARGIN`, the relative 1e-5 and `ORIGIN_MARGIN` at the box's least
/// depth), and the f64 rounding of these few operations is covered by a relative 1e-9. Only
/// meshes whose every vertex is finite are judged (`Blas::finite`); a box reaching the camera
/// plane is never skipped.
fn box_unseen(
    cam: &Camera,
    inst: &PreparedInstance,
    blas: &crate::mesh_tracer::Blas,
    focal: f64,
    reach: f64,
    slack: f64,
) -> bool {
    if !blas.finite {
        return false;
    }
    let ext = (blas.hi - blas.lo).max_element();
    let pad = DVec3::splat(1e-6 * ext + 1e-9 * blas.anchor.abs().max_element());
    let (lo, hi) = (blas.lo - pad, blas.hi + pad);
    let mut q = [DVec3::ZERO; 8];
    for (c, qc) in q.iter_mut().enumerate() {
        let p = DVec3::new(
            if c & 1 == 0 { lo.x } else { hi.x },
            if c & 2 == 0 { lo.y } else { hi.y },
            if c & 4 == 0 { lo.z } else { hi.z },
        );
        *qc = cam.world_to_cam * (inst.to_world.transform_point3(p) - cam.centre);
    }
    if !q.iter().all(|x| x.is_finite()) {
        return false;
    }
    // The f64 rounding of a vertex's camera-space point: relative to the magnitudes of the
    // points, the camera's centre and the node's anchor the transforms subtract.
    let size = q.iter().fold(0.0f64, |m, x| m.max(x.abs().max_element()));
    let origin = inst
        .to_world
        .transform_point3(blas.anchor)
        .abs()
        .max_element()
        .max(cam.centre.abs().max_element());
    let eps = 1e-9 * (size + reach + origin);
    let (zlo, zhi) = q
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x.z), b.max(x.z))
        });
    if zhi + eps < -slack {
        return true;
    }
    let z = zlo - eps;
    if !(z > slack) {
        return false;
    }
    let mut r = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for x in &q {
        let (u, v) = (cam.fx * x.x / x.z + cam.cx, cam.fy * x.y / x.z + cam.cy);
        r = [r[0].min(u), r[1].min(v), r[2].max(u), r[3].max(v)];
    }
    let big = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    // A point moved by `eps` in each coordinate moves its projection by at most
    // `f·eps·(1 + |x|/z)/z`; the projection's own rounding is far below 1e-9 of the terms.
    let lateral = q
        .iter()
        .fold(0.0f64, |m, x| m.max(x.x.abs()).max(x.y.abs()))
        / z;
    let moved = cam.fx.abs().max(cam.fy.abs()) * eps * (1.0 + lateral) / z;
    let terms = big + cam.cx.abs() + cam.cy.abs() + 1.0;
    let m =
        RECT_MARGIN + 1e-5 * big + ORIGIN_MARGIN * focal * reach / z + 2.0 * moved + 1e-9 * terms;
    let (w, h) = (cam.width as f64, cam.height as f64);
    r.iter().all(|x| x.is_finite())
        && m.is_finite()
        && (r[2] + m < 0.0 || r[3] + m < 0.0 || r[0] - m > w || r[1] - m > h)
}

/// A tile's rays' shared state: its list split into [`CELL`]×[`CELL`]-pixel cells (each in
/// the tile's order, padded to whole chunks of [`LANES`]; cell `c` is chunks
/// `cell_start[c]..cell_start[c + 1]`, whose part every entry's walk reads, `hot`, is apart
/// from the part only tested triangles read, `cold`, record `LANES·k + l` for lane `l` of
/// chunk `k`), each instance's local ray for the current ray (made on first use), and the
/// buffer.
pub(crate) struct TileCtx {
    x0: u32,
    y0: u32,
    cell_start: Vec<u32>,
    hot: Vec<HotChunk>,
    cold: Vec<Cold>,
    /// `(ray number, local ray)` per instance; None: the ray misses the instance's bounds.
    rays: Vec<(u32, Option<LocalRay>)>,
    ray: u32,
    buf: KBuffer<TrianglePayload>,
}

impl TileCtx {
    pub(crate) fn new(lists: &TileLists, tx: u32, ty: u32, instances: usize) -> Self {
        let list = lists.tile(tx, ty);
        let n = (TILE / CELL) as usize;
        let (x0, y0) = ((tx * TILE) as f64, (ty * TILE) as f64);
        let spans: Vec<[u8; 4]> = list
            .iter()
            .map(|&i| {
                let r = lists.cands[i as usize].rect;
                let (a, b) = cell_span(r[0], r[2], x0, CELL, n);
                let (c, d) = cell_span(r[1], r[3], y0, CELL, n);
                [a as u8, b as u8, c as u8, d as u8]
            })
            .collect();
        let mut counts = vec![0u32; n * n];
        for s in &spans {
            for cy in s[2]..=s[3] {
                for cx in s[0]..=s[1] {
                    counts[cy as usize * n + cx as usize] += 1;
                }
            }
        }
        // Chunk offsets of the cells, and each cell's next record (in records).
        let mut cell_start = vec![0u32; n * n + 1];
        for (k, &c) in counts.iter().enumerate() {
            cell_start[k + 1] = cell_start[k] + c.div_ceil(LANES as u32);
        }
        let total = cell_start[n * n] as usize;
        let mut next: Vec<u32> = cell_start[..n * n]
            .iter()
            .map(|&c| c * LANES as u32)
            .collect();
        let mut hot = vec![HotChunk::EMPTY; total];
        let mut cold = vec![Cand::BLANK.cold(); total * LANES];
        for (&i, s) in list.iter().zip(&spans) {
            let c = &lists.cands[i as usize];
            let h = c.hot();
            for cy in s[2]..=s[3] {
                for cx in s[0]..=s[1] {
                    let k = &mut next[cy as usize * n + cx as usize];
                    let r = *k as usize;
                    hot[r / LANES].set(r % LANES, &h);
                    cold[r] = c.cold();
                    *k += 1;
                }
            }
        }
        TileCtx {
            x0: tx * TILE,
            y0: ty * TILE,
            cell_start,
            hot,
            cold,
            rays: Vec::new(),
            ray: 0,
            buf: KBuffer::unbounded(),
        }
        .with_instances(instances)
    }

    /// The buffer [`MeshTracer::tile_hits`] filled.
    #[cfg(test)]
    pub(crate) fn buffer(&self) -> &KBuffer<TrianglePayload> {
        &self.buf
    }

    fn with_instances(mut self, n: usize) -> Self {
        self.rays = vec![(0, None); n];
        self
    }
}

impl MeshTracer {
    /// Whether [`MeshTracer::render`] takes the tile path (see the module documentation).
    pub fn tiles_apply(&self) -> bool {
        self.backend == BackendKind::Obvhs
            && self
                .scene
                .meshes
                .iter()
                .zip(&self.blas)
                .all(|(m, b)| m.tris.is_empty() || !b.run_start.is_empty())
    }

    /// Whether a render at `time` of `rays` rays (pixels × samples) takes the tile path: where
    /// it applies ([`MeshTracer::tiles_apply`]) and either the scene has at least
    /// [`crate::instances::MIN_INSTANCES`] instances (the per-ray path's two-level traversal is
    /// its slowest case) or the rays are at least a [`TRIANGLES_PER_RAY`]-th of the triangles.
    /// Binning costs a pass over every triangle a frame, which a one-node mesh's own BVH does
    /// not need; past that many rays the one pass a ray pays for it
    /// (`docs/trace-speed.md`, "Every layout through the tiles").
    pub fn tiles_pay(&self, time: f64, rays: u64) -> bool {
        if !self.tiles_apply() {
            return false;
        }
        let insts = self.prepare_list(time);
        let triangles: u64 = insts
            .iter()
            .map(|i| self.scene.meshes[i.mesh].tris.len() as u64)
            .sum();
        insts.len() >= crate::instances::MIN_INSTANCES
            || rays.saturating_mul(TRIANGLES_PER_RAY) >= triangles
    }

    /// Render `cam` at `time` through the tile lists.
    pub(crate) fn render_tiles(
        &self,
        cam: &Camera,
        time: f64,
        opts: &RenderOptions,
    ) -> Result<(Frame, Stats)> {
        cam.validate()?;
        let start = std::time::Instant::now();
        let insts = self.prepare_list(time);
        let lists = TileLists::build(self, &insts, cam);
        let bin = start.elapsed().as_secs_f64();
        let lin = self.scene.colors_linear;
        let (frame, mut stats) = render_frame_tiles(
            cam,
            opts.spp,
            TILE,
            |tx, ty| TileCtx::new(&lists, tx, ty, insts.len()),
            |ctx, o, d, uv| {
                self.tile_hits(&insts, ctx, o, d, uv, opts.min_transmittance);
                let mut comp = Compositor::new(opts, lin);
                for h in &ctx.buf.hits {
                    if comp.add(h) {
                        break;
                    }
                }
                let mut out = comp.finish();
                out.traversals = 1;
                out.candidates = ctx.buf.candidates;
                out
            },
        )?;
        stats.seconds += bin;
        Ok((frame, stats))
    }

    /// Fill `ctx.buf` with the hits of the ray `o + t·d` (unit `d`, image coordinate `uv` in
    /// the tile) in key order, shaded, up to the hit where compositing from transmittance 1
    /// falls below `min_transmittance`.
    pub(crate) fn tile_hits(
        &self,
        insts: &[PreparedInstance],
        ctx: &mut TileCtx,
        o: DVec3,
        d: DVec3,
        uv: (f64, f64),
        min_transmittance: f32,
    ) {
        ctx.ray = ctx.ray.wrapping_add(1);
        if ctx.ray == 0 {
            // Ray numbers wrapped: forget every instance's ray.
            ctx.rays.iter_mut().for_each(|r| r.0 = u32::MAX);
        }
        let q = Query {
            tmin: 0.0,
            tmax: f32::INFINITY,
            after: None,
        };
        let (u, v) = (uv.0 as f32, uv.1 as f32);
        let mut buf = std::mem::replace(&mut ctx.buf, KBuffer::unbounded());
        buf.clear();
        buf.candidates = 0;
        buf.shade_on_insert = true;
        buf.stop = Some((1.0, min_transmittance));
        let mut cull = f32::INFINITY;
        let ray = ctx.ray;
        let rays = &mut ctx.rays;
        let cell = cell_of(ctx.x0, ctx.y0, uv);
        let range = ctx.cell_start[cell] as usize..ctx.cell_start[cell + 1] as usize;
        // The records in key order, eight at a time: the lanes whose key, rectangle and edges
        // pass, in lane order. Keys ascend and the cull distance only falls, so the first
        // record keyed beyond it ends the walk, as one by one.
        'walk: for (k, chunk) in range.clone().zip(&ctx.hot[range]) {
            if chunk.zmin[0] > cull {
                break;
            }
            let mut m = chunk.mask(u, v, cull);
            while m != 0 {
                let l = m.trailing_zeros() as usize;
                m &= m - 1;
                if chunk.zmin[l] > cull {
                    break 'walk;
                }
                let e = &ctx.cold[k * LANES + l];
                self.tile_candidate(insts, rays, ray, e, o, d, &q, &mut buf, &mut cull);
            }
        }
        buf.shade_on_insert = false;
        buf.stop = None;
        ctx.buf = buf;
    }

    /// The walk's test of one record `e` that passed the pre-tests, for the ray `o + t·d`
    /// (number `ray`): its instance's local ray (made on first use), the triangle, and its
    /// other winding where the first's outcome leaves it open (`Tested`).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn tile_candidate(
        &self,
        insts: &[PreparedInstance],
        rays: &mut [(u32, Option<LocalRay>)],
        ray: u32,
        e: &Cold,
        o: DVec3,
        d: DVec3,
        q: &Query,
        buf: &mut KBuffer<TrianglePayload>,
        cull: &mut f32,
    ) {
        let ii = e.inst as usize;
        let inst = &insts[ii];
        let slot = &mut rays[ii];
        if slot.0 != ray {
            *slot = (ray, local_ray(self, inst, o, d));
        }
        let Some(r) = slot.1 else {
            return;
        };
        let tested = self.test_triangle(
            ii, inst.mesh, &r, e.verts, e.group, e.tri, false, q, buf, cull,
        );
        // The other winding, where the first's outcome leaves it open (`Tested`).
        if e.mirror != u32::MAX && tested == Tested::Open {
            let blas = &self.blas[inst.mesh];
            let mesh = &self.scene.meshes[inst.mesh];
            let m = e.mirror;
            let tri = mesh.tris[m as usize].map(|i| blas.relative(mesh.positions[i as usize]));
            self.test_triangle(ii, inst.mesh, &r, tri, e.group, m, false, q, buf, cull);
        }
    }
}

/// The cell of the tile at `(x0, y0)` that holds image coordinate `uv`.
fn cell_of(x0: u32, y0: u32, uv: (f64, f64)) -> usize {
    let n = TILE / CELL;
    let c = |x: f64, origin: u32| {
        ((x - origin as f64) / CELL as f64)
            .floor()
            .clamp(0.0, (n - 1) as f64) as u32
    };
    let (cx, cy) = (c(uv.0, x0), c(uv.1, y0));
    (cy * n + cx) as usize
}

/// The world ray carried into `inst`'s frame, as [`MeshTracer::collect`] carries it: None when
/// it misses the instance's world bounds or leaves them behind its origin.
pub(crate) fn local_ray(
    tracer: &MeshTracer,
    inst: &PreparedInstance,
    o: DVec3,
    d: DVec3,
) -> Option<LocalRay> {
    let (_, b1) = ray_box(o, d, inst.lo, inst.hi)?;
    if b1 < 0.0 {
        return None;
    }
    let blas = &tracer.blas[inst.mesh];
    LocalRay::new(
        inst.to_local.transform_point3(o) - blas.anchor,
        inst.to_local.transform_vector3(d),
    )
}

impl MeshTracer {
    /// [`MeshTracer::record_hits`] through the tile lists: each pixel centre's hits in
    /// compositing order, up to the hit that takes the transmittance below `min_transmittance`
    /// (the walk of [`MeshTracer::ordered_hits`], on the same hits).
    pub(crate) fn record_hits_tiles(
        &self,
        cam: &Camera,
        time: f64,
        min_transmittance: f32,
    ) -> Result<HitLists> {
        cam.validate()?;
        let insts = self.prepare_list(time);
        let lists = TileLists::build(self, &insts, cam);
        let (w, h) = (cam.width as usize, cam.height as usize);
        let t = TILE as usize;
        let (tw, th) = (w.div_ceil(t), h.div_ceil(t));
        // Per tile: each pixel's hit count (row-major in the tile) and the hits.
        let tiles: Vec<(Vec<u32>, Vec<RecordedHit>)> = (0..tw * th)
            .into_par_iter()
            .map(|k| {
                let (tx, ty) = (k % tw, k / tw);
                let mut ctx = TileCtx::new(&lists, tx as u32, ty as u32, insts.len());
                let (mut counts, mut hits) = (Vec::with_capacity(t * t), Vec::new());
                for j in ty * t..((ty + 1) * t).min(h) {
                    for i in tx * t..((tx + 1) * t).min(w) {
                        let uv = (i as f64 + 0.5, j as f64 + 0.5);
                        let (o, d) = camera_ray(cam, uv.0, uv.1);
                        self.tile_hits(&insts, &mut ctx, o, d, uv, min_transmittance);
                        let before = hits.len();
                        let mut acc = Accum::default();
                        for hit in &ctx.buf.hits {
                            let a = hit.payload.rgba.w;
                            if a > 0.0 {
                                hits.push(RecordedHit {
                                    mesh: insts[hit.instance as usize].mesh as u32,
                                    tri: hit.payload.tri,
                                    bary: hit.payload.bary,
                                    t: hit.t,
                                });
                                acc.add(glam::Vec3::ZERO, a, hit.t);
                                if acc.tr < min_transmittance {
                                    break;
                                }
                            }
                        }
                        counts.push((hits.len() - before) as u32);
                    }
                }
                (counts, hits)
            })
            .collect();
        // Row-major pixels from the tiles' row-major pixels.
        let mut count = vec![0u32; w * h];
        for (k, (c, _)) in tiles.iter().enumerate() {
            let (tx, ty) = (k % tw, k / tw);
            let x0 = tx * t;
            let tw_px = (x0 + t).min(w) - x0;
            for (n, &cnt) in c.iter().enumerate() {
                count[(ty * t + n / tw_px) * w + x0 + n % tw_px] = cnt;
            }
        }
        let mut out = HitLists {
            width: cam.width,
            height: cam.height,
            offsets: Vec::with_capacity(w * h + 1),
            hits: Vec::with_capacity(tiles.iter().map(|x| x.1.len()).sum()),
        };
        out.offsets.push(0);
        for &c in &count {
            let last = *out.offsets.last().unwrap_or(&0);
            out.offsets.push(last + c as u64);
        }
        out.hits.resize(
            *out.offsets.last().unwrap_or(&0) as usize,
            RecordedHit {
                mesh: 0,
                tri: 0,
                bary: [0.0; 3],
                t: 0.0,
            },
        );
        for (k, (c, hs)) in tiles.iter().enumerate() {
            let (tx, ty) = (k % tw, k / tw);
            let x0 = tx * t;
            let tw_px = (x0 + t).min(w) - x0;
            let mut at = 0usize;
            for (n, &cnt) in c.iter().enumerate() {
                let p = (ty * t + n / tw_px) * w + x0 + n % tw_px;
                let dst = out.offsets[p] as usize;
                out.hits[dst..dst + cnt as usize].copy_from_slice(&hs[at..at + cnt as usize]);
                at += cnt as usize;
            }
        }
        Ok(out)
    }
}
