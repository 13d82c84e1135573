//! Surfel export: a scene split into opaque surfels and residual Gaussians (GES, arXiv
//! 2504.17545; the split of `splatbridge_scene::surfels`), written as two materials so that a
//! glTF viewer renders the two passes of the hybrid: first the surfels, opaque with depth
//! test and depth write, then the residual Gaussians blended over them.
//!
//! ## What a surfel becomes
//! One fan of `n` triangles (n + 1 vertices: the centre and `n` rim vertices at
//! `θ_k = 2πk/n`) in the plane of the Gaussian's two largest axes, out to the 1/255 footprint
//! `r = sqrt(2·ln 255) ≈ 3.33σ` ([`splatbridge_scene::surfels::FOOTPRINT_SIGMAS`]) scaled by
//! the area-preserving polygon factor `k_n = sqrt(2π/(n·sin(2π/n)))` (as the `rings`
//! profile), so the n-gon covers the same area as the ellipse the hybrid renderer rasterises.
//! Every vertex alpha is exactly 1; the colour is the SH DC colour (or the `--bake-view`
//! colour), encoded like the residual's (`ColorEncoding`); the normal is `a_u × a_v`. The
//! material is `alphaMode: OPAQUE`, unlit, double-sided, without a texture.
//!
//! ## Where the split happens
//! Every part of the scene is split in its own frame: the static cloud, each object's local
//! cloud (so its surfels ride on the object's animated node) and each per-frame cloud. A
//! part's surfels and residual Gaussians are two primitives of the same mesh, so the node
//! structure is the one of a plain export. `_GAUSSIAN_ID` stays the Gaussian's index in the
//! unsplit scene's composite order, for surfels and residual Gaussians alike.
//!
//! ## Differences from the hybrid renderer
//! A viewer alpha-blends the residual Gaussians over the surfels with the depth test
//! (sorted per object or not at all), where the hybrid accumulates `C_G`, `W_G` unsorted
//! within the depth tolerance ε and normalises. Both show a surfel wherever nothing is in
//! front of it; they differ where residual Gaussians overlap a surfel within ε.
//! `--max-triangles` applies to the residual Gaussians only.

use std::ops::Range;

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::surfel_guard::guard;
use splatbridge_scene::surfels::{
    ges_mean_scale, is_surfel, SplitParams, SurfelCloud, FOOTPRINT_SIGMAS,
};
use splatbridge_scene::{sh, GaussianCloud};

use crate::chunked::ChunkedMesh;
use crate::classify::Frame;
use crate::mesh::{srgb_to_linear, VertexSink};
use crate::options::{ColorEncoding, ConvertOptions};
use crate::FrameClouds;

/// Default segments of a surfel fan: 8, MeshSplats' fan; with the area-preserving factor the
/// octagon's radius is within 5.1 % of the ellipse's everywhere (`polygon_radius_error(8)`).
pub const DEFAULT_SURFEL_SEGMENTS: usize = 8;

/// The surfel knobs of a conversion (`--surfels`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SurfelOptions {
    /// Activated opacity at or above which a Gaussian may become a surfel.
    pub min_opacity: f32,
    /// Largest `s_min / s_mid` of a surfel.
    pub max_flatness: f32,
    /// Triangles per surfel fan.
    pub segments: usize,
    /// Apply the hybrid renderer's guards (scene fraction, neighbour ratio, isolation; see
    /// `splatbridge_scene::surfel_guard`) after the local test, each part judged within its
    /// own cloud. Without them a metre-wide floater that passes the local test becomes an
    /// opaque disc in the export as it would in the hybrid.
    #[serde(default = "guarded_default")]
    pub guarded: bool,
}

fn guarded_default() -> bool {
    true
}

impl Default for SurfelOptions {
    fn default() -> Self {
        let p = SplitParams::default();
        SurfelOptions {
            min_opacity: p.min_opacity,
            max_flatness: p.max_flatness,
            segments: DEFAULT_SURFEL_SEGMENTS,
            guarded: true,
        }
    }
}

impl SurfelOptions {
    /// The split's thresholds: the hybrid's default guards, or the local test alone.
    pub fn params(&self) -> SplitParams {
        if self.guarded {
            SplitParams::guarded(self.min_opacity, self.max_flatness)
        } else {
            SplitParams::unguarded(self.min_opacity, self.max_flatness)
        }
    }

    pub fn validate(&self) -> Result<(), crate::ConvertError> {
        let bad = |m: String| Err(crate::ConvertError::Invalid(m));
        if !(3..=64).contains(&self.segments) {
            return bad(format!(
                "surfel segments must be in 3..=64, got {}",
                self.segments
            ));
        }
        if !self.min_opacity.is_finite() {
            return bad(format!(
                "surfel opacity threshold must be finite, got {}",
                self.min_opacity
            ));
        }
        if !(self.max_flatness.is_finite() && self.max_flatness >= 0.0) {
            return bad(format!(
                "surfel flatness threshold must be a finite number ≥ 0, got {}",
                self.max_flatness
            ));
        }
        Ok(())
    }
}

/// Surfel counts of one part of the scene.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct SurfelCounts {
    pub name: String,
    /// Gaussians of the part before the split.
    pub gaussians_in: u64,
    /// Gaussians that passed the local test but that the guards kept as Gaussians.
    #[serde(default)]
    pub guarded_out: u64,
    /// Gaussians that became surfels (written, or dropped as non-finite).
    pub surfels: u64,
    /// Gaussians left to the converter profile.
    pub residual: u64,
    /// Surfels whose fan would not be finite in f32.
    pub dropped_overflow: u64,
    pub vertices: u64,
    pub triangles: u64,
}

/// What the split did, for the report and the output's metadata.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct SurfelReport {
    pub min_opacity: f32,
    pub max_flatness: f32,
    pub segments: usize,
    /// Whether the guards applied (see [`SurfelOptions::guarded`]).
    #[serde(default)]
    pub guarded: bool,
    pub gaussians_in: u64,
    /// Candidates the guards kept as Gaussians.
    #[serde(default)]
    pub guarded_out: u64,
    pub surfels: u64,
    pub residual: u64,
    pub dropped_overflow: u64,
    pub vertices: u64,
    pub triangles: u64,
    pub parts: Vec<SurfelCounts>,
}

impl SurfelReport {
    pub fn new(o: &SurfelOptions) -> Self {
        SurfelReport {
            min_opacity: o.min_opacity,
            max_flatness: o.max_flatness,
            segments: o.segments,
            guarded: o.guarded,
            ..Default::default()
        }
    }

    pub fn add(&mut self, c: SurfelCounts) {
        self.gaussians_in += c.gaussians_in;
        self.guarded_out += c.guarded_out;
        self.surfels += c.surfels;
        self.residual += c.residual;
        self.dropped_overflow += c.dropped_overflow;
        self.vertices += c.vertices;
        self.triangles += c.triangles;
        self.parts.push(c);
    }
}

/// One part of the scene after the split: its surfels and the original ids (composite order
/// of the unsplit scene) of its surfels and residual Gaussians.
#[derive(Clone, Debug, Default)]
pub struct SplitPart {
    pub name: String,
    pub surfels: SurfelCloud,
    pub surfel_ids: Vec<u32>,
    pub residual_ids: Vec<u32>,
    /// Candidates of the local test that the guards kept as Gaussians.
    pub guarded_out: u64,
}

/// A scene split into residual Gaussians (a scene of the same structure) and surfels; the
/// parts are in the order of [`crate::prepare`]: static, objects, per-frame clouds.
pub struct SplitScene {
    pub residual: DynamicScene,
    pub frames: Option<FrameClouds>,
    pub parts: Vec<SplitPart>,
}

/// Split one cloud; `offset` is the composite id of its first Gaussian.
pub fn split_cloud(
    cloud: &GaussianCloud,
    params: &SplitParams,
    name: &str,
    offset: u64,
) -> (GaussianCloud, SplitPart) {
    let mut flags: Vec<bool> = (0..cloud.len())
        .into_par_iter()
        .map(|i| is_surfel(cloud, i, params) && cloud.invalid_reason(i).is_none())
        .collect();
    // The guards, as the hybrid's split applies them (`splatbridge_scene::surfels::split`).
    let candidates: Vec<(usize, f32)> = (0..cloud.len())
        .filter(|&i| flags[i])
        .map(|i| (i, cloud.scale(i).max_element()))
        .collect();
    let (keep, _) = guard(cloud, &candidates, &params.guard());
    let mut guarded_out = 0u64;
    for (&(i, _), &k) in candidates.iter().zip(&keep) {
        flags[i] = k;
        guarded_out += !k as u64;
    }
    let mut part = SplitPart {
        name: name.to_string(),
        surfels: SurfelCloud::new(cloud.sh_degree),
        guarded_out,
        ..Default::default()
    };
    let mut rest = GaussianCloud::new(cloud.sh_degree);
    for (i, &s) in flags.iter().enumerate() {
        let id = (offset + i as u64) as u32;
        if !s {
            rest.push(
                cloud.means[i],
                cloud.log_scales[i],
                cloud.rotations[i],
                cloud.opacity_logits[i],
                cloud.sh_of(i),
            );
            part.residual_ids.push(id);
            continue;
        }
        // Frame::of sorts the axes as the scene's split does (largest first, total order).
        let f = Frame::of(cloud, i);
        part.surfels.push(
            f.mean,
            f.axes[0],
            f.axes[1],
            [f.scales[0], f.scales[1]],
            ges_mean_scale(f.scales[0], f.scales[1]),
            cloud.sh_of(i),
        );
        part.surfel_ids.push(id);
    }
    (rest, part)
}

/// Split every part of a scene (and of its per-frame content).
pub fn split_scene(
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    o: &SurfelOptions,
) -> SplitScene {
    let params = o.params();
    let mut offset = 0u64;
    let mut parts = Vec::new();
    let mut next = |c: &GaussianCloud, name: &str, parts: &mut Vec<SplitPart>| {
        let (rest, part) = split_cloud(c, &params, name, offset);
        offset += c.len() as u64;
        parts.push(part);
        rest
    };
    let mut residual = DynamicScene {
        time: scene.time,
        static_gaussians: next(&scene.static_gaussians, "static", &mut parts),
        objects: Vec::with_capacity(scene.objects.len()),
        // Per-frame content is meshed from the FrameClouds the caller passes.
        frames: Vec::new(),
        cameras: scene.cameras.clone(),
        effects: scene.effects.clone(),
        four_d: None,
    };
    for o in &scene.objects {
        residual
            .objects
            .push(splatbridge_scene::dynamic::SceneObject {
                name: o.name.clone(),
                gaussians: next(&o.gaussians, &o.name, &mut parts),
                track: o.track.clone(),
            });
    }
    let frames = frames.map(|fr| FrameClouds {
        times: fr.times.clone(),
        clouds: fr
            .clouds
            .iter()
            .enumerate()
            .map(|(k, c)| next(c, &format!("frame {k}"), &mut parts))
            .collect(),
    });
    SplitScene {
        residual,
        frames,
        parts,
    }
}

/// One part's surfels, ready to be meshed chunk by chunk ([`ChunkedMesh`], as
/// [`crate::Mesher`]).
pub struct SurfelMesher<'a> {
    pub surfels: &'a SurfelCloud,
    ids: &'a [u32],
    /// Rim directions `(cos θ_k, sin θ_k)·m`, m the footprint radius in σ.
    rim: Vec<(f32, f32)>,
    keep: Vec<bool>,
    bake_centre: Option<DVec3>,
    linear: bool,
    coplanar: bool,
    frame_reach: f32,
    pub counts: SurfelCounts,
}

impl<'a> SurfelMesher<'a> {
    pub fn new(
        part: &'a SplitPart,
        o: &SurfelOptions,
        opts: &ConvertOptions,
        gaussians_in: u64,
    ) -> Self {
        let n = o.segments;
        let m = FOOTPRINT_SIGMAS * crate::profile::area_factor(n) as f32;
        let rim = (0..n)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / n as f64;
                (t.cos() as f32 * m, t.sin() as f32 * m)
            })
            .collect::<Vec<_>>();
        let s = &part.surfels;
        let keep: Vec<bool> = (0..s.len())
            .into_par_iter()
            .map(|i| {
                let reach =
                    s.means[i].abs().max_element() + m * s.scales[i][0].max(s.scales[i][1]) * 1.01;
                s.means[i].is_finite()
                    && s.axes_u[i].is_finite()
                    && s.axes_v[i].is_finite()
                    && reach.is_finite()
                    && reach < 1e30
            })
            .collect();
        let kept = keep.iter().filter(|&&k| k).count() as u64;
        let counts = SurfelCounts {
            name: part.name.clone(),
            gaussians_in,
            guarded_out: part.guarded_out,
            surfels: s.len() as u64,
            residual: part.residual_ids.len() as u64,
            dropped_overflow: s.len() as u64 - kept,
            vertices: kept * (n as u64 + 1),
            triangles: kept * n as u64,
        };
        SurfelMesher {
            surfels: s,
            ids: &part.surfel_ids,
            rim,
            keep,
            bake_centre: opts.bake_view.as_ref().map(|c| c.centre),
            linear: opts.color_encoding == ColorEncoding::Linear,
            coplanar: opts.coplanar_offset,
            frame_reach: 0.0,
            counts,
        }
    }

    /// See [`crate::Mesher::set_frame_reach`].
    pub fn set_frame_reach(&mut self, reach: f32) {
        self.frame_reach = if reach.is_finite() { reach.abs() } else { 0.0 };
    }

    pub fn is_empty(&self) -> bool {
        self.counts.triangles == 0
    }

    fn colour(&self, i: usize) -> Vec3 {
        let coeffs = self.surfels.sh_of(i);
        let mut rgb = sh::dc_color(coeffs);
        if let Some(c) = self.bake_centre {
            let d = self.surfels.means[i].as_dvec3() - c;
            let l = d.length();
            if l > 0.0 && l.is_finite() {
                rgb = sh::eval_color(self.surfels.sh_degree, coeffs, (d / l).as_vec3())
                    .clamp(Vec3::ZERO, Vec3::ONE);
            }
        }
        if self.linear {
            rgb = Vec3::new(
                srgb_to_linear(rgb.x),
                srgb_to_linear(rgb.y),
                srgb_to_linear(rgb.z),
            );
        }
        rgb
    }
}

impl ChunkedMesh for SurfelMesher<'_> {
    type Scratch = ();

    fn items(&self) -> usize {
        self.surfels.len()
    }

    fn vertices_of(&self, i: usize) -> u64 {
        if self.keep[i] {
            self.rim.len() as u64 + 1
        } else {
            0
        }
    }

    fn indices_of(&self, i: usize, first: u32, _reverse: bool, idx: &mut Vec<u32>) -> u32 {
        if !self.keep[i] {
            return 0;
        }
        let n = self.rim.len() as u32;
        for k in 0..n {
            idx.extend_from_slice(&[first, first + 1 + k, first + 1 + (k + 1) % n]);
        }
        n + 1
    }

    fn emit_range<S: VertexSink>(&self, range: Range<usize>, out: &mut S, _: &mut ()) {
        let s = self.surfels;
        let n = self.rim.len() as u32;
        for i in range {
            if !self.keep[i] {
                continue;
            }
            let (mut mean, eu, ev) = (
                s.means[i],
                s.axes_u[i] * s.scales[i][0],
                s.axes_v[i] * s.scales[i][1],
            );
            let nrm = s.normal(i).normalize_or(Vec3::Z);
            if self.coplanar {
                // The same separation as the residual Gaussians (classify.rs), so a surfel
                // and a splat in one plane do not hide each other in Cycles either.
                let reach = mean.abs().max_element()
                    + self.frame_reach
                    + 4.0 * s.scales[i][0].max(s.scales[i][1]);
                mean += nrm * crate::classify::coplanar_offset(self.ids[i], reach);
            }
            let (rgba, normal, id) = if S::FULL {
                let c = self.colour(i);
                ([c.x, c.y, c.z, 1.0], nrm.to_array(), self.ids[i])
            } else {
                ([0.0; 4], [0.0; 3], 0)
            };
            let c = out.vertex(mean, normal, rgba, [0.0; 2], id);
            for &(x, y) in &self.rim {
                out.vertex(mean + eu * x + ev * y, normal, rgba, [0.0; 2], id);
            }
            for k in 0..n {
                out.triangle([c, c + 1 + k, c + 1 + (k + 1) % n]);
            }
        }
    }

    fn has_uv(&self) -> bool {
        false
    }
}
