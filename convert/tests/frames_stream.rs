//! `convert --frames` streamed (`frames_gltf`) against the in-memory writer it replaces: the
//! same animated glTF byte for byte (the in-memory writer, which holds every frame, is the
//! reference), the size and id limits refused with nothing left behind, and the per-frame
//! folder's files against the single-frame writer.

use std::path::Path;

use glam::{Quat, Vec3};
use splatbridge_convert::frames_gltf::{
    read_frames_index, write_frames_dir, write_frames_file, FramesLimits, FRAMES_FORMAT,
    FRAMES_INDEX,
};
use splatbridge_convert::options::ChunkOrder;
use splatbridge_convert::{convert_to_file, ConvertOptions, Profile};
use splatbridge_scene::dynamic::{DynamicScene, FrameContent, TimeRange};
use splatbridge_scene::GaussianCloud;

/// Frame `f` of a small moving capture: `n` Gaussians on a wavy sheet drifting with `f`, some
/// flat, some volumetric, one transparent, one invalid (zero quaternion), colours varying.
fn frame(f: usize, n: usize) -> GaussianCloud {
    let mut c = GaussianCloud::new(0);
    for i in 0..n {
        let u = i as f32 / n as f32;
        let x = (i % 17) as f32 * 0.1 + 0.05 * f as f32;
        let y = (i / 17) as f32 * 0.1;
        let z = (3.0 * x + f as f32 * 0.3).sin() * 0.2 + u * 0.01;
        let flat = i % 3 == 0;
        let scale = if flat {
            Vec3::new(0.04, 0.03, 0.0005)
        } else {
            Vec3::new(0.03, 0.02 + 0.01 * u, 0.015)
        };
        let rot = Quat::from_rotation_y(u * 2.0 + f as f32 * 0.1);
        let opacity = if i == 5 { 0.001 } else { 0.2 + 0.7 * u };
        c.push_activated(
            Vec3::new(x, y, z),
            scale,
            rot,
            opacity,
            Vec3::new(u, 1.0 - u, 0.5),
        );
    }
    if n > 7 {
        c.rotations[7] = Quat::from_xyzw(0.0, 0.0, 0.0, 0.0);
    }
    c
}

/// Five frames, the fourth with fewer Gaussians (frames need not share a count).
fn frames() -> (Vec<GaussianCloud>, Vec<f64>) {
    let frames: Vec<GaussianCloud> = (0..5)
        .map(|f| frame(f, if f == 3 { 180 } else { 240 }))
        .collect();
    let times = (0..5).map(|f| f as f64 / 30.0).collect();
    (frames, times)
}

/// The scene the in-memory `--frames` export writes (`pipeline::motion::frames_scene`).
fn frames_scene(frames: &[GaussianCloud], times: &[f64]) -> DynamicScene {
    let scene = DynamicScene {
        four_d: None,
        time: TimeRange {
            start: times[0],
            end: *times.last().unwrap(),
            fps: 30.0,
        },
        static_gaussians: GaussianCloud::new(0),
        objects: Vec::new(),
        frames: frames
            .iter()
            .zip(times)
            .map(|(g, &t)| FrameContent {
                t,
                gaussians: g.clone(),
            })
            .collect(),
        cameras: Vec::new(),
        effects: serde_json::Map::new(),
    };
    scene.validate().unwrap();
    scene
}

/// The option sets `convert --frames` gets: the default viewer layout (texture profile,
/// chunked, both windings, no normals, coplanar offset), the input layout, other profiles,
/// no ids, display colours.
fn option_sets() -> Vec<(&'static str, ConvertOptions)> {
    let base = ConvertOptions {
        profile: Profile::Texture,
        coplanar_offset: true,
        ..ConvertOptions::default()
    };
    vec![
        ("viewer layout, texture", base.clone().for_viewers()),
        ("input layout, texture", base.clone()),
        (
            "viewer layout, rings, no ids",
            ConvertOptions {
                profile: Profile::Rings,
                gaussian_ids: false,
                ..base.clone()
            }
            .for_viewers(),
        ),
        (
            "meshsplats, chunks of 64 in input order, display colours",
            ConvertOptions {
                profile: Profile::MeshSplats,
                chunk_size: 64,
                chunk_order: ChunkOrder::Input,
                color_encoding: splatbridge_convert::ColorEncoding::Display,
                ..base
            },
        ),
    ]
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap()
}

/// Files in `dir` (names), sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn streamed_glb_and_gltf_are_the_in_memory_files_byte_for_byte() {
    let (frames, times) = frames();
    let scene = frames_scene(&frames, &times);
    for (what, opts) in option_sets() {
        for ext in ["glb", "gltf"] {
            let a = tempfile::tempdir().unwrap();
            let b = tempfile::tempdir().unwrap();
            let pa = a.path().join(format!("frames.{ext}"));
            let pb = b.path().join(format!("frames.{ext}"));
            let ra = convert_to_file(&pa, &scene, None, &opts, true).unwrap();
            let rb = write_frames_file(&pb, &frames[..], &times, &opts, &FramesLimits::default())
                .unwrap();
            assert!(read(&pa) == read(&pb), "{what}, .{ext}: files differ");
            if ext == "gltf" {
                assert!(
                    read(&pa.with_extension("bin")) == read(&pb.with_extension("bin")),
                    "{what}: .bin files differ"
                );
            }
            assert_eq!(listing(a.path()), listing(b.path()), "{what}, .{ext}");
            assert_eq!(ra.bytes, rb.bytes, "{what}, .{ext}");
            assert_eq!(ra.meshes, rb.meshes, "{what}, .{ext}");
            assert_eq!(ra.triangles, rb.triangles, "{what}, .{ext}");
            // Something was meshed in every frame (the comparison is not of empty files).
            assert!(rb.meshes.iter().filter(|m| m.triangles > 0).count() >= 5);
        }
    }
}

#[test]
fn a_file_over_the_limit_is_refused_before_the_spool_grows_and_leaves_nothing() {
    let (frames, times) = frames();
    let opts = ConvertOptions::default().for_viewers();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frames.glb");
    // The whole file is known (from the test above's writer) to be larger than frame 0's
    // share; a limit of twice frame 0's share is crossed by the estimate already.
    let full = write_frames_file(&out, &frames[..], &times, &opts, &FramesLimits::default())
        .unwrap()
        .bytes;
    std::fs::remove_file(&out).unwrap();
    let limits = FramesLimits {
        max_bytes: full * 2 / 5,
        total_gaussians: None,
    };
    let e = write_frames_file(&out, &frames[..], &times, &opts, &limits)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with(&out.display().to_string()) && e.contains("about") && e.contains("-o DIR/"),
        "{e}"
    );
    assert!(listing(dir.path()).is_empty(), "{:?}", listing(dir.path()));

    // A first frame much smaller than the rest: the estimate fits, the frame that crosses
    // the limit stops the writer.
    let mut uneven = frames.clone();
    uneven[0] = frame(0, 10);
    let limits = FramesLimits {
        max_bytes: full * 3 / 5,
        total_gaussians: None,
    };
    let e = write_frames_file(&out, &uneven[..], &times, &opts, &limits)
        .unwrap_err()
        .to_string();
    assert!(e.contains("passed") && e.contains("at frame"), "{e}");
    assert!(listing(dir.path()).is_empty(), "{:?}", listing(dir.path()));

    // An earlier file of the same name is left as it was.
    std::fs::write(&out, b"previous").unwrap();
    assert!(write_frames_file(&out, &frames[..], &times, &opts, &limits).is_err());
    assert_eq!(read(&out), b"previous");
    assert_eq!(listing(dir.path()), vec!["frames.glb".to_string()]);
}

#[test]
fn too_many_ids_are_refused_before_a_frame_is_read() {
    let (frames, times) = frames();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frames.glb");
    let limits = FramesLimits {
        total_gaussians: Some(150_000_000),
        ..FramesLimits::default()
    };
    let e = write_frames_file(
        &out,
        &frames[..],
        &times,
        &ConvertOptions::default(),
        &limits,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("150000000 Gaussians") && e.contains("--no-ids"),
        "{e}"
    );
    assert!(listing(dir.path()).is_empty());
    // Without ids the count is no limit of its own; what 150 M Gaussians of these frames
    // would weigh is (frame 0's bytes per Gaussian × the count, far over 4 GiB).
    let no_ids = ConvertOptions {
        gaussian_ids: false,
        ..ConvertOptions::default()
    };
    let e = write_frames_file(&out, &frames[..], &times, &no_ids, &limits)
        .unwrap_err()
        .to_string();
    assert!(e.contains("GB (5 frames") && !e.contains("--no-ids"), "{e}");
    assert!(listing(dir.path()).is_empty());
    let fits = FramesLimits {
        total_gaussians: Some(frames.iter().map(|f| f.len() as u64).sum()),
        ..FramesLimits::default()
    };
    write_frames_file(&out, &frames[..], &times, &no_ids, &fits).unwrap();
}

#[test]
fn the_per_frame_folder_holds_each_frame_as_convert_writes_it_alone() {
    let (frames, times) = frames();
    let opts = ConvertOptions {
        profile: Profile::Texture,
        coplanar_offset: true,
        ..ConvertOptions::default()
    }
    .for_viewers();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("seq");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("keep.txt"), b"not ours").unwrap();
    let (index, report) = write_frames_dir(&out, &frames[..], &times, 30.0, &opts).unwrap();
    assert_eq!(index.format, FRAMES_FORMAT);
    assert_eq!(index.frames.len(), 5);
    let mut names = vec![FRAMES_INDEX.to_string(), "keep.txt".to_string()];
    names.extend((0..5).map(|f| format!("frame_{f:04}.glb")));
    names.sort();
    assert_eq!(listing(&out), names);
    let r = tempfile::tempdir().unwrap();
    let mut total = 0;
    for (f, entry) in index.frames.iter().enumerate() {
        assert_eq!(entry.t, times[f]);
        let reference = r.path().join("one.glb");
        let one = DynamicScene::from_static(frames[f].clone());
        let rr = convert_to_file(&reference, &one, None, &opts, false).unwrap();
        assert!(
            read(&reference) == read(&out.join(&entry.uri)),
            "frame {f} differs from the single-frame export"
        );
        assert_eq!(entry.bytes, rr.bytes);
        assert_eq!(entry.gaussians, frames[f].len() as u64);
        total += rr.bytes;
    }
    let index_len = std::fs::metadata(out.join(FRAMES_INDEX)).unwrap().len();
    assert_eq!(report.bytes, total + index_len);
    // The index reads back, from the folder or the file, and names the frame shown at t.
    for p in [out.clone(), out.join(FRAMES_INDEX)] {
        let (d, back) = read_frames_index(&p).unwrap();
        assert_eq!(back, index);
        assert_eq!(d, out);
    }
    assert_eq!(index.frame_at(-1.0), 0);
    assert_eq!(index.frame_at(times[2]), 2);
    assert_eq!(index.frame_at(times[2] + 0.01), 2);
    assert_eq!(index.frame_at(100.0), 4);
}

#[test]
fn a_frames_index_that_lies_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(FRAMES_INDEX);
    for (text, fragment) in [
        ("{", "not a frames index"),
        (
            r#"{"format":"other/1","fps":30,"frames":[]}"#,
            "expected splatbridge-frames/1",
        ),
        (
            r#"{"format":"splatbridge-frames/1","fps":30,"frames":[]}"#,
            "lists no frames",
        ),
        (
            r#"{"format":"splatbridge-frames/1","fps":30,"frames":[{"t":1,"uri":"a.glb","gaussians":1,"triangles":1,"bytes":1},{"t":0.5,"uri":"b.glb","gaussians":1,"triangles":1,"bytes":1}]}"#,
            "strictly increasing",
        ),
        (
            r#"{"format":"splatbridge-frames/1","fps":30,"frames":[{"t":0,"uri":"../x.glb","gaussians":1,"triangles":1,"bytes":1}]}"#,
            "not a file name",
        ),
    ] {
        std::fs::write(&p, text).unwrap();
        let e = read_frames_index(&p).unwrap_err().to_string();
        assert!(e.contains(fragment), "{text}: {e}");
    }
}
