//! `convert SEQUENCE --objects auto|none` and `convert SEQUENCE --frames -o OUT.glb` from the
//! command line: a folder of numbered PLY frames with known motion becomes a manifest every
//! command reads (render at a frame time), or one glTF; bad sequences and options exit 2.

mod cli_common;

use std::path::Path;

use cli_common::{ok, run};
use splatbridge_scene::fixtures::moving::{moving_cutouts, MovingParams};
use splatbridge_scene::ply::{write_ply, PlyFormat};

/// Twelve frames of a 20 000-Gaussian synthetic capture with two moving balls and a deforming
/// one, written as `frame_0000.ply`, … (in a shuffled creation order: names decide the order).
fn sequence(dir: &Path) -> usize {
    let base = splatbridge_scene::fixtures::large(20_000, 5);
    let params = MovingParams {
        objects: 2,
        frames: 12,
        ..MovingParams::default()
    };
    let (frames, _, _) = moving_cutouts(&base, &params);
    for f in [3, 0, 11, 7, 1, 2, 4, 5, 6, 8, 9, 10] {
        write_ply(
            &dir.join(format!("frame_{f:04}.ply")),
            &frames[f],
            PlyFormat::BinaryLittleEndian,
        )
        .unwrap();
    }
    base.len()
}

#[test]
fn objects_auto_writes_a_manifest_other_commands_read() {
    let tmp = tempfile::tempdir().unwrap();
    let seq = tmp.path().join("seq");
    std::fs::create_dir(&seq).unwrap();
    sequence(&seq);
    let out = tmp.path().join("scene");
    let r = ok(&[
        "convert",
        seq.to_str().unwrap(),
        "--objects",
        "auto",
        "--fps",
        "10",
        "-o",
        out.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&r.stdout);
    assert!(
        text.contains("object_0") && text.contains("object_1"),
        "{text}"
    );
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("scene.json")).unwrap()).unwrap();
    assert_eq!(m["objects"].as_array().unwrap().len(), 2, "{m}");
    assert_eq!(m["frames"].as_array().unwrap().len(), 12);
    assert_eq!(m["time"]["end"].as_f64().unwrap(), 1.1);
    // The report beside it: per group the fit's residual in world units and as PSNR at four
    // sampled times, and the per-frame remainder.
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("motion.json")).unwrap()).unwrap();
    assert_eq!(r["frames"], 12, "{r}");
    let groups = r["groups"].as_array().unwrap();
    assert_eq!(groups.len(), 2, "{r}");
    for g in groups {
        assert!(g["rms"].as_f64().unwrap() > 0.0, "{g}");
        let psnr = g["psnr"].as_array().unwrap();
        assert_eq!(psnr.len(), 4, "{g}");
        assert!(
            psnr.iter().all(|p| p["psnr"].as_f64().unwrap() > 20.0),
            "{g}"
        );
    }
    assert!(r["per_frame_gaussians"].as_u64().unwrap() > 0, "{r}");
    assert!(r["per_frame_appearance"].is_u64(), "{r}");
    assert!(text.contains("fit vs true"), "{text}");
    // Another command reads it: a frame rendered at t = 0.5.
    let png = tmp.path().join("t05.png");
    ok(&[
        "render",
        out.join("scene.json").to_str().unwrap(),
        "--time",
        "0.5",
        "--camera",
        "orbit:4:0",
        "--width",
        "64",
        "--height",
        "48",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(png.is_file());
    // And to glTF, directly.
    let glb = tmp.path().join("anim.glb");
    ok(&[
        "convert",
        seq.to_str().unwrap(),
        "--objects",
        "auto",
        "-o",
        glb.to_str().unwrap(),
    ]);
    let frames_glb = tmp.path().join("frames.glb");
    ok(&[
        "convert",
        seq.to_str().unwrap(),
        "--frames",
        "-o",
        frames_glb.to_str().unwrap(),
    ]);
    let (a, f) = (
        std::fs::metadata(&glb).unwrap().len(),
        std::fs::metadata(&frames_glb).unwrap().len(),
    );
    // Two rigid balls and the background are written once instead of twelve times.
    assert!(a * 3 < f, "animated {a} B vs per-frame {f} B");
    // One GLB per frame and the index, into a folder.
    let dir = tmp.path().join("per_frame");
    ok(&[
        "convert",
        seq.to_str().unwrap(),
        "--frames",
        "-o",
        &format!("{}/", dir.display()),
    ]);
    let index: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("frames.json")).unwrap()).unwrap();
    assert_eq!(index["format"], "splatbridge-frames/1");
    let listed = index["frames"].as_array().unwrap();
    assert_eq!(listed.len(), 12);
    for (i, f) in listed.iter().enumerate() {
        let glb = dir.join(f["uri"].as_str().unwrap());
        assert_eq!(
            std::fs::metadata(&glb).unwrap().len(),
            f["bytes"].as_u64().unwrap(),
            "frame {i}"
        );
    }
    // Neither a mesh of another kind nor a partial output.
    let obj = tmp.path().join("frames.obj");
    let r = run(&[
        "convert",
        seq.to_str().unwrap(),
        "--frames",
        "-o",
        obj.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("one GLB per frame into a folder"));
    assert!(!obj.exists());
}

#[test]
fn bad_sequences_exit_2() {
    let tmp = tempfile::tempdir().unwrap();
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let out = tmp.path().join("o");
    let r = run(&[
        "convert",
        empty.to_str().unwrap(),
        "--objects",
        "auto",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("no numbered frames"));
    // Frames of different counts.
    let mixed = tmp.path().join("mixed");
    std::fs::create_dir(&mixed).unwrap();
    write_ply(
        &mixed.join("a_0.ply"),
        &splatbridge_scene::fixtures::large(50, 1),
        PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    write_ply(
        &mixed.join("a_1.ply"),
        &splatbridge_scene::fixtures::large(40, 1),
        PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    let r = run(&[
        "convert",
        mixed.to_str().unwrap(),
        "--objects",
        "auto",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("a_1.ply") && err.contains("40 Gaussians"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written on error");
    // Options.
    let r = run(&[
        "convert",
        mixed.to_str().unwrap(),
        "--objects",
        "auto",
        "--fps",
        "0",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(2));
    let r = run(&[
        "convert",
        mixed.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(2));
}
