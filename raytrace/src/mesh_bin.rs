//! Binning for mode `mesh`'s screen tiles (`mesh_tiles`): each triangle's record, its list
//! key, and every 16×16 tile's list in key order, once a frame.
//!
//! The binning is native splatting's (Kerbl et al. 2023: a global depth sort, then per-tile
//! ranges), with triangles: each triangle's vertices, as the hit test sees them (anchor-relative
//! f32 values carried to the world in f64), are projected; the triangle goes into every tile
//! its widened screen rectangle touches. Its list key is the least view depth `z` of its planar
//! group (a fan's hits all take the group plane's distance) less a margin: along a unit
//! direction `d`, a point at view depth `z ≥ 0` is at ray distance `z / (d·f) ≥ z`, so no hit of
//! the triangle is nearer than its key. Keys are lower bounds only: the walk's early exit rests
//! on them, the hits a ray collects do not (its buffer orders them by their full key), so any
//! valid bound gives the same image. An instance whose box the camera cannot see is skipped
//! whole where none of its triangles would be binned (`box_unseen`).

use glam::DVec3;
use rayon::prelude::*;
use splatbridge_scene::Camera;

use crate::geom::{floor, order_bits};
use crate::mesh_cands::{leads, mirror_pairs, Cand, Edges};
use crate::mesh_groups::{GroupTable, GROUP_MARK};
use crate::mesh_tiles::TILE;
use crate::mesh_tracer::{MeshTracer, PreparedInstance};

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
    pub(crate) cands: Vec<Cand>,
    /// Positions in `cands` in list order.
    #[cfg(test)]
    order: Vec<u32>,
}

/// The rectangle `[u_min, v_min, u_max, v_max]` of image points.
fn bounds(points: impl Iterator<Item = (f64, f64)>) -> [f64; 4] {
    points.fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |r, (u, v)| [r[0].min(u), r[1].min(v), r[2].max(u), r[3].max(v)],
    )
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
pub(crate) fn up(x: f64) -> f32 {
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
    /// Bin the triangles of `insts` for `cam`'s rays from the sample positions `offsets`
    /// within each pixel (`footprint::sample_offsets`, as `render::pixel_at` places them).
    pub(crate) fn build(
        tracer: &MeshTracer,
        insts: &[PreparedInstance],
        cam: &Camera,
        offsets: &[(f64, f64)],
    ) -> Self {
        Self::build_with(tracer, insts, cam, offsets, true)
    }

    /// [`TileLists::build`]; `skip_unseen: false` projects every instance's triangles, even
    /// those of an instance whose box the camera cannot see (the reference of `box_unseen`).
    pub(crate) fn build_with(
        tracer: &MeshTracer,
        insts: &[PreparedInstance],
        cam: &Camera,
        offsets: &[(f64, f64)],
        skip_unseen: bool,
    ) -> Self {
        let samples = Samples::new(offsets, cam);
        let (w, h) = (cam.width as f64, cam.height as f64);
        let tw = cam.width.div_ceil(TILE) as usize;
        let th = cam.height.div_ceil(TILE) as usize;
        let focal = cam.fx.max(cam.fy);
        tracer.prepare_groups(insts, true);
        // Small groups as one record where rays are few for the triangles (`mesh_groups`).
        let rays = (cam.width as u64 * cam.height as u64).saturating_mul(offsets.len() as u64);
        let small_groups = rays.saturating_mul(crate::mesh_groups::SMALL_GROUP_TRIANGLES_PER_RAY)
            <= tracer.triangles_of(insts);
        let mut cands: Vec<Cand> = Vec::new();
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
            let mirror = blas.mirror.get_or_init(|| winding_pairs(mesh, blas));
            let table = blas
                .groups
                .get_or_init(|| GroupTable::new(mesh, blas, mirror));
            let tris = &mesh.tris;
            let extent = w.max(h) + 1.0;
            // The rectangle and pre-test of projected points `v` (bounds `r`) whose nearest
            // lies at view depth `zfront`; None where no ray of the image can meet them.
            let screen = |r: [f64; 4], zfront: f64, edges: &dyn Fn(f64) -> Edges| {
                if !(zfront > slack) {
                    return Some(everywhere());
                }
                let m =
                    |x: f64| RECT_MARGIN + 1e-5 * x.abs() + ORIGIN_MARGIN * focal * reach / zfront;
                let ms = r.map(m);
                let r = [r[0] - ms[0], r[1] - ms[1], r[2] + ms[2], r[3] + ms[3]];
                if !r.iter().all(|x| x.is_finite()) {
                    return Some(everywhere());
                }
                if r[2] < 0.0 || r[3] < 0.0 || r[0] > w || r[1] > h {
                    return None;
                }
                // The rectangle's margin bounds how far along each axis the test's
                // rounding moves a crossing; twice the largest bounds its distance.
                let margin = 2.0 * ms.iter().fold(0.0f64, |a, &b| a.max(b));
                let rect = [down(r[0]), down(r[1]), up(r[2]), up(r[3])];
                Some((rect, samples.may_pass(&rect, || edges(margin))?))
            };
            let make = |p: usize, t: usize| -> Option<Cand> {
                // The higher-indexed triangle of a winding pair goes with the lower one.
                if !leads(mirror, t) {
                    return None;
                }
                let pair = mirror[t];
                let g = blas.group.get(p, t);
                let zg = gz[g as usize];
                let zmin = down(zg - 1e-5 * zg.abs() - slack);
                if table.is_group(g, small_groups) {
                    // One record for the whole group, made at its first triangle
                    // (`mesh_groups`): its rectangle holds every member's.
                    let members = table.members(g);
                    if members[0] != t as u32 {
                        return None;
                    }
                    let v = members
                        .iter()
                        .flat_map(|&m| tris[m as usize])
                        .map(|i| proj[i as usize]);
                    let (zfront, zmax) = v
                        .clone()
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                            (a.min(p.z), b.max(p.z))
                        });
                    if zmax < -slack {
                        return None;
                    }
                    let (rect, edges) =
                        screen(bounds(v.map(|p| (p.u, p.v))), zfront, &|_| Edges::ALL)?;
                    return Some(Cand {
                        zmin,
                        rect,
                        edges,
                        verts: table.record(g).pack(),
                        inst: ii as u32,
                        tri: t as u32,
                        group: g,
                        mirror: GROUP_MARK,
                    });
                }
                let v = tris[t].map(|i| proj[i as usize]);
                let zmax = v[0].z.max(v[1].z).max(v[2].z);
                // Wholly behind the camera: a hit at t ≥ 0 has view depth ≥ 0.
                if zmax < -slack {
                    return None;
                }
                let zfront = v[0].z.min(v[1].z).min(v[2].z);
                let (rect, edges) =
                    screen(bounds(v.iter().map(|p| (p.u, p.v))), zfront, &|margin| {
                        Edges::new(v.map(|p| (p.u, p.v)), margin, extent)
                    })?;
                Some(Cand {
                    zmin,
                    rect,
                    edges,
                    verts: blas.triangle(&mesh.positions, tris[t]),
                    inst: ii as u32,
                    tri: t as u32,
                    group: g,
                    mirror: pair,
                })
            };
            // Runs side by side, their records in order straight into the frame's list.
            let rs = &blas.run_start;
            cands.par_extend(
                (0..runs)
                    .into_par_iter()
                    .flat_map_iter(|p| (rs[p] as usize..rs[p + 1] as usize).map(move |t| (p, t)))
                    .filter_map(|(p, t)| make(p, t)),
            );
        }
        // Tile lists name records by a u32 position: 2³² records would take 460 GB.
        debug_assert!(cands.len() <= u32::MAX as usize);
        let order = list_order(&cands);
        // Tiles a rectangle touches (an infinite one touches every tile), once per record.
        let span = |lo: f32, hi: f32, n: usize| {
            let tile = |x: f32| floor(x as f64 / TILE as f64).clamp(0.0, (n - 1) as f64);
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
    pub(crate) fn tile(&self, tx: u32, ty: u32) -> &[u32] {
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

impl MeshTracer {
    /// Each instanced mesh's winding pairs and group table (and, with `extents`, its groups'
    /// extents, which only binning reads), found on its first frame that needs them: side by
    /// side over the meshes (each is one serial pass over its triangles).
    pub(crate) fn prepare_groups(&self, insts: &[PreparedInstance], extents: bool) {
        insts.par_iter().for_each(|inst| {
            let (blas, mesh) = (&self.blas[inst.mesh], &self.scene.meshes[inst.mesh]);
            if !(mesh.tris.is_empty() || blas.run_start.is_empty()) {
                if extents {
                    blas.group_extent.get_or_init(|| group_extents(mesh, blas));
                }
                let mirror = blas.mirror.get_or_init(|| winding_pairs(mesh, blas));
                blas.groups
                    .get_or_init(|| GroupTable::new(mesh, blas, mirror));
            }
        });
    }
}

/// Each triangle's other winding (`mesh_cands::mirror_pairs` over the mesh's groups), where
/// the two share their material too: a shade of α = 0 settles the other winding only when it
/// samples the same texture (`MeshTracer::zero_alpha_settles`).
fn winding_pairs(mesh: &crate::model::Mesh, blas: &crate::mesh_tracer::Blas) -> Vec<u32> {
    let group = blas.triangle_groups(mesh.tris.len());
    let mut pairs = mirror_pairs(&mesh.tris, &mesh.tri_gaussian, &group);
    let material = |t: usize| mesh.tri_material.get(t);
    for t in 0..pairs.len() {
        let m = pairs[t];
        if m != u32::MAX && material(t) != material(m as usize) {
            pairs[t] = u32::MAX;
        }
    }
    pairs
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

/// The positions a frame's rays start from, per axis: pixel `i`'s samples lie at `i + du`
/// (the offsets' distinct `du`, `render::pixel_at`'s arithmetic), which the walk rounds to f32.
/// A record none of them passes the walk's pre-test for is never a candidate: most sub-pixel
/// triangles of a large export are such (their widened rectangle holds no pixel centre), and
/// dropping them before the sort and the tiles changes no hit (`docs/trace-speed-mesh.md`,
/// "Triangles between the samples").
struct Samples {
    du: Vec<f64>,
    dv: Vec<f64>,
    width: u32,
    height: u32,
}

/// How many sample coordinates per axis [`Samples::may_pass`] tries against the edges; a
/// rectangle holding more is kept without the edge test.
const FEW: usize = 3;

impl Samples {
    fn new(offsets: &[(f64, f64)], cam: &Camera) -> Self {
        let distinct = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v.dedup();
            v
        };
        Samples {
            du: distinct(offsets.iter().map(|o| o.0).collect()),
            dv: distinct(offsets.iter().map(|o| o.1).collect()),
            width: cam.width,
            height: cam.height,
        }
    }

    /// The f32 sample coordinates in `[lo, hi]` along one axis of `n` pixels, into `out`:
    /// their count, or `FEW + 1` once there are more than [`FEW`].
    fn within(lo: f32, hi: f32, offs: &[f64], n: u32, out: &mut [f32; FEW]) -> usize {
        let mut k = 0;
        for &o in offs {
            // From a pixel before the first whose sample can reach `lo` (the f32 rounding of
            // `i + o` moves it by far less than a pixel; `as` takes a positive `s` to its floor,
            // saturating); NaN and anything below 1 start at pixel 0.
            let s = lo as f64 - o;
            let mut i = if s > 1.0 { s as u64 - 1 } else { 0 };
            while i < n as u64 {
                let x = (i as f64 + o) as f32;
                if x > hi {
                    break;
                }
                if x >= lo {
                    if k == FEW {
                        return FEW + 1;
                    }
                    out[k] = x;
                    k += 1;
                }
                i += 1;
            }
        }
        k
    }

    /// The edges of a record with this rectangle, made by `edges()` only for a rectangle
    /// that holds a sample, where some sample of the image may pass the walk's pre-test of it
    /// (`HotChunk::mask`, whose lanes perform `Edges::admit`'s operations); None only where
    /// none can. Samples are taken per axis, so for several samples a pixel this tries a
    /// superset of the pixels' sample positions.
    fn may_pass(&self, rect: &[f32; 4], edges: impl FnOnce() -> Edges) -> Option<Edges> {
        // Beyond a few offsets per axis (more than 4 samples a pixel, a quality setting) the
        // search would cost more than the records it drops.
        if self.du.len() > FEW || self.dv.len() > FEW {
            return Some(edges());
        }
        let (mut us, mut vs) = ([0.0f32; FEW], [0.0f32; FEW]);
        let nu = Self::within(rect[0], rect[2], &self.du, self.width, &mut us);
        let nv = Self::within(rect[1], rect[3], &self.dv, self.height, &mut vs);
        if nu == 0 || nv == 0 {
            return None;
        }
        let e = edges();
        let seen = nu > FEW
            || nv > FEW
            || us[..nu]
                .iter()
                .any(|&u| vs[..nv].iter().any(|&v| e.admit(u, v)));
        seen.then_some(e)
    }
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
    let r = bounds(
        q.iter()
            .map(|x| (cam.fx * x.x / x.z + cam.cx, cam.fy * x.y / x.z + cam.cy)),
    );
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
