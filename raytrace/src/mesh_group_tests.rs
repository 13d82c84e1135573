//! Group records (`mesh_groups`) against the brute-force reference: discs of many triangles
//! (a centre fan and rings of quads, as the `rings` profile writes them, in both windings),
//! some with vertices slightly off their group's plane (within `Mesh::planar_groups`'
//! tolerance), seen face-on, obliquely and edge-on, near the origin and far from it. Every
//! sample's hits through the tiles equal the reference's bit for bit, and so do the images; and
//! the plane-crossing filter never leaves out a triangle the watertight test reports, on rays
//! aimed at the triangles' vertices and edges from every side.

use glam::{DVec3, Vec3, Vec4};
use splatbridge_scene::Camera;

use super::footprint::sample_offsets;
use super::mesh_bin::TileLists;
use super::mesh_groups::GROUP_MARK;
use super::mesh_hit::{plane_distance, LocalRay};
use super::mesh_tile_tests::{
    assert_image_is_reference, check_every_sample, hit_bits, ided_mesh, nodes_over, tracer,
    worst_difference, Rng,
};
use super::model::{Mesh, TriScene};

/// A disc of `segments` sectors: a centre fan and `rings` rings of quads (two triangles a
/// sector), α falling outwards, each triangle again in the other winding right after it when
/// `both`. `wobble`: how far (relative to the radius) the rim vertices leave the plane.
#[allow(clippy::too_many_arguments)]
fn disc(
    m: &mut Mesh,
    gid: u32,
    c: Vec3,
    a0: Vec3,
    a1: Vec3,
    segments: u32,
    rings: u32,
    rgba: Vec4,
    both: bool,
    wobble: f32,
    r: &mut Rng,
) {
    let base = m.positions.len() as u32;
    let normal = a0.cross(a1).normalize_or_zero() * a0.length().max(a1.length());
    m.positions.push(c);
    m.colors.push(rgba);
    for ring in 1..=rings + 1 {
        let f = ring as f32 / (rings + 1) as f32;
        for k in 0..segments {
            let th = std::f32::consts::TAU * k as f32 / segments as f32;
            let off = normal * wobble * r.range(-1.0, 1.0);
            m.positions
                .push(c + (a0 * th.cos() + a1 * th.sin()) * f + off);
            m.colors
                .push(rgba * Vec4::new(1.0, 1.0, 1.0, (1.0 - f * f).max(0.0)));
        }
    }
    let at = |ring: u32, k: u32| base + 1 + ring * segments + k % segments;
    let mut push = |t: [u32; 3]| {
        m.tris.push(t);
        m.tri_material.push(0);
        m.tri_gaussian.push(gid);
        if both {
            m.tris.push([t[0], t[2], t[1]]);
            m.tri_material.push(0);
            m.tri_gaussian.push(gid);
        }
    };
    for k in 0..segments {
        push([base, at(0, k), at(0, k + 1)]);
    }
    for ring in 0..rings {
        for k in 0..segments {
            push([at(ring, k), at(ring + 1, k), at(ring + 1, k + 1)]);
            push([at(ring, k), at(ring + 1, k + 1), at(ring, k + 1)]);
        }
    }
}

/// `n` random discs of `segments` sectors and `rings` rings (8 and 2: 40 triangles a
/// winding, always a group; 6 and 0: a fan of 6, a group only in frames of few rays) around
/// `offset`: every seventh repeated (equal keys), some flat ones twinned under another
/// Gaussian (equal distances, other keys), every third opaque, every fourth wobbling off its
/// plane, every eleventh large.
fn discs(seed: u64, n: usize, extent: f32, offset: Vec3, both: bool, shape: (u32, u32)) -> Mesh {
    let mut r = Rng(seed);
    let mut m = ided_mesh();
    // Flat discs twinned under another Gaussian (their triangles again, over the same
    // vertices, after every disc): the same plane distance under another key, which a round
    // that ended at the first must not skip.
    let mut twins = Vec::new();
    for g in 0..n {
        let c = r.point(offset, extent);
        let q = r.rotation();
        let big = if g % 11 == 0 { 4.0 } else { 1.0 };
        let s = Vec3::new(r.range(0.1, 0.5), r.range(0.1, 0.5), 1.0) * extent * 0.4 * big;
        let mut rgba = Vec4::new(r.f(), r.f(), r.f(), r.range(0.2, 0.9));
        if g % 3 == 0 {
            rgba.w = 1.0;
        }
        let wobble = if g % 4 == 0 { 4e-4 } else { 0.0 };
        let copies = if g % 7 == 0 { 2 } else { 1 };
        let first = m.tris.len();
        for _ in 0..copies {
            let (a0, a1) = (q * Vec3::X * s.x, q * Vec3::Y * s.y);
            let (segments, rings) = shape;
            disc(
                &mut m, g as u32, c, a0, a1, segments, rings, rgba, both, wobble, &mut r,
            );
        }
        if g % 13 == 5 && copies == 1 && wobble == 0.0 {
            twins.push((first, m.tris.len(), g as u32 + 100_000));
        }
    }
    for (a, b, gid) in twins {
        for t in a..b {
            m.tris.push(m.tris[t]);
            m.tri_material.push(m.tri_material.get(t));
            m.tri_gaussian.push(gid);
        }
    }
    m
}

/// Two disc meshes under the tile tests' four nodes, around `offset`; `n` discs in the first
/// mesh, two thirds of that in the second.
fn scene(seed: u64, offset: Vec3, both: bool, n: usize, shape: (u32, u32)) -> TriScene {
    nodes_over(
        discs(seed, n, 1.0, offset, both, shape),
        discs(seed ^ 0x5A5A, n * 2 / 3, 0.6, offset, both, shape),
        seed.is_multiple_of(2),
    )
}

/// Outside the scene, inside it, and edge-on to the horizon of a scene laid flat.
fn cameras(offset: DVec3) -> Vec<Camera> {
    let look = |from: DVec3, to: DVec3, fov: f64, w: u32, h: u32| {
        Camera::look_at(offset + from, offset + to, DVec3::NEG_Y, fov, w, h).unwrap()
    };
    vec![
        look(DVec3::new(0.3, -0.5, -4.0), DVec3::ZERO, 50.0, 41, 30),
        look(
            DVec3::new(0.1, 0.05, -0.2),
            DVec3::new(0.0, 0.0, 1.0),
            70.0,
            35,
            21,
        ),
        look(DVec3::new(-3.5, 0.02, 0.1), DVec3::ZERO, 40.0, 38, 26),
    ]
}

/// Every sample's hits through the tiles, and the images, against the brute-force reference,
/// for the scenes `scenes` (seed, offset, both windings), with hundreds of group records
/// binned and thousands of hits compared.
fn check_scenes(scenes: &[(u64, Vec3, bool)], n: usize, shape: (u32, u32)) {
    let (mut compared, mut groups) = (0usize, 0usize);
    for &(seed, offset, both) in scenes {
        let tracer = tracer(scene(seed, offset, both, n, shape));
        let insts = tracer.prepare_list(0.0);
        for cam in cameras(offset.as_dvec3()) {
            for spp in [1, 4] {
                let offsets = sample_offsets(spp);
                let lists = TileLists::build(&tracer, &insts, &cam, &offsets);
                groups += lists
                    .cands
                    .iter()
                    .filter(|c| c.mirror == GROUP_MARK)
                    .count();
                compared += check_every_sample(&tracer, &insts, &lists, &cam, spp);
            }
            for spp in [1, 4] {
                assert_image_is_reference(&tracer, &cam, spp, &format!("seed {seed}"));
            }
        }
    }
    // The scenes are binned as groups, and thousands of their hits were compared.
    assert!(groups > 500, "{groups} group records");
    assert!(compared > 10_000, "{compared} hits compared");
}

#[test]
fn group_hits_equal_brute_force() {
    let far = Vec3::new(1e4, -2e4, 3e4);
    let scenes = [
        (1, Vec3::ZERO, true),
        (2, Vec3::ZERO, false),
        (3, far, true),
    ];
    check_scenes(&scenes, 60, (8, 2));
}

/// The per-ray path (`MeshTracer::collect_instance`, which stops a group at its first
/// decided triangle, across the runs of a disc) gives the brute-force reference's hits bit
/// for bit, triangle index included (all but the colour, which `all_hits` leaves unshaded),
/// on discs spread over several runs and on repeated discs (equal keys, where the
/// lower-indexed copy must win whichever run the walk reaches first): run by run, and through
/// the group table once it is built (`MeshTracer::prepare_groups`: each group's members by
/// the plane crossing, skipped where the plane lies beyond the cull distance or before the
/// round's last key). Buffers of 16 hits: with fewer the per-ray path keeps the first-found
/// of equal keys at the buffer's end (`mesh_tiles`' module documentation), which the images
/// below allow for.
#[test]
fn per_ray_group_rule_equals_brute_force() {
    use super::mesh_tile_tests::reference;
    use super::render::camera_ray;
    let min_t = super::render::RenderOptions::default().min_transmittance;
    let (mut compared, mut grouped) = (0usize, 0usize);
    for (seed, shape) in [(6, (8, 2)), (7, (6, 0)), (8, (8, 3))] {
        for both in [false, true] {
            let tracer = tracer(scene(seed, Vec3::ZERO, both, 60, shape));
            let insts = tracer.prepare(0.0);
            for table in [false, true] {
                if table {
                    tracer.prepare_groups(insts.list(), false);
                    let t = tracer.blas[0].groups.get().expect("the table is built");
                    grouped += (0..tracer.blas[0].planes.len() as u32)
                        .filter(|&g| t.is_group(g, true))
                        .count();
                }
                for cam in cameras(DVec3::ZERO) {
                    for j in 0..cam.height {
                        for i in 0..cam.width {
                            let (o, d) = camera_ray(&cam, i as f64 + 0.5, j as f64 + 0.5);
                            let want = reference(&tracer, 0.0, o, d, min_t);
                            for k in [16] {
                                let got = tracer.all_hits(&insts, o, d, k);
                                let at = format!("seed {seed} ({i}, {j}) k {k} table {table}");
                                assert!(got.len() >= want.len(), "{at}: lost hits");
                                // `all_hits` does not shade: distance, key, triangle and
                                // barycentrics.
                                for (g, w) in got.iter().zip(&want) {
                                    let (g, w) = (hit_bits(g), hit_bits(w));
                                    assert_eq!(g[..8], w[..8], "{at}");
                                }
                                compared += want.len();
                            }
                        }
                    }
                }
            }
        }
    }
    // 17,932 hits on these scenes: a floor that fails if the cameras stop seeing the discs,
    // and the discs are tested through the table.
    assert!(compared > 10_000, "{compared} hits compared");
    assert!(grouped > 100, "{grouped} groups in the tables");
}

/// The per-ray path's images of discs (through the group table) against the tiles' (the brute-force reference's, `check_scenes`), with buffers of
/// 1, 4 and 16 hits, so rays take many rounds and the table's members are skipped by the
/// last round's key. 1e-6: the per-ray path keeps the first-found of equal keys at a full
/// buffer's end, whose barycentrics are another triangle's of the same disc (or the other
/// winding's) and move the colour by an ulp or two (`mesh_tile_tests`, the same bound).
#[test]
fn per_ray_images_of_discs_match_the_tiles() {
    use super::render::RenderOptions;
    for (seed, both) in [(9, true), (10, false)] {
        let tracer = tracer(scene(seed, Vec3::ZERO, both, 60, (8, 2)));
        // Through the tables whatever `tables_pay` would decide for these small frames.
        tracer.prepare_groups(tracer.prepare(0.0).list(), false);
        for cam in cameras(DVec3::ZERO) {
            for k in [1, 4, 16] {
                let opts = RenderOptions {
                    k,
                    ..RenderOptions::default()
                };
                let (a, _) = tracer.render_tiles(&cam, 0.0, &opts).unwrap();
                let (b, _) = tracer.render_per_ray(&cam, 0.0, &opts).unwrap();
                let worst = worst_difference(&a, &b);
                assert!(worst <= 1e-6, "seed {seed} k = {k}: {worst}");
                assert!(a.alpha.iter().any(|&x| x > 0.5), "the discs are seen");
            }
        }
    }
}

/// Fans of six triangles: one record a fan in the frames of one sample a pixel (enough
/// triangles a ray, `SMALL_GROUP_TRIANGLES_PER_RAY`), one a triangle at four.
#[test]
fn small_groups_equal_brute_force() {
    check_scenes(
        &[(4, Vec3::ZERO, true), (5, Vec3::ZERO, false)],
        400,
        (6, 0),
    );
}

/// The filter of `GroupTable::crossing` and `masks` passes every triangle the watertight test
/// reports: rays from random origins (near, far, grazing the plane) aimed at points on each
/// triangle's vertices and edges, and just beside them.
#[test]
fn crossing_filter_keeps_every_reported_triangle() {
    let mut r = Rng(77);
    let (mut reported, mut filtered_out, mut grazing) = (0usize, 0usize, 0usize);
    for (seed, offset) in [(5u64, Vec3::ZERO), (6, Vec3::new(-3e3, 2e3, 5e3))] {
        let tracer = tracer(scene(seed, offset, true, 60, (8, 2)));
        let cam = &cameras(offset.as_dvec3())[0];
        let insts = tracer.prepare_list(0.0);
        // Binning builds the tables.
        TileLists::build(&tracer, &insts, cam, &sample_offsets(1));
        let blas = &tracer.blas[0];
        let mesh = &tracer.scene.meshes[0];
        let table = blas.groups.get().expect("tables built");
        let mirror = blas.mirror.get().expect("pairs found");
        let groups = blas.planes.len() as u32;
        for g in 0..groups {
            if !table.is_group(g, false) {
                continue;
            }
            let members = table.members(g);
            let count = members.len();
            for _ in 0..40 {
                let k = (r.f() * count as f32) as usize % count;
                let t = members[k] as usize;
                let [a, b, c] = blas.triangle(&mesh.positions, mesh.tris[t]);
                // A vertex, an edge point or an inside point, nudged by up to 1e-6 of the
                // triangle's size.
                let (u, v) = match (r.f() * 3.0) as u32 {
                    0 => (1.0, 0.0),
                    1 => {
                        let s = r.f();
                        (s, 1.0 - s)
                    }
                    _ => (r.f() * 0.5, r.f() * 0.5),
                };
                let size = (b - a).length().max((c - a).length());
                let nudge = Vec3::new(r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0))
                    * size
                    * 1e-6;
                let target = (a * (1.0 - u - v) + b * u + c * v + nudge).as_dvec3();
                // From anywhere around, or nearly in the plane (grazing).
                let n = (b - a).cross(c - a).normalize_or_zero().as_dvec3();
                let dir = DVec3::new(
                    r.range(-1.0, 1.0) as f64,
                    r.range(-1.0, 1.0) as f64,
                    r.range(-1.0, 1.0) as f64,
                )
                .normalize_or_zero();
                let dir = if r.f() < 0.3 {
                    grazing += 1;
                    (dir - n * dir.dot(n) + n * (r.range(-1.0, 1.0) as f64 * 1e-2))
                        .normalize_or_zero()
                } else {
                    dir
                };
                if dir == DVec3::ZERO {
                    continue;
                }
                let dist = [0.05, 1.0, 30.0][(r.f() * 3.0) as usize % 3];
                let o = target - dir * dist;
                let Some(ray) = LocalRay::new(o, dir) else {
                    continue;
                };
                for tri in [t, mirror[t] as usize] {
                    if tri == u32::MAX as usize {
                        continue;
                    }
                    let [a, b, c] = blas.triangle(&mesh.positions, mesh.tris[tri]);
                    if ray.wray.cover(a, b, c).is_err() {
                        continue;
                    }
                    reported += 1;
                    let tp = plane_distance(blas.planes[g as usize], &ray);
                    let kept = match table.crossing(g, &table.record(g), &ray, tp) {
                        None => true,
                        Some(None) => false,
                        Some(Some(at)) => {
                            let masks: Vec<u32> = table.masks(g, &at).collect();
                            masks[k / 8] >> (k % 8) & 1 == 1
                        }
                    };
                    filtered_out += !kept as usize;
                }
            }
        }
    }
    assert_eq!(filtered_out, 0, "of {reported} reported");
    // Most aimed rays are reported, grazing ones among them.
    assert!(
        reported > 3000 && grazing > 1000,
        "{reported} reported, {grazing} grazing"
    );
}

/// Sixty discs of `shape` (with both windings when `both`) as the one node of a scene with
/// the blended material of [`nodes_over`].
fn one_node_discs(both: bool, shape: (u32, u32)) -> crate::model::TriScene {
    let mut scene = nodes_over(
        discs(5, 60, 1.0, Vec3::ZERO, both, shape),
        ided_mesh(),
        false,
    );
    scene.meshes.truncate(1);
    scene.nodes = vec![crate::model::Node {
        mesh: Some(0),
        ..crate::model::Node::default()
    }];
    scene
}

/// A one-node mesh of discs decides on the tiles by its records, each disc of more than 16
/// triangles counted as `GROUP_RECORD_WEIGHT`, not by its triangles; a mesh of small groups
/// (fans of 6) by its triangles, as before. The count is checked against one made group by
/// group over every triangle's plane (`Mesh::planar_groups`, the groups the BVH keeps), and
/// the switch against it at exactly a `TRIANGLES_PER_RAY`-th.
#[test]
fn one_node_meshes_count_large_groups_as_records() {
    use super::backend::{BackendKind, BuildPreset};
    use super::mesh_groups::GROUP_RECORD_WEIGHT;
    use super::mesh_tiles::TRIANGLES_PER_RAY;
    use super::mesh_tracer::MeshTracer;
    // Every seventh disc is drawn twice over in its group: 12 triangles for a fan of 6 in
    // one winding, still a small group.
    let cases = [
        ((8, 3), true, true),
        ((8, 3), false, true),
        ((6, 0), false, false),
    ];
    for (shape, both, large) in cases {
        let scene = one_node_discs(both, shape);
        let (groups, count) = scene.meshes[0].planar_groups();
        let n = scene.meshes[0].tris.len() as u64;
        let t = MeshTracer::new(scene, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
        let reference: u64 = (0..count)
            .map(|g| groups.iter().filter(|&&x| x == g).count() as u64)
            .map(|c| if c > 16 { GROUP_RECORD_WEIGHT } else { c })
            .sum();
        let records = t.records_of(&t.prepare_list(0.0));
        assert_eq!(records, reference, "{shape:?} both {both}");
        // Discs of 56 or 112 triangles are far fewer records (though every fourth disc,
        // whose rim leaves the plane, splits into groups of its own); fans of 6 or 12 are not.
        assert_eq!(records < n / 2, large, "{records} records, {n} triangles");
        if !large {
            assert_eq!(records, n);
        }
        let switch = records.div_ceil(TRIANGLES_PER_RAY);
        assert!(!t.tiles_pay(0.0, switch - 1) && t.tiles_pay(0.0, switch));
    }
}

/// The per-ray path builds the group tables where its rays test many candidates for the
/// triangles and not where they test few: on these discs a ray tests 13.9 (measured), so a
/// 41×30 frame at 16 samples a pixel tests 56 a triangle (built), at one sample 3.5 (not
/// built), and a frame of four rays not either; the images are the same with or without
/// them (`per_ray_images_of_discs_match_the_tiles`).
#[test]
fn per_ray_path_builds_the_tables_where_they_pay() {
    use super::render::RenderOptions;
    let cam = &cameras(DVec3::ZERO)[0];
    let small = Camera {
        width: 2,
        height: 2,
        fx: cam.fx * 2.0 / cam.width as f64,
        fy: cam.fy * 2.0 / cam.height as f64,
        cx: 1.0,
        cy: 1.0,
        ..cam.clone()
    };
    let built = |c: &Camera, spp: u32| {
        let tracer = tracer(scene(11, Vec3::ZERO, false, 60, (8, 2)));
        let opts = RenderOptions {
            spp,
            ..RenderOptions::default()
        };
        let insts = tracer.prepare(0.0);
        let pays = tracer.tables_pay(&insts, c, &opts);
        tracer.render_per_ray(c, 0.0, &opts).unwrap();
        assert_eq!(pays, tracer.blas[0].groups.get().is_some());
        // Once built, a later frame has nothing to decide.
        assert!(!pays || !tracer.tables_pay(&insts, c, &opts));
        pays
    };
    assert!(built(cam, 16), "16 samples a pixel");
    assert!(!built(cam, 1), "one sample a pixel");
    assert!(!built(&small, 1), "four rays");
}

/// A one-node mesh whose every material is opaque (or which names none, the default material)
/// switches to the tiles at an `OPAQUE_TRIANGLES_PER_RAY`-th of its records; one blended or
/// masked (rays may pass through either) at a `TRIANGLES_PER_RAY`-th.
#[test]
fn opaque_meshes_switch_at_their_own_share() {
    use super::backend::{BackendKind, BuildPreset};
    use super::mesh_tiles::{OPAQUE_TRIANGLES_PER_RAY, TRIANGLES_PER_RAY};
    use super::mesh_tracer::MeshTracer;
    use super::model::AlphaMode;
    let cases = [
        (Some(AlphaMode::Opaque), OPAQUE_TRIANGLES_PER_RAY),
        (None, OPAQUE_TRIANGLES_PER_RAY),
        (Some(AlphaMode::Blend), TRIANGLES_PER_RAY),
        (Some(AlphaMode::Mask(0.5)), TRIANGLES_PER_RAY),
    ];
    for (mode, share) in cases {
        let mut scene = one_node_discs(true, (6, 0));
        match mode {
            Some(m) => scene.materials.iter_mut().for_each(|x| x.alpha_mode = m),
            None => scene.materials.clear(),
        }
        let t = MeshTracer::new(scene, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
        let insts = t.prepare_list(0.0);
        assert_eq!(
            t.opaque(&insts),
            share == OPAQUE_TRIANGLES_PER_RAY,
            "{mode:?}"
        );
        let switch = t.records_of(&insts).div_ceil(share);
        assert!(switch > 1, "{mode:?}: too few records to see the switch");
        assert!(
            !t.tiles_pay(0.0, switch - 1) && t.tiles_pay(0.0, switch),
            "{mode:?}"
        );
    }
}
