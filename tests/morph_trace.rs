//! The morph-target encoding of a 4D sequence (`convert::frames_morph`) traced against the
//! per-frame-node encoding (`convert::frames_gltf`, input layout) of the same sequence: a
//! sequence with known motion cut from a real capture, both files loaded by the tracer and
//! rendered at 12 times (between keys and on them), images compared pixel for pixel.
//!
//! The morph file's frame f is `base + 1·Δ_f` with `Δ_f = frame f − frame 0` rounded to f32 by
//! the writer, and the tracer sums in f64 and rounds once; the per-frame node holds frame f as
//! written. So a vertex can differ from the node's by the delta's rounding (the bound is at
//! `within_rounding`): the test checks that bound on every vertex, and that the images agree
//! to float noise (the tolerance's origin is at the assertion), not bit for bit.

use std::path::{Path, PathBuf};

use splatbridge_convert::frames_gltf::{write_frames_file, FramesLimits};
use splatbridge_convert::frames_morph::write_frames_morph;
use splatbridge_convert::ConvertOptions;
use splatbridge_raytrace::{BackendKind, BuildPreset, MeshTracer, RenderOptions, TriScene};
use splatbridge_scene::camera::OrbitRig;
use splatbridge_scene::fixtures::moving::{moving_cutouts, MovingParams};
use splatbridge_scene::metrics::psnr;
use splatbridge_scene::ply::ReadOptions;

fn real(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/real")).join(name)
}

fn load(path: &Path) -> TriScene {
    let mut tri = splatbridge_raytrace::scene_load::load_path(path).unwrap();
    tri.to_capture_frame();
    tri
}

/// The morph file's vertex `a` against the node's `b`, frame 0's being `p0`: the writer's
/// delta `b − p0` rounded to f32 errs by at most ε/2·|b − p0| ≤ ε/2·(|p0| + |b|), and the
/// tracer's one rounding of the sum by ε/2·|b| more (ε = 2⁻²³, a unit step at 1), so
/// |a − b| ≤ ε·(|p0| + |b|).
fn within_rounding(a: f32, b: f32, p0: f32) -> bool {
    a == b || (a - b).abs() <= f32::EPSILON * (p0.abs() + b.abs())
}

fn check(noise: f64, label: &str) {
    let (mut base, _) =
        splatbridge_scene::ply::read_ply(&real("fourth_st.ply"), &ReadOptions::default()).unwrap();
    // Every 40th Gaussian (3,280): twelve frames of meshes stay small.
    base.retain_indices(|i| i % 40 == 0);
    let params = MovingParams {
        frames: 12,
        noise,
        ..MovingParams::default()
    };
    let (frames, times, _) = moving_cutouts(&base, &params);
    let dir = tempfile::tempdir().unwrap();
    // Convert's defaults: input layout, no coplanar offset (which moves a Gaussian by an amount
    // keyed by its global id, different in the two files).
    let opts = ConvertOptions::default();
    let nodes = dir.path().join("nodes.glb");
    let morph = dir.path().join("morph.glb");
    let limits = FramesLimits::default();
    write_frames_file(&nodes, &frames[..], &times, &opts, &limits).unwrap();
    write_frames_morph(&morph, &frames[..], &times, &opts, &limits, &[]).unwrap();

    let (tn, mut m) = (load(&nodes), load(&morph));
    assert_eq!(m.meshes.len(), 1, "{label}: one morphed mesh");
    let keys = m.morphs.meshes[0].channel.as_ref().unwrap().times.clone();
    assert_eq!(keys.len(), frames.len());
    // Vertices: frame f of the morph file against the node of frame f.
    for (f, &t) in keys.iter().enumerate() {
        m.pose_morphs(t).unwrap();
        let node = tn.instances(t);
        assert_eq!(node.len(), 1, "{label}: one node shown at {t}");
        let want = &tn.meshes[node[0].mesh].positions;
        let got = &m.meshes[0].positions;
        let p0 = &m.morphs.meshes[0].base;
        assert_eq!(got.len(), want.len());
        let mut off = 0;
        for ((a, b), z) in got.iter().zip(want).zip(p0) {
            assert!(
                (0..3).all(|k| within_rounding(a[k], b[k], z[k])),
                "{label} frame {f}: {a} vs {b} (frame 0 {z})"
            );
            off += usize::from(a != b);
        }
        eprintln!(
            "{label} frame {f}: {off} of {} vertices differ by rounding",
            got.len()
        );
    }

    let rig = OrbitRig {
        width: 128,
        height: 96,
        ..OrbitRig::default()
    };
    let cam = rig.cameras(&frames[0], 4).unwrap().remove(1);
    let nt = MeshTracer::new(tn, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let mut mt = MeshTracer::new(load(&morph), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let ropts = RenderOptions::default();
    let dt = keys[1] - keys[0];
    // Between keys, on keys, and the sequence played backwards (each pose from the base).
    let mut ts: Vec<f64> = keys.iter().step_by(2).map(|&k| k + 0.5 * dt).collect();
    ts.extend([keys[1], keys[5], keys[11], keys[0] - 1.0, keys[11] + 1.0]);
    ts.extend(keys.iter().rev().step_by(3).map(|&k| k + 0.25 * dt));
    let first = {
        mt.set_time(keys[0]).unwrap();
        mt.render(&cam, keys[0], &ropts).unwrap().0
    };
    let (mut moved, mut worst) = (0, 0.0f32);
    for &t in &ts {
        mt.set_time(t).unwrap();
        let a = mt.render(&cam, t, &ropts).unwrap().0;
        let b = nt.render(&cam, t, &ropts).unwrap().0;
        let differ = a
            .rgb
            .chunks(3)
            .zip(b.rgb.chunks(3))
            .filter(|(x, y)| x != y)
            .count();
        let most = a
            .rgb
            .iter()
            .zip(&b.rgb)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f32, f32::max);
        let p = psnr(&a, &b).unwrap();
        let p0 = psnr(&a, &first).unwrap();
        eprintln!("{label} t = {t:.3}: {differ} pixels differ, by at most {most:e}, {p:.1} dB (vs frame 0: {p0:.1} dB)");
        worst = worst.max(most);
        if a.rgb != first.rgb {
            moved += 1;
        }
    }
    // A vertex off by the delta's rounding (~1e-7 relative) moves where a ray crosses its
    // triangles by as little: the composited colour changes in its last bits, never by a
    // display step. Measured: at most 92 of 12,288 pixels differ, by at most 3.7e-6 (150+ dB),
    // while each time differs from frame 0 by ~36 dB; 1e-5 is that worst case with margin and
    // 1/400 of an 8-bit step (a missed or extra layer changes a pixel by 1e-2 or more).
    assert!(worst <= 1e-5, "{label}: pixels differ by up to {worst}");
    assert!(moved >= ts.len() / 2, "{label}: the sequence barely moves");
}

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn morph_file_traces_like_per_frame_nodes_with_every_vertex_moving() {
    check(MovingParams::default().noise, "jittered");
}

#[test]
#[cfg_attr(
    not(real_data),
    ignore = "needs the shared real scenes (../shared/data/real)"
)]
fn morph_file_traces_like_per_frame_nodes_with_a_still_background() {
    check(0.0, "still background");
}
