//! `convert`'s value enums and how its arguments map to the library's [`ExportRequest`].

use anyhow::bail;
use clap::ValueEnum;
use splatbridge::pipeline::export::OutputFormat;
use splatbridge::pipeline::export_request::{ExportRequest, MeshRequest};
use splatbridge_convert::options::ChunkOrder;
use splatbridge_convert::splats_gltf::KhrCompression;
use splatbridge_convert::{ColorEncoding, ConvertOptions, Profile, UpAxis, VolumetricMode};

use super::Args;
use crate::cmd::hybrid::SplitMode;

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ProfileArg {
    /// MeshSplats baseline: 8-vertex rim at 2.7σ, rim alpha 0.2·opacity.
    Meshsplats,
    /// Concentric rings following opacity·exp(−r²/2) out to the 1/255 footprint.
    Rings,
    /// One textured quad per fan; a shared radial falloff texture carries the profile.
    Texture,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum VolumetricArg {
    /// Three orthogonal fans with an optical-depth correction.
    ThreeFans,
    /// One fan in the plane of the two largest axes.
    Flat,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum UpArg {
    /// Input is Y-up already.
    Y,
    /// Input is Z-up.
    Z,
    /// Input up is −Y (COLMAP / 3DGS captures).
    #[value(name = "-y")]
    NegY,
}

/// Output formats for `--format` (overriding the extension of -o).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// The 3DGS PLY, or a mesh PLY with --mesh or --profile.
    Ply,
    /// The standard 3DGS PLY (lossless splats).
    SplatPly,
    /// SuperSplat/PlayCanvas compressed PLY.
    CompressedPly,
    /// antimatter15 .splat.
    Splat,
    /// Niantic SPZ (--spz-version).
    Spz,
    /// GaussianSplats3D .ksplat (--ksplat-level).
    Ksplat,
    /// Binary glTF (mesh, or KHR_gaussian_splatting with --splats).
    Glb,
    /// glTF JSON + .bin (mesh, or KHR_gaussian_splatting with --splats).
    Gltf,
    /// Wavefront OBJ mesh.
    Obj,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LayoutArg {
    /// For stock viewers that blend in file order (three.js, Babylon.js, EEVEE): spatial
    /// chunks as nodes, each ordered along its normal, both windings single-sided, no NORMAL.
    Viewer,
    /// One node per scene part in the input's order, doubleSided material, with NORMAL.
    Input,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ChunkOrderArg {
    /// The input's order.
    Input,
    /// Along each chunk's dominant normal.
    Normal,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum WindingsArg {
    /// Every triangle twice (both windings) with a single-sided material.
    Both,
    /// One winding and a doubleSided material.
    Double,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ColorArg {
    /// glTF's linear COLOR_0 (display colours sRGB-decoded).
    Linear,
    /// 3DGS display values written as they are.
    Display,
}

impl From<FormatArg> for OutputFormat {
    fn from(f: FormatArg) -> Self {
        match f {
            FormatArg::Ply => OutputFormat::Ply,
            FormatArg::SplatPly => OutputFormat::SplatPly,
            FormatArg::CompressedPly => OutputFormat::CompressedPly,
            FormatArg::Splat => OutputFormat::Splat,
            FormatArg::Spz => OutputFormat::Spz,
            FormatArg::Ksplat => OutputFormat::Ksplat,
            FormatArg::Glb => OutputFormat::Glb,
            FormatArg::Gltf => OutputFormat::Gltf,
            FormatArg::Obj => OutputFormat::Obj,
        }
    }
}

/// `--khr-compression`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum KhrCompressionArg {
    /// Float accessors.
    None,
    /// KHR_gaussian_splatting_compression_spz_2.
    Spz,
}

impl Args {
    /// The options `convert` and `convert --tiles` share (profile, up axis, colour encoding,
    /// ids); `default_profile` is used when `--profile` is not given.
    pub fn base_options(&self, default_profile: Profile) -> ConvertOptions {
        ConvertOptions {
            profile: match self.profile {
                Some(ProfileArg::Meshsplats) => Profile::MeshSplats,
                Some(ProfileArg::Rings) => Profile::Rings,
                Some(ProfileArg::Texture) => Profile::Texture,
                None => default_profile,
            },
            up: match self.up {
                UpArg::Y => UpAxis::Y,
                UpArg::Z => UpAxis::Z,
                UpArg::NegY => UpAxis::NegY,
            },
            color_encoding: match self.color_encoding {
                ColorArg::Linear => ColorEncoding::Linear,
                ColorArg::Display => ColorEncoding::Display,
            },
            gaussian_ids: !self.no_ids,
            ..Default::default()
        }
    }

    /// The library's request for these arguments (refusing the combinations clap cannot).
    pub fn request(&self) -> anyhow::Result<ExportRequest> {
        if self.khr_compression != KhrCompressionArg::None && !self.splats {
            bail!("--khr-compression: applies to --splats glTF outputs only");
        }
        let guarded = match self.surfel_split {
            SplitMode::Guarded => true,
            SplitMode::Thresholds => false,
            SplitMode::Auto => bail!(
                "--surfel-split auto: an export has no renderer to measure it with; use guarded or thresholds"
            ),
        };
        let default_profile = splatbridge::pipeline::export_request::default_profile(&self.output);
        let options = ConvertOptions {
            segments: self.segments,
            rings: self.rings,
            volumetric: match self.volumetric {
                VolumetricArg::ThreeFans => VolumetricMode::ThreeFans,
                VolumetricArg::Flat => VolumetricMode::Flat,
            },
            flat_ratio: self.flat_ratio,
            max_triangles: self.max_triangles,
            coplanar_offset: !self.no_coplanar_offset,
            surfels: self
                .surfels
                .then_some(splatbridge_convert::surfels::SurfelOptions {
                    min_opacity: self.surfel_opacity,
                    max_flatness: self.surfel_flatness,
                    segments: self.surfel_segments,
                    guarded,
                }),
            ..self.base_options(default_profile)
        };
        Ok(ExportRequest {
            input: self.scene.clone(),
            output: self.output.clone(),
            format: self.format.map(OutputFormat::from),
            splats: self.splats,
            khr_compression: match self.khr_compression {
                KhrCompressionArg::None => KhrCompression::None,
                KhrCompressionArg::Spz => KhrCompression::Spz,
            },
            spz_version: self.spz_version,
            ksplat_level: self.ksplat_level,
            mesh_asked: self.mesh || self.profile.is_some(),
            time: self.time,
            first: self.first,
            frames: self.frames,
            shard: self.shard,
            drop_invalid: self.drop_invalid,
            cameras: self.camera.clone(),
            footprint_for: self.footprint_for,
            mesh: MeshRequest {
                options,
                surfels: self.surfels,
                viewer_layout: self.layout == LayoutArg::Viewer,
                chunk_size: self.chunk_size,
                chunk_order: self.chunk_order.map(|o| match o {
                    ChunkOrderArg::Input => ChunkOrder::Input,
                    ChunkOrderArg::Normal => ChunkOrder::Normal,
                }),
                both_windings: self.windings.map(|w| matches!(w, WindingsArg::Both)),
                normals: self.normals,
                view_order: self.view_order.clone(),
                bake_view: self.bake_view.clone(),
            },
            distill: self.distill.distill,
        })
    }
}
