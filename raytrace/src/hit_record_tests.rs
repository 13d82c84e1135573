//! Hit recording through the tiles ([`MeshTracer::record_hits_map`], what distillation
//! records) against the brute-force reference of `mesh_tile_tests`: every pixel's recorded
//! hits are the reference's hits of its centre's ray under the recording rule
//! (`hit_record::record`), bit for bit, in row-major pixel order, on the tile tests' scenes
//! (instances, both windings, a camera inside the scene, sizes that are not multiples of a
//! tile); a mapped record equals the map of the plain one; and the lists do not depend on the
//! thread count.

use glam::{DVec3, Vec3};

use super::hit_record::{record, HitLists, RecordedHit};
use super::kbuffer::Accum;
use super::mesh_tile_tests::{cameras, reference, scene, tracer};
use super::render::camera_ray;

/// Recording down to the distillation's default depth (`record_transmittance`, 1e-4) and far
/// below it, where every hit a ray meets is kept.
const DEPTHS: [f32; 2] = [1e-4, 1e-9];

fn hit_bits(h: &RecordedHit) -> [u32; 6] {
    [
        h.mesh,
        h.tri,
        h.bary[0].to_bits(),
        h.bary[1].to_bits(),
        h.bary[2].to_bits(),
        h.t.to_bits(),
    ]
}

#[test]
fn recorded_lists_equal_brute_force() {
    let mut recorded = 0usize;
    for (seed, both) in [(1u64, true), (2, false), (8, true)] {
        let tracer = tracer(scene(seed, Vec3::ZERO, both));
        let insts = tracer.prepare_list(0.0);
        for cam in cameras(DVec3::ZERO) {
            for min_t in DEPTHS {
                let lists = tracer.record_hits(&cam, 0.0, 16, min_t).unwrap();
                let (w, h) = (cam.width as usize, cam.height as usize);
                assert_eq!(lists.offsets.len(), w * h + 1);
                assert_eq!(lists.offsets[w * h] as usize, lists.hits.len());
                for j in 0..h {
                    for i in 0..w {
                        let (o, d) = camera_ray(&cam, i as f64 + 0.5, j as f64 + 0.5);
                        let mut want = Vec::new();
                        let mut acc = Accum::default();
                        for hit in reference(&tracer, 0.0, o, d, 0.0) {
                            let mesh = insts[hit.instance as usize].mesh;
                            if record(&hit, mesh, &mut acc, &mut want, min_t) {
                                break;
                            }
                        }
                        let got = lists.pixel(j * w + i);
                        assert_eq!(
                            got.iter().map(hit_bits).collect::<Vec<_>>(),
                            want.iter().map(hit_bits).collect::<Vec<_>>(),
                            "seed {seed}, {}×{}, depth {min_t}, pixel ({i}, {j})",
                            cam.width,
                            cam.height
                        );
                        recorded += got.len();
                    }
                }
            }
        }
    }
    // The scenes are not empty to the rays: 3,486 hits were compared when this was written
    // (each pixel's list ends at its first opaque hit, so most lists are short).
    assert!(recorded > 3000, "{recorded} hits recorded");
}

#[test]
fn mapped_lists_are_the_map_of_the_plain_ones_at_any_thread_count() {
    let tracer = tracer(scene(3, Vec3::ZERO, true));
    for cam in cameras(DVec3::ZERO) {
        let plain = tracer.record_hits(&cam, 0.0, 16, 1e-4).unwrap();
        let key = |h: &RecordedHit| (h.tri, h.mesh, h.bary[1].to_bits());
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mapped: HitLists<(u32, u32, u32)> = pool
                .install(|| tracer.record_hits_map(&cam, 0.0, 16, 1e-4, key))
                .unwrap();
            assert_eq!(mapped.offsets, plain.offsets, "{threads} threads");
            assert_eq!(
                mapped.hits,
                plain.hits.iter().map(key).collect::<Vec<_>>(),
                "{threads} threads"
            );
        }
    }
}
