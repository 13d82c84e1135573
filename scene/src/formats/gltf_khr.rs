//! Reader of glTF/GLB files with `KHR_gaussian_splatting` (Khronos, ratified), including the
//! SPZ-compressed variant ([`spz`]).
//!
//! Every primitive carrying the extension becomes Gaussians. Attributes: `POSITION`,
//! `KHR_gaussian_splatting:ROTATION` (x, y, z, w), `…:SCALE` (linear), `…:OPACITY` (after the
//! sigmoid; without it, `COLOR_0`'s alpha), `…:SH_DEGREE_l_COEF_n`. Nodes without animation
//! are baked into one static cloud with their world transforms (uniform scale only; SH are
//! rotated with the Gaussians); animated nodes (LINEAR translation/rotation)
//! become objects of a dynamic scene with tracks; a `splatbridge_root` node written by
//! `splatbridge convert --splats` is undone, so a round trip returns the input frame.
//! Other files are in glTF's frame (+y up, +z front, +x left: LUF), which is a half turn
//! about z from the 3DGS PLY's RDF; the reader turns them back (positions, rotations, SH,
//! object tracks and cameras), the same relation splat-transform's GLB writer and the SPZ
//! variant's LUF rule use, so a PLY converted by either lines up with the PLY.
//! Camera nodes become cameras (with `extras.opencv` intrinsics when present).
//!
//! Hostile input: the node graph must be a tree (each node visited once), accessors are
//! checked against their buffer views before allocation, SPZ buffer views against their
//! buffers, and accessor counts against the SPZ stream's count.

mod document;
pub mod spz;

use std::collections::HashMap;
use std::path::Path;

use glam::{Affine3A, DMat3, DQuat, DVec3, Quat, Vec3};
use serde_json::Value;

use crate::camera::Camera;
use crate::dynamic::{DynamicScene, Pose, PoseKey, SceneObject, TimeRange, Track};
use crate::error::{Result, SceneError};
use crate::gaussians::{logit, sh_coeffs, GaussianCloud};
use crate::sh_rotate::ShRotation;
use document::Document;

/// The extension's name (and its attribute prefix).
pub const EXT: &str = "KHR_gaussian_splatting";

/// Key times, translations and rotations of one animated node.
type NodeAnimation = (Vec<f32>, Option<Vec<f32>>, Option<Vec<f32>>);

/// Read a `KHR_gaussian_splatting` glTF/GLB as a scene.
pub fn read_gltf_splats(path: &Path) -> Result<DynamicScene> {
    let bad = |what: String| SceneError::format(path, what);
    let doc = document::load(path)?;
    let v = &doc.json;
    let nodes: &[Value] = v["nodes"].as_array().map_or(&[], |a| a.as_slice());
    let mut animated: HashMap<usize, NodeAnimation> = HashMap::new();
    for a in v["animations"].as_array().into_iter().flatten() {
        for ch in a["channels"].as_array().into_iter().flatten() {
            let node = ch["target"]["node"]
                .as_u64()
                .ok_or_else(|| bad("animation channel without node".into()))?
                as usize;
            let s = &a["samplers"][ch["sampler"].as_u64().unwrap_or(u64::MAX) as usize];
            let acc = |k: &str| {
                s[k].as_u64()
                    .ok_or_else(|| bad(format!("animation sampler without {k}")))
            };
            let times = doc.read_accessor(path, acc("input")?, 1)?;
            let path_name = ch["target"]["path"].as_str().unwrap_or("");
            let comps = if path_name == "rotation" { 4 } else { 3 };
            let out = doc.read_accessor(path, acc("output")?, comps)?;
            if out.len() != times.len() * comps {
                return Err(bad(format!(
                    "animation of node {node}: {} key times but {} {path_name} values",
                    times.len(),
                    out.len() / comps
                )));
            }
            let e = animated.entry(node).or_insert((times, None, None));
            match path_name {
                "translation" => e.1 = Some(out),
                "rotation" => e.2 = Some(out),
                _ => {}
            }
        }
    }
    let mut scene = DynamicScene::from_static(GaussianCloud::new(0));
    let mut t_range: Option<(f64, f64)> = None;
    let roots: Vec<usize> = v["scenes"][v["scene"].as_u64().unwrap_or(0) as usize]["nodes"]
        .as_array()
        .map(|a| {
            a.iter()
                .map(|x| x.as_u64().map_or(usize::MAX, |x| x as usize))
                .collect()
        })
        .unwrap_or_else(|| (0..nodes.len()).collect());
    let ours = roots.iter().any(|&r| {
        nodes
            .get(r)
            .is_some_and(|n| n["name"] == "splatbridge_root" && n["extras"]["inputUp"].is_string())
    });
    let mut stack: Vec<(usize, Affine3A)> =
        roots.into_iter().map(|r| (r, Affine3A::IDENTITY)).collect();
    let mut visited = vec![false; nodes.len()];
    while let Some((ni, parent)) = stack.pop() {
        let n = nodes
            .get(ni)
            .ok_or_else(|| bad(format!("node {ni} does not exist")))?;
        if std::mem::replace(&mut visited[ni], true) {
            return Err(bad(format!(
                "node {ni} is reached twice; the node hierarchy must be a tree"
            )));
        }
        let ours = n["name"] == "splatbridge_root" && n["extras"]["inputUp"].is_string();
        let local = if ours {
            Affine3A::IDENTITY
        } else {
            node_local(n)
        };
        let world = parent * local;
        for c in n["children"].as_array().into_iter().flatten() {
            stack.push((c.as_u64().map_or(usize::MAX, |c| c as usize), world));
        }
        if let Some(ci) = n["camera"].as_u64() {
            if let Some(cam) = read_camera(
                v,
                ci as usize,
                world,
                n["name"].as_str().unwrap_or("camera"),
            ) {
                scene.cameras.push(cam);
            }
        }
        let Some(mi) = n["mesh"].as_u64() else {
            continue;
        };
        let prims: Vec<&Value> = v["meshes"][mi as usize]["primitives"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|p| p["extensions"][EXT].is_object())
            .collect();
        if prims.is_empty() {
            continue;
        }
        if let Some((times, tr, rot)) = animated.get(&ni) {
            let mut cloud = GaussianCloud::new(0);
            for p in prims {
                read_primitive(path, &doc, p, Affine3A::IDENTITY, &mut cloud)?;
            }
            let keys = times
                .iter()
                .enumerate()
                .map(|(i, &t)| PoseKey {
                    t: t as f64,
                    pose: Pose {
                        translation: tr
                            .as_ref()
                            .map_or(Vec3::ZERO, |x| Vec3::from_slice(&x[3 * i..3 * i + 3])),
                        rotation: rot.as_ref().map_or(Quat::IDENTITY, |x| {
                            Quat::from_slice(&x[4 * i..4 * i + 4]).normalize()
                        }),
                    },
                })
                .collect::<Vec<_>>();
            if let (Some(f), Some(l)) = (keys.first(), keys.last()) {
                t_range = Some(t_range.map_or((f.t, l.t), |(a, b)| (a.min(f.t), b.max(l.t))));
            }
            scene.objects.push(SceneObject {
                name: n["name"].as_str().unwrap_or("object").to_string(),
                gaussians: cloud,
                track: Track { keys },
            });
        } else {
            for p in prims {
                read_primitive(path, &doc, p, world, &mut scene.static_gaussians)?;
            }
        }
    }
    if let Some((a, b)) = t_range {
        scene.time = TimeRange {
            start: a,
            end: b,
            fps: scene.time.fps.max(30.0),
        };
    }
    // Objects in file order (the stack visits children last-first).
    scene.objects.reverse();
    scene.cameras.reverse();
    if scene.gaussian_count() == 0 {
        return Err(no_gaussians(path, v));
    }
    if !ours {
        half_turn_z(&mut scene);
    }
    Ok(scene)
}

/// The error for a glTF without a single Gaussian, saying what it holds instead: an empty
/// scene is never returned, so no command reports "0 Gaussians" or writes an empty output.
fn no_gaussians(path: &Path, v: &Value) -> SceneError {
    let primitives: usize = v["meshes"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|m| m["primitives"].as_array().map_or(0, |p| p.len()))
        .sum();
    let what = if primitives > 0 {
        format!(
            "holds no Gaussians: its {primitives} mesh primitives are triangles or points \
             without {EXT} (a mesh glTF is traced as a mesh, not read as splats)"
        )
    } else {
        format!("holds neither Gaussians ({EXT}) nor meshes: there is nothing to read")
    };
    SceneError::format(path, what)
}

/// Sign of each SH coefficient (coefficient-major, after DC) under a half turn about z
/// (x and y negated): (−1)^m in the 3DGS order (y, z, x; xy, yz, 3z²−1, xz, x²−y²; …).
const SH_HALF_TURN_Z: [f32; 15] = [
    -1.0, 1.0, -1.0, // degree 1
    1.0, -1.0, 1.0, -1.0, 1.0, // degree 2
    -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0, // degree 3
];

/// `qz · q` for the half turn qz = (0, 0, 1, 0) about z, exactly (a permutation with signs).
fn half_turn_quat(q: Quat) -> Quat {
    Quat::from_xyzw(-q.y, q.x, q.w, -q.z)
}

/// glTF's LUF to the PLY's RDF: a half turn about z, applied exactly (sign flips and
/// permutations, no rounding) to the world-space Gaussians, object tracks and cameras.
fn half_turn_z(scene: &mut DynamicScene) {
    let c = &mut scene.static_gaussians;
    for m in &mut c.means {
        *m *= Vec3::new(-1.0, -1.0, 1.0);
    }
    for q in &mut c.rotations {
        *q = half_turn_quat(*q);
    }
    let k = c.coeffs();
    if k > 1 {
        for g in c.sh.chunks_mut(k) {
            for (j, s) in g[1..].iter_mut().enumerate() {
                *s *= SH_HALF_TURN_Z[j];
            }
        }
    }
    for o in &mut scene.objects {
        for key in &mut o.track.keys {
            key.pose.translation *= Vec3::new(-1.0, -1.0, 1.0);
            key.pose.rotation = half_turn_quat(key.pose.rotation);
        }
    }
    let h = DVec3::new(-1.0, -1.0, 1.0);
    for cam in &mut scene.cameras {
        cam.centre *= h;
        cam.world_to_cam *= DMat3::from_diagonal(h);
    }
}

/// Whether any splat primitive of the file's JSON uses the SPZ variant (for `info`).
pub fn uses_spz(json: &Value) -> bool {
    json["extensionsUsed"].as_array().is_some_and(|a| {
        a.iter()
            .any(|e| spz::SPZ_EXTENSIONS.iter().any(|n| e.as_str() == Some(n)))
    })
}

fn node_local(n: &Value) -> Affine3A {
    let arr = |k: &str, d: &[f32]| -> Vec<f32> {
        n[k].as_array()
            .filter(|a| a.len() == d.len())
            .map(|a| a.iter().map(|x| x.as_f64().unwrap_or(0.0) as f32).collect())
            .unwrap_or_else(|| d.to_vec())
    };
    if let Some(m) = n["matrix"].as_array() {
        let m: Vec<f32> = m.iter().map(|x| x.as_f64().unwrap_or(0.0) as f32).collect();
        if m.len() == 16 {
            return Affine3A::from_mat4(glam::Mat4::from_cols_slice(&m));
        }
    }
    let t = arr("translation", &[0.0; 3]);
    let r = arr("rotation", &[0.0, 0.0, 0.0, 1.0]);
    let s = arr("scale", &[1.0; 3]);
    Affine3A::from_scale_rotation_translation(
        Vec3::from_slice(&s),
        Quat::from_slice(&r).normalize(),
        Vec3::from_slice(&t),
    )
}

/// The SPZ buffer view of a compressed primitive, if it is one.
fn spz_view(prim: &Value) -> Option<u64> {
    let nested = &prim["extensions"][EXT]["extensions"];
    spz::SPZ_EXTENSIONS
        .iter()
        .find_map(|name| nested[*name]["bufferView"].as_u64())
}

/// The Gaussians of one primitive in its mesh's local frame.
fn primitive_cloud(path: &Path, doc: &Document, prim: &Value) -> Result<GaussianCloud> {
    let bad = |what: String| SceneError::format(path, what);
    let attrs = &prim["attributes"];
    if let Some(view) = spz_view(prim) {
        let bytes = doc.view_bytes(path, view)?;
        let cloud = spz::decode_khr_spz(&bytes, path)?;
        // The extension requires every accessor's count to match the stream's.
        for (name, a) in attrs.as_object().into_iter().flatten() {
            if let Some(a) = a.as_u64() {
                let n = doc.accessor_count(path, a)?;
                if n != cloud.len() as u64 {
                    return Err(bad(format!(
                        "accessor {a} ({name}) has count {n}, the SPZ stream holds {} Gaussians",
                        cloud.len()
                    )));
                }
            }
        }
        return Ok(cloud);
    }
    let acc = |name: &str, comps: usize| -> Result<Option<document::Accessor>> {
        attrs[name]
            .as_u64()
            .map(|a| doc.accessor(path, a, comps))
            .transpose()
    };
    let need = |name: &str, comps: usize| -> Result<document::Accessor> {
        acc(name, comps)?.ok_or_else(|| bad(format!("splat primitive lacks {name}")))
    };
    // Every attribute is read element by element from the file straight into the cloud's
    // arrays, so the peak is the cloud plus one block of the file.
    let pos = need("POSITION", 3)?;
    let n = pos.count as usize;
    let mut degree = 0u8;
    while degree < 3 && attrs[format!("{EXT}:SH_DEGREE_{}_COEF_0", degree + 1)].is_u64() {
        degree += 1;
    }
    let mismatch = |name: &str| {
        bad(format!(
            "splat attributes have different counts ({name} vs POSITION's {n})"
        ))
    };
    let checked = |name: &str, a: document::Accessor| {
        if a.count == n as u64 {
            Ok(a)
        } else {
            Err(mismatch(name))
        }
    };
    let mut part = GaussianCloud::new(degree);
    part.means.reserve_exact(n);
    doc.for_each(&pos, |v| part.means.push(Vec3::from_slice(v)))?;
    let name = format!("{EXT}:ROTATION");
    let rot = checked(&name, need(&name, 4)?)?;
    part.rotations.reserve_exact(n);
    doc.for_each(&rot, |v| part.rotations.push(Quat::from_slice(v)))?;
    let name = format!("{EXT}:SCALE");
    let scale = checked(&name, need(&name, 3)?)?;
    part.log_scales.reserve_exact(n);
    doc.for_each(&scale, |c| {
        part.log_scales
            .push(Vec3::new(c[0].ln(), c[1].ln(), c[2].ln()))
    })?;
    part.opacity_logits.reserve_exact(n);
    match acc(&format!("{EXT}:OPACITY"), 1)? {
        Some(o) => {
            let o = checked("OPACITY", o)?;
            doc.for_each(&o, |v| part.opacity_logits.push(logit(v[0])))?;
        }
        None => {
            let c = checked("OPACITY", need("COLOR_0", 4)?)?;
            doc.for_each(&c, |v| part.opacity_logits.push(logit(v[3])))?;
        }
    }
    let k = sh_coeffs(degree);
    part.sh = vec![Vec3::ZERO; n * k];
    let mut j = 0;
    for l in 0..=degree as usize {
        for c in 0..2 * l + 1 {
            let name = format!("{EXT}:SH_DEGREE_{l}_COEF_{c}");
            let col = checked(&name, need(&name, 3)?)?;
            let mut i = 0;
            doc.for_each(&col, |v| {
                part.sh[i * k + j] = Vec3::from_slice(v);
                i += 1;
            })?;
            j += 1;
        }
    }
    Ok(part)
}

/// Read the Gaussians of one splat primitive into `cloud`, transformed by `xf`.
fn read_primitive(
    path: &Path,
    doc: &Document,
    prim: &Value,
    xf: Affine3A,
    cloud: &mut GaussianCloud,
) -> Result<()> {
    let mut part = primitive_cloud(path, doc, prim)?;
    let (s, r, _) = xf.to_scale_rotation_translation();
    if (s.x - s.y).abs() > 1e-4 * s.x.abs() || (s.x - s.z).abs() > 1e-4 * s.x.abs() {
        return Err(SceneError::format(
            path,
            format!("node scale {s} is not uniform; splats cannot be baked through it"),
        ));
    }
    if xf != Affine3A::IDENTITY {
        let ls = s.x.ln();
        let k = part.coeffs();
        for i in 0..part.len() {
            part.means[i] = xf.transform_point3(part.means[i]);
            part.log_scales[i] += Vec3::splat(ls);
            part.rotations[i] = r * part.rotations[i];
        }
        if k > 1 && r != Quat::IDENTITY {
            let (degree, rot) = (part.sh_degree, ShRotation::from_quat(r));
            for g in part.sh.chunks_mut(k) {
                rot.apply(degree, g);
            }
        }
    }
    if cloud.is_empty() && cloud.sh_degree < part.sh_degree {
        cloud.sh_degree = part.sh_degree;
    }
    if part.sh_degree != cloud.sh_degree {
        // Bring the part to the cloud's degree (truncate, or pad with zeros).
        let mut p = GaussianCloud::with_capacity(cloud.sh_degree, part.len());
        let k = cloud.coeffs();
        let mut coeffs = vec![Vec3::ZERO; k];
        for i in 0..part.len() {
            let src = part.sh_of(i);
            for (j, c) in coeffs.iter_mut().enumerate() {
                *c = src.get(j).copied().unwrap_or(Vec3::ZERO);
            }
            p.push(
                part.means[i],
                part.log_scales[i],
                part.rotations[i],
                part.opacity_logits[i],
                &coeffs,
            );
        }
        part = p;
    }
    if cloud.is_empty() && cloud.sh_degree == part.sh_degree && cloud.object_ids.is_none() {
        *cloud = part;
    } else {
        cloud.extend_from(&part, None);
    }
    Ok(())
}

fn read_camera(v: &Value, ci: usize, world: Affine3A, name: &str) -> Option<Camera> {
    let c = &v["cameras"][ci];
    let cv = &c["extras"]["opencv"];
    let p = &c["perspective"];
    let yfov = p["yfov"].as_f64()?;
    let (w, h, fx, fy, cx, cy) = if cv.is_object() {
        (
            u32::try_from(cv["width"].as_u64()?).ok()?,
            u32::try_from(cv["height"].as_u64()?).ok()?,
            cv["fx"].as_f64()?,
            cv["fy"].as_f64()?,
            cv["cx"].as_f64()?,
            cv["cy"].as_f64()?,
        )
    } else {
        let aspect = p["aspectRatio"].as_f64().unwrap_or(1.0);
        let h = 1000u32;
        let w = (h as f64 * aspect).round().clamp(1.0, 1e5) as u32;
        let f = h as f64 / (2.0 * (yfov / 2.0).tan());
        (w, h, f, f, w as f64 / 2.0, h as f64 / 2.0)
    };
    let (_, r, t) = world.to_scale_rotation_translation();
    let r = DQuat::from_xyzw(r.x as f64, r.y as f64, r.z as f64, r.w as f64);
    let c2w = DMat3::from_quat(r) * DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
    Some(Camera {
        width: w,
        height: h,
        fx,
        fy,
        cx,
        cy,
        centre: t.as_dvec3(),
        world_to_cam: c2w.transpose(),
        name: name.to_string(),
    })
}
