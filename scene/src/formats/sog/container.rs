//! Where a SOG's files come from: entries of a `.sog` zip, or files beside an unbundled
//! `meta.json`. Every read is capped by what the header's Gaussian count can need, both by the
//! size an entry declares and by the bytes it really inflates to, so a zip bomb is refused
//! before it is inflated past the cap.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Component, Path, PathBuf};

use crate::error::{Result, SceneError};

/// The files of one SOG.
pub(super) enum Container {
    /// A `.sog` zip, read through the file (not loaded whole).
    Zip(Box<zip::ZipArchive<BufReader<File>>>),
    /// An unbundled `meta.json`; image names resolve against its directory.
    Dir(PathBuf),
}

/// The largest `meta.json` accepted. A v2 `meta.json` holds three 256-entry codebooks and a
/// few ranges (about 16 KB as splat-transform writes it); 4 MiB leaves room for any
/// generator's pretty-printing and extra keys while keeping a hostile one small.
pub(super) const META_CAP: u64 = 4 << 20;

impl Container {
    /// Open the container `path` names: a zip (by its magic) or a `meta.json`.
    pub(super) fn open(path: &Path) -> Result<(Container, u64)> {
        let len = super::super::regular_file_len(path)?;
        let file = File::open(path).map_err(|e| SceneError::io(path, e))?;
        let mut magic = [0u8; 4];
        let n = (&file)
            .take(4)
            .read(&mut magic)
            .map_err(|e| SceneError::io(path, e))?;
        if n == 4 && &magic == b"PK\x03\x04" {
            let file = File::open(path).map_err(|e| SceneError::io(path, e))?;
            let zip = zip::ZipArchive::new(BufReader::new(file))
                .map_err(|e| SceneError::format(path, format!("not a readable .sog zip: {e}")))?;
            Ok((Container::Zip(Box::new(zip)), len))
        } else {
            let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
            Ok((Container::Dir(dir), len))
        }
    }

    pub(super) fn is_bundled(&self) -> bool {
        matches!(self, Container::Zip(_))
    }

    /// The stored (compressed) size of an entry, for the compression-ratio guard: the zip's
    /// compressed size, or the file's length.
    pub(super) fn stored_len(&mut self, path: &Path, name: &str) -> Result<u64> {
        match self {
            Container::Zip(z) => z
                .by_name(name)
                .map(|f| f.compressed_size())
                .map_err(|e| SceneError::format(path, format!("{name}: {e}"))),
            Container::Dir(dir) => {
                let p = dir.join(checked_name(path, name)?);
                super::super::regular_file_len(&p)
            }
        }
    }

    /// Read entry `name` whole, refusing more than `cap` bytes (declared or real).
    pub(super) fn read(&mut self, path: &Path, name: &str, cap: u64) -> Result<Vec<u8>> {
        match self {
            Container::Zip(z) => {
                let entry = z.by_name(name).map_err(|e| {
                    SceneError::format(path, format!("zip has no readable entry {name}: {e}"))
                })?;
                let declared = entry.size();
                if declared > cap {
                    return Err(SceneError::format(
                        path,
                        format!(
                            "zip entry {name} declares {declared} bytes, more than the {cap} \
                             its Gaussian count can need"
                        ),
                    ));
                }
                let mut buf = Vec::with_capacity(declared as usize);
                entry
                    .take(cap + 1)
                    .read_to_end(&mut buf)
                    .map_err(|e| SceneError::format(path, format!("zip entry {name}: {e}")))?;
                if buf.len() as u64 > cap {
                    return Err(SceneError::format(
                        path,
                        format!(
                            "zip entry {name} inflates past the {cap} bytes its Gaussian count \
                             can need (declared {declared})"
                        ),
                    ));
                }
                Ok(buf)
            }
            Container::Dir(dir) => {
                let p = dir.join(checked_name(path, name)?);
                super::super::read_file_capped(&p, cap)
            }
        }
    }
}

/// An image name from `meta.json` must stay inside the SOG: a plain relative path without
/// `..`, so a hostile `meta.json` cannot make the reader open `/dev/zero` or a parent's files.
fn checked_name<'a>(path: &Path, name: &'a str) -> Result<&'a Path> {
    let p = Path::new(name);
    if name.is_empty() || p.components().any(|c| !matches!(c, Component::Normal(_))) {
        return Err(SceneError::format(
            path,
            format!("meta.json names file {name:?}, which is not a plain relative path"),
        ));
    }
    Ok(p)
}
