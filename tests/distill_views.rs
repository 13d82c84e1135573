//! Distillation where people look: fitted over the view sphere at several sizes, measured on
//! held-back views of other elevations, distances and sizes, never within a few degrees of a
//! fitting view, on a cut of the shipped real capture (`fixtures/real/fourth_st.spz`).

use std::path::Path;

use splatbridge::distill::run::worst_and_median;
use splatbridge::distill::{native_targets, views, DistillOptions, Distiller};
use splatbridge_convert::{ConvertOptions, Profile};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::formats::load_cloud;
use splatbridge_scene::ply::ReadOptions;
use splatbridge_scene::{Camera, Frame};

/// The 4,000 Gaussians of the real capture nearest its robust centre: a piece of real street
/// (facade, ground, clutter) small enough to fit in a test.
fn real_cut() -> DynamicScene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/real/fourth_st.spz");
    let (mut cloud, _) = load_cloud(&path, &ReadOptions::default()).unwrap();
    let (lo, hi) = cloud.robust_bounds(0.02).unwrap();
    let c = 0.5 * (lo + hi);
    let d2: Vec<f32> = cloud
        .means
        .iter()
        .map(|m| (*m - c).length_squared())
        .collect();
    let mut sorted = d2.clone();
    sorted.sort_by(f32::total_cmp);
    let cut = sorted[4000.min(sorted.len() - 1)];
    cloud.retain_indices(|i| d2[i] < cut);
    DynamicScene::from_static(cloud)
}

fn psnr_each(d: &mut Distiller, cams: &[Camera], refs: &[Frame]) -> Vec<f64> {
    cams.iter()
        .zip(refs)
        .map(|(c, r)| splatbridge_scene::metrics::psnr(&d.render(c).unwrap(), r).unwrap())
        .collect()
}

/// The distilled export at its defaults (footprint, validation views) beats the undistilled
/// MeshSplats export at every held-back view: other elevations (−10…60°), distances
/// (0.5–1.2× the orbit's) and sizes than the fitting views', at least 5° from each.
#[test]
fn held_back_views_off_the_fitting_set_improve_and_none_degrades() {
    let scene = real_cut();
    let cloud = &scene.static_gaussians;
    // Fitting sizes 96×72 and 192×144 through 96×72 windows: the second is fitted at the
    // first's cost, with its own footprint.
    let sizes = [(96, 72), (192, 144)];
    let window = (96, 72);
    let fit = views::sphere(cloud, 24, &sizes, window).unwrap();
    let val = views::sphere_range(cloud, 24..30, &sizes, window).unwrap();
    let avoid = [&fit.frames[..], &val.frames];
    // Held back at sizes of their own, neither fitted: 80×60 and 160×120.
    let held = views::held_back_classes(cloud, &[(80, 60), (160, 120)], 1, &avoid).unwrap();
    let cams: Vec<Camera> = held.iter().map(|h| h.camera.clone()).collect();
    let refs = native_targets(&scene, 0.0, &cams).unwrap();

    let convert = ConvertOptions {
        profile: Profile::MeshSplats,
        ..ConvertOptions::default()
    };
    let plain_opts = DistillOptions {
        footprint: false,
        ..DistillOptions::default()
    };
    let tiny = views::window_of(&cams[0], (8, 6), 0.5, 0.5);
    let mut plain = Distiller::new(&scene, &convert, &[tiny], &plain_opts).unwrap();
    let before = psnr_each(&mut plain, &cams, &refs);

    let opts = DistillOptions {
        iterations: 30,
        ..DistillOptions::default()
    };
    let (mut d, _) =
        Distiller::for_windows(&scene, &convert, &fit.windows, &fit.frames, &opts).unwrap();
    d.add_validation(&scene, &val.windows, &[0.0; 6]).unwrap();
    d.run(|_| {}).unwrap();
    let after = psnr_each(&mut d, &cams, &refs);

    let change: Vec<f64> = after.iter().zip(&before).map(|(a, b)| a - b).collect();
    let (worst, median) = worst_and_median(&change).unwrap();
    let table: Vec<String> = held
        .iter()
        .zip(before.iter().zip(&after))
        .map(|(h, (b, a))| format!("{}: {b:.2} → {a:.2}", h.camera.name))
        .collect();
    // No view may end below the plain export: 0.05 dB is above the PSNR noise of the
    // file's u16 colour quantisation (below 0.01 dB at these sizes) and far below any real
    // loss (the orbit fit lost 1.5–5.1 dB off its ring). The median must be a clear gain:
    // 1 dB is under half the smallest median measured with the same defaults at full size
    // (`pc_short`, twelve held-back views: +3.95 dB median, +1.25 dB worst; docs/distill.md).
    assert!(worst > -0.05, "worst {worst:.2} dB\n{}", table.join("\n"));
    assert!(median > 1.0, "median {median:.2} dB\n{}", table.join("\n"));
}
