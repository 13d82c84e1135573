//! Sharded tilesets (`convert PLY --tiles DIR --shard I/N`, then `--from-shards`): three shard
//! processes and the final run write what one run writes, byte for byte; the final run
//! refuses a missing, duplicated or foreign shard with exit status 2 and writes nothing.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use splatbridge_scene::GaussianCloud;

mod tiles_common;
use tiles_common::{clusters_seeded as clusters, files};

const BIN: &str = env!("CARGO_BIN_EXE_splatbridge");

fn write_ply(path: &Path, c: &GaussianCloud) {
    splatbridge_scene::ply::write_ply(
        path,
        c,
        splatbridge_scene::ply::PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
}

fn run(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .unwrap()
}

fn ok(args: &[&str]) -> String {
    let o = run(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The final run fails with exit 2, an `error:` naming `what`, and leaves no tileset.
fn refused(args: &[&str], out: &Path, what: &str) {
    let o = run(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(
        err.contains("error:") && err.contains(what),
        "{what}: {err}"
    );
    assert!(
        !out.join("tileset.json").exists(),
        "{args:?} wrote a tileset"
    );
}

#[test]
fn three_shards_and_the_final_run_write_what_one_run_writes() {
    let tmp = tempfile::tempdir().unwrap();
    let ply = tmp.path().join("in.ply");
    write_ply(&ply, &clusters(1500, 42));
    let p = ply.to_str().unwrap();
    let one = tmp.path().join("one");
    ok(&[
        "convert",
        p,
        "--tiles",
        one.to_str().unwrap(),
        "--max-gaussians-per-tile",
        "150",
    ]);

    let shard_dir = |i: u32| tmp.path().join(format!("shard-{i}"));
    let mut owned = 0;
    for i in 0..3u32 {
        let d = shard_dir(i);
        let spec = format!("{i}/3");
        let out = ok(&[
            "convert",
            p,
            "--tiles",
            d.to_str().unwrap(),
            "--shard",
            &spec,
            "--max-gaussians-per-tile",
            "150",
        ]);
        assert!(out.contains(&format!("shard {i}/3")), "{out}");
        owned += files(&d)
            .iter()
            .filter(|(n, _)| n.starts_with("tile_"))
            .count();
    }
    let tiles = files(&one).len() - 1;
    // The unsharded tileset's leaves (tiles without children), which the shards split.
    fn leaf_count(t: &serde_json::Value) -> usize {
        match t["children"].as_array() {
            Some(c) if !c.is_empty() => c.iter().map(leaf_count).sum(),
            _ => 1,
        }
    }
    let tileset: serde_json::Value =
        serde_json::from_slice(&std::fs::read(one.join("tileset.json")).unwrap()).unwrap();
    let leaves = leaf_count(&tileset["root"]);
    let dirs: Vec<PathBuf> = (0..3).map(shard_dir).collect();
    let dir_args: Vec<&str> = dirs.iter().map(|d| d.to_str().unwrap()).collect();
    let merged = tmp.path().join("merged");
    let mut args = vec![
        "convert",
        p,
        "--tiles",
        merged.to_str().unwrap(),
        "--max-gaussians-per-tile",
        "150",
        "--from-shards",
    ];
    args.extend(&dir_args);
    ok(&args);

    let (a, b) = (files(&one), files(&merged));
    assert!(a.len() > 10, "several tiles");
    assert!(
        owned > 3 && owned < tiles,
        "shards own the leaves: {owned} of {tiles} tiles"
    );
    assert_eq!(owned, leaves, "the shards together write every leaf once");
    assert_eq!(
        a.iter().map(|f| &f.0).collect::<Vec<_>>(),
        b.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    for ((na, da), (_, db)) in a.iter().zip(&b) {
        assert!(
            da == db,
            "{na} differs between one run and the merged shards"
        );
    }

    // Refusals: a shard missing, a shard given twice, other options, another input.
    let out = tmp.path().join("bad");
    let o = out.to_str().unwrap();
    let base = [
        "convert",
        p,
        "--tiles",
        o,
        "--max-gaussians-per-tile",
        "150",
        "--from-shards",
    ];
    fn with<'a>(base: &[&'a str], dirs: &[&'a str]) -> Vec<&'a str> {
        let mut v = base.to_vec();
        v.extend(dirs);
        v
    }
    refused(
        &with(&base, &dir_args[..2]),
        &out,
        "missing shard(s) 2 of 3",
    );
    refused(
        &with(&base, &[dir_args[0], dir_args[1], dir_args[1]]),
        &out,
        "given twice",
    );
    let mut other_opts = with(&base, &dir_args);
    other_opts[5] = "140";
    refused(&other_opts, &out, "another input or other options");
    let ply2 = tmp.path().join("other.ply");
    write_ply(&ply2, &clusters(1500, 43));
    let mut other_input = with(&base, &dir_args);
    other_input[1] = ply2.to_str().unwrap();
    refused(&other_input, &out, "another input or other options");
    // A shard folder without its manifest (an ordinary directory).
    refused(
        &with(
            &base,
            &[dir_args[0], dir_args[1], tmp.path().to_str().unwrap()],
        ),
        &out,
        "no shard manifest",
    );
    // A shard whose leaf file was replaced by one of another size.
    let victim = files(&dirs[2])
        .into_iter()
        .find(|(n, _)| n.ends_with(".rec"))
        .expect("shard 2 owns a leaf")
        .0;
    std::fs::write(dirs[2].join(&victim), b"short").unwrap();
    refused(&with(&base, &dir_args), &out, "damaged or replaced shard");
}
