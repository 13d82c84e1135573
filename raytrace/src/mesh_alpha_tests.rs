//! Hits of zero α on textured triangles (the texture profile's corners, outside the falloff's
//! disc), which settle their other winding without its test (`mesh_hit`,
//! `MeshTracer::zero_alpha_settles`): the texture's zero blocks are conservative (every
//! coordinate within a texel of one samples alpha 0, checked by sampling), and textured quads
//! in both windings trace to the brute-force reference's hits and images bit for bit, with
//! the settling taken.

use glam::{DVec3, Vec2, Vec3, Vec4};

use super::footprint::sample_offsets;
use super::mesh_bin::TileLists;
use super::mesh_tile_tests::{assert_image_is_reference, check_every_sample, tracer, Rng};
use super::model::{AlphaMode, Material, Mesh, Node, TriScene};
use super::texture::{Texture, Wrap};
use splatbridge_scene::Camera;

/// Edge of the test textures, in texels.
const SIZE: u32 = 64;

/// A radial falloff like the texture profile's (RGB white, alpha `exp(−r²/2)` out to the
/// 1/255 radius, zero beyond), with a few isolated zero texels inside the disc so that blocks
/// next to them are not all zero.
fn falloff_bytes() -> Vec<[u8; 4]> {
    let r_edge = (2.0 * 255f64.ln()).sqrt();
    (0..SIZE * SIZE)
        .map(|i| {
            let (x, y) = (i % SIZE, i / SIZE);
            let u = (x as f64 + 0.5) / SIZE as f64;
            let v = (y as f64 + 0.5) / SIZE as f64;
            let (dx, dy) = ((2.0 * u - 1.0) * r_edge, (2.0 * v - 1.0) * r_edge);
            let r2 = dx * dx + dy * dy;
            let a = if r2 > r_edge * r_edge || (x * 7 + y * 3) % 97 == 0 {
                0
            } else {
                ((-0.5 * r2).exp() * 255.0).round() as u8
            };
            [255, 255, 255, a]
        })
        .collect()
}

#[test]
fn zero_blocks_are_conservative() {
    let bytes = falloff_bytes();
    let floats: Vec<Vec4> = bytes
        .iter()
        .map(|b| Vec4::new(1.0, 1.0, 1.0, b[3] as f32 / 255.0))
        .collect();
    let mut r = Rng(11);
    let mut zero = 0usize;
    for (k, nearest) in [(0, false), (1, false), (2, true)] {
        for wrap in [Wrap::Clamp, Wrap::Repeat, Wrap::Mirror] {
            let tex = if k == 1 {
                Texture::from_texels(SIZE, SIZE, floats.clone(), [wrap; 2], nearest)
            } else {
                Texture::from_bytes(SIZE, SIZE, bytes.clone(), [wrap; 2], nearest)
            };
            for _ in 0..4000 {
                let uv = Vec2::new(r.range(-0.1, 1.1), r.range(-0.1, 1.1));
                if !tex.alpha_zero_near(uv) {
                    continue;
                }
                zero += 1;
                // Offsets of up to 0.999 texel along each axis, both ways.
                for i in -4..=4 {
                    for j in -4..=4 {
                        let d = Vec2::new(i as f32, j as f32) * (0.999 / 4.0 / SIZE as f32);
                        let a = tex.sample(uv + d).w;
                        assert_eq!(a, 0.0, "{uv:?} + {d:?}: alpha {a} (wrap {wrap:?})");
                    }
                }
            }
        }
    }
    // The disc leaves its corners zero, less the rims the blocks need, the border, the
    // isolated zero texels' neighbours and the coordinates outside the image (measured:
    // 2,285 of 36,000 coordinates in zero blocks).
    assert!(zero > 1000, "{zero} coordinates in zero blocks");
}

/// Textured quads (two triangles, the texture profile's layout) in both windings, their UVs
/// over the whole texture, at random places and angles; every fourth opaque. The second
/// winding's material is `mirror_material`: 0, the textured one, or 1, untextured. Each
/// Gaussian's quad `stack` times over, in one plane, the copies' UVs shifted so that a point
/// outside one copy's disc lies inside another's (one group of `2·stack` triangles a winding:
/// a group record from five copies on, `mesh_groups`).
fn textured_scene(seed: u64, mirror_material: u32, stack: u32) -> TriScene {
    let mut r = Rng(seed);
    let mut m = Mesh {
        has_gaussian_ids: true,
        uvs: Some(Vec::new()),
        ..Mesh::default()
    };
    for g in 0..120u32 {
        let c = Vec3::new(r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0));
        let q = r.rotation();
        let (a0, a1) = (
            q * Vec3::X * r.range(0.05, 0.4),
            q * Vec3::Y * r.range(0.05, 0.4),
        );
        let alpha = if g % 4 == 0 { 1.0 } else { r.range(0.2, 1.0) };
        let rgba = Vec4::new(r.f(), r.f(), r.f(), alpha);
        for k in 0..stack {
            let shift = Vec2::new(0.31, -0.17) * k as f32;
            let base = m.positions.len() as u32;
            for (du, dv) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                m.positions
                    .push(c + a0 * (2.0 * du - 1.0) + a1 * (2.0 * dv - 1.0));
                m.colors.push(rgba);
                m.uvs.as_mut().unwrap().push(Vec2::new(du, dv) + shift);
            }
            for t in [[0, 1, 2], [0, 2, 1], [0, 2, 3], [0, 3, 2]] {
                m.tris.push(t.map(|i| base + i));
                m.tri_gaussian.push(g);
            }
        }
    }
    m.tri_material = (0..m.tris.len() as u32)
        .map(|t| if t % 2 == 1 { mirror_material } else { 0 })
        .collect::<Vec<u32>>()
        .into();
    let tex = Texture::from_bytes(SIZE, SIZE, falloff_bytes(), [Wrap::Clamp; 2], false);
    TriScene {
        meshes: vec![m],
        materials: vec![
            Material {
                base_color: Vec4::ONE,
                texture: Some(0),
                alpha_mode: AlphaMode::Blend,
            },
            Material {
                base_color: Vec4::ONE,
                texture: None,
                alpha_mode: AlphaMode::Blend,
            },
        ],
        textures: vec![tex],
        nodes: vec![
            Node {
                mesh: Some(0),
                ..Node::default()
            },
            Node {
                mesh: Some(0),
                translation: DVec3::new(0.3, -0.2, 0.6),
                ..Node::default()
            },
            Node {
                mesh: Some(0),
                translation: DVec3::new(-0.4, 0.1, 1.1),
                ..Node::default()
            },
        ],
        colors_linear: true,
        ..TriScene::default()
    }
}

/// A camera before `textured_scene`'s quads, 45×35 pixels.
fn quads_camera() -> Camera {
    Camera::look_at(
        DVec3::new(0.3, -0.5, -4.0),
        DVec3::ZERO,
        DVec3::NEG_Y,
        50.0,
        45,
        35,
    )
    .unwrap()
}

/// Both windings textured (their corners settle the other winding), and the second winding
/// untextured (where the first's corner has α = 0 and the second's does not: not a pair, each
/// tested on its own; settling it would lose the second's hit); and five coplanar copies of
/// each quad with shifted UVs, one group record (`mesh_groups`), where one copy's α = 0
/// settles its own other winding and not the copies that draw the point.
#[test]
fn textured_quads_equal_brute_force_with_zero_alpha_settled() {
    let cam = quads_camera();
    let mut hits = 0usize;
    for (seed, mirror_material, stack) in [(1u64, 0, 1), (2, 0, 1), (3, 1, 1), (4, 0, 5)] {
        let tracer = tracer(textured_scene(seed, mirror_material, stack));
        let insts = tracer.prepare_list(0.0);
        let lists = TileLists::build(&tracer, &insts, &cam, &sample_offsets(1));
        hits += check_every_sample(&tracer, &insts, &lists, &cam, 1);
        for spp in [1, 4] {
            assert_image_is_reference(&tracer, &cam, spp, &format!("seed {seed}"));
        }
    }
    assert!(hits > 1000, "{hits} hits compared");
}

/// A ray through a quad's corner, outside the falloff's disc, settles the other winding
/// (`Tested::Settled`, nothing inserted); through its middle it is inserted; with a texture
/// whose alpha is nowhere zero the corner's hit is inserted too.
#[test]
fn a_corner_outside_the_disc_settles_its_other_winding() {
    use super::kbuffer::KBuffer;
    use super::mesh_hit::{Query, Tested};
    use super::mesh_tiles::local_ray;

    // The point of triangle 0 at `s` of the way from its uv-(0, 0) vertex to the quad's
    // centre (the middle of the diagonal to its uv-(1, 1) vertex), moved `off` of the way
    // towards its third vertex, off the shared diagonal; and the triangle's normal.
    let point = |t: &super::mesh_tracer::MeshTracer, s: f32, off: f32| {
        let m = &t.scene.meshes[0];
        let uvs = m.uvs.as_ref().unwrap();
        let tri = m.tris[0].map(|i| i as usize);
        let find = |uv: Vec2| *tri.iter().find(|&&i| uvs[i] == uv).unwrap();
        let (a, c) = (find(Vec2::ZERO), find(Vec2::ONE));
        let b = *tri.iter().find(|&&i| i != a && i != c).unwrap();
        let [pa, pb, pc] = [a, b, c].map(|i| m.positions[i]);
        let at = pa + ((pa + pc) / 2.0 - pa) * s + (pb - pa) * off;
        (at, (pb - pa).cross(pc - pa).normalize())
    };
    let shoot = |t: &super::mesh_tracer::MeshTracer, s: f32, off: f32| {
        let (at, n) = point(t, s, off);
        let target = at.as_dvec3();
        let o = target + n.as_dvec3() * 3.0;
        let d = (target - o).normalize();
        let insts = t.prepare_list(0.0);
        let r = local_ray(t, &insts[0], o, d).unwrap();
        let (blas, m) = (&t.blas[0], &t.scene.meshes[0]);
        let mut buf = KBuffer::unbounded();
        buf.shade_on_insert = true;
        let q = Query {
            tmin: 0.0,
            tmax: f32::INFINITY,
            after: None,
        };
        let (g, v) = (blas.group.get(0, 0), blas.triangle(&m.positions, m.tris[0]));
        let mut cull = f32::INFINITY;
        let tested = t.test_triangle(0, 0, &r, v, g, 0, false, &q, &mut buf, &mut cull);
        (tested, buf.hits.len())
    };
    let mut scene = textured_scene(3, 0, 1);
    scene.nodes.truncate(1);
    let one = |scene: TriScene| {
        super::mesh_tracer::MeshTracer::new(
            scene,
            crate::backend::BackendKind::Obvhs,
            crate::backend::BuildPreset::Medium,
        )
        .unwrap()
    };
    let t = one(scene.clone());
    // uv ≈ (0.06, 0.03): outside the disc, in a zero block (texel 3.3, 1.4 of 64).
    assert_eq!(shoot(&t, 0.06, 0.03), (Tested::Settled, 0));
    // uv ≈ (0.35, 0.3): inside the disc.
    assert_eq!(shoot(&t, 0.6, 0.05).1, 1);
    // No zero alpha anywhere: the corner is drawn, faintly, and decides nothing.
    let floor = falloff_bytes()
        .into_iter()
        .map(|[r, g, b, a]| [r, g, b, a.max(1)])
        .collect();
    scene.textures[0] = Texture::from_bytes(SIZE, SIZE, floor, [Wrap::Clamp; 2], false);
    let t = one(scene);
    assert_eq!(shoot(&t, 0.06, 0.03).1, 1);
}

/// `Mesh::shade_alpha` (hit recording's shading) against `Mesh::shade`: the same α bit for
/// bit, and a factor that is the base colour's α times the texture's at the point, for every
/// alpha mode, without a material, with and without a texture, at random points and at the
/// texture's edges.
#[test]
fn recording_alpha_is_the_shaded_alpha() {
    let mut scene = textured_scene(5, 1, 1);
    scene.materials[0].base_color.w = 0.7;
    scene.materials[1].base_color.w = 1.3;
    scene.materials.push(Material {
        base_color: Vec4::new(1.0, 1.0, 1.0, 0.6),
        texture: Some(0),
        alpha_mode: AlphaMode::Mask(0.25),
    });
    scene.materials.push(Material {
        alpha_mode: AlphaMode::Opaque,
        ..scene.materials[0].clone()
    });
    let mut r = Rng(9);
    let m = &scene.meshes[0];
    let mut checked = 0;
    // Material 4 does not exist: the default (white, opaque).
    for mat in 0..5u32 {
        let mut mesh = m.clone();
        mesh.tri_material = vec![mat; mesh.tris.len()].into();
        for t in 0..mesh.tris.len() {
            for k in 0..6 {
                let bary = match k {
                    0 => [1.0, 0.0, 0.0],
                    1 => [0.0, 0.5, 0.5],
                    _ => {
                        let (a, b) = (r.f(), r.f());
                        let (a, b) = if a + b > 1.0 {
                            (1.0 - a, 1.0 - b)
                        } else {
                            (a, b)
                        };
                        [1.0 - a - b, a, b]
                    }
                };
                let (mats, texs) = (&scene.materials, &scene.textures);
                let (a, factor) = mesh.shade_alpha(t, bary, mats, texs);
                let want = mesh.shade(t, bary, mats, texs).w;
                assert_eq!(a.to_bits(), want.to_bits(), "material {mat}, {t}, {bary:?}");
                let want_factor = match mats.get(mat as usize) {
                    None => 1.0,
                    Some(x) => {
                        let tex = x.texture.map_or(1.0, |i| {
                            let [i0, i1, i2] = mesh.tris[t].map(|v| v as usize);
                            let uvs = mesh.uvs.as_ref().unwrap();
                            let uv = uvs[i0] * bary[0] + uvs[i1] * bary[1] + uvs[i2] * bary[2];
                            texs[i].sample(uv).w
                        });
                        x.base_color.w * tex
                    }
                };
                assert_eq!(
                    factor.to_bits(),
                    want_factor.to_bits(),
                    "material {mat}, {t}"
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 10_000, "{checked}");
}

/// Recorded hits (through the tiles and ray by ray) carry `shade_alpha`'s factor of their own
/// triangle and barycentrics (their α is `shade`'s, checked above, so the lists are those a
/// full shading records).
#[test]
fn recorded_hits_carry_their_alpha_factor() {
    let cam = quads_camera();
    let mut scene = textured_scene(6, 1, 1);
    scene.materials[0].base_color.w = 0.8;
    let tracer = tracer(scene);
    let mut textured = 0;
    for lists in [
        tracer.record_hits(&cam, 0.0, 16, 1e-4).unwrap(),
        tracer.record_hits_per_ray(&cam, 0.0, 16, 1e-4).unwrap(),
    ] {
        assert!(lists.hits.len() > 500, "{} hits", lists.hits.len());
        for h in &lists.hits {
            let m = &tracer.scene.meshes[h.mesh as usize];
            let (mats, texs) = (&tracer.scene.materials, &tracer.scene.textures);
            let (_, factor) = m.shade_alpha(h.tri as usize, h.bary, mats, texs);
            assert_eq!(h.alpha_factor.to_bits(), factor.to_bits());
            textured += (factor != 0.8 && factor != 1.0) as usize;
        }
    }
    // The factor is the texture's at the hit, not only the material's.
    assert!(textured > 100, "{textured}");
}
