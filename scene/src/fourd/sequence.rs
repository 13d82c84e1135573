//! Numbered per-frame PLY sequences (`name_0001.ply`, `name_0002.ply`, …), as SuperSplat's and
//! the Blender add-ons' sequence exports write them: a folder, or a pattern naming the frames
//! (`frames/name_*.ply` or `frames/name_%04d.ply`). Frames are ordered by name, the trailing
//! numbers compared by value (so unpadded `f2` comes before `f10`); frame i (from 0) is shown at
//! `i/fps`. Frames may differ in Gaussian count.
//!
//! Opening reads only the headers (each validated against its file's length); a frame is read
//! when sampled, and only the last frame read is kept, so a long sequence costs one frame of
//! memory at a time.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use crate::dynamic::MAX_FRAMES;
use crate::error::{Result, SceneError};
use crate::ply::{read_ply, ReadOptions};
use crate::GaussianCloud;

/// A frame sequence on disk.
#[derive(Debug)]
pub struct Sequence {
    pub files: Vec<PathBuf>,
    /// Gaussians in each frame (from its header).
    pub counts: Vec<usize>,
    last: Mutex<Option<(usize, Arc<GaussianCloud>)>>,
}

/// Does `path` name a sequence (a folder, or a file name with `*` or `%d`/`%0Nd`) rather
/// than one file?
pub fn is_sequence_spec(path: &Path) -> bool {
    if path.is_dir() {
        return true;
    }
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    name.is_some_and(|n| n.contains('*') || percent_d(&n).is_some())
}

/// The `%d`/`%0Nd` in a file name: (start, end) byte range.
fn percent_d(name: &str) -> Option<(usize, usize)> {
    let at = name.find('%')?;
    let rest = &name[at + 1..];
    let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
    (rest.as_bytes().get(digits) == Some(&b'd')).then_some((at, at + 1 + digits + 1))
}

/// Split a file name into (stem before the trailing number, number, extension).
fn numbered(name: &str) -> Option<(&str, u64, &str)> {
    let (stem, ext) = name.rsplit_once('.')?;
    let digits = stem.bytes().rev().take_while(u8::is_ascii_digit).count();
    if digits == 0 || digits > 18 {
        return None;
    }
    let (prefix, num) = stem.split_at(stem.len() - digits);
    Some((prefix, num.parse().ok()?, ext))
}

/// Which file names of a folder belong to the sequence.
type NameMatcher = Box<dyn Fn(&str) -> bool>;

impl Sequence {
    /// Find the frames `spec` names and read their headers.
    pub fn open(spec: &Path) -> Result<Sequence> {
        let err = |what: String| SceneError::format(spec, what);
        let (dir, matcher): (PathBuf, NameMatcher) = if spec.is_dir() {
            (
                spec.to_path_buf(),
                Box::new(|n: &str| {
                    numbered(n).is_some_and(|(_, _, e)| e.eq_ignore_ascii_case("ply"))
                }),
            )
        } else {
            let name = spec
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let dir = match spec.parent() {
                Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
                _ => PathBuf::from("."),
            };
            if !dir.is_dir() {
                return Err(err(format!("folder {} does not exist", dir.display())));
            }
            let (prefix, suffix, digits_only) = if let Some((a, b)) = percent_d(&name) {
                (name[..a].to_string(), name[b..].to_string(), true)
            } else {
                let (a, b) = name.split_once('*').unwrap_or((&name, ""));
                if b.contains('*') {
                    return Err(err("a frame pattern may hold one '*'".into()));
                }
                (a.to_string(), b.to_string(), false)
            };
            (
                dir,
                Box::new(move |n: &str| {
                    n.len() > prefix.len() + suffix.len()
                        && n.starts_with(&prefix)
                        && n.ends_with(&suffix)
                        && (!digits_only
                            || n[prefix.len()..n.len() - suffix.len()]
                                .bytes()
                                .all(|b| b.is_ascii_digit()))
                }),
            )
        };
        let rd = std::fs::read_dir(&dir).map_err(|e| SceneError::io(&dir, e))?;
        let mut names = Vec::new();
        for entry in rd {
            let entry = entry.map_err(|e| SceneError::io(&dir, e))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            if matcher(&name) && entry.path().is_file() {
                names.push(name);
                if names.len() > MAX_FRAMES {
                    return Err(err(format!("more than {MAX_FRAMES} frames")));
                }
            }
        }
        if names.is_empty() {
            // A folder that holds no frames is not a scene at all: say so as every reader
            // says it of a folder.
            let what = if spec.is_dir() {
                "a folder, not a regular file, and no numbered frames in it"
            } else {
                "no frame files found"
            };
            return Err(err(format!(
                "{what} (a sequence is a folder of name_0001.ply, …, or a pattern such as \
                 frames/name_*.ply or frames/name_%04d.ply)"
            )));
        }
        names.sort_by(|a, b| match (numbered(a), numbered(b)) {
            (Some((pa, na, _)), Some((pb, nb, _))) => (pa, na).cmp(&(pb, nb)),
            _ => a.cmp(b),
        });
        let files: Vec<PathBuf> = names.iter().map(|n| dir.join(n)).collect();
        let counts = files
            .iter()
            .map(PathBuf::as_path)
            .map(frame_count)
            .collect::<Result<Vec<_>>>()?;
        Ok(Sequence {
            files,
            counts,
            last: Mutex::new(None),
        })
    }

    pub fn len(&self) -> usize {
        self.files.len()
    }

    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }

    pub fn max_count(&self) -> usize {
        self.counts.iter().copied().max().unwrap_or(0)
    }

    pub fn same_count(&self) -> bool {
        self.counts.windows(2).all(|w| w[0] == w[1])
    }

    /// Frame `i` (clamped), read from its file unless it was the last one read.
    pub fn frame(&self, i: usize) -> Result<Arc<GaussianCloud>> {
        let i = i.min(self.len().saturating_sub(1));
        let mut last = self.last.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((k, c)) = &*last {
            if *k == i {
                return Ok(c.clone());
            }
        }
        // Drop the previous frame before reading the next: one frame in memory at a time.
        *last = None;
        let path = &self.files[i];
        let (cloud, _) = read_ply(path, &ReadOptions::default())?;
        if cloud.len() != self.counts[i] {
            return Err(SceneError::format(
                path,
                format!(
                    "holds {} Gaussians, its header said {} when the sequence was opened",
                    cloud.len(),
                    self.counts[i]
                ),
            ));
        }
        let c = Arc::new(cloud);
        *last = Some((i, c.clone()));
        Ok(c)
    }
}

/// A frame file's Gaussian count from its header, checked against the file's length.
fn frame_count(path: &Path) -> Result<usize> {
    use crate::ply::header::{parse_header, Encoding};
    let (file, len) = crate::input::open_regular(path)?;
    let mut r = std::io::BufReader::with_capacity(16 << 10, file);
    let h = parse_header(&mut r, path)?;
    if h.properties.iter().any(|p| p.name == "trbf_center") {
        return Err(SceneError::format(
            path,
            "a SpacetimeGaussians model cannot be a frame of a sequence",
        ));
    }
    let data = len.saturating_sub(h.len);
    let fits = match h.encoding {
        Encoding::Ascii => h.vertex_count <= data,
        _ => h
            .vertex_count
            .checked_mul(h.stride as u64)
            .is_some_and(|b| b <= data),
    };
    if !fits {
        return Err(SceneError::format(
            path,
            format!(
                "header declares {} vertices but only {data} bytes follow the header",
                h.vertex_count
            ),
        ));
    }
    Ok(h.vertex_count as usize)
}
