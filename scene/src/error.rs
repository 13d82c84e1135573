//! One error type for everything the scene crate reads, validates or writes. Every variant
//! names the file (when there is one) and what was wrong, so the CLI can print
//! `error: FILE: message` without adding context of its own.

use std::path::PathBuf;

/// Errors from reading, validating or writing scenes, cameras and images.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// I/O failure on a named file. The OS error is part of the message and deliberately not
    /// a `source`, so error chains (`{:#}`) do not print it twice.
    #[error("{path}: {err}")]
    Io { path: PathBuf, err: std::io::Error },
    /// The file's content is malformed; `what` names the element, line or field.
    #[error("{path}: {what}")]
    Format { path: PathBuf, what: String },
    /// Invalid values that are not tied to a file (an in-memory cloud, a camera spec).
    #[error("{0}")]
    Invalid(String),
}

impl SceneError {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        SceneError::Io {
            path: path.into(),
            err: source,
        }
    }

    pub fn format(path: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        SceneError::Format {
            path: path.into(),
            what: what.into(),
        }
    }
}

pub type Result<T, E = SceneError> = std::result::Result<T, E>;
