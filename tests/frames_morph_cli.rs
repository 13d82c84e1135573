//! `convert SEQUENCE --frames --frames-encoding nodes|morph` through the CLI: a numbered frame
//! sequence made from the committed cut of a real capture (`fixtures/formats/cut300.ply`, 300
//! Gaussians of `fourth_st`) with part of it moving, written both ways in the input layout
//! and traced by `trace --time` at several times: the two files show the same frames. Then the
//! refusals: a frame of another topology (named), the default viewer layout (the option to
//! use named), a folder output, an input that is not 4D; each exit 2, nothing written.

mod cli_common;

use std::path::{Path, PathBuf};

use cli_common::{cut300, cut300_eye, ok, path, run, temp_dir};
use glam::Vec3;
use splatbridge_scene::image_io::load_png;
use splatbridge_scene::ply::write_ply;

/// Six frames (at i/30 s): the first 100 Gaussians drive along +x, the rest stay; with `drop`
/// frame 3 loses its last Gaussian.
fn sequence(dir: &Path, drop: bool) -> PathBuf {
    let c = cut300();
    let (lo, hi) = c.bounds().expect("the cut has Gaussians");
    let step = 0.04 * (hi - lo).length();
    let seq = dir.join(if drop { "dropped" } else { "frames" });
    std::fs::create_dir_all(&seq).unwrap();
    for i in 0..6 {
        let mut f = c.clone();
        for m in f.means.iter_mut().take(100) {
            *m += Vec3::X * step * i as f32;
        }
        if drop && i == 3 {
            f.retain_indices(|k| k + 1 < c.len());
        }
        write_ply(
            &seq.join(format!("shot_{:04}.ply", i + 1)),
            &f,
            Default::default(),
        )
        .unwrap();
    }
    seq
}

/// Trace `file` at `t` from a fixed eye (64×48; an orbit camera would frame each file's
/// bounds, which differ by the vertices' rounding) and return the decoded image.
fn trace(file: &Path, t: f64, out: &Path) -> Vec<f32> {
    let ts = t.to_string();
    let eye = cut300_eye(1.5);
    let mut args = vec![
        "trace",
        path(file),
        "--time",
        &ts,
        "--width",
        "64",
        "--height",
        "48",
    ];
    args.extend(eye.iter().map(String::as_str));
    args.extend(["-o", path(out)]);
    ok(&args);
    load_png(out).unwrap().rgb
}

#[test]
fn both_encodings_trace_alike_at_several_times() {
    let dir = temp_dir("frames", "morph");
    let seq = sequence(&dir, false);
    let nodes = dir.join("nodes.glb");
    let morph = dir.join("morph.glb");
    // Without the coplanar offset, which moves a Gaussian by a step keyed by its id, and a
    // per-frame node's ids continue the earlier frames' while the morph file's are frame 0's.
    let base = [
        "convert",
        path(&seq),
        "--frames",
        "--layout",
        "input",
        "--no-coplanar-offset",
    ];
    let mut a = base.to_vec();
    a.extend(["-o", path(&nodes)]);
    ok(&a);
    let mut b = base.to_vec();
    b.extend(["--frames-encoding", "morph", "-o", path(&morph)]);
    ok(&b);
    let (sn, sm) = (
        std::fs::metadata(&nodes).unwrap().len(),
        std::fs::metadata(&morph).unwrap().len(),
    );
    // A third of the Gaussians move: sparse targets, far smaller than a node per frame.
    assert!(sm * 2 < sn, "morph {sm} B, nodes {sn} B");
    let first = trace(&nodes, 0.0, &dir.join("n0.png"));
    let mut moved = 0;
    for (i, t) in [0.0, 0.02, 0.05, 0.09, 0.1, 0.15, 0.2, 0.4]
        .into_iter()
        .enumerate()
    {
        let n = trace(&nodes, t, &dir.join(format!("n{i}.png")));
        let m = trace(&morph, t, &dir.join(format!("m{i}.png")));
        // The tracer poses frame f of the morph file within f32 rounding of the node's
        // vertices (tests/morph_trace.rs: colours within 3.7e-6); in 8 bits that can flip a
        // value that sits on a rounding boundary by one level, nothing more.
        let worst = n
            .iter()
            .zip(&m)
            .map(|(x, y)| ((x - y).abs() * 255.0).round() as u32)
            .max()
            .unwrap();
        assert!(worst <= 1, "t = {t}: images differ by {worst} levels");
        if n != first {
            moved += 1;
        }
    }
    assert!(
        moved >= 4,
        "the sequence barely moves ({moved} times differ from t = 0)"
    );
}

/// `convert INPUT --frames --frames-encoding morph [--layout input] -o OUT`.
fn morph_args<'a>(input: &'a Path, input_layout: bool, out: &'a Path) -> Vec<&'a str> {
    let mut a = vec![
        "convert",
        path(input),
        "--frames",
        "--frames-encoding",
        "morph",
    ];
    if input_layout {
        a.extend(["--layout", "input"]);
    }
    a.extend(["-o", path(out)]);
    a
}

fn refused(args: &[&str], want: &str, out: &Path) {
    let r = run(args);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{}: {err}", args.join(" "));
    assert!(err.contains(want), "{err}");
    assert!(!out.exists(), "{} was written", out.display());
}

#[test]
fn morph_refusals_name_the_frame_or_the_option() {
    let dir = temp_dir("frames", "morph-refused");
    let seq = sequence(&dir, false);
    let dropped = sequence(&dir, true);
    let out = dir.join("out.glb");
    refused(&morph_args(&dropped, true, &out), "frame 3 meshes to", &out);
    refused(&morph_args(&seq, false, &out), "give --layout input", &out);
    let folder = dir.join("per-frame/");
    refused(
        &morph_args(&seq, true, &folder),
        "not one GLB per frame",
        &folder,
    );
    let still = dir.join("still.ply");
    write_ply(&still, &cut300(), Default::default()).unwrap();
    refused(&morph_args(&still, false, &out), "takes a 4D input", &out);
}
