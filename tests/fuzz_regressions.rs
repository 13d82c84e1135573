//! Replays every committed fuzz finding on stable: each file under
//! `fuzz/regressions/<target>/` goes through the same entry function the `cargo fuzz` target
//! calls (`fuzz/src/entries.rs`, included here by path), and must return without a panic.
//! A folder whose name is not a target fails the test, so a renamed target cannot silently
//! stop being replayed.

#[allow(dead_code)]
#[path = "../fuzz/src/entries.rs"]
mod entries;
#[allow(dead_code)]
#[path = "../fuzz/src/file_formats.rs"]
mod file_formats;
#[allow(dead_code)]
#[path = "../fuzz/src/splat_formats.rs"]
mod splat_formats;

use std::path::Path;

#[test]
fn every_committed_fuzz_finding_replays_without_a_panic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/regressions");
    let mut replayed = 0;
    for dir in std::fs::read_dir(&root).expect("fuzz/regressions exists") {
        let dir = dir.unwrap().path();
        if !dir.is_dir() {
            continue;
        }
        let target = dir.file_name().unwrap().to_string_lossy().to_string();
        let mut files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .collect();
        files.sort();
        for f in files {
            let data = std::fs::read(&f).unwrap();
            eprintln!("replaying {}", f.display());
            assert!(
                entries::run(&target, &data),
                "{}: no fuzz target named {target}",
                f.display()
            );
            replayed += 1;
        }
    }
    eprintln!("{replayed} regression inputs replayed");
}

#[test]
fn every_target_accepts_empty_and_garbage_input() {
    for (name, f) in entries::all_targets() {
        eprintln!("target {name}");
        f(b"");
        f(&[0xff; 64]);
        f(b"glTF\x02\x00\x00\x00\xff\xff\xff\xff");
    }
}
