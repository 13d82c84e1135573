//! `splatbridge hybrid` end to end: every knob of the command line reaches the renderer. Each
//! run on the street fixture (64×48) reports its knobs in `--json`, and the knobs that change
//! the picture change it: `--blur on` (and `--blur` alone) against `--blur off`, `--supersample
//! 4`, the split thresholds (surfel counts move), `--epsilon`. A bad value exits with status 2
//! naming the option.

mod cli_common;

use std::path::Path;

use cli_common::*;
use serde_json::Value;

const SIZE: [&str; 6] = ["--camera", "scene:0", "--width", "64", "--height", "48"];

fn temp_dir(name: &str) -> cli_common::TempDir {
    cli_common::temp_dir("cli-hybrid", name)
}

/// Run `hybrid` on the street fixture with `knobs`, writing `out`; the JSON report.
fn hybrid(out: &Path, knobs: &[&str]) -> Value {
    hybrid_json(out, &SIZE, knobs)
}

/// The PNG's bytes: the encoder is deterministic, so equal bytes mean equal images.
fn pixels(p: &Path) -> Vec<u8> {
    std::fs::read(p).expect("written image")
}

#[test]
fn every_knob_reaches_the_renderer() {
    let dir = temp_dir("knobs");
    let base_png = dir.join("base.png");
    let base = hybrid(&base_png, &[]);
    assert_eq!(base["knobs"]["blur"], false);
    assert!(
        base["stats"]["surfels"].as_u64().unwrap() > 0,
        "the street has surfels"
    );
    let base_px = pixels(&base_png);

    // Blur: `on`, bare `--blur`, and `off` (the default).
    for (name, knobs, blurred) in [
        ("blur_on", &["--blur", "on"][..], true),
        ("blur_bare", &["--blur"][..], true),
        ("blur_off", &["--blur", "off"][..], false),
    ] {
        let p = dir.join(format!("{name}.png"));
        let r = hybrid(&p, knobs);
        assert_eq!(r["knobs"]["blur"], blurred, "{name}");
        assert_eq!(
            pixels(&p) != base_px,
            blurred,
            "{name}: the image changes iff blurred"
        );
    }

    let p = dir.join("ss4.png");
    let r = hybrid(&p, &["--supersample", "4"]);
    assert_eq!(r["knobs"]["supersample"], 4);
    assert_ne!(pixels(&p), base_px, "4× coverage changes surfel edges");

    // A stricter split makes fewer surfels; a looser one more.
    let n = |r: &Value| r["stats"]["surfels"].as_u64().unwrap();
    let strict = hybrid(
        &dir.join("strict.png"),
        &["--surfel-opacity", "0.99", "--surfel-flatness", "0.1"],
    );
    let loose = hybrid(
        &dir.join("loose.png"),
        &["--surfel-opacity", "0.5", "--surfel-flatness", "1"],
    );
    assert_eq!(strict["knobs"]["surfel_opacity"], 0.99);
    assert!(
        n(&strict) < n(&base) && n(&base) < n(&loose),
        "{} {} {}",
        n(&strict),
        n(&base),
        n(&loose)
    );
    assert_eq!(
        n(&strict) + strict["stats"]["gaussians"].as_u64().unwrap(),
        n(&loose) + loose["stats"]["gaussians"].as_u64().unwrap(),
        "the split partitions the same scene"
    );

    // ε = 0 keeps only Gaussians in front of the surfel: fewer blends than the default 5.
    let e0 = hybrid(&dir.join("eps0.png"), &["--epsilon", "0"]);
    assert_eq!(e0["knobs"]["epsilon"], 0.0);
    let blends = |r: &Value| r["stats"]["blends"].as_u64().unwrap();
    assert!(
        blends(&e0) < blends(&base),
        "{} vs {}",
        blends(&e0),
        blends(&base)
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_knob_values_exit_2_naming_the_option() {
    let dir = temp_dir("bad");
    let scene = street();
    let out = dir.join("x.png");
    for (knob, value) in [
        ("--blur", "maybe"),
        ("--supersample", "2"),
        ("--surfel-opacity", "x"),
    ] {
        let r = run(&["hybrid", &scene, knob, value, "-o", out.to_str().unwrap()]);
        assert_eq!(r.status.code(), Some(2), "{knob} {value}");
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(err.contains(knob), "{knob} {value}: {err}");
        assert!(!out.exists(), "no output written on a bad knob");
    }
    std::fs::remove_dir_all(&dir).ok();
}
