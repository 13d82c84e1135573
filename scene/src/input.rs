//! Guards for every file the project reads: only regular files are opened (a FIFO, a character
//! device such as `/dev/zero` or a directory is refused before anything blocks or reads), and
//! whole-file reads are bounded by a documented size cap, so no input makes a reader block,
//! read forever or allocate more than the cap.
//!
//! Caps (bytes a reader loads into memory at once; streaming readers such as the PLY reader
//! check counts against the file size instead and need no cap):
//! - [`Cap::Text`]: JSON documents (scene manifests, `cameras.json`), 64 MiB. The largest
//!   real `cameras.json` in 3DGS captures is well under 1 MiB; 64 MiB leaves a wide margin.
//! - [`Cap::Mesh`]: glTF/GLB files and their buffers, OBJ and MTL files, 4 GiB (the GLB
//!   length field is a u32, so no valid GLB is larger).
//!
//! Both caps can be raised (or lowered) with the environment variable
//! `SPLATBRIDGE_MAX_INPUT_MB` (mebibytes; applies to every cap).
//!
//! Messages never echo more than [`ECHO_LIMIT`] bytes of file content ([`clip`]).

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::{Result, SceneError};

/// The environment variable that overrides every cap, in mebibytes.
pub const MAX_INPUT_ENV: &str = "SPLATBRIDGE_MAX_INPUT_MB";

/// Longest piece of file content an error message echoes (bytes, before the ellipsis).
pub const ECHO_LIMIT: usize = 64;

/// Which size cap a whole-file read is held to (see the module docs for the numbers).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cap {
    /// JSON documents: manifests and camera files.
    Text,
    /// Triangle-scene files: glTF/GLB and their buffers and images, OBJ and MTL.
    Mesh,
}

impl Cap {
    /// The cap in bytes: the environment override when set and valid, else the default.
    pub fn bytes(self) -> u64 {
        if let Some(mb) = std::env::var(MAX_INPUT_ENV)
            .ok()
            .and_then(|v| v.trim().parse::<u64>().ok())
        {
            return mb.saturating_mul(1 << 20);
        }
        match self {
            Cap::Text => 64 << 20,
            Cap::Mesh => 4 << 30,
        }
    }
}

fn not_regular(path: &Path) -> SceneError {
    SceneError::format(path, "not a regular file")
}

/// Open `path` for reading only if it is a regular file; returns the file and its length.
/// FIFOs are refused before `open` (which would block waiting for a writer), and the opened
/// descriptor is checked again, so a path swapped in between is refused too.
pub fn open_regular(path: &Path) -> Result<(File, u64)> {
    let meta = std::fs::metadata(path).map_err(|e| SceneError::io(path, e))?;
    if !meta.is_file() {
        return Err(not_regular(path));
    }
    let mut opts = std::fs::OpenOptions::new();
    opts.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        // A FIFO swapped in after the check above must not block `open`; on regular files
        // O_NONBLOCK has no effect.
        opts.custom_flags(libc::O_NONBLOCK);
    }
    let file = opts.open(path).map_err(|e| SceneError::io(path, e))?;
    let meta = file.metadata().map_err(|e| SceneError::io(path, e))?;
    if !meta.is_file() {
        return Err(not_regular(path));
    }
    Ok((file, meta.len()))
}

/// Check a path names a regular file (without opening it); for files another library opens.
pub fn check_regular(path: &Path) -> Result<u64> {
    let meta = std::fs::metadata(path).map_err(|e| SceneError::io(path, e))?;
    if !meta.is_file() {
        return Err(not_regular(path));
    }
    Ok(meta.len())
}

/// Check a regular file's size against a cap (without reading it).
pub fn check_size(path: &Path, len: u64, cap: Cap) -> Result<()> {
    let max = cap.bytes();
    if len > max {
        return Err(SceneError::format(
            path,
            format!(
                "file is {len} bytes, more than the {max}-byte limit (raise it with {MAX_INPUT_ENV}=MEBIBYTES)"
            ),
        ));
    }
    Ok(())
}

/// Read a whole regular file, refusing one larger than `cap`. At most cap + 1 bytes are ever
/// read, so a file that grows while it is read (or lies about its size, as `/proc` files do)
/// cannot make this read forever.
pub fn read_bounded(path: &Path, cap: Cap) -> Result<Vec<u8>> {
    let (file, len) = open_regular(path)?;
    check_size(path, len, cap)?;
    let max = cap.bytes();
    let mut out = Vec::with_capacity(len.min(max) as usize);
    file.take(max.saturating_add(1))
        .read_to_end(&mut out)
        .map_err(|e| SceneError::io(path, e))?;
    if out.len() as u64 > max {
        return Err(SceneError::format(
            path,
            format!(
                "file grew past the {max}-byte limit while it was read (raise it with {MAX_INPUT_ENV}=MEBIBYTES)"
            ),
        ));
    }
    Ok(out)
}

/// [`read_bounded`] for UTF-8 text.
pub fn read_text_bounded(path: &Path, cap: Cap) -> Result<String> {
    let bytes = read_bounded(path, cap)?;
    String::from_utf8(bytes).map_err(|e| {
        SceneError::format(
            path,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        )
    })
}

/// Refuse a scene read from a file that holds no Gaussians at all (a mesh glTF given where
/// `KHR_gaussian_splatting` splats were expected), rather than writing an empty output.
pub fn require_gaussians(path: &Path, scene: &crate::dynamic::DynamicScene) -> Result<()> {
    if scene.gaussian_count() == 0 {
        return Err(SceneError::format(
            path,
            "holds no Gaussians (no KHR_gaussian_splatting primitives; a mesh glTF cannot be converted)",
        ));
    }
    Ok(())
}

/// A piece of file content for an error message: at most [`ECHO_LIMIT`] bytes (cut at a
/// character boundary), followed by the total length when it was cut.
pub fn clip(s: &str) -> String {
    clip_to(s, ECHO_LIMIT)
}

/// [`clip`] with a given limit, for whole messages of a third-party parser (which may quote
/// an unknown key or value of any length).
pub fn clip_to(s: &str, limit: usize) -> String {
    if s.len() <= limit {
        return s.to_string();
    }
    let mut end = limit;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}… ({} bytes)", &s[..end], s.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clip_keeps_short_text_and_cuts_long_text_at_a_char_boundary() {
        assert_eq!(clip("abc"), "abc");
        let long = "é".repeat(1000);
        let c = clip(&long);
        assert!(c.len() < ECHO_LIMIT + 32, "{c}");
        assert!(c.ends_with("(2000 bytes)"), "{c}");
    }

    #[test]
    fn directories_and_devices_are_not_regular_files() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_bounded(dir.path(), Cap::Text).unwrap_err().to_string();
        assert!(e.ends_with("not a regular file"), "{e}");
        if Path::new("/dev/zero").exists() {
            let e = read_bounded(Path::new("/dev/zero"), Cap::Text)
                .unwrap_err()
                .to_string();
            assert!(e.ends_with("not a regular file"), "{e}");
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_refused_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("fifo");
        let c = std::ffi::CString::new(p.to_str().unwrap()).unwrap();
        // SAFETY: `c` is a valid NUL-terminated path that outlives the call.
        let rc = unsafe { libc::mkfifo(c.as_ptr(), 0o600) };
        assert_eq!(rc, 0);
        let e = read_bounded(&p, Cap::Text).unwrap_err().to_string();
        assert!(e.ends_with("not a regular file"), "{e}");
    }

    #[test]
    fn regular_files_read_whole() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.json");
        std::fs::write(&p, b"[1, 2]").unwrap();
        assert_eq!(read_text_bounded(&p, Cap::Text).unwrap(), "[1, 2]");
    }
}
