//! The undistilled export as the floor of what `distill_export` writes (`distill::plain`):
//! where the kept fit is below the export without distillation at a validation view, that
//! export is written, and its held-back figures are the "before" of every report.

mod distill_common;

use distill_common::opts;
use splatbridge::distill::run::{distill_export, ViewRequest};
use splatbridge::distill::DistillOptions;
use splatbridge_convert::Profile;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::fixtures::large;

fn small_scene(n: usize) -> DynamicScene {
    DynamicScene::from_static(large(n, 7))
}

/// Views over the sphere at two sizes, 48×36 and 192×144 (each fitted through a 48×36
/// window), three validation views of the same distribution and two held-back views.
fn two_sizes() -> ViewRequest {
    ViewRequest {
        spec: "sphere:6".into(),
        width: 48,
        height: 36,
        sizes: vec![(48, 36), (192, 144)],
        held_back: 2,
        held_size: Some((192, 144)),
        fit_fine: 0,
        validation: 3,
        validation_fine: 1,
        times: 1,
        ..ViewRequest::default()
    }
}

/// Widened for the coarsest view that sees each Gaussian (footprint quantile 1: the 48×36
/// views' low-pass, 16 times the 192×144 views' in area), the mesh blurs what the large
/// validation views see sharp, and with no step to make up for it the kept start is below the
/// undistilled export there: `distill_export` hands back the scene as it was (not widened),
/// no fitted colours, and held-back figures that are the undistilled export's before and
/// after (measured: the widened start gains 6.8 and 8.5 dB on two 48×36 validation views
/// and loses 6.0 and 8.5 dB on two 192×144 ones). It fails when the check is skipped (the
/// widened scene comes back); `floor: false` skips it.
#[test]
fn the_undistilled_export_is_written_where_the_fit_is_below_it() {
    let original = small_scene(1500);
    let mut scene = original.clone();
    let mut convert = opts(Profile::MeshSplats);
    let d_opts = DistillOptions {
        iterations: 0,
        footprint_quantile: 1.0,
        ..DistillOptions::default()
    };
    let out = distill_export(&mut scene, &mut convert, &two_sizes(), &d_opts, |_| {}).unwrap();
    let floor = out.undistilled.as_ref().expect("a widened fit is checked");
    assert_eq!(floor.change.len(), 4, "{floor:?}");
    assert!(floor.kept_undistilled, "{floor:?}");
    let (_, worst) = floor.worst().unwrap();
    assert!(worst < -d_opts.guard_tolerance_db, "{floor:?}");
    assert_eq!(
        scene.static_gaussians.log_scales, original.static_gaussians.log_scales,
        "the scene written is the one given"
    );
    assert!(convert.vertex_colours.is_none());
    assert_eq!(out.held_back_before, out.held_back_after);
    assert!(
        out.description.contains("the undistilled export written"),
        "{}",
        out.description
    );
    // Without the floor, the same fit hands back the widened scene and its colours.
    let mut scene = original.clone();
    let mut convert = opts(Profile::MeshSplats);
    let no_floor = DistillOptions {
        floor: false,
        ..d_opts
    };
    let out = distill_export(&mut scene, &mut convert, &two_sizes(), &no_floor, |_| {}).unwrap();
    assert!(out.undistilled.is_none());
    assert_ne!(
        scene.static_gaussians.log_scales,
        original.static_gaussians.log_scales
    );
    assert!(convert.vertex_colours.is_some());
}

/// Without the footprint the mesh fitted is the undistilled export's, so nothing is checked
/// and the fitted colours are handed back; with it at its default (quantile 0, the most
/// detailed view's low-pass) on the same views, the check runs and its verdict follows its
/// figures.
#[test]
fn the_check_runs_where_the_mesh_was_widened() {
    for footprint in [false, true] {
        let mut scene = small_scene(1500);
        let mut convert = opts(Profile::MeshSplats);
        let d_opts = DistillOptions {
            iterations: 10,
            footprint,
            ..DistillOptions::default()
        };
        let out = distill_export(&mut scene, &mut convert, &two_sizes(), &d_opts, |_| {}).unwrap();
        match &out.undistilled {
            None => {
                assert!(!footprint);
                assert!(convert.vertex_colours.is_some());
            }
            Some(f) => {
                assert!(footprint);
                let below = f.change.iter().any(|&c| c < -d_opts.guard_tolerance_db);
                assert_eq!(f.kept_undistilled, below, "{f:?}");
                assert_eq!(convert.vertex_colours.is_none(), f.kept_undistilled);
            }
        }
    }
}

/// The held-back measurement, a view per thread (`Distiller::psnr_each`), is
/// `Distiller::render_at`'s image measured view after view, bit for bit, in ray order and in
/// splat order, with the colours of the fit as it stands.
#[test]
fn psnr_each_is_render_at_measured_view_by_view() {
    use splatbridge::distill::HitOrder;
    // The street fixture's orbit, which a fit of 20 steps visibly changes between its views.
    let (scene, fit, held, targets) = distill_common::street_fit_and_held_back();
    let times = vec![0.0; held.len()];
    for order in [HitOrder::Ray, HitOrder::Splat] {
        let d_opts = DistillOptions {
            iterations: 20,
            order,
            ..DistillOptions::default()
        };
        let mut d =
            splatbridge::distill::Distiller::new(&scene, &opts(Profile::MeshSplats), &fit, &d_opts)
                .unwrap();
        let start = d.psnr_each(&held, &times, &targets).unwrap();
        d.run(|_| {}).unwrap();
        let each = d.psnr_each(&held, &times, &targets).unwrap();
        // The fit changed what the views see, so a measurement of stale colours would show.
        assert_ne!(start, each, "{order:?}");
        for ((cam, t), p) in held.iter().zip(&targets).zip(&each) {
            let img = d.render_at(cam, 0.0).unwrap();
            let q = splatbridge_scene::metrics::psnr(&img, t).unwrap();
            assert_eq!(
                p.to_bits(),
                q.to_bits(),
                "{order:?} {}: {p} vs {q}",
                cam.name
            );
        }
    }
}

/// `Undistilled` traces the export as an unfitted distiller of the plain mesh does (the
/// reference `accuracy` used for the plain export before), for every profile, up to the
/// rounding of the colours' u16 decode.
#[test]
fn undistilled_traces_as_an_unfitted_distiller() {
    use splatbridge::distill::plain::Undistilled;
    use splatbridge::distill::Distiller;
    let (scene, fit, held, _) = distill_common::street_fit_and_held_back();
    let d_opts = DistillOptions {
        footprint: false,
        ..DistillOptions::default()
    };
    for profile in [Profile::MeshSplats, Profile::Texture, Profile::Rings] {
        let convert = opts(profile);
        let undistilled = Undistilled::new(&scene, &convert, &d_opts).unwrap();
        let mut d = Distiller::new(&scene, &convert, &fit[..1], &d_opts).unwrap();
        for cam in &held {
            let a = undistilled.render_at(cam, 0.0).unwrap();
            let b = d.render_at(cam, 0.0).unwrap();
            // The distiller applies its colours quantised as the file stores them,
            // round(x·65535)/65535; the file's colours come through the glTF loader's own
            // decode: the same values to an ulp, 1–2 ulps of the image's (measured: 1.2e-7
            // at worst over these 12 views, 14–67 values a view). 2.4e-7 is 4 ulps at 1.0;
            // a mesh of other Gaussians or other colours (widened, fitted) is off by 1e-3
            // and more.
            let worst = distill_common::worst_difference(&a.rgb, &b.rgb);
            assert!(worst <= 2.4e-7, "{profile:?} {}: {worst:e}", cam.name);
        }
    }
}
