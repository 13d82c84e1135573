//! Pass 2 of the hybrid with the sorted blend ([`super::Blend::Sorted`]): the Gaussians left
//! after the surfel pass, in depth order, blended front to back exactly as the native renderer
//! blends (its [`crate::raster`] tile loop and kernel: the 0.99 α clamp, the transmittance chain,
//! the early stop), with each pixel's list cut at the pass-1 limit `D_S + ε`; the surfel is then
//! an opaque layer behind them:
//!
//! `C = Σ cᵢ·αᵢ·Tᵢ + T·(w_S·C_S + (1 − w_S)·background)`, alpha `1 − T·(1 − w_S)`.
//!
//! Why: the unsorted pass (GES's weighted mean `C_G/W_G`) is exact for one Gaussian per pixel
//! but not for a stack of them, and a real capture stacks many semi-transparent Gaussians in
//! front of every surface; measured on `tile_lod1` with no surfels at all the unsorted pass
//! alone scores 19.6 dB against native. Sorting restores native's order. The Gaussians behind
//! the surfels still never reach a tile list ([`super::project_gauss`], [`super::tiles`]) and
//! only the survivors are sorted, but on trained captures the surfels hide few of them, so
//! this pass costs about what native splatting does (figures in `docs/blend.md`).
//!
//! With no surfels the image is the native renderer's bit for bit (same projection, same
//! depth order with the same tie rule, same tile loop); `hybrid/tests/ges_sorted.rs` checks it.

use rayon::prelude::*;
use splatbridge_scene::GaussianCloud;

use crate::bin::{depth_key, depth_order_mapped};
use crate::kernel::TileState;
use crate::project::Splat;
use crate::raster::{blend_tile_cut, resolve, BlendParams};

use super::gauss_pass::FrameOut;
use super::surfel_pass::{N, P_B, P_DEPTH, P_G, P_LIMIT, P_R, P_W, T};

/// Reorder `splats` and `rects` front to back: by f32 view depth, exact ties by the stored
/// values of the Gaussians (`index` maps each splat to its Gaussian in `cloud`), the native
/// renderer's order ([`crate::bin::depth_order`]) restricted to these splats.
pub fn sort_by_depth(
    cloud: &GaussianCloud,
    index: &[u32],
    splats: &mut Vec<Splat>,
    rects: &mut Vec<[u32; 4]>,
) {
    let mut keys: Vec<u64> = splats
        .par_iter()
        .enumerate()
        .map(|(k, s)| depth_key(s.depth, k as u32))
        .collect();
    let mut order = Vec::with_capacity(keys.len());
    depth_order_mapped(&mut keys, cloud, &mut order, |k| index[k] as usize);
    *splats = order.par_iter().map(|&k| splats[k as usize]).collect();
    *rects = order.par_iter().map(|&k| rects[k as usize]).collect();
}

/// Blend and composite one tile whose top-left pixel is `(px0, py0)` into `out`: `list` holds
/// the tile's Gaussians front to back, `surf` the tile's surfel planes (None: no surfel
/// touches the tile). Returns the blend count.
///
/// # Safety
/// `out` must come from a frame that is still alive and that no one else reads or writes
/// meanwhile, and no other call may write the same tile concurrently.
pub unsafe fn sorted_tile(
    splats: &[Splat],
    list: &[u32],
    px0: i32,
    py0: i32,
    surf: Option<&[f32]>,
    params: &BlendParams,
    out: &FrameOut,
) -> u64 {
    let (ux0, uy0) = (px0 as usize, py0 as usize);
    let cols = out.width().saturating_sub(ux0).min(T);
    let rows = out.height().saturating_sub(uy0).min(T);
    let mut st = TileState::new(cols, rows);
    let mut cut: Vec<(f32, u16)> = Vec::new();
    if let Some(p) = surf {
        cut.reserve(N);
        for y in 0..rows {
            for x in 0..cols {
                let i = y * T + x;
                let limit = p[P_LIMIT * N + i];
                // An uncovered pixel (limit +inf) takes every Gaussian: no cut.
                if limit < f32::INFINITY {
                    cut.push((limit, i as u16));
                }
            }
        }
        cut.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    }
    let blends = blend_tile_cut(splats, list, px0, py0, params, &mut st, &cut);
    for y in 0..rows {
        for x in 0..cols {
            let i = y * T + x;
            let (rgb, alpha, depth) = match surf {
                Some(p) if p[P_W * N + i] > 0.0 => {
                    let ws = p[P_W * N + i];
                    let cs = [p[P_R * N + i], p[P_G * N + i], p[P_B * N + i]];
                    let t = st.t[i];
                    let behind: [f32; 3] =
                        std::array::from_fn(|j| ws * cs[j] + (1.0 - ws) * params.background[j]);
                    let rgb = [
                        st.r[i] + t * behind[0],
                        st.g[i] + t * behind[1],
                        st.b[i] + t * behind[2],
                    ];
                    (rgb, 1.0 - t * (1.0 - ws), p[P_DEPTH * N + i])
                }
                _ => resolve(&st, i, params.background),
            };
            // SAFETY: the pixel lies inside the image (x < cols, y < rows); the caller
            // guarantees the frame is alive and this tile is written only here.
            unsafe { out.write((uy0 + y) * out.width() + ux0 + x, rgb, alpha, depth) };
        }
    }
    blends
}
