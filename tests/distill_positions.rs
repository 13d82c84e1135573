//! Fitting vertex positions (`--distill-positions`): the position gradient against finite
//! differences of the re-traced loss, the fitted export traced to the fitted mesh's image,
//! and the texture profile refused.

mod distill_common;

use splatbridge::distill::run::distill_export;
use splatbridge::distill::{views, DistillOptions, Distiller, Loss};
use splatbridge_convert::Profile;
use splatbridge_raytrace::RenderOptions;
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::fixtures::large;

use distill_common::{
    grad_scale, largest, opts, refit, small_request, trace_export, worst_difference,
};

fn with_positions(loss: Loss) -> DistillOptions {
    DistillOptions {
        positions: true,
        loss,
        ..DistillOptions::default()
    }
}

/// The analytic position gradient (barycentrics through the ray–triangle solve) against
/// central differences of the loss with the mesh moved and re-traced, for the coordinates
/// with the largest gradients, on the fan profiles.
#[test]
fn position_gradient_matches_finite_differences() {
    // Gaussians large enough in these views that their fans are hit (the `large` fixture's
    // are mostly under a pixel at 24×18, and a view without hits has no gradient).
    let scene = DynamicScene::from_static(distill_common::crossing_cloud(120));
    let cloud = scene.composite(0.0);
    let cams = views::orbit(&cloud, 4, 0..1, 24, 18).unwrap();
    for profile in [Profile::MeshSplats, Profile::Rings] {
        let mut d =
            Distiller::new(&scene, &opts(profile), &cams, &with_positions(Loss::L2)).unwrap();
        d.loss_and_gradient().unwrap();
        let grad = d.position_gradient().to_vec();
        let scale = grad_scale(&grad, 3);
        assert!(scale > 0.0, "{profile:?}: no position gradient");
        for (v, c) in largest(&grad, 3, |_, _| true, 8) {
            let size = d.positions().unwrap().size[v];
            assert!(size > 0.0);
            // A step of 1e-4 of the Gaussian's size: far above f32 position rounding (the
            // coordinates are under 1, rounded to 6e-8; a size of 0.05 to 0.15 makes the
            // step 5e-6 to 1.5e-5), small enough that
            // no ray's set of hits changes (a hit appearing or vanishing would be a step in
            // the loss that no gradient carries).
            let e = 1e-4f32;
            let o0 = d.positions().unwrap().offset[v][c];
            let at = |o: f32, d: &mut Distiller| {
                d.positions_mut().unwrap().offset[v][c] = o;
                d.refresh_geometry().unwrap();
                d.loss_and_gradient().unwrap().0
            };
            let lp = at(o0 + e, &mut d);
            let lm = at(o0 - e, &mut d);
            at(o0, &mut d);
            let fd = (lp - lm) / (2.0 * (e * size) as f64);
            let g = grad[v][c] as f64;
            // The loss is composited in f32 (~1e-7 relative over hundreds of hits, i.e.
            // 1e-7·L / (2e-4·size) of the gradient), and the barycentrics' response is
            // linear only to first order over ±1e-4 of a size; 10 % of the value or 2 % of
            // the largest component, as for the colour gradient.
            let tol = (0.1 * fd.abs()).max(0.02 * scale);
            assert!(
                (g - fd).abs() <= tol,
                "{profile:?}: vertex {v} axis {c}: analytic {g:e} vs finite difference {fd:e}"
            );
        }
    }
}

/// With positions fitted, the export is written with the fitted positions and traces to the
/// image of the fitted mesh in memory; the positions moved.
#[test]
fn export_with_fitted_positions_traces_like_the_fitted_mesh() {
    let original = DynamicScene::from_static(large(1500, 7));
    let mut scene = original.clone();
    let mut convert = opts(Profile::MeshSplats).for_viewers();
    let req = small_request();
    let d_opts = DistillOptions {
        iterations: 4,
        ..with_positions(Loss::default())
    };
    let out = distill_export(&mut scene, &mut convert, &req, &d_opts, |_| {}).unwrap();
    assert!(
        out.description.contains("with positions"),
        "{}",
        out.description
    );
    let (mut d, fit_cams) = refit(&original, &scene, &convert, &req, &d_opts);
    let moved = d
        .positions()
        .unwrap()
        .offset
        .iter()
        .filter(|o| o[..3].iter().any(|&x| x != 0.0))
        .count();
    assert!(moved > 0, "no vertex moved");
    let (tracer, _) = trace_export(&scene, &convert);
    for cam in &fit_cams {
        let mem = d.render(cam).unwrap();
        let (file, _) = tracer.render(cam, 0.0, &RenderOptions::default()).unwrap();
        let worst = worst_difference(&mem.rgb, &file.rgb);
        // The same positions (f32, as the file stores them) and quantised colours; the
        // colour-only test measured at most one f32 step (2e-8) from separately built BVHs.
        assert!(
            worst < 1e-6,
            "camera {}: worst difference {worst}",
            cam.name
        );
    }
    // The written positions are the fitted ones, not the converted ones.
    let mut plain = convert.clone();
    plain.vertex_colours = None;
    let (plain_bytes, _) = splatbridge_convert::glb_bytes(&scene, None, &plain).unwrap();
    let mut unfitted =
        splatbridge_raytrace::scene_load::load_glb_bytes(&plain_bytes, "plain.glb".as_ref())
            .unwrap();
    unfitted.to_capture_frame();
    let fitted = &tracer.scene;
    let differ = fitted
        .meshes
        .iter()
        .zip(&unfitted.meshes)
        .map(|(a, b)| {
            a.positions
                .iter()
                .zip(&b.positions)
                .filter(|(p, q)| p != q)
                .count()
        })
        .sum::<usize>();
    assert!(differ > 0, "the export's positions are the converted ones");
}

/// The texture profile's opacity comes from its texture: fitting its positions is refused.
#[test]
fn texture_profile_positions_are_refused() {
    let scene = DynamicScene::from_static(large(100, 7));
    let cloud = scene.composite(0.0);
    let cams = views::orbit(&cloud, 2, 0..1, 16, 12).unwrap();
    let err = Distiller::new(
        &scene,
        &opts(Profile::Texture),
        &cams,
        &with_positions(Loss::L2),
    )
    .err()
    .expect("refused");
    assert!(err.to_string().contains("--distill-positions"), "{err}");
}
