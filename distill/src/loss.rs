//! Image losses of mesh distillation and their gradients with respect to the rendered image.
//!
//! MeshSplats fine-tunes with `0.6·L1 + 0.4·(1 − SSIM)` (11×11 Gaussian window, σ 1.5, the
//! 3DGS `ssim` with zero padding; `../shared/reference/meshsplats-and-ges.md`); L1 and L2 alone
//! are the cheaper alternatives. All are means over pixels and the three channels.
//!
//! SSIM's gradient: per pixel p and channel, with window weights w, means μ, variances σ² and
//! covariance σxy, `S_p = N1·N2 / (D1·D2)` where `N1 = 2μxμy + C1`, `N2 = 2σxy + C2`,
//! `D1 = μx² + μy² + C1`, `D2 = σx² + σy² + C2`. Since `∂μx/∂x_q = w_q`,
//! `∂σx²/∂x_q = 2w_q(x_q − μx)` and `∂σxy/∂x_q = w_q(y_q − μy)`,
//! `∂S_p/∂x_q = w(p − q)·(A_p + B_p·x_q + C_p·y_q)` with
//! `A = 2μy·N2/(D1D2) − 2μx·S/D1 − 2μy·N1/(D1D2) + 2μx·S/D2`, `B = −2S/D2`, `C = 2N1/(D1D2)`;
//! so `∂ mean(S)/∂x = (w ⋆ A + x·(w ⋆ B) + y·(w ⋆ C)) / P`, three more blurs (the window is
//! symmetric and zero padded, so the blur is its own adjoint).

use rayon::prelude::*;
use splatbridge_scene::metrics::ssim_kernel;

/// C1 and C2 of 3DGS's SSIM (data range 1).
const C1: f64 = 0.01 * 0.01;
const C2: f64 = 0.03 * 0.03;

/// Which loss to fit.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Loss {
    /// `(1 − λ)·L1 + λ·(1 − SSIM)` (MeshSplats: λ = 0.4).
    L1Ssim(f32),
    L1,
    L2,
}

impl Default for Loss {
    fn default() -> Self {
        Loss::L1Ssim(0.4)
    }
}

impl std::fmt::Display for Loss {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Loss::L1Ssim(l) => write!(f, "{}·L1 + {}·(1 − SSIM)", 1.0 - l, l),
            Loss::L1 => write!(f, "L1"),
            Loss::L2 => write!(f, "L2"),
        }
    }
}

/// Zero-padded separable blur of a row-major `w`×`h` plane with the SSIM window.
pub fn blur(x: &[f64], w: usize, h: usize) -> Vec<f64> {
    let g = ssim_kernel();
    let r = g.len() / 2;
    let mut tmp = vec![0.0; w * h];
    // Columns whose window lies inside the row take every tap, in the same order: summed
    // tap by tap over the whole run of them (vectorised), each element still from 0.0 in
    // the order of the column walk at the edges.
    let inner = if w > 2 * r { r..w - r } else { 0..0 };
    for (xr, tr) in x
        .chunks_exact(w.max(1))
        .zip(tmp.chunks_exact_mut(w.max(1)))
        .take(h)
    {
        for col in (0..inner.start).chain(inner.end..w) {
            let lo = col.saturating_sub(r);
            let hi = (col + r).min(w - 1);
            let mut a = 0.0;
            for k in lo..=hi {
                a += g[k + r - col] * xr[k];
            }
            tr[col] = a;
        }
        if inner.is_empty() {
            continue;
        }
        for (k, &gk) in g.iter().enumerate() {
            let src = &xr[inner.start + k - r..];
            for (o, v) in tr[inner.clone()].iter_mut().zip(src) {
                *o += gk * v;
            }
        }
    }
    // Rows of the output accumulate whole input rows (contiguous, vectorised); each element
    // still sums its terms in the same order from 0.0, so the result is the column walk's.
    let mut out = vec![0.0; w * h];
    for (row, dst) in out.chunks_exact_mut(w.max(1)).enumerate().take(h) {
        let lo = row.saturating_sub(r);
        let hi = (row + r).min(h - 1);
        for k in lo..=hi {
            let gk = g[k + r - row];
            for (o, t) in dst.iter_mut().zip(&tmp[k * w..(k + 1) * w]) {
                *o += gk * t;
            }
        }
    }
    out
}

/// Mean SSIM of one channel and its gradient with respect to `x`.
// One index walks eight per-pixel maps at once; zipped iterators would hide the formula.
#[allow(clippy::needless_range_loop)]
pub fn ssim_plane_grad(x: &[f64], y: &[f64], w: usize, h: usize) -> (f64, Vec<f64>) {
    let n = w * h;
    let sq = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(p, q)| p * q).collect::<Vec<_>>();
    let mx = blur(x, w, h);
    let my = blur(y, w, h);
    let mxx = blur(&sq(x, x), w, h);
    let myy = blur(&sq(y, y), w, h);
    let mxy = blur(&sq(x, y), w, h);
    let (mut a, mut b, mut c) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut total = 0.0;
    for p in 0..n {
        let (ux, uy) = (mx[p], my[p]);
        let vx = mxx[p] - ux * ux;
        let vy = myy[p] - uy * uy;
        let cxy = mxy[p] - ux * uy;
        let n1 = 2.0 * ux * uy + C1;
        let n2 = 2.0 * cxy + C2;
        let d1 = ux * ux + uy * uy + C1;
        let d2 = vx + vy + C2;
        let s = n1 * n2 / (d1 * d2);
        total += s;
        a[p] = 2.0 * uy * n2 / (d1 * d2) - 2.0 * ux * s / d1 - 2.0 * uy * n1 / (d1 * d2)
            + 2.0 * ux * s / d2;
        b[p] = -2.0 * s / d2;
        c[p] = 2.0 * n1 / (d1 * d2);
    }
    let (ba, bb, bc) = (blur(&a, w, h), blur(&b, w, h), blur(&c, w, h));
    let inv = 1.0 / n as f64;
    let grad = (0..n)
        .map(|q| (ba[q] + x[q] * bb[q] + y[q] * bc[q]) * inv)
        .collect();
    (total * inv, grad)
}

/// The loss between an image and its target (interleaved RGB, `w`×`h`) and its gradient
/// with respect to the image.
pub fn loss_and_grad(
    img: &[f32],
    target: &[f32],
    w: usize,
    h: usize,
    loss: Loss,
) -> (f64, Vec<f32>) {
    let m = img.len().min(target.len());
    let inv = 1.0 / m.max(1) as f64;
    let mut grad = vec![0.0f32; m];
    let l1_weight = match loss {
        Loss::L1Ssim(l) => 1.0 - l as f64,
        Loss::L1 => 1.0,
        Loss::L2 => 0.0,
    };
    let mut value = 0.0;
    if loss == Loss::L2 {
        for ((g, &x), &y) in grad.iter_mut().zip(img).zip(target) {
            let d = (x - y) as f64;
            value += d * d * inv;
            *g = (2.0 * d * inv) as f32;
        }
        return (value, grad);
    }
    for ((g, &x), &y) in grad.iter_mut().zip(img).zip(target) {
        let d = (x - y) as f64;
        value += l1_weight * d.abs() * inv;
        *g = (l1_weight * d.signum() * inv) as f32;
    }
    if let Loss::L1Ssim(l) = loss {
        let l = l as f64;
        if m == 3 * w * h && l != 0.0 {
            // The three channels are independent (the largest share of an iteration's
            // serial work at 240×180); collected in channel order, so the sum is the same
            // on any thread count.
            let planes: Vec<(f64, Vec<f64>)> = (0..3usize)
                .into_par_iter()
                .map(|ch| {
                    let x: Vec<f64> = (0..w * h).map(|p| img[3 * p + ch] as f64).collect();
                    let y: Vec<f64> = (0..w * h).map(|p| target[3 * p + ch] as f64).collect();
                    ssim_plane_grad(&x, &y, w, h)
                })
                .collect();
            for (ch, (s, g)) in planes.into_iter().enumerate() {
                // Mean over channels of (1 − SSIM): each channel weighs 1/3.
                value += l * (1.0 - s) / 3.0;
                for (p, gp) in g.iter().enumerate() {
                    grad[3 * p + ch] -= (l * gp / 3.0) as f32;
                }
            }
        }
    }
    (value, grad)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The blur of the definition: every output element its own weighted sum over the window,
    /// rows then columns (terms outside the plane are zero, and skipped).
    fn blur_reference(x: &[f64], w: usize, h: usize) -> Vec<f64> {
        let g = ssim_kernel();
        let r = g.len() as isize / 2;
        // One pass along an axis: `(row, col, k) -> Some(index)` of the k-th tap, if inside.
        let pass = |v: &[f64], tap: &dyn Fn(usize, usize, isize) -> Option<usize>| {
            let mut out = vec![0.0; w * h];
            for row in 0..h {
                for col in 0..w {
                    let mut a = 0.0;
                    for (j, gj) in g.iter().enumerate() {
                        if let Some(i) = tap(row, col, j as isize - r) {
                            a += gj * v[i];
                        }
                    }
                    out[row * w + col] = a;
                }
            }
            out
        };
        let inside = |i: isize, n: usize| (i >= 0 && (i as usize) < n).then_some(i as usize);
        let tmp = pass(x, &|row, col, k| {
            inside(col as isize + k, w).map(|c| row * w + c)
        });
        pass(&tmp, &|row, col, k| {
            inside(row as isize + k, h).map(|r| r * w + col)
        })
    }

    /// The row-accumulating blur sums each element's terms in the definition's order: equal
    /// bit for bit, on planes narrower and shorter than the window too.
    #[test]
    fn blur_equals_the_definition() {
        for (w, h) in [
            (23, 17),
            (5, 3),
            (1, 12),
            (12, 1),
            (40, 30),
            (11, 4),
            (12, 13),
            (10, 11),
        ] {
            let x: Vec<f64> = (0..w * h)
                .map(|i| ((i * 7919 % 101) as f64 / 37.0).sin())
                .collect();
            let (a, b) = (blur(&x, w, h), blur_reference(&x, w, h));
            assert!(
                a.iter().zip(&b).all(|(p, q)| p.to_bits() == q.to_bits()),
                "{w}×{h}"
            );
        }
    }

    /// A smooth deterministic pattern in [0, 1].
    fn pattern(w: usize, h: usize, phase: f64) -> Vec<f32> {
        (0..3 * w * h)
            .map(|i| {
                let (p, c) = (i / 3, i % 3);
                let (x, y) = ((p % w) as f64, (p / w) as f64);
                (0.5 + 0.4 * (0.7 * x + 0.3 * y * (c as f64 + 1.0) + phase).sin()) as f32
            })
            .collect()
    }

    /// The loss agrees with the repository's SSIM metric (the same window and constants).
    #[test]
    fn ssim_value_matches_the_metric() {
        let (w, h) = (23, 17);
        let (a, b) = (pattern(w, h, 0.0), pattern(w, h, 0.9));
        let fa = splatbridge_scene::Frame {
            width: w as u32,
            height: h as u32,
            rgb: a.clone(),
            alpha: vec![1.0; w * h],
            depth: vec![0.0; w * h],
        };
        let fb = splatbridge_scene::Frame {
            rgb: b.clone(),
            ..fa.clone()
        };
        let want = splatbridge_scene::metrics::ssim(&fa, &fb).unwrap();
        let (v, _) = loss_and_grad(&a, &b, w, h, Loss::L1Ssim(1.0));
        // f32 images, f64 sums in both: agreement to rounding.
        assert!((v - (1.0 - want)).abs() < 1e-9, "{v} vs {}", 1.0 - want);
    }

    /// Analytic gradients against central differences (the slow reference).
    #[test]
    fn gradients_match_finite_differences() {
        let (w, h) = (13, 11);
        let target = pattern(w, h, 1.3);
        for loss in [Loss::L1Ssim(0.4), Loss::L1Ssim(1.0), Loss::L2] {
            let img = pattern(w, h, 0.2);
            let (_, g) = loss_and_grad(&img, &target, w, h, loss);
            for &i in &[0usize, 7, 3 * w * 5 + 4, 3 * w * h - 1, 3 * (w * 6 + 6) + 2] {
                let e = 1e-3f32;
                let mut up = img.clone();
                up[i] += e;
                let mut dn = img.clone();
                dn[i] -= e;
                let fd = (loss_and_grad(&up, &target, w, h, loss).0
                    - loss_and_grad(&dn, &target, w, h, loss).0)
                    / (2.0 * e as f64);
                // The loss is a mean over 3·143 values: gradients are ~1e-3; f32 images and a
                // step of 1e-3 leave ~1e-7 of rounding in the difference, so 2 % or 1e-6.
                let tol = (0.02 * fd.abs()).max(1e-6);
                assert!(
                    (g[i] as f64 - fd).abs() < tol,
                    "{loss:?} value {i}: analytic {} vs finite difference {fd}",
                    g[i]
                );
            }
        }
    }
}
