//! Shared test scaffolding: synthetic fan scenes and the brute-force f64 reference tracer.
//!
//! The reference intersects every triangle of every instance in f64 with a plane-then-
//! barycentric test (not the watertight algorithm under test), de-duplicates per planar group,
//! sorts by (distance, Gaussian id, instance, group) and composites with the same rules as the
//! mesh mode. Hits whose point lies within a barycentric 1e-5 of a group's outer boundary are
//! flagged ambiguous: there f32 and f64 may legitimately disagree on coverage.
#![allow(dead_code)]

use std::collections::{HashMap, HashSet};

use glam::{DVec3, Quat, Vec3, Vec4};
use splatbridge_raytrace::model::{Material, Mesh, TriScene};
use splatbridge_raytrace::{
    AlphaMode, BackendKind, BuildPreset, Compositing, MeshTracer, RenderOptions,
};
use splatbridge_scene::{Camera, Frame};

/// Small deterministic generator (SplitMix64).
pub struct Rng(pub u64);
impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn f(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    pub fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.f()
    }
}

/// Append a MeshSplats-style fan: centre alpha `o`, rim alpha 0.2·o, `n` rim vertices at
/// `centre + cos θ·a0 + sin θ·a1`.
pub fn push_fan(
    mesh: &mut Mesh,
    gid: u32,
    centre: Vec3,
    a0: Vec3,
    a1: Vec3,
    n: usize,
    rgb: Vec3,
    o: f32,
) {
    let base = mesh.positions.len() as u32;
    mesh.positions.push(centre);
    mesh.colors.push(rgb.extend(o));
    for k in 0..n {
        let th = -std::f32::consts::PI + std::f32::consts::TAU * k as f32 / n as f32;
        mesh.positions.push(centre + a0 * th.cos() + a1 * th.sin());
        mesh.colors.push(rgb.extend(0.2 * o));
    }
    for k in 0..n as u32 {
        mesh.tris
            .push([base, base + 1 + k, base + 1 + (k + 1) % n as u32]);
        mesh.tri_material.push(0);
        mesh.tri_gaussian.push(gid);
    }
}

pub fn blend_materials() -> Vec<Material> {
    vec![Material {
        base_color: Vec4::ONE,
        texture: None,
        alpha_mode: AlphaMode::Blend,
    }]
}

/// `n` random fans (some volumetric: three orthogonal fans of one Gaussian) in a box of
/// half-size `extent` around `offset`.
pub fn random_fans(seed: u64, n: usize, extent: f32, offset: Vec3) -> Mesh {
    let mut r = Rng(seed);
    let mut m = Mesh {
        has_gaussian_ids: true,
        ..Mesh::default()
    };
    for g in 0..n {
        let c = offset
            + Vec3::new(
                r.range(-extent, extent),
                r.range(-extent, extent),
                r.range(-extent, extent),
            );
        let q = Quat::from_xyzw(
            r.range(-1.0, 1.0),
            r.range(-1.0, 1.0),
            r.range(-1.0, 1.0),
            r.range(-1.0, 1.0),
        )
        .normalize();
        let s =
            Vec3::new(r.range(0.05, 0.4), r.range(0.05, 0.4), r.range(0.05, 0.4)) * extent * 0.5;
        let (ax, ay, az) = (q * Vec3::X, q * Vec3::Y, q * Vec3::Z);
        let rgb = Vec3::new(r.f(), r.f(), r.f());
        let o = r.range(0.05, 0.95);
        let gid = (g as u32 * 7919) % 100_003;
        push_fan(&mut m, gid, c, ax * s.x, ay * s.y, 8, rgb, o);
        if g % 4 == 0 {
            push_fan(&mut m, gid, c, ay * s.y, az * s.z, 8, rgb, o);
            push_fan(&mut m, gid, c, az * s.z, ax * s.x, 8, rgb, o);
        }
    }
    m
}

/// One reference hit.
#[derive(Clone, Debug)]
pub struct RefHit {
    pub t: f64,
    pub gaussian: u32,
    pub instance: u32,
    pub group: u32,
    pub tri: usize,
    pub bary: [f64; 3],
}

/// Everything the reference says about one ray.
#[derive(Clone, Debug, Default)]
pub struct RefRay {
    pub hits: Vec<RefHit>,
    /// (instance, group) pairs whose coverage is within 1e-5 of the group boundary.
    pub ambiguous: HashSet<(u32, u32)>,
}

/// Brute-force reference over a scene at time `time`.
pub struct Reference {
    pub scene: TriScene,
    pub insts: Vec<(usize, glam::DAffine3)>,
    pub groups: Vec<Vec<u32>>,
    /// Per mesh: boundary edges (sorted vertex pairs) per group.
    pub boundary: Vec<HashSet<(u32, u32)>>,
    /// Per mesh, per group: the triangle whose plane gives the group's distance.
    pub planes: Vec<Vec<usize>>,
}

impl Reference {
    pub fn new(scene: &TriScene, time: f64) -> Self {
        // Instances are listed in the order the tracer uses (`TriScene::instances`), so the
        // instance index in keys agrees; meshes without triangles are skipped there too.
        let insts: Vec<(usize, glam::DAffine3)> = scene
            .instances(time)
            .into_iter()
            .filter(|i| !scene.meshes[i.mesh].tris.is_empty())
            .map(|i| (i.mesh, i.to_world))
            .collect();
        let mut groups = Vec::new();
        let mut boundary = Vec::new();
        let mut planes = Vec::new();
        for m in &scene.meshes {
            let (g, ng) = m.planar_groups();
            // The group's largest triangle (by local area) defines its plane.
            let mut best = vec![(0.0f64, 0usize); ng as usize];
            for (t, tri) in m.tris.iter().enumerate() {
                let [a, b, c] = tri.map(|i| m.positions[i as usize].as_dvec3());
                let area = (b - a).cross(c - a).length();
                if area > best[g[t] as usize].0 {
                    best[g[t] as usize] = (area, t);
                }
            }
            planes.push(best.into_iter().map(|(_, t)| t).collect());
            let mut count: HashMap<(u32, u32, u32), u32> = HashMap::new();
            for (t, tri) in m.tris.iter().enumerate() {
                for e in 0..3 {
                    let (a, b) = (tri[e], tri[(e + 1) % 3]);
                    *count.entry((g[t], a.min(b), a.max(b))).or_default() += 1;
                }
            }
            boundary.push(
                count
                    .into_iter()
                    .filter(|(_, c)| *c == 1)
                    .map(|((_, a, b), _)| (a, b))
                    .collect(),
            );
            groups.push(g);
        }
        Reference {
            scene: scene.clone(),
            insts,
            groups,
            boundary,
            planes,
        }
    }

    pub fn trace(&self, o: DVec3, d: DVec3) -> RefRay {
        const TOL: f64 = 1e-5;
        let mut best: HashMap<(u32, u32), RefHit> = HashMap::new();
        let mut amb = HashSet::new();
        for (ii, (mi, xf)) in self.insts.iter().enumerate() {
            let m = &self.scene.meshes[*mi];
            for (t, tri) in m.tris.iter().enumerate() {
                let [a, b, c] =
                    tri.map(|i| xf.transform_point3(m.positions[i as usize].as_dvec3()));
                let n = (b - a).cross(c - a);
                let nn = n.length_squared();
                let den = n.dot(d);
                if nn == 0.0 || den.abs() <= 1e-12 * nn.sqrt() {
                    continue;
                }
                let th = n.dot(a - o) / den;
                if !(th >= 0.0) {
                    continue;
                }
                let p = o + d * th;
                let l = [
                    (c - b).cross(p - b).dot(n) / nn,
                    (a - c).cross(p - c).dot(n) / nn,
                    (b - a).cross(p - a).dot(n) / nn,
                ];
                let min = l[0].min(l[1]).min(l[2]);
                if min < -TOL {
                    continue;
                }
                let key = (ii as u32, self.groups[*mi][t]);
                for i in 0..3 {
                    let (va, vb) = (tri[(i + 1) % 3], tri[(i + 2) % 3]);
                    if l[i].abs() <= TOL && self.boundary[*mi].contains(&(va.min(vb), va.max(vb))) {
                        amb.insert(key);
                    }
                }
                // Exactly on an interior edge (shared within the group), f64 rounding can make
                // λ slightly negative in both triangles: the group still covers the point.
                let interior_ok = (0..3).all(|i| {
                    let (va, vb) = (tri[(i + 1) % 3], tri[(i + 2) % 3]);
                    l[i] >= 0.0
                        || (l[i] >= -1e-9
                            && !self.boundary[*mi].contains(&(va.min(vb), va.max(vb))))
                });
                if !interior_ok {
                    continue;
                }
                // A planar group's distance is its plane's (its largest triangle's): fans
                // quantised to f32 far from the origin are planar only to ~ulp(coordinate).
                let pt = self.planes[*mi][key.1 as usize];
                let [pa, pb, pc] =
                    m.tris[pt].map(|i| xf.transform_point3(m.positions[i as usize].as_dvec3()));
                let pn = (pb - pa).cross(pc - pa);
                let tg = pn.dot(pa - o) / pn.dot(d);
                let h = RefHit {
                    t: if tg.is_finite() { tg } else { th },
                    gaussian: m.tri_gaussian[t],
                    instance: ii as u32,
                    group: key.1,
                    tri: t,
                    bary: l,
                };
                match best.get(&key) {
                    Some(e) if (e.t, e.tri) <= (h.t, h.tri) => {}
                    _ => {
                        best.insert(key, h);
                    }
                }
            }
        }
        let mut hits: Vec<RefHit> = best.into_values().collect();
        hits.sort_by(|x, y| {
            x.t.total_cmp(&y.t)
                .then(x.gaussian.cmp(&y.gaussian))
                .then(x.instance.cmp(&y.instance))
                .then(x.group.cmp(&y.group))
        });
        RefRay {
            hits,
            ambiguous: amb,
        }
    }

    /// Composite like the mesh mode: (rgb, alpha).
    pub fn composite(&self, r: &RefRay, opts: &RenderOptions) -> (DVec3, f64) {
        let mut tr = 1.0f64;
        let mut c = DVec3::ZERO;
        for h in &r.hits {
            let m = &self.scene.meshes[self.insts[h.instance as usize].0];
            let rgba = m.shade(
                h.tri,
                h.bary.map(|v| v as f32),
                &self.scene.materials,
                &self.scene.textures,
            );
            let a = rgba.w as f64;
            if a > 0.0 {
                let mut rgb = rgba.truncate().as_dvec3().clamp(DVec3::ZERO, DVec3::ONE);
                let enc = |x: f64| {
                    if x <= 0.0031308 {
                        12.92 * x
                    } else {
                        1.055 * x.powf(1.0 / 2.4) - 0.055
                    }
                };
                let dec = |x: f64| {
                    if x <= 0.04045 {
                        x / 12.92
                    } else {
                        ((x + 0.055) / 1.055).powf(2.4)
                    }
                };
                match (opts.compositing, self.scene.colors_linear) {
                    (Compositing::Display, true) => {
                        rgb = DVec3::new(enc(rgb.x), enc(rgb.y), enc(rgb.z))
                    }
                    (Compositing::Viewer, false) => {
                        rgb = DVec3::new(dec(rgb.x), dec(rgb.y), dec(rgb.z))
                    }
                    _ => {}
                }
                c += rgb * a * tr;
                tr *= 1.0 - a;
                if tr < opts.min_transmittance as f64 {
                    break;
                }
            }
        }
        if opts.compositing == Compositing::Viewer {
            let enc = |x: f64| {
                if x <= 0.0031308 {
                    12.92 * x
                } else {
                    1.055 * x.powf(1.0 / 2.4) - 0.055
                }
            };
            let dec = |x: f64| {
                if x <= 0.04045 {
                    x / 12.92
                } else {
                    ((x + 0.055) / 1.055).powf(2.4)
                }
            };
            let bg = opts.background.as_dvec3();
            let l = (c + DVec3::new(dec(bg.x), dec(bg.y), dec(bg.z)) * tr)
                .clamp(DVec3::ZERO, DVec3::ONE);
            return (DVec3::new(enc(l.x), enc(l.y), enc(l.z)), 1.0 - tr);
        }
        (c + opts.background.as_dvec3() * tr, 1.0 - tr)
    }
}

/// Every channel of a frame as bits, for bit-for-bit comparisons.
pub fn bits(f: &Frame) -> Vec<u32> {
    f.rgb
        .iter()
        .chain(&f.alpha)
        .chain(&f.depth)
        .map(|v| v.to_bits())
        .collect()
}

pub fn backends() -> Vec<BackendKind> {
    let mut v = vec![BackendKind::Obvhs];
    if splatbridge_raytrace::backend::EMBREE_AVAILABLE {
        v.push(BackendKind::Embree);
    }
    v
}

/// Image tolerance: f32 barycentrics and f32 compositing against f64 carry ~1e-6 absolute
/// error per layer at these depths (measured max ≈ 1e-6); the bound is 1e-5.
pub const IMAGE_TOL: f64 = 1e-5;

/// Compare tracer and reference on every pixel of `cam`; returns the number of pixels skipped
/// as ambiguous (a group boundary within 1e-5 of the ray).
pub fn compare(
    scene: &TriScene,
    time: f64,
    cam: &Camera,
    backend: BackendKind,
    opts: &RenderOptions,
) -> usize {
    let tracer = MeshTracer::new(scene.clone(), backend, BuildPreset::Medium).unwrap();
    let reference = Reference::new(scene, time);
    let insts = tracer.prepare(time);
    let (frame, stats) = tracer.render(cam, time, opts).unwrap();
    assert!(frame.is_finite());
    assert_eq!(stats.rays, (cam.width * cam.height) as u64);
    let mut skipped = 0;
    let mut total_hits = 0;
    for j in 0..cam.height {
        for i in 0..cam.width {
            let (o, d) = (cam.centre, cam.ray_dir(i as f64 + 0.5, j as f64 + 0.5));
            let got = tracer.all_hits(&insts, o, d, opts.k);
            let want = reference.trace(o, d);
            total_hits += want.hits.len();
            let key = |g: u32, inst: u32, grp: u32| (g, inst, grp);
            let a: Vec<_> = got
                .iter()
                .map(|h| key(h.gaussian, h.instance, h.group))
                .collect();
            let b: Vec<_> = want
                .hits
                .iter()
                .map(|h| key(h.gaussian, h.instance, h.group))
                .collect();
            if a != b {
                // Only boundary-ambiguous groups may differ.
                let strip = |v: &[(u32, u32, u32)]| -> Vec<(u32, u32, u32)> {
                    v.iter()
                        .copied()
                        .filter(|k| !want.ambiguous.contains(&(k.1, k.2)))
                        .collect()
                };
                assert_eq!(
                    strip(&a),
                    strip(&b),
                    "{backend}: hit sets differ at pixel ({i}, {j})"
                );
                skipped += 1;
                continue;
            }
            for (g, w) in got.iter().zip(&want.hits) {
                // f32 distance from a camera-relative origin: relative error ~1e-6.
                assert!(
                    (g.t as f64 - w.t).abs() <= 1e-5 * w.t.max(1.0),
                    "{backend}: t {} vs {} at ({i}, {j})",
                    g.t,
                    w.t
                );
            }
            let (rgb, alpha) = reference.composite(&want, opts);
            let px = frame.rgb_at(i, j);
            let k = (j * cam.width + i) as usize;
            for c in 0..3 {
                assert!(
                    (px[c] as f64 - rgb[c]).abs() <= IMAGE_TOL,
                    "{backend}: pixel ({i}, {j}) channel {c}: {} vs {}",
                    px[c],
                    rgb[c]
                );
            }
            assert!((frame.alpha[k] as f64 - alpha).abs() <= IMAGE_TOL);
        }
    }
    assert!(total_hits > 0, "the scene must be visible");
    // Ambiguity is a measure-zero event for random scenes: allow at most 0.5 % of pixels.
    assert!(
        skipped * 200 <= (cam.width * cam.height) as usize,
        "{skipped} ambiguous pixels"
    );
    skipped
}
