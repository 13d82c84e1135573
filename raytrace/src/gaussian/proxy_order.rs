//! The order of a part's proxy records in memory.

use glam::Vec3;
use rayon::prelude::*;

use super::Proxy;

/// Put the proxies in the Morton order of their boxes' centres (ties in the input order):
/// the BVH's leaves, and so the candidates of one ray and of neighbouring rays, then read
/// neighbouring records instead of records scattered over the cloud's file order (each
/// candidate was a cache miss on the record). Only the proxies' internal order changes: a
/// hit is keyed and coloured by its Gaussian's index in the cloud (`index`), so images do not.
pub(super) fn spatial_order(
    boxes: &mut Vec<(Vec3, Vec3)>,
    index: &mut Vec<u32>,
    proxy: &mut Vec<Proxy>,
) {
    if boxes.len() < 2 {
        return;
    }
    let centre = |(lo, hi): &(Vec3, Vec3)| 0.5 * (*lo + *hi);
    let (lo, hi) = boxes.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), b| (lo.min(centre(b)), hi.max(centre(b))),
    );
    let scale = (hi - lo).max(Vec3::splat(f32::MIN_POSITIVE)).recip() * 1023.0;
    // Ten bits an axis, interleaved: a 1024³ grid over the centres.
    let spread = |v: u32| {
        let mut x = v & 0x3ff;
        x = (x | (x << 16)) & 0x0300_00ff;
        x = (x | (x << 8)) & 0x0300_f00f;
        x = (x | (x << 4)) & 0x030c_30c3;
        (x | (x << 2)) & 0x0924_9249
    };
    let code = |b: &(Vec3, Vec3)| {
        let q = ((centre(b) - lo) * scale).clamp(Vec3::ZERO, Vec3::splat(1023.0));
        spread(q.x as u32) | (spread(q.y as u32) << 1) | (spread(q.z as u32) << 2)
    };
    let mut order: Vec<(u32, u32)> = boxes
        .par_iter()
        .enumerate()
        .map(|(i, b)| (code(b), i as u32))
        .collect();
    // (code, position) pairs are distinct: the order is total, whatever the sort.
    order.par_sort_unstable();
    *boxes = order.iter().map(|&(_, i)| boxes[i as usize]).collect();
    *index = order.iter().map(|&(_, i)| index[i as usize]).collect();
    *proxy = order.iter().map(|&(_, i)| proxy[i as usize]).collect();
}
