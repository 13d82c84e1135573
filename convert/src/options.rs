//! Conversion options and the conversion report.
//!
//! Every knob that shapes the output is a field of [`ConvertOptions`]; the options and the
//! counts of [`ConvertReport`] are written into the output's metadata (glTF `asset.extras`,
//! a comment in OBJ and PLY), so a file says how it was made.

use serde::{Deserialize, Serialize};
use splatbridge_scene::Camera;

/// How one Gaussian becomes triangles.
///
/// The default is `texture`: head-on, the relative L2 error of one flat Gaussian's alpha
/// footprint against the rasterizer's `o·exp(−r²/2)` (cut at 1/255), averaged over opacities
/// 0.1–1 (test `profile_footprint_errors_per_triangle`), is
///
/// | profile | triangles (flat) | error |
/// |---|---|---|
/// | meshsplats n=8 | 8 | 0.494 |
/// | rings n=8 m=2 | 24 | 0.211 |
/// | rings n=8 m=3 | 40 | 0.102 |
/// | rings n=16 m=3 | 80 | 0.096 |
/// | texture quad | 2 | 0.009 |
///
/// so the textured quad is both the most accurate and the cheapest per Gaussian wherever the
/// client multiplies texture alpha by vertex alpha (glTF's `baseColorTexture × COLOR_0`;
/// verified for Blender 3.4's importer, which builds `texture alpha × vertex alpha`). OBJ and
/// PLY carry no texture, so the CLI defaults to `rings` for them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// The published MeshSplats converter: n rim vertices at 2.7σ, centre alpha = opacity,
    /// rim alpha = 0.2·opacity (a cone cut at 20 %), no opacity-aware extent. The baseline.
    MeshSplats,
    /// Concentric rings whose radii and alphas follow opacity·exp(−r²/2) out to the 1/255
    /// footprint (see `profile.rs` for the error bound).
    Rings,
    /// One polygon (a quad by default) per fan with texture coordinates into a shared radial
    /// falloff texture; the vertex colour carries colour and opacity.
    #[default]
    Texture,
}

impl Profile {
    pub fn name(self) -> &'static str {
        match self {
            Profile::MeshSplats => "meshsplats",
            Profile::Rings => "rings",
            Profile::Texture => "texture",
        }
    }

    /// Segments per fan when the user gives none.
    pub fn default_segments(self) -> usize {
        match self {
            Profile::MeshSplats | Profile::Rings => 8,
            Profile::Texture => 4,
        }
    }
}

/// What to do with Gaussians that are not flat.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum VolumetricMode {
    /// Three orthogonal fans sharing the centre and the axis vertices.
    #[default]
    ThreeFans,
    /// One fan in the plane of the two largest axes, whatever the shape.
    Flat,
}

/// The input's up axis. The root node rotates it onto glTF's +Y; vertices are not touched.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum UpAxis {
    /// Input is already Y-up: identity root.
    #[serde(rename = "y")]
    Y,
    /// Input is Z-up (many photogrammetry tools): root rotates −90° about X.
    #[serde(rename = "z")]
    Z,
    /// Input up is −Y (COLMAP and most 3DGS captures: y points down): root rotates 180° about X.
    #[default]
    #[serde(rename = "-y")]
    NegY,
}

impl UpAxis {
    /// The root rotation taking the input frame to glTF's Y-up frame (x, y, z, w).
    pub fn root_rotation(self) -> glam::Quat {
        match self {
            UpAxis::Y => glam::Quat::IDENTITY,
            UpAxis::Z => glam::Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2),
            UpAxis::NegY => glam::Quat::from_xyzw(1.0, 0.0, 0.0, 0.0),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            UpAxis::Y => "y",
            UpAxis::Z => "z",
            UpAxis::NegY => "-y",
        }
    }
}

/// How vertex colours are encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ColorEncoding {
    /// glTF's rule: `COLOR_0` is linear. 3DGS colours are display (sRGB-encoded) values, so
    /// they are decoded with the sRGB transfer function; viewers re-encode on display and
    /// show the trained colour. A renderer that wants to composite like native splatting
    /// re-encodes each vertex colour before blending.
    #[default]
    Linear,
    /// The display values as 3DGS computes them, unchanged (viewers show them too bright).
    Display,
}

/// The order of Gaussians inside a mesh node (see `order.rs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ChunkOrder {
    /// The input's order.
    #[default]
    Input,
    /// Ascending along the node's dominant normal: back to front for views from its +normal
    /// side (and, with both windings, the reverse copy for the other side).
    Normal,
}

/// Default smallest/middle scale ratio at or above which a Gaussian counts as volumetric.
///
/// 0.3: below it the thickness is under 30 % of the width, so seen edge-on the single fan
/// misses at most a sliver 0.3 wide of a footprint that is mostly seen from the front; above
/// it the three-fan form (3× the triangles) pays for itself from oblique views.
pub const DEFAULT_FLAT_RATIO: f32 = 0.3;

/// Everything that shapes a conversion.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ConvertOptions {
    pub profile: Profile,
    /// Segments per fan; `None` takes the profile's default (8, or 4 for `texture`).
    pub segments: Option<usize>,
    /// Rings per fan (profile `rings`).
    pub rings: usize,
    pub volumetric: VolumetricMode,
    /// Smallest/middle scale ratio at or above which a Gaussian is volumetric.
    pub flat_ratio: f32,
    pub up: UpAxis,
    /// Keep the highest-scoring Gaussians within this many triangles (score in `budget.rs`).
    pub max_triangles: Option<u64>,
    /// Bake view-dependent colour for this camera instead of the DC term.
    #[serde(skip)]
    pub bake_view: Option<Camera>,
    /// Name of the baked camera, for the metadata.
    pub bake_view_name: Option<String>,
    pub color_encoding: ColorEncoding,
    /// Write the `_GAUSSIAN_ID` vertex attribute (glTF) / `gaussian_id` property (PLY).
    pub gaussian_ids: bool,
    /// Move each Gaussian's fans along its normal by a tiny hashed amount so that exactly
    /// coplanar splats stay visible to ray tracers that continue from the last hit (Cycles);
    /// see `classify.rs` for what it costs. Off here, on in `splatbridge convert`.
    #[serde(default)]
    pub coplanar_offset: bool,
    /// Split off opaque surfels and write them with their own OPAQUE material (glTF only;
    /// see `surfels.rs`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surfels: Option<crate::surfels::SurfelOptions>,
    /// Split the static Gaussians into mesh nodes of at most this many (median cuts; 0: one
    /// node), so that viewers sorting objects get the coarse order right.
    #[serde(default)]
    pub chunk_size: usize,
    /// The order inside each node.
    #[serde(default)]
    pub chunk_order: ChunkOrder,
    /// A single-sided material with every triangle in both windings (each view draws one copy,
    /// in one pass) instead of a `doubleSided` material (drawn in two passes by three.js).
    #[serde(default)]
    pub both_windings: bool,
    /// Write the NORMAL attribute (unlit materials never read it).
    #[serde(default = "yes")]
    pub normals: bool,
    /// Sort every part far to near for this camera (one node per part, both windings facing
    /// it first); overrides the chunking.
    #[serde(skip)]
    pub view_order: Option<Camera>,
    /// Name of the view-order camera, for the metadata.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view_order_name: Option<String>,
    /// Replace the profile's vertex colours with these (mesh distillation).
    #[serde(skip)]
    pub vertex_colours: Option<std::sync::Arc<crate::vertex_colours::VertexColours>>,
    /// How the vertex colours were fitted, for the metadata (mesh distillation).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distilled: Option<String>,
}

fn yes() -> bool {
    true
}

impl Default for ConvertOptions {
    fn default() -> Self {
        ConvertOptions {
            profile: Profile::default(),
            segments: None,
            rings: 3,
            volumetric: VolumetricMode::default(),
            flat_ratio: DEFAULT_FLAT_RATIO,
            up: UpAxis::default(),
            max_triangles: None,
            bake_view: None,
            bake_view_name: None,
            color_encoding: ColorEncoding::default(),
            gaussian_ids: true,
            coplanar_offset: false,
            surfels: None,
            chunk_size: 0,
            chunk_order: ChunkOrder::Input,
            both_windings: false,
            normals: true,
            view_order: None,
            view_order_name: None,
            vertex_colours: None,
            distilled: None,
        }
    }
}

impl ConvertOptions {
    /// Whether the Gaussians are rearranged for viewers (`order.rs`).
    pub fn arranged(&self) -> bool {
        self.chunk_size > 0
            || self.chunk_order != ChunkOrder::Input
            || self.both_windings
            || self.view_order.is_some()
    }

    /// The arrangement for stock viewers: measured in docs/viewers.md.
    pub fn for_viewers(mut self) -> Self {
        self.chunk_size = crate::order::VIEWER_CHUNK;
        self.chunk_order = ChunkOrder::Normal;
        self.both_windings = true;
        self.normals = false;
        self
    }

    pub fn segments(&self) -> usize {
        self.segments.unwrap_or(self.profile.default_segments())
    }

    /// Reject knob values that cannot produce a sensible mesh.
    pub fn validate(&self) -> Result<(), crate::ConvertError> {
        let n = self.segments();
        let bad = |m: String| Err(crate::ConvertError::Invalid(m));
        if !(3..=64).contains(&n) {
            return bad(format!("segments must be in 3..=64, got {n}"));
        }
        if !(1..=16).contains(&self.rings) {
            return bad(format!("rings must be in 1..=16, got {}", self.rings));
        }
        if !(self.flat_ratio.is_finite() && self.flat_ratio >= 0.0) {
            return bad(format!(
                "flat ratio must be a finite number ≥ 0, got {}",
                self.flat_ratio
            ));
        }
        if let Some(s) = &self.surfels {
            s.validate()?;
        }
        if let Some(c) = &self.view_order {
            c.validate()
                .map_err(|e| crate::ConvertError::Invalid(format!("view-order camera: {e}")))?;
        }
        if self.surfels.is_some() && self.arranged() {
            return bad("surfel export keeps one node per part: no chunks, chunk order, both windings or view order".into());
        }
        if let Some(c) = &self.bake_view {
            c.validate()
                .map_err(|e| crate::ConvertError::Invalid(format!("bake-view camera: {e}")))?;
        }
        Ok(())
    }
}

/// Counts for one meshed cloud (the static part, one object, or one frame's content).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct MeshCounts {
    pub name: String,
    pub gaussians_in: u64,
    pub flat: u64,
    pub volumetric: u64,
    /// NaN, infinite values or zero quaternions.
    pub dropped_invalid: u64,
    /// Opacity below 1/255: the Gaussian never reaches the rasterizer's cut-off.
    pub dropped_transparent: u64,
    /// Scales so large that vertices would overflow f32.
    pub dropped_overflow: u64,
    /// Removed to meet `max_triangles`.
    pub dropped_budget: u64,
    pub vertices: u64,
    pub triangles: u64,
    /// Global id of this cloud's first Gaussian (see the `_GAUSSIAN_ID` docs in `lib.rs`).
    pub id_offset: u64,
}

/// What a conversion did. Serialisable; the counts are also embedded in the output.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct ConvertReport {
    pub format: String,
    pub profile: String,
    pub segments: usize,
    pub rings: usize,
    pub meshes: Vec<MeshCounts>,
    pub gaussians_in: u64,
    pub dropped_invalid: u64,
    pub dropped_transparent: u64,
    pub dropped_overflow: u64,
    pub dropped_budget: u64,
    pub vertices: u64,
    pub triangles: u64,
    /// Bytes written (all files), filled in after writing.
    pub bytes: u64,
    pub seconds: f64,
    pub warnings: Vec<String>,
    /// The surfel split (`--surfels`): thresholds and counts. With a split, `gaussians_in`
    /// counts every input Gaussian, `meshes` the residual ones, and `vertices`/`triangles`
    /// include the surfel fans.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surfels: Option<crate::surfels::SurfelReport>,
}

impl ConvertReport {
    pub fn new(format: &str, opts: &ConvertOptions) -> Self {
        ConvertReport {
            format: format.to_string(),
            profile: opts.profile.name().to_string(),
            segments: opts.segments(),
            rings: opts.rings,
            ..Default::default()
        }
    }

    pub fn add(&mut self, m: MeshCounts) {
        self.gaussians_in += m.gaussians_in;
        self.dropped_invalid += m.dropped_invalid;
        self.dropped_transparent += m.dropped_transparent;
        self.dropped_overflow += m.dropped_overflow;
        self.dropped_budget += m.dropped_budget;
        self.vertices += m.vertices;
        self.triangles += m.triangles;
        self.meshes.push(m);
    }

    /// The metadata object embedded into outputs.
    pub fn metadata(&self, opts: &ConvertOptions) -> serde_json::Value {
        let mut v = serde_json::json!({
            "generator": concat!("splatbridge ", env!("CARGO_PKG_VERSION")),
            "options": opts,
            "colorEncoding": opts.color_encoding,
            "gaussianIdAttribute": if opts.gaussian_ids { Some("_GAUSSIAN_ID") } else { None },
            "counts": {
                "gaussiansIn": self.gaussians_in,
                "droppedInvalid": self.dropped_invalid,
                "droppedTransparent": self.dropped_transparent,
                "droppedOverflow": self.dropped_overflow,
                "droppedBudget": self.dropped_budget,
                "vertices": self.vertices,
                "triangles": self.triangles,
            },
            "meshes": self.meshes,
        });
        if let Some(s) = &self.surfels {
            v["surfels"] = serde_json::json!(s);
        }
        v
    }
}
