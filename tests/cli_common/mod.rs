//! What the command-line tests share: the binary, the street fixture, the committed cut of a
//! real capture and a fixed camera on it, running and checking a command, a temporary folder
//! removed after the test, and `hybrid`'s JSON report.

#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

pub const BIN: &str = env!("CARGO_BIN_EXE_splatbridge");

/// The committed cut of a real capture (`fixtures/formats/cut300.ply`: 300 Gaussians of
/// `fourth_st`).
pub fn cut300() -> splatbridge_scene::GaussianCloud {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/formats/cut300.ply");
    let opts = splatbridge_scene::ply::ReadOptions::default();
    splatbridge_scene::ply::read_ply(&p, &opts).unwrap().0
}

/// Camera options for one fixed view of [`cut300`]: its centre seen from `diagonals` of its
/// bounds' diagonal away along −z, up −y as 3DGS captures are, 50° field of view. A generated
/// camera is framed on the scene it renders, so tests comparing different files of one scene
/// give them this one instead.
pub fn cut300_eye(diagonals: f32) -> [String; 8] {
    let (lo, hi) = cut300().bounds().expect("the cut has Gaussians");
    let centre = (lo + hi) * 0.5;
    let eye = centre - glam::Vec3::Z * diagonals * (hi - lo).length();
    let v = |v: glam::Vec3| format!("{},{},{}", v.x, v.y, v.z);
    [
        "--eye".into(),
        v(eye),
        "--target".into(),
        v(centre),
        "--up".into(),
        "0,-1,0".into(),
        "--fov".into(),
        "50".into(),
    ]
}

/// The street fixture's manifest.
pub fn street() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/street/scene.json").into()
}

/// `convert STREET --distill` of four 32×24 views with `held_back` held-back views, then
/// `extra` and `-o out`: the small distillation the CLI tests run; returns stderr.
pub fn distil_street_with(held_back: &str, extra: &[&str], out: &Path) -> String {
    let scene = street();
    let mut args = vec![
        "convert",
        scene.as_str(),
        "--distill",
        "--views",
        "orbit:4",
        "--distill-width",
        "32",
        "--distill-height",
        "24",
        "--held-back",
        held_back,
    ];
    args.extend_from_slice(extra);
    args.extend(["-o", path(out)]);
    String::from_utf8_lossy(&ok(&args).stderr).into_owned()
}

pub fn run(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("the splatbridge binary runs")
}

/// [`run`], failing the test with the command's stderr unless it succeeds.
pub fn ok(args: &[&str]) -> Output {
    let r = run(args);
    assert!(
        r.status.success(),
        "splatbridge {} failed:\n{}",
        args.join(" "),
        String::from_utf8_lossy(&r.stderr)
    );
    r
}

/// The binary with arguments or an environment [`ok`] cannot give (paths, variables).
pub fn bin() -> Command {
    Command::new(BIN)
}

/// Run `cmd`, failing the test with its stderr unless it succeeds.
pub fn succeeded(cmd: &mut Command) -> Output {
    let r = cmd.output().expect("the command runs");
    assert!(
        r.status.success(),
        "{cmd:?} failed:\n{}",
        String::from_utf8_lossy(&r.stderr)
    );
    r
}

/// A fresh folder `splatbridge-PREFIX-NAME-…` under the system's temporary folder, removed
/// with everything in it when the returned guard drops (a test's outputs would otherwise pile
/// up run after run). Dereferences to the folder's path.
pub fn temp_dir(prefix: &str, name: &str) -> TempDir {
    TempDir(
        tempfile::Builder::new()
            .prefix(&format!("splatbridge-{prefix}-{name}-"))
            .tempdir()
            .expect("a temporary folder"),
    )
}

/// A temporary folder that is deleted on drop; see [`temp_dir`].
pub struct TempDir(tempfile::TempDir);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        self.0.path()
    }
}

pub fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `hybrid` on the street fixture with `size` (camera and image options) then `knobs`,
/// writing `out`; the JSON report.
pub fn hybrid_json(out: &Path, size: &[&str], knobs: &[&str]) -> Value {
    let scene = street();
    let mut a = vec!["hybrid", scene.as_str()];
    a.extend_from_slice(size);
    a.extend_from_slice(knobs);
    a.extend_from_slice(&["-o", path(out), "--json"]);
    serde_json::from_slice(&ok(&a).stdout).expect("JSON report")
}

/// Run one of the repository's real-client check scripts (`scripts/validate-exports.sh
/// --mesh`, `scripts/blender-check.sh`) on `file`, failing the test unless it exits 0; its
/// standard output.
pub fn client_check(script: &str, args: &[&str], file: &Path) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let r = Command::new(root.join("scripts").join(script))
        .args(args)
        .arg(file)
        .output()
        .unwrap_or_else(|e| panic!("run {script}: {e}"));
    let stdout = String::from_utf8_lossy(&r.stdout).into_owned();
    println!("{stdout}{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(
        r.status.code(),
        Some(0),
        "{script} reported problems:\n{stdout}"
    );
    stdout
}
