//! Sharded runs the way the batch engines of `docs/scale/` start them — the Slurm array script
//! and the Kubernetes Indexed Job's command, one process per shard with the engine's
//! environment variable mapped to `--shard` — merged with `splatbridge merge` and checked
//! against one unsharded run: the same files, bit for bit, and the same records (timings and
//! memory figures aside). Then the merge's refusals: missing, duplicate and mismatched shards.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

mod shards_common;
use shards_common::{bin, list, merge, merged_is_one_run, ok, sharded, street};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Small enough for seconds in a test build, large enough that every renderer draws something:
/// the street fixture (dynamic: moving objects, per-frame OBJs), 2 times × 3 cameras = 6 items.
const CAMERAS: &str = "orbit:3";
const ARGS: &str = "--width 32 --height 24 --times 0,2 --profiles meshsplats";

fn unsharded(scene: &Path, out: &Path) {
    let mut c = Command::new(bin());
    c.arg("compare").arg(scene).args(["--cameras", CAMERAS]);
    c.args(ARGS.split_whitespace()).arg("-o").arg(out);
    ok(c.output().unwrap(), "unsharded compare");
}

/// `report.json` records without the run's costs (milliseconds, peak memory).
fn records(dir: &Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(dir.join("report.json")).unwrap();
    let mut v: Vec<serde_json::Value> = serde_json::from_str(&text).unwrap();
    for r in &mut v {
        let o = r.as_object_mut().unwrap();
        o.remove("milliseconds");
        o.remove("peak_memory_bytes");
    }
    v
}

/// Every file of `a` and `b` is the same, bit for bit, except the reports (their timings
/// differ), whose records are compared without timings.
fn same_run(a: &Path, b: &Path) {
    let (la, lb) = (list(a), list(b));
    assert_eq!(la, lb, "file lists differ");
    let mut images = 0;
    for name in &la {
        if name == "report.json" || name == "report.md" {
            continue;
        }
        images += name.ends_with(".png") as usize;
        let (x, y) = (
            std::fs::read(a.join(name)).unwrap(),
            std::fs::read(b.join(name)).unwrap(),
        );
        assert!(x == y, "{name} differs");
    }
    assert!(images > 20, "only {images} images");
    let (ra, rb) = (records(a), records(b));
    assert!(!ra.is_empty());
    assert_eq!(ra, rb);
}

/// The variables the Slurm and Kubernetes job scripts read: the scene, the output folder, the
/// comparison's cameras and options, and the binary.
fn job_env<'a>(scene: &'a Path, out: &'a Path) -> [(&'static str, &'a OsStr); 5] {
    [
        ("SCENE", scene.as_os_str()),
        ("OUT", out.as_os_str()),
        ("CAMERAS", OsStr::new(CAMERAS)),
        ("ARGS", OsStr::new(ARGS)),
        ("SPLATBRIDGE", OsStr::new(bin())),
    ]
}

#[test]
fn slurm_and_kubernetes_shards_merge_into_one_run() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = street(tmp.path(), 1500);
    let one = tmp.path().join("one");
    unsharded(&scene, &one);

    // Slurm: three array tasks, the script run as sbatch would run it.
    let slurm = tmp.path().join("slurm");
    let script = repo().join("docs/scale/slurm-compare.sh");
    for i in 0..3 {
        let out = Command::new("bash")
            .arg(&script)
            .env("SLURM_ARRAY_TASK_ID", i.to_string())
            .env("SLURM_ARRAY_TASK_COUNT", "3")
            .env("SLURM_ARRAY_TASK_MIN", "0")
            .envs(job_env(&scene, &slurm))
            .output()
            .unwrap();
        ok(out, "slurm task");
    }
    let shards: Vec<PathBuf> = (0..3).map(|i| slurm.join(format!("shard-{i}"))).collect();
    // A task re-run (after a failure, or twice) replaces its own outputs.
    let rerun = Command::new("bash")
        .arg(&script)
        .env("SLURM_ARRAY_TASK_ID", "1")
        .env("SLURM_ARRAY_TASK_COUNT", "3")
        .envs(job_env(&scene, &slurm))
        .output()
        .unwrap();
    ok(rerun, "slurm task re-run");
    let merged = tmp.path().join("merged_slurm");
    ok(merge(&shards, &merged), "merge");
    same_run(&one, &merged);

    // Kubernetes: the manifest's container command, run by sh with the index Kubernetes sets.
    let yaml = std::fs::read_to_string(repo().join("docs/scale/k8s-indexed-job.yaml")).unwrap();
    let field = |key: &str| {
        yaml.lines()
            .find_map(|l| l.trim().strip_prefix(key).map(|v| v.trim().to_string()))
            .unwrap_or_else(|| panic!("{key} not in the manifest"))
    };
    let completions = field("completions:");
    assert!(
        yaml.contains(&format!("{{name: SHARD_COUNT, value: \"{completions}\"}}")),
        "SHARD_COUNT must equal completions ({completions})"
    );
    assert_eq!(field("completionMode:"), "Indexed");
    let command = field("- exec ");
    let k8s = tmp.path().join("k8s");
    for i in 0..2 {
        let out = Command::new("sh")
            .arg("-c")
            .arg(format!("exec {command}"))
            .env("JOB_COMPLETION_INDEX", i.to_string())
            .env("SHARD_COUNT", "2")
            .envs(job_env(&scene, &k8s))
            .output()
            .unwrap();
        ok(out, "kubernetes pod");
    }
    let merged = tmp.path().join("merged_k8s");
    // Any order of folders.
    ok(
        merge(&[k8s.join("shard-1"), k8s.join("shard-0")], &merged),
        "merge",
    );
    same_run(&one, &merged);

    // Refusals: exit status 2 and a message naming the problem; nothing written.
    let refused = |dirs: &[PathBuf], needle: &str| {
        let out_dir = tmp.path().join("refused");
        let out = merge(dirs, &out_dir);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.starts_with("error: ") && err.contains(needle), "{err}");
        assert!(!out_dir.join("report.json").exists());
    };
    refused(&shards[..2], "missing shard(s) 2 of 3");
    refused(
        &[
            shards[0].clone(),
            shards[1].clone(),
            shards[1].clone(),
            shards[2].clone(),
        ],
        "duplicate shard 1/3",
    );
    refused(&[shards[0].clone(), k8s.join("shard-1")], "shard count");
    // Shard 2 of a run with other options (another image size).
    let other = tmp.path().join("other");
    let mut c = Command::new(bin());
    c.arg("compare").arg(&scene).args(["--cameras", CAMERAS]);
    c.args(ARGS.replace("--width 32", "--width 40").split_whitespace())
        .args(["--shard", "2/3", "-o"])
        .arg(&other);
    ok(c.output().unwrap(), "other shard");
    refused(
        &[shards[0].clone(), shards[1].clone(), other.clone()],
        "options hash",
    );
    // A different scene, and a different tool version (edited into a copy of shard 2).
    for (field, value, needle) in [
        ("scene_hash", "0000000000000000", "scene hash"),
        ("version", "0.0.0-other", "tool version"),
    ] {
        let edited = tmp.path().join(format!("edited_{field}"));
        std::fs::create_dir_all(&edited).unwrap();
        let text = std::fs::read_to_string(shards[2].join("report.json")).unwrap();
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v[field] = serde_json::Value::String(value.into());
        std::fs::write(edited.join("report.json"), v.to_string()).unwrap();
        refused(&[shards[0].clone(), shards[1].clone(), edited], needle);
    }
    // A folder of an unsharded run is not a shard.
    refused(std::slice::from_ref(&one), "not a shard's partial report");
}

/// `render --frames --shard I/N`: each shard renders its frames into its own folder; the merge
/// holds exactly the unsharded sequence, bit for bit.
#[test]
fn render_frames_shards_merge_into_one_sequence() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = street(tmp.path(), 1500);
    let render = |out: &Path, shard: Option<&str>| {
        let size = ["--camera", "orbit:4:1", "--width", "32", "--height", "24"];
        sharded(
            "render",
            &scene,
            &[&size[..], &["--frames"]].concat(),
            shard,
            out,
        );
    };
    let one = tmp.path().join("one");
    render(&one.join("f.png"), None);
    let shards: Vec<PathBuf> = (0..3).map(|i| tmp.path().join(format!("s{i}"))).collect();
    for (i, d) in shards.iter().enumerate() {
        render(&d.join("f.png"), Some(&format!("{i}/3")));
    }
    let frames = list(&one);
    assert!(frames.len() > 3, "{frames:?}");
    merged_is_one_run(&shards, &one, &tmp.path().join("merged"), "render --frames");
}

/// `accuracy --shard I/N`: the settings split across shards; the merge writes the unsharded
/// sweep's `accuracy.json` (records in the same order, timings aside) and its plots.
#[test]
fn accuracy_shards_merge_into_one_sweep() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = street(tmp.path(), 1500);
    let sweep = |out: &Path, shard: Option<&str>| {
        let only = ["--only", "profile,format", "--cameras", "orbit:2"];
        let size = ["--width", "32", "--height", "24"];
        sharded("accuracy", &scene, &[&only[..], &size].concat(), shard, out);
    };
    let one = tmp.path().join("one");
    sweep(&one, None);
    let shards: Vec<PathBuf> = (0..3).map(|i| tmp.path().join(format!("s{i}"))).collect();
    for (i, d) in shards.iter().enumerate() {
        sweep(d, Some(&format!("{i}/3")));
    }
    let merged = tmp.path().join("merged");
    ok(merge(&shards, &merged), "merge accuracy");
    let read = |d: &Path| {
        let text = std::fs::read_to_string(d.join("accuracy.json")).unwrap();
        let mut v: Vec<serde_json::Value> = serde_json::from_str(&text).unwrap();
        for r in &mut v {
            let o = r.as_object_mut().unwrap();
            o.remove("milliseconds");
            o.remove("peak_memory_bytes");
        }
        v
    };
    let (a, b) = (read(&one), read(&merged));
    assert!(a.len() > 5, "{} records", a.len());
    assert_eq!(a, b);
    assert!(merged.join("accuracy.md").exists() && merged.join("psnr_vs_time.png").exists());
}
