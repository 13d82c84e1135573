//! Per-frame runs split into shards: `convert --frames --shard I/N` as N separate processes,
//! merged with `splatbridge merge`, holds exactly the files of one unsharded run, bit for bit;
//! and the merge refuses an incomplete set. The same for `trace --lidar-all-frames` and
//! `trace --frames`.

use std::path::{Path, PathBuf};
use std::process::Command;

mod shards_common;
use shards_common::{
    bin, count, list, merge, merged_is_one_run, ok, sharded, street, street_with_effects,
};

#[test]
fn convert_frames_shards_merge_into_one_export() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = street(tmp.path(), 800);
    let convert =
        |out: &Path, shard: Option<&str>| sharded("convert", &scene, &["--frames"], shard, out);
    let one = tmp.path().join("one");
    convert(&one.join("m.obj"), None);
    let files = list(&one);
    // One MTL and several frames, or the split below proves nothing.
    assert!(files.len() > 4, "{files:?}");
    assert!(files.contains(&"m.mtl".to_string()), "{files:?}");

    let shards: Vec<PathBuf> = (0..3).map(|i| tmp.path().join(format!("s{i}"))).collect();
    for (i, d) in shards.iter().enumerate() {
        convert(&d.join("m.obj"), Some(&format!("{i}/3")));
    }
    // Each frame in exactly one shard (the MTL in all).
    let mut owned: Vec<String> = shards
        .iter()
        .flat_map(|d| list(d))
        .filter(|f| f.ends_with(".obj"))
        .collect();
    owned.sort();
    let frames: Vec<String> = files
        .iter()
        .filter(|f| f.ends_with(".obj"))
        .cloned()
        .collect();
    assert_eq!(owned, frames, "frames are not partitioned");
    assert!(
        shards
            .iter()
            .filter(|d| list(d).iter().any(|f| f.ends_with(".obj")))
            .count()
            > 1,
        "one shard did every frame"
    );

    merged_is_one_run(&shards, &one, &tmp.path().join("merged"), "convert");

    // A missing shard is refused, and nothing is written.
    let partial = tmp.path().join("partial");
    let out = merge(&shards[..2], &partial);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("error:"),
        "{out:?}"
    );
    assert!(!partial.exists());

    // Shards of other options do not merge.
    let other = tmp.path().join("other");
    let mut c = Command::new(bin());
    c.arg("convert")
        .arg(&scene)
        .args(["--frames", "--profile", "meshsplats", "--shard", "2/3"]);
    std::fs::create_dir_all(&other).unwrap();
    ok(
        c.arg("-o").arg(other.join("m.obj")).output().unwrap(),
        "convert other",
    );
    let out = merge(&[shards[0].clone(), shards[1].clone(), other], &partial);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("options hash"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `trace --lidar-all-frames --shard I/N` (mode gaussian and mode mesh): each shard scans the
/// frames it owns into its own folder beside the traced image; the merge holds the unsharded
/// run's scans and image, bit for bit.
#[test]
fn lidar_frames_shards_merge_into_one_run() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = street_with_effects(tmp.path(), 600, "lidar");
    for mode in ["gaussian", "mesh"] {
        let trace = |out: &Path, shard: Option<&str>| {
            let size = ["--camera", "orbit:4:1", "--width", "16", "--height", "12"];
            let args = [&["--mode", mode][..], &size, &["--lidar-all-frames"]].concat();
            sharded("trace", &scene, &args, shard, out);
        };
        let root = tmp.path().join(mode);
        let one = root.join("one");
        trace(&one.join("t.png"), None);
        let files = list(&one);
        let scans = files.iter().filter(|f| f.ends_with(".ply")).count();
        assert!(scans > 2, "{mode}: {files:?}");
        let shards: Vec<PathBuf> = (0..3).map(|i| root.join(format!("s{i}"))).collect();
        for (i, d) in shards.iter().enumerate() {
            trace(&d.join("t.png"), Some(&format!("{i}/3")));
        }
        let per_shard: Vec<usize> = shards.iter().map(|d| count(d, ".ply")).collect();
        assert_eq!(
            per_shard.iter().sum::<usize>(),
            scans,
            "{mode}: {per_shard:?}"
        );
        assert!(
            per_shard.iter().filter(|&&n| n > 0).count() > 1,
            "{mode}: one shard scanned every frame: {per_shard:?}"
        );
        merged_is_one_run(&shards, &one, &root.join("merged"), mode);
    }
}

/// `trace --frames --shard I/N` (mode gaussian, whose weather particles are rebuilt per frame,
/// and mode mesh): the merged shards hold the unsharded sequence (frames and per-frame LiDAR
/// scans) bit for bit; and a frame of the sequence is the single `trace --time T` of that
/// frame, bit for bit (the sequence poses, rebuilds and scans each frame at its own time).
#[test]
fn trace_frames_shards_merge_into_one_sequence() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = street_with_effects(tmp.path(), 600, "lidar,rain");
    for mode in ["gaussian", "mesh"] {
        let trace = |out: &Path, extra: &[&str]| {
            let mut c = Command::new(bin());
            c.arg("trace").arg(&scene).args(["--mode", mode]);
            // A camera of the scene: an orbit rig would frame each single frame's composite.
            c.args(["--camera", "scene:0", "--width", "16", "--height", "12"]);
            std::fs::create_dir_all(out.parent().unwrap()).unwrap();
            ok(c.args(extra).arg("-o").arg(out).output().unwrap(), "trace");
        };
        let root = tmp.path().join(mode);
        let one = root.join("one");
        trace(&one.join("t.png"), &["--frames"]);
        let files = list(&one);
        let frames = files.iter().filter(|f| f.ends_with(".png")).count();
        let scans = files.iter().filter(|f| f.ends_with(".ply")).count();
        // 0..4 s at 10 fps: 41 frames, each with its scan.
        assert_eq!((frames, scans), (41, 41), "{mode}: {files:?}");
        let first = std::fs::read(one.join("t_0000.png")).unwrap();
        let last = std::fs::read(one.join("t_0040.png")).unwrap();
        assert!(first != last, "{mode}: the objects did not move");

        // Frame 17 (t = 1.7 s) alone.
        let single = root.join("single");
        trace(&single.join("t.png"), &["--time", "1.7"]);
        assert!(
            std::fs::read(single.join("t.png")).unwrap()
                == std::fs::read(one.join("t_0017.png")).unwrap(),
            "{mode}: frame 17 differs from trace --time 1.7"
        );
        assert!(
            std::fs::read(single.join("lidar_0017.ply")).unwrap()
                == std::fs::read(one.join("lidar_0017.ply")).unwrap(),
            "{mode}: scan 17 differs from trace --time 1.7's"
        );

        let shards: Vec<PathBuf> = (0..3).map(|i| root.join(format!("s{i}"))).collect();
        for (i, d) in shards.iter().enumerate() {
            trace(
                &d.join("t.png"),
                &["--frames", "--shard", &format!("{i}/3")],
            );
        }
        let per_shard: Vec<usize> = shards.iter().map(|d| count(d, ".png")).collect();
        assert_eq!(
            per_shard.iter().sum::<usize>(),
            frames,
            "{mode}: {per_shard:?}"
        );
        assert!(
            per_shard.iter().all(|&n| n > 0),
            "{mode}: a shard traced nothing: {per_shard:?}"
        );
        merged_is_one_run(&shards, &one, &root.join("merged"), mode);
    }
    // --shard alone names what it splits.
    let out = Command::new(bin())
        .arg("trace")
        .arg(&scene)
        .args(["--shard", "0/2", "-o"])
        .arg(tmp.path().join("x.png"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--shard"),
        "{out:?}"
    );
}
