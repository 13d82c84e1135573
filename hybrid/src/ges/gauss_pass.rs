//! Pass 2 of the GES hybrid: the residual Gaussians, unsorted, additively accumulated.
//!
//! Per pixel, Gaussian i (projected by the native renderer's [`crate::project::project_one`])
//! counts when its view depth `zᵢ ≤ D_S + ε` (the pass-1 limit, +inf where no surfel covers the
//! pixel), `power ≤ 0` and `αᵢ = opacityᵢ·exp(power) ≥ 1/255`: no 0.99 clamp, no transmittance
//! order, no early stop (GES's Gaussian pass). It adds `αᵢ·cᵢ` to `C_G`, `αᵢ` to `W_G`, `αᵢ·zᵢ` to
//! the depth sum and multiplies `T` by `1 − αᵢ` (see [`super::composite`] for what T is for).
//!
//! Gaussians are visited per tile in input order, each pixel by one task, so the sums are formed
//! in a fixed order and the image is the same for any thread count. The tile lists themselves
//! already omit Gaussians behind every surfel of the tile (see [`super::tiles`]); inside a tile,
//! a Gaussian skips each 8-pixel row group whose largest limit it lies behind. The loop is the
//! native renderer's 8-lane branch-free form, with its vectorisable `exp`.

use crate::kernel::exp_nonpos;
use crate::project::Splat;

use super::composite::{composite_pixel, GaussAcc};
use super::surfel_pass::{N, P_B, P_DEPTH, P_G, P_LIMIT, P_R, P_W, T};

/// Output planes per tile: r, g, b, alpha, depth.
pub const OUT_PLANES: usize = 5;

struct Acc {
    r: [f32; N],
    g: [f32; N],
    b: [f32; N],
    w: [f32; N],
    t: [f32; N],
    dz: [f32; N],
}

/// Eight pixels of a row: branch-free on fixed-size arrays so that the compiler vectorises it.
#[inline(always)]
fn lanes8(
    acc: &mut Acc,
    base: usize,
    limit: &[f32],
    xb: f32,
    dy: f32,
    s: &Splat,
    q: [f32; 3],
    c: [f32; 3],
) -> u32 {
    let r: &mut [f32; 8] = (&mut acc.r[base..base + 8]).try_into().unwrap();
    let g: &mut [f32; 8] = (&mut acc.g[base..base + 8]).try_into().unwrap();
    let b: &mut [f32; 8] = (&mut acc.b[base..base + 8]).try_into().unwrap();
    let w: &mut [f32; 8] = (&mut acc.w[base..base + 8]).try_into().unwrap();
    let t: &mut [f32; 8] = (&mut acc.t[base..base + 8]).try_into().unwrap();
    let dz: &mut [f32; 8] = (&mut acc.dz[base..base + 8]).try_into().unwrap();
    let limit: &[f32; 8] = limit.try_into().unwrap();
    // power = −½·c0·dx² − c1·dy·dx − ½·c2·dy², with the row terms formed once.
    let (k1, k0) = (-q[1] * dy, -0.5 * q[2] * dy * dy);
    let mut n = 0u32;
    for l in 0..8 {
        let dx = s.x - (xb + l as f32);
        let power = -0.5 * q[0] * dx * dx + k1 * dx + k0;
        let a = s.opacity * exp_nonpos(power);
        let add = (power <= 0.0) & (a >= 1.0 / 255.0) & (s.depth <= limit[l]);
        let a = if add { a } else { 0.0 };
        r[l] += c[0] * a;
        g[l] += c[1] * a;
        b[l] += c[2] * a;
        w[l] += a;
        dz[l] += s.depth * a;
        t[l] *= 1.0 - a;
        n += add as u32;
    }
    n
}

/// Accumulate and composite one tile whose top-left pixel is `(px0, py0)`. `surf` is the tile's (None: no surfel touches the tile)
/// surfel planes, `out` receives r, g, b, alpha, depth (`N` each). Returns the blend count.
pub fn gauss_tile(
    splats: &[Splat],
    list: &[u32],
    px0: i32,
    py0: i32,
    surf: Option<&[f32]>,
    bg: [f32; 3],
    out: &mut [f32],
) -> u64 {
    let mut acc = Acc {
        r: [0.0; N],
        g: [0.0; N],
        b: [0.0; N],
        w: [0.0; N],
        t: [1.0; N],
        dz: [0.0; N],
    };
    const INF: [f32; N] = [f32::INFINITY; N];
    let limit: &[f32; N] = match surf {
        Some(p) => p[P_LIMIT * N..(P_LIMIT + 1) * N].try_into().unwrap(),
        None => &INF,
    };
    // Largest limit of each 8-pixel half row.
    let mut group_max = [f32::NEG_INFINITY; N / 8];
    for (gi, m) in group_max.iter_mut().enumerate() {
        *m = limit[gi * 8..gi * 8 + 8]
            .iter()
            .cloned()
            .fold(f32::NEG_INFINITY, f32::max);
    }
    let (tx1, ty1) = (px0 + T as i32 - 1, py0 + T as i32 - 1);
    let mut blends = 0u64;
    for &k in list {
        let s = &splats[k as usize];
        let [bx0, by0, bx1, by1] = s.bbox;
        let (x0, x1) = (bx0.max(px0), bx1.min(tx1));
        let (y0, y1) = (by0.max(py0), by1.min(ty1));
        if x0 > x1 || y0 > y1 {
            continue;
        }
        let (h0, h1) = (((x0 - px0) / 8) as usize, ((x1 - px0) / 8) as usize);
        let [c0, c1, c2] = s.conic;
        let [cr, cg, cb] = s.color;
        for y in y0..=y1 {
            let ly = (y - py0) as usize;
            let dy = s.y - y as f32;
            for h in h0..=h1 {
                let base = ly * T + h * 8;
                if s.depth > group_max[base / 8] {
                    continue;
                }
                let xb = (px0 + 8 * h as i32) as f32;
                blends += lanes8(
                    &mut acc,
                    base,
                    &limit[base..base + 8],
                    xb,
                    dy,
                    s,
                    [c0, c1, c2],
                    [cr, cg, cb],
                ) as u64;
            }
        }
    }
    for i in 0..N {
        let g = GaussAcc {
            c: [acc.r[i], acc.g[i], acc.b[i]],
            w: acc.w[i],
            t: acc.t[i],
            dz: acc.dz[i],
        };
        let (cs, ws, ds) = match surf {
            Some(p) => (
                [p[P_R * N + i], p[P_G * N + i], p[P_B * N + i]],
                p[P_W * N + i],
                p[P_DEPTH * N + i],
            ),
            None => ([0.0; 3], 0.0, 0.0),
        };
        let (rgb, alpha, depth) = composite_pixel(cs, ws, ds, &g, bg);
        out[i] = rgb[0];
        out[N + i] = rgb[1];
        out[2 * N + i] = rgb[2];
        out[3 * N + i] = alpha;
        out[4 * N + i] = depth;
    }
    blends
}
