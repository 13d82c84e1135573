//! Morph targets against a slow reference: a GLB written by hand here (dense, sparse with u8,
//! u16 and u32 indices, sparse over a dense part, and all-zero targets; a `weights` channel of
//! each interpolation; a second node showing the same mesh with node weights), loaded and
//! posed at random times, against `base + Σ w_i Δ_i` computed from the arrays written, with
//! the weights sampled independently (glTF 2.0 §3.11 and Appendix C). Then the tracer posed by
//! `MeshTracer::set_time` against one built on the reference positions, and malformed files.

mod common;

use common::{blend_materials, Rng};
use glam::{DVec3, Vec3};
use serde_json::{json, Value};
use splatbridge_raytrace::model::{Mesh, Node, TriScene};
use splatbridge_raytrace::scene_load::{load_glb_bytes, load_path};
use splatbridge_raytrace::{BackendKind, BuildPreset, MeshTracer, RenderOptions};
use splatbridge_scene::Camera;

const V: usize = 40;

/// How a target's deltas are stored.
#[derive(Clone, Copy, Debug)]
enum Store {
    Dense,
    /// Sparse with this index width (1, 2, 4 bytes), with or without a dense part under it.
    Sparse(usize, bool),
    /// No buffer view and no sparse part: zeros.
    Zero,
}

const STORES: [Store; 6] = [
    Store::Dense,
    Store::Sparse(1, false),
    Store::Sparse(2, true),
    Store::Sparse(4, false),
    Store::Zero,
    Store::Dense,
];

#[derive(Default)]
struct Bin {
    data: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.data.len().is_multiple_of(4) {
            self.data.push(0);
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len()}));
        self.data.extend_from_slice(bytes);
        self.views.len() - 1
    }
    fn acc(&mut self, a: Value) -> usize {
        self.accessors.push(a);
        self.accessors.len() - 1
    }
    fn f32s(&mut self, v: &[f32], count: usize, ty: &str) -> usize {
        let b: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&b);
        self.acc(json!({"bufferView": view, "componentType": 5126, "count": count, "type": ty}))
    }
}

fn flat(v: &[Vec3]) -> Vec<f32> {
    v.iter().flat_map(|p| p.to_array()).collect()
}

/// The file's raw arrays: base positions, each target's full deltas (zeros where not stored).
struct Raw {
    base: Vec<Vec3>,
    deltas: Vec<Vec<Vec3>>,
    interpolation: &'static str,
    times: Vec<f64>,
    values: Vec<f64>,
    node_weights: Vec<f64>,
}

/// A target's accessor as `store` lays it out; returns the full deltas it stands for.
fn target(bin: &mut Bin, rng: &mut Rng, store: Store) -> (usize, Vec<Vec3>) {
    let mut d: Vec<Vec3> = (0..V)
        .map(|_| {
            Vec3::new(
                rng.range(-0.3, 0.3),
                rng.range(-0.3, 0.3),
                rng.range(-0.3, 0.3),
            )
        })
        .collect();
    match store {
        Store::Dense => (bin.f32s(&flat(&d), V, "VEC3"), d),
        Store::Zero => {
            d = vec![Vec3::ZERO; V];
            let a = bin.acc(json!({"componentType": 5126, "count": V, "type": "VEC3"}));
            (a, d)
        }
        Store::Sparse(width, under) => {
            let idx: Vec<usize> = (0..V).filter(|_| rng.f() < 0.4).collect();
            let under_d: Vec<Vec3> = if under {
                (0..V)
                    .map(|_| Vec3::new(rng.range(-0.1, 0.1), 0.05, rng.range(-0.1, 0.1)))
                    .collect()
            } else {
                vec![Vec3::ZERO; V]
            };
            let mut full = under_d.clone();
            for &i in &idx {
                full[i] = d[i];
            }
            let ib: Vec<u8> = idx
                .iter()
                .flat_map(|&i| match width {
                    1 => vec![i as u8],
                    2 => (i as u16).to_le_bytes().to_vec(),
                    _ => (i as u32).to_le_bytes().to_vec(),
                })
                .collect();
            let ct = match width {
                1 => 5121,
                2 => 5123,
                _ => 5125,
            };
            let iv = bin.view(&ib);
            let vals: Vec<Vec3> = idx.iter().map(|&i| d[i]).collect();
            let vb: Vec<u8> = flat(&vals).iter().flat_map(|x| x.to_le_bytes()).collect();
            let vv = bin.view(&vb);
            let mut a = json!({"componentType": 5126, "count": V, "type": "VEC3",
                "sparse": {"count": idx.len(), "indices": {"bufferView": iv, "componentType": ct},
                           "values": {"bufferView": vv}}});
            if under {
                let b: Vec<u8> = flat(&under_d)
                    .iter()
                    .flat_map(|x| x.to_le_bytes())
                    .collect();
                a["bufferView"] = json!(bin.view(&b));
            }
            if idx.is_empty() {
                // A sparse part needs at least one entry; fall back to the dense part alone.
                a.as_object_mut().unwrap().remove("sparse");
                if !under {
                    return (bin.acc(a), vec![Vec3::ZERO; V]);
                }
            }
            (bin.acc(a), full)
        }
    }
}

fn glb(doc: &Value, data: &[u8]) -> Vec<u8> {
    let mut js = serde_json::to_vec(doc).unwrap();
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    let total = 28 + js.len() + data.len();
    let mut g = Vec::with_capacity(total);
    g.extend_from_slice(b"glTF");
    g.extend_from_slice(&2u32.to_le_bytes());
    g.extend_from_slice(&(total as u32).to_le_bytes());
    g.extend_from_slice(&(js.len() as u32).to_le_bytes());
    g.extend_from_slice(b"JSON");
    g.extend_from_slice(&js);
    g.extend_from_slice(&(data.len() as u32).to_le_bytes());
    g.extend_from_slice(b"BIN\0");
    g.extend_from_slice(data);
    g
}

/// A morphed strip of triangles: node 0 animated by a weights channel, node 1 showing the same
/// mesh with fixed node weights. Returns the document, its BIN chunk and the raw arrays.
fn build(seed: u64, interpolation: &'static str, stores: &[Store]) -> (Value, Vec<u8>, Raw) {
    let mut rng = Rng(seed);
    let mut bin = Bin::default();
    let base: Vec<Vec3> = (0..V)
        .map(|i| {
            Vec3::new(
                (i / 2) as f32 * 0.1 - 1.0,
                (i % 2) as f32 * 0.5 + rng.range(-0.05, 0.05),
                rng.range(-0.2, 0.2),
            )
        })
        .collect();
    let pos = bin.f32s(&flat(&base), V, "VEC3");
    let (lo, hi) = base
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), p| {
            (l.min(*p), h.max(*p))
        });
    bin.accessors[pos]["min"] = json!(lo.to_array());
    bin.accessors[pos]["max"] = json!(hi.to_array());
    let idx: Vec<u8> = (0..V as u32 - 2)
        .flat_map(|i| [i, i + 1, i + 2])
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let iv = bin.view(&idx);
    let ia = bin.acc(
        json!({"bufferView": iv, "componentType": 5125, "count": 3 * (V - 2), "type": "SCALAR"}),
    );
    let mut targets = Vec::new();
    let mut deltas = Vec::new();
    for &s in stores {
        let (a, d) = target(&mut bin, &mut rng, s);
        targets.push(json!({"POSITION": a}));
        deltas.push(d);
    }
    let n = stores.len();
    let keys = 5;
    let mut times = Vec::new();
    let mut t = 0.0f64;
    for _ in 0..keys {
        t += 0.2 + rng.f() as f64;
        times.push(t as f32 as f64);
    }
    let per = if interpolation == "CUBICSPLINE" { 3 } else { 1 };
    // Some weights exactly 0 (skipped targets), some 1, the rest random.
    let values: Vec<f64> = (0..keys * n * per)
        .map(|_| match rng.f() {
            x if x < 0.3 => 0.0,
            x if x < 0.45 => 1.0,
            _ => rng.range(-0.5, 1.5) as f64,
        })
        .collect();
    let node_weights: Vec<f64> = (0..n).map(|_| rng.range(0.0, 1.0) as f64).collect();
    let tf: Vec<f32> = times.iter().map(|&t| t as f32).collect();
    let vf: Vec<f32> = values.iter().map(|&v| v as f32).collect();
    let ta = bin.f32s(&tf, keys, "SCALAR");
    let va = bin.f32s(&vf, vf.len(), "SCALAR");
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [
            {"mesh": 0},
            {"mesh": 0, "translation": [0.0, -1.2, 0.0], "weights": node_weights},
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "indices": ia, "targets": targets}],
                    "weights": vec![0.25; n]}],
        "animations": [{
            "samplers": [{"input": ta, "output": va, "interpolation": interpolation}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]
        }],
        "accessors": bin.accessors,
        "bufferViews": bin.views,
        "buffers": [{"byteLength": bin.data.len()}]
    });
    let mut data = bin.data;
    while !data.len().is_multiple_of(4) {
        data.push(0);
    }
    let raw = Raw {
        base,
        deltas,
        interpolation,
        times,
        values: vf.iter().map(|&v| v as f64).collect(),
        node_weights: node_weights.iter().map(|&w| w as f32 as f64).collect(),
    };
    (doc, data, raw)
}

/// The weights at `t`, from the spec's formulas (Appendix C), written independently of the
/// loader: clamp outside the keys, STEP holds, LINEAR lerps, CUBICSPLINE is the Hermite spline
/// with tangents scaled by the key interval.
fn ref_weights(r: &Raw, t: f64) -> Vec<f64> {
    let n = r.deltas.len();
    let cubic = r.interpolation == "CUBICSPLINE";
    let val = |k: usize, i: usize| {
        if cubic {
            r.values[3 * k * n + n + i]
        } else {
            r.values[k * n + i]
        }
    };
    let last = r.times.len() - 1;
    if t <= r.times[0] {
        return (0..n).map(|i| val(0, i)).collect();
    }
    if t >= r.times[last] {
        return (0..n).map(|i| val(last, i)).collect();
    }
    let mut k = 0;
    while r.times[k + 1] <= t {
        k += 1;
    }
    let td = r.times[k + 1] - r.times[k];
    let s = (t - r.times[k]) / td;
    (0..n)
        .map(|i| match r.interpolation {
            "STEP" => val(k, i),
            "LINEAR" => val(k, i) * (1.0 - s) + val(k + 1, i) * s,
            _ => {
                let b_k = r.values[3 * k * n + 2 * n + i];
                let a_k1 = r.values[3 * (k + 1) * n + i];
                (2.0 * s.powi(3) - 3.0 * s * s + 1.0) * val(k, i)
                    + (s.powi(3) - 2.0 * s * s + s) * td * b_k
                    + (-2.0 * s.powi(3) + 3.0 * s * s) * val(k + 1, i)
                    + (s.powi(3) - s * s) * td * a_k1
            }
        })
        .collect()
}

/// base + Σ w_i Δ_i over every target, zero weights included, in f64 then rounded once.
fn ref_positions(r: &Raw, w: &[f64]) -> Vec<Vec3> {
    (0..V)
        .map(|v| {
            let mut p = r.base[v].as_dvec3();
            for (i, d) in r.deltas.iter().enumerate() {
                p += w[i] * d[v].as_dvec3();
            }
            p.as_vec3()
        })
        .collect()
}

/// Within one f32 ulp: the loader and the reference sum the same f64 terms, but the
/// interpolated weights come from differently ordered f64 expressions (≈1e-16 relative),
/// which can move the single f32 rounding by one step.
fn close(a: Vec3, b: Vec3) -> bool {
    (0..3).all(|k| {
        let (x, y) = (a[k], b[k]);
        x == y || (x - y).abs() <= f32::EPSILON * x.abs().max(y.abs())
    })
}

fn check(scene: &mut TriScene, raw: &Raw, times: &[f64], label: &str) {
    // Node 0 keeps mesh 0 and is driven by the channel; node 1 got a copy with its own weights.
    let m1 = scene.nodes[1].mesh.unwrap();
    assert_ne!(m1, 0, "{label}: the second node needs its own copy");
    for &t in times {
        scene.pose_morphs(t).unwrap();
        let want = ref_positions(raw, &ref_weights(raw, t));
        for (v, (a, b)) in scene.meshes[0].positions.iter().zip(&want).enumerate() {
            assert!(close(*a, *b), "{label} t={t} vertex {v}: {a} vs {b}");
        }
        let fixed = ref_positions(raw, &raw.node_weights);
        assert_eq!(scene.meshes[m1].positions, fixed, "{label}: node weights");
    }
}

fn sample_times(raw: &Raw, rng: &mut Rng) -> Vec<f64> {
    let (a, b) = (raw.times[0], *raw.times.last().unwrap());
    let mut ts: Vec<f64> = (0..25)
        .map(|_| a - 0.3 + (b - a + 0.6) * rng.f() as f64)
        .collect();
    ts.extend(&raw.times);
    // Back to an earlier time: the pose is recomputed from the base, not accumulated.
    ts.push(a);
    ts
}

#[test]
fn loader_matches_the_reference_for_every_storage_and_interpolation() {
    for (seed, interp) in [
        (1u64, "STEP"),
        (2, "LINEAR"),
        (3, "CUBICSPLINE"),
        (4, "LINEAR"),
    ] {
        let (doc, data, raw) = build(seed, interp, &STORES);
        let bytes = glb(&doc, &data);
        let mut scene = load_glb_bytes(&bytes, "m.glb".as_ref()).unwrap();
        // Loaded posed at t = 0 (before the first key: the first key's weights).
        let want0 = ref_positions(&raw, &ref_weights(&raw, 0.0));
        assert!(scene.meshes[0]
            .positions
            .iter()
            .zip(&want0)
            .all(|(a, b)| close(*a, *b)));
        let mut rng = Rng(seed * 77);
        let times = sample_times(&raw, &mut rng);
        check(&mut scene, &raw, &times, interp);
        assert_eq!(
            scene.time_range(),
            (raw.times[0], *raw.times.last().unwrap())
        );
    }
}

#[test]
fn streamed_file_matches_the_reference() {
    // Dense targets only: a plain GLB, read from the file an accessor at a time when posed.
    let (doc, data, raw) = build(9, "LINEAR", &[Store::Dense, Store::Dense, Store::Zero]);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("dense.glb");
    std::fs::write(&p, glb(&doc, &data)).unwrap();
    let mut scene = load_path(&p).unwrap();
    let mut rng = Rng(5);
    let times = sample_times(&raw, &mut rng);
    check(&mut scene, &raw, &times, "streamed");
}

/// Frame every vertex of the scene at `t` from +Z.
fn camera(scene: &TriScene, t: f64) -> Camera {
    let pts = scene.sample_points(t, 1);
    let (lo, hi) = pts.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(l, h), p| (l.min(*p), h.max(*p)),
    );
    let c = 0.5 * (lo + hi);
    let r = (hi - lo).length().max(1e-3);
    Camera::look_at(c + DVec3::new(0.0, 0.0, 2.0 * r), c, DVec3::Y, 50.0, 96, 72).unwrap()
}

#[test]
fn tracer_posed_by_set_time_renders_what_a_fresh_build_renders() {
    let (doc, data, raw) = build(11, "LINEAR", &STORES);
    let mut scene = load_glb_bytes(&glb(&doc, &data), "m.glb".as_ref()).unwrap();
    for m in &mut scene.meshes {
        // The file has no materials: blend, so every layer counts.
        m.tri_material = vec![0u32; m.tris.len()].into();
    }
    scene.materials = blend_materials();
    let opts = RenderOptions::default();
    let mut posed =
        MeshTracer::new(scene.clone(), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let mut differ = 0;
    let first = {
        let cam = camera(&scene, raw.times[0]);
        posed.set_time(raw.times[0]).unwrap();
        posed.render(&cam, raw.times[0], &opts).unwrap().0
    };
    for (i, &t) in raw.times.iter().enumerate().skip(1) {
        let t = t - 0.1 * (i as f64);
        posed.set_time(t).unwrap();
        // The reference: a scene whose mesh 0 holds the reference positions, built fresh.
        let mut fixed = scene.clone();
        fixed.morphs = Default::default();
        fixed.meshes[0].positions = ref_positions(&raw, &ref_weights(&raw, t));
        let m1 = fixed.nodes[1].mesh.unwrap();
        fixed.meshes[m1].positions = ref_positions(&raw, &raw.node_weights);
        let cam = camera(&fixed, t);
        let fresh = MeshTracer::new(fixed, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
        let a = posed.render(&cam, t, &opts).unwrap().0;
        let b = fresh.render(&cam, t, &opts).unwrap().0;
        assert_eq!(common::bits(&a), common::bits(&b), "t = {t}");
        if common::bits(&a) != common::bits(&first) {
            differ += 1;
        }
    }
    // The pose changes the image: a tracer ignoring the weights would fail above, this
    // guards the test itself against a scene that does not move.
    assert!(differ > 0);
}

fn load_err(doc: &Value, data: &[u8]) -> String {
    load_glb_bytes(&glb(doc, data), "bad.glb".as_ref())
        .unwrap_err()
        .to_string()
}

#[test]
fn malformed_morphs_are_clear_errors() {
    let (doc, data, _) = build(21, "LINEAR", &[Store::Dense, Store::Sparse(2, false)]);
    // A weights channel on a node whose mesh has no targets.
    let mut d = doc.clone();
    d["meshes"][0]["primitives"][0]
        .as_object_mut()
        .unwrap()
        .remove("targets");
    d["meshes"][0].as_object_mut().unwrap().remove("weights");
    d["nodes"][1].as_object_mut().unwrap().remove("weights");
    let e = load_err(&d, &data);
    assert!(e.contains("no morph targets"), "{e}");
    // Too few weights for keys × targets.
    let mut d = doc.clone();
    let out = d["animations"][0]["samplers"][0]["output"]
        .as_u64()
        .unwrap() as usize;
    d["accessors"][out]["count"] = json!(9);
    let e = load_err(&d, &data);
    assert!(e.contains("9 weights for 5 keys of 2 morph targets"), "{e}");
    // Node weights of the wrong length.
    let mut d = doc.clone();
    d["nodes"][1]["weights"] = json!([0.5]);
    let e = load_err(&d, &data);
    assert!(e.contains("node 1: node weights"), "{e}");
    // A target with fewer entries than the base.
    let mut d = doc.clone();
    let t0 = d["meshes"][0]["primitives"][0]["targets"][0]["POSITION"]
        .as_u64()
        .unwrap() as usize;
    d["accessors"][t0]["count"] = json!(V - 1);
    let e = load_err(&d, &data);
    assert!(
        e.contains("morph target 0: POSITION has 39 entries for 40 vertices"),
        "{e}"
    );
    // NaN weights in the channel's output (f32 bytes patched in the BIN chunk).
    let mut d2 = data.clone();
    let view = doc["accessors"][out]["bufferView"].as_u64().unwrap() as usize;
    let at = doc["bufferViews"][view]["byteOffset"].as_u64().unwrap() as usize;
    d2[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = load_err(&doc, &d2);
    assert!(e.contains("weights are not finite"), "{e}");
    // Sparse indices out of order.
    let t1 = doc["meshes"][0]["primitives"][0]["targets"][1]["POSITION"]
        .as_u64()
        .unwrap() as usize;
    let sp = &doc["accessors"][t1]["sparse"];
    assert!(
        sp["count"].as_u64().unwrap() >= 2,
        "the sparse target needs two entries"
    );
    {
        let iv = sp["indices"]["bufferView"].as_u64().unwrap() as usize;
        let at = doc["bufferViews"][iv]["byteOffset"].as_u64().unwrap() as usize;
        let mut d3 = data.clone();
        d3[at..at + 2].copy_from_slice(&(V as u16 - 1).to_le_bytes());
        // Weight 1 on target 1 at every time, so the target is read at load.
        let mut d = doc.clone();
        d["animations"] = json!([]);
        d["nodes"][0]["weights"] = json!([0.0, 1.0]);
        let e = load_err(&d, &d3);
        assert!(e.contains("not increasing"), "{e}");
    }
}

#[test]
fn morphed_points_load_with_nothing_to_pose() {
    // POINTS carry no surface: their targets and weights channel are valid glTF, not traced.
    let (mut doc, data, _) = build(23, "STEP", &[Store::Dense, Store::Zero]);
    doc["meshes"][0]["primitives"][0]["mode"] = json!(0);
    let mut scene = load_glb_bytes(&glb(&doc, &data), "points.glb".as_ref()).unwrap();
    assert!(scene.morphs.is_empty());
    assert_eq!(scene.triangle_count(), 0);
    assert!(scene.pose_morphs(1.0).unwrap().is_empty());
}

#[test]
fn a_scene_without_morphs_is_untouched_by_set_time() {
    let mut mesh = Mesh::default();
    common::push_fan(
        &mut mesh,
        0,
        Vec3::ZERO,
        Vec3::X,
        Vec3::Y,
        6,
        Vec3::new(1.0, 0.5, 0.2),
        0.8,
    );
    let scene = TriScene {
        meshes: vec![mesh],
        materials: blend_materials(),
        nodes: vec![Node {
            mesh: Some(0),
            ..Node::default()
        }],
        ..TriScene::default()
    };
    let mut t = MeshTracer::new(scene, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let before = t.scene.meshes[0].positions.clone();
    t.set_time(3.0).unwrap();
    assert_eq!(t.scene.meshes[0].positions, before);
}
