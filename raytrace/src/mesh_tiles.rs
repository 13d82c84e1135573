//! Mode `mesh`, primary rays of a pinhole camera traced tile by tile: the triangles a
//! 16×16-pixel tile can see are gathered once, ordered by a lower bound of their hits'
//! distances, and each of the tile's rays walks that list with the per-ray test, k-buffer and
//! compositing of [`MeshTracer::trace`] (`mesh_hit`), stopping where no later triangle can
//! come before the hit compositing stops at.
//!
//! The binning (`mesh_bin`) is native splatting's, with triangles: every tile's list in the
//! order of a lower bound of its triangles' hit distances, so a ray can stop walking at the
//! first entry keyed beyond its k-buffer's cull distance.
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
use crate::footprint::sample_offsets;
use crate::geom::{floor, ray_box};
use crate::hit_record::{record, HitLists, RecordedHit};
use crate::kbuffer::{Accum, KBuffer};
use crate::mesh_bin::TileLists;
use crate::mesh_cands::{Cand, Cold, HotChunk, LANES};
use crate::mesh_groups::{RecordFrame, GROUP_MARK};
use crate::mesh_hit::{plane_distance, Compositor, LocalRay, Query, Tested};
use crate::mesh_tracer::{MeshTracer, PreparedInstance, TrianglePayload};
use crate::render::{camera_ray, render_frame_tiles, RenderOptions, Stats};
use crate::screen_cells::cell_span;

/// A scene of fewer than `MIN_INSTANCES` instances is traced through the tiles when its rays
/// are at least this fraction of its binned records (`MeshTracer::records_of`). Measured on
/// one-node exports (`--layout input`) of `fourth_st` and `plant` at 80×60 to 640×480 with the
/// BVH already built, the tiles became faster above about a 66th of the records (`fourth_st`'s
/// texture export), a 200th (its `rings`), a 435th (`plant`'s meshsplats) and a 680th (its
/// `rings`): the per-ray path's cost a ray grows with the candidates a ray meets, the tiles'
/// with the records binned. A 500th keeps the per-ray path at thumbnail sizes, where it is
/// faster on every export measured, and otherwise takes the tiles; a frame traced per ray
/// also builds the BVH the tiles do not need, 0.15–2.6 s on those exports
/// (`docs/trace-speed-mesh-paths.md`, "Where the tiles pay, measured again").
pub const TRIANGLES_PER_RAY: u64 = 500;

/// [`TRIANGLES_PER_RAY`] for a scene whose every material is opaque (glTF's `OPAQUE`, or no
/// material: an OBJ's): a ray stops at its first hit, so the per-ray path costs little a ray
/// and the tiles pay only from a smaller share of the records on. Measured on `fourth_st`'s
/// OBJ exports with the BVH built, the tiles became faster above about half the records
/// (texture) and a 15th (`rings`); a 25th, the rule measured before for every mesh, keeps
/// these exports where they were.
pub const OPAQUE_TRIANGLES_PER_RAY: u64 = 25;

/// Tile edge in pixels (native's `BLOCK_X = BLOCK_Y`).
pub const TILE: u32 = 16;

/// Edge in pixels of the cells a tile's list is split into before its rays are traced.
const CELL: u32 = 4;

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
    /// [`TileCtx::fill`]'s scratch: each list entry's cell span, each cell's next record.
    spans: Vec<[u8; 4]>,
    next: Vec<u32>,
    /// `(ray number, local ray)` per instance; None: the ray misses the instance's bounds.
    rays: Vec<(u32, Option<LocalRay>)>,
    ray: u32,
    buf: KBuffer<TrianglePayload>,
}

impl TileCtx {
    /// A context holding no tile yet, for a scene of `instances` instances: [`TileCtx::fill`]
    /// gives it one.
    pub(crate) fn empty(instances: usize) -> Self {
        TileCtx {
            x0: 0,
            y0: 0,
            cell_start: Vec::new(),
            hot: Vec::new(),
            cold: Vec::new(),
            spans: Vec::new(),
            next: Vec::new(),
            rays: vec![(0, None); instances],
            ray: 0,
            buf: KBuffer::unbounded(),
        }
    }

    /// The context of tile `(tx, ty)`, for a scene of `instances` instances.
    #[cfg(test)]
    pub(crate) fn new(lists: &TileLists, tx: u32, ty: u32, instances: usize) -> Self {
        let mut ctx = Self::empty(instances);
        ctx.fill(lists, tx, ty);
        ctx
    }

    /// Make this the context of tile `(tx, ty)`: its cells filled from the tile's list, in
    /// the buffers the previous tile used. The instances' local rays stay keyed by ray
    /// number, which keeps counting, so none is taken for a ray of this tile.
    pub(crate) fn fill(&mut self, lists: &TileLists, tx: u32, ty: u32) {
        let list = lists.tile(tx, ty);
        let n = (TILE / CELL) as usize;
        let (x0, y0) = ((tx * TILE) as f64, (ty * TILE) as f64);
        self.spans.clear();
        self.spans.extend(list.iter().map(|&i| {
            let r = lists.cands[i as usize].rect;
            let (a, b) = cell_span(r[0], r[2], x0, CELL, n);
            let (c, d) = cell_span(r[1], r[3], y0, CELL, n);
            [a as u8, b as u8, c as u8, d as u8]
        }));
        let mut counts = [0u32; ((TILE / CELL) * (TILE / CELL)) as usize];
        for s in &self.spans {
            for cy in s[2]..=s[3] {
                for cx in s[0]..=s[1] {
                    counts[cy as usize * n + cx as usize] += 1;
                }
            }
        }
        // Chunk offsets of the cells, and each cell's next record (in records).
        self.cell_start.clear();
        self.cell_start.push(0);
        for (k, &c) in counts.iter().enumerate() {
            self.cell_start
                .push(self.cell_start[k] + c.div_ceil(LANES as u32));
        }
        let total = self.cell_start[n * n] as usize;
        self.next.clear();
        self.next
            .extend(self.cell_start[..n * n].iter().map(|&c| c * LANES as u32));
        // The buffers keep the previous tile's chunks, grown but never cleared: placing the
        // records overwrites every lane of a cell's full chunks, so only the lanes past a
        // cell's last record need `EMPTY` (its last chunk, emptied first). Those lanes' cold
        // parts are never read (no pixel passes an empty lane), so they keep what they hold.
        // Refilling both whole each tile was 2.5 % of a texture-export frame's instructions.
        if self.hot.len() < total {
            self.hot.resize(total, HotChunk::EMPTY);
        }
        if self.cold.len() < total * LANES {
            self.cold.resize(total * LANES, Cand::BLANK.cold());
        }
        for (c, &count) in counts.iter().enumerate() {
            if count % LANES as u32 != 0 {
                self.hot[self.cell_start[c + 1] as usize - 1] = HotChunk::EMPTY;
            }
        }
        for (&i, s) in list.iter().zip(&self.spans) {
            let c = &lists.cands[i as usize];
            let h = c.hot();
            for cy in s[2]..=s[3] {
                for cx in s[0]..=s[1] {
                    let k = &mut self.next[cy as usize * n + cx as usize];
                    let r = *k as usize;
                    self.hot[r / LANES].set(r % LANES, &h);
                    self.cold[r] = c.cold();
                    *k += 1;
                }
            }
        }
        (self.x0, self.y0) = (tx * TILE, ty * TILE);
    }

    /// The buffer [`MeshTracer::tile_hits`] filled.
    #[cfg(test)]
    pub(crate) fn buffer(&self) -> &KBuffer<TrianglePayload> {
        &self.buf
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
    /// its slowest case) or the rays are at least a [`TRIANGLES_PER_RAY`]-th (an
    /// [`OPAQUE_TRIANGLES_PER_RAY`]-th for opaque materials) of the records binning makes
    /// ([`MeshTracer::records_of`]: the triangles, with each planar group of more than 16
    /// triangles counted as a few). Binning costs a pass over every record a frame,
    /// which a one-node mesh's own BVH does not need; past that many rays the one pass a ray
    /// pays for it (`docs/trace-speed-mesh.md`, "Every layout through the tiles", and
    /// `docs/trace-speed-groups.md`, "One-node meshes of large groups", for the groups).
    pub fn tiles_pay(&self, time: f64, rays: u64) -> bool {
        if !self.tiles_apply() {
            return false;
        }
        let insts = self.prepare_list(time);
        if insts.len() >= crate::instances::MIN_INSTANCES {
            return true;
        }
        let share = if self.opaque(&insts) {
            OPAQUE_TRIANGLES_PER_RAY
        } else {
            TRIANGLES_PER_RAY
        };
        rays.saturating_mul(share) >= self.records_of(&insts)
    }

    /// Whether every triangle of the instances `insts` is drawn opaque: its material's alpha
    /// mode is `OPAQUE`, or it names none (the default material, opaque).
    pub(crate) fn opaque(&self, insts: &[PreparedInstance]) -> bool {
        let materials = &self.scene.materials;
        insts.iter().all(|i| {
            self.scene.meshes[i.mesh].tri_material.named().all(|m| {
                materials
                    .get(m as usize)
                    .is_none_or(|m| m.alpha_mode == crate::model::AlphaMode::Opaque)
            })
        })
    }

    /// The records binning the instances `insts` makes, as far as
    /// [`Blas::binned_records`](crate::mesh_tracer::Blas::binned_records)
    /// tells it (a mesh counted once per instance).
    pub(crate) fn records_of(&self, insts: &[PreparedInstance]) -> u64 {
        insts
            .iter()
            .map(|i| self.blas[i.mesh].binned_records(self.scene.meshes[i.mesh].tris.len()))
            .sum()
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
        let lists = TileLists::build(self, &insts, cam, &sample_offsets(opts.spp));
        let bin = start.elapsed().as_secs_f64();
        let lin = self.scene.colors_linear;
        let (frame, mut stats) = render_frame_tiles(
            cam,
            opts.spp,
            TILE,
            || TileCtx::empty(insts.len()),
            |ctx, tx, ty| ctx.fill(&lists, tx, ty),
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
        // By reference: a `LocalRay` is 150 bytes, and a copy a candidate was a `memcpy`
        // call (17 a ray, `callgrind`).
        let Some(r) = &slot.1 else {
            return;
        };
        if e.mirror == GROUP_MARK {
            self.group_candidate(ii, inst.mesh, r, e, q, buf, cull);
            return;
        }
        let tested = self.test_triangle(
            ii, inst.mesh, r, e.verts, e.group, e.tri, false, q, buf, cull,
        );
        // The other winding, where the first's outcome leaves it open (`Tested`).
        if e.mirror != u32::MAX && tested == Tested::Open {
            let blas = &self.blas[inst.mesh];
            let mesh = &self.scene.meshes[inst.mesh];
            let m = e.mirror;
            let tri = blas.triangle(&mesh.positions, mesh.tris[m as usize]);
            self.test_triangle(ii, inst.mesh, r, tri, e.group, m, false, q, buf, cull);
        }
    }
}

impl MeshTracer {
    /// The walk's test of a group record (`mesh_groups`): each of group `g`'s triangles the
    /// ray may cross, by where it crosses the group plane, in ascending order, and its other
    /// winding where the first's outcome leaves it open. The group's triangles share the hit
    /// key, so the first outcome decided by the key decides the rest (`Tested::Decided`):
    /// inserted, they would have a higher rank; rejected, the same key is.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn group_candidate(
        &self,
        ii: usize,
        mesh: usize,
        r: &LocalRay,
        e: &Cold,
        q: &Query,
        buf: &mut KBuffer<TrianglePayload>,
        cull: &mut f32,
    ) {
        let frame = RecordFrame::unpack(&e.verts);
        self.group_test(ii, mesh, r, e.group, &frame, q, buf, cull);
    }

    /// [`MeshTracer::group_candidate`]'s test of group `g` of `mesh` (instance `ii`), whose
    /// record carries `frame`: every member the ray may cross and its other winding where the
    /// first's outcome leaves it open, up to the first outcome the key decides. The per-ray
    /// path tests a run's large groups this way too (`MeshTracer::collect_instance`).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn group_test(
        &self,
        ii: usize,
        mesh: usize,
        r: &LocalRay,
        g: u32,
        frame: &RecordFrame,
        q: &Query,
        buf: &mut KBuffer<TrianglePayload>,
        cull: &mut f32,
    ) {
        let blas = &self.blas[mesh];
        let m = &self.scene.meshes[mesh];
        let (Some(table), Some(mirror)) = (blas.groups.get(), blas.mirror.get()) else {
            return;
        };
        // Every member's hit is keyed by the group plane's distance where that is finite
        // (`test_triangle`, the same arithmetic): beyond the cull distance, before the
        // query's range or at most the last round's key, each would be rejected by the key
        // alone, so none is tested (the buffer ends as it would).
        let tp = plane_distance(blas.planes[g as usize], r);
        if tp.is_finite() {
            let t = tp as f32 + 0.0;
            let before_after = q.after.is_some_and(|a| t < f32::from_bits(a.0));
            if t > *cull || t < q.tmin || before_after {
                return;
            }
        }
        let at = match table.crossing(g, frame, r, tp) {
            Some(None) => return,
            Some(Some(at)) => Some(at),
            None => None,
        };
        let members = table.members(g);
        let mut test = |t: u32| {
            let tri = blas.triangle(&m.positions, m.tris[t as usize]);
            let tested = self.test_triangle(ii, mesh, r, tri, g, t, false, q, buf, cull);
            let pair = mirror[t as usize];
            if pair != u32::MAX && tested == Tested::Open {
                let tri = blas.triangle(&m.positions, m.tris[pair as usize]);
                return self.test_triangle(ii, mesh, r, tri, g, pair, false, q, buf, cull);
            }
            tested
        };
        match at {
            None => {
                for &t in members {
                    if test(t) == Tested::Decided {
                        return;
                    }
                }
            }
            Some(at) => {
                for (i, mut mask) in table.masks(g, &at).enumerate() {
                    while mask != 0 {
                        let l = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        if test(members[i * LANES + l]) == Tested::Decided {
                            return;
                        }
                    }
                }
            }
        }
    }
}

/// The cell of the tile at `(x0, y0)` that holds image coordinate `uv`.
fn cell_of(x0: u32, y0: u32, uv: (f64, f64)) -> usize {
    let n = TILE / CELL;
    let c = |x: f64, origin: u32| {
        floor((x - origin as f64) / CELL as f64).clamp(0.0, (n - 1) as f64) as u32
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
    /// [`MeshTracer::record_hits_map`] through the tile lists: each pixel centre's hits in
    /// compositing order, up to the hit that takes the transmittance below `min_transmittance`
    /// (the walk of [`MeshTracer::ordered_hits`], on the same hits), each stored as `map` makes
    /// it.
    ///
    /// A tile's hits are recorded into its thread's scratch list (reused tile after tile, so a
    /// tile neither grows a fresh list nor faults in new pages), stored mapped in a list of
    /// their exact count, and finally copied into the row-major lists image row by image row
    /// in parallel: each hit is written twice after its recording, and no list of all hits
    /// exists in another form (`docs/distill-time.md`, "Recording straight into the fit's
    /// lists").
    pub(crate) fn record_hits_tiles_map<T, F>(
        &self,
        cam: &Camera,
        time: f64,
        min_transmittance: f32,
        map: F,
    ) -> Result<HitLists<T>>
    where
        T: Copy + Send + Sync,
        F: Fn(&RecordedHit) -> T + Sync,
    {
        cam.validate()?;
        let insts = self.prepare_list(time);
        // One ray through each pixel's centre.
        let lists = TileLists::build(self, &insts, cam, &sample_offsets(1));
        let (w, h) = (cam.width as usize, cam.height as usize);
        let t = TILE as usize;
        let (tw, th) = (w.div_ceil(t), h.div_ceil(t));
        // Per tile: each pixel's hit count (row-major in the tile), where each of its pixel
        // rows' hits start, and the hits.
        let tiles: Vec<RecordedTile<T>> = (0..tw * th)
            .into_par_iter()
            .map_init(
                || {
                    let mut ctx = TileCtx::empty(insts.len());
                    ctx.buf.record_alpha = true;
                    (ctx, Vec::new())
                },
                |(ctx, scratch), k| {
                    let (tx, ty) = (k % tw, k / tw);
                    ctx.fill(&lists, tx as u32, ty as u32);
                    scratch.clear();
                    let mut counts = Vec::with_capacity(t * t);
                    let mut row_start = Vec::with_capacity(t + 1);
                    for j in ty * t..((ty + 1) * t).min(h) {
                        row_start.push(scratch.len());
                        for i in tx * t..((tx + 1) * t).min(w) {
                            let uv = (i as f64 + 0.5, j as f64 + 0.5);
                            let (o, d) = camera_ray(cam, uv.0, uv.1);
                            self.tile_hits(&insts, ctx, o, d, uv, min_transmittance);
                            let before = scratch.len();
                            let mut acc = Accum::default();
                            for hit in &ctx.buf.hits {
                                let mesh = insts[hit.instance as usize].mesh;
                                if record(hit, mesh, &mut acc, scratch, min_transmittance) {
                                    break;
                                }
                            }
                            counts.push((scratch.len() - before) as u32);
                        }
                    }
                    row_start.push(scratch.len());
                    RecordedTile {
                        counts,
                        row_start,
                        hits: scratch.iter().map(&map).collect(),
                    }
                },
            )
            .collect();
        // Row-major offsets from the tiles' row-major pixels.
        let mut count = vec![0u32; w * h];
        for (k, tile) in tiles.iter().enumerate() {
            let (tx, ty) = (k % tw, k / tw);
            let x0 = tx * t;
            let tw_px = (x0 + t).min(w) - x0;
            for (n, &cnt) in tile.counts.iter().enumerate() {
                count[(ty * t + n / tw_px) * w + x0 + n % tw_px] = cnt;
            }
        }
        let mut offsets = Vec::with_capacity(w * h + 1);
        offsets.push(0u64);
        for &c in &count {
            let last = *offsets.last().unwrap_or(&0);
            offsets.push(last + c as u64);
        }
        let total = *offsets.last().unwrap_or(&0) as usize;
        let mut hits: Vec<T> = Vec::with_capacity(total);
        {
            // Image row j's hits are the hits of its pixel row in each tile of its tile row,
            // tile after tile: one disjoint range of the output per row.
            let mut rows = Vec::with_capacity(h);
            let mut rest = &mut hits.spare_capacity_mut()[..total];
            for j in 0..h {
                let n = (offsets[(j + 1) * w] - offsets[j * w]) as usize;
                let (row, tail) = rest.split_at_mut(n);
                rows.push(row);
                rest = tail;
            }
            rows.into_par_iter().enumerate().for_each(|(j, dst)| {
                let (ty, r) = (j / t, j % t);
                let mut at = 0;
                for tile in &tiles[ty * tw..(ty + 1) * tw] {
                    let src = &tile.hits[tile.row_start[r]..tile.row_start[r + 1]];
                    for (d, s) in dst[at..at + src.len()].iter_mut().zip(src) {
                        d.write(*s);
                    }
                    at += src.len();
                }
                // The row's length is the sum of its pixels' counts, which are these ranges'
                // lengths: every slot of the row is written (checked, not assumed, for the
                // `set_len` below).
                assert_eq!(at, dst.len(), "a row's recorded hits fill its range");
            });
        }
        // SAFETY: the rows split `spare_capacity_mut()[..total]` into disjoint ranges that
        // cover it (their lengths add up to `offsets[w·h] = total`), and every row asserted
        // above that it wrote each of its slots; a failed assertion panics before this line.
        unsafe { hits.set_len(total) };
        Ok(HitLists {
            width: cam.width,
            height: cam.height,
            offsets,
            hits,
        })
    }
}

/// One tile's recorded hits (see [`MeshTracer::record_hits_tiles_map`]).
struct RecordedTile<T> {
    /// Each pixel's hit count, row-major in the tile.
    counts: Vec<u32>,
    /// Where each of the tile's pixel rows' hits start in `hits`, and their end.
    row_start: Vec<usize>,
    hits: Vec<T>,
}
