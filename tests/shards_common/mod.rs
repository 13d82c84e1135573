//! What the shard tests share: the binary, a street fixture written by the CLI, `merge`, and a
//! folder's file names.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_splatbridge")
}

/// Fails the test with the command's output unless it succeeded.
pub fn ok(out: Output, what: &str) {
    assert!(
        out.status.success(),
        "{what} failed: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `fixture street --count COUNT` written under `dir`; its manifest. Dynamic (moving
/// objects), so every frame's outputs differ.
pub fn street(dir: &Path, count: usize) -> PathBuf {
    street_with_effects(dir, count, "")
}

/// As [`street`], declaring `effects` (comma-separated, as `fixture --effects`; empty: none).
pub fn street_with_effects(dir: &Path, count: usize, effects: &str) -> PathBuf {
    let mut c = Command::new(bin());
    c.args(["fixture", "street", "--count", &count.to_string()]);
    if !effects.is_empty() {
        c.args(["--effects", effects]);
    }
    ok(
        c.arg("-o").arg(dir.join("street")).output().unwrap(),
        "fixture",
    );
    dir.join("street/scene.json")
}

/// `splatbridge COMMAND SCENE ARGS… [--shard SHARD] -o OUT` (OUT's folder made first), failing
/// the test unless it succeeds.
pub fn sharded(command: &str, scene: &Path, args: &[&str], shard: Option<&str>, out: &Path) {
    let mut c = Command::new(bin());
    c.arg(command).arg(scene).args(args);
    if let Some(s) = shard {
        c.args(["--shard", s]);
    }
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    ok(c.arg("-o").arg(out).output().unwrap(), command);
}

/// `splatbridge merge DIRS… -o OUT`.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Output {
    Command::new(bin())
        .arg("merge")
        .args(dirs)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap()
}

/// The names of a folder's entries, sorted.
pub fn list(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// How many of a folder's entries end with `ext`.
pub fn count(d: &Path, ext: &str) -> usize {
    list(d).iter().filter(|f| f.ends_with(ext)).count()
}

/// `merge` the shard folders into `merged` and check it holds exactly the files of the
/// unsharded run in `one`, bit for bit.
pub fn merged_is_one_run(shards: &[PathBuf], one: &Path, merged: &Path, what: &str) {
    ok(merge(shards, merged), "merge");
    let files = list(one);
    assert_eq!(list(merged), files, "{what}");
    for f in &files {
        assert!(
            std::fs::read(one.join(f)).unwrap() == std::fs::read(merged.join(f)).unwrap(),
            "{what}: {f} differs"
        );
    }
}
