//! The two windings of a triangle (the same three vertices in opposite orders, as the viewer
//! layout writes every triangle) give the same hit to the bit: barycentrics per vertex, and so
//! the same shade. `mesh_hit::test_triangle` rests on it when a hit of α = 0 decides the other
//! winding without testing it (`Tested::Decided`).

use glam::{DVec3, Vec2, Vec3, Vec4};

use crate::backend::{BackendKind, BuildPreset};
use crate::kbuffer::KBuffer;
use crate::mesh_hit::{LocalRay, Query};
use crate::mesh_tracer::{MeshTracer, TrianglePayload};
use crate::model::{AlphaMode, Material, MaterialRuns, Mesh, TriScene};
use crate::texture::{Texture, Wrap};

/// Triangles of random size and orientation, far from and near the origin, each written
/// twice (`[a, b, c]` and `[a, c, b]`), with random colours, UVs over a random 8×8 texture
/// whose alpha is 0 on a third of its texels.
fn scene(seed: u64) -> TriScene {
    let mut draw = crate::test_rng::unit(seed);
    let mut f = move || draw() as f32;
    let mut m = Mesh {
        has_gaussian_ids: true,
        tri_material: MaterialRuns::default(),
        ..Mesh::default()
    };
    let mut uvs = Vec::new();
    for g in 0..300u32 {
        let centre =
            Vec3::new(f() - 0.5, f() - 0.5, 3.0 + f()) * if g % 3 == 0 { 40.0 } else { 1.0 };
        let size = 0.01 + f() * f() * 0.5;
        let base = m.positions.len() as u32;
        for _ in 0..3 {
            m.positions
                .push(centre + Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * size);
            m.colors.push(Vec4::new(f(), f(), f(), f()));
            uvs.push(Vec2::new(f() * 1.4 - 0.2, f() * 1.4 - 0.2));
        }
        for t in [[base, base + 1, base + 2], [base, base + 2, base + 1]] {
            m.tris.push(t);
            m.tri_material.push(0);
            m.tri_gaussian.push(g);
        }
    }
    m.uvs = Some(uvs);
    let texels = (0..64)
        .map(|i| Vec4::new(f(), f(), f(), if i % 3 == 0 { 0.0 } else { f() }))
        .collect();
    let texture = Texture::from_texels(8, 8, texels, [Wrap::Repeat, Wrap::Mirror], false);
    let material = Material {
        base_color: Vec4::ONE,
        texture: Some(0),
        alpha_mode: AlphaMode::Blend,
    };
    TriScene::single(m, vec![material], vec![texture])
}

/// The hit `test_triangle` inserts for triangle `t` (vertices as the tile records hold them)
/// and the ray `o + s·d`, if any.
fn hit(tracer: &MeshTracer, t: usize, o: DVec3, d: DVec3) -> Option<TrianglePayload> {
    let (mesh, blas) = (&tracer.scene.meshes[0], &tracer.blas[0]);
    let run = blas.run_start.partition_point(|&s| s as usize <= t) - 1;
    let verts = mesh.tris[t].map(|i| blas.relative(mesh.positions[i as usize]));
    let r = LocalRay::new(o - blas.anchor, d)?;
    let q = Query {
        tmin: 0.0,
        tmax: f32::INFINITY,
        after: None,
    };
    let mut buf = KBuffer::unbounded();
    buf.shade_on_insert = true;
    let mut cull = f32::INFINITY;
    let g = blas.group.get(run, t);
    tracer.test_triangle(0, 0, &r, verts, g, t as u32, false, &q, &mut buf, &mut cull);
    buf.hits.first().map(|h| h.payload)
}

#[test]
fn both_windings_give_the_same_hit() {
    let (mut hits, mut zero) = (0, 0);
    for seed in [1u64, 2] {
        let tracer = MeshTracer::new(scene(seed), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
        let mut draw = crate::test_rng::unit(seed ^ 0x77);
        let mesh = &tracer.scene.meshes[0];
        for pair in 0..mesh.tris.len() / 2 {
            let (t, u) = (2 * pair, 2 * pair + 1);
            let p = mesh.tris[t].map(|i| mesh.positions[i as usize].as_dvec3());
            for k in 0..12 {
                // Points inside, on the edges and at the vertices, from the origin and from an
                // oblique origin.
                let (mut b0, mut b1) = (draw(), draw());
                if b0 + b1 > 1.0 {
                    (b0, b1) = (1.0 - b0, 1.0 - b1);
                }
                match k % 4 {
                    0 => b1 = 0.0,
                    1 => (b0, b1) = (1.0, 0.0),
                    _ => {}
                }
                let target = p[0] * b0 + p[1] * b1 + p[2] * (1.0 - b0 - b1);
                let o = if k % 2 == 0 {
                    DVec3::ZERO
                } else {
                    DVec3::new(5.0, -3.0, -1.0)
                };
                let d = (target - o).normalize();
                let (a, b) = (hit(&tracer, t, o, d), hit(&tracer, u, o, d));
                // The watertight test reports a ray to one winding exactly when to the other.
                assert_eq!(a.is_some(), b.is_some(), "pair {pair}, ray {k}");
                let (Some(a), Some(b)) = (a, b) else {
                    // No hit, or a hit of α = 0 in both (nothing inserted).
                    zero += 1;
                    continue;
                };
                hits += 1;
                // `[a, b, c]` against `[a, c, b]`: the last two weights swap.
                let (ba, bb) = (a.bary.map(f32::to_bits), b.bary.map(f32::to_bits));
                assert_eq!(
                    [ba[0], ba[1], ba[2]],
                    [bb[0], bb[2], bb[1]],
                    "pair {pair}, ray {k}"
                );
                assert_eq!(
                    a.rgba.to_array().map(f32::to_bits),
                    b.rgba.to_array().map(f32::to_bits),
                    "pair {pair}, ray {k}"
                );
            }
        }
    }
    // Most rays hit with α > 0; some find α = 0 texels or miss past a vertex.
    assert!(hits > 3000 && zero > 100, "{hits} hits, {zero} without");
}
