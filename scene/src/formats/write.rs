//! Writing one cloud in a splat format, chosen by the output's name or explicitly.
//!
//! The rule (also `splatbridge convert --help`): `.splat`, `.spz` and `.ksplat` are always
//! splats;
//! `*.compressed.ply` is a compressed PLY; `.ply` is the 3DGS PLY, as every splat tool writes
//! it, unless a mesh is asked for (`convert --mesh` or `--profile`: then `splats` is false).
//! glTF splats (`KHR_gaussian_splatting`) are written by `splatbridge-convert`, which keeps a
//! dynamic scene's objects as animated nodes; the formats here hold one cloud, so a dynamic
//! scene is composited at one time first ([`crate::dynamic::DynamicScene::composite`]).

use std::path::Path;

use super::{compressed_ply, ksplat, splat, spz};
use crate::error::Result;
use crate::ply::{write_ply, PlyFormat};
use crate::GaussianCloud;

/// A single-cloud output format.
#[derive(Clone, Copy, Debug)]
pub enum CloudFormat {
    /// The standard 3DGS PLY (binary little endian, lossless).
    Ply,
    /// SuperSplat / PlayCanvas compressed PLY.
    CompressedPly,
    /// antimatter15 `.splat`.
    Splat,
    /// Niantic SPZ with these options.
    Spz(spz::SpzOptions),
    /// GaussianSplats3D `.ksplat` with these options.
    Ksplat(ksplat::KsplatOptions),
}

impl CloudFormat {
    /// A short name for reports.
    pub fn name(&self) -> &'static str {
        match self {
            CloudFormat::Ply => "3DGS PLY",
            CloudFormat::CompressedPly => "compressed PLY",
            CloudFormat::Splat => ".splat",
            CloudFormat::Spz(_) => "SPZ",
            CloudFormat::Ksplat(_) => ".ksplat",
        }
    }

    /// The format an output path implies under the rule in the module docs (`splats`: the
    /// caller asked for splats, so a plain `.ply` is a 3DGS PLY). `None`: not a single-cloud
    /// splat output (a mesh, or glTF).
    pub fn for_path(path: &Path, splats: bool) -> Option<CloudFormat> {
        let name = path.file_name()?.to_string_lossy().to_ascii_lowercase();
        if name.ends_with(".compressed.ply") {
            return Some(CloudFormat::CompressedPly);
        }
        let ext = path.extension()?.to_string_lossy().to_ascii_lowercase();
        match ext.as_str() {
            "splat" => Some(CloudFormat::Splat),
            "spz" => Some(CloudFormat::Spz(spz::SpzOptions::default())),
            "ksplat" => Some(CloudFormat::Ksplat(ksplat::KsplatOptions::default())),
            "ply" if splats => Some(CloudFormat::Ply),
            _ => None,
        }
    }
}

/// Write `cloud` to `path` (atomically) in `format`; returns the bytes written.
pub fn write_cloud(path: &Path, cloud: &GaussianCloud, format: CloudFormat) -> Result<u64> {
    match format {
        CloudFormat::Ply => write_ply(path, cloud, PlyFormat::BinaryLittleEndian)?,
        CloudFormat::CompressedPly => compressed_ply::write_compressed_ply(path, cloud)?,
        CloudFormat::Splat => splat::write_splat(path, cloud)?,
        CloudFormat::Spz(o) => spz::write_spz(path, cloud, &o)?,
        CloudFormat::Ksplat(o) => ksplat::write_ksplat(path, cloud, &o)?,
    }
    Ok(std::fs::metadata(path).map(|m| m.len()).unwrap_or(0))
}
