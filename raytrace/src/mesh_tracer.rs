//! Mode `mesh`: render exactly what was exported by compositing every triangle hit front to
//! back, as a viewer with an unlit BLEND material shows it.
//!
//! Per ray, the k-buffer (`kbuffer`, with a [`TrianglePayload`] per hit) collects the k nearest
//! hits beyond the last composited one (ordered by the key distance, Gaussian id, instance,
//! planar group), `kbuffer::walk` composites them, and tracing resumes until the transmittance
//! falls below 1e-4 (native splatting's threshold) or no hit is left.
//! When compositing, hits are shaded as they are found and those with α = 0 (the texture
//! profile's quad corners, fully transparent texels) are not kept: they add nothing, and in
//! the buffer they would only cost extra rounds. Hit enumeration ([`MeshTracer::all_hits`])
//! keeps every crossing.
//! Ordering by the full key means hits at one distance are never lost or repeated across
//! rounds, however many there are, and the image does not depend on traversal order.
//!
//! A planar group (one fan of one Gaussian, see `Mesh::planar_groups`) is crossed at most
//! once by a ray, so its hit distance is taken from the group's plane: every triangle of the
//! fan reports the same key, and a ray through a shared edge, vertex or fan centre counts the
//! Gaussian once. Unlike native splatting, a hit is composited before the termination test (a
//! viewer draws an opaque triangle; the rasterizer's "stop without adding" rule would drop it),
//! and no 0.99 clamp or 1/255 cut is applied: those belong to the Gaussians, not to the mesh.
//!
//! Colour: glTF vertex colours are linear; by default each hit's colour is sRGB-encoded
//! before blending, so the image is in display values and composited like native splatting
//! (`Compositing::Display`); `Compositing::Viewer` blends in linear light and encodes the
//! result, as Blender or three.js show the file. Colours are clamped to [0, 1] (glTF's range).
//!
//! A render's primary rays take the screen-tile path of `mesh_tiles` where it applies
//! ([`MeshTracer::tiles_pay`]): the same per-candidate test and compositing (`mesh_hit`) on
//! triangles binned per tile, one pass a ray instead of BVH traversals and k-buffer rounds.
//!
//! Geometry: one BVH per mesh in the mesh's local frame, relative to an anchor (the centre of
//! its bounds) so f32 keeps precision far from the origin; at time t each visible node is an
//! instance and the ray is carried into its frame in f64 (instancing, no per-frame rebuild;
//! only a mesh whose morph weights change is posed and rebuilt, [`MeshTracer::set_time`]).

use std::ops::ControlFlow;
use std::sync::OnceLock;
use std::time::Instant;

use glam::{DAffine3, DVec3, Vec3, Vec4};

use crate::backend::{Accel, BackendKind, BuildPreset};
use crate::error::Result;
use crate::geom::{ray_box, transformed_box};
pub use crate::instances::Instances;
pub use crate::kbuffer::Key;
use crate::kbuffer::{self, Hit, KBuffer, Payload};
use crate::mesh_hit::{Compositor, LocalRay, Query, Tested};
use crate::model::TriScene;
use crate::render::{render_frame_spp, PixelOut, RenderOptions, Stats};
use splatbridge_scene::{Camera, Frame};

mod build;

/// What a mode-mesh hit carries: the triangle, where on it, and (when shaded during
/// collection, see [`KBuffer::shade_on_insert`]) its RGBA.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrianglePayload {
    /// Triangle index in its mesh.
    pub tri: u32,
    pub bary: [f32; 3],
    pub rgba: Vec4,
}

impl Payload for TrianglePayload {
    /// A fan's triangles share one key: the lower triangle index is kept.
    #[inline]
    fn rank(&self) -> u32 {
        self.tri
    }

    /// The shaded α (0 until shaded: hit enumeration never stops).
    #[inline]
    fn opacity(&self) -> f32 {
        self.rgba.w
    }
}

/// A mode-mesh hit.
pub type MeshHit = Hit<TrianglePayload>;

kbuffer::thread_buffer!(pub(crate) fn with_thread_buffer, TrianglePayload);

/// Triangles per primitive of the obvhs structure: runs of up to this many consecutive
/// triangles of one Gaussian (a fan's triangles are consecutive in every export) share one box. A PLOC build
/// holds a few hundred bytes of scratch per primitive (Morton codes, two node generations, the
/// binary tree before its conversion to a wide one), which for the 37 M triangles of a
/// 500k-Gaussian `rings` export was most of a comparison's memory; up to sixteen to a box
/// divides it by about ten on fans of 8 to 40 triangles, while a leaf visit tests up to sixteen
/// triangles instead of up to three. The hit set
/// does not change: every triangle in a box the ray enters is still tested, and hits are
/// ordered by their full key (`tests/mesh_boxes.rs` checks it bit for bit).
pub const TRIANGLES_PER_BOX: usize = 16;

/// Boxes a mesh's structure is built over before its runs grow past [`TRIANGLES_PER_BOX`]:
/// the build's scratch (about 480 bytes a box, measured on a 37 M-triangle rings export: 1.1 GB
/// over 2.3 M boxes) is held beside the whole mesh, so on very large meshes runs lengthen to
/// keep it near this many boxes. Measured on that export at 480×360: runs of 48 built in 3.1 s
/// instead of 5.7 s and traced in 1.68 s instead of 1.46 s, 0.47 GB lower; runs of 128 traced
/// in 2.58 s, hence the cap [`MAX_TRIANGLES_PER_BOX`].
pub const BOXES_PER_MESH: usize = 1 << 20;

/// The longest run a box holds, however large the mesh.
pub const MAX_TRIANGLES_PER_BOX: usize = 64;

/// The run length for a mesh of `triangles` triangles: [`TRIANGLES_PER_BOX`], or longer on
/// meshes of more than [`BOXES_PER_MESH`] runs of it.
pub fn run_length(triangles: usize) -> usize {
    triangles
        .div_ceil(BOXES_PER_MESH)
        .clamp(TRIANGLES_PER_BOX, MAX_TRIANGLES_PER_BOX)
}

/// One mesh's acceleration structure and the data the hit test needs.
pub struct Blas {
    pub anchor: DVec3,
    /// Plane of each group in relative coordinates (f64): `n·x = w`, from the group's
    /// largest triangle (the best conditioned normal).
    pub planes: Vec<(DVec3, f64)>,
    pub lo: DVec3,
    pub hi: DVec3,
    /// Every vertex position is finite, so `lo..hi` holds every vertex the hit test sees (a
    /// NaN coordinate is skipped by `min`/`max`): the screen tiles may skip an instance whose
    /// box the camera cannot see (`mesh_tiles::box_unseen`).
    pub finite: bool,
    /// The BVH ([`MeshTracer::accel`]). An obvhs BVH over runs is built on the first frame
    /// that traces ray by ray ([`MeshTracer::prepare`]): frames through the screen tiles bin
    /// the triangles themselves and never read it (building it was a third of the load of a
    /// `rings` export, `docs/trace-speed-groups.md`, "What a mesh costs before its first
    /// ray").
    accel: OnceLock<Box<dyn Accel>>,
    /// Over single triangles: the triangles laid out in the acceleration structure's order
    /// (see `Accel::slots`), their vertices (relative to `anchor`), index in the mesh and
    /// group, so traversal reads them in order. Empty over runs of triangles.
    pub slot_verts: Vec<[Vec3; 3]>,
    pub slot_tri: Vec<u32>,
    pub slot_group: Vec<u32>,
    /// Over runs of triangles: primitive `p` is the mesh's triangles
    /// `run_start[p]..run_start[p + 1]`. Empty over single triangles.
    pub run_start: Vec<u32>,
    /// Over runs of triangles: each triangle's group, in the mesh's order. The vertices are
    /// read through the mesh's index buffer and made relative to `anchor` as they are tested
    /// ([`Blas::relative`], the same f32 values a stored copy held, so hits are unchanged): a
    /// run's triangles are consecutive, and so, in every export, are their vertices, so the
    /// reads stay local, and no copy of the positions is kept (12 bytes a vertex; laying
    /// triangles out per slot would copy every vertex three times, 36 bytes a triangle).
    pub group: GroupIds,
    /// Each triangle's other winding (`mesh_cands::mirror_pairs`), found on the first render
    /// through screen tiles (4 bytes a triangle, kept for later frames).
    pub(crate) mirror: std::sync::OnceLock<Vec<u32>>,
    /// Each planar group's largest triangle side (`mesh_tiles`' list keys), found on the
    /// first render through screen tiles (8 bytes a group).
    pub(crate) group_extent: std::sync::OnceLock<Vec<f64>>,
    /// The groups binned as one record each (`mesh_groups`), found with `mirror`.
    pub(crate) groups: std::sync::OnceLock<crate::mesh_groups::GroupTable>,
    /// What binning this mesh costs, in records ([`Blas::binned_records`]), found when a
    /// render first asks whether the tiles pay (8 bytes a mesh).
    pub(crate) records: std::sync::OnceLock<u64>,
}

/// Each triangle's planar group over runs of triangles. Runs never cross Gaussians, and a
/// Gaussian's groups are numbered together (`Mesh::planar_groups`), so a triangle's group is
/// its run's lowest group plus a small offset: one byte a triangle instead of four (110 MB
/// less on a 37 M-triangle export). A mesh whose runs span more than 256 groups (a large
/// non-export mesh, whose connected components stand for Gaussians) keeps the full list.
pub enum GroupIds {
    Full(Vec<u32>),
    Runs { base: Vec<u32>, offset: Vec<u8> },
}

impl GroupIds {
    /// Compact `group` over the runs `run_start` (see `run_starts`) when every offset fits.
    fn over_runs(group: Vec<u32>, run_start: &[u32]) -> Self {
        let mut base = Vec::with_capacity(run_start.len().saturating_sub(1));
        for w in run_start.windows(2) {
            let run = &group[w[0] as usize..w[1] as usize];
            let lo = run.iter().copied().min().unwrap_or(0);
            if run.iter().any(|&g| g - lo > u8::MAX as u32) {
                return GroupIds::Full(group);
            }
            base.push(lo);
        }
        let mut offset = Vec::with_capacity(group.len());
        for (p, w) in run_start.windows(2).enumerate() {
            offset.extend(
                group[w[0] as usize..w[1] as usize]
                    .iter()
                    .map(|&g| (g - base[p]) as u8),
            );
        }
        GroupIds::Runs { base, offset }
    }

    /// Triangle `t`'s group; `run` is the run holding it.
    #[inline]
    pub fn get(&self, run: usize, t: usize) -> u32 {
        match self {
            GroupIds::Full(g) => g[t],
            GroupIds::Runs { base, offset } => base[run] + offset[t] as u32,
        }
    }
}

impl Blas {
    /// What binning this mesh of `n` triangles costs the screen tiles, in records, as far as
    /// the groups decide it without the winding pairs: a group of more than twice
    /// [`crate::mesh_cands::LANES`] triangles has more than `LANES` pair-leading members
    /// whatever its windings (each pair has one leader), so it is one record
    /// (`mesh_groups::GroupTable::is_group`), counted as
    /// [`crate::mesh_groups::GROUP_RECORD_WEIGHT`]; every other triangle counts as one, as
    /// if binned on its own. The triangle count itself for a mesh without such groups (every
    /// export but `rings`), and never more.
    pub(crate) fn binned_records(&self, n: usize) -> u64 {
        *self.records.get_or_init(|| {
            let mut per_group = vec![0u64; self.planes.len()];
            let mut in_runs = 0u64;
            for (_, g) in self.run_groups() {
                per_group[g as usize] += 1;
                in_runs += 1;
            }
            let big = 2 * crate::mesh_cands::LANES as u64;
            let weight = crate::mesh_groups::GROUP_RECORD_WEIGHT;
            let grouped: u64 = per_group
                .iter()
                .map(|&c| if c > big { weight } else { c })
                .sum();
            grouped + (n as u64).saturating_sub(in_runs)
        })
    }

    /// Each triangle a run holds, with its planar group, in the mesh's order.
    fn run_groups(&self) -> impl Iterator<Item = (usize, u32)> + '_ {
        self.run_start
            .windows(2)
            .enumerate()
            .flat_map(move |(p, w)| {
                (w[0] as usize..w[1] as usize).map(move |t| (t, self.group.get(p, t)))
            })
    }

    /// Each of the mesh's `n` triangles' planar group (over runs of triangles; 0 for a
    /// triangle no run holds), expanded from [`Blas::group`].
    pub(crate) fn triangle_groups(&self, n: usize) -> Vec<u32> {
        let mut group = vec![0u32; n];
        for (t, g) in self.run_groups() {
            group[t] = g;
        }
        group
    }

    /// Whether the BVH is built (not left for its first use).
    #[cfg(test)]
    pub(crate) fn accel_built(&self) -> bool {
        self.accel.get().is_some()
    }

    /// A vertex position relative to the anchor, in f32 (what the hit test sees).
    #[inline]
    pub fn relative(&self, p: Vec3) -> Vec3 {
        (p.as_dvec3() - self.anchor).as_vec3()
    }

    /// Triangle `tri`'s vertices (indices into `positions`) relative to the anchor: each
    /// [`Blas::relative`]. Written out rather than through `[T; 3]::map`, which the
    /// compiler kept as a call on every candidate of the per-ray path (a tenth of its
    /// profile over a 14 M-triangle mesh).
    #[inline(always)]
    pub fn triangle(&self, positions: &[Vec3], tri: [u32; 3]) -> [Vec3; 3] {
        [
            self.relative(positions[tri[0] as usize]),
            self.relative(positions[tri[1] as usize]),
            self.relative(positions[tri[2] as usize]),
        ]
    }
}

/// An instance prepared for one time: mesh, inverse transform, world bounds.
#[derive(Clone, Copy, Debug)]
pub struct PreparedInstance {
    pub mesh: usize,
    pub to_world: DAffine3,
    pub to_local: DAffine3,
    pub lo: DVec3,
    pub hi: DVec3,
}

/// The triangle scene with one BVH per mesh.
pub struct MeshTracer {
    pub scene: TriScene,
    pub blas: Vec<Blas>,
    pub backend: BackendKind,
    preset: BuildPreset,
    /// Each mesh's triangles per box (`None`: single triangles), to rebuild a posed mesh's BVH.
    per_box: Vec<Option<usize>>,
    /// Seconds spent building at load (the planar grouping included); the BVHs left for
    /// their first use add theirs to [`MeshTracer::total_build_seconds`].
    pub build_seconds: f64,
    /// Nanoseconds spent building BVHs left for their first use (`MeshTracer::accel`).
    deferred_build_nanos: std::sync::atomic::AtomicU64,
}

impl MeshTracer {
    /// Instances visible at `t`, with inverse transforms and world bounds, under a top-level
    /// BVH (see [`Instances`]); their meshes' BVHs built.
    pub fn prepare(&self, t: f64) -> Instances {
        let list = self.prepare_list(t);
        self.build_deferred(&list);
        Instances::new(list, self.backend)
    }

    /// How many triangles the instances `insts` draw (a mesh counted once per instance).
    pub(crate) fn triangles_of(&self, insts: &[PreparedInstance]) -> u64 {
        insts
            .iter()
            .map(|i| self.scene.meshes[i.mesh].tris.len() as u64)
            .sum()
    }

    /// The instances visible at `t` in node order, without the top-level structure.
    pub fn prepare_list(&self, t: f64) -> Vec<PreparedInstance> {
        self.scene
            .instances(t)
            .into_iter()
            .filter(|i| !self.scene.meshes[i.mesh].tris.is_empty())
            .map(|i| {
                let b = &self.blas[i.mesh];
                let (lo, hi) = transformed_box(&i.to_world, b.lo, b.hi);
                PreparedInstance {
                    mesh: i.mesh,
                    to_world: i.to_world,
                    to_local: i.to_world.inverse(),
                    lo,
                    hi,
                }
            })
            .collect()
    }

    /// Fill `buf` with the k smallest-key hits with key > `after` and `tmin ≤ t ≤ tmax` along
    /// the world ray `o + t·d` (`d` unit length).
    pub fn collect(
        &self,
        insts: &Instances,
        o: DVec3,
        d: DVec3,
        tmin: f32,
        tmax: f32,
        after: Option<Key>,
        buf: &mut KBuffer<TrianglePayload>,
    ) {
        buf.clear();
        insts.visit(o, d, buf.cull(tmax), &mut |ii, inst, top_cull| {
            self.collect_instance(ii, inst, o, d, tmin, tmax, after, buf);
            *top_cull = top_cull.min(buf.cull(tmax));
        });
    }

    /// [`MeshTracer::collect`]'s work in instance `ii`.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn collect_instance(
        &self,
        ii: usize,
        inst: &PreparedInstance,
        o: DVec3,
        d: DVec3,
        tmin: f32,
        tmax: f32,
        after: Option<Key>,
        buf: &mut KBuffer<TrianglePayload>,
    ) {
        {
            let Some((b0, b1)) = ray_box(o, d, inst.lo, inst.hi) else {
                return;
            };
            if b1 < tmin as f64 || b0 > buf.cull(tmax) as f64 {
                return;
            }
            let blas = &self.blas[inst.mesh];
            let mesh = &self.scene.meshes[inst.mesh];
            let lo64 = inst.to_local.transform_point3(o) - blas.anchor;
            let ld64 = inst.to_local.transform_vector3(d);
            let Some(r) = LocalRay::new(lo64, ld64) else {
                return;
            };
            let cull0 = buf.cull(tmax);
            // Resume from the last hit: the distance of `after` in this instance's ray units
            // (the local direction keeps the world parameter, so it is the same number).
            let t_from = after.map(|a| f32::from_bits(a.0)).unwrap_or(0.0).max(tmin);
            let (lo, ld) = (r.wray.origin, r.wray.dir);
            let q = Query { tmin, tmax, after };
            // A group's triangles share the hit key: once one of them is decided by it
            // (inserted, or rejected by the range, the stop or an equal key), its triangles of
            // higher index would be rejected (the tile path's rule,
            // `mesh_tiles::group_candidate`). The last such group and triangle, over the runs
            // in the order the walk reaches them (a disc's runs come one after another).
            let mut decided: Option<(u32, usize)> = None;
            // Where the group table is built (`MeshTracer::prepare_groups`, on a frame that pays
            // for it: `MeshTracer::tables_pay`), a run's triangles
            // of a group of at least `mesh_groups::MIN_MEMBERS` binned triangles are tested as
            // the tile path tests its group records: the members the ray may cross, by where
            // it crosses the group's plane (a disc's runs are entered by many rays that cross
            // none of its triangles). Each such group once a visit: the groups last tested.
            let table = blas.groups.get().filter(|_| blas.mirror.get().is_some());
            let mut grouped = [u32::MAX; 4];
            let mut next = 0;
            let accel = self.accel(inst.mesh);
            accel.traverse_slots(lo, ld, t_from, cull0, &mut |slot, reported, cull| {
                let s = slot as usize;
                if blas.run_start.is_empty() {
                    let (v, g) = (blas.slot_verts[s], blas.slot_group[s]);
                    let prim = blas.slot_tri[s];
                    self.test_triangle(ii, inst.mesh, &r, v, g, prim, reported, &q, buf, cull);
                } else {
                    let p = accel.slots().map_or(s, |m| m[s] as usize);
                    let (start, end) = (blas.run_start[p] as usize, blas.run_start[p + 1] as usize);
                    let mut group_once =
                        |g: u32, buf: &mut KBuffer<TrianglePayload>, cull: &mut f32| {
                            let Some(table) = table.filter(|tb| tb.is_group(g, true)) else {
                                return false;
                            };
                            if !grouped.contains(&g) {
                                grouped[next] = g;
                                next = (next + 1) % grouped.len();
                                let frame = table.record(g);
                                self.group_test(ii, inst.mesh, &r, g, &frame, &q, buf, cull);
                            }
                            true
                        };
                    // Most runs lie in one group (a disc's 16 triangles): one check.
                    let g0 = blas.group.get(p, start);
                    if table.is_some()
                        && (start + 1..end).all(|t| blas.group.get(p, t) == g0)
                        && group_once(g0, buf, cull)
                    {
                        return;
                    }
                    for t in start..end {
                        let g = blas.group.get(p, t);
                        if group_once(g, buf, cull) {
                            continue;
                        }
                        if decided.is_some_and(|(dg, dt)| dg == g && t > dt) {
                            continue;
                        }
                        let v = blas.triangle(&mesh.positions, mesh.tris[t]);
                        let tested = self
                            .test_triangle(ii, inst.mesh, &r, v, g, t as u32, false, &q, buf, cull);
                        if tested == Tested::Decided {
                            decided = Some((g, t));
                        }
                    }
                }
            });
        }
    }

    /// Shade a hit: RGBA as the viewer computes it.
    pub fn shade(&self, insts: &[PreparedInstance], h: &MeshHit) -> Vec4 {
        let mesh = &self.scene.meshes[insts[h.instance as usize].mesh];
        mesh.shade(
            h.payload.tri as usize,
            h.payload.bary,
            &self.scene.materials,
            &self.scene.textures,
        )
    }

    /// Every hit along a world ray in key order (no compositing), for tests and tools.
    pub fn all_hits(&self, insts: &Instances, o: DVec3, d: DVec3, k: usize) -> Vec<MeshHit> {
        kbuffer::all_hits(k, |after, buf| {
            self.collect(insts, o, d, 0.0, f32::INFINITY, after, buf)
        })
    }

    /// Composite one ray (world origin `o`, unit direction `d`). `depth` in the result is the
    /// weighted mean ray parameter.
    pub fn trace(
        &self,
        insts: &Instances,
        o: DVec3,
        d: DVec3,
        opts: &RenderOptions,
        buf: &mut KBuffer<TrianglePayload>,
    ) -> PixelOut {
        let mut comp = Compositor::new(opts, self.scene.colors_linear);
        buf.candidates = 0;
        buf.shade_on_insert = true;
        // The transmittance compositing has reached, for the buffer's stop (`KBuffer::stop`).
        let tr_now = std::cell::Cell::new(comp.acc.tr);
        let (rounds, _) = kbuffer::walk(
            buf,
            |after, buf| {
                buf.stop = Some((tr_now.get(), opts.min_transmittance));
                self.collect(insts, o, d, 0.0, f32::INFINITY, after, buf)
            },
            |h| {
                let stop = comp.add(h);
                tr_now.set(comp.acc.tr);
                if stop {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            },
        );
        let mut out = comp.finish();
        out.traversals = rounds;
        out.candidates = buf.candidates;
        buf.shade_on_insert = false;
        buf.stop = None;
        out
    }

    /// Render camera `cam` at time `time`: through screen tiles where they apply
    /// ([`MeshTracer::tiles_pay`], `mesh_tiles`), otherwise ray by ray.
    pub fn render(&self, cam: &Camera, time: f64, opts: &RenderOptions) -> Result<(Frame, Stats)> {
        opts.validate()?;
        if self.tiles_pay(time, cam.width as u64 * cam.height as u64 * opts.spp as u64) {
            return self.render_tiles(cam, time, opts);
        }
        self.render_per_ray(cam, time, opts)
    }

    /// Render ray by ray through the BVHs and k-buffer rounds (the path every backend takes).
    pub fn render_per_ray(
        &self,
        cam: &Camera,
        time: f64,
        opts: &RenderOptions,
    ) -> Result<(Frame, Stats)> {
        opts.validate()?;
        // The BVHs left for their first use count as build time, not as the frame's.
        let list = self.prepare_list(time);
        self.build_deferred(&list);
        let start = Instant::now();
        let insts = Instances::new(list, self.backend);
        if self.tables_pay(&insts, cam, opts) {
            self.prepare_groups(insts.list(), false);
        }
        let tables = start.elapsed().as_secs_f64();
        let (frame, mut stats) = render_frame_spp(cam, opts.spp, |o, d| {
            with_thread_buffer(opts.k, |b| self.trace(&insts, o, d, opts, b))
        })?;
        // The frame's time includes the tables its rays read, as the tiles' includes binning.
        stats.seconds += tables;
        Ok((frame, stats))
    }
}
