//! Running library work from Python: on a worker thread with the GIL released, while the
//! calling thread waits in short slices and checks for signals between them (Python runs
//! signal handlers only on the main thread, and only while it holds the GIL).
//!
//! On Ctrl-C the cancel flag is set; work that reports progress (frames, comparison stages,
//! distillation steps) calls [`Cancel::check`], which unwinds out of the library with a
//! [`Cancelled`] payload. The worker catches it, nothing is committed (the library writes
//! outputs atomically), and the call raises `KeyboardInterrupt`. Work without progress
//! points (one frame) ends first.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Once};
use std::time::Duration;

use pyo3::prelude::*;

/// How often the waiting thread looks for signals: short enough that Ctrl-C feels immediate,
/// long enough that waking costs nothing measurable (one wake per 50 ms).
const SLICE: Duration = Duration::from_millis(50);

/// The payload of the unwind that stops cancelled work.
struct Cancelled;

/// The cancel flag handed to the work.
pub struct Cancel(AtomicBool);

impl Cancel {
    /// Stop here when Ctrl-C was pressed.
    pub fn check(&self) {
        if self.0.load(Ordering::Relaxed) {
            std::panic::panic_any(Cancelled);
        }
    }
}

/// Keep the panic hook quiet for [`Cancelled`] (a cancellation is not a bug to report).
fn quiet_cancel_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if info.payload().downcast_ref::<Cancelled>().is_none() {
                previous(info);
            }
        }));
    });
}

/// Run `work` without the GIL on a worker thread; Ctrl-C cancels it (see the module docs).
pub fn run<T, F>(py: Python<'_>, work: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce(&Cancel) -> anyhow::Result<T> + Send,
{
    quiet_cancel_hook();
    let cancel = Cancel(AtomicBool::new(false));
    let mut interrupted: Option<PyErr> = None;
    let outcome = std::thread::scope(|s| {
        let (tx, mut rx) = mpsc::channel::<()>();
        let cancel = &cancel;
        let worker = s.spawn(move || {
            let r = catch_unwind(AssertUnwindSafe(|| work(cancel)));
            let _ = tx.send(());
            r
        });
        loop {
            let (back, got) = py.detach(move || {
                let got = rx.recv_timeout(SLICE);
                (rx, got)
            });
            rx = back;
            if !matches!(got, Err(mpsc::RecvTimeoutError::Timeout)) {
                break;
            }
            if interrupted.is_none() {
                if let Err(e) = py.check_signals() {
                    cancel.0.store(true, Ordering::Relaxed);
                    interrupted = Some(e);
                }
            }
        }
        worker.join()
    });
    if let Some(e) = interrupted {
        return Err(e);
    }
    match outcome {
        Ok(Ok(Ok(v))) => Ok(v),
        Ok(Ok(Err(e))) => Err(crate::to_py(e)),
        Ok(Err(payload)) | Err(payload) => {
            let what = payload
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "a panic".into());
            Err(pyo3::exceptions::PyRuntimeError::new_err(format!(
                "internal error: {what}"
            )))
        }
    }
}
