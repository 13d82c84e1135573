//! The `splatbridge-scene/1` JSON manifest and scene loading (PLY or manifest).
//! To be completed: see issue "Foundation".

use std::path::Path;

use crate::dynamic::DynamicScene;
use crate::error::Result;
use crate::ply::{read_ply, ReadOptions};

/// Load anything accepted where a scene is expected: a 3DGS PLY (a static scene) or a
/// `splatbridge-scene/1` manifest. Warnings are returned for the caller to print.
pub fn load_scene(path: &Path, opts: &ReadOptions) -> Result<(DynamicScene, Vec<String>)> {
    let (cloud, report) = read_ply(path, opts)?;
    Ok((DynamicScene::from_static(cloud), report.warnings))
}
