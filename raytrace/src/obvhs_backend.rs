//! The obvhs backend: a compressed wide BVH (CWBVH, Ylitie et al. 2017) built with PLOC
//! (Meister & Bittner 2018) from the pure-Rust `obvhs` crate.
//!
//! Presets never pre-split triangles (see `BuildPreset`), so each primitive sits in exactly one
//! leaf. Traversal goes through `ray_traverse`, whose closure returns a distance that shrinks
//! the ray's `tmax`: that is how the k-nearest query culls nodes beyond the k-th hit.

use std::time::Duration;

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::{build_cwbvh, build_cwbvh_from_tris};
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;

use crate::backend::{Accel, BuildPreset};

fn params(p: BuildPreset) -> BvhBuildParams {
    let mut b = match p {
        BuildPreset::Fastest => BvhBuildParams::fastest_build(),
        BuildPreset::VeryFast => BvhBuildParams::very_fast_build(),
        BuildPreset::Fast => BvhBuildParams::fast_build(),
        BuildPreset::Medium => BvhBuildParams::medium_build(),
    };
    b.pre_split = false;
    b
}

/// The traversal ray. Two departures from `Ray::new`: −0.0 direction components become +0.0
/// (the node test takes the octant from the sign of the direction but slab order from the sign
/// of its inverse, and `safe_inverse(−0.0)` is negative while `−0.0 < 0.0` is false, so every
/// node was missed), and the inverse is exact down to |d| = 1e-18 (clamped to ±1e18 below, which
/// keeps node arithmetic finite) instead of being clamped at f32::EPSILON, which turned nearly
/// grazing rays into steeper ones and could miss flat boxes.
fn make_ray(origin: Vec3, dir: Vec3, tmax: f32) -> Ray {
    let dir = dir + Vec3::ZERO;
    let inv = |x: f32| {
        if x.abs() < 1e-18 {
            1e18f32.copysign(x)
        } else {
            1.0 / x
        }
    };
    Ray {
        origin: Vec3A::from(origin),
        direction: Vec3A::from(dir),
        inv_direction: Vec3A::new(inv(dir.x), inv(dir.y), inv(dir.z)),
        tmin: 0.0,
        tmax,
    }
}

/// A CWBVH plus the map from its leaf order to the caller's primitive indices.
pub struct ObvhsAccel {
    bvh: CwBvh,
}

impl ObvhsAccel {
    pub fn triangles(preset: BuildPreset, verts: &[Vec3], tris: &[[u32; 3]]) -> Self {
        let t: Vec<Triangle> = tris
            .iter()
            .map(|&[a, b, c]| Triangle {
                v0: Vec3A::from(verts[a as usize]),
                v1: Vec3A::from(verts[b as usize]),
                v2: Vec3A::from(verts[c as usize]),
            })
            .collect();
        let bvh = build_cwbvh_from_tris(&t, params(preset), &mut Duration::default());
        ObvhsAccel::kept(bvh)
    }

    pub fn boxes(preset: BuildPreset, boxes: &[(Vec3, Vec3)]) -> Self {
        let b: Vec<Aabb> = boxes
            .iter()
            .map(|(lo, hi)| Aabb::new(Vec3A::from(*lo), Vec3A::from(*hi)))
            .collect();
        let bvh = build_cwbvh(&b, params(preset), &mut Duration::default());
        ObvhsAccel::kept(bvh)
    }

    /// The built structure as it is kept: obvhs reserves one wide node per primitive for the
    /// conversion from its binary tree (80 bytes each) and fills a fraction of them, so the
    /// spare capacity is released (a few hundred MB over tens of millions of primitives).
    fn kept(mut bvh: CwBvh) -> Self {
        bvh.nodes.shrink_to_fit();
        bvh.primitive_indices.shrink_to_fit();
        ObvhsAccel { bvh }
    }
}

impl ObvhsAccel {
    /// Traverse. obvhs's CWBVH node test clamps a node's entry distance to at least 1e-4 ray
    /// units (`cwbvh::node::EPSILON`), so a node the ray leaves within 1e-4 of its origin is
    /// skipped. Nodes are therefore tested against a ray whose origin sits 2e-4 units before
    /// `tmin` (before the real origin when resuming from 0: hits right at the camera are kept),
    /// while the caller's closure tests primitives against its own unmoved ray, so hit values
    /// never depend on the shift. Resuming from the last hit this skips the nodes behind it.
    fn walk(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        map: Option<&[u32]>,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    ) {
        let tmin = if tmin.is_finite() { tmin.max(0.0) } else { 0.0 };
        // 1e-5 relative covers the f32 rounding of `origin + dir·shift` at large tmin.
        let shift = tmin - tmin * 1e-5 - 2e-4;
        let ray = make_ray(origin + dir * shift, dir, tmax - shift);
        let mut hit = RayHit::none();
        let mut cull = tmax;
        self.bvh.ray_traverse(ray, &mut hit, |_, id| {
            let before = cull;
            let prim = match map {
                Some(m) => m[id],
                None => id as u32,
            };
            visit(prim, false, &mut cull);
            if cull < before {
                cull - shift
            } else {
                f32::INFINITY
            }
        });
    }
}

impl Accel for ObvhsAccel {
    fn traverse(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    ) {
        self.walk(
            origin,
            dir,
            0.0,
            tmax,
            Some(&self.bvh.primitive_indices),
            visit,
        );
    }

    fn slots(&self) -> Option<&[u32]> {
        Some(&self.bvh.primitive_indices)
    }

    fn traverse_slots(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    ) {
        self.walk(origin, dir, tmin, tmax, None, visit);
    }
}
