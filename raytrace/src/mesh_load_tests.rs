//! What a mesh gets when it is loaded. Its BVH is left for its first use (`Blas::accel`):
//! frames through the screen tiles never build it, the first frame traced ray by ray does,
//! and a mesh an f32 BVH cannot hold is still refused when it is loaded, not when a ray first
//! reaches it. Its planar groups, found stretch by stretch in parallel, are those of one
//! pass over the triangles (`Mesh::planar_groups`).

use glam::{DVec3, Vec3, Vec4};

use super::backend::{BackendKind, BuildPreset};
use super::mesh_tile_tests::{assert_image_is_reference, bits, cameras, ided_mesh, scene, tracer};
use super::mesh_tile_tests::{random_mesh, Rng};
use super::mesh_tracer::MeshTracer;
use super::model::{Mesh, TriScene};
use super::render::RenderOptions;

fn built(t: &MeshTracer) -> Vec<bool> {
    t.blas.iter().map(|b| b.accel_built()).collect()
}

#[test]
fn tiles_leave_the_bvh_unbuilt_and_rays_build_it() {
    let tiles = tracer(scene(4, Vec3::ZERO, true));
    assert!(tiles.blas.len() >= 2, "the scene has meshes to build");
    for cam in cameras(DVec3::ZERO) {
        assert_image_is_reference(&tiles, &cam, 1, "through the tiles");
    }
    assert!(built(&tiles).iter().all(|b| !b), "{:?}", built(&tiles));
    assert_eq!(tiles.total_build_seconds(), tiles.build_seconds);
    // A frame ray by ray builds every instanced mesh's BVH, and draws what a tracer whose
    // BVHs were built by its own first such frame draws.
    let fresh = tracer(scene(4, Vec3::ZERO, true));
    let opts = RenderOptions::default();
    for cam in cameras(DVec3::ZERO) {
        let (a, _) = tiles.render_per_ray(&cam, 0.0, &opts).unwrap();
        let (b, _) = fresh.render_per_ray(&cam, 0.0, &opts).unwrap();
        assert_eq!(bits(&a), bits(&b));
    }
    assert!(built(&tiles).iter().all(|&b| b), "{:?}", built(&tiles));
    // Their build counts as build time (reported beside the load's), not as a frame's.
    assert!(tiles.total_build_seconds() > tiles.build_seconds);
}

#[test]
fn a_mesh_beyond_an_f32_bvh_is_refused_when_loaded() {
    // One vertex 1e13 from the others: relative to the box's centre, 5e12 lies beyond the
    // ±1e12 an f32 BVH holds (`backend::MAX_BVH_COORD`).
    let mut m = ided_mesh();
    m.positions = vec![Vec3::ZERO, Vec3::X, Vec3::new(1e13, 0.0, 0.0)];
    m.colors = vec![Vec4::ONE; 3];
    m.tris = vec![[0, 1, 2]];
    m.tri_material = vec![0].into();
    m.tri_gaussian = vec![0];
    let mut s: TriScene = scene(4, Vec3::ZERO, true);
    s.meshes[0] = m;
    match MeshTracer::new(s, BackendKind::Obvhs, BuildPreset::Medium) {
        Err(e) => assert!(e.to_string().contains("an f32 BVH holds"), "{e}"),
        Ok(_) => panic!("a mesh beyond an f32 BVH was loaded"),
    }
}

/// `Mesh::planar_groups` as one pass over every triangle, a Gaussian's triangles together
/// (a stable sort by Gaussian), each side's length its own root: the reference.
fn groups_in_one_pass(m: &Mesh) -> (Vec<u32>, u32) {
    let mut order: Vec<usize> = (0..m.tris.len()).collect();
    order.sort_by_key(|&t| m.tri_gaussian[t]);
    let mut group = vec![u32::MAX; m.tris.len()];
    let mut next = 0u32;
    let mut reps: Vec<(DVec3, DVec3, f64, u32)> = Vec::new();
    let mut cur = None;
    for t in order {
        if cur != Some(m.tri_gaussian[t]) {
            reps.clear();
            cur = Some(m.tri_gaussian[t]);
        }
        let [a, b, c] = m.tris[t].map(|i| m.positions[i as usize].as_dvec3());
        let ext = (b - a).length().max((c - a).length()).max((c - b).length());
        let nn = (b - a).cross(c - a).normalize_or_zero();
        let near = |p: DVec3, rn: DVec3, rp: DVec3, tol: f64| {
            rn.dot(p - rp).abs() <= tol.max(1e-3 * ext) + 1e-6 * p.abs().max_element()
        };
        let found = reps.iter().find(|&&(rn, rp, tol, _)| {
            nn != DVec3::ZERO
                && rn.dot(nn).abs() > 0.99
                && [a, b, c].iter().all(|&p| near(p, rn, rp, tol))
        });
        group[t] = match found {
            Some(r) => r.3,
            None => {
                next += 1;
                if nn != DVec3::ZERO {
                    reps.push((nn, a, 1e-3 * ext, next - 1));
                }
                next - 1
            }
        };
    }
    (group, next)
}

#[test]
fn planar_groups_by_stretches_are_one_pass_groups() {
    let mut compared = 0;
    for seed in 1..6u64 {
        // Random fans (repeated ones, both windings), with degenerate triangles and a
        // Gaussian's triangles split by another's in some meshes (not ascending).
        let mut m = random_mesh(seed, 60, 1.0, Vec3::ZERO, seed % 2 == 0);
        let mut r = Rng(seed);
        for _ in 0..8 {
            let i = (r.f() * m.positions.len() as f32) as u32 % m.positions.len() as u32;
            let g = m.tri_gaussian[(r.f() * m.tris.len() as f32) as usize % m.tris.len()];
            m.tris.push([i, i, i]);
            m.tri_gaussian.push(g);
        }
        // Each degenerate triangle among its Gaussian's (ascending, as exports list them),
        // but in one mesh, where a Gaussian's triangles are split by another's.
        let mut order: Vec<usize> = (0..m.tris.len()).collect();
        order.sort_by_key(|&t| m.tri_gaussian[t]);
        m.tris = order.iter().map(|&t| m.tris[t]).collect();
        m.tri_gaussian = order.iter().map(|&t| m.tri_gaussian[t]).collect();
        let ascending = seed != 3;
        if !ascending {
            m.tri_gaussian.swap(0, m.tris.len() - 1);
        }
        assert_eq!(m.tri_gaussian.windows(2).all(|w| w[0] <= w[1]), ascending);
        let want = groups_in_one_pass(&m);
        for stretch in [1, 2, 7, 64, 1 << 16] {
            assert_eq!(
                m.planar_groups_in(stretch),
                want,
                "seed {seed}, stretch {stretch}"
            );
            compared += 1;
        }
    }
    assert_eq!(compared, 25);
}
