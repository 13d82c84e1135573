//! PLY reader and writer for the standard 3DGS layout (see the module docs of `scene` and
//! `../shared/reference/3dgs-conventions.md`). To be completed: see issue "Foundation".

use std::path::Path;

use crate::error::{Result, SceneError};
use crate::GaussianCloud;

/// Encoding of a written PLY.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum PlyFormat {
    #[default]
    BinaryLittleEndian,
    BinaryBigEndian,
    Ascii,
}

/// How the reader treats invalid Gaussians (NaN anywhere, zero quaternion, infinite values
/// other than opacity logits).
#[derive(Clone, Copy, Debug, Default)]
pub struct ReadOptions {
    /// Drop invalid Gaussians with a counted warning instead of failing.
    pub drop_invalid: bool,
}

/// What the reader noticed besides the Gaussians.
#[derive(Clone, Debug, Default)]
pub struct ReadReport {
    /// Gaussians dropped under `drop_invalid`, by reason.
    pub dropped: Vec<(String, usize)>,
    /// Properties present in the file that the reader does not use.
    pub ignored_properties: Vec<String>,
    /// Human-readable warnings (one line each).
    pub warnings: Vec<String>,
}

/// Read a 3DGS PLY file.
pub fn read_ply(path: &Path, opts: &ReadOptions) -> Result<(GaussianCloud, ReadReport)> {
    let _ = opts;
    Err(SceneError::format(path, "PLY reading is not implemented yet"))
}

/// Write a 3DGS PLY file (atomically: a temporary file renamed on success).
pub fn write_ply(path: &Path, cloud: &GaussianCloud, format: PlyFormat) -> Result<()> {
    let _ = (cloud, format);
    Err(SceneError::format(path, "PLY writing is not implemented yet"))
}
