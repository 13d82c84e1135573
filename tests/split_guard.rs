//! The guarded surfel split (`splatbridge_scene::surfel_guard`) and `--split auto`
//! (`splatbridge::pipeline::split_auto`), on small synthetic scenes rendered natively (the reference) and
//! with the GES hybrid:
//!
//! - one test per guard: the failure it prevents is visible without it (the hybrid far from
//!   native, the offending Gaussian a surfel) and gone with it (the Gaussian stays a Gaussian,
//!   the hybrid close to native), each with only that guard on;
//! - the split is the same twice and at 1 and 4 threads;
//! - `--split auto` meets `--min-psnr` on a synthetic scene, picks the cheapest rung that does,
//!   and reports its cost; the CLI reports it in `--json`;
//! - bad `--split` / `--min-psnr` / guard values exit 2 naming the option.

use std::process::Command;

use glam::{DVec3, Quat, Vec3};
use splatbridge::pipeline::split_auto::{
    choose, choose_from, ladder, AutoConfig, DISC_FOOTPRINT_SIGMAS,
};
use splatbridge_hybrid::ges::{render_ges, Blend, GesOptions};
use splatbridge_hybrid::{render, RenderOptions};
use splatbridge_scene::metrics::psnr;
use splatbridge_scene::surfel_guard::GuardCounts;
use splatbridge_scene::surfels::{split, split_counted, SplitParams};
use splatbridge_scene::{Camera, GaussianCloud};

const BIN: &str = env!("CARGO_BIN_EXE_splatbridge");

/// A wall of small, flat, opaque Gaussians facing the camera at depth `z`, all one colour:
/// `n × n` of them at `spacing`, each with scale `0.7·spacing` in the wall's plane (so
/// neighbours overlap and the wall is closed) and a tenth of that across it. One colour,
/// because coplanar surfels tie in the z-buffer and a patterned wall would measure that
/// (the 3.33σ footprint of a surfel against the Gaussian's soft falloff), not the guards.
fn wall(c: &mut GaussianCloud, n: usize, spacing: f32, z: f32) {
    let s = 0.7 * spacing;
    let half = 0.5 * spacing * (n as f32 - 1.0);
    for i in 0..n {
        for j in 0..n {
            c.push_activated(
                Vec3::new(i as f32 * spacing - half, j as f32 * spacing - half, z),
                Vec3::new(s, s, 0.1 * s),
                Quat::IDENTITY,
                0.95,
                Vec3::new(0.2, 0.6, 0.3),
            );
        }
    }
}

/// A flat opaque disc-like Gaussian facing the camera.
fn flat(c: &mut GaussianCloud, at: Vec3, s: f32, rgb: Vec3) {
    c.push_activated(at, Vec3::new(s, s, 0.05 * s), Quat::IDENTITY, 0.9, rgb);
}

/// The camera of every scene: at the origin looking down +z, 50° vertical field of view.
fn camera() -> Camera {
    Camera::look_at(DVec3::ZERO, DVec3::Z, DVec3::NEG_Y, 50.0, 64, 48).unwrap()
}

/// The base scene: a 2 m wall 1.5 m away (it fills the 64×48 view: half-height
/// 1.5·tan 25° = 0.7 m), 60×60 Gaussians.
fn base() -> GaussianCloud {
    let mut c = GaussianCloud::new(0);
    wall(&mut c, 60, 2.0 / 59.0, 1.5);
    c
}

/// Every guard off, the local thresholds at their defaults.
fn unguarded() -> SplitParams {
    let d = SplitParams::default();
    SplitParams::unguarded(d.min_opacity, d.max_flatness)
}

/// PSNR of the hybrid with `p` against native, and the split's counts.
fn hybrid_psnr(c: &GaussianCloud, p: &SplitParams) -> (f64, usize, GuardCounts) {
    let cam = camera();
    let (reference, _) = render(c, &cam, &RenderOptions::default()).unwrap();
    let (s, g, counts) = split_counted(c, p);
    let (img, _) = render_ges(&s, &g, &cam, &GesOptions::default()).unwrap();
    (psnr(&reference, &img).unwrap(), s.len(), counts)
}

#[test]
fn the_wall_alone_is_split_into_surfels_by_every_guard() {
    // The base scene is what a fair surfel split looks like: every guard keeps every wall
    // Gaussian a surfel, and the hybrid is close to native.
    let c = base();
    let (db, n, counts) = hybrid_psnr(&c, &SplitParams::default());
    assert_eq!(n, c.len(), "{counts:?}");
    // 30 dB: the bar is 28; the flat wall measured well above it.
    assert!(db > 30.0, "{db:.2} dB");
}

/// Runs one guard's test: `bad` is the index of the Gaussian the guard must reject.
fn guard_case(
    c: &GaussianCloud,
    bad: usize,
    with: SplitParams,
    rejected_by: impl Fn(&GuardCounts) -> usize,
) -> (f64, f64) {
    let (db_without, n_without, _) = hybrid_psnr(c, &unguarded());
    let (db_with, n_with, counts) = hybrid_psnr(c, &with);
    assert_eq!(
        n_without,
        c.len(),
        "without the guard every Gaussian is a surfel"
    );
    assert_eq!(
        n_with,
        c.len() - 1,
        "with it only the offender stays a Gaussian: {counts:?}"
    );
    assert_eq!(rejected_by(&counts), 1, "{counts:?}");
    let (s, g) = split(c, &with);
    assert_eq!(g.len(), 1);
    assert_eq!(g.means[0], c.means[bad]);
    assert!(!s.means.contains(&c.means[bad]));
    eprintln!("PSNR without {db_without:.2} dB, with {db_with:.2} dB");
    (db_without, db_with)
}

#[test]
fn scene_scale_guard_keeps_a_wall_sized_floater_soft() {
    // A 1.2 m-σ flat opaque Gaussian half a metre in front of the wall, centred 1.9 m to the
    // right: on screen only its tail (1.1σ–2.9σ from its centre, native alpha 0.5 down to
    // 0.01). As a surfel it is a hard red disc 4 m across over the whole view.
    let mut c = base();
    let bad = c.len();
    flat(
        &mut c,
        Vec3::new(1.9, 0.0, 1.0),
        1.2,
        Vec3::new(0.9, 0.1, 0.1),
    );
    let with = SplitParams {
        max_scene_fraction: SplitParams::default().max_scene_fraction,
        ..unguarded()
    };
    let (without, with) = guard_case(&c, bad, with, |k| k.too_large_for_scene);
    // Measured 8.44 dB without the guard and 27.98 dB with it; the bars leave 3 dB of margin
    // each way. What remains with the guard is the hybrid's unsorted blend of the tail over
    // the wall, the same in kind as any residual Gaussian's.
    assert!(without < 11.5, "without the guard: {without:.2} dB");
    assert!(with > 25.0, "with the guard: {with:.2} dB");
}

#[test]
fn neighbourhood_guard_keeps_coarse_fill_off_fine_detail() {
    // A Gaussian 8× the wall's scale, flat and opaque, 2 cm in front of the wall in the middle
    // of the view: native shows its soft centre over the wall, the surfel paints out to 3.33σ
    // and hides the wall in a 0.9 m circle.
    let mut c = base();
    let bad = c.len();
    let s_wall = 0.7 * 2.0 / 59.0;
    flat(
        &mut c,
        Vec3::new(0.0, 0.0, 1.48),
        8.0 * s_wall,
        Vec3::new(0.1, 0.1, 0.9),
    );
    let with = SplitParams {
        max_neighbour_ratio: SplitParams::default().max_neighbour_ratio,
        ..unguarded()
    };
    let (without, with) = guard_case(&c, bad, with, |k| k.too_large_for_neighbours);
    // Measured 11.13 dB without and 29.76 dB with; bars 3 dB inside each.
    assert!(without < 14.0, "without the guard: {without:.2} dB");
    assert!(with > 26.5, "with the guard: {with:.2} dB");
}

#[test]
fn isolation_guard_keeps_a_lone_floater_soft() {
    // A lone flat opaque Gaussian (σ = 8 cm) 0.9 m in front of the wall: no other centre within
    // its 0.27 m footprint. As a surfel its hard rim reaches 3.33σ, where native has faded out.
    let mut c = base();
    let bad = c.len();
    flat(
        &mut c,
        Vec3::new(0.1, 0.05, 0.6),
        0.08,
        Vec3::new(0.9, 0.8, 0.1),
    );
    let with = SplitParams {
        min_neighbours: SplitParams::default().min_neighbours,
        ..unguarded()
    };
    let (without, with) = guard_case(&c, bad, with, |k| k.isolated);
    // Measured 11.38 dB without and 29.81 dB with; bars 3 dB inside each.
    assert!(without < 14.5, "without the guard: {without:.2} dB");
    assert!(with > 26.5, "with the guard: {with:.2} dB");
}

#[test]
fn split_is_the_same_twice_and_at_any_thread_count() {
    // 20,000 Gaussians of the synthetic large scene with loose thresholds, so thousands of
    // candidates reach the guards.
    let c = splatbridge_scene::fixtures::large(20_000, 7);
    let p = SplitParams {
        min_opacity: 0.3,
        max_flatness: 1.0,
        ..SplitParams::default()
    };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| split_counted(&c, &p))
    };
    let (s1, g1, k1) = run(1);
    let (s4, g4, k4) = run(4);
    let (s4b, g4b, k4b) = run(4);
    assert!(k1.candidates > 1000, "{k1:?}");
    assert!(!s1.is_empty() && s1.len() < k1.candidates, "{k1:?}");
    assert_eq!((&s1, &g1, k1), (&s4, &g4, k4));
    assert_eq!((&s4, &g4, k4), (&s4b, &g4b, k4b));
}

/// The scene-scale case: a floater that ruins the unguarded split.
fn floater_scene() -> GaussianCloud {
    let mut c = base();
    flat(
        &mut c,
        Vec3::new(1.9, 0.0, 1.0),
        1.2,
        Vec3::new(0.9, 0.1, 0.1),
    );
    c
}

#[test]
fn auto_split_meets_the_target_at_the_least_work_and_reports_its_cost() {
    let c = floater_scene();
    let cfg = AutoConfig {
        min_psnr: 20.0,
        views: 2,
        width: 48,
        height: 36,
        ..AutoConfig::default()
    };
    let mut rungs = ladder();
    rungs.push(("unguarded".into(), unguarded(), None));
    let n = rungs.len();
    let a = choose_from(&c, &GesOptions::default(), &cfg, rungs).unwrap();
    assert!(a.met);
    let chosen = &a.candidates[a.chosen];
    // The fitting views must clear the target by the margin, not just the target.
    let target = cfg.min_psnr + cfg.margin;
    assert!(cfg.margin > 0.0);
    assert!(chosen.worst_psnr >= target);
    assert_eq!(chosen.psnr.len(), 2);
    // The disc rungs render with the √2σ footprint, every other rung with the caller's.
    for r in &a.candidates {
        let want = if r.label.contains("disc") {
            DISC_FOOTPRINT_SIGMAS
        } else {
            GesOptions::default().footprint_sigmas
        };
        assert_eq!(r.footprint, want, "{}", r.label);
    }
    assert_eq!(
        a.candidates
            .iter()
            .filter(|r| r.label.contains("disc"))
            .count(),
        2,
        "one disc rung, both blends"
    );
    assert_eq!(
        a.apply(&GesOptions::default()).footprint_sigmas,
        chosen.footprint
    );
    // At the disc's own footprint the disc rung would repeat the default one: skipped.
    let at_disc = GesOptions {
        footprint_sigmas: DISC_FOOTPRINT_SIGMAS,
        ..GesOptions::default()
    };
    let d = choose(&c, &at_disc, &cfg).unwrap();
    assert_eq!(d.candidates.len(), 2 * (ladder().len() - 1));
    assert!(d.candidates.iter().all(|r| !r.label.contains("disc")));
    // No rung that meets the target does less work.
    for r in &a.candidates {
        if r.worst_psnr >= target {
            assert!(r.work >= chosen.work, "{} beats {}", r.label, chosen.label);
        }
    }
    // Every rung with both blends, in ladder order.
    let m = 2 * n;
    assert_eq!(a.candidates.len(), m);
    for (k, r) in a.candidates.iter().enumerate() {
        let want = if k % 2 == 0 {
            Blend::Unsorted
        } else {
            Blend::Sorted
        };
        assert_eq!(r.blend, want, "{}", r.label);
    }
    // The unguarded rung makes the floater a surfel and misses the target by far, blended
    // either way.
    assert!(a.candidates[m - 2].worst_psnr < cfg.min_psnr);
    assert!(a.candidates[m - 1].worst_psnr < cfg.min_psnr);
    assert_eq!(a.renders, 2 * (1 + m));
    assert!(a.ms > 0.0);
    let j = a.to_json();
    assert_eq!(j["cost"]["views"], 2);
    assert_eq!(j["cost"]["renders"], 2 * (1 + m));
    assert!(j["blend"] == "sorted" || j["blend"] == "unsorted");
    assert!(j["cost"]["milliseconds"].as_f64().unwrap() > 0.0);
    // The same choice again.
    let b = choose(&c, &GesOptions::default(), &cfg).unwrap();
    let again = choose(&c, &GesOptions::default(), &cfg).unwrap();
    assert_eq!(b.chosen, again.chosen);
    assert_eq!(b.params(), again.params());
}

#[test]
fn auto_split_says_when_no_rung_meets_the_target() {
    let c = floater_scene();
    let cfg = AutoConfig {
        min_psnr: 150.0,
        views: 1,
        width: 32,
        height: 24,
        // Unsorted only: with the sorted blend the no-surfel rung is native itself.
        blends: vec![Blend::Unsorted],
        margin: 0.0,
    };
    let a = choose(&c, &GesOptions::default(), &cfg).unwrap();
    assert!(!a.met);
    let best = a
        .candidates
        .iter()
        .map(|r| r.worst_psnr)
        .fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(a.candidates[a.chosen].worst_psnr, best);
}

/// A temporary folder removed when the guard drops.
fn temp(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("splatbridge-split-{name}-"))
        .tempdir()
        .expect("a temporary folder")
}

fn street() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/street/scene.json").into()
}

#[test]
fn cli_split_auto_reports_the_choice_and_its_cost() {
    let dir = temp("auto");
    let out = dir.path().join("h.png");
    let scene = street();
    let r = Command::new(BIN)
        .args([
            "hybrid",
            &scene,
            "--camera",
            "scene:0",
            "--width",
            "64",
            "--height",
            "48",
            "--split",
            "auto",
            "--min-psnr",
            "20",
            "--json",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let a = &v["split_auto"];
    assert_eq!(a["min_psnr"], 20.0);
    assert!(a["cost"]["milliseconds"].as_f64().unwrap() > 0.0);
    assert_eq!(a["cost"]["views"], 4);
    assert!(a["params"]["min_opacity"].is_number());
    assert_eq!(v["knobs"]["split"], "auto");
    assert!(out.exists());
}

#[test]
fn cli_bad_split_values_exit_2_naming_the_option() {
    let dir = temp("bad");
    let out = dir.path().join("h.png");
    let scene = street();
    for (opt, val) in [
        ("--split", "sometimes"),
        ("--min-psnr", "-3"),
        ("--min-psnr", "nan"),
        ("--min-psnr", "inf"),
        ("--surfel-scene-fraction", "0"),
        ("--surfel-neighbour-ratio", "-1"),
        ("--surfel-min-neighbours", "many"),
    ] {
        let r = Command::new(BIN)
            // `--opt=value`, so a negative number is not taken for an option.
            .args([
                "hybrid",
                &scene,
                "--camera",
                "scene:0",
                &format!("{opt}={val}"),
                "-o",
            ])
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{opt} {val}: {err}");
        assert!(err.contains(opt), "{opt} {val}: {err}");
        assert!(!out.exists(), "{opt} {val} wrote an image");
    }
}

#[test]
fn auto_split_margin_raises_the_bar_it_chooses_by() {
    // With a margin the chosen rung may be dearer, never one that misses target + margin.
    let c = floater_scene();
    let base = AutoConfig {
        min_psnr: 20.0,
        views: 1,
        width: 32,
        height: 24,
        blends: vec![Blend::Unsorted],
        margin: 0.0,
    };
    let a = choose(&c, &GesOptions::default(), &base).unwrap();
    // Put the bar just above the choice without margin: with the margin it must move on.
    let margin = a.candidates[a.chosen].worst_psnr - base.min_psnr + 0.01;
    let b = choose(
        &c,
        &GesOptions::default(),
        &AutoConfig {
            margin,
            ..base.clone()
        },
    )
    .unwrap();
    if b.met {
        assert!(b.candidates[b.chosen].worst_psnr >= base.min_psnr + margin);
        assert_ne!(b.chosen, a.chosen);
    } else {
        assert!(b
            .candidates
            .iter()
            .all(|r| r.worst_psnr < base.min_psnr + margin));
    }
    let bad = AutoConfig {
        margin: f64::NAN,
        ..base
    };
    assert!(choose(&c, &GesOptions::default(), &bad).is_err());
}
