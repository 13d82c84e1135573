//! Output files that appear together or not at all.
//!
//! Every command's outputs go through an [`OutputSet`]: each file is written to a temporary
//! name in its target directory (`.NAME.tmpPID.SERIAL`), and only when every file of the set
//! has been written completely are they renamed onto their targets, so a `.gltf` never sits
//! beside a `.bin` of another run and a `--frames` sequence is never half old, half new.
//!
//! The renames themselves are made reversible: an existing target is first renamed to a
//! backup (`.NAME.oldPID.SERIAL`) and restored if a later rename of the set fails, so a failure
//! at any point leaves the previous outputs as they were and no temporary behind. (POSIX has no
//! multi-file atomic rename; a crash in the middle of the rename loop can still leave a mix,
//! and the next run repairs what it can: see below.)
//!
//! Temporaries of a run that was killed are removed by the next run writing into the same
//! directory ([`clean_stale`]): files matching our naming pattern whose process is gone, or
//! that are older than [`STALE_AFTER`]. A stale backup whose target is missing (a run killed
//! between its two renames) is put back instead of deleted.

use std::collections::HashSet;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, SystemTime};

use crate::error::{Result, SceneError};

/// A temporary of ours older than this is stale whatever its process: no single output takes
/// an hour to write, and a process id may have been reused.
pub const STALE_AFTER: Duration = Duration::from_secs(3600);

/// Distinguishes temporaries of concurrent writers in one process.
static SERIAL: AtomicU64 = AtomicU64::new(0);

/// The two kinds of temporary name: a new file being written, an old one moved aside.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Tmp,
    Old,
}

impl Kind {
    fn tag(self) -> &'static str {
        match self {
            Kind::Tmp => "tmp",
            Kind::Old => "old",
        }
    }
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A fresh temporary name next to `target`: `.NAME.tmpPID.SERIAL` (or `old`).
fn temp_name(target: &Path, kind: Kind) -> PathBuf {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let serial = SERIAL.fetch_add(1, Ordering::Relaxed);
    parent_dir(target).join(format!(
        ".{name}.{}{}.{serial}",
        kind.tag(),
        std::process::id()
    ))
}

/// Parse one of our temporary names: the target's file name, the kind and the writer's pid.
fn parse_temp_name(file_name: &str) -> Option<(&str, Kind, u32)> {
    let rest = file_name.strip_prefix('.')?;
    let (head, serial) = rest.rsplit_once('.')?;
    if serial.is_empty() || !serial.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let (name, tag) = head.rsplit_once('.')?;
    let (kind, pid) = if let Some(pid) = tag.strip_prefix("tmp") {
        (Kind::Tmp, pid)
    } else {
        (Kind::Old, tag.strip_prefix("old")?)
    };
    if name.is_empty() || pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    Some((name, kind, pid.parse().ok()?))
}

/// Whether process `pid` still runs. Without `/proc` (not Linux) every process counts as
/// alive, so only [`STALE_AFTER`] decides.
fn process_alive(pid: u32) -> bool {
    if !Path::new("/proc/self").exists() {
        return true;
    }
    Path::new("/proc").join(pid.to_string()).exists()
}

/// Remove our temporaries in `dir` left by runs that are gone (their process no longer
/// exists, or the file is older than [`STALE_AFTER`]); put back a stale backup whose target
/// is missing. Files of this process and of running processes are left alone, and anything
/// that does not match our naming pattern exactly is never touched. Returns the paths
/// removed or restored. Errors (an unreadable directory) are ignored: cleaning is a courtesy
/// that must never fail a run.
pub fn clean_stale(dir: &Path) -> Vec<PathBuf> {
    let mut cleaned = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return cleaned;
    };
    let me = std::process::id();
    let now = SystemTime::now();
    for e in entries.flatten() {
        let file_name = e.file_name();
        let Some(file_name) = file_name.to_str() else {
            continue;
        };
        let Some((target_name, kind, pid)) = parse_temp_name(file_name) else {
            continue;
        };
        let Ok(meta) = std::fs::symlink_metadata(e.path()) else {
            continue;
        };
        // Our staging directories are `Tmp` directories; nothing else but files is ours.
        let is_dir = meta.is_dir() && kind == Kind::Tmp;
        if !(meta.is_file() || is_dir) || pid == me {
            continue;
        }
        let old = meta
            .modified()
            .ok()
            .and_then(|m| now.duration_since(m).ok())
            .is_some_and(|age| age > STALE_AFTER);
        if !old && process_alive(pid) {
            continue;
        }
        let target = dir.join(target_name);
        let done = if is_dir {
            std::fs::remove_dir_all(e.path()).is_ok()
        } else if kind == Kind::Old && std::fs::symlink_metadata(&target).is_err() {
            std::fs::rename(e.path(), &target).is_ok()
        } else {
            std::fs::remove_file(e.path()).is_ok()
        };
        if done {
            cleaned.push(e.path());
        }
    }
    cleaned
}

/// One staged file: its temporary and its target.
#[derive(Debug)]
struct Staged {
    tmp: PathBuf,
    target: PathBuf,
}

/// A set of output files committed together; see the module documentation.
///
/// Dropping a set without [`OutputSet::commit`] removes its temporaries and leaves every
/// target untouched.
#[derive(Debug, Default)]
pub struct OutputSet {
    staged: Vec<Staged>,
    /// Staging directories ([`OutputSet::stage_dir`]): (the directory, its target).
    dirs: Vec<(PathBuf, PathBuf)>,
    /// Scratch files ([`OutputSet::scratch`]): removed with the set, never committed.
    scratch: Vec<PathBuf>,
    cleaned: HashSet<PathBuf>,
}

impl OutputSet {
    pub fn new() -> Self {
        OutputSet::default()
    }

    /// Files staged so far.
    pub fn len(&self) -> usize {
        self.staged.len()
    }

    pub fn is_empty(&self) -> bool {
        self.staged.is_empty()
    }

    /// Stage `bytes` for `path`.
    pub fn write(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        self.write_with(path, |w| w.write_all(bytes))
    }

    /// Stage `path`, streamed through a buffered writer by `f`. Nothing is visible at `path`
    /// until [`OutputSet::commit`]. Staging the same path again replaces the earlier content.
    pub fn write_with<F>(&mut self, path: &Path, f: F) -> Result<()>
    where
        F: FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
    {
        if path.file_name().is_none() {
            return Err(SceneError::format(path, "output path names no file"));
        }
        if std::fs::metadata(path).is_ok_and(|m| m.is_dir()) {
            return Err(SceneError::format(
                path,
                "output path is a directory, not a file",
            ));
        }
        let dir = parent_dir(path);
        if self.cleaned.insert(dir.clone()) {
            clean_stale(&dir);
        }
        let tmp = temp_name(path, Kind::Tmp);
        let result = (|| -> std::io::Result<()> {
            let file = File::create(&tmp)?;
            let mut w = BufWriter::with_capacity(1 << 20, file);
            f(&mut w)?;
            let file = w.into_inner().map_err(|e| e.into_error())?;
            // Data on disk before the rename makes it visible (a crash must not leave an
            // empty file under the final name); a file system without fsync still works.
            file.sync_data().ok();
            Ok(())
        })();
        if let Err(e) = result {
            let _ = std::fs::remove_file(&tmp);
            return Err(SceneError::io(path, e));
        }
        if let Some(i) = self.staged.iter().position(|s| s.target == path) {
            let old = std::mem::replace(&mut self.staged[i].tmp, tmp);
            let _ = std::fs::remove_file(old);
        } else {
            self.staged.push(Staged {
                tmp,
                target: path.to_path_buf(),
            });
        }
        Ok(())
    }

    /// A scratch file next to `target` (a writer's spool: data that is copied into an output
    /// before the set is committed), opened for reading and writing. It carries a temporary's
    /// name, so a run that is killed leaves nothing [`clean_stale`] does not remove, and it is
    /// deleted when the set is committed or dropped; it never becomes an output.
    pub fn scratch(&mut self, target: &Path) -> Result<(PathBuf, File)> {
        let dir = parent_dir(target);
        if self.cleaned.insert(dir.clone()) {
            clean_stale(&dir);
        }
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = temp_name(&dir.join(format!("{name}.spool")), Kind::Tmp);
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(|e| SceneError::io(target, e))?;
        self.scratch.push(tmp.clone());
        Ok((tmp, file))
    }

    /// A fresh staging directory for `target_dir` (created with its parents): a command whose
    /// library code writes into a directory writes there instead, and [`OutputSet::commit`]
    /// moves every file in it into `target_dir` with the rest of the set. Other files already
    /// in `target_dir` are kept (it may be `.`); only the set's own names are replaced.
    pub fn stage_dir(&mut self, target_dir: &Path) -> Result<PathBuf> {
        std::fs::create_dir_all(target_dir).map_err(|e| SceneError::io(target_dir, e))?;
        if self.cleaned.insert(target_dir.to_path_buf()) {
            clean_stale(target_dir);
        }
        let dir = temp_name(&target_dir.join("staging"), Kind::Tmp);
        std::fs::create_dir(&dir).map_err(|e| SceneError::io(target_dir, e))?;
        self.dirs.push((dir.clone(), target_dir.to_path_buf()));
        Ok(dir)
    }

    /// Stage the files of the staging directories (they stay where they are, named by their
    /// final names; the directory is removed after the commit).
    fn adopt_dirs(&mut self) -> Result<()> {
        for (dir, target) in &self.dirs {
            let entries = std::fs::read_dir(dir).map_err(|e| SceneError::io(dir, e))?;
            let mut files = Vec::new();
            for e in entries {
                let e = e.map_err(|e| SceneError::io(dir, e))?;
                let ty = e.file_type().map_err(|err| SceneError::io(e.path(), err))?;
                if !ty.is_file() {
                    return Err(SceneError::format(
                        e.path(),
                        "output staging holds a non-file; only flat file sets are committed",
                    ));
                }
                files.push(e.file_name());
            }
            files.sort();
            for name in files {
                let to = target.join(&name);
                if std::fs::metadata(&to).is_ok_and(|m| m.is_dir()) {
                    return Err(SceneError::format(
                        &to,
                        "output path is a directory, not a file",
                    ));
                }
                if let Some(i) = self.staged.iter().position(|s| s.target == to) {
                    let replaced = self.staged.remove(i);
                    let _ = std::fs::remove_file(replaced.tmp);
                }
                self.staged.push(Staged {
                    tmp: dir.join(&name),
                    target: to,
                });
            }
        }
        Ok(())
    }

    /// Rename every staged file onto its target. On failure, the targets renamed so far are
    /// put back as they were, every temporary is removed, and the error names the file whose
    /// rename failed.
    pub fn commit(mut self) -> Result<()> {
        for s in std::mem::take(&mut self.scratch) {
            let _ = std::fs::remove_file(s);
        }
        self.adopt_dirs()?;
        let staged = std::mem::take(&mut self.staged);
        // (target, backup of the previous file) for each rename done.
        let mut done: Vec<(&Path, Option<PathBuf>)> = Vec::with_capacity(staged.len());
        let mut failure = None;
        for s in &staged {
            let existing = std::fs::symlink_metadata(&s.target);
            if existing.as_ref().is_ok_and(|m| m.is_dir()) {
                // Checked when staged; a folder that appeared since is never moved aside.
                failure = Some(SceneError::format(
                    &s.target,
                    "output path is a directory, not a file",
                ));
                break;
            }
            let backup = if existing.is_ok() {
                let b = temp_name(&s.target, Kind::Old);
                if let Err(e) = std::fs::rename(&s.target, &b) {
                    failure = Some(SceneError::io(&s.target, e));
                    break;
                }
                Some(b)
            } else {
                None
            };
            if let Err(e) = std::fs::rename(&s.tmp, &s.target) {
                if let Some(b) = &backup {
                    let _ = std::fs::rename(b, &s.target);
                }
                failure = Some(SceneError::io(&s.target, e));
                break;
            }
            done.push((&s.target, backup));
        }
        if let Some(err) = failure {
            for (target, backup) in done.into_iter().rev() {
                let _ = std::fs::remove_file(target);
                if let Some(b) = backup {
                    let _ = std::fs::rename(b, target);
                }
            }
            for s in &staged {
                let _ = std::fs::remove_file(&s.tmp);
            }
            return Err(err);
        }
        for (_, backup) in done {
            if let Some(b) = backup {
                let _ = std::fs::remove_file(b);
            }
        }
        Ok(())
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        for s in &self.scratch {
            let _ = std::fs::remove_file(s);
        }
        for s in &self.staged {
            let _ = std::fs::remove_file(&s.tmp);
        }
        for (dir, _) in &self.dirs {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temp_names_parse_back() {
        let t = temp_name(Path::new("/x/out.gltf"), Kind::Tmp);
        let name = t.file_name().unwrap().to_str().unwrap();
        let (target, kind, pid) = parse_temp_name(name).unwrap();
        assert_eq!(
            (target, kind, pid),
            ("out.gltf", Kind::Tmp, std::process::id())
        );
        let o = temp_name(Path::new("a.b.c"), Kind::Old);
        let (target, kind, _) = parse_temp_name(o.file_name().unwrap().to_str().unwrap()).unwrap();
        assert_eq!((target, kind), ("a.b.c", Kind::Old));
    }

    #[test]
    fn names_of_others_do_not_parse() {
        for n in [
            "out.gltf",
            ".out.gltf",
            ".out.tmp.1",
            ".out.tmp12.",
            ".out.tmpx.3",
            ".out.tmp12.3a",
            "..tmp12.3",
            ".out.bak12.3",
            "out.tmp12.3",
        ] {
            assert_eq!(parse_temp_name(n), None, "{n}");
        }
    }
}
