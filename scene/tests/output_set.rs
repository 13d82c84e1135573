//! `scene::output::OutputSet`: a set of files appears together or not at all, a failure at
//! any point leaves the previous outputs as they were and no temporary behind, and stale
//! temporaries of killed runs are cleaned by the next run.

use std::path::Path;
use std::time::{Duration, SystemTime};

use splatbridge_scene::output::{clean_stale, OutputSet, STALE_AFTER};

/// Names in `dir` that are not in `keep` (temporaries, backups, staging folders).
fn extra_entries(dir: &Path, keep: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !keep.contains(&n.as_str()))
        .collect();
    v.sort();
    v
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

#[test]
fn a_set_commits_every_file() {
    let d = tempfile::tempdir().unwrap();
    let (a, b) = (d.path().join("x.gltf"), d.path().join("x.bin"));
    std::fs::write(&a, "old gltf").unwrap();
    let mut set = OutputSet::new();
    set.write(&b, b"new bin").unwrap();
    set.write(&a, b"new gltf").unwrap();
    // Nothing is visible before the commit.
    assert_eq!(read(&a), "old gltf");
    assert!(!b.exists());
    set.commit().unwrap();
    assert_eq!((read(&a), read(&b)), ("new gltf".into(), "new bin".into()));
    assert_eq!(
        extra_entries(d.path(), &["x.gltf", "x.bin"]),
        Vec::<String>::new()
    );
}

#[test]
fn a_failed_write_between_files_leaves_the_old_set_and_no_temporaries() {
    let d = tempfile::tempdir().unwrap();
    let (a, b) = (d.path().join("x.bin"), d.path().join("x.gltf"));
    std::fs::write(&a, "old bin").unwrap();
    std::fs::write(&b, "old gltf").unwrap();
    let mut set = OutputSet::new();
    set.write(&a, b"new bin").unwrap();
    // The second path cannot be written: its folder does not exist.
    let bad = d.path().join("missing/x.mtl");
    let err = set.write(&bad, b"new").unwrap_err().to_string();
    assert!(err.contains("x.mtl"), "{err}");
    drop(set);
    assert_eq!((read(&a), read(&b)), ("old bin".into(), "old gltf".into()));
    assert_eq!(
        extra_entries(d.path(), &["x.bin", "x.gltf"]),
        Vec::<String>::new()
    );
}

#[test]
fn a_failed_writer_callback_leaves_no_temporary() {
    let d = tempfile::tempdir().unwrap();
    let a = d.path().join("a.png");
    let mut set = OutputSet::new();
    let r = set.write_with(&a, |_| Err(std::io::Error::other("encoder failed")));
    assert!(r.unwrap_err().to_string().contains("encoder failed"));
    assert_eq!(extra_entries(d.path(), &[]), Vec::<String>::new());
}

#[test]
fn a_failed_rename_rolls_back_the_renames_already_done() {
    let d = tempfile::tempdir().unwrap();
    let names = ["f_0000.png", "f_0001.png", "f_0002.png"];
    let paths: Vec<_> = names.iter().map(|n| d.path().join(n)).collect();
    std::fs::write(&paths[0], "old 0").unwrap();
    std::fs::write(&paths[1], "old 1").unwrap();
    let mut set = OutputSet::new();
    for (i, p) in paths.iter().enumerate() {
        set.write(p, format!("new {i}").as_bytes()).unwrap();
    }
    // The third target turns into a folder after staging: its rename fails after the first
    // two have been renamed, which must be undone.
    std::fs::create_dir(&paths[2]).unwrap();
    let err = set.commit().unwrap_err().to_string();
    assert!(err.contains("f_0002.png"), "{err}");
    assert_eq!(read(&paths[0]), "old 0");
    assert_eq!(read(&paths[1]), "old 1");
    assert!(paths[2].is_dir());
    assert_eq!(extra_entries(d.path(), &names), Vec::<String>::new());
}

#[test]
fn a_directory_target_is_refused_when_staged() {
    let d = tempfile::tempdir().unwrap();
    let mut set = OutputSet::new();
    let err = set.write(d.path(), b"x").unwrap_err().to_string();
    assert!(
        err.contains("directory") || err.contains("names no file"),
        "{err}"
    );
}

/// A pid that no process has: Linux caps pids at 2²² (`/proc/sys/kernel/pid_max`).
const DEAD_PID: u32 = 999_999_999;

#[test]
fn stale_temporaries_are_cleaned_by_the_next_run() {
    let d = tempfile::tempdir().unwrap();
    let dead = d.path().join(format!(".out.png.tmp{DEAD_PID}.3"));
    std::fs::write(&dead, "partial").unwrap();
    // pid 1 always runs: a fresh temporary of a running process is left alone, an old one
    // (older than STALE_AFTER) is removed.
    let live = d.path().join(".out.png.tmp1.4");
    std::fs::write(&live, "in progress").unwrap();
    let old = d.path().join(".out.bin.tmp1.5");
    std::fs::write(&old, "old").unwrap();
    let f = std::fs::File::options().write(true).open(&old).unwrap();
    f.set_modified(SystemTime::now() - STALE_AFTER - Duration::from_secs(60))
        .unwrap();
    drop(f);
    // A stale staging folder of a killed `compare`.
    let staging = d.path().join(format!(".staging.tmp{DEAD_PID}.7"));
    std::fs::create_dir(&staging).unwrap();
    std::fs::write(staging.join("report.md"), "partial").unwrap();
    // Names that merely look similar are never ours.
    let others = [
        ".out.png.tmp.3",
        "out.png.tmp999999999.3",
        ".out.png.bak999999999.3",
    ];
    for o in others {
        std::fs::write(d.path().join(o), "user file").unwrap();
    }
    let mut set = OutputSet::new();
    set.write(&d.path().join("out.png"), b"png").unwrap();
    set.commit().unwrap();
    assert!(!dead.exists() && !old.exists() && !staging.exists());
    assert!(live.exists());
    let mut keep = vec!["out.png", ".out.png.tmp1.4"];
    keep.extend(others);
    assert_eq!(extra_entries(d.path(), &keep), Vec::<String>::new());
}

#[test]
fn a_stale_backup_without_its_target_is_put_back() {
    let d = tempfile::tempdir().unwrap();
    // A run killed between moving the old file aside and moving the new one in.
    let backup = d.path().join(format!(".scene.gltf.old{DEAD_PID}.1"));
    std::fs::write(&backup, "previous").unwrap();
    // A stale backup whose target exists is the previous file of a finished rename: removed.
    let done = d.path().join(format!(".x.bin.old{DEAD_PID}.2"));
    std::fs::write(&done, "previous bin").unwrap();
    std::fs::write(d.path().join("x.bin"), "current bin").unwrap();
    let cleaned = clean_stale(d.path());
    assert_eq!(cleaned.len(), 2, "{cleaned:?}");
    assert_eq!(read(&d.path().join("scene.gltf")), "previous");
    assert_eq!(read(&d.path().join("x.bin")), "current bin");
    assert_eq!(
        extra_entries(d.path(), &["scene.gltf", "x.bin"]),
        Vec::<String>::new()
    );
}

#[test]
fn a_staging_folder_commits_with_the_set_and_keeps_other_files() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("cmp");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    std::fs::write(out.join("report.md"), "old report").unwrap();
    let mut set = OutputSet::new();
    let stage = set.stage_dir(&out).unwrap();
    std::fs::write(stage.join("report.md"), "new report").unwrap();
    std::fs::write(stage.join("a.png"), "png").unwrap();
    assert_eq!(read(&out.join("report.md")), "old report");
    set.commit().unwrap();
    assert_eq!(read(&out.join("report.md")), "new report");
    assert_eq!(read(&out.join("notes.txt")), "mine");
    assert_eq!(
        extra_entries(&out, &["report.md", "a.png", "notes.txt"]),
        Vec::<String>::new()
    );
}

#[test]
fn an_abandoned_staging_folder_is_removed_and_changes_nothing() {
    let d = tempfile::tempdir().unwrap();
    std::fs::write(d.path().join("report.md"), "old report").unwrap();
    let mut set = OutputSet::new();
    let stage = set.stage_dir(d.path()).unwrap();
    std::fs::write(stage.join("report.md"), "new report").unwrap();
    drop(set);
    assert_eq!(read(&d.path().join("report.md")), "old report");
    assert_eq!(
        extra_entries(d.path(), &["report.md"]),
        Vec::<String>::new()
    );
}
