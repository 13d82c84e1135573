//! `convert --distill` from the command line: a dynamic scene's distilled export keeps its
//! animated objects and cameras, says how it was fitted, passes the glTF validator and
//! imports into Blender; a bad distillation option is refused with exit 2. Also
//! `accuracy --only distill`, the accuracy-against-time sweep of distillation.

mod cli_common;

use std::path::Path;

use cli_common::{client_check, ok, path, run, street, temp_dir};
use serde_json::Value;

/// The JSON chunk of a GLB.
fn glb_json(bytes: &[u8]) -> Value {
    assert_eq!(&bytes[..4], b"glTF", "not a GLB");
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&bytes[20..20 + len]).expect("GLB JSON chunk")
}

/// A small distillation of the street fixture (moving cars) into `out`: four 32×24 views
/// over two scene times, one held back, with `extra` options; returns stderr.
fn distil_street(out: &Path, extra: &[&str]) -> String {
    let mut args = vec!["--distill-times", "2"];
    args.extend_from_slice(extra);
    cli_common::distil_street_with("1", &args, out)
}

/// The MeshSplats profile distilled for three steps.
fn distilled_street(dir: &Path) -> (std::path::PathBuf, String) {
    let out = dir.join("street_distilled.glb");
    let stderr = distil_street(&out, &["--profile", "meshsplats", "--iterations", "3"]);
    (out, stderr)
}

#[test]
fn distilled_dynamic_export_keeps_its_animation_and_says_how_it_was_fitted() {
    let dir = temp_dir("distill-cli", "anim");
    let (out, stderr) = distilled_street(&dir);
    assert!(stderr.contains("held-back PSNR"), "{stderr}");
    let plain = dir.join("street_plain.glb");
    let scene = street();
    ok(&[
        "convert",
        scene.as_str(),
        "--profile",
        "meshsplats",
        "-o",
        path(&plain),
    ]);
    let (d, p) = (
        glb_json(&std::fs::read(&out).unwrap()),
        glb_json(&std::fs::read(&plain).unwrap()),
    );
    let how = d["asset"]["extras"]["splatbridge"]["options"]["distilled"]
        .as_str()
        .unwrap_or_else(|| panic!("no distillation note in {}", d["asset"]));
    assert!(
        how.contains("4 views") && how.contains("over 2 scene times"),
        "{how}"
    );
    assert!(
        how.contains("widened"),
        "the default footprint is noted: {how}"
    );
    // The cars stay animated nodes, and the cameras and node tree are the plain export's.
    for key in ["animations", "cameras", "nodes"] {
        let (a, b) = (d[key].as_array(), p[key].as_array());
        assert_eq!(
            a.map(Vec::len),
            b.map(Vec::len),
            "{key}: distilled and plain exports differ"
        );
    }
    assert!(!d["animations"].as_array().unwrap().is_empty());
    assert_eq!(
        d["animations"], p["animations"],
        "the animation is unchanged"
    );
}

/// `--distill-order splat` (a measurement) runs on a dynamic scene, whose animated cars
/// are regrouped in their pose at each fitting time, and the export says it was fitted in
/// that order.
#[test]
fn splat_order_distillation_says_so_in_the_export() {
    let dir = temp_dir("distill-cli", "order");
    let out = dir.join("street_splat_order.glb");
    let stderr = distil_street(&out, &["--distill-order", "splat", "--iterations", "2"]);
    assert!(stderr.contains("held-back PSNR"), "{stderr}");
    let d = glb_json(&std::fs::read(&out).unwrap());
    let how = d["asset"]["extras"]["splatbridge"]["options"]["distilled"]
        .as_str()
        .unwrap_or_else(|| panic!("no distillation note in {}", d["asset"]));
    assert!(how.contains("splat order"), "{how}");
}

/// A near plane other than the reference's is said in the export's note and beside the
/// held-back figures; the reference's is not mentioned.
#[test]
fn a_targets_near_plane_says_so_in_the_export() {
    let dir = temp_dir("distill-cli", "near");
    let note = |out: &Path| {
        let d = glb_json(&std::fs::read(out).unwrap());
        d["asset"]["extras"]["splatbridge"]["options"]["distilled"]
            .as_str()
            .unwrap_or_else(|| panic!("no distillation note in {}", d["asset"]))
            .to_string()
    };
    let out = dir.join("street_near.glb");
    let stderr = distil_street(&out, &["--distill-near", "0.05", "--iterations", "1"]);
    assert!(stderr.contains("views, near plane 0.05)"), "{stderr}");
    assert!(note(&out).contains("near plane at 0.05"), "{}", note(&out));
    let plain = dir.join("street_reference_near.glb");
    let stderr = distil_street(&plain, &["--iterations", "1"]);
    assert!(!stderr.contains("near plane"), "{stderr}");
    assert!(!note(&plain).contains("near plane"), "{}", note(&plain));
}

/// Position fitting's bad settings exit 2 naming the option: a negative step, and the
/// texture profile (the default for glTF), whose opacity comes from a texture.
#[test]
fn bad_position_fitting_exits_2_naming_the_option() {
    let dir = temp_dir("distill-cli", "positions");
    let out = dir.join("x.glb");
    let scene = street();
    for (args, flag) in [
        (
            vec!["--distill-positions", "--distill-position-step=-1"],
            "--distill-position-step",
        ),
        (vec!["--distill-positions"], "--distill-positions"),
    ] {
        let mut all = vec!["convert", scene.as_str(), "--distill"];
        all.extend(args.iter().copied());
        all.extend(["-o", path(&out)]);
        let r = run(&all);
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(flag), "{args:?}: {stderr}");
        assert!(!out.exists(), "{args:?}: an output was written");
    }
}

#[test]
fn bad_distillation_options_exit_2_naming_the_option() {
    let dir = temp_dir("distill-cli", "bad");
    let out = dir.join("x.glb");
    let scene = street();
    for arg in [
        "--distill-eps=-1",
        "--distill-eps=nan",
        "--distill-eps=inf",
        "--distill-sh-degree=4",
        "--distill-order=diagonal",
        "--distill-footprint-quantile=1.5",
        "--distill-footprint-quantile=nan",
        "--distill-guard-tolerance=-1",
        "--distill-guard-tolerance=inf",
        "--distill-memory=-1",
        "--distill-memory=nan",
        "--distill-record-transmittance=0",
        "--distill-record-transmittance=1",
        "--distill-record-transmittance=nan",
        "--distill-record-transmittance=-0.5",
        "--distill-patience=-1",
        "--distill-patience=three",
        "--distill-eps-backtrack=-1",
        "--distill-eps-backtrack=nan",
        "--distill-colour-step=0",
        "--distill-colour-step=inf",
        "--distill-alpha-step=-1",
        "--distill-alpha-step=nan",
        "--distill-fit-sh-degree=4",
        "--distill-near=0",
        "--distill-near=-0.1",
        "--distill-near=inf",
        "--distill-near=nan",
        "--distill-log",
    ] {
        let r = run(&[
            "convert",
            scene.as_str(),
            "--distill",
            arg,
            "-o",
            path(&out),
        ]);
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{arg}: {stderr}");
        let flag = arg.split('=').next().unwrap();
        assert!(stderr.contains(flag), "{arg}: {stderr}");
        assert!(!out.exists(), "{arg}: an output was written");
    }
}

/// `bench distill` times the set-up and the steps of the fit `convert --distill` would make,
/// with its counters; hit memory 0 streams every view (the same hits, counted the same);
/// a bad option or input exits 2 naming it.
#[test]
fn bench_distill_reports_set_up_steps_and_views_kept() {
    let scene = street();
    let bench = |extra: &[&str]| {
        let mut args = vec![
            "bench",
            "distill",
            scene.as_str(),
            "--views",
            "orbit:4",
            "--width",
            "32",
            "--height",
            "24",
            "--steps",
            "2",
        ];
        args.extend_from_slice(extra);
        String::from_utf8_lossy(&ok(&args).stdout).into_owned()
    };
    let kept = bench(&["--profile", "meshsplats"]);
    let streamed = bench(&["--profile", "meshsplats", "--memory", "0"]);
    assert!(kept.contains("4 fitting windows 32×24"), "{kept}");
    assert!(kept.contains("set-up"), "{kept}");
    // The set-up's parts, each a number of seconds.
    for part in ["the mesh ", "native targets ", "hit recording "] {
        let secs = kept
            .split(part)
            .nth(1)
            .and_then(|t| t.split(' ').next())
            .and_then(|v| v.parse::<f64>().ok());
        assert!(secs.is_some_and(|s| s >= 0.0), "{part}: {kept}");
    }
    assert!(kept.contains("4 views kept, 0 streamed"), "{kept}");
    assert!(streamed.contains("0 views kept, 4 streamed"), "{streamed}");
    assert!(
        kept.contains("median") && kept.contains("over 2 steps"),
        "{kept}"
    );
    // The same hits either way: the count on the line is the recording's, not the budget's.
    let hits = |t: &str| {
        t.lines()
            .find(|l| l.starts_with("hits"))
            .map(|l| l.split(' ').nth(1).unwrap().to_string())
    };
    assert_eq!(hits(&kept), hits(&streamed));
    // Recording stops at the named transmittance: a shallower one keeps fewer hits.
    let shallow = bench(&["--profile", "meshsplats", "--record-transmittance", "0.5"]);
    let count = |t: &str| hits(t).unwrap().parse::<u64>().unwrap();
    assert!(count(&shallow) < count(&kept), "{shallow}\n{kept}");
    for (arg, name) in [
        (&["--profile", "cubes"][..], "--profile"),
        (&["--memory=-1"][..], "--memory"),
        (&["--record-transmittance=1"][..], "--record-transmittance"),
    ] {
        let mut args = vec!["bench", "distill", scene.as_str()];
        args.extend_from_slice(arg);
        let r = run(&args);
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{arg:?}: {stderr}");
        assert!(stderr.contains(name), "{arg:?}: {stderr}");
    }
    let r = run(&["bench", "distill", "no-such-scene.ply"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("error: no-such-scene.ply"));
}

/// `--distill-memory 0` keeps no view's hits: every view is traced again in each step, and
/// the set-up line says so; the default keeps them all.
#[test]
fn distill_memory_decides_which_views_are_kept() {
    let dir = temp_dir("distill-cli", "memory");
    let extra = ["--profile", "meshsplats", "--iterations", "2"];
    let kept = distil_street(&dir.join("kept.glb"), &extra);
    let streamed = distil_street(
        &dir.join("streamed.glb"),
        &[&extra[..], &["--distill-memory", "0"]].concat(),
    );
    assert!(kept.contains("(4 views kept, 0 streamed"), "{kept}");
    assert!(streamed.contains("(0 views kept, 4 streamed"), "{streamed}");
}

#[test]
#[cfg_attr(
    not(gltf_tools),
    ignore = "needs the glTF validator wrapper (../shared/tools), node and npm"
)]
fn distilled_export_is_validator_clean() {
    let dir = temp_dir("distill-cli", "validator");
    let (out, _) = distilled_street(&dir);
    client_check("validate-exports.sh", &["--mesh"], &out);
}

/// With positions fitted (the cars' vertices in their own frames, moved), the export is
/// still validator-clean, keeps its animation and imports into Blender.
#[test]
#[cfg_attr(not(blender), ignore = "needs Blender on PATH")]
fn position_fitted_export_passes_the_validator_and_blender() {
    let dir = temp_dir("distill-cli", "positions-ok");
    let out = dir.join("street_positions.glb");
    let stderr = distil_street(
        &out,
        &[
            "--profile",
            "meshsplats",
            "--distill-positions",
            "--iterations",
            "2",
        ],
    );
    assert!(stderr.contains("held-back PSNR"), "{stderr}");
    let d = glb_json(&std::fs::read(&out).unwrap());
    let how = d["asset"]["extras"]["splatbridge"]["options"]["distilled"]
        .as_str()
        .unwrap_or_default();
    assert!(how.contains("with positions"), "{how}");
    assert!(!d["animations"].as_array().unwrap().is_empty());
    client_check("validate-exports.sh", &["--mesh"], &out);
    let stdout = client_check("blender-check.sh", &[], &out);
    assert!(stdout.contains("\"problems\": []"), "{stdout}");
}

#[test]
#[cfg_attr(not(blender), ignore = "needs Blender on PATH")]
fn distilled_export_imports_into_blender() {
    let dir = temp_dir("distill-cli", "blender");
    let (out, _) = distilled_street(&dir);
    let stdout = client_check("blender-check.sh", &[], &out);
    assert!(stdout.contains("\"problems\": []"), "{stdout}");
}

/// `accuracy --only distill` fits only the profiles named, measures every checkpoint on the
/// held-back classes and writes the curve and the per-class table; an unknown profile exits
/// 2 before anything is written.
#[test]
fn accuracy_distill_sweep_fits_the_named_profiles() {
    let dir = temp_dir("distill-cli", "accuracy");
    let out = dir.join("acc");
    let scene = street();
    let r = accuracy_distill(
        &scene,
        &out,
        &[
            "--distill-for",
            "48x36",
            "--distill-sizes",
            "40x30",
            "--distill-iterations",
            "12",
        ],
    );
    let stdout = String::from_utf8_lossy(&r.stdout);
    let psnr = |it: usize| -> f64 {
        let line = stdout
            .lines()
            .find(|l| l.contains(&format!("meshsplats it={it} ")))
            .unwrap_or_else(|| panic!("no checkpoint {it}:\n{stdout}"));
        let after = line.split("PSNR").nth(1).expect("a PSNR column");
        after.split_whitespace().next().unwrap().parse().unwrap()
    };
    // Checkpoints at 0, a third and all of the iterations.
    for it in [0, 4, 12] {
        assert!(psnr(it).is_finite());
    }
    // The fit keeps the best iteration its validation views accept: never below the start
    // on them, so on the held-back views a fall would be a real loss.
    assert!(psnr(12) >= psnr(0) - 0.05, "{stdout}");
    assert!(!stdout.contains("rings it=") && !stdout.contains("texture it="));
    let md = std::fs::read_to_string(out.join("distill.md")).unwrap();
    assert!(md.contains("| meshsplats | all views | 6 |"), "{md}");
    // Every view's start column is the fit's start: its mean is the it=0 checkpoint's
    // mean PSNR (`accuracy.json`, unrounded). The column is printed to 0.01 dB, so the mean
    // of its six values is within 0.005 of the true mean.
    let starts: Vec<f64> = every_view(&md).iter().map(|c| c[2]).collect();
    assert_eq!(starts.len(), 6, "{md}");
    let json: Value =
        serde_json::from_slice(&std::fs::read(out.join("accuracy.json")).unwrap()).unwrap();
    let start_mean = json
        .as_array()
        .unwrap()
        .iter()
        .find(|r| {
            r["value"]
                .as_str()
                .is_some_and(|v| v.starts_with("meshsplats it=0 "))
        })
        .and_then(|r| r["psnr"].as_f64())
        .expect("the it=0 record");
    let mean = starts.iter().sum::<f64>() / 6.0;
    assert!(
        (mean - start_mean).abs() <= 0.005,
        "{mean} against {start_mean}: {md}"
    );
    // The guard's log: the start, then every 10 steps and the end.
    for it in [0, 10, 12] {
        assert!(md.contains(&format!("| meshsplats | {it} | ")), "{md}");
    }
    assert!(out.join("psnr_vs_distill_time.png").exists());
    // The view that gains least, for a person to look at: native, plain and distilled at the
    // held-back size, linked from the report; the plain image is the plain export's, not
    // the distilled one (they differ: the fit moved the colours).
    let img = |what: &str| {
        let f = format!("worst_meshsplats_{what}.png");
        assert!(md.contains(&format!("]({f})")), "{md}");
        splatbridge_scene::image_io::load_png(&out.join(f)).unwrap()
    };
    let (native, plain, distilled) = (img("native"), img("plain"), img("distilled"));
    for f in [&native, &plain, &distilled] {
        assert_eq!((f.width, f.height), (40, 30));
    }
    assert_ne!(plain.rgb, distilled.rgb);

    let bad = dir.join("bad");
    let r = run(&[
        "accuracy",
        scene.as_str(),
        "--only",
        "distill",
        "--distill-profiles",
        "cubes",
        "-o",
        path(&bad),
    ]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--distill-profiles"), "{stderr}");
    assert!(!bad.exists(), "an output was written");
}

/// `accuracy --only distill` reports as distilled what `convert --distill` writes: widened
/// for the coarsest fitting view (quantile 1) of 24×18 and 96×72 views, with no step, the
/// start is below the plain export at the large validation views, so with the floor every
/// view's distilled figure is the plain export's, and without it the start's, which differs
/// from the plain export's.
#[test]
fn accuracy_distill_reports_the_floor_as_convert_writes_it() {
    let dir = temp_dir("distill-cli", "accuracy-floor");
    let scene = street();
    let columns = |floor: &str| -> Vec<(f64, f64, f64)> {
        let out = dir.join(floor);
        accuracy_distill(
            &scene,
            &out,
            &[
                "--distill-for",
                "24x18,96x72",
                "--distill-sizes",
                "96x72",
                "--distill-iterations",
                "0",
                "--distill-footprint-quantile",
                "1",
                "--distill-floor",
                floor,
            ],
        );
        let md = std::fs::read_to_string(out.join("distill.md")).unwrap();
        every_view(&md).iter().map(|c| (c[1], c[2], c[3])).collect()
    };
    let on = columns("on");
    assert_eq!(on.len(), 6, "{on:?}");
    assert!(
        on.iter().all(|(plain, _, distilled)| plain == distilled),
        "{on:?}"
    );
    let off = columns("off");
    assert!(
        off.iter().all(|(_, start, distilled)| start == distilled),
        "{off:?}"
    );
    assert!(
        off.iter().any(|(plain, _, distilled)| plain != distilled),
        "{off:?}"
    );
}

/// `accuracy SCENE --only distill` of the MeshSplats profile from two 32×24 orbit cameras
/// into `out`, with `extra` options; it must succeed.
fn accuracy_distill(scene: &str, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "accuracy",
        scene,
        "--only",
        "distill",
        "--distill-profiles",
        "meshsplats",
        "--cameras",
        "orbit:2",
        "--width",
        "32",
        "--height",
        "24",
    ];
    args.extend_from_slice(extra);
    args.extend(["-o", path(out)]);
    ok(&args)
}

/// The MeshSplats rows of `distill.md`'s per-view table: default, plain, start and distilled
/// PSNR of each view.
fn every_view(md: &str) -> Vec<[f64; 4]> {
    md.split("## Every view")
        .nth(1)
        .expect("the per-view table")
        .lines()
        .filter(|l| l.starts_with("| meshsplats | "))
        .map(|l| {
            let c: Vec<f64> = l
                .split('|')
                .skip(3)
                .take(4)
                .map(|x| x.trim().parse().unwrap())
                .collect();
            [c[0], c[1], c[2], c[3]]
        })
        .collect()
}
