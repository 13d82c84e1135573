//! The memory budget of a comparison: what each of `compare`'s growing stages will hold,
//! estimated *before* it runs from counts known in advance: the scene's Gaussians, and a
//! profile's vertices and triangles from the converter's classification pass (no mesh is
//! built). A stage whose estimate is over the budget is skipped with the figures, instead of
//! exhausting the machine part-way through (a 10 M-Gaussian scene's `rings` export is 1.5 G
//! triangles, about 35 GB traced).
//!
//! The estimates are of the process's peak resident memory during the stage: the scene's
//! clouds (held throughout), a fixed process base, and the stage's own data. The per-item
//! coefficients are measured peaks rounded up (docs/scale.md, "Memory budget"), so they are
//! upper bounds; `tests/memory_budget.rs` checks them against the peaks a run records.

use splatbridge_convert::{ConvertOptions, ConvertReport};
use splatbridge_scene::dynamic::DynamicScene;
use splatbridge_scene::GaussianCloud;

/// Code, thread stacks, malloc arenas and the frame store's buffers: a comparison of 20,000
/// Gaussians peaks at 123 MB of which 5 MB are the cloud (tests/memory_growth.rs); 64 MB
/// covers the fixed part with the traced stages' images at any size this tool renders.
pub const PROCESS_BASE_BYTES: u64 = 64 << 20;

/// The Gaussian tracer's BVH, proxy boxes and build scratch per Gaussian, beyond the cloud it
/// borrows. Measured (`trace --mode gaussian`, max RSS less `info`'s): 500 B at 100k, 514 B at
/// 500k, 413 B at 10 M Gaussians.
pub const GAUSSIAN_TRACER_BYTES: u64 = 560;

/// What the export leaves resident per Gaussian: the converter's classification, order and
/// per-part tables, freed before the read-back but kept by the allocator's arenas. Measured
/// (`convert`, max RSS less the loaded cloud): about 220 B at 100k and 400 B at 10 M (texture).
const EXPORT_BYTES_PER_GAUSSIAN: u64 = 400;

/// Per vertex and per triangle of a mesh read back from a GLB and traced: positions, colours
/// and ids (12 + 16 + 4 B a vertex), indices, material runs and group ids (about 18 B a
/// triangle). Measured (`trace FILE.glb`, 500k-Gaussian fixture, max RSS): rings 18.8 M
/// vertices, 73.7 M triangles, 2.06 GB; a least-squares fit with meshsplats' 6.6 M / 14.8 M
/// (495 MB) gives 27.3 B a vertex and 20.9 B a triangle. A GLB's blended mesh is traced
/// through the tiles from a 500th of its records a ray on (`TRIANGLES_PER_RAY`), whose
/// binned records and lists take the place of the BVH: measured on the 100k fixture at 96×72
/// (`tests/memory_budget.rs`, each stage in a process of its own), rings 707–715 MB resident
/// and meshsplats 204–211 MB, against 473 and 147 MB through the BVH (about 32 and 40 B more
/// a triangle); 32 B more is counted, the BVH's boxes (`BYTES_PER_BOX`) still counted beside
/// them.
const GLB_VERTEX_BYTES: u64 = 32;
const GLB_TRIANGLE_BYTES: u64 = 56;
/// A texture coordinate per vertex (f32 pair), which only the `texture` profile has.
const UV_BYTES: u64 = 8;
/// The same for OBJ read-back, whose peak follows the vertices (the reader's per-corner
/// tables): meshsplats 543 MB, rings 1.57 GB, texture (with `vt`) 432 MB at 500k.
const OBJ_VERTEX_BYTES: u64 = 96;
const OBJ_UV_BYTES: u64 = 32;
const OBJ_TRIANGLE_BYTES: u64 = 8;
/// The BVH build's scratch and nodes per box over a run of triangles (`run_length`): about
/// 480 B, measured on a 37 M-triangle rings export (1.1 GB over 2.3 M boxes).
const BYTES_PER_BOX: u64 = 480;

/// Bytes a cloud's arrays hold.
pub fn cloud_bytes(c: &GaussianCloud) -> u64 {
    let v3 = std::mem::size_of::<glam::Vec3>() as u64;
    let per = 2 * v3 // means, log-scales
        + std::mem::size_of::<glam::Quat>() as u64
        + 4 // opacity logit
        + v3 * c.coeffs() as u64
        + if c.object_ids.is_some() { 4 } else { 0 };
    per * c.len() as u64
}

/// Bytes every cloud of a scene holds (static part and objects).
pub fn scene_bytes(scene: &DynamicScene) -> u64 {
    cloud_bytes(&scene.static_gaussians)
        + scene
            .objects
            .iter()
            .map(|o| cloud_bytes(&o.gaussians))
            .sum::<u64>()
}

/// The Gaussians of a scene (static part and objects).
pub fn scene_gaussians(scene: &DynamicScene) -> u64 {
    scene.static_gaussians.len() as u64
        + scene
            .objects
            .iter()
            .map(|o| o.gaussians.len() as u64)
            .sum::<u64>()
}

/// Peak bytes of the Gaussian-trace stage of `scene`.
pub fn gaussian_stage_bytes(scene: &DynamicScene) -> u64 {
    PROCESS_BASE_BYTES + scene_bytes(scene) + gaussian_data_bytes(scene_gaussians(scene))
}

/// A mesh export's size, counted without building it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshSize {
    pub vertices: u64,
    pub triangles: u64,
    /// Texture coordinates per vertex (the `texture` profile).
    pub uv: bool,
}

/// The vertices and triangles `opts` makes of `scene`: the converter's classification and
/// triangle budget, which decide every count, without meshing.
pub fn mesh_size(scene: &DynamicScene, opts: &ConvertOptions) -> anyhow::Result<MeshSize> {
    let shape = splatbridge_convert::shape_for(opts);
    let mut report = ConvertReport::new("count", opts);
    splatbridge_convert::prepare(scene, None, opts, &shape, &mut report)?;
    Ok(MeshSize {
        vertices: report.vertices,
        triangles: report.triangles,
        uv: opts.profile == splatbridge_convert::Profile::Texture,
    })
}

/// Peak bytes of the stage that exports `scene` as a mesh file (`glb` or `obj`) of `size`,
/// reads it back and traces it.
pub fn mesh_stage_bytes(scene: &DynamicScene, size: MeshSize, format: &str) -> u64 {
    PROCESS_BASE_BYTES + scene_bytes(scene) + mesh_data_bytes(scene_gaussians(scene), size, format)
}

/// What the mesh stage adds to the process for a scene of `gaussians`: the export's leftovers,
/// the read-back mesh and its BVH.
pub fn mesh_data_bytes(gaussians: u64, size: MeshSize, format: &str) -> u64 {
    let (v, uv, t) = if format == "obj" {
        (OBJ_VERTEX_BYTES, OBJ_UV_BYTES, OBJ_TRIANGLE_BYTES)
    } else {
        (GLB_VERTEX_BYTES, UV_BYTES, GLB_TRIANGLE_BYTES)
    };
    let per_vertex = v + if size.uv { uv } else { 0 };
    let boxes = size
        .triangles
        .div_ceil(splatbridge_raytrace::mesh_tracer::run_length(size.triangles as usize) as u64);
    EXPORT_BYTES_PER_GAUSSIAN * gaussians
        + per_vertex.saturating_mul(size.vertices)
        + t.saturating_mul(size.triangles)
        + BYTES_PER_BOX * boxes
}

/// What the Gaussian-trace stage adds to the process beyond the clouds it borrows.
pub fn gaussian_data_bytes(gaussians: u64) -> u64 {
    GAUSSIAN_TRACER_BYTES * gaussians
}

/// An upper bound of the GLB a mesh of `size` makes: positions and normals (12 B each),
/// RGBA u16 (8 B), the Gaussian id (4 B) and, for `texture`, UVs (8 B) a vertex; three u32
/// indices a triangle; and 1 % + 16 MB for the JSON, padding, images and animation. Measured
/// on the 100k fixture's rings export (compare's options): 3.76 M vertices and 7.38 M
/// triangles are 224.0 MB of buffer views, exactly 36 B and 12 B each.
pub fn glb_bytes_bound(size: MeshSize) -> u64 {
    let data = (36 + if size.uv { 8 } else { 0 }) * size.vertices + 12 * size.triangles;
    data + data / 100 + (16 << 20)
}

/// The largest GLB the format allows: its header's total length is a u32 (glTF 2.0 §4.4.3).
pub const GLB_MAX_BYTES: u64 = u32::MAX as u64;

/// The file a comparison exports a mesh of `size` to for `format`: `glb` unless the GLB could
/// pass the format's 4 GiB, then `gltf` (JSON with the buffer in a `.bin` beside it, read back
/// streamed the same way); `obj` as asked.
pub fn export_format(size: MeshSize, format: &'static str) -> &'static str {
    if format == "glb" && glb_bytes_bound(size) > GLB_MAX_BYTES {
        "gltf"
    } else {
        format
    }
}

/// A `--max-memory` value: `auto` (the physical memory), `none` (no budget), or a size with an
/// optional binary suffix: `512M`, `16G`, `1.5G`, `2000000000`.
pub fn parse_budget(s: &str) -> Result<Option<u64>, String> {
    match s.trim() {
        "auto" => Ok(crate::measure::memory::physical_bytes()),
        "none" => Ok(None),
        t => {
            let (num, mult) = match t.chars().last() {
                Some('K' | 'k') => (&t[..t.len() - 1], 1u64 << 10),
                Some('M' | 'm') => (&t[..t.len() - 1], 1 << 20),
                Some('G' | 'g') => (&t[..t.len() - 1], 1 << 30),
                Some('T' | 't') => (&t[..t.len() - 1], 1 << 40),
                _ => (t, 1),
            };
            let x: f64 = num
                .parse()
                .map_err(|_| format!("'{s}' is not a size (auto, none, or e.g. 512M, 16G)"))?;
            let bytes = x * mult as f64;
            if !(1.0..1.8e19).contains(&bytes) {
                return Err(format!("'{s}' is not a positive size"));
            }
            Ok(Some(bytes as u64))
        }
    }
}

/// `bytes` as GB with two decimals (1 GB = 10⁹ bytes, as the reports print memory).
pub fn gb(bytes: u64) -> String {
    format!("{:.2} GB", bytes as f64 / 1e9)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_budget("16G"), Ok(Some(16 << 30)));
        assert_eq!(parse_budget("512m"), Ok(Some(512 << 20)));
        assert_eq!(parse_budget("1.5G"), Ok(Some(3 << 29)));
        assert_eq!(parse_budget("2000"), Ok(Some(2000)));
        assert_eq!(parse_budget("none"), Ok(None));
        for bad in ["", "G", "-1G", "0", "nanG", "1e30T", "12X"] {
            assert!(parse_budget(bad).is_err(), "{bad}");
        }
    }

    /// A mesh whose GLB could pass 4 GiB is exported as `.gltf`; OBJ is never renamed. The
    /// bound is at its limit between 70 M and 71 M untextured vertices with 2 triangles each
    /// (60.6 B a vertex with the margin).
    #[test]
    fn meshes_over_4_gib_export_as_gltf() {
        let size = |vertices: u64| MeshSize {
            vertices,
            triangles: 2 * vertices,
            uv: false,
        };
        assert_eq!(export_format(size(1_000_000), "glb"), "glb");
        assert_eq!(export_format(size(70_000_000), "glb"), "glb");
        assert_eq!(export_format(size(71_000_000), "glb"), "gltf");
        assert_eq!(export_format(size(71_000_000), "obj"), "obj");
    }

    /// The cloud's byte count is what its vectors' lengths say (SH degree 3: 16 RGB triples).
    #[test]
    fn cloud_bytes_count_the_arrays() {
        let mut c = GaussianCloud::new(3);
        for _ in 0..5 {
            c.push(
                glam::Vec3::ZERO,
                glam::Vec3::ZERO,
                glam::Quat::IDENTITY,
                0.0,
                &[glam::Vec3::ZERO; 16],
            );
        }
        let held = |c: &GaussianCloud| {
            (c.means.capacity() + c.log_scales.capacity() + c.sh.capacity()) as u64 * 12
                + c.rotations.capacity() as u64 * 16
                + c.opacity_logits.capacity() as u64 * 4
        };
        c.means.shrink_to_fit();
        c.log_scales.shrink_to_fit();
        c.sh.shrink_to_fit();
        c.rotations.shrink_to_fit();
        c.opacity_logits.shrink_to_fit();
        assert_eq!(cloud_bytes(&c), held(&c));
        assert_eq!(cloud_bytes(&c), 5 * (12 + 12 + 16 + 4 + 16 * 12));
    }
}
