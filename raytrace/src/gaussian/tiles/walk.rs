//! The tile walk's per-ray pieces ([`super`]): compositing a ray's hits as they come, the
//! chunk pass of the walk's build, and which build and exponential the CPU runs.

use glam::{DVec3, Vec3};

use super::super::exp_lanes;
use super::super::lanes::Chunk;
use super::super::{GaussianHit, GaussianTracer};
use crate::kbuffer::Accum;
use crate::render::RenderOptions;

/// A ray's compositing in the tile walk: the accumulator, the composited hit count, and
/// where colours go (`mean`: SH toward the mean, the frame's table where it holds the ray's
/// origin, each colour added at once; else `composited`, each hit's index and weight, whose
/// colours are added after the walk in the same order: either way the colour sum's operations
/// are those of adding each hit's colour as it comes). Methods inlined where they are
/// called, not closures: a closure is compiled without the walk's AVX2 build, and was called
/// once a hit.
pub(super) struct RayComposite<'a> {
    pub(super) acc: Accum,
    pub(super) hits: u32,
    pub(super) composited: &'a mut Vec<(u32, f32)>,
    pub(super) opts: &'a RenderOptions,
    pub(super) mean: Option<(Option<&'a [Vec3]>, DVec3)>,
}

impl RayComposite<'_> {
    /// Composite `pending` (hits of one key distance) in Gaussian order
    /// ([`RayComposite::composite`] each) and empty it; true: the ray stopped.
    #[inline(always)]
    pub(super) fn flush(
        &mut self,
        tracer: &GaussianTracer,
        pending: &mut Vec<GaussianHit>,
    ) -> bool {
        if pending.len() > 1 {
            pending.sort_unstable_by_key(|h| h.gaussian);
        }
        for h in pending.iter() {
            if self.composite(tracer, h) {
                return true;
            }
        }
        pending.clear();
        false
    }

    /// Composite hit `h` as `Accum::add` does; true: the ray stopped (native's rule: the hit
    /// that would take T below the threshold is not added).
    #[inline(always)]
    pub(super) fn composite(&mut self, tracer: &GaussianTracer, h: &GaussianHit) -> bool {
        let a = h.payload.alpha;
        let acc = &mut self.acc;
        if acc.after(a) < self.opts.min_transmittance {
            return true;
        }
        self.hits += 1;
        let w = a * acc.tr;
        acc.dsum += w * h.t;
        acc.wsum += w;
        acc.tr *= 1.0 - a;
        match self.mean {
            Some((table, o)) => {
                let c = match table {
                    Some(c) => c[h.payload.index as usize],
                    None => tracer.hit_color_toward_mean(h, o),
                };
                acc.rgb += c * w;
            }
            None => self.composited.push((h.payload.index, w)),
        }
        false
    }
}

/// Whether the CPU runs [`GaussianTracer::trace_tile`]'s AVX2-and-FMA build.
pub(in crate::gaussian) fn vector_exp_supported() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// [`Chunk::pass`], or in the AVX2 build (`AVX2`) [`Chunk::pass_avx2`]: the same mask.
#[inline(always)]
pub(super) fn chunk_pass<const AVX2: bool>(chunk: &Chunk, u: f32, v: f32, cu: f32, cv: f32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: `AVX2` is true only in `trace_tile_avx2`'s build, which runs only where the
        // CPU has AVX2 and FMA (`vector_exp_supported`).
        return unsafe { chunk.pass_avx2(u, v, cu, cv) };
    }
    chunk.pass(u, v, cu, cv)
}

/// Whether `x` is in the range where [`exp_lanes::exp_lanes`] has `f32::exp`'s bits.
#[inline(always)]
pub(super) fn in_exp_range(x: f32) -> bool {
    x >= exp_lanes::RANGE.0 && x <= exp_lanes::RANGE.1
}
