//! The tile path of mode `mesh` ([`super::mesh_tiles`]) against the brute-force reference
//! (every triangle of every instance tested, no BVH, no binning, no cull; hits sorted by their
//! full key with the lowest triangle kept among equal keys; cut where compositing stops): the
//! same hits, bit for bit, for every sample of every pixel, and images bit for bit equal, on
//! scenes with exact ties (fans repeated at one place, both windings of every triangle as the
//! viewer layout writes them), instanced meshes under static transforms with scales, triangles
//! reaching behind the camera and around it, a scene far from the origin, images whose sides
//! are not multiples of a tile, at 1 and 4 samples a pixel; equal at 1, 2 and 3 threads; and
//! the per-ray BVH path within the tie rule of its k-buffer. Grids whose vertices project onto
//! pixel centres, in the viewer layout's order of windings, put rays through vertices and shared
//! edges, where the screen-space pre-test and the winding pairs (`mesh_cands`) are decided.

use glam::{DAffine3, DQuat, DVec3, Quat, Vec3, Vec4};
use splatbridge_scene::{Camera, Frame};

use super::footprint::sample_offsets;
use super::kbuffer::KBuffer;
use super::mesh_bin::TileLists;
use super::mesh_hit::{Compositor, Query};
use super::mesh_tiles::{local_ray, TileCtx, TILE};
use super::mesh_tracer::{MeshHit, MeshTracer, PreparedInstance};
use super::model::{AlphaMode, Material, Mesh, Node, TriScene};
use super::render::{camera_ray, RenderOptions};
use crate::backend::{BackendKind, BuildPreset};

/// SplitMix64.
pub(crate) struct Rng(pub(crate) u64);
impl Rng {
    pub(crate) fn f(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
    pub(crate) fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.f()
    }
    /// A point in the box of half-size `extent` around `offset`.
    pub(crate) fn point(&mut self, offset: Vec3, extent: f32) -> Vec3 {
        offset
            + Vec3::new(
                self.range(-extent, extent),
                self.range(-extent, extent),
                self.range(-extent, extent),
            )
    }
    /// A random rotation (a normalised quaternion of random components).
    pub(crate) fn rotation(&mut self) -> Quat {
        Quat::from_xyzw(
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
        )
        .normalize()
    }
}

/// A fan of `n` triangles (`gid`'s; α `rgba.w` at the centre, `rim·rgba.w` at the rim), and,
/// with `both`, each triangle again with the other winding right after it (the viewer layout).
#[allow(clippy::too_many_arguments)]
fn fan(
    m: &mut Mesh,
    gid: u32,
    c: Vec3,
    a0: Vec3,
    a1: Vec3,
    n: usize,
    rgba: Vec4,
    rim: f32,
    both: bool,
) {
    let base = m.positions.len() as u32;
    m.positions.push(c);
    m.colors.push(rgba);
    for k in 0..n {
        let th = std::f32::consts::TAU * k as f32 / n as f32;
        m.positions.push(c + a0 * th.cos() + a1 * th.sin());
        m.colors.push(rgba * Vec4::new(1.0, 1.0, 1.0, rim));
    }
    for k in 0..n as u32 {
        let (b, c) = (base + 1 + k, base + 1 + (k + 1) % n as u32);
        let mut push = |t: [u32; 3]| {
            m.tris.push(t);
            m.tri_material.push(0);
            m.tri_gaussian.push(gid);
        };
        push([base, b, c]);
        if both {
            push([base, c, b]);
        }
    }
}

/// An empty mesh whose triangles name their Gaussians.
pub(crate) fn ided_mesh() -> Mesh {
    Mesh {
        has_gaussian_ids: true,
        ..Mesh::default()
    }
}

/// `n` random fans in a box of half-size `extent` around `offset`: every seventh repeated
/// exactly (equal keys), every fifth fully transparent, every third opaque (so rays stop, and
/// the walk's early exit is exercised), some large (across the camera of [`cameras`]), with
/// both windings when `both`.
pub(crate) fn random_mesh(seed: u64, n: usize, extent: f32, offset: Vec3, both: bool) -> Mesh {
    let mut r = Rng(seed);
    let mut m = ided_mesh();
    for g in 0..n {
        let c = r.point(offset, extent);
        let q = r.rotation();
        let big = if g % 53 == 0 { 6.0 } else { 1.0 };
        let s = Vec3::new(r.range(0.05, 0.4), r.range(0.05, 0.4), 1.0) * extent * 0.4 * big;
        let mut rgba = Vec4::new(r.f(), r.f(), r.f(), r.range(0.1, 1.0));
        let mut rim = 0.3;
        if g % 5 == 0 {
            rgba.w = 0.0;
        } else if g % 3 == 0 {
            (rgba.w, rim) = (1.0, 1.0);
        }
        let gid = (g as u32 * 7919) % 1009;
        let copies = if g % 7 == 0 { 2 } else { 1 };
        for _ in 0..copies {
            fan(
                &mut m,
                gid,
                c,
                q * Vec3::X * s.x,
                q * Vec3::Y * s.y,
                6,
                rgba,
                rim,
                both,
            );
        }
    }
    m
}

pub(crate) fn blend() -> Vec<Material> {
    vec![Material {
        base_color: Vec4::ONE,
        texture: None,
        alpha_mode: AlphaMode::Blend,
    }]
}

/// Two meshes, four static nodes (the first mesh twice, one node rotated and scaled, one under
/// a scaled parent), around `offset`.
pub(crate) fn scene(seed: u64, offset: Vec3, both: bool) -> TriScene {
    let a = random_mesh(seed, 160, 1.0, offset, both);
    let b = random_mesh(seed ^ 0xABCD, 90, 0.5, offset, both);
    nodes_over(a, b, seed.is_multiple_of(2))
}

/// The meshes `a` and `b` under four static nodes (`a` twice, `b` rotated and scaled, one
/// under a scaled parent), blended, with linear vertex colours when `linear`.
pub(crate) fn nodes_over(a: Mesh, b: Mesh, linear: bool) -> TriScene {
    TriScene {
        meshes: vec![a, b],
        materials: blend(),
        nodes: vec![
            Node {
                mesh: Some(0),
                ..Node::default()
            },
            Node {
                mesh: Some(1),
                translation: DVec3::new(0.3, -0.2, 0.4),
                rotation: DQuat::from_rotation_y(0.7),
                scale: DVec3::new(1.0, 1.5, 0.8),
                ..Node::default()
            },
            Node {
                mesh: Some(0),
                parent: Some(3),
                translation: DVec3::new(-0.5, 0.2, 1.0),
                ..Node::default()
            },
            Node {
                scale: DVec3::splat(0.5),
                ..Node::default()
            },
        ],
        colors_linear: linear,
        ..TriScene::default()
    }
}

/// A camera outside the scene and one inside it (triangles reach behind it and around it),
/// at sizes that are not multiples of a tile.
pub(crate) fn cameras(offset: DVec3) -> Vec<Camera> {
    vec![
        Camera::look_at(
            offset + DVec3::new(0.4, -0.6, -4.0),
            offset,
            DVec3::NEG_Y,
            50.0,
            37,
            29,
        )
        .unwrap(),
        Camera::look_at(
            offset + DVec3::new(0.1, 0.05, -0.2),
            offset + DVec3::new(0.0, 0.0, 1.0),
            DVec3::NEG_Y,
            70.0,
            33,
            18,
        )
        .unwrap(),
    ]
}

/// The reference hits of one ray: every triangle of every instance through the per-candidate
/// test into a buffer with neither a capacity nor a stop, then cut after the hit where
/// compositing's transmittance falls below `min_t`.
pub(crate) fn reference(
    tracer: &MeshTracer,
    time: f64,
    o: DVec3,
    d: DVec3,
    min_t: f32,
) -> Vec<MeshHit> {
    let insts = tracer.prepare_list(time);
    let mut buf = KBuffer::unbounded();
    buf.shade_on_insert = true;
    let q = Query {
        tmin: 0.0,
        tmax: f32::INFINITY,
        after: None,
    };
    for (ii, inst) in insts.iter().enumerate() {
        let Some(r) = local_ray(tracer, inst, o, d) else {
            continue;
        };
        let blas = &tracer.blas[inst.mesh];
        let mesh = &tracer.scene.meshes[inst.mesh];
        for p in 0..blas.run_start.len() - 1 {
            for t in blas.run_start[p] as usize..blas.run_start[p + 1] as usize {
                let v = blas.triangle(&mesh.positions, mesh.tris[t]);
                let mut cull = f32::INFINITY;
                let g = blas.group.get(p, t);
                tracer.test_triangle(
                    ii, inst.mesh, &r, v, g, t as u32, false, &q, &mut buf, &mut cull,
                );
            }
        }
    }
    let mut tr = 1.0f32;
    let mut out = Vec::new();
    for h in &buf.hits {
        out.push(*h);
        tr *= 1.0 - h.payload.rgba.w;
        if tr < min_t {
            break;
        }
    }
    out
}

/// Trace sample `uv` through the tile path (stop at transmittance 1e-4) and require its hits
/// to be the reference's (stopped at `min_t`) bit for bit, as far as the reference goes;
/// returns the reference's hits.
pub(crate) fn check_sample(
    tracer: &MeshTracer,
    insts: &[PreparedInstance],
    ctx: &mut TileCtx,
    cam: &Camera,
    uv: (f64, f64),
    min_t: f32,
) -> Vec<MeshHit> {
    let (i, j) = (uv.0 as u32, uv.1 as u32);
    let (o, d) = camera_ray(cam, uv.0, uv.1);
    let want = reference(tracer, 0.0, o, d, min_t);
    tracer.tile_hits(insts, ctx, o, d, uv, 1e-4);
    let got = &ctx.buffer().hits;
    assert!(got.len() >= want.len(), "pixel ({i}, {j}) lost hits");
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(hit_bits(g), hit_bits(w), "pixel ({i}, {j})");
    }
    want
}

/// [`check_sample`] at every sample of every pixel of `cam` through `lists` (binned for
/// `spp` samples a pixel: the pixel centre at 1); returns the reference hits compared.
pub(crate) fn check_every_sample(
    tracer: &MeshTracer,
    insts: &[PreparedInstance],
    lists: &TileLists,
    cam: &Camera,
    spp: u32,
) -> usize {
    let min_t = RenderOptions::default().min_transmittance;
    let offsets = sample_offsets(spp);
    let mut compared = 0;
    for ty in 0..cam.height.div_ceil(TILE) {
        for tx in 0..cam.width.div_ceil(TILE) {
            let mut ctx = TileCtx::new(lists, tx, ty, insts.len());
            for j in ty * TILE..((ty + 1) * TILE).min(cam.height) {
                for i in tx * TILE..((tx + 1) * TILE).min(cam.width) {
                    for &(du, dv) in &offsets {
                        let (du, dv) = if spp == 1 { (0.5, 0.5) } else { (du, dv) };
                        let uv = (i as f64 + du, j as f64 + dv);
                        compared += check_sample(tracer, insts, &mut ctx, cam, uv, min_t).len();
                    }
                }
            }
        }
    }
    compared
}

/// Hits as bits (distance, key, triangle, barycentrics, colour).
pub(crate) fn hit_bits(h: &MeshHit) -> Vec<u32> {
    let mut v = vec![
        h.t.to_bits(),
        h.gaussian,
        h.instance,
        h.group,
        h.payload.tri,
    ];
    v.extend(h.payload.bary.map(f32::to_bits));
    v.extend(h.payload.rgba.to_array().map(f32::to_bits));
    v
}

pub(crate) fn bits(f: &Frame) -> Vec<u32> {
    f.rgb
        .iter()
        .chain(&f.alpha)
        .chain(&f.depth)
        .map(|v| v.to_bits())
        .collect()
}

/// The image from the reference hits (the compositing of `MeshTracer::trace`).
pub(crate) fn reference_image(tracer: &MeshTracer, cam: &Camera, opts: &RenderOptions) -> Frame {
    crate::render::render_frame_spp(cam, opts.spp, |o, d| {
        let mut comp = Compositor::new(opts, tracer.scene.colors_linear);
        for h in reference(tracer, 0.0, o, d, opts.min_transmittance) {
            if comp.add(&h) {
                break;
            }
        }
        comp.finish()
    })
    .unwrap()
    .0
}

/// The image of `cam` at `spp` samples a pixel (other options at their defaults) equals the
/// brute-force reference's, bit for bit (`what` names the case).
pub(crate) fn assert_image_is_reference(tracer: &MeshTracer, cam: &Camera, spp: u32, what: &str) {
    let opts = RenderOptions {
        spp,
        ..RenderOptions::default()
    };
    let (got, _) = tracer.render(cam, 0.0, &opts).unwrap();
    assert_eq!(
        bits(&got),
        bits(&reference_image(tracer, cam, &opts)),
        "{what}, {spp} spp"
    );
}

pub(crate) fn tracer(scene: TriScene) -> MeshTracer {
    let t = MeshTracer::new(scene, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    assert!(t.tiles_pay(0.0, 1));
    t
}

#[test]
fn tile_hits_equal_brute_force() {
    let opts = RenderOptions::default();
    let (mut compared, mut stopped) = (0usize, 0usize);
    for (seed, both) in [(1u64, true), (2, false), (3, true), (8, true)] {
        let tracer = tracer(scene(seed, Vec3::ZERO, both));
        let insts = tracer.prepare_list(0.0);
        for cam in cameras(DVec3::ZERO) {
            for spp in [1, 4] {
                let offsets = sample_offsets(spp);
                let lists = TileLists::build(&tracer, &insts, &cam, &offsets);
                for ty in 0..cam.height.div_ceil(TILE) {
                    for tx in 0..cam.width.div_ceil(TILE) {
                        let mut ctx = TileCtx::new(&lists, tx, ty, insts.len());
                        for j in ty * TILE..((ty + 1) * TILE).min(cam.height) {
                            for i in tx * TILE..((tx + 1) * TILE).min(cam.width) {
                                for &(du, dv) in &offsets {
                                    let (du, dv) = if spp == 1 { (0.5, 0.5) } else { (du, dv) };
                                    let uv = (i as f64 + du, j as f64 + dv);
                                    let want = check_sample(
                                        &tracer,
                                        &insts,
                                        &mut ctx,
                                        &cam,
                                        uv,
                                        opts.min_transmittance,
                                    );
                                    compared += want.len();
                                    let opaque = want
                                        .iter()
                                        .fold(1.0f32, |tr, h| tr * (1.0 - h.payload.rgba.w))
                                        < opts.min_transmittance;
                                    stopped += opaque as usize;
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    // The scenes are not empty to the rays: thousands of hits were compared.
    assert!(compared > 5000, "{compared} hits compared");
    // Many rays stop at an opaque hit, so the walk's early exit decides their hits.
    assert!(stopped > 2000, "{stopped} rays stopped");
}

#[test]
fn tile_images_equal_brute_force_far_from_origin() {
    for (seed, offset) in [(3u64, Vec3::ZERO), (4, Vec3::new(1e4, -2e4, 3e4))] {
        let tracer = tracer(scene(seed, offset, true));
        for cam in cameras(offset.as_dvec3()) {
            for spp in [1, 4] {
                for k in [1, 16] {
                    let opts = RenderOptions {
                        k,
                        spp,
                        ..RenderOptions::default()
                    };
                    let (got, _) = tracer.render(&cam, 0.0, &opts).unwrap();
                    let want = reference_image(&tracer, &cam, &opts);
                    assert!(got.alpha.iter().any(|&a| a > 0.5), "nothing drawn");
                    assert_eq!(bits(&got), bits(&want), "seed {seed}, spp {spp}");
                }
            }
        }
    }
}

#[test]
fn tile_images_match_per_ray_path() {
    // The per-ray path keeps, for the k-th key of a full buffer, the triangle it found first;
    // its barycentrics are those of another triangle of the fan (or the other winding), which
    // moves the interpolated colour by an ulp or two: 1e-6 is a few f32 ulps of a colour ≤ 1.
    let tracer = tracer(scene(5, Vec3::ZERO, true));
    for cam in cameras(DVec3::ZERO) {
        for k in [1, 4, 16] {
            let opts = RenderOptions {
                k,
                ..RenderOptions::default()
            };
            let (a, _) = tracer.render(&cam, 0.0, &opts).unwrap();
            let (b, _) = tracer.render_per_ray(&cam, 0.0, &opts).unwrap();
            let worst = worst_difference(&a, &b);
            assert!(worst <= 1e-6, "k = {k}: {worst}");
        }
    }
}

/// The largest difference between two images of one size, over colour and alpha.
pub(crate) fn worst_difference(a: &Frame, b: &Frame) -> f32 {
    a.rgb
        .iter()
        .zip(&b.rgb)
        .chain(a.alpha.iter().zip(&b.alpha))
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max)
}

#[test]
fn tile_render_does_not_depend_on_threads() {
    let tracer = tracer(scene(6, Vec3::ZERO, true));
    let cam = &cameras(DVec3::ZERO)[0];
    let opts = RenderOptions::default();
    let images: Vec<Vec<u32>> = [1, 2, 3]
        .iter()
        .map(|&n| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap();
            pool.install(|| bits(&tracer.render(cam, 0.0, &opts).unwrap().0))
        })
        .collect();
    assert_eq!(images[0], images[1]);
    assert_eq!(images[0], images[2]);
}

#[test]
fn skewed_instance_matches_reference() {
    // A node transform that stretches one axis fifteen times another, under a rotation: the
    // bounds, margins and list keys follow the instance's transform.
    let mut s = scene(7, Vec3::ZERO, false);
    s.nodes[1].matrix = Some(DAffine3::from_scale_rotation_translation(
        DVec3::new(0.2, 3.0, 1.0),
        DQuat::from_rotation_x(0.3),
        DVec3::new(0.1, 0.0, 0.2),
    ));
    let tracer = tracer(s);
    let cam = &cameras(DVec3::ZERO)[0];
    let opts = RenderOptions::default();
    let (got, _) = tracer.render(cam, 0.0, &opts).unwrap();
    assert_eq!(bits(&got), bits(&reference_image(&tracer, cam, &opts)));
}

/// A grid of quads (two triangles over a shared diagonal) whose vertices project onto pixel
/// centres and whose edges run along pixel rows, columns and diagonals, in the viewer layout's
/// order (every triangle, then every triangle again in the other winding, in reverse order):
/// rays through vertices and shared edges, where the pre-test's margin and the winding pairs'
/// rule meet the exact test's edge cases. Colours reach α = 0 at some vertices, so hits on
/// those edges shade to 0 and the other winding is tested itself.
fn pixel_grid(cam: &Camera, depth: f64, step: u32, gid0: u32, alpha0: bool) -> Mesh {
    let mut m = Mesh {
        has_gaussian_ids: true,
        ..Mesh::default()
    };
    let (nx, ny) = (cam.width.div_ceil(step) + 1, cam.height.div_ceil(step) + 1);
    for j in 0..ny {
        for i in 0..nx {
            let (u, v) = ((i * step) as f64 + 0.5, (j * step) as f64 + 0.5);
            let d = cam.ray_dir(u, v);
            let p = cam.centre + d * (depth / d.dot(cam.ray_dir(cam.cx, cam.cy)));
            m.positions.push(p.as_vec3());
            let a = if alpha0 && (i + j) % 3 == 0 {
                0.0
            } else {
                0.45
            };
            m.colors.push(Vec4::new(
                i as f32 / nx as f32,
                j as f32 / ny as f32,
                0.5,
                a,
            ));
        }
    }
    let mut first = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let k = j * nx + i;
            let (a, b, c, d) = (k, k + 1, k + nx + 1, k + nx);
            // Alternate diagonals, so edges run both ways.
            let quad = if (i + j) % 2 == 0 {
                [[a, b, c], [a, c, d]]
            } else {
                [[a, b, d], [b, c, d]]
            };
            let gid = gid0 + j * nx + i;
            first.extend(quad.map(|t| (t, gid)));
        }
    }
    let second: Vec<_> = first
        .iter()
        .rev()
        .map(|&([a, b, c], g)| ([a, c, b], g))
        .collect();
    for (t, g) in first.into_iter().chain(second) {
        m.tris.push(t);
        m.tri_material.push(0);
        m.tri_gaussian.push(g);
    }
    m
}

#[test]
fn pixel_aligned_grids_equal_brute_force() {
    let cam = Camera::look_at(
        DVec3::new(0.3, -0.2, -3.0),
        DVec3::new(0.3, -0.2, 0.0),
        DVec3::NEG_Y,
        45.0,
        41,
        23,
    )
    .unwrap();
    // Three grids at three depths (steps of 2, 3 and 5 pixels, two with α = 0 vertices), each
    // its own node, and a random fan mesh through them.
    let mut meshes = vec![
        pixel_grid(&cam, 1.0, 2, 0, true),
        pixel_grid(&cam, 1.5, 3, 5000, false),
        pixel_grid(&cam, 2.0, 5, 9000, true),
    ];
    meshes.push(random_mesh(11, 60, 0.6, Vec3::new(0.3, -0.2, -1.5), true));
    let nodes = (0..meshes.len())
        .map(|i| Node {
            mesh: Some(i),
            ..Node::default()
        })
        .collect();
    let tracer = tracer(TriScene {
        meshes,
        materials: blend(),
        nodes,
        ..TriScene::default()
    });
    let insts = tracer.prepare_list(0.0);
    let lists = TileLists::build(&tracer, &insts, &cam, &sample_offsets(1));
    let mut compared = 0usize;
    for ty in 0..cam.height.div_ceil(TILE) {
        for tx in 0..cam.width.div_ceil(TILE) {
            let mut ctx = TileCtx::new(&lists, tx, ty, insts.len());
            for j in ty * TILE..((ty + 1) * TILE).min(cam.height) {
                for i in tx * TILE..((tx + 1) * TILE).min(cam.width) {
                    let uv = (i as f64 + 0.5, j as f64 + 0.5);
                    compared += check_sample(&tracer, &insts, &mut ctx, &cam, uv, 1e-4).len();
                }
            }
        }
    }
    // Every ray crosses the three grids (hits of α = 0 at a vertex are not kept).
    assert!(compared >= 2 * 41 * 23, "{compared} hits compared");
    let opts = RenderOptions::default();
    let (got, _) = tracer.render(&cam, 0.0, &opts).unwrap();
    assert_eq!(bits(&got), bits(&reference_image(&tracer, &cam, &opts)));
}
