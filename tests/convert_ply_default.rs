//! `convert SPLATS -o out.ply` writes Gaussians (the 3DGS PLY every splat tool writes); a
//! triangle mesh PLY is one flag away (`--mesh`, or any `--profile`).

use std::path::{Path, PathBuf};
use std::process::Command;

use splatbridge_scene::ply::{read_ply, ReadOptions};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/formats")
        .join(name)
}

fn convert(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_splatbridge"))
        .arg("convert")
        .args(args)
        .output()
        .expect("run splatbridge")
}

fn header(p: &Path) -> String {
    let bytes = std::fs::read(p).unwrap();
    let end = bytes
        .windows(10)
        .position(|w| w == b"end_header")
        .expect("a PLY header");
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

#[test]
fn a_ply_output_of_splats_is_the_3dgs_ply() {
    let tmp = tempfile::tempdir().unwrap();
    let spz = fixture("cut300.spz");
    let out = tmp.path().join("cut.ply");
    let o = convert(&[spz.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let h = header(&out);
    assert!(!h.contains("element face"), "{h}");
    let (cloud, _) = read_ply(&out, &ReadOptions::default()).unwrap();
    assert_eq!(cloud.len(), 300);
    // The same Gaussians the SPZ reader gives (the PLY is lossless).
    let (direct, _) =
        splatbridge_scene::formats::load_cloud(&spz, &ReadOptions::default()).unwrap();
    assert_eq!(cloud, direct);
}

#[test]
fn mesh_or_profile_writes_a_mesh_ply() {
    let tmp = tempfile::tempdir().unwrap();
    let input = fixture("cut300.ply");
    for flags in [
        &["--mesh"][..],
        &["--profile", "rings"][..],
        &["--format", "ply", "--mesh"][..],
    ] {
        let out = tmp.path().join("mesh.ply");
        let mut args = vec![input.to_str().unwrap(), "-o", out.to_str().unwrap()];
        args.extend_from_slice(flags);
        let o = convert(&args);
        assert!(
            o.status.success(),
            "{flags:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let h = header(&out);
        assert!(h.contains("element face"), "{flags:?}: {h}");
        std::fs::remove_file(&out).unwrap();
    }
}

#[test]
fn mesh_and_splats_conflict() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("x.ply");
    let input = fixture("cut300.ply");
    let o = convert(&[
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--mesh",
        "--splats",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--mesh"));
    assert!(!out.exists());
}
