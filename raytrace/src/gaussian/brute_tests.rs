//! The Gaussian tracer's footprint path (the default of `trace --mode gaussian`) against a
//! brute-force reference: every proxy box the ray enters tested on every ray (no BVH, no
//! cull), the hits ordered by the k-buffer. This checks the traversal's culls — the k-th hit,
//! compositing's stop (`KBuffer::stop`), the mean-depth margin — and the proxies' spatial
//! order: the images must be equal bit for bit, for every compiled-in backend, at k = 1, 4
//! and 16, in both hit orders, on scenes with exact ties (Gaussians repeated at one place),
//! needles and discs at random orientations and a camera inside some of the boxes; and equal
//! at 1, 2 and 3 threads.

use glam::{DVec3, Vec3};
use splatbridge_scene::rng::Rng;
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use super::camera::{Bucket, Padded};
use super::cull_tests::{bits, random_rotation_and_sh};
use super::GaussianTracer;
use crate::backend::{Accel, BackendKind, BuildPreset, EMBREE_AVAILABLE};
use crate::footprint::{Footprint, HitOrder};
use crate::geom::ray_box;
use crate::render::{RenderOptions, Stats};

/// Needles, discs and balls in front of the camera, some huge (the camera inside their
/// boxes), and every tenth Gaussian repeated exactly (ties in distance).
fn needles(seed: u64, n: usize) -> GaussianCloud {
    let mut r = Rng::new(seed ^ 0x5851_F42D_4C95_7F2D);
    let mut c = GaussianCloud::new(1);
    for i in 0..n {
        let m = Vec3::new(r.range(-1.0, 1.0), r.range(-0.8, 0.8), r.range(0.3, 6.0));
        let size = if i % 151 == 0 {
            r.range(0.8, 2.0)
        } else {
            0.01 * 10f32.powf(r.range(0.0, 1.5))
        };
        let shape = match i % 3 {
            0 => Vec3::new(1.0, r.range(0.02, 0.2), r.range(0.02, 0.2)),
            1 => Vec3::new(1.0, r.range(0.5, 1.0), r.range(0.02, 0.1)),
            _ => Vec3::new(1.0, r.range(0.3, 1.0), r.range(0.3, 1.0)),
        };
        let s = shape * size;
        let (q, sh) = random_rotation_and_sh(&mut r);
        let o = r.range(0.05, 0.9);
        let log_s = Vec3::new(s.x.ln(), s.y.ln(), s.z.ln());
        let logit = splatbridge_scene::gaussians::logit(o);
        c.push(m, log_s, q, logit, &sh);
        if i % 10 == 0 {
            c.push(m, log_s, q, logit, &sh);
        }
    }
    c
}

fn camera(w: u32, h: u32) -> Camera {
    Camera::look_at(
        DVec3::new(0.05, 0.02, -0.4),
        DVec3::new(0.0, 0.0, 4.0),
        DVec3::NEG_Y,
        60.0,
        w,
        h,
    )
    .unwrap()
}

/// The brute-force structure: every box on every ray, kept when the f64 slab test says the
/// ray enters it at t ≥ 0 (what a BVH hands over, without the tree or its cull).
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

fn backends() -> Vec<BackendKind> {
    let mut b = vec![BackendKind::Obvhs];
    if EMBREE_AVAILABLE {
        b.push(BackendKind::Embree);
    }
    b
}

/// The traced and the brute-force renders of `cam`.
fn renders(tracer: &GaussianTracer, cam: &Camera, opts: &RenderOptions) -> [(Frame, Stats); 2] {
    let variance = opts.sample_footprint.variance_px2(opts.spp);
    let traced = tracer.padded(cam, variance).unwrap();
    let mut brute: Padded = tracer.padded(cam, variance).unwrap();
    for (accels, boxes) in brute.accels.iter_mut().zip(&brute.boxes) {
        *accels = vec![Bucket {
            accel: Box::new(Everything(boxes.clone())),
            ids: None,
            reach: f32::INFINITY,
        }];
    }
    [&traced, &brute].map(|p| tracer.render_padded(cam, opts, Some(p)).unwrap())
}

#[test]
fn footprint_trace_matches_brute_force() {
    for b in backends() {
        let tracer = GaussianTracer::new(needles(7, 1200), b, BuildPreset::Medium).unwrap();
        let cam = camera(40, 30);
        for order in [HitOrder::MeanDepth, HitOrder::Hit] {
            for k in [1, 4, 16] {
                let opts = RenderOptions {
                    k,
                    footprint: Footprint::On,
                    order,
                    ..RenderOptions::default()
                };
                let [(traced, ts), (brute, bs)] = renders(&tracer, &cam, &opts);
                assert!(bs.hits > 0, "{b}: nothing drawn");
                assert_eq!(bits(&traced), bits(&brute), "{b} {order:?} k {k}");
                assert_eq!(ts.hits, bs.hits, "{b} {order:?} k {k}");
            }
        }
    }
}

/// Without a footprint (`--footprint off`: the tracer's own BVH), against every Gaussian
/// tested on every ray by `all_hits`-style enumeration through the brute-force structure.
#[test]
fn plain_trace_composites_every_hit_in_order() {
    let tracer =
        GaussianTracer::new(needles(9, 900), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let cam = camera(32, 24);
    for k in [1, 4, 16] {
        let opts = RenderOptions {
            k,
            ..RenderOptions::default()
        };
        let (frame, _) = tracer.render(&cam, &opts).unwrap();
        for j in 0..cam.height {
            for i in 0..cam.width {
                let (o, d) = (cam.centre, cam.ray_dir(i as f64 + 0.5, j as f64 + 0.5));
                // Every hit (no stop), then composited by the native rule.
                let hits = tracer.all_hits(o, d, 4096);
                let forward = cam.world_to_cam.row(2);
                let mut acc = crate::kbuffer::Accum::default();
                for h in &hits {
                    let part = &tracer.parts[h.instance as usize];
                    let g = h.payload.index as usize;
                    let depth = (part.cloud.means[g].as_dvec3() - o).dot(forward);
                    if depth <= opts.near as f64 {
                        continue;
                    }
                    if acc.after(h.payload.alpha) < opts.min_transmittance {
                        break;
                    }
                    acc.add(tracer.hit_color(h, d), h.payload.alpha, h.t);
                }
                let px = frame.rgb_at(i, j);
                let want = acc.rgb + opts.background * acc.tr;
                for c in 0..3 {
                    // The same hits through the same operations, except the near cull, which
                    // the render applies to the f32 anchor-relative mean (the reference to the
                    // f64 one): 1e-5 absolute allows a Gaussian at the near plane to differ.
                    assert!(
                        (px[c] - want[c]).abs() <= 1e-5,
                        "k {k} pixel ({i}, {j}) channel {c}: {} vs {}",
                        px[c],
                        want[c]
                    );
                }
            }
        }
    }
}

#[test]
fn footprint_render_does_not_depend_on_threads() {
    let tracer =
        GaussianTracer::new(needles(8, 800), BackendKind::Obvhs, BuildPreset::Medium).unwrap();
    let cam = camera(48, 36);
    let opts = RenderOptions {
        footprint: Footprint::On,
        order: HitOrder::MeanDepth,
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
    assert_eq!(frames[0], frames[1]);
    assert_eq!(frames[0], frames[2]);
}
