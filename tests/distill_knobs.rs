//! The fit's separate knobs: the fitting targets' SH degree apart from the measuring one,
//! the colour and opacity steps apart, and `--distill-log`, the fit's record.

mod cli_common;
mod distill_common;

use cli_common::{path, temp_dir};
use distill_common::opts;
use splatbridge::distill::{views, DistillOptions, Distiller, ParamMode};
use splatbridge_convert::Profile;
use splatbridge_scene::dynamic::DynamicScene;

/// The view-dependent cloud of the shared helpers, as a static scene.
fn view_dependent() -> DynamicScene {
    DynamicScene::from_static(distill_common::view_dependent_cloud())
}

/// The first loss and the first validation's PSNRs of a fit of `scene` with `d_opts` (no
/// iterations, per-vertex parameters) on two orbit views, validated on three others.
fn first_loss_and_validation(scene: &DynamicScene, d_opts: DistillOptions) -> (f64, Vec<f64>) {
    let cloud = scene.composite(0.0);
    let fit = views::orbit(&cloud, 4, 0..2, 32, 24).unwrap();
    let val = views::orbit(&cloud, 5, 0..3, 32, 24).unwrap();
    let d_opts = DistillOptions {
        iterations: 0,
        params: ParamMode::Vertex,
        ..d_opts
    };
    let mut d = Distiller::new(scene, &opts(Profile::MeshSplats), &fit, &d_opts).unwrap();
    d.add_validation(scene, &val, &[0.0; 3]).unwrap();
    d.run(|_| {}).unwrap();
    let loss = d.loss_and_gradient().unwrap().0;
    (loss, d.validation_log()[0].psnr.clone())
}

/// `fit_sh_degree` changes the fitting views' targets and nothing else: the first loss is
/// the one of a fit whose targets are all at that degree (bit for bit), the validation
/// views' start is the one of a fit at the full degree (bit for bit), and both differ from
/// the other fit's, so the test sees which targets each set got.
#[test]
fn the_fitting_targets_sh_degree_leaves_the_validation_targets_alone() {
    let scene = view_dependent();
    let first = |target: u8, fit_degree: Option<u8>| {
        first_loss_and_validation(
            &scene,
            DistillOptions {
                target_sh_degree: target,
                fit_sh_degree: fit_degree,
                ..DistillOptions::default()
            },
        )
    };
    let (loss_mixed, val_mixed) = first(3, Some(0));
    let (loss_dc, val_dc) = first(0, None);
    let (loss_full, val_full) = first(3, None);
    assert_eq!(loss_mixed, loss_dc, "the fitting targets are at degree 0");
    assert_eq!(
        val_mixed, val_full,
        "the validation targets keep the full degree"
    );
    assert_ne!(
        loss_dc, loss_full,
        "the first band shows in the fitting targets"
    );
    assert_ne!(
        val_dc, val_full,
        "the first band shows in the validation targets"
    );
}

/// A zero opacity step keeps every vertex's alpha as converted while the colours move; a
/// zero colour step the other way round.
#[test]
fn a_zero_step_keeps_its_channels_as_converted() {
    let scene = view_dependent();
    let fit = views::orbit(&scene.composite(0.0), 4, 0..4, 32, 24).unwrap();
    for (lr_colour, lr_alpha) in [(0.02, 0.0), (1e-30, 0.02)] {
        let d_opts = DistillOptions {
            iterations: 5,
            params: ParamMode::Vertex,
            lr_colour,
            lr_alpha,
            ..DistillOptions::default()
        };
        let mut d = Distiller::new(&scene, &opts(Profile::MeshSplats), &fit, &d_opts).unwrap();
        let start = d.params().to_vec();
        d.run(|_| {}).unwrap();
        let moved = |lanes: std::ops::Range<usize>| {
            d.params()
                .iter()
                .zip(&start)
                .filter(|(a, b)| lanes.clone().any(|l| a[l] != b[l]))
                .count()
        };
        // A colour step of 1e-30 moves a value in [0, 1] by less than half an ulp of any
        // colour above 1e-23, which every converted colour here is (they are at least the
        // background's 1/255): none changes.
        let (colours, alphas) = (moved(0..3), moved(3..4));
        if lr_alpha == 0.0 {
            assert_eq!(alphas, 0, "no alpha moves at a zero opacity step");
            assert!(colours > 0, "the colours move");
        } else {
            assert_eq!(colours, 0, "no colour moves at a colour step of 1e-30");
            assert!(alphas > 0, "the alphas move");
        }
    }
}

/// `--distill-log` writes every validation (each view's PSNR and its change from the start)
/// and the held-back views' PSNRs before and after, which agree with what `convert` prints.
#[test]
fn the_distill_log_holds_every_validation_and_the_held_back_views() {
    let dir = temp_dir("distill-knobs", "log");
    let (out, log) = (dir.join("street.glb"), dir.join("fit.json"));
    let stderr = cli_common::distil_street_with(
        "2",
        &[
            "--distill-validation",
            "3",
            "--iterations",
            "20",
            "--distill-patience",
            "0",
            "--distill-log",
            path(&log),
        ],
        &out,
    );
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&log).unwrap()).unwrap();
    let vals = v["validations"].as_array().unwrap();
    let its: Vec<u64> = vals
        .iter()
        .map(|x| x["iteration"].as_u64().unwrap())
        .collect();
    assert_eq!(its, [0, 10, 20]);
    let start: Vec<f64> = serde_json::from_value(vals[0]["psnr"].clone()).unwrap();
    assert_eq!(start.len(), 3);
    for x in vals {
        let psnr: Vec<f64> = serde_json::from_value(x["psnr"].clone()).unwrap();
        let change: Vec<f64> = serde_json::from_value(x["change"].clone()).unwrap();
        for ((p, c), s) in psnr.iter().zip(&change).zip(&start) {
            // The change is the difference of the same two numbers, up to the rounding of
            // one subtraction of values near 30 dB (ulp 3.6e-15).
            assert!((p - s - c).abs() < 1e-12, "{p} - {s} vs {c}");
        }
    }
    let names: Vec<String> = serde_json::from_value(v["validation_names"].clone()).unwrap();
    assert_eq!(names.len(), 3);
    assert!(names.iter().all(|n| n.starts_with("sphere ")), "{names:?}");
    let held: Vec<String> = serde_json::from_value(v["held_back_names"].clone()).unwrap();
    assert_eq!(held.len(), 2);
    let before: Vec<f64> = serde_json::from_value(v["held_back_before"].clone()).unwrap();
    let after: Vec<f64> = serde_json::from_value(v["held_back_after"].clone()).unwrap();
    assert_eq!((before.len(), after.len()), (2, 2));
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    let said = format!("{:.2} dB → {:.2} dB", mean(&before), mean(&after));
    assert!(stderr.contains(&said), "{said} not in {stderr}");
}

/// The street fixture fitted from two views of an orbit and validated from five of another,
/// so that the fit, made for two directions, makes some validation view worse.
fn guarded() -> (
    DynamicScene,
    Vec<splatbridge_scene::Camera>,
    Vec<splatbridge_scene::Camera>,
) {
    let scene = splatbridge_scene::fixtures::street_with(
        &splatbridge_scene::fixtures::StreetParams::new(3, 3000),
    );
    let cloud = scene.composite(0.0);
    let mut fit = views::orbit(&cloud, 8, 0..8, 64, 48).unwrap();
    fit.truncate(2);
    let val = views::orbit(&cloud, 5, 0..5, 64, 48).unwrap();
    (scene, fit, val)
}

/// The guarded fit of [`guarded`] for `iterations` steps with `eps_backtrack_pixels` and
/// `tolerance`: its validation log, report and final parameters.
fn guarded_run(
    backtrack: f32,
    tolerance: f64,
    iterations: usize,
    patience: usize,
) -> (
    Vec<splatbridge::distill::guard::Validation>,
    splatbridge::distill::DistillReport,
    Vec<[f32; 4]>,
) {
    let (scene, fit, val) = guarded();
    let d_opts = DistillOptions {
        iterations,
        params: ParamMode::Vertex,
        guard_tolerance_db: tolerance,
        eps_backtrack_pixels: backtrack,
        patience,
        ..DistillOptions::default()
    };
    let mut d = Distiller::new(&scene, &opts(Profile::MeshSplats), &fit, &d_opts).unwrap();
    d.add_validation(&scene, &val, &[0.0; 5]).unwrap();
    d.run(|_| {}).unwrap();
    (d.validation_log().to_vec(), d.report(), d.params().to_vec())
}

/// Backtracking: the fit is the same as without it up to its first refused validation; there
/// it goes back to the best admissible iteration, exactly: with an ε so large that no later
/// step moves a value (1e30 pixels' loss: a step is lr·g/ε, far below half an ulp of any
/// colour), every later validation measures that iteration's colours bit for bit. A fit
/// whose every validation passes never backtracks and is the same bit for bit.
#[test]
fn a_refused_validation_sends_the_fit_back_to_the_best_admissible_iteration() {
    let default_tol = splatbridge::distill::guard::TOLERANCE_DB;
    let eps = DistillOptions::default().eps_pixels;
    let (plain, plain_report, _) = guarded_run(eps, default_tol, 40, 0);
    assert_eq!(
        plain_report.backtracked, None,
        "no backtrack at ε_backtrack = ε"
    );
    let refused = plain
        .iter()
        .position(|v| !v.admissible)
        .expect("the two-view fit makes some validation view worse");
    let (log, report, _) = guarded_run(1e30, default_tol, 40, 0);
    assert_eq!(
        &log[..=refused],
        &plain[..=refused],
        "the same fit up to the refusal"
    );
    let best = plain[..refused]
        .iter()
        .filter(|v| v.admissible)
        .max_by(|a, b| a.mean.total_cmp(&b.mean))
        .unwrap();
    assert_eq!(
        report.backtracked,
        Some((plain[refused].iteration, best.iteration))
    );
    assert!(log.len() > refused + 1, "validations after the backtrack");
    for v in &log[refused + 1..] {
        assert_eq!(
            v.psnr, best.psnr,
            "iteration {}: not the kept colours",
            v.iteration
        );
    }
    // Every validation admissible: no backtrack, the same parameters bit for bit.
    let (_, r1, p1) = guarded_run(eps, 1e9, 30, 0);
    let (_, r2, p2) = guarded_run(10.0, 1e9, 30, 0);
    assert_eq!((r1.backtracked, r2.backtracked), (None, None));
    assert_eq!(p1, p2);
}

/// After a backtrack to ε 10 the fit keeps moving: the last validation differs from the
/// one it went back to, and the kept iteration is never below the start. The backtrack is
/// progress for the patience: at a patience of 1 the fit still takes the steps after it.
#[test]
fn the_fit_goes_on_after_a_backtrack() {
    let tol = splatbridge::distill::guard::TOLERANCE_DB;
    let (_, r1, _) = guarded_run(10.0, tol, 40, 1);
    let (at, _) = r1.backtracked.expect("a backtrack");
    assert!(r1.iterations > at, "stopped at the backtrack: {r1:?}");
    let (log, report, _) = guarded_run(10.0, tol, 40, 0);
    let (at, to) = report.backtracked.expect("a backtrack");
    let back = log.iter().find(|v| v.iteration == to).unwrap();
    let last = log.last().unwrap();
    assert!(last.iteration > at);
    assert_ne!(last.psnr, back.psnr, "nothing moved after the backtrack");
    assert!(report.validation_kept >= report.validation_start);
}

/// `target_near` reaches the fitting and the validation targets: a near plane beyond every
/// Gaussian empties both (the first loss and the validation PSNRs change), and one closer than
/// every Gaussian to the orbit's cameras drops none, giving the reference's targets bit for
/// bit.
#[test]
fn the_targets_near_plane_reaches_the_fitting_and_validation_targets() {
    let scene = view_dependent();
    let first = |near: f32| {
        first_loss_and_validation(
            &scene,
            DistillOptions {
                target_near: near,
                ..DistillOptions::default()
            },
        )
    };
    let reference = first(splatbridge_hybrid::native::NEAR_REFERENCE);
    // The orbit's cameras stand outside the cloud's bounds, about 2.5 radii from its centre
    // (`views::orbit`: the radius over sin(fov/2), 1.05×), so no Gaussian is within 0.2 of
    // one and both planes keep every Gaussian.
    assert_eq!(
        first(1e-3),
        reference,
        "no Gaussian lies in front of either plane"
    );
    let (loss_far, val_far) = first(1e6);
    assert_ne!(
        loss_far, reference.0,
        "the fitting targets lost their Gaussians"
    );
    assert_ne!(val_far, reference.1, "the validation targets lost theirs");
}

/// The `--distill-log` of a zero-step distillation of the street through 32×24 windows, with
/// no held-back views, and `flags` (the views and the knobs a test varies) after those.
fn small_fit_log(name: &str, flags: &[&str]) -> serde_json::Value {
    let dir = temp_dir("distill-knobs", name);
    let scene = cli_common::street();
    let (out, log) = (dir.join("street.glb"), dir.join("fit.json"));
    let mut args = vec![
        "convert",
        scene.as_str(),
        "--distill",
        "--distill-width",
        "32",
        "--distill-height",
        "24",
        "--held-back",
        "0",
        "--iterations",
        "0",
        "--distill-log",
        path(&log),
        "-o",
        path(&out),
    ];
    args.extend_from_slice(flags);
    cli_common::ok(&args);
    serde_json::from_slice(&std::fs::read(&log).unwrap()).unwrap()
}

/// `--distill-validation-fine N` adds N validation views at the `sphere:N` fitting views'
/// fine end, after the others: the nearest distance (0.5× the orbit's) and the largest size
/// the export is made for, whatever the order `--distill-for` names them in. The street's
/// default `orbit:4` views take none (`the_distill_log_holds_every_validation_…`: three
/// names with the default of two fine-end views).
#[test]
fn fine_end_validation_views_are_the_nearest_and_largest() {
    let v = small_fit_log(
        "fine",
        &[
            "--views",
            "sphere:3",
            "--distill-for",
            "64x48,48x36",
            "--distill-validation",
            "2",
            "--distill-validation-fine",
            "1",
        ],
    );
    let names: Vec<String> = serde_json::from_value(v["validation_names"].clone()).unwrap();
    assert_eq!(names.len(), 3, "{names:?}");
    assert!(names[2].contains("0.50×, 64×48 "), "{names:?}");
    assert!(names[..2].iter().all(|n| !n.contains("0.50×")), "{names:?}");
}

/// `--distill-fit-fine N` adds N fitting views to `sphere:M` (the report counts M + N views),
/// and none to a camera list such as `orbit:4` (four windows a view, as without it).
#[test]
fn fine_end_fitting_views_are_added_to_the_sphere_only() {
    let views_of = |views: &str, fine: &str| {
        let name = format!("fit-fine-{}-{fine}", views.replace(':', "-"));
        let flags = [
            "--views",
            views,
            "--distill-for",
            "64x48",
            "--distill-validation",
            "0",
            "--distill-fit-fine",
            fine,
        ];
        small_fit_log(&name, &flags)["report"]["views"]
            .as_u64()
            .unwrap()
    };
    assert_eq!(views_of("sphere:3", "0"), 3);
    assert_eq!(views_of("sphere:3", "2"), 5);
    assert_eq!(views_of("orbit:4", "3"), views_of("orbit:4", "0"));
}
