//! The triangle-soup model and the mesher that produces it, chunk by chunk.
//!
//! A [`MeshSoup`] holds positions, unit normals, RGBA colours, optional texture coordinates,
//! the id of the Gaussian each vertex came from, and u32 triangle indices. No vertex is
//! shared between Gaussians (the three fans of one volumetric Gaussian share their centre
//! and axis vertices, as in MeshSplats).
//!
//! [`Mesher`] classifies a cloud once and then generates the mesh in chunks of Gaussians in
//! parallel through [`crate::chunked::ChunkedMesh`] (shared with the surfel mesher), handing
//! them to a writer in order: writers stream, and nothing holds a second full copy of the
//! mesh.

use std::ops::Range;

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use splatbridge_scene::{sh, GaussianCloud};

use crate::chunked::ChunkedMesh;
use crate::classify::{classify, corrected_alpha, score, Frame, Kind};
use crate::options::{ColorEncoding, ConvertOptions, MeshCounts, Profile, VolumetricMode};
use crate::order::Facing;
use crate::profile::{FanLayout, ProfileShape, VertexKey};

/// A triangle soup (or one chunk of one); indices are relative to its first vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshSoup {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    /// RGBA in [0, 1], encoded as the options say (linear by default).
    pub colors: Vec<[f32; 4]>,
    /// Texture coordinates (profile `texture` only; empty otherwise).
    pub uvs: Vec<[f32; 2]>,
    pub gaussian_ids: Vec<u32>,
    pub indices: Vec<u32>,
}

impl MeshSoup {
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Append `other`, offsetting its indices.
    pub fn append(&mut self, other: &MeshSoup) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        self.colors.extend_from_slice(&other.colors);
        self.uvs.extend_from_slice(&other.uvs);
        self.gaussian_ids.extend_from_slice(&other.gaussian_ids);
        self.indices.extend(other.indices.iter().map(|i| i + base));
    }
}

/// Where generated vertices and triangles go: a [`MeshSoup`], a bounds accumulator, or a
/// writer's byte encoding. `FULL = false` sinks only need positions, so colours, normals and
/// ids are not computed for them.
pub trait VertexSink {
    const FULL: bool;
    /// Add a vertex and return its index (relative to the chunk).
    fn vertex(&mut self, p: Vec3, normal: [f32; 3], rgba: [f32; 4], uv: [f32; 2], id: u32) -> u32;
    fn triangle(&mut self, t: [u32; 3]);
}

impl VertexSink for MeshSoup {
    const FULL: bool = true;
    #[inline]
    fn vertex(&mut self, p: Vec3, normal: [f32; 3], rgba: [f32; 4], uv: [f32; 2], id: u32) -> u32 {
        let idx = self.positions.len() as u32;
        self.positions.push(p.to_array());
        self.normals.push(normal);
        self.colors.push(rgba);
        self.uvs.push(uv);
        self.gaussian_ids.push(id);
        idx
    }
    #[inline]
    fn triangle(&mut self, t: [u32; 3]) {
        self.indices.extend_from_slice(&t);
    }
}

/// Exact per-axis bounds of the generated positions.
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    pub lo: Vec3,
    pub hi: Vec3,
    pub count: u32,
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds {
            lo: Vec3::INFINITY,
            hi: Vec3::NEG_INFINITY,
            count: 0,
        }
    }
}

impl VertexSink for Bounds {
    const FULL: bool = false;
    #[inline]
    fn vertex(&mut self, p: Vec3, _: [f32; 3], _: [f32; 4], _: [f32; 2], _: u32) -> u32 {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
        self.count += 1;
        self.count - 1
    }
    #[inline]
    fn triangle(&mut self, _: [u32; 3]) {}
}

/// The sRGB transfer functions (IEC 61966-2-1): display value → linear, linear → display.
pub use splatbridge_scene::srgb::{decode as srgb_to_linear, encode as linear_to_srgb};

/// Scratch space one worker reuses between Gaussians.
#[derive(Default)]
pub struct Scratch {
    layout: FanLayout,
    keymap: Vec<u32>,
    map: Vec<u32>,
}

/// One cloud, classified and ready to be meshed.
pub struct Mesher<'a> {
    pub cloud: &'a GaussianCloud,
    shape: &'a ProfileShape,
    kinds: Vec<Kind>,
    correct_three_fans: bool,
    bake_centre: Option<DVec3>,
    linear: bool,
    /// Vertex count and index pattern of a flat and a volumetric Gaussian.
    templates: [(u32, Vec<u32>); 2],
    /// Per template triangle: its fan (plane) and whether its winding's normal is
    /// `+axes[a] × axes[b]` of that plane (see [`Mesher::set_facing`]).
    tri_planes: [Vec<(u8, bool)>; 2],
    /// Which way fans face in the index stream; anything but `Template` writes each
    /// triangle twice, once per winding (see `order.rs`).
    facing: Facing,
    /// Explicit `_GAUSSIAN_ID` per Gaussian (a split cloud keeps its unsplit ids).
    id_map: Option<&'a [u32]>,
    /// Coplanar separation on (see `classify.rs`), and the largest distance the cloud's
    /// frame moves from the world origin (an object's track), for the coordinate bound.
    coplanar: bool,
    frame_reach: f32,
    /// Fitted vertex colours that replace the profile's (mesh distillation).
    fitted: Option<std::sync::Arc<crate::vertex_colours::VertexColours>>,
    pub counts: MeshCounts,
}

impl<'a> Mesher<'a> {
    /// Classify `cloud` (in parallel). `id_offset` is added to every `_GAUSSIAN_ID`.
    pub fn new(
        cloud: &'a GaussianCloud,
        shape: &'a ProfileShape,
        opts: &ConvertOptions,
        name: &str,
        id_offset: u64,
    ) -> Self {
        let three = opts.volumetric == VolumetricMode::ThreeFans;
        let aware = shape.profile != Profile::MeshSplats;
        let kinds: Vec<Kind> = (0..cloud.len())
            .into_par_iter()
            .map(|i| classify(cloud, i, opts.flat_ratio, three, aware))
            .collect();
        let mut m = Mesher {
            cloud,
            shape,
            kinds,
            correct_three_fans: aware,
            bake_centre: opts.bake_view.as_ref().map(|c| c.centre),
            linear: opts.color_encoding == ColorEncoding::Linear,
            templates: [(0, Vec::new()), (0, Vec::new())],
            tri_planes: [Vec::new(), Vec::new()],
            facing: Facing::Template,
            id_map: None,
            coplanar: opts.coplanar_offset,
            frame_reach: 0.0,
            fitted: opts.vertex_colours.clone(),
            counts: MeshCounts {
                name: name.to_string(),
                gaussians_in: cloud.len() as u64,
                id_offset,
                ..Default::default()
            },
        };
        for (k, volumetric) in [false, true].into_iter().enumerate() {
            let probe = m.probe(volumetric);
            m.tri_planes[k] = probe_planes(&probe, volumetric);
            m.templates[k] = (probe.vertex_count() as u32, probe.indices);
        }
        m.recount();
        m
    }

    /// Write fans facing `facing` in the index stream: with `Axis` or `Point`, every fan's
    /// triangles first face that way (Gaussians in cloud order), then every triangle follows
    /// once more in the other winding (Gaussians in reverse order). Vertices are not
    /// duplicated. Counts double accordingly.
    pub fn set_facing(&mut self, facing: Facing) {
        self.facing = facing;
        self.recount();
    }

    /// Copies of each triangle in the index stream.
    fn copies(&self) -> u64 {
        if self.facing == Facing::Template {
            1
        } else {
            2
        }
    }

    /// One unit Gaussian of the given kind at the origin, axes x, y, z (opacity 1; the
    /// topology of every profile is independent of opacity): its vertex count and index
    /// pattern are the kind's template.
    fn probe(&self, volumetric: bool) -> MeshSoup {
        let f = Frame {
            mean: Vec3::ZERO,
            axes: [Vec3::X, Vec3::Y, Vec3::Z],
            scales: [1.0; 3],
            opacity: 1.0,
        };
        let mut out = MeshSoup::default();
        let mut s = Scratch::default();
        self.emit_frame(&f, Vec3::ONE, 0, volumetric, None, None, &mut out, &mut s);
        out
    }

    fn recount(&mut self) {
        let copies = self.copies();
        let c = &mut self.counts;
        let (mut flat, mut vol, mut inv, mut tr, mut ov, mut bu) =
            (0u64, 0u64, 0u64, 0u64, 0u64, 0u64);
        for k in &self.kinds {
            match k {
                Kind::Flat => flat += 1,
                Kind::Volumetric => vol += 1,
                Kind::Invalid => inv += 1,
                Kind::Transparent => tr += 1,
                Kind::Overflow => ov += 1,
                Kind::Budget => bu += 1,
            }
        }
        c.flat = flat;
        c.volumetric = vol;
        c.dropped_invalid = inv;
        c.dropped_transparent = tr;
        c.dropped_overflow = ov;
        c.dropped_budget = bu;
        let [(fv, fi), (vv, vi)] = &self.templates;
        c.vertices = flat * *fv as u64 + vol * *vv as u64;
        c.triangles = (flat * (fi.len() / 3) as u64 + vol * (vi.len() / 3) as u64) * copies;
    }

    /// Use `ids[i]` as Gaussian `i`'s `_GAUSSIAN_ID` instead of `id_offset + i`.
    /// Fails (and keeps the default ids) unless there is one id per Gaussian.
    pub fn set_id_map(&mut self, ids: &'a [u32], id_offset: u64) -> crate::Result<()> {
        if ids.len() != self.cloud.len() {
            return Err(crate::ConvertError::Invalid(format!(
                "{} Gaussian ids for {} Gaussians",
                ids.len(),
                self.cloud.len()
            )));
        }
        self.id_map = Some(ids);
        self.counts.id_offset = id_offset;
        Ok(())
    }

    /// The cloud is in a frame that sits up to `reach` from the world origin (an object's
    /// track): the coplanar separation scales with world, not local, coordinates.
    pub fn set_frame_reach(&mut self, reach: f32) {
        self.frame_reach = if reach.is_finite() { reach.abs() } else { 0.0 };
    }

    pub fn frame_reach(&self) -> f32 {
        self.frame_reach
    }

    /// The global id of Gaussian `i`.
    fn global_id(&self, i: usize) -> u32 {
        match self.id_map {
            Some(m) => m[i],
            None => (self.counts.id_offset + i as u64) as u32,
        }
    }

    pub fn kind(&self, i: usize) -> Kind {
        self.kinds[i]
    }

    pub fn has_uv(&self) -> bool {
        self.shape.has_uv()
    }

    pub fn is_empty(&self) -> bool {
        self.counts.triangles == 0
    }

    /// The display colour of Gaussian `i` in [0, 1] (DC term, or baked for the camera).
    fn display_colour(&self, i: usize, mean: Vec3) -> Vec3 {
        let coeffs = self.cloud.sh_of(i);
        if let Some(c) = self.bake_centre {
            let d = mean.as_dvec3() - c;
            let l = d.length();
            if l > 0.0 && l.is_finite() {
                let dir = (d / l).as_vec3();
                return sh::eval_color(self.cloud.sh_degree, coeffs, dir)
                    .clamp(Vec3::ZERO, Vec3::ONE);
            }
        }
        sh::dc_color(coeffs)
    }

    #[allow(clippy::too_many_arguments)]
    fn emit_frame<S: VertexSink>(
        &self,
        f: &Frame,
        rgb: Vec3,
        id: u32,
        volumetric: bool,
        fitted: Option<&[[f32; 4]]>,
        fitted_at: Option<&[[f32; 3]]>,
        out: &mut S,
        s: &mut Scratch,
    ) {
        if !self.shape.layout(f.opacity, &mut s.layout) {
            return;
        }
        let normal = f.normal().to_array();
        let planes: &[(usize, usize)] = if volumetric {
            &[(0, 1), (1, 2), (2, 0)]
        } else {
            &[(0, 1)]
        };
        s.keymap.clear();
        s.keymap.resize(1 + 6 * self.shape.rings.max(1), u32::MAX);
        let correct = volumetric && self.correct_three_fans;
        // The Gaussian's own vertices in emission order: the key of fitted colours.
        let mut own = 0usize;
        for &(a, b) in planes {
            let ea = f.axes[a] * f.scales[a];
            let eb = f.axes[b] * f.scales[b];
            s.map.clear();
            for v in &s.layout.verts {
                let slot = match v.key {
                    VertexKey::Centre => Some(0),
                    VertexKey::Axis { ring, dir } => {
                        let axis = if dir % 2 == 0 { a } else { b };
                        Some(1 + ring as usize * 6 + axis * 2 + (dir >= 2) as usize)
                    }
                    VertexKey::Own => None,
                };
                if let Some(sl) = slot {
                    if s.keymap[sl] != u32::MAX {
                        s.map.push(s.keymap[sl]);
                        continue;
                    }
                }
                let p = match fitted_at.and_then(|q| q.get(own)) {
                    Some(q) => Vec3::from_array(*q),
                    None => f.mean + ea * v.x + eb * v.y,
                };
                let alpha = if !S::FULL {
                    0.0
                } else if correct {
                    corrected_alpha(v.alpha)
                } else {
                    v.alpha
                };
                let rgba = match fitted.and_then(|c| c.get(own)) {
                    Some(c) => *c,
                    None => [rgb.x, rgb.y, rgb.z, alpha.clamp(0.0, 1.0)],
                };
                own += 1;
                let idx = out.vertex(p, normal, rgba, v.uv, id);
                if let Some(sl) = slot {
                    s.keymap[sl] = idx;
                }
                s.map.push(idx);
            }
            for t in &s.layout.tris {
                out.triangle(t.map(|k| s.map[k as usize]));
            }
        }
    }

    fn emit_items<S: VertexSink>(&self, range: Range<usize>, out: &mut S, s: &mut Scratch) {
        for i in range {
            let kind = self.kinds[i];
            if !kind.kept() {
                continue;
            }
            let mut f = Frame::of(self.cloud, i);
            let id = self.global_id(i);
            if self.coplanar {
                // The bound of the fan's world coordinates: centre, frame and fan extent.
                let reach = f.mean.abs().max_element() + self.frame_reach + 4.0 * f.scales[0].abs();
                f.mean += f.normal() * crate::classify::coplanar_offset(id, reach);
            }
            if !S::FULL {
                let at = self.fitted.as_deref().and_then(|v| v.positions_of(id));
                self.emit_frame(
                    &f,
                    Vec3::ZERO,
                    0,
                    kind == Kind::Volumetric,
                    None,
                    at,
                    out,
                    s,
                );
                continue;
            }
            let mut rgb = self.display_colour(i, f.mean);
            if self.linear {
                rgb = Vec3::new(
                    srgb_to_linear(rgb.x),
                    srgb_to_linear(rgb.y),
                    srgb_to_linear(rgb.z),
                );
            }
            let fitted = self.fitted.as_deref().and_then(|v| v.of(id));
            let at = self.fitted.as_deref().and_then(|v| v.positions_of(id));
            self.emit_frame(&f, rgb, id, kind == Kind::Volumetric, fitted, at, out, s);
        }
    }

    /// Template 0 (flat) or 1 (volumetric) of a kept Gaussian.
    fn template_of(&self, i: usize) -> Option<usize> {
        match self.kinds[i] {
            Kind::Flat => Some(0),
            Kind::Volumetric => Some(1),
            _ => None,
        }
    }

    /// Gaussian `i`'s triangles with its first vertex at `v`: the template's winding, or
    /// facing [`Mesher::facing`] (`reverse`: the opposite winding of that).
    fn gaussian_indices(&self, i: usize, v: u32, kind: usize, reverse: bool, idx: &mut Vec<u32>) {
        let pattern = &self.templates[kind].1;
        let towards = match self.facing {
            Facing::Template => {
                idx.extend(pattern.iter().map(|&j| v + j));
                return;
            }
            Facing::Axis(a) => a,
            Facing::Point(p) => (p - self.cloud.means[i].as_dvec3()).as_vec3(),
        };
        let f = Frame::of(self.cloud, i);
        const PLANES: [(usize, usize); 3] = [(0, 1), (1, 2), (2, 0)];
        let side: [bool; 3] = PLANES.map(|(a, b)| f.axes[a].cross(f.axes[b]).dot(towards) >= 0.0);
        for (tri, &(plane, positive)) in pattern.chunks_exact(3).zip(&self.tri_planes[kind]) {
            // Front face towards `towards` when the template's normal sign agrees with the side.
            let keep = (positive == side[plane as usize]) != reverse;
            let t = [v + tri[0], v + tri[1], v + tri[2]];
            idx.extend(if keep { t } else { [t[0], t[2], t[1]] });
        }
    }

    /// Triangles of Gaussian `i` under its current classification.
    fn triangles_of(&self, i: usize) -> u64 {
        match self.kinds[i] {
            Kind::Flat => (self.templates[0].1.len() / 3) as u64 * self.copies(),
            Kind::Volumetric => (self.templates[1].1.len() / 3) as u64 * self.copies(),
            _ => 0,
        }
    }
}

/// The plane and orientation of every triangle of a template: the probe's axes are
/// x, y, z, so plane (a, b)'s normal `axes[a] × axes[b]` is z, x or y.
fn probe_planes(out: &MeshSoup, volumetric: bool) -> Vec<(u8, bool)> {
    let planes = if volumetric { 3 } else { 1 };
    let per_plane = (out.indices.len() / 3 / planes).max(1);
    let normals = [Vec3::Z, Vec3::X, Vec3::Y];
    out.indices
        .chunks_exact(3)
        .enumerate()
        .map(|(t, tri)| {
            let p = [0, 1, 2].map(|k| Vec3::from_array(out.positions[tri[k] as usize]));
            let plane = (t / per_plane).min(planes - 1);
            let n = (p[1] - p[0]).cross(p[2] - p[0]);
            (plane as u8, n.dot(normals[plane]) >= 0.0)
        })
        .collect()
}

/// Keep the highest-scoring Gaussians of all `meshers` within `max_triangles`; the rest are
/// marked [`Kind::Budget`]. Ties keep the earlier mesher and the lower index (deterministic).
pub fn apply_budget(meshers: &mut [&mut Mesher<'_>], max_triangles: u64) {
    let total: u64 = meshers.iter().map(|m| m.counts.triangles).sum();
    if total <= max_triangles {
        return;
    }
    let mut entries: Vec<(f32, u32, u32)> = Vec::new();
    for (mi, m) in meshers.iter().enumerate() {
        let e: Vec<(f32, u32, u32)> = (0..m.cloud.len())
            .into_par_iter()
            .filter(|&i| m.kinds[i].kept())
            .map(|i| (score(m.cloud, i), mi as u32, i as u32))
            .collect();
        entries.extend(e);
    }
    entries
        .par_sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut used = 0u64;
    for &(_, mi, i) in &entries {
        let m = &mut meshers[mi as usize];
        let t = m.triangles_of(i as usize);
        if used + t <= max_triangles {
            used += t;
        } else {
            m.kinds[i as usize] = Kind::Budget;
        }
    }
    for m in meshers.iter_mut() {
        m.recount();
    }
}

impl ChunkedMesh for Mesher<'_> {
    type Scratch = Scratch;

    fn items(&self) -> usize {
        self.cloud.len()
    }

    fn vertices_of(&self, i: usize) -> u64 {
        match self.kinds[i] {
            Kind::Flat => self.templates[0].0 as u64,
            Kind::Volumetric => self.templates[1].0 as u64,
            _ => 0,
        }
    }

    fn index_passes(&self) -> usize {
        self.copies() as usize
    }

    fn indices_of(&self, i: usize, first: u32, reverse: bool, idx: &mut Vec<u32>) -> u32 {
        match self.template_of(i) {
            Some(kind) => {
                self.gaussian_indices(i, first, kind, reverse, idx);
                self.templates[kind].0
            }
            None => 0,
        }
    }

    fn emit_range<S: VertexSink>(&self, range: Range<usize>, out: &mut S, s: &mut Scratch) {
        self.emit_items(range, out, s)
    }

    fn has_uv(&self) -> bool {
        self.shape.has_uv()
    }
}
