//! splatbridge-raytrace: a BVH ray tracer that renders exactly what was exported (GLB/glTF/OBJ
//! triangle scenes, mode `mesh`) and ray-traces the Gaussians themselves (mode `gaussian`,
//! after 3DGRT), over two interchangeable BVH backends (obvhs, and Embree 4 behind the
//! `embree` feature).
//!
//! Entry points: [`scene_load::load_path`] / [`scene_load::load_glb_bytes`] give a
//! [`model::TriScene`]; [`mesh_tracer::MeshTracer`] renders it; [`gaussian::GaussianTracer`]
//! renders a `GaussianCloud`; [`secondary`] answers transmittance and closest-opaque queries.

pub mod backend;
#[cfg(test)]
mod hit_record_tests;
#[cfg(test)]
mod mesh_alpha_tests;
mod mesh_bin;
mod mesh_cands;
#[cfg(test)]
mod mesh_cull_tests;
#[cfg(test)]
mod mesh_group_tests;
mod mesh_groups;
pub(crate) mod mesh_hit;
#[cfg(test)]
mod mesh_load_tests;
#[cfg(test)]
mod mesh_tile_tests;
pub(crate) mod mesh_tiles;
pub mod mesh_tracer;
mod screen_cells;
/// The mesh tracer under its former name.
pub use mesh_tracer as composite;
pub mod dedup;
#[cfg(feature = "embree")]
pub mod embree_backend;
pub mod error;
pub mod footprint;
pub mod gaussian;
pub mod geom;
pub mod gltf_check;
pub mod gltf_stream;
pub mod hit_record;
pub mod instances;
pub mod kbuffer;
pub mod lidar;
pub mod model;
pub mod morph;
mod obj_block;
pub mod obj_frame;
pub mod obj_read;
#[cfg(test)]
mod obj_read_tests;
pub mod obvhs_backend;
pub mod prefetch;
pub mod render;
pub mod scene_load;
pub mod secondary;
pub mod shadows;
#[cfg(test)]
mod test_rng;
mod texture;
pub mod tri;

pub use backend::{BackendKind, BuildPreset};
pub use error::{Result, TraceError};
pub use footprint::{Footprint, HitOrder, SampleFootprint, ShDirection};
pub use gaussian::GaussianTracer;
pub use mesh_tracer::MeshTracer;
pub use model::{AlphaMode, TriScene};
pub use render::{Compositing, RenderOptions, Stats};
