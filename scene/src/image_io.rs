//! Image output (8-bit PNG, float OpenEXR with RGBA and depth) and atomic file writing.

use std::io::Write;
use std::path::Path;

use crate::error::{Result, SceneError};
use crate::Frame;

/// Write `bytes` to `path` atomically: a temporary file in the same directory, renamed on
/// success, so a failure never leaves a partial file at the target.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    with_atomic_writer(path, |w| w.write_all(bytes))
}

/// Stream into `path` atomically through a buffered writer; the target appears only if `f`
/// and the final flush succeed.
pub fn with_atomic_writer<F>(path: &Path, f: F) -> Result<()>
where
    F: FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
{
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let result = (|| -> std::io::Result<()> {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
        f(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_data().ok();
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(SceneError::io(path, e));
    }
    Ok(())
}

/// Save a frame by extension: `.png` (8-bit RGB, values clamped to [0,1], no gamma: the
/// renderers' colours are already display values as 3DGS trains them) or `.exr` (float R, G,
/// B, A and a `Z` depth channel).
pub fn save_frame(path: &Path, frame: &Frame) -> Result<()> {
    let _ = frame;
    Err(SceneError::format(path, "image writing is not implemented yet"))
}
