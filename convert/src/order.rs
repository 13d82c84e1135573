//! Draw order for viewers that blend triangles in file order.
//!
//! Stock rasterising viewers (three.js, Babylon.js, EEVEE) sort transparent *objects* by the
//! depth of their bounding-sphere centre and then draw each mesh's triangles in index order;
//! nothing sorts inside a mesh. 3DGS compositing is back to front per ray, so the file's
//! order is the image. This module arranges each part of the scene so that those viewers get
//! the order right from any viewpoint outside the scene's chunks:
//!
//! * **Spatial chunks**: a cloud is split by median cuts along the longest axis of its centres
//!   until a chunk holds at most `chunk_size` Gaussians; each chunk is its own mesh node, so
//!   the viewer's per-object sort gets the coarse order right.
//! * **Ordered, single-sided both ways**: inside a chunk the Gaussians are sorted along the
//!   chunk's dominant normal `N`. Each triangle is written twice, once facing `+N` (the
//!   Gaussians in ascending `N·x`) and once facing `−N` (descending), with a single-sided
//!   material. A ray that crosses the chunk against `N` meets its Gaussians' centres in
//!   descending `N·x`, which is the order of the `+N` block, and back-face culling shows it
//!   only the block that faces it — so the order is exact for point-like Gaussians and every
//!   camera on that side, and a `doubleSided` material's two passes (all back faces, then all
//!   front faces) are avoided.
//! * **One camera** (`--view-order`): one node, Gaussians sorted far to near for the camera,
//!   each facing it (the opposite copies follow in reverse order for other views).
//!
//! The mesher keeps each Gaussian's triangles contiguous (`mesh.rs`); this module decides
//! the Gaussian order, the chunks and which way each fan faces ([`Facing`]).

use glam::{DVec3, Vec3};
use splatbridge_scene::{Camera, GaussianCloud};

use crate::classify::Frame;
use crate::options::{ChunkOrder, ConvertOptions};
use crate::{FrameClouds, Result, Role};
use splatbridge_scene::dynamic::DynamicScene;

/// Gaussians per spatial chunk in the arrangement for viewers
/// ([`ConvertOptions::for_viewers`]); chosen by the measurements in docs/viewers.md.
pub const VIEWER_CHUNK: usize = 256;

/// One mesh node of an arranged scene: its own copy of the Gaussians in draw order, their
/// global (`_GAUSSIAN_ID`) ids and which way their fans face.
pub struct Part {
    pub role: Role,
    pub name: String,
    pub cloud: GaussianCloud,
    pub ids: Vec<u32>,
    pub facing: Facing,
}

/// The scene arranged as the options ask ([`ConvertOptions::arranged`]), or `None` when they
/// keep the input's layout. Static Gaussians are chunked; objects (meshed in their moving
/// local frames) and per-frame content are ordered as one chunk each.
pub fn arrange_for(
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
) -> Result<Option<Vec<Part>>> {
    if !opts.arranged() {
        return Ok(None);
    }
    opts.validate()?;
    let mut wholes: Vec<(Role, String, &GaussianCloud, usize)> = vec![(
        Role::Static,
        "static".into(),
        &scene.static_gaussians,
        opts.chunk_size,
    )];
    for (k, o) in scene.objects.iter().enumerate() {
        wholes.push((Role::Object(k), o.name.clone(), &o.gaussians, 0));
    }
    if let Some(fr) = frames {
        for (k, c) in fr.clouds.iter().enumerate() {
            wholes.push((Role::Frame(k), format!("frame {k}"), c, 0));
        }
    }
    let mut parts = Vec::new();
    let mut offset = 0u64;
    for (role, name, cloud, max) in wholes {
        arrange_part(role, &name, cloud, max, offset, opts, &mut parts)?;
        offset += cloud.len() as u64;
    }
    Ok(Some(parts))
}

/// Arrange one part of a scene (its Gaussians' global ids start at `offset`; `max` Gaussians
/// per spatial chunk, 0 for one chunk) as [`arrange_for`] does, appending its chunks to `parts`.
pub(crate) fn arrange_part(
    role: Role,
    name: &str,
    cloud: &GaussianCloud,
    max: usize,
    offset: u64,
    opts: &ConvertOptions,
    parts: &mut Vec<Part>,
) -> Result<()> {
    cloud.check_shape()?;
    let in_world = !matches!(role, Role::Object(_));
    let chunks = match &opts.view_order {
        Some(cam) if in_world => vec![view_chunk(cloud, cam)],
        _ => spatial_chunks(&cloud.means, max)
            .into_iter()
            .map(|mut indices| {
                let n = dominant_normal(cloud, &indices);
                if opts.chunk_order == ChunkOrder::Normal {
                    sort_by_key(&mut indices, |i| n.dot(cloud.means[i as usize]) as f64);
                }
                let facing = if opts.both_windings {
                    Facing::Axis(n)
                } else {
                    Facing::Template
                };
                Chunk { indices, facing }
            })
            .collect(),
    };
    let many = chunks.len() > 1;
    for (k, c) in chunks.into_iter().enumerate() {
        let ids = c
            .indices
            .iter()
            .map(|&i| u32::try_from(offset + i as u64).unwrap_or(u32::MAX))
            .collect();
        parts.push(Part {
            role,
            name: if many {
                format!("{name}_{k:04}")
            } else {
                name.to_string()
            },
            cloud: subset(cloud, &c.indices),
            ids,
            facing: c.facing,
        });
    }
    Ok(())
}

/// Which way the first copy of each fan faces (the second, when written, faces away).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Facing {
    /// The profile's own winding (double-sided material; one copy).
    Template,
    /// Front faces towards `+axis`, then the reversed copies in reverse Gaussian order.
    Axis(Vec3),
    /// Front faces towards the point (a camera centre), then the reversed copies.
    Point(DVec3),
}

/// One chunk of one part: which Gaussians of the part's cloud, in draw order, and facing.
#[derive(Clone, Debug)]
pub struct Chunk {
    /// Indices into the part's cloud, in the order the triangles are written.
    pub indices: Vec<u32>,
    pub facing: Facing,
}

/// Median splits along the longest axis of the centres until every chunk holds at most
/// `max` Gaussians (`max == 0`: one chunk). Deterministic: ties are broken by index.
pub fn spatial_chunks(means: &[Vec3], max: usize) -> Vec<Vec<u32>> {
    let all: Vec<u32> = (0..means.len() as u32).collect();
    if max == 0 || means.len() <= max {
        return vec![all];
    }
    let mut out = Vec::new();
    let mut stack = vec![all];
    while let Some(mut set) = stack.pop() {
        if set.len() <= max {
            out.push(set);
            continue;
        }
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for &i in &set {
            lo = lo.min(means[i as usize]);
            hi = hi.max(means[i as usize]);
        }
        let ext = hi - lo;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let mid = set.len() / 2;
        set.select_nth_unstable_by(mid, |&a, &b| {
            means[a as usize][axis]
                .total_cmp(&means[b as usize][axis])
                .then(a.cmp(&b))
        });
        let right = set.split_off(mid);
        // Pushed right then left: chunks come out in a stable left-to-right order.
        stack.push(right);
        stack.push(set);
    }
    out
}

/// The dominant unit normal of a set of Gaussians: the principal eigenvector of
/// Σ wᵢ nᵢnᵢᵀ (sign-free, weights = opacity × footprint area), by power iteration.
pub fn dominant_normal(cloud: &GaussianCloud, idx: &[u32]) -> Vec3 {
    let mut m = [[0.0f64; 3]; 3];
    for &i in idx {
        let f = Frame::of(cloud, i as usize);
        let n = f.normal().as_dvec3();
        let w = (f.opacity * f.scales[0] * f.scales[1]) as f64;
        if !(w.is_finite() && n.is_finite()) {
            continue;
        }
        for (r, row) in m.iter_mut().enumerate() {
            for (c, x) in row.iter_mut().enumerate() {
                *x += w * n[r] * n[c];
            }
        }
    }
    let mul = |v: DVec3| {
        DVec3::new(
            m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
            m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
        )
    };
    // Start off every axis so no eigenvector is missed by symmetry.
    let mut v = DVec3::new(0.57, 0.61, 0.55).normalize();
    for _ in 0..64 {
        let u = mul(v);
        let l = u.length();
        if !(l > 1e-300 && l.is_finite()) {
            return Vec3::Y;
        }
        v = u / l;
    }
    v.as_vec3()
}

/// Sort `idx` in place by ascending `key`, ties by index (deterministic).
fn sort_by_key(idx: &mut [u32], key: impl Fn(u32) -> f64) {
    let mut keyed: Vec<(f64, u32)> = idx.iter().map(|&i| (key(i), i)).collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    for (d, (_, i)) in idx.iter_mut().zip(keyed) {
        *d = i;
    }
}

/// Chunks of a cloud for views from outside: spatial chunks of at most `max` Gaussians, each
/// sorted by ascending `N·x` along its dominant normal and facing `+N` first (the
/// arrangement [`arrange_for`] makes with `ChunkOrder::Normal` and both windings).
pub fn outside_chunks(cloud: &GaussianCloud, max: usize) -> Vec<Chunk> {
    spatial_chunks(&cloud.means, max)
        .into_iter()
        .map(|mut indices| {
            let n = dominant_normal(cloud, &indices);
            sort_by_key(&mut indices, |i| n.dot(cloud.means[i as usize]) as f64);
            Chunk {
                indices,
                facing: Facing::Axis(n),
            }
        })
        .collect()
}

/// One chunk with the Gaussians far to near for `cam` (camera-space depth), facing it.
pub fn view_chunk(cloud: &GaussianCloud, cam: &Camera) -> Chunk {
    let mut indices: Vec<u32> = (0..cloud.len() as u32).collect();
    let fwd = cam.cam_to_world().z_axis;
    sort_by_key(&mut indices, |i| {
        -(cloud.means[i as usize].as_dvec3() - cam.centre).dot(fwd)
    });
    Chunk {
        indices,
        facing: Facing::Point(cam.centre),
    }
}

/// A copy of the Gaussians `idx` of `cloud`, in that order.
pub fn subset(cloud: &GaussianCloud, idx: &[u32]) -> GaussianCloud {
    let k = cloud.coeffs();
    let mut sh = Vec::with_capacity(idx.len() * k);
    for &i in idx {
        sh.extend_from_slice(cloud.sh_of(i as usize));
    }
    let pick = |i: &u32| *i as usize;
    GaussianCloud {
        means: idx.iter().map(|i| cloud.means[pick(i)]).collect(),
        log_scales: idx.iter().map(|i| cloud.log_scales[pick(i)]).collect(),
        rotations: idx.iter().map(|i| cloud.rotations[pick(i)]).collect(),
        opacity_logits: idx.iter().map(|i| cloud.opacity_logits[pick(i)]).collect(),
        sh_degree: cloud.sh_degree,
        sh,
        object_ids: cloud
            .object_ids
            .as_ref()
            .map(|o| idx.iter().map(|i| o[pick(i)]).collect()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chunked::ChunkedMesh;

    fn cloud(points: &[Vec3]) -> GaussianCloud {
        let mut c = GaussianCloud::new(0);
        for &p in points {
            c.means.push(p);
            c.log_scales.push(Vec3::new(0.0, -0.5, -4.0));
            c.rotations.push(glam::Quat::IDENTITY);
            c.opacity_logits.push(0.0);
            c.sh.push(Vec3::ZERO);
        }
        c
    }

    fn lcg(seed: &mut u64) -> f32 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }

    #[test]
    fn chunks_partition_and_respect_the_size() {
        let mut s = 7;
        let pts: Vec<Vec3> = (0..1000)
            .map(|_| Vec3::new(lcg(&mut s) * 10.0, lcg(&mut s), lcg(&mut s) * 3.0))
            .collect();
        let chunks = spatial_chunks(&pts, 64);
        let mut seen = vec![0u32; pts.len()];
        for c in &chunks {
            assert!(!c.is_empty() && c.len() <= 64);
            for &i in c {
                seen[i as usize] += 1;
            }
        }
        assert!(
            seen.iter().all(|&n| n == 1),
            "every Gaussian in exactly one chunk"
        );
        // Median splits of 1000 down to ≤ 64: 16 chunks of 62–63.
        assert_eq!(chunks.len(), 16);
    }

    #[test]
    fn dominant_normal_of_a_flat_layer() {
        // Flat Gaussians (identity rotation, smallest scale along z) have normal ±z.
        let pts: Vec<Vec3> = (0..50)
            .map(|i| Vec3::new(i as f32, 0.0, 0.1 * i as f32))
            .collect();
        let n = dominant_normal(&cloud(&pts), &(0..50).collect::<Vec<_>>());
        assert!(n.z.abs() > 0.999, "{n}");
    }

    /// The order of a chunk is back to front for every camera outside it on the side its
    /// first block faces: checked against a brute-force sort of the centres by distance
    /// along each camera ray through them (here: by depth along the ray from the camera).
    #[test]
    fn chunk_order_is_back_to_front_from_outside() {
        let mut s = 11;
        // A slab 4 × 4 × 0.2 of flat Gaussians facing ±z.
        let pts: Vec<Vec3> = (0..400)
            .map(|_| Vec3::new(lcg(&mut s) * 2.0, lcg(&mut s) * 2.0, lcg(&mut s) * 0.1))
            .collect();
        let c = cloud(&pts);
        let chunk = outside_chunks(&c, 0).pop().unwrap();
        let Facing::Axis(n) = chunk.facing else {
            panic!("axis facing")
        };
        let mut pairs = 0;
        for k in 0..20 {
            // Cameras on the +N side, outside the slab, at varied angles.
            let eye = n * (3.0 + k as f32 * 0.2)
                + Vec3::new(lcg(&mut s) * 5.0, lcg(&mut s) * 5.0, 0.0).reject_from(n);
            // Two centres on one camera ray are hit in order of distance from the eye; along
            // the ray, the distance and N·x are monotonic (the ray goes against N). Check
            // every pair that lies (nearly) on one ray through the eye.
            let pos: Vec<usize> = {
                let mut p = vec![0; pts.len()];
                for (r, &i) in chunk.indices.iter().enumerate() {
                    p[i as usize] = r;
                }
                p
            };
            for a in 0..pts.len() {
                for b in 0..pts.len() {
                    let (da, db) = (pts[a] - eye, pts[b] - eye);
                    let cos = da.normalize().dot(db.normalize());
                    if a == b || cos < 0.9995 {
                        continue;
                    }
                    // "Nearly" one ray: b sits up to |db|·sin θ off a's ray, which can move
                    // its N·x by as much; count only pairs whose separation along the ray
                    // (times the ray's slope against N) clearly exceeds that.
                    let off = db.length() * (1.0 - cos * cos).max(0.0).sqrt();
                    let slope = da.normalize().dot(n).abs();
                    if (da.length() - db.length()) * slope <= 2.0 * off {
                        continue;
                    }
                    // a is behind b on (nearly) one ray: it must be drawn first.
                    pairs += 1;
                    assert!(pos[a] < pos[b], "camera {k}: {a} behind {b} drawn after it");
                }
            }
        }
        assert!(pairs > 100, "the check saw only {pairs} overlapping pairs");
    }

    #[test]
    fn view_chunk_matches_a_brute_force_depth_sort() {
        let mut s = 3;
        let pts: Vec<Vec3> = (0..300)
            .map(|_| Vec3::new(lcg(&mut s) * 5.0, lcg(&mut s) * 5.0, lcg(&mut s) * 5.0))
            .collect();
        let c = cloud(&pts);
        let cam = Camera::look_at(
            DVec3::new(1.0, -2.0, -20.0),
            DVec3::ZERO,
            DVec3::NEG_Y,
            50.0,
            64,
            48,
        )
        .unwrap();
        let chunk = view_chunk(&c, &cam);
        // Brute force: camera-space z of every centre through the full world-to-camera map.
        let z = |i: u32| cam.to_camera(pts[i as usize].as_dvec3()).z;
        for w in chunk.indices.windows(2) {
            assert!(z(w[0]) >= z(w[1]), "far to near");
        }
    }

    /// The writer's index stream (the fast path: index patterns flipped per fan) against the
    /// geometry the mesher emits (the slow reference): every first-copy triangle faces the
    /// requested way, the second copies are the same triangles reversed, Gaussians in reverse.
    #[test]
    fn index_stream_faces_the_requested_way() {
        let mut s = 5;
        let mut c = GaussianCloud::new(0);
        for k in 0..200 {
            c.means
                .push(Vec3::new(lcg(&mut s), lcg(&mut s), lcg(&mut s)) * 4.0);
            // Every other Gaussian volumetric (three fans), rotations all over.
            let thin = if k % 2 == 0 { -4.0 } else { -0.2 };
            c.log_scales.push(Vec3::new(-1.0, -0.5, thin));
            c.rotations.push(
                glam::Quat::from_xyzw(lcg(&mut s), lcg(&mut s), lcg(&mut s), lcg(&mut s) + 1.5)
                    .normalize(),
            );
            c.opacity_logits.push(1.0);
            c.sh.push(Vec3::ZERO);
        }
        for profile in [crate::Profile::Texture, crate::Profile::Rings] {
            let opts = crate::ConvertOptions {
                profile,
                ..Default::default()
            };
            let shape = crate::shape_for(&opts);
            for facing in [
                Facing::Axis(Vec3::new(0.3, -0.8, 0.5).normalize()),
                Facing::Point(DVec3::new(10.0, 3.0, -20.0)),
            ] {
                let mut m = crate::Mesher::new(&c, &shape, &opts, "t", 0);
                let single = m.counts.triangles;
                m.set_facing(facing);
                assert_eq!(m.counts.triangles, 2 * single);
                let soup = m.build();
                let mut idx = Vec::new();
                m.map_index_chunks::<_, ()>(
                    0,
                    |i| i.to_vec(),
                    |i| {
                        idx.extend(i);
                        Ok(())
                    },
                )
                .unwrap();
                assert_eq!(idx.len() as u64, 3 * m.counts.triangles);
                let tris: Vec<[u32; 3]> = idx.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
                let (first, second) = tris.split_at(tris.len() / 2);
                let p = |v: u32| Vec3::from_array(soup.positions[v as usize]);
                for t in first {
                    let n = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
                    let g = soup.gaussian_ids[t[0] as usize] as usize;
                    let towards = match facing {
                        Facing::Axis(a) => a,
                        Facing::Point(q) => (q - c.means[g].as_dvec3()).as_vec3(),
                        Facing::Template => unreachable!(),
                    };
                    // Exactly edge-on fans have n·towards ≈ 0 either way: allow rounding.
                    assert!(n.dot(towards) >= -1e-5 * n.length() * towards.length());
                }
                // The second copies: the first copies' triangles, reversed, Gaussians reversed.
                let gid = |t: &[u32; 3]| soup.gaussian_ids[t[0] as usize];
                let mut rev: Vec<[u32; 3]> = Vec::new();
                let mut k = first.len();
                while k > 0 {
                    let g = gid(&first[k - 1]);
                    let mut j = k;
                    while j > 0 && gid(&first[j - 1]) == g {
                        j -= 1;
                    }
                    rev.extend(first[j..k].iter().map(|t| [t[0], t[2], t[1]]));
                    k = j;
                }
                assert_eq!(second, &rev[..]);
            }
        }
    }
}
