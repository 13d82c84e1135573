//! The ray tracer's error type: every variant names the file (when there is one) and what was
//! wrong, so the CLI can print `error: FILE: message` as is.

use std::path::PathBuf;

/// Errors from loading scenes, building acceleration structures and rendering.
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    /// The input file is malformed; `what` names the element (node, accessor, line) and the fault.
    #[error("{path}: {what}")]
    Format { path: PathBuf, what: String },
    /// I/O failure on a named file. The OS error is part of the message and deliberately not
    /// a `source`, so error chains (`{:#}`) print it once.
    #[error("{path}: {err}")]
    Io { path: PathBuf, err: std::io::Error },
    /// Invalid arguments or values not tied to a file (a camera, an option, a backend).
    #[error("{0}")]
    Invalid(String),
    /// A backend could not be used (not compiled in, or its library failed).
    #[error("{0}")]
    Backend(String),
    /// Errors from the shared scene model.
    #[error(transparent)]
    Scene(#[from] splatbridge_scene::SceneError),
}

impl TraceError {
    pub fn format(path: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        TraceError::Format {
            path: path.into(),
            what: what.into(),
        }
    }
}

pub type Result<T, E = TraceError> = std::result::Result<T, E>;
