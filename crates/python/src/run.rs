//! Running a library job from Python: the job runs on a thread of its own with the GIL
//! released, while the calling thread waits in steps of [`POLL`], passes the progress to the
//! Python callback and asks Python for pending signals (`Python::check_signals`, which runs
//! the `SIGINT` handler on the main thread). A `KeyboardInterrupt` (or an exception raised by
//! the callback) sets the stop flag the job's [`Progress::stopped`] reports and returns at
//! once: the job's thread ends at the library's next check and its result is dropped.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{RecvTimeoutError, channel};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use pyo3::exceptions::{PyKeyboardInterrupt, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use relief_heightfield::Progress;

/// How often the calling thread looks at signals and progress: a Ctrl-C returns within it.
const POLL: Duration = Duration::from_millis(50);

/// Why a job failed, as the Python exception it becomes.
#[derive(Debug)]
pub(crate) enum Failure {
    /// Bad parameters or inputs: `ValueError` with the library's message.
    Value(String),
    /// A file could not be read or written: `OSError`.
    Os(String),
    /// The run was asked to stop.
    Stopped,
}

impl Failure {
    /// A `ValueError` with the error's text (the library's message).
    pub(crate) fn value(e: impl std::fmt::Display) -> Self {
        Failure::Value(e.to_string())
    }

    /// The failure of a relief-io call: `OSError` for the operating system's errors,
    /// `ValueError` for a file relief-io cannot decode.
    pub(crate) fn io(e: relief_io::IoError) -> Self {
        match e {
            relief_io::IoError::Os { .. } => Failure::Os(e.to_string()),
            other => Failure::Value(other.to_string()),
        }
    }
}

impl From<Failure> for PyErr {
    fn from(f: Failure) -> PyErr {
        match f {
            Failure::Value(m) => PyValueError::new_err(m),
            Failure::Os(m) => PyOSError::new_err(m),
            Failure::Stopped => PyKeyboardInterrupt::new_err("relief: the run was interrupted"),
        }
    }
}

/// What the job reports, read by the calling thread.
#[derive(Debug, Default)]
struct Shared {
    /// Current phase and its total units.
    phase: Mutex<(String, u64)>,
    /// Reports queued since the caller last looked, `(phase, done, total)`: every phase begun
    /// (with 0 done) and every phase ended (with its last count), however short, so a bar
    /// of a phase shorter than the caller's poll still ends full.
    begun: Mutex<Vec<(String, u64, u64)>>,
    /// Units done in the phase.
    done: AtomicU64,
    /// Bumped on every report, so the caller only calls back on change.
    seq: AtomicU64,
    /// Set by the caller: the job's [`Progress::stopped`].
    stop: AtomicBool,
    /// A callback takes the reports (else phases are not queued).
    listening: bool,
}

/// The job's [`Progress`]: stores the reports for the calling thread.
#[derive(Debug, Clone)]
pub(crate) struct Reporter(Arc<Shared>);

impl Progress for Reporter {
    fn begin(&self, phase: &str, total: u64) {
        let previous = self
            .0
            .phase
            .lock()
            .map(|mut p| std::mem::replace(&mut *p, (phase.to_string(), total)))
            .unwrap_or_default();
        let done = self.0.done.swap(0, Ordering::Relaxed);
        if self.0.listening
            && let Ok(mut b) = self.0.begun.lock()
        {
            if !previous.0.is_empty() {
                b.push((previous.0, done, previous.1));
            }
            b.push((phase.to_string(), 0, total));
        }
        self.0.seq.fetch_add(1, Ordering::Relaxed);
    }

    fn advance(&self, n: u64) {
        self.0.done.fetch_add(n, Ordering::Relaxed);
        self.0.seq.fetch_add(1, Ordering::Relaxed);
    }

    fn stopped(&self) -> bool {
        self.0.stop.load(Ordering::Relaxed)
    }
}

impl Reporter {
    /// Whether the job was asked to stop (for jobs that take a `stop` closure).
    pub(crate) fn stop_flag(&self) -> bool {
        self.stopped()
    }
}

std::thread_local! {
    /// Wall time of the last job run from this thread, in seconds (see [`last_run_seconds`]).
    static LAST_RUN: std::cell::Cell<f64> = const { std::cell::Cell::new(0.0) };
}

/// Wall time in seconds of the last job run from the calling thread, measured on the job's
/// own thread from its start to its result: what a call costs beyond it is the Python layer's
/// (conversions, the thread, the polling). For the overhead row of `tests/test_bench.py`.
#[pyfunction]
pub(crate) fn last_run_seconds() -> f64 {
    LAST_RUN.with(|c| c.get())
}

/// Calls `callback(phase, done, total)` when the reports changed since `seen`.
fn report(
    py: Python<'_>,
    shared: &Shared,
    callback: Option<&Py<PyAny>>,
    seen: &mut u64,
) -> PyResult<()> {
    let Some(cb) = callback else {
        return Ok(());
    };
    let seq = shared.seq.load(Ordering::Relaxed);
    if seq == *seen {
        return Ok(());
    }
    *seen = seq;
    let begun = shared
        .begun
        .lock()
        .map(|mut b| std::mem::take(&mut *b))
        .unwrap_or_default();
    for (phase, done, total) in begun {
        cb.call1(py, (phase, done, total))?;
    }
    let (phase, total) = shared.phase.lock().map(|p| p.clone()).unwrap_or_default();
    let done = shared.done.load(Ordering::Relaxed);
    cb.call1(py, (phase, done, total))?;
    Ok(())
}

/// Runs `work` on its own thread with the GIL released (see the module docs). `work` gets the
/// [`Reporter`] to pass to the library as its progress.
pub(crate) fn run<T, F>(py: Python<'_>, callback: Option<Py<PyAny>>, work: F) -> PyResult<T>
where
    T: Send + 'static,
    F: FnOnce(&Reporter) -> Result<T, Failure> + Send + 'static,
{
    let shared = Arc::new(Shared {
        listening: callback.is_some(),
        ..Shared::default()
    });
    let reporter = Reporter(Arc::clone(&shared));
    let (tx, rx) = channel();
    std::thread::Builder::new()
        .name("relief-job".into())
        .spawn(move || {
            let t = std::time::Instant::now();
            let r = work(&reporter).map(|v| (v, t.elapsed().as_secs_f64()));
            // The caller may have returned (interrupted): nobody listens any more.
            let _ = tx.send(r);
        })
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start the job's thread: {e}")))?;
    // `detach` needs a `Sync` receiver: only this thread ever locks it.
    let rx = Mutex::new(rx);
    let mut seen = 0;
    loop {
        let got = py.detach(|| match rx.lock() {
            Ok(rx) => rx.recv_timeout(POLL),
            Err(_) => Err(RecvTimeoutError::Disconnected),
        });
        match got {
            Ok(result) => {
                report(py, &shared, callback.as_ref(), &mut seen)?;
                let (value, seconds) = result?;
                LAST_RUN.with(|c| c.set(seconds));
                return Ok(value);
            }
            Err(RecvTimeoutError::Timeout) => {
                let checked = report(py, &shared, callback.as_ref(), &mut seen)
                    .and_then(|()| py.check_signals());
                if let Err(e) = checked {
                    shared.stop.store(true, Ordering::Relaxed);
                    return Err(e);
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(PyRuntimeError::new_err(
                    "relief: the job's thread ended without a result (a bug: please report it)",
                ));
            }
        }
    }
}
