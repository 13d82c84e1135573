//! One step's loss and gradient over a batch of views: the forward composite and the loss of a
//! few views at a time in parallel, then each view's backward pass and its scatter to the
//! vertices in view order, so every sum is taken in the same order at any thread count.
//!
//! The scatter of a view's per-hit gradients to its vertices is serial (hits of different
//! pixels share vertices); it runs beside the next view's backward pass (two per-hit gradient
//! buffers), which keeps both cores busy without changing the order of any addition.

use rayon::prelude::*;

use crate::{composite, loss, positions, Distiller, Result};

/// Where a view's backward pass writes: its per-hit gradients, the vertices' gradient and the
/// positions' gradient.
type Outputs<'a> = (
    &'a mut Vec<[f32; 4]>,
    &'a mut [[f32; 4]],
    &'a mut [[f32; 4]],
);

impl Distiller {
    /// Mean loss over the views `which` and its gradient with respect to every vertex's RGBA.
    pub fn loss_and_gradient_over(&mut self, which: &[usize]) -> Result<(f64, Vec<[f32; 4]>)> {
        let mut grad = vec![[0.0f32; 4]; self.params.len()];
        let mut pos_grad = vec![[0.0f32; 4]; self.positions.as_ref().map_or(0, |p| p.start.len())];
        let nviews = which.len().max(1) as f64;
        let mut total = 0.0;
        let streamed = which.iter().any(|&i| self.views[i].hits.is_none());
        if streamed {
            self.apply();
        }
        let s = (1.0 / nviews) as f32;
        // Images and image gradients of a few views at a time in parallel (the loss is serial
        // work per view), then the backward passes in view order. A chunk holds one image
        // gradient per thread.
        let chunk = rayon::current_num_threads().max(1);
        let mut shaded_bufs = std::mem::take(&mut self.shaded_bufs);
        shaded_bufs.resize_with(chunk, Vec::new);
        let [mut dh, mut dh_prev] = std::mem::take(&mut self.dh_bufs);
        // The stored view whose per-hit gradients are in `dh_prev`, not yet scattered.
        let mut pending: Option<usize> = None;
        for group in which.chunks(chunk) {
            let (params, shading, kind) = (&self.params, &self.shading, self.opts.loss);
            let views = &self.views;
            // Each stored view's loss and image gradient, and whether its hits as shaded are
            // in its buffer (when few enough to keep, [`composite::MAX_SHADED_HITS`]).
            let losses: Vec<Option<(f64, Vec<f32>, bool)>> = group
                .par_iter()
                .zip(shaded_bufs.par_iter_mut())
                .map(|(&i, buf)| {
                    let v = &views[i];
                    v.hits.as_ref().map(|hits| {
                        let (w, h) = (hits.width as usize, hits.height as usize);
                        let keep = hits.hits.len() <= composite::MAX_SHADED_HITS;
                        let img = if keep {
                            composite::render_shaded_into(hits, params, shading, buf)
                        } else {
                            composite::render(hits, params, shading)
                        };
                        let (l, dimg) = loss::loss_and_grad(&img, &v.target, w, h, kind);
                        (l, dimg, keep)
                    })
                })
                .collect();
            for ((&i, stored), buf) in group.iter().zip(losses).zip(&shaded_bufs) {
                let (l, mut dimg, kept) = match stored {
                    Some(lg) if self.positions.is_none() => lg,
                    stored => {
                        // A streamed view (traced again here) or fitted positions (whose
                        // gradient reads this view's per-hit gradients after its scatter):
                        // in turn.
                        if let Some(j) = pending.take() {
                            composite::scatter(self.stored(j), &dh_prev, &mut grad);
                        }
                        let out = (&mut dh, &mut grad[..], &mut pos_grad[..]);
                        total += self.backward_in_turn(i, stored, buf, s, nviews, out)?;
                        continue;
                    }
                };
                total += l / nviews;
                dimg.iter_mut().for_each(|g| *g *= s);
                let hits = self.stored(i);
                let cached = kept.then_some(buf.as_slice());
                let (params, shading) = (&self.params, &self.shading);
                let backward = |dh: &mut Vec<[f32; 4]>| {
                    composite::hit_gradients_into(hits, params, cached, shading, &dimg, dh)
                };
                match pending {
                    Some(j) => {
                        let prev = self.stored(j);
                        rayon::join(
                            || composite::scatter(prev, &dh_prev, &mut grad),
                            || backward(&mut dh),
                        );
                    }
                    None => backward(&mut dh),
                }
                std::mem::swap(&mut dh, &mut dh_prev);
                pending = Some(i);
            }
        }
        if let Some(j) = pending {
            composite::scatter(self.stored(j), &dh_prev, &mut grad);
        }
        self.shaded_bufs = shaded_bufs;
        self.dh_bufs = [dh, dh_prev];
        if let Some(p) = &mut self.positions {
            p.grad = pos_grad;
        }
        Ok((total, grad))
    }

    /// The stored hits of view `i` (the caller knows it is stored).
    fn stored(&self, i: usize) -> &composite::ViewHits {
        self.views[i].hits.as_ref().expect("a stored view")
    }

    /// View `i`'s loss (divided by `nviews`), and its backward pass and scatter (and position
    /// gradient) done at once, from its loss and image gradient when the group computed them
    /// (`stored`, with its shaded hits in `buf` when kept); the view's hits are traced again
    /// when they are not stored.
    fn backward_in_turn(
        &self,
        i: usize,
        stored: Option<(f64, Vec<f32>, bool)>,
        buf: &[composite::Shaded],
        s: f32,
        nviews: f64,
        (dh, grad, pos_grad): Outputs,
    ) -> Result<f64> {
        let view = &self.views[i];
        let owned;
        let hits = match &view.hits {
            Some(h) => h,
            None => {
                owned = self.record(&view.camera, view.time)?;
                &owned
            }
        };
        let (l, mut dimg, kept) = match stored {
            Some(lg) => lg,
            None => {
                let (w, h) = (hits.width as usize, hits.height as usize);
                let img = composite::render(hits, &self.params, &self.shading);
                let (l, dimg) = loss::loss_and_grad(&img, &view.target, w, h, self.opts.loss);
                (l, dimg, false)
            }
        };
        dimg.iter_mut().for_each(|g| *g *= s);
        let cached = kept.then_some(buf);
        composite::hit_gradients_into(hits, &self.params, cached, &self.shading, &dimg, dh);
        composite::scatter(hits, dh, grad);
        if self.positions.is_some() {
            let mut to_local = vec![None; self.base.len()];
            for inst in self.tracer.prepare_list(view.time) {
                to_local[inst.mesh].get_or_insert(inst.to_local);
            }
            let rays = positions::ViewRays {
                camera: &view.camera,
                to_local,
                scene: &self.tracer.scene,
                base: &self.base,
            };
            positions::gradient(hits, dh, &self.params, &rays, pos_grad);
        }
        Ok(l / nviews)
    }
}
