//! The morph-target encoding of `--frames` (`frames_morph`) against the per-frame writers
//! (`frames_gltf`, the references): at every frame, base + that frame's target equals that
//! frame as `convert` writes it alone (the per-frame folder's GLB, `_GAUSSIAN_ID`s from 0) and,
//! without `--coplanar-offset` (which moves each Gaussian by an amount keyed by its global id,
//! and a per-frame node's ids start after the earlier frames'), the per-frame node's vertices;
//! the weights animation turns exactly that target on at the frame's key time (the nodes' key
//! time); sparse targets where few vertices move; sequences whose topology or colours change
//! are refused, leaving nothing behind; the files are validator-clean.

use std::path::Path;

use glam::{Quat, Vec3};
use splatbridge_convert::frames_gltf::{write_frames_dir, write_frames_file, FramesLimits};
use splatbridge_convert::frames_morph::write_frames_morph;
use splatbridge_convert::{ConvertOptions, Profile};
use splatbridge_scene::GaussianCloud;

/// Frame `f` of a capture with fixed topology: `n` Gaussians, the first `moving` of them
/// translated and turned with `f` (flat and volumetric), the rest still; one faded Gaussian
/// (culled in every frame alike); colours fixed.
fn frame(f: usize, n: usize, moving: usize) -> GaussianCloud {
    let mut c = GaussianCloud::new(0);
    for i in 0..n {
        let u = i as f32 / n as f32;
        let m = if i < moving { f as f32 } else { 0.0 };
        let pos = Vec3::new((i % 13) as f32 * 0.1, (i / 13) as f32 * 0.1, u * 0.3)
            + Vec3::new(0.05, 0.02, -0.03) * m;
        let scale = if i % 3 == 0 {
            Vec3::new(0.04, 0.03, 0.0005)
        } else {
            Vec3::new(0.03, 0.02 + 0.01 * u, 0.015)
        };
        let rot = Quat::from_rotation_y(u * 2.0 + m * 0.2);
        let opacity = if i == 5 { 0.001 } else { 0.2 + 0.7 * u };
        c.push_activated(pos, scale, rot, opacity, Vec3::new(u, 1.0 - u, 0.5));
    }
    c
}

fn capture(n: usize, moving: usize, frames: usize) -> (Vec<GaussianCloud>, Vec<f64>) {
    let clouds = (0..frames).map(|f| frame(f, n, moving)).collect();
    // 0.1 s is not an f32: the key times are rounded down (`frame_key_times`) in both files.
    let times = (0..frames).map(|f| f as f64 * 0.1).collect();
    (clouds, times)
}

/// The option sets a morph file can take: every profile, with and without normals and ids.
fn option_sets() -> Vec<(&'static str, ConvertOptions)> {
    vec![
        (
            "texture, no normals, coplanar offset",
            ConvertOptions {
                profile: Profile::Texture,
                coplanar_offset: true,
                normals: false,
                ..ConvertOptions::default()
            },
        ),
        ("meshsplats, normals", ConvertOptions::default()),
        (
            "rings, no ids",
            ConvertOptions {
                profile: Profile::Rings,
                gaussian_ids: false,
                ..ConvertOptions::default()
            },
        ),
    ]
}

struct Read {
    doc: gltf::Document,
    buffers: Vec<gltf::buffer::Data>,
}

fn open(p: &Path) -> Read {
    let (doc, buffers, _) = gltf::import(p).unwrap();
    Read { doc, buffers }
}

/// Per-frame node `frame_NNNN`'s positions and normals (empty without normals).
fn node_frame(r: &Read, f: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let name = format!("frame_{f:04}");
    let node = r
        .doc
        .nodes()
        .find(|n| n.name() == Some(&name))
        .unwrap_or_else(|| panic!("no node {name}"));
    let prim = node.mesh().unwrap().primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&r.buffers[b.index()]));
    let p = reader.read_positions().unwrap().collect();
    let n = reader
        .read_normals()
        .map(|n| n.collect())
        .unwrap_or_default();
    (p, n)
}

/// Frame `f` of a per-frame folder: its one mesh's positions and normals.
fn alone_frame(dir: &Path, f: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let r = open(&dir.join(format!("frame_{f:04}.glb")));
    let prim = r.doc.meshes().next().unwrap().primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&r.buffers[b.index()]));
    let p = reader.read_positions().unwrap().collect();
    let n = reader
        .read_normals()
        .map(|n| n.collect())
        .unwrap_or_default();
    (p, n)
}

/// The slow reference of a morph viewer at frame `f`: base + target `f - 1` (weight 1), added
/// in f32 as three.js and Blender add them.
fn morph_frame(r: &Read, f: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let mesh = r.doc.meshes().next().unwrap();
    let prim = mesh.primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&r.buffers[b.index()]));
    let mut p: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    let mut n: Vec<[f32; 3]> = reader
        .read_normals()
        .map(|n| n.collect())
        .unwrap_or_default();
    if f > 0 {
        let (dp, dn, _) = reader.read_morph_targets().nth(f - 1).unwrap();
        // An accessor with neither buffer view nor sparse part is all zeros.
        let add = |v: &mut Vec<[f32; 3]>, d: Option<Vec<[f32; 3]>>| {
            if let Some(d) = d {
                assert_eq!(d.len(), v.len());
                for (x, d) in v.iter_mut().zip(d) {
                    for i in 0..3 {
                        x[i] += d[i];
                    }
                }
            }
        };
        add(&mut p, dp.map(|i| i.collect()));
        add(&mut n, dn.map(|i| i.collect()));
    }
    (p, n)
}

/// `a` (base `a0` + delta) equals `b` within f32 rounding: the delta `b - a0` and the sum
/// `a0 + delta` each round once to the nearest f32 (half an ulp of |b - a0| ≤ |a0| + |b|,
/// then half an ulp of |b|), so 2 ε max(|a0|, |b|) bounds the difference.
fn close(a0: &[[f32; 3]], a: &[[f32; 3]], b: &[[f32; 3]], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: vertex count");
    for (v, (x, y)) in a.iter().zip(b).enumerate() {
        for i in 0..3 {
            let tol = 2.0 * f32::EPSILON * a0[v][i].abs().max(y[i].abs());
            assert!(
                (x[i] - y[i]).abs() <= tol,
                "{what}: vertex {v} axis {i}: {} vs {}",
                x[i],
                y[i]
            );
        }
    }
}

#[test]
fn every_frame_of_the_morph_file_is_the_per_frame_node() {
    let dir = tempfile::tempdir().unwrap();
    // Half the Gaussians move: sparse targets; all move: dense targets.
    for (moving, n) in [(40, 120), (120, 120)] {
        let (clouds, times) = capture(n, moving, 5);
        for (name, opts) in option_sets() {
            let alone = dir.path().join(format!("alone-{moving}-{name}"));
            write_frames_dir(&alone, &clouds[..], &times, 30.0, &opts).unwrap();
            for ext in ["glb", "gltf"] {
                let nodes = dir.path().join(format!("nodes.{ext}"));
                let morph = dir.path().join(format!("morph.{ext}"));
                write_frames_file(&nodes, &clouds[..], &times, &opts, &FramesLimits::default())
                    .unwrap();
                let r = write_frames_morph(
                    &morph,
                    &clouds[..],
                    &times,
                    &opts,
                    &FramesLimits::default(),
                    &[],
                )
                .unwrap();
                let (a, b) = (open(&nodes), open(&morph));
                assert_eq!(b.doc.meshes().count(), 1, "{name}");
                let prim = b.doc.meshes().next().unwrap().primitives().next().unwrap();
                assert_eq!(prim.morph_targets().count(), 4, "{name}");
                let sparse = b.doc.accessors().filter(|a| a.sparse().is_some()).count();
                if moving < n {
                    assert!(sparse >= 4, "{name}: {sparse} sparse accessors");
                } else {
                    assert_eq!(sparse, 0, "{name}: every vertex moves, dense is smaller");
                }
                for f in 0..clouds.len() {
                    let (mp, mn) = morph_frame(&b, f);
                    let (bp, bn) = morph_frame(&b, 0);
                    let (ap, an) = alone_frame(&alone, f);
                    close(
                        &bp,
                        &mp,
                        &ap,
                        &format!("{name} {ext} frame {f} positions, alone"),
                    );
                    close(
                        &bn,
                        &mn,
                        &an,
                        &format!("{name} {ext} frame {f} normals, alone"),
                    );
                    if !opts.coplanar_offset {
                        let (np, nn) = node_frame(&a, f);
                        close(
                            &bp,
                            &mp,
                            &np,
                            &format!("{name} {ext} frame {f} positions, node"),
                        );
                        close(
                            &bn,
                            &mn,
                            &nn,
                            &format!("{name} {ext} frame {f} normals, node"),
                        );
                    }
                    // Indices and the other attributes are frame 0's in the morph file.
                    let read_idx = |r: &Read, p: gltf::Primitive<'_>| -> Vec<u32> {
                        let rd = p.reader(|b| Some(&r.buffers[b.index()]));
                        rd.read_indices().unwrap().into_u32().collect()
                    };
                    let node = a
                        .doc
                        .nodes()
                        .find(|x| x.name() == Some(&format!("frame_{f:04}")))
                        .unwrap();
                    let np0 = node.mesh().unwrap().primitives().next().unwrap();
                    assert_eq!(read_idx(&a, np0), read_idx(&b, prim.clone()), "{name}");
                }
                if moving < n && ext == "glb" {
                    let (sn, sm) = (
                        std::fs::metadata(&nodes).unwrap().len(),
                        std::fs::metadata(&morph).unwrap().len(),
                    );
                    assert!(sm < sn, "{name}: morph {sm} B, nodes {sn} B");
                    assert_eq!(r.bytes, sm);
                }
                check_animation(&a, &b, clouds.len(), name);
            }
        }
    }
}

/// The weights animation: STEP, keyed at the nodes' key times, target `f - 1` alone on
/// from frame `f`'s key.
fn check_animation(nodes: &Read, morph: &Read, frames: usize, name: &str) {
    let times = |r: &Read| -> Vec<f32> {
        let ch = r
            .doc
            .animations()
            .next()
            .unwrap()
            .channels()
            .next()
            .unwrap();
        let rd = ch.reader(|b| Some(&r.buffers[b.index()]));
        rd.read_inputs().unwrap().collect()
    };
    assert_eq!(times(nodes), times(morph), "{name}: key times");
    let anim = morph.doc.animations().next().unwrap();
    let ch = anim.channels().next().unwrap();
    assert_eq!(
        ch.sampler().interpolation(),
        gltf::animation::Interpolation::Step
    );
    assert_eq!(
        ch.target().property(),
        gltf::animation::Property::MorphTargetWeights
    );
    let rd = ch.reader(|b| Some(&morph.buffers[b.index()]));
    let w: Vec<f32> = match rd.read_outputs().unwrap() {
        gltf::animation::util::ReadOutputs::MorphTargetWeights(w) => w.into_f32().collect(),
        _ => panic!("{name}: not weights"),
    };
    let k = frames - 1;
    assert_eq!(w.len(), frames * k);
    for f in 0..frames {
        for t in 0..k {
            let on = if t + 1 == f { 1.0 } else { 0.0 };
            assert_eq!(w[f * k + t], on, "{name}: frame {f} target {t}");
        }
    }
}

#[test]
fn changing_topology_or_colours_is_refused_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.glb");
    let opts = ConvertOptions::default();
    let lim = FramesLimits::default();
    // A frame with fewer Gaussians.
    let (mut clouds, times) = capture(60, 20, 4);
    clouds[2] = frame(2, 50, 20);
    let e = write_frames_morph(&out, &clouds[..], &times, &opts, &lim, &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("frame 2") && e.contains("topology"), "{e}");
    // A Gaussian flattened in one frame: same count, another fan.
    let (mut clouds, times) = capture(60, 20, 4);
    clouds[3].log_scales[1] = Vec3::new(0.04f32.ln(), 0.03f32.ln(), 0.0001f32.ln());
    let e = write_frames_morph(&out, &clouds[..], &times, &opts, &lim, &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("frame 3") && e.contains("topology"), "{e}");
    // A colour change.
    let (mut clouds, times) = capture(60, 20, 4);
    clouds[1] = {
        let mut c = frame(1, 60, 20);
        c.sh[4].x += 0.5;
        c
    };
    let e = write_frames_morph(&out, &clouds[..], &times, &opts, &lim, &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("frame 1") && e.contains("colour"), "{e}");
    // Chunked layouts reorder each frame.
    let (clouds, times) = capture(60, 20, 4);
    let viewers = ConvertOptions::default().for_viewers();
    let e = write_frames_morph(&out, &clouds[..], &times, &viewers, &lim, &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("m.glb") && e.contains("viewer layout"), "{e}");
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn one_frame_is_a_plain_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("one.glb");
    let (clouds, times) = capture(30, 10, 1);
    write_frames_morph(
        &out,
        &clouds[..],
        &times,
        &ConvertOptions::default(),
        &FramesLimits::default(),
        &[],
    )
    .unwrap();
    let r = open(&out);
    assert_eq!(r.doc.animations().count(), 0);
    let prim = r.doc.meshes().next().unwrap().primitives().next().unwrap();
    assert_eq!(prim.morph_targets().count(), 0);
}

/// Sparse, dense and all-zero targets (a frame equal to frame 0), GLB and glTF, pass the
/// Khronos glTF-Validator with 0 errors and 0 warnings (`scripts/validate-exports.sh --mesh`).
#[test]
#[cfg_attr(
    not(gltf_tools),
    ignore = "needs the glTF validator wrapper (../shared/tools), node and npm"
)]
fn morph_files_are_validator_clean() {
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for (moving, n, big) in [(40, 120, false), (120, 120, false), (20, 70_000, true)] {
        let (mut clouds, mut times) = capture(n, moving, 4);
        // A still frame: its target is all zeros.
        clouds.insert(1, clouds[0].clone());
        times.push(0.4);
        for (name, opts) in option_sets().into_iter().take(if big { 1 } else { 3 }) {
            for ext in ["glb", "gltf"] {
                let slug = name.replace([' ', ','], "_");
                let p = dir.path().join(format!("m-{moving}-{n}-{slug}.{ext}"));
                write_frames_morph(
                    &p,
                    &clouds[..],
                    &times,
                    &opts,
                    &FramesLimits::default(),
                    &[],
                )
                .unwrap();
                files.push(p);
            }
        }
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/validate-exports.sh");
    let out = std::process::Command::new(&script)
        .arg("--mesh")
        .args(&files)
        .output()
        .expect("run validate-exports.sh");
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}{}", String::from_utf8_lossy(&out.stderr));
    match out.status.code() {
        Some(0) => {
            let lines: Vec<&str> = stdout.lines().filter(|l| l.starts_with('{')).collect();
            assert_eq!(lines.len(), files.len());
            // Not even hints (a vertex attribute's buffer view without its target).
            for l in lines {
                assert!(l.contains("\"infos\":0,\"hints\":0"), "{l}");
            }
        }
        c => panic!("validator reported problems (exit {c:?}):\n{stdout}"),
    }
}
