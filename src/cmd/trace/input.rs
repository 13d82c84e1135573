//! `trace`'s input options (shared with `bench trace`) and the library's [`TraceSource`]
//! they describe.

use std::path::PathBuf;

use glam::Vec3;
use splatbridge::pipeline::{Prepared, TraceMode, TraceSource};
use splatbridge_convert::Profile;
use splatbridge_raytrace::{
    BackendKind, BuildPreset, Compositing, Footprint, HitOrder, RenderOptions, SampleFootprint,
    ShDirection,
};

use crate::cmd::common::{parse_rgb, print_warning, CameraArgs};

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Composite every triangle hit front to back (what the exported file shows).
    Mesh,
    /// Ray-trace the Gaussians themselves (needs a PLY or manifest).
    Gaussian,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendArg {
    Obvhs,
    Embree,
}

impl From<BackendArg> for BackendKind {
    fn from(b: BackendArg) -> Self {
        match b {
            BackendArg::Obvhs => BackendKind::Obvhs,
            BackendArg::Embree => BackendKind::Embree,
        }
    }
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PresetArg {
    Fastest,
    VeryFast,
    Fast,
    Medium,
}

impl From<PresetArg> for BuildPreset {
    fn from(p: PresetArg) -> Self {
        match p {
            PresetArg::Fastest => BuildPreset::Fastest,
            PresetArg::VeryFast => BuildPreset::VeryFast,
            PresetArg::Fast => BuildPreset::Fast,
            PresetArg::Medium => BuildPreset::Medium,
        }
    }
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompositingArg {
    /// Blend display values like native splatting (glTF's linear colours encoded per hit).
    Display,
    /// Blend in linear light and encode the result, as viewers show the file.
    Viewer,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FootprintArg {
    /// Each Gaussian widened in 3-D by the ray's pixel footprint (native's 0.3-px low-pass).
    On,
    /// The exact point-sampled 3-D response (3DGRT's).
    Off,
    /// Each Gaussian evaluated as native's projection does (EWA 2-D conic at the pixel).
    Projected,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OrderArg {
    /// By the distance of maximum response along the ray (3DGRT's).
    Hit,
    /// By the view depth of the Gaussian's mean (native's sort).
    MeanDepth,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShDirectionArg {
    /// The ray's direction (3DGRT's).
    Ray,
    /// From the camera toward the Gaussian's mean (native's).
    Mean,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleFootprintArg {
    /// Each of N samples carries its sub-pixel's footprint (0.3/N px²).
    Subpixel,
    /// Each sample carries the whole pixel's footprint (0.3 px²).
    Pixel,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProfileArg {
    Meshsplats,
    Rings,
    Texture,
}

/// What is traced, shared with `bench trace`.
#[derive(clap::Args, Clone, Debug)]
pub struct TraceInput {
    #[arg(
        help = "A GLB, glTF or OBJ mesh, traced as exported (a .glb or .gltf is read as a mesh, so \
                the Gaussians of a glTF with KHR_gaussian_splatting are not traced: convert it to \
                .ply first), or a scene: a 3DGS PLY (also 2DGS, Mip-Splatting and red-green-blue \
                point PLYs), a compressed PLY, .splat, .spz, .ksplat, SOG (a folder's \
                meta.json or a .sog zip), or a splatbridge-scene/1 manifest (JSON)."
    )]
    pub input: PathBuf,
    #[command(flatten)]
    pub camera: CameraArgs,
    /// Scene time in seconds (animated files and manifests).
    #[arg(long, default_value_t = 0.0, value_parser = crate::cmd::ranges::time, allow_hyphen_values = true)]
    pub time: f64,
    /// mesh: composite the triangles; gaussian: ray-trace the Gaussians (PLY/manifest input).
    #[arg(long, value_enum, default_value_t = Mode::Mesh)]
    pub mode: Mode,
    /// k-buffer size: hits gathered per traversal before compositing and resuming.
    #[arg(long, default_value_t = 16, value_parser = crate::cmd::ranges::k_buffer)]
    pub k: usize,
    /// BVH build preset (none pre-splits triangles).
    #[arg(long, value_enum, default_value_t = PresetArg::Medium)]
    pub preset: PresetArg,
    /// Background colour R,G,B in [0, 1].
    #[arg(long, value_parser = parse_rgb, default_value = "0,0,0")]
    pub background: Vec3,
    /// Mode gaussian: cull Gaussians whose mean is at view depth ≤ NEAR (reference 0.2).
    #[arg(long, default_value_t = 0.2)]
    pub near: f32,
    /// Mode mesh: display (compare with native splatting) or viewer (as Blender shows it).
    #[arg(long, value_enum, default_value_t = CompositingArg::Display)]
    pub compositing: CompositingArg,
    /// Mode gaussian: primary rays carry their pixel footprint, widening each Gaussian like
    /// native splatting's 0.3-pixel low-pass: on (3-D, default in mode gaussian), off, or
    /// projected (native's 2-D conic at the pixel). Mode mesh has none.
    #[arg(long, value_enum)]
    pub footprint: Option<FootprintArg>,
    /// Mode gaussian: order of a primary ray's hits: hit (3DGRT's t*) or mean-depth (native's;
    /// the default with a footprint, hit with --footprint off).
    #[arg(long, value_enum)]
    pub order: Option<OrderArg>,
    /// Mode gaussian: SH direction of a primary ray's hits: ray (3DGRT's) or mean (camera
    /// toward the mean, native's; the default with a footprint, ray with --footprint off).
    #[arg(long, value_enum)]
    pub sh_direction: Option<ShDirectionArg>,
    /// Samples per pixel (both modes): a fixed stratified pattern (k×k grid when N = k²),
    /// box-filtered; 1 samples the pixel centre.
    #[arg(long, default_value_t = 1, value_parser = crate::cmd::ranges::spp)]
    pub spp: u32,
    /// With --spp > 1 and the footprint on: the sub-pixel's footprint or the whole pixel's.
    #[arg(long, value_enum, default_value_t = SampleFootprintArg::Subpixel)]
    pub sample_footprint: SampleFootprintArg,
    /// Keep the glTF world frame of a splatbridge export (default: the capture's frame).
    #[arg(long)]
    pub gltf_frame: bool,
    /// Converter profile for PLY/manifest input in mode mesh (default: the converter's).
    #[arg(long, value_enum)]
    pub profile: Option<ProfileArg>,
    /// Drop invalid Gaussians with a warning instead of failing (PLY/manifest input).
    #[arg(long)]
    pub drop_invalid: bool,
    /// For an exported file (GLB/glTF/OBJ): take the declared effects, time range and cameras
    /// of this manifest (the scene it was exported from).
    #[arg(long, value_name = "MANIFEST")]
    pub effects_from: Option<PathBuf>,
}

impl TraceInput {
    /// The library's description of this input.
    pub fn source(&self) -> anyhow::Result<TraceSource> {
        Ok(TraceSource {
            input: self.input.clone(),
            camera: self.camera.request()?,
            time: self.time,
            mode: match self.mode {
                Mode::Mesh => TraceMode::Mesh,
                Mode::Gaussian => TraceMode::Gaussian,
            },
            options: RenderOptions {
                k: self.k,
                background: self.background,
                min_transmittance: 1e-4,
                near: self.near,
                compositing: match self.compositing {
                    CompositingArg::Display => Compositing::Display,
                    CompositingArg::Viewer => Compositing::Viewer,
                },
                footprint: self.footprint(),
                order: match self.order {
                    Some(OrderArg::Hit) => HitOrder::Hit,
                    Some(OrderArg::MeanDepth) => HitOrder::MeanDepth,
                    // With a footprint the trace is the parity mode: native's order too.
                    None if self.footprint() != Footprint::Off => HitOrder::MeanDepth,
                    None => HitOrder::Hit,
                },
                sh_direction: match self.sh_direction {
                    Some(ShDirectionArg::Ray) => ShDirection::Ray,
                    Some(ShDirectionArg::Mean) => ShDirection::Mean,
                    None => ShDirection::for_footprint(self.footprint()),
                },
                spp: self.spp,
                sample_footprint: match self.sample_footprint {
                    SampleFootprintArg::Subpixel => SampleFootprint::Subpixel,
                    SampleFootprintArg::Pixel => SampleFootprint::Pixel,
                },
            },
            gltf_frame: self.gltf_frame,
            profile: self.profile.map(|p| match p {
                ProfileArg::Meshsplats => Profile::MeshSplats,
                ProfileArg::Rings => Profile::Rings,
                ProfileArg::Texture => Profile::Texture,
            }),
            drop_invalid: self.drop_invalid,
            effects_from: self.effects_from.clone(),
        })
    }

    /// `--footprint`, defaulting to on in mode gaussian (the parity mode) and off in mode mesh
    /// (triangles are not widened).
    pub fn footprint(&self) -> Footprint {
        match (self.footprint, self.mode) {
            (Some(FootprintArg::On), _) | (None, Mode::Gaussian) => Footprint::On,
            (Some(FootprintArg::Off), _) | (None, Mode::Mesh) => Footprint::Off,
            (Some(FootprintArg::Projected), _) => Footprint::Projected,
        }
    }

    pub fn prepare(&self) -> anyhow::Result<Prepared> {
        self.prepare_with(false)
    }

    /// As [`TraceInput::prepare`]; `all_weather_frames` converts every frame's weather (mode
    /// mesh), for scanning every frame, instead of the traced frame's only.
    pub fn prepare_with(&self, all_weather_frames: bool) -> anyhow::Result<Prepared> {
        self.source()?.prepare(all_weather_frames, &print_warning)
    }
}
