//! Ray and box helpers shared by the tracers: the f64 slab test and the world bounds of a
//! transformed box (instanced meshes and Gaussian parts).

use glam::DVec3;

/// Slab test of a ray against a box in f64: the parameter interval inside, if any.
pub fn ray_box(o: DVec3, d: DVec3, lo: DVec3, hi: DVec3) -> Option<(f64, f64)> {
    let mut t0 = f64::NEG_INFINITY;
    let mut t1 = f64::INFINITY;
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[a];
        let (mut ta, mut tb) = ((lo[a] - o[a]) * inv, (hi[a] - o[a]) * inv);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
    }
    (t0 <= t1).then_some((t0, t1))
}

/// World bounds of the box `lo..hi` under `to_world` (its eight corners), padded by a relative
/// 1e-6 so rounding in the f64 transform cannot clip a hit at the box's surface.
pub fn transformed_box(to_world: &glam::DAffine3, lo: DVec3, hi: DVec3) -> (DVec3, DVec3) {
    let (mut wlo, mut whi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for c in 0..8 {
        let p = DVec3::new(
            if c & 1 == 0 { lo.x } else { hi.x },
            if c & 2 == 0 { lo.y } else { hi.y },
            if c & 4 == 0 { lo.z } else { hi.z },
        );
        let w = to_world.transform_point3(p);
        wlo = wlo.min(w);
        whi = whi.max(w);
    }
    let pad = (whi - wlo).max_element() * 1e-6 + 1e-9 * whi.abs().max(wlo.abs()).max_element();
    (wlo - DVec3::splat(pad), whi + DVec3::splat(pad))
}

/// A total order on f32 as u32 (negative values below positive ones).
#[inline]
pub(crate) fn order_bits(z: f32) -> u32 {
    let b = z.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// `x.floor()` without the library call where the target has no rounding instruction: the
/// integer part, one less for a negative non-integer, exact while `|x| < 2⁵²` (every such
/// f64 integer converts to i64 and back exactly); `f64::floor` beyond.
#[inline]
pub(crate) fn floor(x: f64) -> f64 {
    if x.abs() < 4_503_599_627_370_496.0 {
        let t = x as i64 as f64;
        if t > x {
            t - 1.0
        } else {
            // floor(−0) is −0.
            t.copysign(x)
        }
    } else {
        x.floor()
    }
}

#[cfg(test)]
mod tests {
    use super::floor;

    /// The inline `floor` is `f64::floor` bit for bit: at the special values (signed zeros,
    /// halves, integers either side of zero, the ends of the exact range, infinities, NaN) and
    /// at a million values spread over magnitudes from 1e-3 to 1e17 of both signs, and their
    /// quarters. Without its copysign, floor(−0) comes out as +0 and the test fails (tried).
    #[test]
    fn floor_is_the_library_floor() {
        let same = |x: f64| {
            let (a, b) = (floor(x), x.floor());
            assert!(
                a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                "floor({x:e}) = {a:e}, library {b:e}"
            );
        };
        let edge = 4_503_599_627_370_496.0f64;
        for x in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1e-300,
            1e-300,
            2.5,
            -2.5,
            edge,
            -edge,
            edge - 0.5,
            -(edge - 0.5),
            edge * 2.0,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ] {
            same(x);
        }
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..1_000_000 {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let u = (s >> 11) as f64 / (1u64 << 53) as f64;
            let mag = 10f64.powf(-3.0 + 20.0 * u);
            same(if s & 1 == 0 { mag } else { -mag });
            same((mag * 4.0).round() / 4.0 * if s & 2 == 0 { 1.0 } else { -1.0 });
        }
    }
}
