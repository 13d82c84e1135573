//! `splatbridge._native`: the Python extension module behind `import splatbridge`.
//!
//! Every function calls the library functions the CLI calls (`splatbridge::pipeline`,
//! `splatbridge::measure`, the stage crates), so a Python call and the matching command give
//! the same bytes and the same figures. Work runs with the GIL released on a worker thread
//! ([`run`]); the calling thread checks for signals while it waits, so Ctrl-C stops a long
//! call. Errors are [`Error`] exceptions carrying the CLI's message text (`error: …` without
//! the prefix).
//!
//! - [`scene`]: `Scene` (arrays viewed without copies), `load`, `save`, `Scene.from_arrays`.
//! - [`camera`]: `Camera` from OpenCV world-to-camera matrices, 3DGS `cameras.json` and specs.
//! - [`render`]: `render` (native splatting), `trace`, `hybrid`, `save_image`.
//! - [`convert`]: `convert` (meshes, splat files, distillation) and `compare`.

use pyo3::prelude::*;

mod camera;
mod convert;
mod render;
mod run;
mod scene;

pyo3::create_exception!(
    splatbridge,
    Error,
    pyo3::exceptions::PyException,
    "A splatbridge call failed; the message is the one the command line prints after `error: `."
);

/// An error of the library as the Python exception [`Error`], with the CLI's text.
pub(crate) fn to_py(e: anyhow::Error) -> PyErr {
    Error::new_err(format!("{e:#}"))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    scene::register(m)?;
    camera::register(m)?;
    render::register(m)?;
    convert::register(m)?;
    Ok(())
}
