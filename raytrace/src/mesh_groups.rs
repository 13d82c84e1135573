//! Group records for mode `mesh`'s screen tiles (`mesh_bin`, `mesh_tiles`): a planar group of
//! many triangles (a `rings` disc, 40 triangles a Gaussian; a MeshSplats fan, 8, in frames of
//! few rays for their triangles) is binned as one record instead of one a triangle, and a ray
//! that reaches the record finds the group's triangles it may cross by where it crosses the
//! group's plane.
//!
//! Why: every triangle's record costs binning its projection, rectangle, edge functions,
//! sort key, tile entries and cell copies once a frame, whether a ray reaches it or not. On
//! the `rings` export of a real capture that was half of a 1080p frame
//! (`docs/trace-speed-groups.md`, "Group records"). A group's triangles share its list key
//! (the group plane's least depth) and its hit key (the group plane's distance), so at most
//! one of them is a ray's hit: the lowest-indexed one that covers the ray and shades.
//!
//! Exactness: the record only chooses which triangles get the exact test
//! (`MeshTracer::test_triangle`, the same as for a triangle's record); it must never leave
//! out one the watertight test would report. A triangle of the group lies within `slab` of
//! the group plane (measured over its vertices), so where the ray crosses the triangle is at
//! most `slab·√(1 − c²)/c` sideways from where it crosses the plane (`c` the cosine between
//! ray and normal). The watertight test decides for the f32 ray and vertices, whose
//! rounding moves the crossing by less than `EPS·R/c` (`R` the magnitude of the local
//! origin and the vertices). A triangle whose projection into the plane lies farther than
//! both from the crossing point (plus the f32 rounding of the frame's axes and of the lanes'
//! edge functions) cannot be reported. Below `MIN_COSINE` (grazing rays) every triangle of
//! the group is tested.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::mesh_bin::up;
use crate::mesh_cands::{leads, LANES};
use crate::mesh_tracer::{Blas, MeshTracer};
use crate::model::Mesh;

/// Groups of at least this many binned triangles (pair-leading, see
/// `mesh_cands::mirror_pairs`) may be binned as one record: a MeshSplats fan has 8, a `rings`
/// disc 40, the texture profile's quad 2 (its two records keep their edge pre-test). Groups
/// of more than [`LANES`] always are; smaller ones only in frames of few rays for their
/// triangles ([`SMALL_GROUP_TRIANGLES_PER_RAY`]).
pub(crate) const MIN_MEMBERS: usize = 4;

/// Groups of 4 to 8 binned triangles are binned as one record in a frame whose instances
/// hold at least this many triangles a ray (samples of every pixel). Measured on the
/// MeshSplats export of a real capture (8 triangles a group, 5.66 M triangles, both
/// windings): as one record a group saves its members' binning but costs each ray reaching it
/// the crossing and reads through the table, a win at 320×240 (74 triangles a ray: 0.72 →
/// 0.42 s) and 640×480 (18: 0.93 → 0.69 s), a loss at 1920×1080 (2.7: 1.78 → 2.07 s).
pub(crate) const SMALL_GROUP_TRIANGLES_PER_RAY: u64 = 6;

/// What a group of more than 2·[`LANES`] triangles counts for when a one-node render decides
/// whether the screen tiles pay (`MeshTracer::tiles_pay`: rays against records): as many
/// records as this, not as its triangles. Its record is binned once a frame, but its first
/// frame also builds the group table (a pass over every triangle) and each ray that reaches
/// it pays the crossing and the table's reads. Measured on the `rings` export of a real
/// capture as one node (14.15 M triangles in 353,775 groups of 40, single `trace`, wall time,
/// per-ray path → tiles, with the table then built on one thread): 320×240 4.9 → 5.4 s,
/// 640×480 9.3 → 6.05 s, so the single frame breaks even near 110 k rays; 8 puts the switch
/// at 113 k (`docs/trace-speed-groups.md`, "One-node meshes of large groups").
pub(crate) const GROUP_RECORD_WEIGHT: u64 = 8;

// Such a group never counts for more than its triangles, so no mesh takes the tiles less
// often than by its triangle count.
const _: () = assert!(GROUP_RECORD_WEIGHT <= 2 * LANES as u64);

/// The `mirror` field of a group record's `Cand` (no triangle index reaches it: the tile
/// lists address records by u32 and triangles by u32 below `u32::MAX - 1`).
pub(crate) const GROUP_MARK: u32 = u32::MAX - 1;

/// Below this cosine between ray and plane normal, every triangle of the group is tested
/// (the sideways bound grows as `1/c`).
const MIN_COSINE: f64 = 1e-3;

/// Bound on the watertight test's rounding, relative to the magnitude of the local origin
/// and vertices: the f32 ray (origin and direction rounded from f64) and the f32 vertices
/// relative to it each move a crossing by a few units of 2⁻²⁴ of that magnitude; the shear
/// and the edge functions are decided exactly on those values (`tri::WRay`). 256 of them is
/// tens of times that.
const EPS: f64 = 256.0 / 16_777_216.0;

/// What a group record carries (in its `Cand`'s `verts`, which a group record does not
/// otherwise use, so a ray reads it from the tile's cell, not from the table): a point of the
/// group (its first member's first vertex, an f32 value), the first axis of its frame (f32),
/// how far its members' vertices lie off its plane (`slab`, rounded up), and the largest
/// coordinate of a member vertex in its frame (`reach`, rounded up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RecordFrame {
    origin: Vec3,
    e1: Vec3,
    slab: f32,
    reach: f32,
}

impl RecordFrame {
    /// No frame: every member is tested.
    const NONE: RecordFrame = RecordFrame {
        origin: Vec3::ZERO,
        e1: Vec3::ZERO,
        slab: f32::INFINITY,
        reach: f32::INFINITY,
    };

    pub(crate) fn pack(&self) -> [Vec3; 3] {
        [self.origin, self.e1, Vec3::new(self.slab, self.reach, 0.0)]
    }

    pub(crate) fn unpack(v: &[Vec3; 3]) -> Self {
        RecordFrame {
            origin: v[0],
            e1: v[1],
            slab: v[2].x,
            reach: v[2].y,
        }
    }
}

/// The group plane's unit normal and offset, and the frame's two axes: `e1` as the record
/// holds it, `e2` the f32 rounding of `n × e1`. The table's lines and a ray's crossing both
/// come from these same operations on the same values, so they agree to the bit; the axes are
/// unit and orthogonal to the normal and each other within a few 1e-8 (the f32 rounding),
/// which [`GroupTable::crossing`] allows for.
#[inline]
fn axes(plane: (DVec3, f64), e1: Vec3) -> (DVec3, f64, DVec3, DVec3) {
    let (pn, pw) = plane;
    let len = pn.length();
    let n = pn / len;
    let e1 = e1.as_dvec3();
    (n, pw / len, e1, n.cross(e1).as_vec3().as_dvec3())
}

/// Per mesh, built on its first frame through the tiles: for each group of at least
/// [`MIN_MEMBERS`] binned triangles, the triangles (ascending) and their edges in the group
/// plane's 2D frame, eight at a time, and the frame its record carries.
pub(crate) struct GroupTable {
    /// `members[start[g]..start[g + 1]]`: group `g`'s binned triangles (empty for a small
    /// group), padded with `u32::MAX` to a multiple of [`LANES`]. Empty when no group is big.
    start: Vec<u32>,
    members: Vec<u32>,
    /// Lanes of `members`, eight at a time: chunk `k` is members `8k..8k + 8`.
    lines: Vec<LineChunk>,
    frames: Vec<RecordFrame>,
    /// Each group's frame in f64 ([`axes`] of its plane and its record's `e1`), made once
    /// here instead of at every crossing (a square root and four divisions a group a ray).
    axes: Vec<Axes>,
    /// The largest magnitude of a vertex relative to the anchor.
    vmax: f64,
}

/// A group's unit normal and its frame's second axis, as [`axes`] makes them; the first
/// axis is the record's `e1`.
#[derive(Clone, Copy, Debug)]
struct Axes {
    n: DVec3,
    e2: Vec3,
}

impl Axes {
    const NONE: Axes = Axes {
        n: DVec3::ZERO,
        e2: Vec3::ZERO,
    };
}

/// Where a ray crosses a group's plane, in its frame, and the sideways margin within which
/// a triangle may be reported; `None` where every triangle must be tested.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Crossing {
    x: f32,
    y: f32,
    margin: f32,
}

impl GroupTable {
    /// The table of `mesh` (its BLAS `blas`, winding pairs `mirror`).
    pub(crate) fn new(mesh: &Mesh, blas: &Blas, mirror: &[u32]) -> Self {
        let groups = blas.planes.len();
        // Each triangle's group, and the binned (pair-leading) triangles per group.
        let group_of = blas.triangle_groups(mesh.tris.len());
        let mut count = vec![0u32; groups + 1];
        for (t, &g) in group_of.iter().enumerate() {
            if leads(mirror, t) {
                count[g as usize + 1] += 1;
            }
        }
        let big = |c: u32| c as usize >= MIN_MEMBERS;
        let vmax = (blas.lo - blas.anchor)
            .abs()
            .max((blas.hi - blas.anchor).abs())
            .length();
        if !count.iter().any(|&c| big(c)) {
            return GroupTable {
                start: Vec::new(),
                members: Vec::new(),
                lines: Vec::new(),
                frames: Vec::new(),
                axes: Vec::new(),
                vmax,
            };
        }
        let lanes = LANES as u32;
        let mut start = vec![0u32; groups + 1];
        for g in 0..groups {
            let c = if big(count[g + 1]) { count[g + 1] } else { 0 };
            start[g + 1] = start[g] + c.div_ceil(lanes) * lanes;
        }
        let mut next = start.clone();
        let mut members = vec![u32::MAX; start[groups] as usize];
        for (t, &g) in group_of.iter().enumerate() {
            let g = g as usize;
            if leads(mirror, t) && start[g + 1] > start[g] {
                members[next[g] as usize] = t as u32;
                next[g] += 1;
            }
        }
        drop(next);
        let vert = |i: u32| blas.relative(mesh.positions[i as usize]);
        let mut frames = vec![RecordFrame::NONE; groups];
        let mut group_axes = vec![Axes::NONE; groups];
        let mut lines = vec![LineChunk::EMPTY; members.len() / LANES];
        // Each group's chunks, in group order: the groups are independent and filled in
        // parallel (the table's first frame was a serial pass over every triangle).
        let mut chunks: Vec<&mut [LineChunk]> = Vec::with_capacity(groups);
        let mut rest = &mut lines[..];
        for g in 0..groups {
            let n = ((start[g + 1] - start[g]) as usize) / LANES;
            let (mine, tail) = std::mem::take(&mut rest).split_at_mut(n);
            chunks.push(mine);
            rest = tail;
        }
        frames
            .par_iter_mut()
            .zip(group_axes.par_iter_mut())
            .zip(chunks.into_par_iter())
            .enumerate()
            .with_min_len(256)
            .for_each(|(g, ((frame, ga), lines))| {
                let (s, e) = (start[g] as usize, start[g + 1] as usize);
                let (pn, _) = blas.planes[g];
                let len = pn.length();
                if s == e || !(len > 0.0 && len.is_finite()) {
                    return;
                }
                let e1 = (pn / len).any_orthonormal_vector().as_vec3();
                let (n, w, e1d, e2d) = axes(blas.planes[g], e1);
                *ga = Axes {
                    n,
                    e2: e2d.as_vec3(),
                };
                let origin = vert(mesh.tris[members[s] as usize][0]);
                let od = origin.as_dvec3();
                let (mut slab, mut reach) = (0.0f64, 0.0f64);
                for (k, &t) in unpadded(&members[s..e]).iter().enumerate() {
                    let mut p = [(0.0f64, 0.0f64); 3];
                    for (j, &i) in mesh.tris[t as usize].iter().enumerate() {
                        let v = vert(i).as_dvec3();
                        slab = slab.max((n.dot(v) - w).abs());
                        p[j] = ((v - od).dot(e1d), (v - od).dot(e2d));
                        reach = reach.max(p[j].0.abs()).max(p[j].1.abs());
                    }
                    lines[k / LANES].set(k % LANES, p);
                }
                // The f64 arithmetic above rounds far below a relative 1e-9 of the magnitudes
                // involved.
                let scale = od.length() + vmax;
                *frame = RecordFrame {
                    origin,
                    e1,
                    slab: up(slab * (1.0 + 1e-9) + 1e-9 * scale),
                    reach: up(reach * (1.0 + 1e-9)),
                };
            });
        GroupTable {
            start,
            members,
            lines,
            frames,
            axes: group_axes,
            vmax,
        }
    }

    /// Whether group `g` is binned as one record: a group of more than [`LANES`] binned
    /// triangles, or with `small`, of at least [`MIN_MEMBERS`] (its padded member list is
    /// one chunk).
    #[inline]
    pub(crate) fn is_group(&self, g: u32, small: bool) -> bool {
        let g = g as usize;
        if g + 1 >= self.start.len() {
            return false;
        }
        let n = (self.start[g + 1] - self.start[g]) as usize;
        n > LANES || (small && n > 0)
    }

    /// Group `g`'s binned triangles, ascending (the first is the one its record is made at);
    /// member `8i + l` is lane `l` of [`GroupTable::masks`]'s `i`-th mask.
    #[inline]
    pub(crate) fn members(&self, g: u32) -> &[u32] {
        let g = g as usize;
        unpadded(&self.members[self.start[g] as usize..self.start[g + 1] as usize])
    }

    /// What group `g`'s record carries ([`RecordFrame`]).
    pub(crate) fn record(&self, g: u32) -> RecordFrame {
        self.frames[g as usize]
    }

    /// Where the local ray `r` crosses the plane of group `g`, whose record carries `f`, with
    /// the margin of the module documentation: `Some(None)` where the ray can cross none of
    /// the group's triangles (the crossing is beyond the margin of the members' reach),
    /// `None` where every triangle must be tested. `tp`: the ray's distance to the group
    /// plane as the hit key takes it (`mesh_hit::plane_distance`).
    #[inline]
    pub(crate) fn crossing(
        &self,
        g: u32,
        f: &RecordFrame,
        r: &crate::mesh_hit::LocalRay,
        tp: f64,
    ) -> Option<Option<Crossing>> {
        let slab = f.slab as f64;
        // A group without a frame (`RecordFrame::NONE`) has no axes either.
        if !slab.is_finite() {
            return None;
        }
        let Axes { n, e2 } = self.axes[g as usize];
        let (e1, e2) = (f.e1.as_dvec3(), e2.as_dvec3());
        let nd = n.dot(r.ld64).abs();
        // The cosine and its reciprocal, each within a few ulps of the quotient `|n·d|/|d|`
        // (one per ray, one here).
        let c = nd * r.ld_inv;
        if !(c >= MIN_COSINE) {
            return None;
        }
        let inv_c = r.ld_len / nd;
        // The crossing at the key's distance: the unnormalised plane's quotient, which differs
        // from the normalised one's by a relative 1e-16 (far below the margin's last term).
        let p = r.lo64 + r.ld64 * tp;
        let q = p - f.origin.as_dvec3();
        let (x, y) = (q.dot(e1), q.dot(e2));
        let rr = r.lo_len + self.vmax;
        // The ray meets a member at most `slab/c` from `p`; the frame's axes, off unit and
        // orthogonal by the f32 rounding, move that displacement's projection by less than
        // 1e-6 of it. The few ulps of the cosine, of `1/c` and of this sum are covered by the
        // relative 1e-12; `|p|₁ ≥ |p|` stands for the magnitude of the crossing.
        let margin =
            (slab * (1.0 - c * c).max(0.0).sqrt() + 1e-6 * slab + EPS * rr) * inv_c * (1.0 + 1e-12)
                + 1e-9 * (rr + p.abs().element_sum());
        if !(x.is_finite() && y.is_finite() && margin.is_finite()) {
            return None;
        }
        let reach = f.reach as f64;
        if x.abs() - margin > reach || y.abs() - margin > reach {
            return Some(None);
        }
        // The lanes evaluate `a·x + b·y + c` in f32 on coefficients rounded to f32, with
        // `|a|, |b| ≤ 1` and `|c|` at most twice the members' reach: each of the few
        // roundings moves the value by a relative 2⁻²⁴ of `|x| + |y| + |c|`, and 1e-6 of that
        // sum (about 17 units) covers them, with the margin's own rounding.
        let margin = margin + 1e-6 * (x.abs() + y.abs() + 2.0 * reach + margin);
        Some(Some(Crossing {
            x: x as f32,
            y: y as f32,
            margin: up(margin),
        }))
    }

    /// The members of group `g` that a ray crossing its plane at `at` may cross: bit `l` of
    /// the `i`-th mask is member `8i + l`, set where the crossing is within the margin of
    /// each edge line of the member's projection into the plane (which holds the projection
    /// of every point of the triangle; a point within the margin of the triangle is within it
    /// of each line). Padding lanes never pass.
    #[inline]
    pub(crate) fn masks<'a>(&'a self, g: u32, at: &'a Crossing) -> impl Iterator<Item = u32> + 'a {
        let g = g as usize;
        let (s, e) = (self.start[g] as usize, self.start[g + 1] as usize);
        self.lines[s / LANES..e / LANES]
            .iter()
            .map(move |c| c.mask(at))
    }
}

/// Candidates a frame's rays test for each triangle of the meshes without a group table, at
/// which the per-ray path builds the tables first ([`MeshTracer::tables_pay`]). Measured on
/// one-node exports of two real captures at 320×240 (single `trace`, wall time on 2 cores):
/// the table costs 70–205 ns a triangle to build (MeshSplats fans of 8 to `rings` discs of 40,
/// both tables filled in parallel) and saves 10–14 ns of each candidate the run-by-run walk
/// tests, so it pays from 7–15 candidates a triangle. 16 builds it where it paid (`plant`'s
/// `rings`, 31 a triangle: 6.0 → 3.75 s with the build; its MeshSplats fans, 38: 1.55 →
/// 0.93 s) and not where it did not (`fourth_st`'s `rings`, 6.2: 2.15 → 3.76 s; `plant`'s
/// opaque `rings` OBJ, 3.7: 0.76 → 2.27 s), `docs/trace-speed-groups.md`.
pub(crate) const TABLE_CANDIDATES_PER_TRIANGLE: f64 = 16.0;

/// Rays the estimate of [`MeshTracer::tables_pay`] traces at most (a 32×32 grid), and the
/// largest share of a frame's rays it takes (a 16th).
const SAMPLE_RAYS: u64 = 1024;

impl MeshTracer {
    /// Whether the per-ray path builds the group tables (`mesh_bin`'s `prepare_groups`)
    /// before it traces `cam`: where some instanced mesh of runs has none yet and the frame's
    /// rays, estimated from a grid of sample rays traced without them, test at least
    /// [`TABLE_CANDIDATES_PER_TRIANGLE`] candidates for each of those meshes' triangles.
    /// Opaque meshes (whose rays stop at their first hit) and small frames keep the
    /// run-by-run walk; the images are the same either way (the table only chooses which
    /// triangles get the exact test).
    pub(crate) fn tables_pay(
        &self,
        insts: &crate::instances::Instances,
        cam: &splatbridge_scene::Camera,
        opts: &crate::render::RenderOptions,
    ) -> bool {
        let mut seen = vec![false; self.blas.len()];
        let mut missing = 0u64;
        for i in insts.list() {
            let b = &self.blas[i.mesh];
            if !seen[i.mesh] && !b.run_start.is_empty() && b.groups.get().is_none() {
                seen[i.mesh] = true;
                missing += self.scene.meshes[i.mesh].tris.len() as u64;
            }
        }
        if missing == 0 {
            return false;
        }
        let rays = cam.width as u64 * cam.height as u64 * opts.spp as u64;
        let n = (rays / 16).clamp(1, SAMPLE_RAYS);
        let aspect = cam.width as f64 / cam.height as f64;
        let gx = ((n as f64 * aspect).sqrt().ceil() as u64).clamp(1, cam.width as u64);
        let gy = n.div_ceil(gx).clamp(1, cam.height as u64);
        let candidates: u64 = (0..gx * gy)
            .into_par_iter()
            .map(|s| {
                let u = ((s % gx) as f64 + 0.5) * cam.width as f64 / gx as f64;
                let v = ((s / gx) as f64 + 0.5) * cam.height as f64 / gy as f64;
                let (o, d) = crate::render::camera_ray(cam, u, v);
                let out = crate::mesh_tracer::with_thread_buffer(opts.k, |b| {
                    self.trace(insts, o, d, opts, b)
                });
                out.candidates as u64
            })
            .sum();
        let per_ray = candidates as f64 / (gx * gy) as f64;
        per_ray * rays as f64 >= TABLE_CANDIDATES_PER_TRIANGLE * missing as f64
    }
}

/// A group's members without the `u32::MAX` that pads them to whole chunks (fewer than
/// [`LANES`] at its end).
#[inline]
fn unpadded(members: &[u32]) -> &[u32] {
    let pad = members.iter().rev().take_while(|&&t| t == u32::MAX).count();
    &members[..members.len() - pad]
}

/// Eight members' edges in the group's frame, field by field: `line[edge][coefficient][lane]`,
/// `a·x + b·y + c ≥ 0` inside, `(a, b)` a unit normal, so the value is the signed distance
/// to the edge's line (Pineda's edge functions, as `mesh_cands::Edges` in screen space).
#[derive(Clone, Copy, Debug)]
struct LineChunk {
    line: [[[f32; LANES]; 3]; 3],
}

impl LineChunk {
    /// No member: no crossing passes (`0·x + 0·y − ∞`).
    const EMPTY: LineChunk = LineChunk {
        line: [[[0.0; LANES], [0.0; LANES], [f32::NEG_INFINITY; LANES]]; 3],
    };

    /// Lane `l` set to the triangle `p` (its vertices in the frame). A sliver, or a triangle
    /// whose lines cannot be formed, passes every crossing (the exact test decides).
    fn set(&mut self, l: usize, p: [(f64, f64); 3]) {
        let area = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0);
        let mut lines = [[0.0f32, 0.0, f32::INFINITY]; 3];
        if area != 0.0 && area.is_finite() {
            for (j, line) in lines.iter_mut().enumerate() {
                let (a, b) = (p[j], p[(j + 1) % 3]);
                let (ex, ey) = (b.0 - a.0, b.1 - a.1);
                let len = (ex * ex + ey * ey).sqrt();
                // Inward unit normal: left of the edge for a counter-clockwise triangle.
                let s = area.signum() / len;
                let (na, nb) = (-ey * s, ex * s);
                let c = -(na * a.0 + nb * a.1);
                if na.is_finite() && nb.is_finite() && c.is_finite() {
                    *line = [na as f32, nb as f32, c as f32];
                }
            }
        }
        for (e, line) in self.line.iter_mut().zip(lines) {
            for (k, v) in line.into_iter().enumerate() {
                e[k][l] = v;
            }
        }
    }

    /// Bit `l` set where lane `l`'s three lines are each within `at.margin` of the crossing
    /// (NaN passes).
    #[inline(always)]
    fn mask(&self, at: &Crossing) -> u32 {
        let mut m = 0u32;
        let e = &self.line;
        let lim = -at.margin;
        for l in 0..LANES {
            let out = (e[0][0][l] * at.x + e[0][1][l] * at.y + e[0][2][l] < lim)
                | (e[1][0][l] * at.x + e[1][1][l] * at.y + e[1][2][l] < lim)
                | (e[2][0][l] * at.x + e[2][1][l] * at.y + e[2][2][l] < lim);
            m |= (!out as u32) << l;
        }
        m
    }
}
