//! The tile path of primary rays ([`super::tiles`]) against the per-ray BVH path and against
//! the brute-force reference (every grown box the ray enters tested, no BVH, no cull): images
//! bit for bit equal, on scenes with exact ties (Gaussians repeated at one place) and near
//! ties (clusters whose means differ by a few ulps, so that distinct mean depths divide to
//! equal keys and the Gaussian index must order them), a camera inside some boxes, in the
//! three footprint modes, at 1 and 4 samples a pixel, on every compiled-in backend; and equal
//! at 1, 2 and 3 threads.

use glam::{DVec3, Vec3};
use splatbridge_scene::rng::Rng;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use super::camera::Bucket;
use super::cull_tests::{bits, random_rotation_and_sh};
use super::GaussianTracer;
use crate::backend::{Accel, BackendKind, BuildPreset, EMBREE_AVAILABLE};
use crate::footprint::{Footprint, HitOrder, ShDirection};
use crate::geom::ray_box;
use crate::render::{RenderOptions, Stats};

/// Needles, discs and balls, some huge (the camera inside their boxes), every tenth Gaussian
/// repeated exactly, and clusters of eight whose means differ by a few f32 ulps, listed in
/// random index order.
fn scene(seed: u64, n: usize) -> GaussianCloud {
    let mut r = Rng::new(seed ^ 0x2545_F491_4F6C_DD1D);
    let mut c = GaussianCloud::new(1);
    for i in 0..n {
        let m = Vec3::new(r.range(-1.2, 1.2), r.range(-0.9, 0.9), r.range(0.1, 5.0));
        let size = if i % 137 == 0 {
            r.range(0.6, 1.5)
        } else {
            0.01 * 10f32.powf(r.range(0.0, 1.5))
        };
        let shape = match i % 3 {
            0 => Vec3::new(1.0, r.range(0.02, 0.2), r.range(0.02, 0.2)),
            1 => Vec3::new(1.0, r.range(0.5, 1.0), r.range(0.02, 0.1)),
            _ => Vec3::new(1.0, r.range(0.3, 1.0), r.range(0.3, 1.0)),
        };
        let s = shape * size;
        let log_s = Vec3::new(s.x.ln(), s.y.ln(), s.z.ln());
        let (q, sh) = random_rotation_and_sh(&mut r);
        let o = r.range(0.05, 0.7);
        let logit = splatbridge_scene::gaussians::logit(o);
        if i % 29 == 0 {
            for _ in 0..8 {
                let ulps = |x: f32, r: &mut Rng| {
                    let mut x = x;
                    for _ in 0..(r.range(0.0, 4.0) as u32) {
                        x = x.next_up();
                    }
                    x
                };
                let mm = Vec3::new(ulps(m.x, &mut r), ulps(m.y, &mut r), ulps(m.z, &mut r));
                c.push(mm, log_s, q, logit, &sh);
            }
            continue;
        }
        c.push(m, log_s, q, logit, &sh);
        if i % 10 == 0 {
            c.push(m, log_s, q, logit, &sh);
        }
    }
    c
}

fn camera(w: u32, h: u32) -> Camera {
    Camera::look_at(
        DVec3::new(0.05, 0.02, -0.3),
        DVec3::new(0.1, -0.05, 4.0),
        DVec3::NEG_Y,
        75.0,
        w,
        h,
    )
    .unwrap()
}

/// Every box on every ray (the brute-force structure of `brute_tests`).
struct Everything(Vec<(Vec3, Vec3)>);

impl Accel for Everything {
    fn traverse(&self, o: Vec3, d: Vec3, _: f32, visit: &mut dyn FnMut(u32, bool, &mut f32)) {
        let mut cull = f32::INFINITY;
        for (p, (lo, hi)) in self.0.iter().enumerate() {
            let inside = ray_box(o.as_dvec3(), d.as_dvec3(), lo.as_dvec3(), hi.as_dvec3());
            if inside.is_some_and(|(_, t1)| t1 >= 0.0) {
                visit(p as u32, false, &mut cull);
            }
        }
    }
}

/// The tile render, the per-ray BVH render and the brute-force render of `cam`.
fn renders(tracer: &GaussianTracer, cam: &Camera, opts: &RenderOptions) -> [(Frame, Stats); 3] {
    assert!(tracer.tiles_apply(opts));
    let tiled = tracer.render(cam, opts).unwrap();
    let variance = opts.sample_footprint.variance_px2(opts.spp);
    let per_ray = tracer.for_camera(cam, opts.footprint, variance).unwrap();
    let per_ray_frame = tracer.render_padded(cam, opts, per_ray.as_ref()).unwrap();
    let mut brute = tracer.for_camera(cam, opts.footprint, variance).unwrap();
    for p in brute.iter_mut() {
        for (accels, boxes) in p.accels.iter_mut().zip(&p.boxes) {
            *accels = vec![Bucket {
                accel: Box::new(Everything(boxes.clone())),
                ids: None,
                reach: f32::INFINITY,
            }];
        }
    }
    let brute_frame = tracer.render_padded(cam, opts, brute.as_ref()).unwrap();
    [tiled, per_ray_frame, brute_frame]
}

fn backends() -> Vec<BackendKind> {
    let mut b = vec![BackendKind::Obvhs];
    if EMBREE_AVAILABLE {
        b.push(BackendKind::Embree);
    }
    b
}

#[test]
fn tiles_match_per_ray_and_brute_force() {
    for b in backends() {
        let tracer = GaussianTracer::new(scene(11, 1500), b, BuildPreset::Medium).unwrap();
        // 37×29: tiles cut at the right and bottom edges.
        let cam = camera(37, 29);
        for (footprint, spp) in [
            (Footprint::On, 1),
            (Footprint::On, 4),
            (Footprint::Projected, 1),
            (Footprint::Off, 1),
        ] {
            // The SH direction `mean` is looked up in the frame's colour table on the tile
            // path and evaluated per hit on the others.
            for (k, sh_direction) in [
                (1, ShDirection::Ray),
                (16, ShDirection::Ray),
                (16, ShDirection::Mean),
            ] {
                let opts = RenderOptions {
                    k,
                    spp,
                    footprint,
                    order: HitOrder::MeanDepth,
                    sh_direction,
                    ..RenderOptions::default()
                };
                let what = format!("{b} {footprint:?} spp {spp} k {k} {sh_direction:?}");
                let [(tiled, ts), (per_ray, ps), (brute, bs)] = renders(&tracer, &cam, &opts);
                assert!(bs.hits > 0, "{what}: nothing drawn");
                assert_eq!(bits(&tiled), bits(&brute), "{what}: tiles vs brute force");
                assert_eq!(bits(&per_ray), bits(&brute), "{what}: BVH vs brute force");
                assert_eq!(ts.hits, bs.hits, "{what}");
                assert_eq!(ps.hits, bs.hits, "{what}");
            }
        }
    }
}

/// The scene's near ties are real: some pixel's ray gives two Gaussians equal keys although
/// their means' depths differ (the case the tile path orders by Gaussian index).
#[test]
fn near_ties_occur() {
    let tracer =
        GaussianTracer::new(scene(11, 1500), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let cam = camera(37, 29);
    let part = &tracer.parts[0];
    let ro = tracer.local_point(0, cam.centre);
    let fwd = tracer.local_dir(0, cam.world_to_cam.row(2));
    let mut found = 0;
    for j in 0..cam.height {
        for i in 0..cam.width {
            let d = cam.ray_dir(i as f64 + 0.5, j as f64 + 0.5).as_vec3();
            let cos = d.dot(fwd);
            let mut keys: Vec<(u32, u32)> = part
                .proxy
                .iter()
                .map(|x| {
                    let z = (x.mean - ro).dot(fwd);
                    ((z / cos).to_bits(), z.to_bits())
                })
                .collect();
            keys.sort_unstable();
            found += keys
                .windows(2)
                .filter(|w| w[0].0 == w[1].0 && w[0].1 != w[1].1)
                .count();
        }
    }
    assert!(found > 0, "no equal keys from distinct depths");
}

#[test]
fn tile_render_does_not_depend_on_threads() {
    let tracer =
        GaussianTracer::new(scene(12, 1000), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let cam = camera(50, 35);
    for (footprint, sh_direction) in [
        (Footprint::On, ShDirection::Ray),
        (Footprint::On, ShDirection::Mean),
        (Footprint::Projected, ShDirection::Mean),
    ] {
        let opts = RenderOptions {
            footprint,
            order: HitOrder::MeanDepth,
            sh_direction,
            ..RenderOptions::default()
        };
        let frames: Vec<Vec<u32>> = [1, 2, 3]
            .iter()
            .map(|&n| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .unwrap();
                pool.install(|| bits(&tracer.render(&cam, &opts).unwrap().0))
            })
            .collect();
        assert_eq!(frames[0], frames[1], "{footprint:?}");
        assert_eq!(frames[0], frames[2], "{footprint:?}");
    }
}

/// A frame `footprint::covers_frame` refuses (a 179.8° view: its corner rays are too oblique)
/// works out every ray's footprint whole, and still equals the per-ray path and brute force
/// bit for bit. Its grown boxes nest deeply (the footprint's pad grows as the focal length
/// shrinks): as a wide tree the per-ray BVH would be 36 levels deep (measured), which obvhs's
/// traversal stack does not hold, so the backend keeps it binary (`obvhs_backend`).
#[test]
fn frames_the_pixel_check_refuses_still_match() {
    let tracer =
        GaussianTracer::new(scene(13, 800), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let cam = Camera::look_at(
        DVec3::new(0.05, 0.02, -0.3),
        DVec3::new(0.1, -0.05, 4.0),
        DVec3::NEG_Y,
        179.8,
        41,
        23,
    )
    .unwrap();
    assert!(!crate::footprint::covers_frame(&cam, 0.3));
    let opts = RenderOptions {
        footprint: Footprint::On,
        order: HitOrder::MeanDepth,
        sh_direction: ShDirection::Mean,
        ..RenderOptions::default()
    };
    let [(tiled, ts), (per_ray, _), (brute, bs)] = renders(&tracer, &cam, &opts);
    assert!(bs.hits > 0, "nothing drawn");
    assert_eq!(bits(&tiled), bits(&brute), "tiles vs brute force");
    assert_eq!(bits(&per_ray), bits(&brute), "BVH vs brute force");
    assert_eq!(ts.hits, bs.hits);
}
