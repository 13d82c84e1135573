//! 4D inputs through the CLI: a SpacetimeGaussians lite PLY, a `params.npz` and a numbered
//! frame sequence made from the committed cut of a real capture (`fixtures/formats/cut300.ply`,
//! 300 Gaussians of `fourth_st`), moved along a known path. `info` reports the time range and
//! how far the Gaussians move; `render --time T` of each equals the render of the model's cloud
//! at T written as a plain PLY (bit-identical: the same stored values reach the same renderer);
//! `trace --time` and `hybrid --time` take them; `compare` runs at several times.

mod cli_common;

use std::io::Write;
use std::path::{Path, PathBuf};

use cli_common::{cut300, cut300_eye, ok, path, temp_dir};
use glam::Vec3;
use splatbridge_scene::fourd::{self, FourDForm};
use splatbridge_scene::image_io::load_png;
use splatbridge_scene::ply::write_ply;
use splatbridge_scene::sh::SH_C0;
use splatbridge_scene::GaussianCloud;

/// Velocity of every Gaussian (world units per unit time).
const V: Vec3 = Vec3::new(0.5, 0.0, -0.25);

/// The cut as a SpacetimeGaussians lite model: velocity `V` about centre 0.5, a temporal RBF
/// wide enough (exp(3) ≈ 20) that opacity barely changes, colour the DC colour.
fn write_stg(path: &Path, c: &GaussianCloud) {
    let mut names: Vec<String> = ["x", "y", "z", "trbf_center", "trbf_scale", "nx", "ny", "nz"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    names.extend((0..9).map(|i| format!("motion_{i}")));
    names.extend((0..3).map(|i| format!("f_dc_{i}")));
    names.push("opacity".into());
    names.extend((0..3).map(|i| format!("scale_{i}")));
    names.extend((0..4).map(|i| format!("rot_{i}")));
    names.extend((0..4).map(|i| format!("omega_{i}")));
    let mut f = std::fs::File::create(path).unwrap();
    write!(
        f,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\n",
        c.len()
    )
    .unwrap();
    for n in &names {
        writeln!(f, "property float {n}").unwrap();
    }
    f.write_all(b"end_header\n").unwrap();
    for i in 0..c.len() {
        let m = c.means[i];
        let rgb = Vec3::splat(0.5) + c.sh_of(i)[0] * SH_C0;
        let q = c.rotations[i];
        let s = c.log_scales[i];
        let row = [
            m.x,
            m.y,
            m.z,
            0.5,
            3.0,
            0.0,
            0.0,
            0.0,
            V.x,
            V.y,
            V.z,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            rgb.x,
            rgb.y,
            rgb.z,
            c.opacity_logits[i],
            s.x,
            s.y,
            s.z,
            q.w,
            q.x,
            q.y,
            q.z,
            0.0,
            0.0,
            0.0,
            0.0,
        ];
        for v in row {
            f.write_all(&v.to_le_bytes()).unwrap();
        }
    }
}

/// One fixed camera for every render of these tests: a still PLY of the model at time t is
/// another scene than the model (framed at its start), so the comparisons give both the same
/// explicit eye, 2 diagonals from the cut.
fn fixed_eye() -> [String; 8] {
    cut300_eye(2.0)
}

/// Render `scene` at `t` (the fixed eye, 64×48) and return the PNG's bytes.
fn render(scene: &Path, t: f64, out: &Path, extra: &[&str]) -> Vec<u8> {
    let ts = t.to_string();
    let eye = fixed_eye();
    let mut args = vec![
        "render",
        path(scene),
        "--time",
        &ts,
        "--width",
        "64",
        "--height",
        "48",
        "-o",
        path(out),
    ];
    args.extend(eye.iter().map(String::as_str));
    args.extend_from_slice(extra);
    ok(&args);
    std::fs::read(out).unwrap()
}

fn models(dir: &Path) -> Vec<(PathBuf, FourDForm)> {
    let c = cut300();
    let stg = dir.join("point_cloud.ply");
    write_stg(&stg, &c);
    // Three frames of the same model written as a sequence (frame i at i/30 s).
    let seq = dir.join("frames");
    std::fs::create_dir_all(&seq).unwrap();
    let model = fourd::load(&stg, FourDForm::SpacetimeLite, 30.0).unwrap();
    for i in 0..3 {
        let f = model.sample(i as f64 * 0.25).unwrap();
        write_ply(
            &seq.join(format!("shot_{:04}.ply", i + 1)),
            &f,
            Default::default(),
        )
        .unwrap();
    }
    vec![(stg, FourDForm::SpacetimeLite), (seq, FourDForm::Sequence)]
}

#[test]
fn four_d_inputs_render_at_their_time_in_every_command() {
    let dir = temp_dir("fourd", "cli");
    for (input, form) in models(&dir) {
        let model = fourd::load(&input, form, 30.0).unwrap();
        // info: the time range, the count, the motion.
        let out = ok(&["info", path(&input), "--json"]);
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let f = &v["four_d"];
        assert_eq!(f["max_gaussians"], 300, "{v}");
        let end = model.time_range().end;
        assert_eq!(f["time"]["end"].as_f64().unwrap(), end);
        // Every Gaussian moves by |V|·Δt between the first and last frame times: for the
        // STG model over [0, 1], |V|; for the sequence (times 0, 0.25, 0.5 of the model),
        // |V|·0.5. f32 positions: 1e-5.
        let moved = if form == FourDForm::Sequence {
            V.length() * 0.5
        } else {
            V.length()
        };
        let d = &f["displacement"];
        assert!(
            (d["max"].as_f64().unwrap() as f32 - moved).abs() < 1e-5,
            "{d}"
        );
        assert!(
            (d["median"].as_f64().unwrap() as f32 - moved).abs() < 1e-5,
            "{d}"
        );
        let text = String::from_utf8(ok(&["info", path(&input)]).stdout).unwrap();
        assert!(text.contains("4D ") && text.contains("motion "), "{text}");

        // render --time: the same image as the model's cloud at that time as a plain PLY.
        for t in [0.0, 1.0 / 30.0, 0.75] {
            let still = dir.join("still.ply");
            write_ply(&still, &model.sample(t).unwrap(), Default::default()).unwrap();
            let a = render(&input, t, &dir.join("a.png"), &[]);
            let b = render(&still, 0.0, &dir.join("b.png"), &[]);
            let (fa, fb) = (
                load_png(&dir.join("a.png")).unwrap(),
                load_png(&dir.join("b.png")).unwrap(),
            );
            assert_eq!(fa.rgb, fb.rgb, "{input:?} at t = {t}");
            assert_eq!(a.len(), b.len());
        }
        // The picture changes with time (the Gaussians move).
        render(&input, 0.0, &dir.join("a.png"), &[]);
        render(&input, end, &dir.join("b.png"), &[]);
        let (fa, fb) = (
            load_png(&dir.join("a.png")).unwrap(),
            load_png(&dir.join("b.png")).unwrap(),
        );
        assert_ne!(fa.rgb, fb.rgb, "{input:?}: nothing moved");

        for cmd in ["trace", "hybrid"] {
            let png = dir.join(format!("{cmd}.png"));
            ok(&[
                cmd,
                path(&input),
                "--time",
                "0.5",
                "--camera",
                "orbit:4:1",
                "--width",
                "32",
                "--height",
                "24",
                "-o",
                path(&png),
            ]);
            assert!(load_png(&png).unwrap().width == 32);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn compare_runs_at_several_times_of_a_sequence() {
    let dir = temp_dir("fourd", "compare");
    let (seq, _) = models(&dir).pop().unwrap();
    let out = dir.join("cmp");
    ok(&[
        "compare",
        path(&seq),
        "--times",
        "0,0.0333333333,0.0666666667",
        "--cameras",
        "orbit:2",
        "--width",
        "32",
        "--height",
        "24",
        "--profiles",
        "rings",
        "-o",
        path(&out),
    ]);
    let report = std::fs::read_to_string(out.join("report.json")).unwrap();
    assert!(report.contains("0.0333"), "{report}");
    let _ = std::fs::remove_dir_all(&dir);
}
