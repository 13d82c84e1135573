//! The per-candidate work of mode `mesh`, shared by every path that finds candidates (the
//! per-ray BVH traversal of `mesh_tracer` and the screen tiles of `mesh_tiles`): carrying a
//! world ray into an instance's frame, the exact triangle test and its k-buffer insertion, and
//! front-to-back compositing of the hits. Sharing it is what makes the paths' images equal:
//! they differ only in which candidates they offer and in which order, and the k-buffer orders
//! hits by their full key.

use glam::{DVec3, Vec3, Vec4};

use crate::kbuffer::{Accum, Hit, KBuffer, Key};
use crate::mesh_tracer::{MeshTracer, TrianglePayload};
use crate::model::srgb_to_linear;
use crate::render::{Compositing, PixelOut, RenderOptions};
use crate::tri::{Miss, WRay};
use splatbridge_scene::srgb::encode_unit;

/// A world ray carried into an instance's frame: origin relative to the mesh's anchor and
/// direction in f64 (plane distances, barycentrics) and the f32 watertight ray.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LocalRay {
    pub lo64: DVec3,
    pub ld64: DVec3,
    /// `lo64.length()` and `ld64.length()`, which every group record the ray reaches reads
    /// (`GroupTable::crossing`): taken once a ray and instance.
    pub lo_len: f64,
    pub ld_len: f64,
    /// `1 / ld_len`.
    pub ld_inv: f64,
    pub wray: WRay,
}

impl LocalRay {
    /// None when the f32 ray cannot be formed (non-finite, or a zero direction).
    #[inline]
    pub fn new(lo64: DVec3, ld64: DVec3) -> Option<Self> {
        let (lo, ld) = (lo64.as_vec3(), ld64.as_vec3());
        if !lo.is_finite() || !ld.is_finite() || ld == Vec3::ZERO {
            return None;
        }
        let ld_len = ld64.length();
        Some(LocalRay {
            lo64,
            ld64,
            lo_len: lo64.length(),
            ld_len,
            ld_inv: 1.0 / ld_len,
            wray: WRay::new(lo, ld),
        })
    }
}

/// The query a candidate is tested for: the accepted distances and the last key already
/// visited (hits at or before it belong to an earlier k-buffer round).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Query {
    pub tmin: f32,
    pub tmax: f32,
    pub after: Option<Key>,
}

/// Barycentrics of the ray's crossing of the triangle's plane, in f64, clamped to the
/// triangle (the watertight test already decided coverage) and renormalised.
#[inline]
fn refine_bary(a: DVec3, b: DVec3, c: DVec3, o: DVec3, d: DVec3) -> Option<[f32; 3]> {
    let n = (b - a).cross(c - a);
    let nn = n.length_squared();
    let den = n.dot(d);
    if !(nn > 0.0) || den == 0.0 {
        return None;
    }
    let p = o + d * (n.dot(a - o) / den);
    let l = [
        (c - b).cross(p - b).dot(n).max(0.0),
        (a - c).cross(p - c).dot(n).max(0.0),
        (b - a).cross(p - a).dot(n).max(0.0),
    ];
    let s = l[0] + l[1] + l[2];
    (s > 0.0 && s.is_finite()).then(|| [(l[0] / s) as f32, (l[1] / s) as f32, (l[2] / s) as f32])
}

/// Where the local ray `r` crosses the group plane `n·x = w` (`Blas::planes`), as a ray
/// parameter: the distance every hit of the group is keyed by where it is finite. The one
/// place it is computed, so that a group's test (`mesh_tiles::group_test`) and its
/// triangles' ([`MeshTracer::test_triangle`]) agree on it bit for bit.
#[inline]
pub(crate) fn plane_distance((n, w): (DVec3, f64), r: &LocalRay) -> f64 {
    (w - n.dot(r.lo64)) / n.dot(r.ld64)
}

impl MeshTracer {
    /// Test triangle `prim` (anchor-relative vertices `[a, b, c]`, planar group `g`) of
    /// instance `ii` (mesh `mesh`) against the local ray `r`, and insert its hit into `buf`,
    /// lowering `cull` to the buffer's new cull distance. `reported`: the backend's own test
    /// found the hit (see `Accel::traverse`).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(crate) fn test_triangle(
        &self,
        ii: usize,
        mesh: usize,
        r: &LocalRay,
        [a, b, c]: [Vec3; 3],
        g: u32,
        prim: u32,
        reported: bool,
        q: &Query,
        buf: &mut KBuffer<TrianglePayload>,
        cull: &mut f32,
    ) -> Tested {
        let blas = &self.blas[mesh];
        let m = &self.scene.meshes[mesh];
        buf.candidates = buf.candidates.wrapping_add(1);
        // Coverage from the watertight f32 test (or the backend's own report, whose edge rule
        // may pick the neighbouring triangle); distance and barycentrics of accepted hits are
        // refined in f64 (f32 loses ~ulp(|o − v|)/size on small far triangles).
        // Over every t, without the test's divisions: its distance and barycentrics are
        // needed only where the f64 ones below cannot be formed.
        let wt = r.wray.cover(a, b, c);
        match wt {
            Err(Miss::Outside) if !reported => return Tested::Outside,
            Err(_) if !reported => return Tested::Open,
            _ => {}
        }
        let wt = wt.ok();
        let tp = plane_distance(blas.planes[g as usize], r);
        // From here on, with the group plane's distance the key is the group's: the other
        // winding of this triangle (same group, same Gaussian) would get the same key, and
        // where it is decided by the key alone it is [`Tested::Decided`].
        let decided = if tp.is_finite() {
            Tested::Decided
        } else {
            Tested::Open
        };
        let t = match wt {
            _ if tp.is_finite() => tp as f32,
            Some(h) => h.hit().t,
            None => return Tested::Open,
        };
        // +0.0 normalises −0.0 so the bit pattern orders like the value.
        let t = t + 0.0;
        if !(t >= q.tmin && t <= q.tmax) {
            return decided;
        }
        let key = (t.to_bits(), m.tri_gaussian[prim as usize], ii as u32, g);
        if q.after.is_some_and(|a| key <= a) || buf.rejects(key) {
            return decided;
        }
        let pos = buf.search(key);
        if buf.holds_at(pos, prim) {
            return decided;
        }
        // Only hits that enter the buffer pay for the f64 barycentrics.
        let refined = refine_bary(a.as_dvec3(), b.as_dvec3(), c.as_dvec3(), r.lo64, r.ld64);
        let bary = match (wt, refined) {
            (_, Some(bary)) => bary,
            (Some(h), None) => h.hit().bary,
            (None, None) => return Tested::Open,
        };
        let rgba = if buf.shade_on_insert {
            let (mats, texs) = (&self.scene.materials, &self.scene.textures);
            let c = if buf.record_alpha {
                let (a, factor) = m.shade_alpha(prim as usize, bary, mats, texs);
                Vec4::new(factor, 0.0, 0.0, a)
            } else {
                m.shade(prim as usize, bary, mats, texs)
            };
            // The other winding's barycentrics are the same numbers computed in another order:
            // its shade may differ in the last bits, so its α is not decided here, unless the
            // texture makes it zero whatever those bits are (`zero_alpha_settles`).
            if !(c.w > 0.0) {
                return if refined.is_some() && self.zero_alpha_settles(m, prim, bary) {
                    Tested::Settled
                } else {
                    Tested::Open
                };
            }
            c
        } else {
            Vec4::ZERO
        };
        let hit = Hit {
            t,
            gaussian: key.1,
            instance: ii as u32,
            group: g,
            payload: TrianglePayload {
                tri: prim,
                bary,
                rgba,
            },
        };
        // The buffer is as it was searched: one search serves both.
        *cull = buf.insert_at(hit, pos, q.tmax);
        decided
    }
}

impl MeshTracer {
    /// Whether a hit of triangle `prim` at `bary` (from the f64 refinement) that shaded to no
    /// α leaves its other winding nothing to add: the triangle's material samples a texture
    /// whose alpha is zero within a texel of the hit's texture coordinate
    /// ([`crate::texture::Texture::alpha_zero_near`]), and the vertex and base alphas it
    /// multiplies are finite. The other winding's refined barycentrics are these up to f32
    /// rounding, so its coordinate is within far less than a texel: its texture alpha is 0,
    /// its α 0 (or the same NaN-free 0 the alpha mode keeps), and it is not inserted either.
    /// This is the texture profile's corners, outside the falloff's disc: a fifth of the
    /// default export's candidates at 1080p (`docs/trace-speed-mesh.md`).
    fn zero_alpha_settles(&self, m: &crate::model::Mesh, prim: u32, bary: [f32; 3]) -> bool {
        let tri = prim as usize;
        let Some(mat) = m.material(tri, &self.scene.materials) else {
            return false;
        };
        let Some((tex, uv)) = m.texture_at(tri, bary, mat, &self.scene.textures) else {
            return false;
        };
        // Below f32's largest: an interpolation of them cannot overflow to ±∞ (whose product
        // with a zero alpha would be NaN, not 0).
        let bounded = |a: f32| a.abs() < 1e30;
        bounded(mat.base_color.w)
            && m.tris[tri].iter().all(|&i| bounded(m.colors[i as usize].w))
            && tex.alpha_zero_near(uv)
    }
}

/// What [`MeshTracer::test_triangle`] found, for the triangle's other winding (the same three
/// vertices in the opposite order, same group and Gaussian, higher index), which would find
/// nothing more where this says so.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Tested {
    /// The ray is outside the triangle by the watertight test's edge signs (the same for
    /// the other winding, [`WRay::intersect_or`]).
    Outside,
    /// The hit's key (the group plane's distance, the Gaussian, instance and group) decided
    /// it: inserted, or rejected by the range, the buffer's stop or an equal key of lower
    /// rank. The other winding has the same key and a higher rank: it would be rejected.
    Decided,
    /// A hit that shades to α = 0 where the texture's alpha is zero within a texel
    /// (`zero_alpha_settles`): the other winding, at the same texture coordinate up to
    /// rounding, would not be inserted either. Only the other winding: another triangle of
    /// the group with the same key may map the point elsewhere in the texture.
    Settled,
    /// Anything else (shading, a degenerate or in-plane case, a distance not from the plane):
    /// the other winding must be tested itself.
    Open,
}

/// Front-to-back compositing of one ray's shaded hits, in key order, as a viewer with an unlit
/// BLEND material draws them (see the `mesh_tracer` module documentation).
pub(crate) struct Compositor<'a> {
    pub acc: Accum,
    pub hits: u32,
    opts: &'a RenderOptions,
    to_display: bool,
    to_linear: bool,
}

impl<'a> Compositor<'a> {
    /// `colors_linear`: the scene's vertex colours are linear (glTF).
    pub fn new(opts: &'a RenderOptions, colors_linear: bool) -> Self {
        let (to_display, to_linear) = match opts.compositing {
            Compositing::Display => (colors_linear, false),
            Compositing::Viewer => (false, !colors_linear),
        };
        Compositor {
            acc: Accum::default(),
            hits: 0,
            opts,
            to_display,
            to_linear,
        }
    }

    /// Blend the next hit; true once the ray is opaque (transmittance below the threshold).
    #[inline]
    pub fn add(&mut self, h: &Hit<TrianglePayload>) -> bool {
        self.hits += 1;
        let rgba = h.payload.rgba;
        let a = rgba.w;
        if a > 0.0 {
            let mut rgb = rgba.truncate().clamp(Vec3::ZERO, Vec3::ONE);
            if self.to_display {
                // The table encode (`scene::srgb`: within one ulp of the encode rounded once,
                // where `powf`'s f32 formula is within three) of a clamped colour: the encode
                // distillation's model of this compositing uses, bit for bit, at a fraction
                // of `powf`'s cost (3 % of a 1080p frame of a MeshSplats export).
                rgb = Vec3::new(encode_unit(rgb.x), encode_unit(rgb.y), encode_unit(rgb.z));
            } else if self.to_linear {
                rgb = Vec3::new(
                    srgb_to_linear(rgb.x),
                    srgb_to_linear(rgb.y),
                    srgb_to_linear(rgb.z),
                );
            }
            // Composited before the termination test: a viewer draws the triangle.
            self.acc.add(rgb, a, h.t);
            if self.acc.tr < self.opts.min_transmittance {
                return true;
            }
        }
        false
    }

    /// The pixel: colour over the background, alpha, depth and the hit count (the caller
    /// fills in rounds and candidates).
    pub fn finish(self) -> PixelOut {
        let opts = self.opts;
        let mut out = PixelOut {
            hits: self.hits,
            ..PixelOut::default()
        };
        let (c, tr) = (self.acc.rgb, self.acc.tr);
        out.rgb = c + opts.background * tr;
        if opts.compositing == Compositing::Viewer {
            // The background is a display colour; blend it in linear light, then encode.
            let bg = opts.background;
            let lin = c + Vec3::new(
                srgb_to_linear(bg.x),
                srgb_to_linear(bg.y),
                srgb_to_linear(bg.z),
            ) * tr;
            let l = lin.clamp(Vec3::ZERO, Vec3::ONE);
            out.rgb = Vec3::new(encode_unit(l.x), encode_unit(l.y), encode_unit(l.z));
        }
        out.alpha = 1.0 - tr;
        out.depth = self.acc.depth();
        out
    }
}
