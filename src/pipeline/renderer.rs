//! The ways a frame is drawn, behind one type: native splatting (the reference forward
//! pass, `splatbridge_hybrid::native`), 2DGS surfels as 2D Gaussian Splatting draws them
//! (`splatbridge_hybrid::surfel2d`), the GES hybrid (`splatbridge_hybrid::ges`: a surfel
//! split of the frame's cloud, then opaque surfels and unsorted Gaussians), the mesh tracer
//! (`splatbridge_raytrace::MeshTracer`, an exported or in-memory converted file) and the
//! Gaussian tracer (`splatbridge_raytrace::GaussianTracer`, 3DGRT-style).
//!
//! Native, 2DGS and hybrid draw a cloud: each frame's content (composite, particles, shutter
//! samples) is built for them by [`super::frame::render_frame`]. The tracers hold a BVH built
//! once and are posed at each time sample (instancing, no rebuild).

use std::time::Instant;

use anyhow::bail;
use splatbridge_hybrid::ges::{render_ges, GesOptions, GesStats};
use splatbridge_hybrid::{RenderOptions as NativeOptions, RenderStats};
use splatbridge_raytrace::{
    BackendKind, BuildPreset, GaussianTracer, MeshTracer, RenderOptions as TraceOptions, Stats,
};
use splatbridge_scene::surfels::{
    looks_like_ges, split_counted, split_ges, SplitParams, SurfelCloud,
};
use splatbridge_scene::{Camera, Frame, GaussianCloud};

use super::source::{Loaded, Prepared};

/// How the hybrid finds its surfels.
#[derive(Clone, Debug)]
pub struct SurfelSplit {
    /// Thresholds of the trained-cloud split.
    pub params: SplitParams,
    /// Read a GES PLY's own flags.
    pub ges_ply: bool,
    /// Also read them when the cloud looks like a GES PLY (the CLI's default; the parity
    /// pipeline always splits by thresholds).
    pub detect_ges: bool,
}

impl SurfelSplit {
    /// The thresholds, checked (finite and non-negative).
    pub fn checked_params(&self) -> anyhow::Result<SplitParams> {
        let p = &self.params;
        if let Some((field, why)) = p.check() {
            let (option, value) = match field {
                "min_opacity" => ("--surfel-opacity", p.min_opacity.to_string()),
                "max_flatness" => ("--surfel-flatness", p.max_flatness.to_string()),
                "max_scene_fraction" => {
                    ("--surfel-scene-fraction", p.max_scene_fraction.to_string())
                }
                "max_neighbour_ratio" => (
                    "--surfel-neighbour-ratio",
                    p.max_neighbour_ratio.to_string(),
                ),
                other => (other, String::new()),
            };
            bail!("{option} {value} {why}");
        }
        Ok(*p)
    }

    /// Split `cloud` into surfels and residual Gaussians; the string says how (for reports).
    pub fn split(
        &self,
        cloud: &GaussianCloud,
    ) -> anyhow::Result<(SurfelCloud, GaussianCloud, String)> {
        if self.ges_ply || (self.detect_ges && looks_like_ges(cloud)) {
            let (s, g, rep) = split_ges(cloud);
            let mut how = format!(
                "GES PLY flags{}",
                if self.ges_ply { "" } else { " (detected)" }
            );
            if rep.clamped_opacity > 0 {
                how += &format!(
                    ", {} Gaussian opacities above 1 clamped",
                    rep.clamped_opacity
                );
            }
            return Ok((s, g, how));
        }
        let p = &self.checked_params()?;
        let (s, g, counts) = split_counted(cloud, p);
        let mut how = crate::pipeline::split_auto::describe_params(p);
        if counts.candidates > s.len() {
            how += &format!(
                " ({} candidates: {} too large for the scene, {} isolated, {} too large for their neighbours)",
                counts.candidates,
                counts.too_large_for_scene,
                counts.isolated,
                counts.too_large_for_neighbours
            );
        }
        Ok((s, g, how))
    }
}

/// A renderer with its options (and, for the tracers, its BVHs).
pub enum Renderer {
    /// Native splatting; the renderer keeps its buffers across frames.
    Native {
        renderer: splatbridge_hybrid::Renderer,
        options: NativeOptions,
    },
    /// 2DGS surfels drawn as 2D Gaussian Splatting's rasterizer does
    /// (`splatbridge_hybrid::surfel2d`); the stats are native splatting's.
    Surfels2D {
        renderer: splatbridge_hybrid::surfel2d::SurfelRenderer,
        options: NativeOptions,
    },
    /// The GES hybrid.
    Hybrid {
        options: GesOptions,
        split: SurfelSplit,
    },
    /// Triangles composited hit by hit.
    Mesh {
        tracer: MeshTracer,
        options: TraceOptions,
    },
    /// The Gaussians ray-traced.
    Gaussian {
        tracer: GaussianTracer,
        options: TraceOptions,
    },
}

/// What one drawing of a frame (or one shutter sample of it) did.
#[derive(Clone, Debug)]
pub enum FrameStats {
    Native(RenderStats),
    Hybrid {
        stats: GesStats,
        /// Milliseconds spent splitting surfels from the cloud.
        split_ms: f64,
        /// How surfels were found.
        surfels_by: String,
    },
    Trace(Stats),
}

impl Renderer {
    /// Native splatting with `options` (checked).
    pub fn native(options: NativeOptions) -> anyhow::Result<Renderer> {
        options.validate()?;
        Ok(Renderer::Native {
            renderer: splatbridge_hybrid::Renderer::new(),
            options,
        })
    }

    /// [`Renderer::native`] drawing into `buffers`, a native renderer kept from an earlier
    /// frame (see [`Renderer::into_native_buffers`]): callers that render one frame per call,
    /// as the Python bindings do, keep warm buffers instead of faulting new ones each frame.
    pub fn native_reusing(
        options: NativeOptions,
        buffers: splatbridge_hybrid::Renderer,
    ) -> anyhow::Result<Renderer> {
        options.validate()?;
        Ok(Renderer::Native {
            renderer: buffers,
            options,
        })
    }

    /// A native renderer's buffers, for [`Renderer::native_reusing`]; `None` for the others.
    pub fn into_native_buffers(self) -> Option<splatbridge_hybrid::Renderer> {
        match self {
            Renderer::Native { renderer, .. } => Some(renderer),
            _ => None,
        }
    }

    /// The 2DGS surfel renderer with `options` (checked; the extent knob is not used).
    pub fn surfels_2d(options: NativeOptions) -> anyhow::Result<Renderer> {
        options.validate()?;
        Ok(Renderer::Surfels2D {
            renderer: splatbridge_hybrid::surfel2d::SurfelRenderer::new(),
            options,
        })
    }

    /// The GES hybrid with `options` (checked).
    pub fn hybrid(options: GesOptions, split: SurfelSplit) -> anyhow::Result<Renderer> {
        options.validate()?;
        Ok(Renderer::Hybrid { options, split })
    }

    /// As [`Renderer::tracer`], moving what is traced into the tracer instead of copying it: a
    /// triangle scene (`p.loaded` is left an empty scene), and with `take_gaussians` the
    /// scene's Gaussians (`p.effects_scene` keeps its tracks, cameras, time range and effects,
    /// with empty clouds: only for a caller that needs nothing more of them, not one that
    /// rebuilds tracers from the scene or hashes it). A command that builds one tracer holds
    /// its content once, not twice (1.2 GB for a 37 M-triangle export, 2.5 GB for 10 M
    /// Gaussians).
    pub fn tracer_taking(
        p: &mut Prepared,
        backend: BackendKind,
        preset: BuildPreset,
        take_gaussians: bool,
    ) -> anyhow::Result<Renderer> {
        match (&mut p.loaded, &mut p.effects_scene) {
            (Loaded::Mesh(s), _) => {
                let scene = std::mem::take(s);
                Ok(Renderer::Mesh {
                    tracer: MeshTracer::new(scene, backend, preset)?,
                    options: p.options.clone(),
                })
            }
            (Loaded::Gaussians(particles), Some(scene)) if take_gaussians => {
                let mut g = GaussianTracer::for_scene_taking(scene, p.time, backend, preset)?;
                g.set_particles(particles.take())?;
                Ok(Renderer::Gaussian {
                    tracer: g,
                    options: p.options.clone(),
                })
            }
            _ => Self::tracer(p, backend, preset),
        }
    }

    /// A tracer for a prepared input on one backend.
    pub fn tracer(
        p: &Prepared,
        backend: BackendKind,
        preset: BuildPreset,
    ) -> anyhow::Result<Renderer> {
        Ok(match &p.loaded {
            Loaded::Mesh(s) => Renderer::Mesh {
                tracer: MeshTracer::new(s.clone(), backend, preset)?,
                options: p.options.clone(),
            },
            Loaded::Gaussians(particles) => {
                let Some(scene) = p.effects_scene.as_ref() else {
                    bail!("a Gaussian input keeps its scene");
                };
                let mut g = GaussianTracer::for_scene(scene, p.time, backend, preset)?;
                g.set_particles(particles.clone())?;
                Renderer::Gaussian {
                    tracer: g,
                    options: p.options.clone(),
                }
            }
        })
    }

    /// Whether this renderer draws a cloud built per frame (native, hybrid) rather than a
    /// prebuilt BVH (the tracers).
    pub fn draws_clouds(&self) -> bool {
        matches!(
            self,
            Renderer::Native { .. } | Renderer::Surfels2D { .. } | Renderer::Hybrid { .. }
        )
    }

    /// Seconds spent building BVHs so far (0 for native and hybrid): mode mesh builds a BVH
    /// over runs on the first frame that reads it, so after a render this includes it.
    pub fn build_seconds(&self) -> f64 {
        match self {
            Renderer::Mesh { tracer, .. } => tracer.total_build_seconds(),
            Renderer::Gaussian { tracer, .. } => tracer.build_seconds,
            _ => 0.0,
        }
    }

    /// The tracers' options (None for native and hybrid).
    pub fn trace_options_mut(&mut self) -> Option<&mut TraceOptions> {
        match self {
            Renderer::Mesh { options, .. } | Renderer::Gaussian { options, .. } => Some(options),
            _ => None,
        }
    }

    /// Pose the tracers' scene at `t` for the next render (mode gaussian re-poses its
    /// objects; mode mesh poses its morphed meshes, reading their targets from the file, and
    /// takes the node transforms per render).
    pub fn set_time(&mut self, t: f64) -> anyhow::Result<()> {
        match self {
            Renderer::Gaussian { tracer, .. } => tracer.set_time(t),
            Renderer::Mesh { tracer, .. } => tracer.set_time(t)?,
            _ => {}
        }
        Ok(())
    }

    /// Draw `cloud` (native, hybrid) at `cam`.
    pub fn render_cloud(
        &mut self,
        cloud: &GaussianCloud,
        cam: &Camera,
    ) -> anyhow::Result<(Frame, FrameStats)> {
        match self {
            Renderer::Native { renderer, options } => {
                let (f, st) = renderer.render(cloud, cam, options)?;
                Ok((f, FrameStats::Native(st)))
            }
            Renderer::Surfels2D { renderer, options } => {
                let (f, st) = renderer.render(cloud, cam, options)?;
                Ok((f, FrameStats::Native(st)))
            }
            Renderer::Hybrid { options, split } => {
                let t0 = Instant::now();
                let (surfels, rest, how) = split.split(cloud)?;
                let split_ms = t0.elapsed().as_secs_f64() * 1e3;
                let (f, st) = render_ges(&surfels, &rest, cam, options)?;
                Ok((
                    f,
                    FrameStats::Hybrid {
                        stats: st,
                        split_ms,
                        surfels_by: how,
                    },
                ))
            }
            _ => bail!("a tracer draws its own BVH, not a cloud"),
        }
    }

    /// Trace the prebuilt scene at `cam` and `time` (the tracers; mode gaussian draws the
    /// pose of its last [`Renderer::set_time`]).
    pub fn render_traced(&self, cam: &Camera, time: f64) -> anyhow::Result<(Frame, Stats)> {
        match self {
            Renderer::Mesh { tracer, options } => Ok(tracer.render(cam, time, options)?),
            Renderer::Gaussian { tracer, options } => Ok(tracer.render(cam, options)?),
            _ => bail!("native splatting and the hybrid draw a cloud"),
        }
    }
}

impl FrameStats {
    /// Sum another sample's stats into these (same renderer).
    pub fn add(&mut self, other: &FrameStats) -> anyhow::Result<()> {
        match (self, other) {
            (FrameStats::Native(a), FrameStats::Native(b)) => *a += b,
            (
                FrameStats::Hybrid {
                    stats,
                    split_ms,
                    surfels_by,
                },
                FrameStats::Hybrid {
                    stats: s,
                    split_ms: ms,
                    surfels_by: how,
                },
            ) => {
                *stats += s;
                *split_ms += ms;
                surfels_by.clone_from(how);
            }
            (FrameStats::Trace(a), FrameStats::Trace(b)) => {
                a.rays += b.rays;
                a.hits += b.hits;
                a.traversals += b.traversals;
                a.seconds += b.seconds;
            }
            _ => bail!("stats of different renderers cannot be summed"),
        }
        Ok(())
    }

    /// Empty stats of the kind `r` produces.
    pub fn zero_for(r: &Renderer) -> FrameStats {
        match r {
            Renderer::Native { .. } | Renderer::Surfels2D { .. } => {
                FrameStats::Native(RenderStats::default())
            }
            Renderer::Hybrid { .. } => FrameStats::Hybrid {
                stats: GesStats::default(),
                split_ms: 0.0,
                surfels_by: String::new(),
            },
            _ => FrameStats::Trace(Stats::default()),
        }
    }

    /// The tracers' stats (None for native and hybrid).
    pub fn trace(&self) -> Option<&Stats> {
        match self {
            FrameStats::Trace(s) => Some(s),
            _ => None,
        }
    }
}
