//! splatbridge-convert: trained Gaussian splats to triangle meshes that viewers and Blender
//! open correctly (glTF/GLB, OBJ + MTL, PLY), and to native glTF splats
//! (`KHR_gaussian_splatting`), with a reader for the latter.
//!
//! Follows MeshSplats (arXiv 2502.07754: one triangle fan per Gaussian, vertex colour and
//! alpha, three fans for volumetric Gaussians) and adds opacity-aware profiles (see
//! [`profile`]), dynamic scenes as animated glTF nodes, and cameras.
//!
//! ## What the glTF output contains
//! * One root node `splatbridge_root` whose rotation maps the input's up axis onto glTF's +Y
//!   ([`options::UpAxis`]; default: input up is −Y as in COLMAP, a 180° turn about X).
//!   Vertices stay in the input frame.
//! * Under it: the static Gaussians as one mesh node; each object's Gaussians meshed once in
//!   its local frame under a node whose translation and rotation are animated (LINEAR,
//!   seconds, unit x,y,z,w quaternions); per-frame content as one node per frame, shown
//!   only on its frame by a STEP scale animation; the scene's cameras as camera nodes.
//! * Vertex attributes: POSITION, NORMAL (the Gaussian's shortest axis; optional, off in the
//!   arrangement for viewers), COLOR_0 (RGBA, normalized u16, linear by default: see
//!   [`options::ColorEncoding`]), `_GAUSSIAN_ID` and, for the `texture` profile, TEXCOORD_0;
//!   u32 indexed TRIANGLES; one unlit BLEND material, double-sided, or single-sided with
//!   every triangle in both windings when arranged for viewers ([`order`]: spatial chunks as
//!   nodes, ordered along each chunk's normal). With `--surfels` ([`surfels`]) each part's
//!   mesh gets a second primitive: opaque surfel fans with an unlit, double-sided OPAQUE material `surfels`.
//! * With [`ConvertOptions::coplanar_offset`] (on in `splatbridge convert`), every Gaussian's
//!   fans sit a hashed sub-millimetre step off its own plane, so that Cycles renders exactly
//!   coplanar splats (see [`classify`] for why and what it costs).
//! * `_GAUSSIAN_ID` (FLOAT SCALAR, exact for ids below 2²⁴; glTF forbids unsigned-int vertex
//!   attributes) is the Gaussian's index in [`DynamicScene::composite`] order: static
//!   Gaussians first, then each object's in order, then per-frame content. Every
//!   mesh's `extras.idOffset` says where its ids start.
//! * `asset.extras.splatbridge`: the options and counts ([`options::ConvertReport::metadata`]),
//!   with the surfel split's thresholds and counts under `surfels`.
//!
//! ## Blender
//! Blender 3.4 imports the BLEND material as Emission/Transparent mixed by `COLOR_0` alpha
//! (× the falloff texture's alpha) behind a Light Path "Is Camera Ray" switch; camera rays keep
//! that flag through transparent bounces, so Cycles composites the layers correctly. What the
//! file cannot carry (the view transform, a black world, enough transparent bounces, an
//! order-independent or sorted EEVEE blend, compositing display values rather than the linear
//! `COLOR_0`) is set by `scripts/blender-splat-setup.py`; `scripts/blender-render-compare.sh`
//! measures EEVEE and Cycles against native splatting.

pub mod chunked;
pub mod classify;
pub mod decimal;
pub mod frames_gltf;
pub mod frames_morph;
pub mod gltf_doc;
mod gltf_vertex;
pub mod gltf_writer;
pub mod mesh;
pub mod motion;
pub mod obj;
pub mod options;
pub mod order;
pub mod ply_mesh;
pub mod profile;
pub mod splats_gltf;
pub mod surfels;
pub mod texture;
pub mod tiles;
pub mod vertex_colours;

use std::io::Write;
use std::path::{Path, PathBuf};

use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::GaussianCloud;

pub use chunked::ChunkedMesh;
pub use mesh::{MeshSoup, Mesher};
pub use options::{
    ColorEncoding, ConvertOptions, ConvertReport, MeshCounts, Profile, UpAxis, VolumetricMode,
};
pub use profile::ProfileShape;

/// Errors of conversion and writing.
#[derive(Debug, thiserror::Error)]
pub enum ConvertError {
    /// I/O failure on a named file. The OS error is part of the message and deliberately not
    /// a `source`, so error chains (`{:#}`) print it once.
    #[error("{path}: {err}")]
    Io { path: PathBuf, err: std::io::Error },
    #[error("{path}: {what}")]
    Format { path: PathBuf, what: String },
    #[error("{0}")]
    Invalid(String),
    #[error(transparent)]
    Scene(#[from] splatbridge_scene::SceneError),
}

pub type Result<T, E = ConvertError> = std::result::Result<T, E>;

/// Content that changes per frame without a rigid track (e.g. weather particles): one cloud
/// per frame time, in the scene's world frame.
#[derive(Clone, Debug, Default)]
pub struct FrameClouds {
    /// Strictly increasing frame times in seconds.
    pub times: Vec<f64>,
    pub clouds: Vec<GaussianCloud>,
}

/// The per-frame content to mesh: the scene's own ([`DynamicScene::frames`], what a motion
/// decomposition kept per frame) and the caller's (weather particles), joined frame by frame
/// when both exist (their times must then be the same).
pub fn merged_frames<'a>(
    scene: &DynamicScene,
    frames: Option<&'a FrameClouds>,
) -> Result<Option<std::borrow::Cow<'a, FrameClouds>>> {
    use std::borrow::Cow;
    if scene.frames.is_empty() {
        return Ok(frames.map(Cow::Borrowed));
    }
    let mut own = FrameClouds {
        times: scene.frames.iter().map(|f| f.t).collect(),
        clouds: scene.frames.iter().map(|f| f.gaussians.clone()).collect(),
    };
    if let Some(fr) = frames {
        if fr.times != own.times {
            return Err(ConvertError::Invalid(format!(
                "the scene's per-frame content has {} frames from t = {}, the other per-frame \
                 content (weather) {} from t = {}: they must share their times",
                own.times.len(),
                own.times[0],
                fr.times.len(),
                fr.times.first().copied().unwrap_or(f64::NAN)
            )));
        }
        for (c, w) in own.clouds.iter_mut().zip(&fr.clouds) {
            if c.sh_degree < w.sh_degree {
                let mut up = GaussianCloud::new(w.sh_degree);
                up.extend_from(c, None);
                *c = up;
            }
            c.extend_from(w, None);
        }
    }
    Ok(Some(Cow::Owned(own)))
}

/// Which part of the scene a mesh stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    Static,
    Object(usize),
    Frame(usize),
}

/// One classified cloud and its place in the scene.
pub struct MeshEntry<'a> {
    pub role: Role,
    pub mesher: Mesher<'a>,
    /// The part's surfels (`--surfels`), written as a second, opaque primitive.
    pub surfels: Option<surfels::SurfelMesher<'a>>,
}

/// Classify every cloud of a scene (static, objects, per-frame content), apply the triangle
/// budget, and fill the report's counts.
pub fn prepare<'a>(
    scene: &'a DynamicScene,
    frames: Option<&'a FrameClouds>,
    opts: &ConvertOptions,
    shape: &'a ProfileShape,
    report: &mut ConvertReport,
) -> Result<Vec<MeshEntry<'a>>> {
    opts.validate()?;
    check_frames(frames)?;
    let mut clouds: Vec<Piece<'a>> = vec![Piece::whole(
        Role::Static,
        "static",
        &scene.static_gaussians,
    )];
    for (k, o) in scene.objects.iter().enumerate() {
        clouds.push(Piece::whole(Role::Object(k), &o.name, &o.gaussians));
    }
    if let Some(fr) = frames {
        for (k, c) in fr.clouds.iter().enumerate() {
            clouds.push(Piece::whole(Role::Frame(k), &format!("frame {k}"), c));
        }
    }
    prepare_pieces(clouds, scene, opts, shape, report)
}

/// Per-frame content has one cloud per time, times finite and strictly increasing.
fn check_frames(frames: Option<&FrameClouds>) -> Result<()> {
    if let Some(fr) = frames {
        if fr.times.len() != fr.clouds.len() {
            return Err(ConvertError::Invalid(format!(
                "per-frame content has {} times but {} clouds",
                fr.times.len(),
                fr.clouds.len()
            )));
        }
        if fr.times.windows(2).any(|w| !(w[1] > w[0])) || fr.times.iter().any(|t| !t.is_finite()) {
            return Err(ConvertError::Invalid(
                "per-frame content times must be finite and strictly increasing".into(),
            ));
        }
    }
    Ok(())
}

/// One cloud to mesh: a whole part of the scene, or a chunk of one with its global ids and
/// facing (`order.rs`).
pub(crate) struct Piece<'a> {
    pub role: Role,
    pub name: String,
    pub cloud: &'a GaussianCloud,
    pub ids: Option<&'a [u32]>,
    pub facing: order::Facing,
}

impl<'a> Piece<'a> {
    pub(crate) fn whole(role: Role, name: &str, cloud: &'a GaussianCloud) -> Self {
        Piece {
            role,
            name: name.into(),
            cloud,
            ids: None,
            facing: order::Facing::Template,
        }
    }

    /// A chunk of an arranged part.
    pub(crate) fn of_part(p: &'a order::Part) -> Self {
        Piece {
            role: p.role,
            name: p.name.clone(),
            cloud: &p.cloud,
            ids: Some(&p.ids),
            facing: p.facing,
        }
    }
}

/// [`prepare`] for a scene arranged for viewers ([`order::arrange_for`]): one entry per chunk.
pub fn prepare_arranged<'a>(
    parts: &'a [order::Part],
    scene: &'a DynamicScene,
    opts: &ConvertOptions,
    shape: &'a ProfileShape,
    report: &mut ConvertReport,
) -> Result<Vec<MeshEntry<'a>>> {
    opts.validate()?;
    let pieces = parts.iter().map(Piece::of_part).collect();
    prepare_pieces(pieces, scene, opts, shape, report)
}

fn prepare_pieces<'a>(
    clouds: Vec<Piece<'a>>,
    scene: &'a DynamicScene,
    opts: &ConvertOptions,
    shape: &'a ProfileShape,
    report: &mut ConvertReport,
) -> Result<Vec<MeshEntry<'a>>> {
    let mut offset = 0u64;
    let mut entries = Vec::with_capacity(clouds.len());
    for piece in clouds {
        entries.push(piece_entry(piece, scene, opts, shape, &mut offset)?);
    }
    if opts.gaussian_ids && offset > 1 << 24 {
        return Err(ConvertError::Invalid(format!(
            "{offset} Gaussians: _GAUSSIAN_ID is a float attribute, exact only below 2^24 = 16777216; convert without ids"
        )));
    }
    if let Some(max) = opts.max_triangles {
        let mut ms: Vec<&mut Mesher<'a>> = entries.iter_mut().map(|e| &mut e.mesher).collect();
        mesh::apply_budget(&mut ms, max);
    }
    for e in &entries {
        check_entry(e, report)?;
    }
    Ok(entries)
}

/// Classify one piece: its mesher, with `_GAUSSIAN_ID`s from `offset` for a whole part (or its
/// own id map), and `offset` advanced past its Gaussians.
pub(crate) fn piece_entry<'a>(
    piece: Piece<'a>,
    scene: &DynamicScene,
    opts: &ConvertOptions,
    shape: &'a ProfileShape,
    offset: &mut u64,
) -> Result<MeshEntry<'a>> {
    let Piece {
        role,
        name,
        cloud,
        ids,
        facing,
    } = piece;
    cloud.check_shape()?;
    let mut mesher = Mesher::new(cloud, shape, opts, &name, *offset);
    if let Some(ids) = ids {
        let first = ids.iter().copied().min().unwrap_or(0) as u64;
        mesher.set_id_map(ids, first)?;
        *offset = (*offset).max(ids.iter().copied().max().map_or(0, |m| m as u64 + 1));
    } else {
        *offset += cloud.len() as u64;
    }
    mesher.set_facing(facing);
    if let Role::Object(k) = role {
        let reach = scene.objects[k]
            .track
            .keys
            .iter()
            .map(|k| k.pose.translation.abs().max_element())
            .fold(0.0f32, f32::max);
        mesher.set_frame_reach(reach);
    }
    Ok(MeshEntry {
        role,
        mesher,
        surfels: None,
    })
}

/// A classified entry's vertices fit u32 indices; its counts go into the report.
pub(crate) fn check_entry(e: &MeshEntry<'_>, report: &mut ConvertReport) -> Result<()> {
    if e.mesher.counts.vertices >= u32::MAX as u64 {
        return Err(ConvertError::Invalid(format!(
            "{}: {} vertices do not fit u32 indices (4294967295 is reserved)",
            e.mesher.counts.name, e.mesher.counts.vertices
        )));
    }
    report.add(e.mesher.counts.clone());
    Ok(())
}

/// [`prepare`] for a scene split into surfels and residual Gaussians: the residual parts are
/// classified as usual (and keep their unsplit `_GAUSSIAN_ID`s), each entry gets its part's
/// surfels, and the report gets the split's counts (`gaussians_in` is the unsplit total).
pub fn prepare_split<'a>(
    split: &'a surfels::SplitScene,
    so: &surfels::SurfelOptions,
    opts: &ConvertOptions,
    shape: &'a ProfileShape,
    report: &mut ConvertReport,
) -> Result<Vec<MeshEntry<'a>>> {
    let mut entries = prepare(&split.residual, split.frames.as_ref(), opts, shape, report)?;
    debug_assert_eq!(entries.len(), split.parts.len());
    let mut sr = surfels::SurfelReport::new(so);
    let mut offset = 0u64;
    for (e, part) in entries.iter_mut().zip(&split.parts) {
        let n = (part.residual_ids.len() + part.surfel_ids.len()) as u64;
        e.mesher.set_id_map(&part.residual_ids, offset)?;
        let mut sm = surfels::SurfelMesher::new(part, so, opts, n);
        sm.set_frame_reach(e.mesher.frame_reach());
        sr.add(sm.counts.clone());
        if sm.counts.vertices >= u32::MAX as u64 {
            return Err(ConvertError::Invalid(format!(
                "{}: {} surfel vertices do not fit u32 indices",
                part.name, sm.counts.vertices
            )));
        }
        e.surfels = Some(sm);
        offset += n;
    }
    if opts.gaussian_ids && offset > 1 << 24 {
        return Err(ConvertError::Invalid(format!(
            "{offset} Gaussians: _GAUSSIAN_ID is a float attribute, exact only below 2^24 = 16777216; convert without ids"
        )));
    }
    for (m, e) in report.meshes.iter_mut().zip(&entries) {
        m.id_offset = e.mesher.counts.id_offset;
    }
    report.gaussians_in += sr.surfels;
    report.vertices += sr.vertices;
    report.triangles += sr.triangles;
    report.surfels = Some(sr);
    Ok(entries)
}

/// Classify a scene for the mesh writers: arranged for viewers when the options ask
/// ([`order::arrange_for`], owned by `parts`), split into surfels when they ask, else as is.
pub(crate) fn prepare_any<'a>(
    scene: &'a DynamicScene,
    frames: Option<&'a FrameClouds>,
    split: Option<&'a surfels::SplitScene>,
    parts: Option<&'a [order::Part]>,
    opts: &ConvertOptions,
    shape: &'a ProfileShape,
    report: &mut ConvertReport,
) -> Result<Vec<MeshEntry<'a>>> {
    match (split, &opts.surfels, parts) {
        (Some(s), Some(o), _) => prepare_split(s, o, opts, shape, report),
        (_, _, Some(p)) => {
            check_frames(frames)?;
            prepare_arranged(p, scene, opts, shape, report)
        }
        _ => prepare(scene, frames, opts, shape, report),
    }
}

/// The profile shape for the options.
pub fn shape_for(opts: &ConvertOptions) -> ProfileShape {
    ProfileShape::new(opts.profile, opts.segments(), opts.rings)
}

/// Mesh one cloud in memory (tests, in-memory consumers).
pub fn mesh_cloud(cloud: &GaussianCloud, opts: &ConvertOptions) -> Result<(MeshSoup, MeshCounts)> {
    opts.validate()?;
    cloud.check_shape()?;
    let shape = shape_for(opts);
    let mut m = Mesher::new(cloud, &shape, opts, "cloud", 0);
    if let Some(max) = opts.max_triangles {
        mesh::apply_budget(&mut [&mut m], max);
    }
    Ok((m.build(), m.counts.clone()))
}

/// Output formats by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Glb,
    Gltf,
    Obj,
    Ply,
}

impl Format {
    pub fn from_path(path: &Path) -> Result<Format> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "glb" => Ok(Format::Glb),
            "gltf" => Ok(Format::Gltf),
            "obj" => Ok(Format::Obj),
            "ply" => Ok(Format::Ply),
            _ => Err(ConvertError::Format {
                path: path.into(),
                what: format!(
                    "unknown output extension '{ext}' (expected .glb, .gltf, .obj or .ply)"
                ),
            }),
        }
    }
}

/// Write a scene as a mesh GLB into any writer (in-memory conversion for the ray tracer).
pub fn write_glb<W: Write>(
    w: &mut W,
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
) -> Result<ConvertReport> {
    let mut report = ConvertReport::new("glb", opts);
    let merged = merged_frames(scene, frames)?;
    let frames = merged.as_deref();
    let bytes = with_mesh_entries(
        scene,
        frames,
        opts,
        &mut report,
        |entries, scene, frames, report| {
            gltf_writer::write_glb(w, entries, scene, frames, opts, report).map_err(|e| {
                ConvertError::Io {
                    path: "<memory>".into(),
                    err: e,
                }
            })
        },
    )?;
    report.bytes = bytes;
    Ok(report)
}

/// Prepare the mesh entries of a glTF export (the surfel split and the viewer arrangement
/// when the options ask for them) and hand them to `write`, with the scene and frames they
/// were made from (the residual scene after a surfel split).
pub(crate) fn with_mesh_entries<T>(
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
    report: &mut ConvertReport,
    write: impl FnOnce(
        &[MeshEntry<'_>],
        &DynamicScene,
        Option<&FrameClouds>,
        &mut ConvertReport,
    ) -> Result<T>,
) -> Result<T> {
    let shape = shape_for(opts);
    let split = opts
        .surfels
        .as_ref()
        .map(|o| surfels::split_scene(scene, frames, o));
    let (scene, frames) = match &split {
        Some(s) => (&s.residual, s.frames.as_ref()),
        None => (scene, frames),
    };
    let parts = order::arrange_for(scene, frames, opts)?;
    let entries = prepare_any(
        scene,
        frames,
        split.as_ref(),
        parts.as_deref(),
        opts,
        &shape,
        report,
    )?;
    write(&entries, scene, frames, report)
}

/// A scene converted to GLB bytes in memory.
pub fn glb_bytes(
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
) -> Result<(Vec<u8>, ConvertReport)> {
    let mut v = Vec::new();
    let r = write_glb(&mut v, scene, frames, opts)?;
    Ok((v, r))
}

/// Convert a scene to a file; the format follows the extension. Writes are atomic. For OBJ,
/// `obj_frames` writes one OBJ per frame (`OUT_0000.obj`, …) at the scene's frame rate.
pub fn convert_to_file(
    path: &Path,
    scene: &DynamicScene,
    frames: Option<&FrameClouds>,
    opts: &ConvertOptions,
    obj_frames: bool,
) -> Result<ConvertReport> {
    let t0 = std::time::Instant::now();
    let format = Format::from_path(path)?;
    let merged = merged_frames(scene, frames)?;
    let frames = merged.as_deref();
    let mut report = match format {
        Format::Glb | Format::Gltf => {
            gltf_writer::write_file(path, format == Format::Glb, scene, frames, opts)?
        }
        Format::Obj | Format::Ply if opts.surfels.is_some() => {
            return Err(ConvertError::Format {
                path: path.into(),
                what: "surfel export writes glTF (.glb or .gltf): OBJ and PLY carry one material without alpha modes".into(),
            })
        }
        Format::Obj => obj::write_file(path, scene, frames, opts, obj_frames)?,
        Format::Ply => ply_mesh::write_file(path, scene, frames, opts)?,
    };
    report.seconds = t0.elapsed().as_secs_f64();
    Ok(report)
}

pub(crate) fn io_err(path: &Path) -> impl Fn(std::io::Error) -> ConvertError + '_ {
    move |e| ConvertError::Io {
        path: path.into(),
        err: e,
    }
}

pub(crate) fn scene_err(e: splatbridge_scene::SceneError) -> ConvertError {
    ConvertError::Scene(e)
}
