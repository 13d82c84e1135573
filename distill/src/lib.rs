//! Mesh distillation: fit the exported mesh's per-vertex RGBA to native splatting, as
//! MeshSplats (arXiv 2502.07754) fine-tunes its converted meshes, without a GPU, training
//! images or an autodiff framework.
//!
//! 1. Targets: native splatting (reference settings) of `composite(time)` from the fitting
//!    views.
//! 2. The mesh: the glTF export built in memory with the export's own options
//!    (`convert::glb_bytes`, the same bytes the file gets) and loaded by the tracer, so the
//!    fitted vertices are the written vertices. By default it is made from the Gaussians
//!    widened by native splatting's 0.3 px² low-pass in the fitting views ([`widen_for_fit`];
//!    the 3DGS EWA dilation, which fans otherwise lack), and that scene is what is exported.
//! 3. Hits: per view and pixel, the ordered hit list the compositor uses
//!    (`raytrace::hit_record`), recorded once (the geometry is fixed; only colours and
//!    opacities change) down to a transmittance of `record_transmittance`: by default
//!    1e-4, where native splatting stops blending (`--distill-record-transmittance` keeps
//!    deeper hits, for fits that lower the opacities in front a long way).
//! 4. Iterations: every view is composited from its hits with the current vertex RGBA
//!    ([`composite`]), the loss ([`loss`]) and its image gradient are computed, the gradient is
//!    carried back through front-to-back compositing analytically to the vertices, and one
//!    Adam step (over a batch of views spread around the rig, projected onto [0, 1], with an
//!    ε that keeps barely-seen vertices near the conversion) updates them.
//! 5. The fitted colours go back to the writers as a [`VertexColours`] table keyed by
//!    `_GAUSSIAN_ID` and template vertex, so the export is written by the same code as
//!    any other (and is traced to the image the fit saw; tested).
//!
//! Memory: hit lists (20 bytes a hit, [`composite::Rec`]) are kept while their total stays
//! within `hit_budget` bytes (`--distill-memory`); views beyond it are re-traced in every
//! iteration (streamed: one view's hits at a time). A step keeps each of its views' hits
//! shaded between the forward and backward pass (32 bytes a hit, one view per thread). The
//! optimiser holds three RGBA arrays per vertex (values, Adam's two moments) and one for the
//! gradient.
//!
//! Dynamic scenes: each view has its own scene time (`times`, assigned to the views in
//! turn), its target is native splatting of the composite at that time and its hits are
//! traced with the objects' animated nodes at that time. The fitted parameters are the
//! vertices of each object's own mesh (its frame), so one set of colours is fitted to every
//! pose it takes. Per-frame content (weather) is not part of the fitted mesh.

pub mod composite;
pub mod footprint;
pub mod guard;
pub mod loss;
mod mesh;
pub mod optim;
pub mod options;
pub mod order;
pub mod plain;
pub mod positions;
pub mod run;
mod shade;
mod step;
pub mod targets;
pub mod tied;
pub mod views;

use std::time::Instant;

use rayon::prelude::*;
use splatbridge_convert::vertex_colours::VertexColours;
use splatbridge_convert::ConvertOptions;

use splatbridge_raytrace::hit_record::RecordedHit;
use splatbridge_raytrace::{BackendKind, BuildPreset, MeshTracer, RenderOptions};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::{Camera, Frame};

use composite::{Rec, Shading, ViewHits};
pub use loss::Loss;
use mesh::{export_mesh, quantise, vertex_gaussians};
use optim::{adam, batch_views, mean_pixels};
pub use options::{near_unless_reference, DistillOptions};
use order::Centres;
pub use order::HitOrder;
pub use targets::{
    mean_psnr, mean_psnr_at, native_targets, native_targets_at, native_targets_sh, render_native,
    widen_for_fit,
};
use targets::{native_options, psnr_views};
pub use tied::ParamMode;
pub use tied::Tied;

/// Errors of distillation.
#[derive(Debug, thiserror::Error)]
pub enum DistillError {
    #[error(transparent)]
    Convert(#[from] splatbridge_convert::ConvertError),
    #[error(transparent)]
    Trace(#[from] splatbridge_raytrace::TraceError),
    #[error(transparent)]
    Native(#[from] splatbridge_hybrid::native::RenderError),
    #[error(transparent)]
    Scene(#[from] splatbridge_scene::SceneError),
    #[error("{0}")]
    Invalid(String),
}

pub type Result<T, E = DistillError> = std::result::Result<T, E>;

/// Fitting views of the default `orbit:N` rig: three times MeshSplats-like 16, taken 16 to a
/// step ([`DistillOptions::batch`]); on `fourth_st` 48 views in batches of 16 gained 3.0 dB on
/// held-back views where 16 views gained 2.3 dB at the same ε (docs/distill.md).
pub const DEFAULT_VIEWS: usize = 48;

/// One point of the fit's progress.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Progress {
    pub iteration: usize,
    /// Seconds since the distiller was created (set-up included).
    pub seconds: f64,
    /// Mean loss over the views before this step.
    pub loss: f64,
}

/// What the fit did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct DistillReport {
    pub views: usize,
    pub width: u32,
    pub height: u32,
    pub loss: String,
    pub vertices: usize,
    /// "vertex", or "gaussian" with the number of Gaussians.
    pub params: String,
    pub iterations: usize,
    pub setup_seconds: f64,
    /// Parts of the set-up: the native targets and the hit recording (the rest is the mesh:
    /// the export in memory, its load and BVH).
    pub setup_targets_seconds: f64,
    pub setup_record_seconds: f64,
    pub seconds: f64,
    pub hits: u64,
    pub stored_views: usize,
    pub streamed_views: usize,
    pub hit_bytes: u64,
    pub loss_first: f64,
    pub loss_last: f64,
    /// Validation views ([`guard`]): never fitted, they pick the iteration kept.
    pub validation_views: usize,
    /// Mean validation PSNR at the start and of the kept iteration, and that iteration.
    pub validation_start: f64,
    pub validation_kept: f64,
    pub kept_iteration: usize,
    /// Whether the fit stopped before its iterations ran out, its patience spent
    /// ([`DistillOptions::patience`]).
    pub stopped_early: bool,
    /// The iteration whose refused validation sent the fit back to the best admissible one
    /// with ε raised ([`DistillOptions::eps_backtrack_pixels`]), and that iteration.
    pub backtracked: Option<(usize, usize)>,
}

pub(crate) struct View {
    camera: Camera,
    time: f64,
    target: Vec<f32>,
    hits: Option<ViewHits>,
}

/// The fitting state: the in-memory export and its tracer, the vertex RGBA being fitted, the
/// optimiser's moments and the views.
pub struct Distiller {
    tracer: MeshTracer,
    /// First global vertex of each mesh.
    base: Vec<usize>,
    /// First global triangle of each mesh, and every triangle's global vertices (what the
    /// tracer's hits are numbered by, before each view numbers its own: `ViewHits::new`).
    tri_base: Vec<u32>,
    tris: Vec<[u32; 3]>,
    params: Vec<[f32; 4]>,
    /// Per-Gaussian parameters, when the fit moves those instead of `params`.
    tied: Option<Tied>,
    m: Vec<[f32; 4]>,
    v: Vec<[f32; 4]>,
    views: Vec<View>,
    shading: Shading,
    opts: DistillOptions,
    start: Instant,
    pub history: Vec<Progress>,
    report: DistillReport,
    /// The views' mean pixel count, which Adam's ε in pixels' loss is divided by
    /// ([`Distiller::eps`]).
    pixels: f32,
    /// The Gaussians' centres when hits are composited in splat order.
    centres: Option<Centres>,
    /// Fitted positions ([`DistillOptions::positions`]).
    positions: Option<positions::Positions>,
    /// Validation views and the best iteration they have seen ([`guard`]).
    guard: guard::Guard,
    /// Buffers a step reuses ([`Distiller::loss_and_gradient_over`]): each view of a group
    /// its shaded hits, and the per-hit gradients of the view being differentiated and of the
    /// one being scattered.
    shaded_bufs: Vec<Vec<composite::Shaded>>,
    dh_bufs: [Vec<[f32; 4]>; 2],
}

impl Distiller {
    /// Build the export in memory, render the targets and record the hits of `cameras`.
    pub fn new(
        scene: &DynamicScene,
        convert: &ConvertOptions,
        cameras: &[Camera],
        opts: &DistillOptions,
    ) -> Result<Self> {
        Self::with_mesh_scene(scene, scene, convert, cameras, opts)
    }

    /// As [`Distiller::new`], the targets native splatting of `scene` and the mesh made from
    /// `mesh_scene` (the same Gaussians, widened by [`widen_for_fit`]).
    pub fn with_mesh_scene(
        scene: &DynamicScene,
        mesh_scene: &DynamicScene,
        convert: &ConvertOptions,
        cameras: &[Camera],
        opts: &DistillOptions,
    ) -> Result<Self> {
        let start = Instant::now();
        opts.validate()?;
        if cameras.is_empty() {
            return Err(DistillError::Invalid(
                "distillation needs at least one view".into(),
            ));
        }
        if convert.surfels.is_some() {
            return Err(DistillError::Invalid(
                "distillation fits the profile's vertex colours; it does not take --surfels".into(),
            ));
        }
        if opts.positions && convert.profile == splatbridge_convert::Profile::Texture {
            return Err(DistillError::Invalid(
                "--distill-positions fits the meshsplats and rings profiles: the texture \
                 profile's opacity comes from its texture, which the position gradient does \
                 not carry"
                    .into(),
            ));
        }
        let tri = export_mesh(mesh_scene, convert)?;
        let shading = Shading {
            encode: tri.colors_linear,
            background: RenderOptions::default().background,
        };
        let mut base = Vec::with_capacity(tri.meshes.len());
        let mut params = Vec::new();
        for m in &tri.meshes {
            if !m.has_gaussian_ids && !m.tris.is_empty() {
                return Err(DistillError::Invalid(
                    "distillation needs _GAUSSIAN_ID (do not pass --no-ids)".into(),
                ));
            }
            base.push(params.len());
            params.extend(m.colors.iter().map(|c| c.to_array()));
        }
        let n = params.len();
        let ntris = tri.triangle_count();
        if n > u32::MAX as usize || ntris > u32::MAX as usize {
            return Err(DistillError::Invalid(format!(
                "distillation indexes vertices and triangles with 32 bits: this mesh has {n} \
                 vertices and {ntris} triangles"
            )));
        }
        let mut tri_base = Vec::with_capacity(tri.meshes.len());
        let mut tris = Vec::with_capacity(ntris);
        for (m, &b) in tri.meshes.iter().zip(&base) {
            tri_base.push(tris.len() as u32);
            tris.extend(m.tris.iter().map(|t| t.map(|i| b as u32 + i)));
        }
        let (w, h) = (cameras[0].width as u64, cameras[0].height as u64);
        let values = cameras.len() as u64 * w * h * 3;
        let per_gaussian = match opts.params {
            ParamMode::Vertex => false,
            ParamMode::Gaussian => true,
            ParamMode::Auto => 4 * n as u64 > values,
        };
        let tied = per_gaussian.then(|| {
            let per_vertex = vertex_gaussians(&tri);
            let keys = per_vertex
                .iter()
                .enumerate()
                .flat_map(|(mi, g)| g.iter().map(move |&id| (mi as u32, id)));
            Tied::new(params.clone(), keys)
        });
        let moments = tied.as_ref().map_or(n, Tied::groups);
        let centres = (opts.order == HitOrder::Splat).then(|| Centres::new(&tri));
        let fitted_positions = opts.positions.then(|| positions::Positions::new(&tri));
        let tracer = MeshTracer::new(tri, BackendKind::default(), BuildPreset::default())?;
        let native = native_options(
            opts.fit_sh_degree.unwrap_or(opts.target_sh_degree),
            opts.target_near,
        );
        let (mut targets_seconds, mut record_seconds) = (0.0, 0.0);
        let mut renderer = splatbridge_hybrid::native::Renderer::new();
        let mut d = Distiller {
            tracer,
            base,
            tri_base,
            tris,
            params,
            report: DistillReport {
                views: cameras.len(),
                width: cameras[0].width,
                height: cameras[0].height,
                loss: opts.loss.to_string(),
                vertices: n,
                params: match &tied {
                    Some(t) => format!("gaussian ({})", t.groups()),
                    None => "vertex".into(),
                },
                ..Default::default()
            },
            tied,
            m: vec![[0.0; 4]; moments],
            v: vec![[0.0; 4]; moments],
            views: Vec::with_capacity(cameras.len()),
            shading,
            opts: opts.clone(),
            start,
            history: Vec::new(),
            pixels: mean_pixels(cameras),
            centres,
            positions: fitted_positions,
            guard: guard::Guard::default(),
            shaded_bufs: Vec::new(),
            dh_bufs: [Vec::new(), Vec::new()],
        };
        let mut stored = 0u64;
        let times = opts.view_times(cameras.len());
        // One composite alive at a time: the views of each time in turn, kept in camera order.
        let mut distinct = times.clone();
        distinct.sort_by(f64::total_cmp);
        distinct.dedup();
        let mut slots: Vec<Option<View>> = (0..cameras.len()).map(|_| None).collect();
        // Views are recorded a few at a time (one per thread): a 240×180 window's tiles do
        // not keep two cores busy, and its hit lists are assembled serially.
        let threads = rayon::current_num_threads().max(1);
        let mut frames = vec![Vec::new(); cameras.len()];
        for &t in &distinct {
            let cloud = scene.composite(t);
            let of_t: Vec<usize> = (0..cameras.len()).filter(|&i| times[i] == t).collect();
            let t0 = Instant::now();
            for &i in &of_t {
                frames[i] =
                    targets::render_native(&mut renderer, &cloud, &cameras[i], &native)?.rgb;
            }
            targets_seconds += t0.elapsed().as_secs_f64();
            drop(cloud);
            for group in of_t.chunks(threads) {
                let t1 = Instant::now();
                // Moving vertices change the hits in every step: none are kept.
                let lists: Vec<Result<ViewHits>> = group
                    .par_iter()
                    .map(|&i| {
                        if opts.positions {
                            Ok(ViewHits::default())
                        } else {
                            d.record(&cameras[i], t)
                        }
                    })
                    .collect();
                record_seconds += t1.elapsed().as_secs_f64();
                for (&i, hits) in group.iter().zip(lists) {
                    let hits = hits?;
                    d.report.hits += hits.hits.len() as u64;
                    // Kept in camera order while they fit the budget.
                    let keep = !opts.positions && stored + hits.bytes() <= opts.hit_budget;
                    if keep {
                        stored += hits.bytes();
                        d.report.stored_views += 1;
                    } else {
                        d.report.streamed_views += 1;
                    }
                    slots[i] = Some(View {
                        camera: cameras[i].clone(),
                        time: t,
                        target: std::mem::take(&mut frames[i]),
                        hits: keep.then_some(hits),
                    });
                }
            }
        }
        d.views = slots.into_iter().flatten().collect();
        d.report.hit_bytes = stored;
        d.report.setup_seconds = start.elapsed().as_secs_f64();
        d.report.setup_targets_seconds = targets_seconds;
        d.report.setup_record_seconds = record_seconds;
        Ok(d)
    }

    /// The distiller of an export: the mesh made from `scene` widened for `cameras` when
    /// `opts.footprint` ([`widen_for_fit`]), the targets from `scene` as it is. Returns the
    /// widened scene too, which is what the export is to be written from (None: `scene`).
    pub fn for_export(
        scene: &DynamicScene,
        convert: &ConvertOptions,
        cameras: &[Camera],
        opts: &DistillOptions,
    ) -> Result<(Self, Option<DynamicScene>)> {
        Self::for_windows(scene, convert, cameras, cameras, opts)
    }

    /// As [`Distiller::for_export`], fitting `windows` (each a window of `frames[i]`, or the
    /// view itself) with the footprint sized by the whole views `frames`.
    pub fn for_windows(
        scene: &DynamicScene,
        convert: &ConvertOptions,
        windows: &[Camera],
        frames: &[Camera],
        opts: &DistillOptions,
    ) -> Result<(Self, Option<DynamicScene>)> {
        let cameras = windows;
        let widened = widen_for_fit(scene, frames, opts, convert);
        let d = Self::with_mesh_scene(
            scene,
            widened.as_ref().unwrap_or(scene),
            convert,
            cameras,
            opts,
        )?;
        Ok((d, widened))
    }

    /// Trace one view's hit lists at scene time `time` with the tracer's current colours.
    fn record(&self, cam: &Camera, time: f64) -> Result<ViewHits> {
        let scene = &self.tracer.scene;
        let rec = |h: &RecordedHit| Rec {
            tri: self.tri_base[h.mesh as usize] + h.tri,
            bary: h.bary,
            fa: h.alpha_factor,
        };
        let (k, tr) = (self.opts.record_k, self.opts.record_transmittance);
        let lists = match &self.centres {
            // Splat order sorts each pixel's hits by their distances, which `Rec` does not
            // keep: sorted first, then made `Rec`s.
            Some(c) => {
                let mut lists = self.tracer.record_hits(cam, time, k, tr)?;
                c.reorder(scene, &mut lists, cam, time);
                lists.map(rec)
            }
            // Each hit made a `Rec` as the lists are assembled (no list of every hit in the
            // tracer's form).
            None => self.tracer.record_hits_map(cam, time, k, tr, rec)?,
        };
        Ok(ViewHits::new(
            lists.width,
            lists.height,
            lists.offsets,
            lists.hits,
            &self.tris,
            self.params.len(),
        ))
    }

    /// The vertex RGBA being fitted (linear RGB as the file stores it, alpha), in the
    /// tracer's mesh order.
    pub fn params(&self) -> &[[f32; 4]] {
        &self.params
    }

    pub fn params_mut(&mut self) -> &mut [[f32; 4]] {
        &mut self.params
    }

    /// The per-Gaussian parameters, when the fit moves those.
    pub fn tied(&self) -> Option<&Tied> {
        self.tied.as_ref()
    }

    pub fn shading(&self) -> Shading {
        self.shading
    }

    /// The recorded hits of view `i` (None when it is streamed).
    pub fn view_hits(&self, i: usize) -> Option<&ViewHits> {
        self.views.get(i).and_then(|v| v.hits.as_ref())
    }

    /// Mean loss over the views and its gradient with respect to every vertex's RGBA.
    pub fn loss_and_gradient(&mut self) -> Result<(f64, Vec<[f32; 4]>)> {
        let all: Vec<usize> = (0..self.views.len()).collect();
        self.loss_and_gradient_over(&all)
    }

    /// ∂L/∂p per vertex (fourth lane unused) of the last [`Self::loss_and_gradient_over`],
    /// when positions are fitted (empty otherwise).
    pub fn position_gradient(&self) -> &[[f32; 4]] {
        self.positions.as_ref().map_or(&[], |p| &p.grad)
    }

    /// The fitted positions, when positions are fitted.
    pub fn positions(&self) -> Option<&positions::Positions> {
        self.positions.as_ref()
    }

    /// The fitted positions to change; [`Self::refresh_geometry`] makes the tracer see them.
    pub fn positions_mut(&mut self) -> Option<&mut positions::Positions> {
        self.positions.as_mut()
    }

    /// Write the fitted positions into the tracer's meshes and rebuild its BVHs.
    pub fn refresh_geometry(&mut self) -> Result<()> {
        if let Some(p) = &self.positions {
            let mut scene = std::mem::take(&mut self.tracer.scene);
            p.write(&mut scene, &self.base);
            self.tracer = MeshTracer::new(scene, BackendKind::default(), BuildPreset::default())?;
        }
        Ok(())
    }

    /// The views of step `t` (0-based): every view, or `batch` of them taken in turn from the
    /// strided order 0, s, 2s, …, 1, 1 + s, … (s = ⌈n / batch⌉), so a batch of an orbit sees
    /// the scene from all sides and every view is used once per `n / batch` steps.
    pub fn batch(&self, t: usize) -> Vec<usize> {
        batch_views(self.views.len(), self.opts.batch, t)
    }

    /// One Adam step over every view; returns the loss before the step.
    pub fn step(&mut self) -> Result<f64> {
        let which = self.batch(self.history.len());
        let (loss, grad) = self.loss_and_gradient_over(&which)?;
        // Adam's bias correction counts from the backtrack, where its moments start again.
        let from = self.report.backtracked.map_or(0, |(at, _)| at);
        let t = (self.history.len() - from) as i32 + 1;
        let eps = self.eps();
        let lr = [
            self.opts.lr_colour,
            self.opts.lr_colour,
            self.opts.lr_colour,
            self.opts.lr_alpha,
        ];
        match &mut self.tied {
            None => adam(
                &mut self.params,
                &mut self.m,
                &mut self.v,
                &grad,
                lr,
                t,
                eps,
                |p| p.iter_mut().for_each(|x| *x = x.clamp(0.0, 1.0)),
            ),
            Some(tied) => {
                let g = tied.reduce(&grad);
                adam(
                    &mut tied.theta,
                    &mut self.m,
                    &mut self.v,
                    &g,
                    lr,
                    t,
                    eps,
                    Tied::project,
                );
                tied.expand(&mut self.params);
            }
        }
        if let Some(pos) = &mut self.positions {
            // Adam on the offsets in units of each Gaussian's size: ∂L/∂offset = size·∂L/∂p.
            let g: Vec<[f32; 4]> = pos
                .grad
                .iter()
                .zip(&pos.size)
                .map(|(g, &s)| [g[0] * s, g[1] * s, g[2] * s, 0.0])
                .collect();
            let lr = self.opts.lr_position;
            adam(
                &mut pos.offset,
                &mut pos.m,
                &mut pos.v,
                &g,
                [lr, lr, lr, 0.0],
                t,
                eps,
                |_| {},
            );
        }
        self.refresh_geometry()?;
        self.history.push(Progress {
            iteration: self.history.len(),
            seconds: self.start.elapsed().as_secs_f64(),
            loss,
        });
        if self.report.loss_first == 0.0 && self.history.len() == 1 {
            self.report.loss_first = loss;
        }
        self.report.loss_last = loss;
        self.report.iterations = self.history.len();
        self.report.seconds = self.start.elapsed().as_secs_f64();
        Ok(loss)
    }

    /// Adam's ε for these views' size: [`DistillOptions::eps_pixels`], or after a backtrack
    /// ([`guard`]) [`DistillOptions::eps_backtrack_pixels`], in units of one pixel's loss.
    fn eps(&self) -> f32 {
        let e = match self.report.backtracked {
            Some(_) => self.opts.eps_backtrack_pixels,
            None => self.opts.eps_pixels,
        };
        e / self.pixels
    }

    /// Whether the iteration count or the time budget is used up.
    pub fn done(&self) -> bool {
        self.history.len() >= self.opts.iterations
            || self
                .opts
                .max_seconds
                .is_some_and(|s| self.start.elapsed().as_secs_f64() >= s)
    }

    /// Step until [`Distiller::done`], calling `on_step` after each; with validation views,
    /// keep the best iteration they accept ([`guard`]).
    pub fn run(&mut self, mut on_step: impl FnMut(&Progress)) -> Result<()> {
        self.validate()?;
        while !self.done() {
            self.step()?;
            if let Some(p) = self.history.last() {
                on_step(p);
            }
            if self.history.len().is_multiple_of(guard::EVERY) && self.validate_step()? {
                self.report.stopped_early = true;
                break;
            }
        }
        self.validate()?;
        self.keep_best();
        Ok(())
    }

    /// Write the fitted colours into the tracer's meshes, quantised as the file stores them
    /// (normalized u16), so its renders are the export's.
    pub fn apply(&mut self) {
        for (mi, m) in self.tracer.scene.meshes.iter_mut().enumerate() {
            let b = self.base[mi];
            for (j, c) in m.colors.iter_mut().enumerate() {
                *c = glam::Vec4::from_array(quantise(self.params[b + j]));
            }
        }
    }

    /// The fitted colours as the file stores them.
    fn quantised(&self) -> Vec<[f32; 4]> {
        self.params.iter().map(|&p| quantise(p)).collect()
    }

    /// Trace the fitted mesh from `cam` at the options' `time` (the tracer's defaults, k as
    /// fitted).
    pub fn render(&mut self, cam: &Camera) -> Result<Frame> {
        self.render_at(cam, self.opts.time)
    }

    /// Trace the fitted mesh from `cam` at scene time `time` (in splat order, composited from
    /// its recorded hits: [`order`]).
    pub fn render_at(&mut self, cam: &Camera, time: f64) -> Result<Frame> {
        self.apply();
        if self.centres.is_some() {
            let hits = self.record(cam, time)?;
            let mut f = Frame::new(hits.width, hits.height);
            f.rgb = composite::render(&hits, &self.quantised(), &self.shading);
            return Ok(f);
        }
        let opts = RenderOptions {
            k: self.opts.k,
            ..RenderOptions::default()
        };
        Ok(self.tracer.render(cam, time, &opts)?.0)
    }

    /// PSNR against native of the fitted mesh traced from each of `cameras` (at `times`,
    /// against `targets`): [`Distiller::render_at`]'s images, a view at a time per thread
    /// where they are traced (one after another in splat order, which records each view).
    pub fn psnr_each(
        &mut self,
        cameras: &[Camera],
        times: &[f64],
        targets: &[Frame],
    ) -> Result<Vec<f64>> {
        if self.centres.is_some() {
            return cameras
                .iter()
                .zip(times)
                .zip(targets)
                .map(|((c, &time), t)| {
                    let img = self.render_at(c, time)?;
                    Ok(splatbridge_scene::metrics::psnr(&img, t)?)
                })
                .collect();
        }
        self.apply();
        let opts = RenderOptions {
            k: self.opts.k,
            ..RenderOptions::default()
        };
        let tracer = &self.tracer;
        psnr_views(cameras, times, targets, |c, time| {
            Ok(tracer.render(c, time, &opts)?.0)
        })
    }

    /// The fitted colours as the writers take them.
    pub fn vertex_colours(&self) -> Result<VertexColours> {
        let per_vertex = vertex_gaussians(&self.tracer.scene);
        let ids = per_vertex
            .iter()
            .flatten()
            .filter(|&&x| x != u32::MAX)
            .map(|&x| x as usize + 1)
            .max()
            .unwrap_or(0);
        let mut vc = if self.positions.is_some() {
            VertexColours::with_positions(ids)
        } else {
            VertexColours::new(ids)
        };
        for (mi, g) in per_vertex.iter().enumerate() {
            let b = self.base[mi];
            let mesh = &self.tracer.scene.meshes[mi];
            let mut s = 0;
            while s < g.len() {
                let mut e = s + 1;
                while e < g.len() && g[e] == g[s] {
                    e += 1;
                }
                if g[s] != u32::MAX {
                    let colours = &self.params[b + s..b + e];
                    if self.positions.is_some() {
                        let at: Vec<[f32; 3]> =
                            mesh.positions[s..e].iter().map(|p| p.to_array()).collect();
                        vc.set_positions(g[s], colours, &at)
                    } else {
                        vc.set(g[s], colours)
                    }
                    .map_err(DistillError::Invalid)?;
                }
                s = e;
            }
        }
        Ok(vc)
    }

    pub fn report(&self) -> DistillReport {
        self.report.clone()
    }

    /// Triangles of the fitted mesh (index-buffer triangles, every winding counted).
    pub fn triangles(&self) -> u64 {
        self.tracer
            .scene
            .meshes
            .iter()
            .map(|m| m.tris.len() as u64)
            .sum()
    }

    /// Seconds since the distiller was created.
    pub fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }
}
