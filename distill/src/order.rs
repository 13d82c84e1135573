//! The order a pixel's hits are composited in during a fit.
//!
//! Every viewer draws a mesh in ray order: the tracer's hits sorted by distance along the ray,
//! so the fans of overlapping Gaussians interleave where they cut through each other. Native
//! splatting (Kerbl et al. 2023) composites whole splats sorted by the view-space depth of
//! their means. [`HitOrder::Splat`] regroups each pixel's recorded hits that way: every hit is
//! keyed by the view-space depth of its Gaussian's centre (the mean of the vertices carrying
//! that `_GAUSSIAN_ID`, which is the Gaussian's mean for every profile: fans, rings, quads and
//! volumetric fans are point-symmetric about it), and a stable sort keeps a Gaussian's own
//! hits (up to three for a volumetric fan) in ray order. A fit and its measurement in that
//! order take ordering out of the remaining error, so what is left is the profile's shape
//! (docs/distill.md, "Where the remaining error is"). It is a measurement: no viewer can
//! draw a mesh in it, so an export fitted this way is not what it was fitted to be.
//!
//! The hit lists are recorded in ray order down to the recording transmittance; a hit cut
//! there in ray order (transmittance below 1e-6 in front of it) can move forward in splat
//! order and is missing. Its weight in ray order is under 1e-6; in splat order it is bounded
//! by its own opacity, so the regrouped image is an approximation where more than a few
//! opaque fans overlap deeply.

use glam::DVec3;
use splatbridge_raytrace::hit_record::HitLists;
use splatbridge_raytrace::model::TriScene;
use splatbridge_scene::Camera;

/// How a pixel's hits are composited in a fit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HitOrder {
    /// The tracer's order, nearest hit first: what every viewer draws (the default).
    #[default]
    Ray,
    /// Whole Gaussians by the view-space depth of their centres, as native splatting sorts:
    /// a measurement of what ray order costs, not an export setting.
    Splat,
}

impl std::fmt::Display for HitOrder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            HitOrder::Ray => "ray",
            HitOrder::Splat => "splat",
        })
    }
}

/// The Gaussian centres of a triangle scene, in each mesh's own frame.
#[derive(Clone, Debug, Default)]
pub struct Centres {
    /// Per mesh: per triangle, the index of its Gaussian in `local`.
    tri_group: Vec<Vec<u32>>,
    /// Per mesh: the centres of its Gaussians (mesh-local).
    local: Vec<Vec<DVec3>>,
}

impl Centres {
    /// The centre of every Gaussian of `scene`: the mean of the vertices carrying its
    /// `_GAUSSIAN_ID` (per vertex as the distiller derives it from the triangles).
    pub fn new(scene: &TriScene) -> Self {
        let per_vertex = super::vertex_gaussians(scene);
        let mut out = Centres::default();
        for (m, ids) in scene.meshes.iter().zip(&per_vertex) {
            let (index, centres) = super::mesh::gaussian_centres(m, ids);
            let tri_group = m
                .tri_gaussian
                .iter()
                .map(|g| index.get(g).map_or(u32::MAX, |&k| k as u32))
                .collect();
            out.tri_group.push(tri_group);
            out.local.push(centres);
        }
        out
    }

    /// Regroup every pixel's hits of `lists` (traced from `cam` at `time`) into splat order.
    /// A mesh drawn by several nodes takes its first node's pose (splatbridge writes one node
    /// per mesh).
    pub fn reorder(&self, scene: &TriScene, lists: &mut HitLists, cam: &Camera, time: f64) {
        let mut depth: Vec<Vec<f32>> = vec![Vec::new(); self.local.len()];
        for inst in scene.instances(time) {
            if depth[inst.mesh].is_empty() {
                depth[inst.mesh] = self.local[inst.mesh]
                    .iter()
                    .map(|&c| cam.to_camera(inst.to_world.transform_point3(c)).z as f32)
                    .collect();
            }
        }
        let key = |h: &splatbridge_raytrace::hit_record::RecordedHit| {
            let (m, t) = (h.mesh as usize, h.tri as usize);
            let g = self.tri_group[m][t];
            depth[m].get(g as usize).copied().unwrap_or(h.t)
        };
        for p in 0..lists.offsets.len().saturating_sub(1) {
            let (a, b) = (lists.offsets[p] as usize, lists.offsets[p + 1] as usize);
            lists.hits[a..b].sort_by(|x, y| key(x).total_cmp(&key(y)));
        }
    }
}
