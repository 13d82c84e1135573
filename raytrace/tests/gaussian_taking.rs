//! `GaussianTracer::for_scene_taking` (the scene's Gaussians moved into the tracer) against
//! `for_scene` (copied), the reference: the same image, bit for bit, at two times of a scene
//! with moving objects; the scene is left with its tracks and empty clouds, and
//! `give_back` returns it exactly as it was.

use glam::DVec3;
use splatbridge_raytrace::{BackendKind, BuildPreset, GaussianTracer, RenderOptions};
use splatbridge_scene::fixtures::{street_with, StreetParams};
use splatbridge_scene::Camera;

#[test]
fn taking_the_scene_traces_the_same_image() {
    let scene = street_with(&StreetParams::new(3, 3000));
    assert!(!scene.objects.is_empty());
    let cam = Camera::look_at(
        DVec3::new(0.0, -4.0, -14.0),
        DVec3::ZERO,
        DVec3::NEG_Y,
        60.0,
        48,
        36,
    )
    .unwrap();
    let mut taken = scene.clone();
    let mut a =
        GaussianTracer::for_scene(&scene, 0.0, BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let mut b =
        GaussianTracer::for_scene_taking(&mut taken, 0.0, BackendKind::Obvhs, BuildPreset::Medium)
            .unwrap();
    assert_eq!(taken.static_gaussians.len(), 0);
    assert!(taken.objects.iter().all(|o| o.gaussians.is_empty()));
    assert_eq!(taken.objects.len(), scene.objects.len());
    for t in [0.0, 2.5] {
        a.set_time(t);
        b.set_time(t);
        let (fa, _) = a.render(&cam, &RenderOptions::default()).unwrap();
        let (fb, _) = b.render(&cam, &RenderOptions::default()).unwrap();
        assert!(fa.rgb.iter().any(|&v| v > 0.0), "t = {t}: nothing drawn");
        assert!(
            fa.rgb
                .iter()
                .zip(&fb.rgb)
                .all(|(x, y)| x.to_bits() == y.to_bits()),
            "t = {t}: images differ"
        );
    }
    b.give_back(&mut taken);
    assert!(
        taken.static_gaussians == scene.static_gaussians,
        "static cloud differs"
    );
    assert_eq!(taken.objects.len(), scene.objects.len());
    for (i, (a, b)) in taken.objects.iter().zip(&scene.objects).enumerate() {
        assert!(a.gaussians == b.gaussians, "object {i}: cloud differs");
    }
}
