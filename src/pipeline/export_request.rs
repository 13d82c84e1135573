//! What `convert` asks of an export, checked and resolved in the order the command line reads
//! it: the output format, the input loaded (with embedded cameras and, for `--footprint-for`,
//! the Gaussians widened), then either a single-cloud splat file or the mesh options (layout,
//! chunking, view order, baked view) and the export itself. Every refusal happens before a
//! byte is written. The command maps its arguments into an [`ExportRequest`] and prints what
//! these calls return.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use splatbridge_convert::options::{ChunkOrder, VolumetricMode};
use splatbridge_convert::splats_gltf::KhrCompression;
use splatbridge_convert::{ConvertOptions, ConvertReport, Profile};
use splatbridge_distill::footprint::{widen_scene_for, LowPass, Widened};
use splatbridge_scene::camera_spec::{CameraRequest, CameraSource};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::effects::EffectCounters;
use splatbridge_scene::formats::CloudFormat;
use splatbridge_scene::ply::GaussianKind;
use splatbridge_scene::Camera;

use super::export::{
    cloud_format, embedded_cameras, export_scene, is_gltf, load_export_input_kind,
    ply_holds_gaussians, write_cloud_export, CloudExport, ExportKind, OutputFormat,
};
use super::export_shard::export_obj_frames_shard;
use crate::batch::shard::Shard;

/// One `convert` run (without `--tiles`), in the library's terms.
#[derive(Clone, Debug)]
pub struct ExportRequest {
    pub input: PathBuf,
    pub output: PathBuf,
    /// `--format`, instead of the one the output's extension implies.
    pub format: Option<OutputFormat>,
    /// Native glTF splats (or the 3DGS PLY for `.ply`) instead of a mesh.
    pub splats: bool,
    pub khr_compression: KhrCompression,
    pub spz_version: u32,
    /// `.ksplat` compression level (0, 1 or 2).
    pub ksplat_level: u8,
    /// A mesh was asked for (`--mesh` or `--profile`): a `.ply` output is then a triangle mesh
    /// PLY instead of the 3DGS PLY.
    pub mesh_asked: bool,
    /// Single-cloud outputs: the time the scene is composited at, and a cut to the first N.
    pub time: Option<f64>,
    pub first: Option<usize>,
    /// One OBJ per frame, and the shard of those frames written.
    pub frames: bool,
    pub shard: Option<Shard>,
    pub drop_invalid: bool,
    /// `--camera` lists embedded in glTF outputs (replacing the scene's own).
    pub cameras: Vec<String>,
    /// `--footprint-for WxH`.
    pub footprint_for: Option<(u32, u32)>,
    pub mesh: MeshRequest,
    /// `--distill` (fitted by the caller between [`ExportRequest::mesh_options`] and
    /// [`ExportRequest::export`]).
    pub distill: bool,
}

/// The mesh options as asked: `options` holds the profile's knobs; the layout settings below
/// are applied over them by [`ExportRequest::mesh_options`].
#[derive(Clone, Debug, Default)]
pub struct MeshRequest {
    pub options: ConvertOptions,
    pub surfels: bool,
    /// `--layout viewer` (glTF meshes without surfels get [`ConvertOptions::for_viewers`]).
    pub viewer_layout: bool,
    pub chunk_size: Option<usize>,
    pub chunk_order: Option<ChunkOrder>,
    /// `--windings`: `Some(true)` both windings, `Some(false)` one and a doubleSided material.
    pub both_windings: Option<bool>,
    pub normals: Option<bool>,
    pub view_order: Option<String>,
    pub bake_view: Option<String>,
}

/// The loaded input of an export.
pub struct ExportInput {
    pub scene: DynamicScene,
    /// The single-cloud splat format the output asks for, if any.
    pub cloud: Option<CloudFormat>,
    /// What `--footprint-for` widened.
    pub widened: Option<Widened>,
    /// What the input's Gaussians are: 2DGS surfels become one fan each in their own plane.
    pub kind: GaussianKind,
}

/// The meshing profile when none is asked for: texture for glTF, which carries textures;
/// rings for OBJ and PLY, which carry none.
pub fn default_profile(output: &Path) -> Profile {
    if is_gltf(output) {
        Profile::Texture
    } else {
        Profile::Rings
    }
}

/// A camera spec (`orbit:N:I`, `scene:I`, `PATH.json:I`) with the command line's defaults
/// (640×480, 50° field of view, up −y), orbits framing the scene's composite at its start.
pub fn resolve_spec(spec: &str, scene: &DynamicScene, what: &str) -> anyhow::Result<Camera> {
    let composite = scene.composite_view(scene.time.start);
    let resolve = || -> anyhow::Result<Camera> {
        Ok(CameraRequest::new(spec.parse()?).resolve(CameraSource {
            cloud: &composite,
            own: &scene.cameras,
        })?)
    };
    resolve().with_context(|| format!("{what} {spec}"))
}

impl ExportRequest {
    /// Whether the output is a glTF mesh (not splats).
    pub fn gltf_mesh(&self) -> bool {
        is_gltf(&self.output) && !self.splats
    }

    /// The output format, the loaded scene with its embedded cameras, and the footprint
    /// widening (`warn` gets the readers' warnings).
    pub fn load(&self, warn: &dyn Fn(&str)) -> anyhow::Result<ExportInput> {
        let cloud = cloud_format(
            &self.output,
            self.format,
            ply_holds_gaussians(self.splats, self.mesh_asked),
            self.spz_version,
            self.ksplat_level,
        )?;
        let (mut scene, kind) = load_export_input_kind(&self.input, self.drop_invalid, warn)?;
        if !self.cameras.is_empty() {
            scene.cameras = embedded_cameras(&self.cameras, &scene)?;
        }
        if self.first.is_some() && cloud.is_none() {
            bail!("--first applies to single-cloud splat outputs (.ply without --mesh, .splat, .spz, .ksplat, .compressed.ply)");
        }
        let widened = match self.footprint_for {
            Some(_) if cloud.is_some() => bail!("--footprint-for: widens Gaussians for a mesh export; a splat output keeps the Gaussians native splatting filters itself"),
            Some((w, h)) => {
                // A 2DGS file's mesh stands in for 2DGS's own filter, anything else's for
                // 3DGS splatting's: the renderer `render --model auto` takes for it.
                let low_pass = match kind {
                    GaussianKind::Surfels2D => LowPass::Surfel2d,
                    GaussianKind::Gaussians3D | GaussianKind::Points => LowPass::Splat3d,
                };
                Some(
                    widen_scene_for(&mut scene, w, h, low_pass)
                        .map_err(|e| anyhow::anyhow!("--footprint-for: {e}"))?,
                )
            }
            None => None,
        };
        Ok(ExportInput {
            scene,
            cloud,
            widened,
            kind,
        })
    }

    /// Write a single-cloud splat file (refusing the options that apply to meshes only).
    pub fn write_cloud(
        &self,
        scene: DynamicScene,
        format: CloudFormat,
        kind: GaussianKind,
    ) -> anyhow::Result<CloudExport> {
        let m = &self.mesh;
        for (set, name) in [
            (m.surfels, "--surfels"),
            (self.frames, "--frames"),
            (m.bake_view.is_some(), "--bake-view"),
            (m.options.max_triangles.is_some(), "--max-triangles"),
        ] {
            if set {
                bail!(
                    "{}: {name} applies to meshes, not to a {} output",
                    self.output.display(),
                    format.name()
                );
            }
        }
        write_cloud_export(scene, &self.output, format, self.time, self.first, kind)
    }

    /// The converter options for a mesh or glTF splat export of `scene`, with every
    /// combination the output cannot hold refused.
    pub fn mesh_options(
        &self,
        scene: &DynamicScene,
        kind: GaussianKind,
    ) -> anyhow::Result<ConvertOptions> {
        let m = &self.mesh;
        let out = self.output.display();
        let mut opts = m.options.clone();
        if kind == GaussianKind::Surfels2D {
            // A 2DGS surfel is a disc: one fan in its own plane, never three.
            opts.volumetric = VolumetricMode::Flat;
        }
        if m.surfels && (self.splats || !is_gltf(&self.output)) {
            let what = if self.splats {
                "--splats"
            } else {
                "OBJ or PLY"
            };
            bail!("{out}: --surfels writes a mesh glTF (.glb or .gltf), not {what}");
        }
        let gltf_mesh = self.gltf_mesh();
        if gltf_mesh && m.viewer_layout && !m.surfels {
            opts = opts.for_viewers();
        }
        if let Some(n) = m.chunk_size {
            opts.chunk_size = n;
        }
        if let Some(o) = m.chunk_order {
            opts.chunk_order = o;
        }
        if let Some(both) = m.both_windings {
            opts.both_windings = both;
        }
        if let Some(n) = m.normals {
            opts.normals = n;
        }
        if let Some(spec) = &m.view_order {
            let cam = resolve_spec(spec, scene, "--view-order")?;
            opts.view_order_name = Some(format!("{spec} ({})", cam.name));
            opts.view_order = Some(cam);
            if m.both_windings.is_none() {
                opts.both_windings = true;
            }
        }
        if opts.arranged() && !gltf_mesh {
            bail!("{out}: --chunk-size, --chunk-order, --windings and --view-order arrange glTF meshes (.glb or .gltf without --splats)");
        }
        if let Some(spec) = &m.bake_view {
            let cam = resolve_spec(spec, scene, "--bake-view")?;
            opts.bake_view_name = Some(format!("{spec} ({})", cam.name));
            opts.bake_view = Some(cam);
        }
        if self.frames && !is_obj(&self.output) && !(gltf_mesh && !scene.frames.is_empty()) {
            bail!("{out}: --frames writes one OBJ per frame; use an .obj output");
        }
        if self.shard.is_some() && !self.frames {
            bail!("--shard: applies to --frames and --tiles");
        }
        if self.shard.is_some() && self.splats {
            bail!("--shard splits --frames OBJ exports, not --splats");
        }
        if self.distill && (!gltf_mesh || self.frames) {
            bail!("{out}: --distill fits a mesh glTF (.glb or .gltf without --splats)");
        }
        Ok(opts)
    }

    /// Write the mesh or glTF splat export of `scene` with `opts` (a shard of its OBJ frames
    /// with `shard`): the converter's report and the effect counters.
    pub fn export(
        &self,
        scene: &DynamicScene,
        opts: &ConvertOptions,
    ) -> anyhow::Result<(ConvertReport, EffectCounters)> {
        let kind = if self.splats {
            ExportKind::Splats(self.khr_compression)
        } else {
            ExportKind::Mesh {
                frames: self.frames,
            }
        };
        match self.shard {
            Some(shard) => export_obj_frames_shard(scene, &self.input, &self.output, opts, shard),
            None => export_scene(scene, &self.input, &self.output, opts, kind),
        }
    }
}

/// Whether `p` names an OBJ file (any case).
pub fn is_obj(p: &Path) -> bool {
    p.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"))
}
