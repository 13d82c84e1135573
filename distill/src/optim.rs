//! The fit's optimiser: Adam (Kingma & Ba 2015) with a pixel-scaled ε, over batches of views
//! spread around the rig. MeshSplats fine-tunes with Adam one image at a time; full-batch
//! steps over all views cost a pass over every view per step, so steps take a batch that sees
//! the scene from all sides, and every view is used once per epoch.

use rayon::prelude::*;
use splatbridge_scene::Camera;

/// The views of step `t` among `n`, `b` per step ([`super::Distiller::batch`]), in view order.
pub fn batch_views(n: usize, b: usize, t: usize) -> Vec<usize> {
    if b == 0 || b >= n {
        return (0..n).collect();
    }
    let stride = n.div_ceil(b);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| (i % stride, i));
    let mut out: Vec<usize> = (0..b).map(|j| order[(t * b + j) % n]).collect();
    // Backward passes in view order, as a full batch runs them.
    out.sort_unstable();
    out
}

/// Mean pixels per view.
pub(super) fn mean_pixels(cameras: &[Camera]) -> f32 {
    let total: f64 = cameras
        .iter()
        .map(|c| c.width as f64 * c.height as f64)
        .sum();
    (total / cameras.len().max(1) as f64).max(1.0) as f32
}

/// One Adam step (β 0.9/0.999, bias-corrected at step `t`) on every lane with a gradient or
/// momentum, then `project`.
#[allow(clippy::too_many_arguments)]
pub(super) fn adam(
    p: &mut [[f32; 4]],
    m: &mut [[f32; 4]],
    v: &mut [[f32; 4]],
    g: &[[f32; 4]],
    lr: [f32; 4],
    t: i32,
    eps: f32,
    project: impl Fn(&mut [f32; 4]) + Sync,
) {
    let (b1, b2) = (0.9f32, 0.999f32);
    let c1 = 1.0 - b1.powi(t);
    let c2 = 1.0 - b2.powi(t);
    p.par_iter_mut()
        .zip(m.par_iter_mut())
        .zip(v.par_iter_mut())
        .zip(g.par_iter())
        .for_each(|(((p, m), v), g)| {
            let lanes = p.iter_mut().zip(m.iter_mut()).zip(v.iter_mut());
            for (((p, m), v), (&g, &lr)) in lanes.zip(g.iter().zip(&lr)) {
                if g == 0.0 && *m == 0.0 {
                    continue;
                }
                *m = b1 * *m + (1.0 - b1) * g;
                *v = b2 * *v + (1.0 - b2) * g * g;
                *p -= lr * (*m / c1) / ((*v / c2).sqrt() + eps);
            }
            project(p);
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Batches of an orbit: every view once per epoch when `b` divides `n`, each batch spread
    /// evenly (the stride apart), all views when the batch is 0 or at least `n`.
    #[test]
    fn batches_cover_every_view_and_spread_around_the_rig() {
        assert_eq!(batch_views(5, 0, 3), vec![0, 1, 2, 3, 4]);
        assert_eq!(batch_views(5, 8, 1), vec![0, 1, 2, 3, 4]);
        assert_eq!(
            batch_views(48, 16, 0),
            (0..16).map(|i| 3 * i).collect::<Vec<_>>()
        );
        assert_eq!(
            batch_views(48, 16, 1),
            (0..16).map(|i| 3 * i + 1).collect::<Vec<_>>()
        );
        for (n, b) in [(48, 16), (12, 4), (10, 5)] {
            let mut seen = vec![0; n];
            for t in 0..n / b {
                let v = batch_views(n, b, t);
                assert_eq!(v.len(), b);
                v.iter().for_each(|&i| seen[i] += 1);
            }
            assert!(seen.iter().all(|&c| c == 1), "n {n} b {b}: {seen:?}");
            assert_eq!(
                batch_views(n, b, 0),
                batch_views(n, b, n / b),
                "epochs repeat"
            );
        }
        // A batch that does not divide the views still uses each of them in turn.
        let mut seen = vec![0; 10];
        for t in 0..3 {
            batch_views(10, 4, t).iter().for_each(|&i| seen[i] += 1);
        }
        assert!(seen.iter().all(|&c| c >= 1), "{seen:?}");
    }

    /// Adam's ε sets the scale below which a gradient no longer takes a full step: a lane
    /// whose gradient is far above ε moves by the step size on the first step whatever the
    /// gradient's size (Adam's normalisation), one far below moves by about lr·g/ε.
    #[test]
    fn epsilon_damps_gradients_below_it() {
        let eps = 1e-6;
        let g = [[1e-3, 1e-9, 0.0, -1e-3]];
        let mut p = [[0.5f32; 4]];
        let (mut m, mut v) = ([[0.0f32; 4]], [[0.0f32; 4]]);
        adam(&mut p, &mut m, &mut v, &g, [0.02; 4], 1, eps, |_| {});
        let step = p[0].map(|x| x - 0.5);
        // Full steps (0.02 down for a positive gradient) up to lr·ε/|g| = 2e-5 and rounding.
        assert!(
            (step[0] + 0.02).abs() < 3e-5 && (step[3] - 0.02).abs() < 3e-5,
            "{step:?}"
        );
        // 1e-9 against ε 1e-6: lr·g/(|g| + ε) = 0.02 · 1e-9 / 1.001e-6 ≈ 2e-5.
        assert!(step[1] < 0.0 && step[1].abs() < 3e-5, "{step:?}");
        // No gradient and no momentum: untouched.
        assert_eq!(step[2], 0.0);
    }
}
