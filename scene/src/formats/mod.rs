//! Every splat file format the tools read, detected by content, and one loader for all of them.
//!
//! [`detect`] looks at the first few KB of a file (magic bytes, PLY header, JSON keys), never
//! at the extension alone, so a `.splat` renamed `.bin` still opens. [`load`] dispatches to the
//! format's reader and returns a [`LoadInfo`] saying what was read and what the format's
//! quantisation costs; [`crate::manifest::load_scene`] calls it, so every command and a
//! manifest's `static`/`gaussians` paths accept every format.
//!
//! | format | module | spec followed |
//! |---|---|---|
//! | 3DGS PLY | [`crate::ply`] | graphdeco-inria `gaussian-splatting` |
//! | compressed PLY | [`compressed_ply`] | PlayCanvas SuperSplat / splat-transform |
//! | `.splat` | [`splat`] | antimatter15 `splat` viewer (32-byte records) |
//! | SPZ v1–v4 | [`spz`] | nianticlabs/spz `load-spz.cc` |
//! | `.ksplat` | [`ksplat`] | mkkellogg/GaussianSplats3D `SplatBuffer.js` |
//! | SOG | `sog` | PlayCanvas SOG (`meta.json` + WebP) |
//! | glTF/GLB | `gltf_khr` | Khronos `KHR_gaussian_splatting` |
//!
//! Every reader validates sizes against the file before allocating, names the file in every
//! error and applies the same invalid-Gaussian policy as the PLY reader
//! ([`ReadOptions::drop_invalid`]).

pub mod compressed_ply;
pub mod gltf_khr;
pub mod ksplat;
mod prefetch;
pub mod sog;
pub mod splat;
pub mod spz;
pub mod write;

pub use write::{write_cloud, CloudFormat};

use std::fmt;
use std::io::Read;
use std::path::Path;

use crate::dynamic::DynamicScene;
use crate::error::{Result, SceneError};
use crate::ply::{read_ply, ReadOptions};
use crate::GaussianCloud;

/// How many bytes [`detect`] reads at most.
pub const DETECT_BYTES: usize = 4096;

/// A splat file format, as recognised from content.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplatFormat {
    /// The standard 3DGS PLY (float properties by name).
    Ply,
    /// SuperSplat/PlayCanvas compressed PLY (`chunk` + packed `vertex` [+ `sh`] elements).
    CompressedPly,
    /// antimatter15 `.splat`: 32-byte records, no header.
    Splat,
    /// Niantic SPZ of the given header version (1–3: one gzip stream; 4: zstd streams).
    Spz { version: u32 },
    /// PlayCanvas SOG: `bundled` is a `.sog` zip, otherwise a `meta.json` beside WebP images.
    /// `version` is `None` when it cannot be known without unpacking the zip.
    Sog { version: Option<u32>, bundled: bool },
    /// glTF (`binary` for GLB) with `KHR_gaussian_splatting`; `spz` when it uses the
    /// SPZ-compressed variant.
    Gltf { binary: bool, spz: bool },
    /// GaussianSplats3D `.ksplat` at compression level 0, 1 or 2.
    Ksplat { level: u8 },
    /// A `splatbridge-scene/1` manifest.
    Manifest,
    /// A 4D model (Gaussians that change with time): see [`crate::fourd`].
    FourD(crate::fourd::FourDForm),
}

impl fmt::Display for SplatFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            SplatFormat::Ply => write!(f, "3DGS PLY"),
            SplatFormat::CompressedPly => write!(f, "compressed PLY (SuperSplat)"),
            SplatFormat::Splat => write!(f, ".splat (antimatter15)"),
            SplatFormat::Spz { version } => write!(f, "SPZ v{version}"),
            SplatFormat::Sog { version, bundled } => {
                let v = version.map_or_else(|| "?".to_string(), |v| v.to_string());
                let kind = if bundled { "bundled .sog" } else { "meta.json" };
                write!(f, "SOG v{v} ({kind})")
            }
            SplatFormat::Gltf { binary, spz } => {
                let kind = if binary { "GLB" } else { "glTF" };
                let ext = if spz {
                    "KHR_gaussian_splatting + SPZ compression"
                } else {
                    "KHR_gaussian_splatting"
                };
                write!(f, "{kind} ({ext})")
            }
            SplatFormat::Ksplat { level } => write!(f, ".ksplat (GaussianSplats3D, level {level})"),
            SplatFormat::Manifest => write!(f, "splatbridge-scene/1 manifest"),
            SplatFormat::FourD(form) => write!(f, "{} (4D)", form.name()),
        }
    }
}

impl SplatFormat {
    /// A short machine name (`info --json`, `--format`).
    pub fn name(&self) -> &'static str {
        match self {
            SplatFormat::Ply => "ply",
            SplatFormat::CompressedPly => "compressed-ply",
            SplatFormat::Splat => "splat",
            SplatFormat::Spz { .. } => "spz",
            SplatFormat::Sog { .. } => "sog",
            SplatFormat::Gltf { binary: true, .. } => "glb",
            SplatFormat::Gltf { binary: false, .. } => "gltf",
            SplatFormat::Ksplat { .. } => "ksplat",
            SplatFormat::Manifest => "manifest",
            SplatFormat::FourD(crate::fourd::FourDForm::SpacetimeLite) => "spacetime-ply",
            SplatFormat::FourD(crate::fourd::FourDForm::Splatv) => "splatv",
            SplatFormat::FourD(crate::fourd::FourDForm::Npz) => "npz",
            SplatFormat::FourD(crate::fourd::FourDForm::Sequence) => "ply-sequence",
        }
    }

    /// The format's version, where it has one.
    pub fn version(&self) -> Option<u32> {
        match *self {
            SplatFormat::Spz { version } => Some(version),
            SplatFormat::Sog { version, .. } => version,
            SplatFormat::Ksplat { level } => Some(level as u32),
            _ => None,
        }
    }

    /// What the format's quantisation costs, in one sentence.
    pub fn quantisation(&self) -> &'static str {
        match *self {
            SplatFormat::Ply => "lossless: every value float32",
            SplatFormat::CompressedPly => {
                "per 256-Gaussian chunk: positions 11-10-11 bits and log-scales 11-10-11 bits \
                 between the chunk's bounds, rotation 2-10-10-10 smallest three, colour and \
                 opacity 8 bits each, higher SH 8 bits in [-4, 4]"
            }
            SplatFormat::Splat => {
                "positions and scales float32, colour and opacity 8-bit, rotation 8-bit per \
                 component, SH degree 0 only"
            }
            SplatFormat::Spz { version: 1 } => {
                "positions float16, log-scales 8-bit (1/16 steps), rotation 8-bit x,y,z, colour \
                 8-bit (DC/0.15 range), opacity 8-bit, higher SH 8-bit (5 bits degree 1, 4 bits \
                 beyond)"
            }
            SplatFormat::Spz { version: 2 } => {
                "positions 24-bit fixed point, log-scales 8-bit (1/16 steps), rotation 8-bit \
                 x,y,z, colour 8-bit (DC/0.15 range), opacity 8-bit, higher SH 8-bit (5 bits \
                 degree 1, 4 bits beyond)"
            }
            SplatFormat::Spz { .. } => {
                "positions 24-bit fixed point, log-scales 8-bit (1/16 steps), rotation 32-bit \
                 smallest three (9 bits + sign), colour 8-bit (DC/0.15 range), opacity 8-bit, \
                 higher SH 8-bit (5 bits degree 1, 4 bits beyond)"
            }
            SplatFormat::Sog { .. } => {
                "positions 16-bit per axis on a log scale, rotation 8-bit smallest three, \
                 scales and colours through 256-entry codebooks, opacity 8-bit, higher SH \
                 through a palette (k-means)"
            }
            SplatFormat::Gltf { spz: true, .. } => {
                "SPZ-compressed: positions 24-bit fixed point, log-scales 8-bit, rotation \
                 smallest three, colour, opacity and higher SH 8-bit"
            }
            SplatFormat::Gltf { .. } => "lossless: float32 attributes",
            SplatFormat::Ksplat { level: 0 } => {
                "positions, linear scales, rotations and SH float32; colour and opacity 8-bit"
            }
            SplatFormat::Ksplat { level: 1 } => {
                "positions 16-bit in 5-unit buckets, scales, rotations and SH float16, colour \
                 and opacity 8-bit"
            }
            SplatFormat::Ksplat { .. } => {
                "positions 16-bit in 5-unit buckets, scales and rotations float16, colour, \
                 opacity and SH 8-bit (SH over the file's range)"
            }
            SplatFormat::Manifest => "as stored by each referenced file",
            SplatFormat::FourD(crate::fourd::FourDForm::Splatv) => {
                "positions float32; rotations, scales, motion, rotation velocity and temporal \
                 centre and width float16; colour and opacity 8-bit"
            }
            SplatFormat::FourD(_) => "lossless: the model's float values, evaluated at each time",
        }
    }
}

/// What [`load`] read: the format and the reader's warnings.
#[derive(Clone, Debug)]
pub struct LoadInfo {
    pub format: SplatFormat,
    /// Human-readable warnings, one line each.
    pub warnings: Vec<String>,
    /// What the Gaussians are: 2DGS surfels (flat discs) or points given defaults are told
    /// apart from 3D Gaussians, so later stages can treat them as such.
    pub kind: crate::ply::GaussianKind,
}

impl LoadInfo {
    fn new(format: SplatFormat) -> Self {
        LoadInfo {
            format,
            warnings: Vec::new(),
            kind: Default::default(),
        }
    }

    /// One sentence on what the format's quantisation costs.
    pub fn quantisation(&self) -> &'static str {
        self.format.quantisation()
    }
}

/// Check that `path` is a regular file (so opening it cannot block on a FIFO and reading it
/// cannot go on forever on a device) and return its length.
pub(crate) fn regular_file_len(path: &Path) -> Result<u64> {
    let meta = std::fs::metadata(path).map_err(|e| SceneError::io(path, e))?;
    if !meta.is_file() {
        return Err(SceneError::format(
            path,
            "not a regular file (a directory, FIFO or device cannot be read as a scene)",
        ));
    }
    Ok(meta.len())
}

/// Read a whole regular file whose length must not exceed `max` bytes. The length is checked
/// before anything is allocated, and the read is capped at that length so a file that grows
/// while it is read cannot make it allocate more.
pub(crate) fn read_file_capped(path: &Path, max: u64) -> Result<Vec<u8>> {
    let len = regular_file_len(path)?;
    if len > max {
        return Err(SceneError::format(
            path,
            format!("file is {len} bytes, more than the {max} bytes this format can need"),
        ));
    }
    let file = std::fs::File::open(path).map_err(|e| SceneError::io(path, e))?;
    let mut buf = Vec::with_capacity(len as usize);
    file.take(len)
        .read_to_end(&mut buf)
        .map_err(|e| SceneError::io(path, e))?;
    Ok(buf)
}

/// The first [`DETECT_BYTES`] bytes of a regular file, and its length.
fn head(path: &Path) -> Result<(Vec<u8>, u64)> {
    let len = regular_file_len(path)?;
    let file = std::fs::File::open(path).map_err(|e| SceneError::io(path, e))?;
    let mut buf = Vec::with_capacity(DETECT_BYTES);
    file.take(DETECT_BYTES as u64)
        .read_to_end(&mut buf)
        .map_err(|e| SceneError::io(path, e))?;
    Ok((buf, len))
}

/// Recognise a file's format from its content (at most [`DETECT_BYTES`] bytes are read; for
/// a gzip file, at most the first 16 decompressed bytes). The extension only breaks ties
/// where content cannot: JSON that is neither glTF nor SOG is taken for a manifest.
pub fn detect(path: &Path) -> Result<SplatFormat> {
    if crate::fourd::is_sequence_spec(path) {
        return Ok(SplatFormat::FourD(crate::fourd::FourDForm::Sequence));
    }
    let (buf, len) = head(path)?;
    detect_bytes(path, &buf, len)
}

fn detect_bytes(path: &Path, buf: &[u8], len: u64) -> Result<SplatFormat> {
    if buf.starts_with(b"ply\n") || buf.starts_with(b"ply\r\n") {
        if crate::fourd::spacetime::spacetime_header(buf).is_some() {
            return Ok(SplatFormat::FourD(crate::fourd::FourDForm::SpacetimeLite));
        }
        return Ok(if compressed_ply::looks_compressed(buf) {
            SplatFormat::CompressedPly
        } else {
            SplatFormat::Ply
        });
    }
    if buf.starts_with(&[0x1f, 0x8b]) {
        let version = spz::gzip_header_version(path, buf)?;
        return Ok(SplatFormat::Spz { version });
    }
    if buf.starts_with(&spz::MAGIC.to_le_bytes()) {
        let version = buf
            .get(4..8)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .ok_or_else(|| SceneError::format(path, "SPZ header truncated"))?;
        return Ok(SplatFormat::Spz { version });
    }
    if crate::fourd::splatv::plausible(buf) {
        return Ok(SplatFormat::FourD(crate::fourd::FourDForm::Splatv));
    }
    if crate::fourd::npz::plausible(buf) {
        return Ok(SplatFormat::FourD(crate::fourd::FourDForm::Npz));
    }
    if buf.starts_with(b"PK\x03\x04") {
        return Ok(SplatFormat::Sog {
            version: None,
            bundled: true,
        });
    }
    let is_ext = |e: &str| path.extension().is_some_and(|x| x.eq_ignore_ascii_case(e));
    // Before `.splat`, whose record test a ksplat header (small integers) can pass.
    if ksplat::plausible(buf, len) || is_ext("ksplat") {
        let level = buf.get(20).map_or(0, |&l| l.min(2));
        return Ok(SplatFormat::Ksplat { level });
    }
    if buf.starts_with(b"glTF") {
        let spz = contains(buf, b"KHR_gaussian_splatting_compression_spz");
        return Ok(SplatFormat::Gltf { binary: true, spz });
    }
    let text = trim_json_start(buf);
    if text.first() == Some(&b'{') {
        // The extension's name makes a glTF whatever else the text holds.
        if contains(text, b"KHR_gaussian_splatting") {
            let spz = contains(text, b"KHR_gaussian_splatting_compression_spz");
            return Ok(SplatFormat::Gltf { binary: false, spz });
        }
        // SOG before the glTF "asset" test: splat-transform 0.16 and later write a
        // glTF-style `"asset": {"generator": …}` into `meta.json` too.
        if looks_like_sog_meta(text) {
            return Ok(SplatFormat::Sog {
                version: Some(sog_meta_version(text)),
                bundled: false,
            });
        }
        // glTF next: every glTF has "asset", which a manifest (unknown keys rejected) never
        // has, while a glTF's metadata may quote a manifest's format string.
        if contains(text, b"\"asset\"") {
            return Ok(SplatFormat::Gltf {
                binary: false,
                spz: false,
            });
        }
        if contains(text, b"splatbridge-scene/") {
            return Ok(SplatFormat::Manifest);
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        return match ext.as_deref() {
            Some("gltf") => Ok(SplatFormat::Gltf {
                binary: false,
                spz: false,
            }),
            _ => Ok(SplatFormat::Manifest),
        };
    }
    // `.splat` has no magic: records that look like Gaussians, or the extension (so that a
    // damaged `.splat` gets the reader's precise error rather than "unknown format").
    let is_splat_ext = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("splat"));
    if splat::plausible(buf, len) || is_splat_ext {
        return Ok(SplatFormat::Splat);
    }
    // Content names no format: the extension picks the reader whose message says what is wrong
    // with this file ("empty file (no PLY header)", "not UTF-8", a manifest that is not an
    // object) instead of a generic "unknown format".
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("ply") => return Ok(SplatFormat::Ply),
        Some("json") => return Ok(SplatFormat::Manifest),
        _ => {}
    }
    let shown: String = buf
        .iter()
        .take(8)
        .map(|b| format!("{b:02x}"))
        .collect::<Vec<_>>()
        .join(" ");
    Err(SceneError::format(
        path,
        format!(
            "not a splat file this tool reads (3DGS or compressed PLY, .splat, .ksplat, SPZ, \
             SOG, glTF/GLB, manifest, SpacetimeGaussians PLY, .splatv, params.npz, frame \
             sequence); first bytes: {shown}"
        ),
    ))
}

fn trim_json_start(buf: &[u8]) -> &[u8] {
    let buf = buf.strip_prefix(b"\xef\xbb\xbf").unwrap_or(buf);
    let start = buf
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(buf.len());
    &buf[start..]
}

fn contains(hay: &[u8], needle: &[u8]) -> bool {
    hay.windows(needle.len()).any(|w| w == needle)
}

/// A SOG `meta.json`: a `"means"` object with `"files"` (every version), and none of the
/// arrays that hold a glTF's data. Only these two keys are looked for, since only they are
/// sure to fall in the first [`DETECT_BYTES`] bytes: splat-transform writes `version`,
/// `asset`, `count` and `means` first, then a 256-entry scale codebook (about 5 KB) before
/// `quats` and `sh0`.
fn looks_like_sog_meta(text: &[u8]) -> bool {
    contains(text, b"\"means\"")
        && contains(text, b"\"files\"")
        && !contains(text, b"\"accessors\"")
        && !contains(text, b"\"bufferViews\"")
}

/// SOG's `meta.json` carries `"version": 2` from version 2 on; version 1 has no such key.
fn sog_meta_version(text: &[u8]) -> u32 {
    let Some(at) = text.windows(9).position(|w| w == b"\"version\"") else {
        return 1;
    };
    let rest = &text[at + 9..];
    let digits: String = rest
        .iter()
        .skip_while(|b| b.is_ascii_whitespace() || **b == b':')
        .take_while(|b| b.is_ascii_digit())
        .map(|&b| b as char)
        .collect();
    digits.parse().unwrap_or(1)
}

/// Load any supported file as a scene: detect the format, read it, apply the invalid-Gaussian
/// policy. A manifest loads through [`crate::manifest::load_manifest`] (whose referenced
/// files come back through [`load_cloud`]).
pub fn load(path: &Path, opts: &ReadOptions) -> Result<(DynamicScene, LoadInfo)> {
    let format = detect(path)?;
    let mut info = LoadInfo::new(format);
    let scene = match format {
        SplatFormat::Manifest => {
            let (scene, warnings) = crate::manifest::load_manifest(path, opts)?;
            info.warnings = warnings;
            scene
        }
        SplatFormat::Gltf { .. } => {
            let mut scene = read_gltf(path)?;
            // The same invalid-Gaussian policy as every other format (NaN, infinite or
            // non-positive scales, zero quaternions).
            let mut report = crate::ply::ReadReport::default();
            crate::ply::validate(&mut scene.static_gaussians, true, path, opts, &mut report)?;
            for o in &mut scene.objects {
                crate::ply::validate(&mut o.gaussians, true, path, opts, &mut report)?;
            }
            info.warnings.append(&mut report.warnings);
            scene
        }
        SplatFormat::FourD(form) => {
            let model = crate::fourd::load(path, form, crate::fourd::frame_rate())?;
            crate::fourd::into_scene(model)?
        }
        _ => {
            let (cloud, warnings) = read_single(path, &mut info.format, &mut info.kind, opts)?;
            info.warnings = warnings;
            DynamicScene::from_static(cloud)
        }
    };
    Ok((scene, info))
}

/// Load one cloud (a manifest's `static` or an object's `gaussians`): any single-cloud format,
/// or a glTF whose scene is composited at its start time (with a warning when it has objects).
/// A manifest cannot be nested.
pub fn load_cloud(path: &Path, opts: &ReadOptions) -> Result<(GaussianCloud, LoadInfo)> {
    let format = detect(path)?;
    let mut info = LoadInfo::new(format);
    let cloud = match format {
        SplatFormat::Manifest => {
            return Err(SceneError::format(
                path,
                "a manifest cannot refer to another manifest; give a splat file",
            ))
        }
        SplatFormat::Gltf { .. } => {
            let scene = read_gltf(path)?;
            let (start, objects) = (scene.time.start, scene.objects.len());
            let mut cloud = scene.into_composite(start);
            let mut report = crate::ply::ReadReport::default();
            crate::ply::validate(&mut cloud, true, path, opts, &mut report)?;
            info.warnings.append(&mut report.warnings);
            if objects > 0 {
                info.warnings.push(format!(
                    "{objects} objects composited at t = {start} into one cloud"
                ));
            }
            cloud
        }
        SplatFormat::FourD(form) => {
            let model = crate::fourd::load(path, form, crate::fourd::frame_rate())?;
            let start = model.time_range().start;
            info.warnings.push(format!(
                "{} sampled at t = {start} into one cloud",
                form.name()
            ));
            model.sample(start)?
        }
        _ => {
            let (cloud, warnings) = read_single(path, &mut info.format, &mut info.kind, opts)?;
            info.warnings = warnings;
            cloud
        }
    };
    Ok((cloud, info))
}

/// Read a single-cloud format and apply the invalid-Gaussian policy. `format` is completed
/// where reading tells more than detection (a bundled SOG's version).
fn read_single(
    path: &Path,
    format: &mut SplatFormat,
    kind: &mut crate::ply::GaussianKind,
    opts: &ReadOptions,
) -> Result<(GaussianCloud, Vec<String>)> {
    // `screened`: the decoder's own validity flag where it has one (false: no Gaussian can be
    // invalid), else None and the generic screen runs over the decoded arrays.
    let mut screened = None;
    let (mut cloud, mut warnings) = match *format {
        SplatFormat::Ply => {
            let (cloud, report) = read_ply(path, opts)?;
            *kind = report.kind;
            return Ok((cloud, report.warnings));
        }
        SplatFormat::CompressedPly => {
            let (cloud, suspect) = compressed_ply::read_compressed_ply(path)?;
            screened = Some(suspect);
            (cloud, Vec::new())
        }
        SplatFormat::Splat => (splat::read_splat(path)?, Vec::new()),
        SplatFormat::Ksplat { .. } => (ksplat::read_ksplat(path)?, Vec::new()),
        SplatFormat::Spz { .. } => spz::read_spz(path)?,
        SplatFormat::Sog { .. } => {
            let (cloud, summary) = sog::read_sog_with_summary(path)?;
            *format = SplatFormat::Sog {
                version: Some(summary.version),
                bundled: summary.bundled,
            };
            (cloud, Vec::new())
        }
        SplatFormat::Gltf { .. } | SplatFormat::Manifest | SplatFormat::FourD(_) => {
            return Err(SceneError::format(path, "not a single-cloud format"))
        }
    };
    let mut report = crate::ply::ReadReport::default();
    let suspect = screened.unwrap_or_else(|| cloud.may_have_invalid());
    crate::ply::validate(&mut cloud, suspect, path, opts, &mut report)?;
    warnings.append(&mut report.warnings);
    Ok((cloud, warnings))
}

fn read_gltf(path: &Path) -> Result<DynamicScene> {
    gltf_khr::read_gltf_splats(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sog_version_from_meta_text() {
        assert_eq!(sog_meta_version(br#"{"version": 2, "means": {}}"#), 2);
        assert_eq!(sog_meta_version(br#"{"means": {}}"#), 1);
    }
}
