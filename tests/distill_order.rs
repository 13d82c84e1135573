//! Splat order (`--distill-order splat`): each pixel's recorded hits regrouped into whole
//! Gaussians sorted by the view-space depth of their means, checked against a sort by the
//! cloud's own means, and the fit's images in that order.

mod distill_common;

use std::path::Path;

use splatbridge::distill::order::Centres;
use splatbridge::distill::{views, DistillOptions, Distiller, HitOrder};
use splatbridge_convert::Profile;
use splatbridge_raytrace::hit_record::RecordedHit;
use splatbridge_raytrace::{BackendKind, BuildPreset, MeshTracer};
use splatbridge_scene::dynamic::DynamicScene;

use distill_common::{opts, worst_difference};

/// The reordered hits of every pixel are the ray-order hits stably sorted by the depth of
/// their Gaussian's mean as the cloud stores it (the slow reference: no vertex means), for
/// every profile; and the order does change somewhere (the fixture's fans cut through each
/// other), so the check is not of a no-op.
#[test]
fn splat_order_sorts_whole_gaussians_by_the_depth_of_their_means() {
    let cloud = distill_common::crossing_cloud(300);
    let scene = DynamicScene::from_static(cloud.clone());
    let cam = views::orbit(&cloud, 4, 0..1, 48, 36).unwrap().remove(0);
    for profile in [Profile::MeshSplats, Profile::Rings, Profile::Texture] {
        let (bytes, _) = splatbridge_convert::glb_bytes(&scene, None, &opts(profile)).unwrap();
        let mut tri =
            splatbridge_raytrace::scene_load::load_glb_bytes(&bytes, Path::new("t.glb")).unwrap();
        tri.to_capture_frame();
        let tracer = MeshTracer::new(tri, BackendKind::default(), BuildPreset::default()).unwrap();
        let ray = tracer.record_hits(&cam, 0.0, 64, 1e-6).unwrap();
        let mut splat = ray.clone();
        Centres::new(&tracer.scene).reorder(&tracer.scene, &mut splat, &cam, 0.0);
        let gid = |h: &RecordedHit| {
            tracer.scene.meshes[h.mesh as usize].tri_gaussian[h.tri as usize] as usize
        };
        let depth = |h: &RecordedHit| cam.to_camera(cloud.means[gid(h)].as_dvec3()).z;
        let mut changed = 0;
        for p in 0..ray.offsets.len() - 1 {
            let (r, s) = (ray.pixel(p), splat.pixel(p));
            let mut expect = r.to_vec();
            expect.sort_by(|a, b| depth(a).total_cmp(&depth(b)));
            if s != expect.as_slice() {
                // Only two Gaussians at the same depth may come out the other way round:
                // the vertex mean is in f32 (about 1e-7 of the coordinates, which are under
                // 10 here), so 1e-5 of the depth separates every other pair.
                for (a, b) in s.iter().zip(&expect) {
                    if a != b {
                        let (da, db) = (depth(a), depth(b));
                        assert!(
                            (da - db).abs() <= 1e-5 * da.abs().max(1.0),
                            "{profile:?} pixel {p}: Gaussian {} at depth {da} where {} at {db} belongs",
                            gid(a),
                            gid(b)
                        );
                    }
                }
            }
            changed += usize::from(s != r);
        }
        assert!(changed > 0, "{profile:?}: no pixel changed order");
    }
}

/// In splat order the fit measures what it fits: the distiller's image of a view is its
/// recorded (regrouped) hits composited, and it differs from the ray-order image of the same
/// mesh where fans cross.
#[test]
fn splat_order_fits_and_measures_in_the_same_order() {
    let scene = DynamicScene::from_static(distill_common::crossing_cloud(300));
    let cloud = scene.composite(0.0);
    let cams = views::orbit(&cloud, 4, 0..2, 40, 30).unwrap();
    let splat_opts = DistillOptions {
        order: HitOrder::Splat,
        ..DistillOptions::default()
    };
    let conv = opts(Profile::MeshSplats);
    let mut splat = Distiller::new(&scene, &conv, &cams, &splat_opts).unwrap();
    let mut ray = Distiller::new(&scene, &conv, &cams, &DistillOptions::default()).unwrap();
    for (i, cam) in cams.iter().enumerate() {
        let hits = splat.view_hits(i).unwrap().clone();
        let img = splatbridge::distill::composite::render(&hits, splat.params(), &splat.shading());
        let measured = splat.render(cam).unwrap();
        let worst = worst_difference(&img, &measured.rgb);
        // The same hits in the same order; the measurement uses the u16-quantised colours
        // the file stores (1/65535 of a colour, under 2e-5 after compositing).
        assert!(worst < 1e-4, "view {i}: worst difference {worst}");
        let traced = ray.render(cam).unwrap();
        // Not assert_ne!: on failure it would print both images.
        assert!(
            measured.rgb != traced.rgb,
            "view {i}: splat order changed nothing"
        );
    }
}
