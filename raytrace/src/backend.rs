//! One interface over the BVH libraries: build over triangles or over boxes (custom
//! primitives such as Gaussian proxies), then enumerate the candidate primitives along a ray.
//!
//! The caller's closure does the exact primitive test (the watertight triangle test or the
//! Gaussian's response), so every backend produces identical hits from identical candidates:
//! backends differ only in which candidates they visit and how fast. The closure may lower the
//! cull distance (the k-nearest pattern); a backend may use it to skip farther nodes or ignore
//! it, which never changes the result, only the work.

use glam::Vec3;

use crate::error::{Result, TraceError};

/// Which BVH library traces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BackendKind {
    /// obvhs CWBVH (pure Rust).
    #[default]
    Obvhs,
    /// Embree 4 (feature `embree`).
    Embree,
}

impl std::str::FromStr for BackendKind {
    type Err = TraceError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "obvhs" => Ok(BackendKind::Obvhs),
            "embree" => Ok(BackendKind::Embree),
            _ => Err(TraceError::Invalid(format!(
                "backend '{s}' is not obvhs or embree"
            ))),
        }
    }
}

impl std::fmt::Display for BackendKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            BackendKind::Obvhs => "obvhs",
            BackendKind::Embree => "embree",
        })
    }
}

/// BVH build quality. Only presets without spatial pre-splits are offered: with pre-splits one
/// triangle sits in several leaves and an all-hits query would see it more than once.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BuildPreset {
    Fastest,
    VeryFast,
    Fast,
    #[default]
    Medium,
}

impl std::str::FromStr for BuildPreset {
    type Err = TraceError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "fastest" => Ok(BuildPreset::Fastest),
            "very-fast" => Ok(BuildPreset::VeryFast),
            "fast" => Ok(BuildPreset::Fast),
            "medium" => Ok(BuildPreset::Medium),
            _ => Err(TraceError::Invalid(format!(
                "build preset '{s}' is not fastest, very-fast, fast or medium"
            ))),
        }
    }
}

/// Whether the Embree backend is compiled in.
pub const EMBREE_AVAILABLE: bool = cfg!(feature = "embree");

/// An acceleration structure over one primitive set.
pub trait Accel: Send + Sync {
    /// Call `visit(primitive, reported, &mut cull)` for (at least) every primitive whose
    /// bounds the ray `origin + t·dir, 0 ≤ t ≤ tmax` enters. `reported` is true when the
    /// backend's own primitive test already found a hit (Embree triangles), so the caller
    /// can honour the backend's edge rule where its own test picks the neighbouring triangle.
    /// `visit` may lower `cull`.
    fn traverse(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    );

    /// The structure's own primitive order, when it has one: `slots()[s]` is the primitive at
    /// slot `s`. Callers that lay their per-primitive data out in slot order and traverse with
    /// [`Accel::traverse_slots`] read it sequentially instead of at random (on converted
    /// scenes, gathering vertices through the index buffer was the dominant cost).
    fn slots(&self) -> Option<&[u32]> {
        None
    }

    /// As [`Accel::traverse`], but visiting slots (see [`Accel::slots`]; identity when None)
    /// and allowed to skip nodes the ray leaves before `tmin` (resuming a k-buffer query from
    /// the last hit: without it every round re-walks the tree from the origin).
    fn traverse_slots(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        visit: &mut dyn FnMut(u32, bool, &mut f32),
    ) {
        let _ = tmin;
        self.traverse(origin, dir, tmax, visit)
    }
}

/// An empty structure (no primitives).
pub struct EmptyAccel;

impl Accel for EmptyAccel {
    fn traverse(&self, _: Vec3, _: Vec3, _: f32, _: &mut dyn FnMut(u32, bool, &mut f32)) {}
}

/// Largest coordinate magnitude a BVH build accepts (scene units, metres in captures). BVH
/// builders compute surface areas (extent²) times primitive counts in f32, which must stay
/// below f32::MAX ≈ 3.4e38: at ±1e12 an extent² is ~4e24, leaving 1e14 for counts and sums.
/// Real captures span kilometres; 1e12 m is about seven astronomical units.
pub const MAX_BVH_COORD: f32 = 1e12;

/// Whether a point is finite and within ±[`MAX_BVH_COORD`] on every axis.
pub fn fits_bvh(p: Vec3) -> bool {
    // `max_element` skips NaN, hence the explicit finiteness test.
    p.is_finite() && p.abs().max_element() <= MAX_BVH_COORD
}

fn check_extent(points: impl Iterator<Item = Vec3>, what: &str) -> Result<()> {
    for (i, p) in points.enumerate() {
        if !fits_bvh(p) {
            return Err(TraceError::Invalid(format!(
                "{what} {i} has coordinates {p}, beyond the ±{MAX_BVH_COORD} an f32 BVH holds"
            )));
        }
    }
    Ok(())
}

/// The check [`build_boxes`] makes before building: every corner within what an f32 BVH
/// holds. After it, an obvhs build over the same boxes cannot fail.
pub fn check_boxes(boxes: &[(Vec3, Vec3)]) -> Result<()> {
    check_extent(boxes.iter().flat_map(|(lo, hi)| [*lo, *hi]), "box corner")
}

/// Build a structure over triangles (`tris` index `verts`).
pub fn build_triangles(
    kind: BackendKind,
    preset: BuildPreset,
    verts: &[Vec3],
    tris: &[[u32; 3]],
) -> Result<Box<dyn Accel>> {
    if tris.is_empty() {
        return Ok(Box::new(EmptyAccel));
    }
    check_extent(verts.iter().copied(), "vertex")?;
    if let Some(t) = tris
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= verts.len()))
    {
        return Err(TraceError::Invalid(format!(
            "triangle {t} indexes past {} vertices",
            verts.len()
        )));
    }
    match kind {
        BackendKind::Obvhs => {
            // Many copies of one triangle would make the PLOC build quadratic (see `dedup`).
            let boxes = crate::dedup::triangle_boxes(verts, tris);
            if let Some(a) = crate::dedup::FoldedAccel::build(&boxes, |d| {
                Ok(Box::new(crate::obvhs_backend::ObvhsAccel::boxes(preset, d)))
            })? {
                return Ok(a);
            }
            Ok(Box::new(crate::obvhs_backend::ObvhsAccel::triangles(
                preset, verts, tris,
            )))
        }
        BackendKind::Embree => embree_triangles(preset, verts, tris),
    }
}

/// Build a structure over axis-aligned boxes (custom primitives).
pub fn build_boxes(
    kind: BackendKind,
    preset: BuildPreset,
    boxes: &[(Vec3, Vec3)],
) -> Result<Box<dyn Accel>> {
    if boxes.is_empty() {
        return Ok(Box::new(EmptyAccel));
    }
    check_boxes(boxes)?;
    match kind {
        BackendKind::Obvhs => {
            if let Some(a) = crate::dedup::FoldedAccel::build(boxes, |d| {
                Ok(Box::new(crate::obvhs_backend::ObvhsAccel::boxes(preset, d)))
            })? {
                return Ok(a);
            }
            Ok(Box::new(crate::obvhs_backend::ObvhsAccel::boxes(
                preset, boxes,
            )))
        }
        BackendKind::Embree => embree_boxes(preset, boxes),
    }
}

#[cfg(feature = "embree")]
fn embree_triangles(
    preset: BuildPreset,
    verts: &[Vec3],
    tris: &[[u32; 3]],
) -> Result<Box<dyn Accel>> {
    Ok(Box::new(crate::embree_backend::EmbreeAccel::triangles(
        preset, verts, tris,
    )?))
}

#[cfg(feature = "embree")]
fn embree_boxes(preset: BuildPreset, boxes: &[(Vec3, Vec3)]) -> Result<Box<dyn Accel>> {
    Ok(Box::new(crate::embree_backend::EmbreeAccel::boxes(
        preset, boxes,
    )?))
}

#[cfg(not(feature = "embree"))]
fn embree_triangles(_: BuildPreset, _: &[Vec3], _: &[[u32; 3]]) -> Result<Box<dyn Accel>> {
    Err(not_built())
}

#[cfg(not(feature = "embree"))]
fn embree_boxes(_: BuildPreset, _: &[(Vec3, Vec3)]) -> Result<Box<dyn Accel>> {
    Err(not_built())
}

#[cfg(not(feature = "embree"))]
fn not_built() -> TraceError {
    TraceError::Backend(
        "the embree backend is not compiled in: run scripts/get-embree.sh, then build with `--features embree`".into(),
    )
}
