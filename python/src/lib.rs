//! `funcorr._funcorr`: the native module of the Python package `funcorr` (python/funcorr/).
//!
//! A thin layer over the library, as the CLI is: arguments are checked and converted
//! (`arrays`), every computation runs with the GIL released on a rayon pool of
//! `set_num_threads(n)` / `$FUNCORR_NUM_THREADS` threads (`compute`), and library errors become
//! Python exceptions naming the argument (`to_py`). The Python package wraps these functions
//! with docstrings, scipy.sparse matrices and result classes.

mod arrays;
mod functions;
mod matching;
mod options;
mod prepared;
mod viewer;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{mpsc, Arc, Mutex, Weak};
use std::time::Duration;

use funcorr::progress::{Monitor, Status};

use pyo3::exceptions::{PyFileNotFoundError, PyKeyboardInterrupt, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

/// Large arrays on transparent huge pages (`funcorr::alloc`): fewer page faults, same results.
#[global_allocator]
static ALLOC: funcorr::alloc::HugePageAlloc = funcorr::alloc::HugePageAlloc;

/// A library error as a Python exception: `FileNotFoundError` / `OSError` for files that cannot
/// be read or written, `RuntimeError` for numerical failures, `ValueError` for everything else
/// (malformed files, invalid parameters and inputs; the message names them).
pub(crate) fn to_py(e: funcorr::Error) -> PyErr {
    match &e {
        funcorr::Error::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(e.to_string())
        }
        funcorr::Error::Io { .. } => PyOSError::new_err(e.to_string()),
        funcorr::Error::Numerical { .. } => PyRuntimeError::new_err(e.to_string()),
        funcorr::Error::Cancelled { .. } => PyKeyboardInterrupt::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// Threads per call set by `set_num_threads` (0: not set).
static NUM_THREADS: AtomicUsize = AtomicUsize::new(0);

/// Threads per call: `set_num_threads`, else `$FUNCORR_NUM_THREADS`, else 0 (rayon's global
/// pool: every core, or `$RAYON_NUM_THREADS`).
fn threads() -> PyResult<usize> {
    let n = NUM_THREADS.load(Ordering::Relaxed);
    if n > 0 {
        return Ok(n);
    }
    match std::env::var("FUNCORR_NUM_THREADS") {
        Ok(s) if !s.trim().is_empty() => match s.trim().parse::<usize>() {
            Ok(n) => Ok(n),
            Err(_) => Err(PyValueError::new_err(format!(
                "FUNCORR_NUM_THREADS: expected a number of threads (0: all cores), got {s:?}"
            ))),
        },
        _ => Ok(0),
    }
}

/// How often a waiting call looks for Ctrl-C and reports progress.
const POLL: Duration = Duration::from_millis(50);

/// Computations running now, by the Python thread that started them (`threading.get_ident()`),
/// for [`_cancel_threads`].
static ACTIVE: Mutex<Vec<(u64, Weak<Monitor>)>> = Mutex::new(Vec::new());

/// One cancellable computation of a Python call (it may run several library calls, e.g. one per
/// chunk of `geodesic_all_pairs`): a [`Monitor`] and a rayon pool of [`threads`] threads of its
/// own whose workers run under it (so that concurrent calls from several Python threads or Ray
/// workers each use that many and no more, and cancelling one leaves the others alone), and the
/// progress reporter, a Python callable `report(stage, done, total)`.
pub(crate) struct Session {
    monitor: Arc<Monitor>,
    pool: rayon::ThreadPool,
    reporter: Option<Py<PyAny>>,
    /// The reporter raised: it is not called again.
    broken: std::sync::atomic::AtomicBool,
}

impl Session {
    /// A session reporting to `reporter` (None or Python None: no progress).
    pub(crate) fn new(reporter: Option<&Bound<'_, PyAny>>) -> PyResult<Session> {
        let n = threads()?;
        let monitor = Monitor::new();
        let pool = monitor
            .thread_pool(n)
            .build()
            .map_err(|e| PyRuntimeError::new_err(format!("could not start the threads of a computation: {e}")))?;
        // SAFETY: a plain C call, made with the GIL held.
        let thread = unsafe { pyo3::ffi::PyThread_get_thread_ident() } as u64;
        let mut active = ACTIVE.lock().unwrap_or_else(|e| e.into_inner());
        active.retain(|(_, m)| m.strong_count() > 0);
        active.push((thread, Arc::downgrade(&monitor)));
        let reporter = reporter.filter(|r| !r.is_none()).map(|r| r.clone().unbind());
        Ok(Session { monitor, pool, reporter, broken: Default::default() })
    }

    /// Runs `f` with the GIL released on the session's pool. The calling thread waits, and
    /// every [`POLL`] takes the GIL to report progress and to run Python's signal handlers: on
    /// Ctrl-C (KeyboardInterrupt from the handler) the computation is cancelled, and once it has
    /// stopped (at its next check, [`funcorr::progress`]) the KeyboardInterrupt is raised. A
    /// computation cancelled by [`_cancel_threads`] raises KeyboardInterrupt too.
    pub(crate) fn run<T: Send>(&self, py: Python<'_>, f: impl FnOnce() -> funcorr::Result<T> + Send) -> PyResult<T> {
        let monitor = &self.monitor;
        let (result, interrupt) = py.detach(|| {
            let (tx, rx) = mpsc::channel();
            let mut interrupt: Option<PyErr> = None;
            let result = self.pool.in_place_scope(|s| {
                s.spawn(move |_| {
                    let _ = tx.send(monitor.run(f));
                });
                loop {
                    match rx.recv_timeout(POLL) {
                        Ok(r) => return Some(r),
                        // The computation panicked: the scope raises the panic.
                        Err(mpsc::RecvTimeoutError::Disconnected) => return None,
                        Err(mpsc::RecvTimeoutError::Timeout) if interrupt.is_none() => Python::attach(|py| {
                            if let Err(e) = py.check_signals() {
                                monitor.cancel();
                                interrupt = Some(e);
                            } else {
                                // Also when unchanged: the reporter redraws the elapsed time.
                                self.report_now(py, &monitor.status());
                            }
                        }),
                        Err(mpsc::RecvTimeoutError::Timeout) => {}
                    }
                }
            });
            (result, interrupt)
        });
        if let Some(e) = interrupt {
            return Err(e);
        }
        match result {
            Some(r) => r.map_err(to_py),
            None => Err(PyRuntimeError::new_err("the computation stopped without a result")),
        }
    }

    /// Reports `status` to the reporter now (with the GIL held), e.g. between library calls.
    pub(crate) fn report_now(&self, py: Python<'_>, status: &Status) {
        if let (Some(r), false) = (&self.reporter, self.broken.load(Ordering::Relaxed)) {
            if !report(py, r, status) {
                self.broken.store(true, Ordering::Relaxed);
            }
        }
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        let mut active = ACTIVE.lock().unwrap_or_else(|e| e.into_inner());
        active.retain(|(_, m)| m.strong_count() > 0 && !std::ptr::eq(m.as_ptr(), Arc::as_ptr(&self.monitor)));
    }
}

/// Calls the reporter; an exception it raises is printed (as an unraisable exception) and
/// otherwise ignored: progress output never fails a computation. Returns whether it succeeded.
fn report(py: Python<'_>, reporter: &Py<PyAny>, status: &Status) -> bool {
    match reporter.call1(py, (status.stage.as_str(), status.done, status.total)) {
        Ok(_) => true,
        Err(e) => {
            e.write_unraisable(py, Some(reporter.bind(py)));
            false
        }
    }
}

/// Runs a library computation with the GIL released on a pool of its own, cancellable by
/// Ctrl-C ([`Session::run`]), without progress output.
pub(crate) fn compute<T: Send>(py: Python<'_>, f: impl FnOnce() -> funcorr::Result<T> + Send) -> PyResult<T> {
    Session::new(None)?.run(py, f)
}

/// [`compute`] reporting progress to `reporter` (a callable `report(stage, done, total)`, or
/// None).
pub(crate) fn compute_reporting<T: Send>(
    py: Python<'_>,
    reporter: Option<&Bound<'_, PyAny>>,
    f: impl FnOnce() -> funcorr::Result<T> + Send,
) -> PyResult<T> {
    Session::new(reporter)?.run(py, f)
}

/// Cancels the computations running now that were started by the Python threads `threads`
/// (`threading.get_ident()` values): each raises KeyboardInterrupt in its thread once it has
/// stopped. Returns how many were cancelled. (For `funcorr.batch`: Ctrl-C in the main thread
/// stops the pair jobs of its worker threads.)
#[pyfunction]
fn _cancel_threads(threads: Vec<u64>) -> usize {
    let active = ACTIVE.lock().unwrap_or_else(|e| e.into_inner());
    let mut count = 0;
    for (t, m) in active.iter() {
        if let (true, Some(m)) = (threads.contains(t), m.upgrade()) {
            m.cancel();
            count += 1;
        }
    }
    count
}

/// Sets the number of threads each funcorr call uses (None or 0: the default, every core or
/// `$FUNCORR_NUM_THREADS`). Each call runs on a pool of that many threads of its own. A negative
/// or non-integer count is a ValueError.
#[pyfunction]
#[pyo3(signature = (n=None))]
fn set_num_threads(n: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
    let n = match n {
        None => 0,
        Some(v) if v.is_none() => 0,
        Some(v) => {
            let bad = || {
                PyValueError::new_err(format!(
                    "n: expected a number of threads ≥ 0 (0 or None: every core), got {}",
                    v.repr().map(|r| r.to_string()).unwrap_or_default()
                ))
            };
            if v.is_instance_of::<pyo3::types::PyBool>() {
                return Err(bad());
            }
            let i: i64 = v.extract().map_err(|_| bad())?;
            if !(0..=MAX_THREADS as i64).contains(&i) {
                return Err(bad());
            }
            i as usize
        }
    };
    NUM_THREADS.store(n, Ordering::Relaxed);
    Ok(())
}

/// Most threads `set_num_threads` accepts (far above any machine's cores; beyond it a count is
/// surely a mistake).
const MAX_THREADS: usize = 1 << 16;

/// The number of threads a funcorr call uses now (the setting, `$FUNCORR_NUM_THREADS`, or the
/// size of rayon's global pool).
#[pyfunction]
fn get_num_threads() -> PyResult<usize> {
    Ok(match threads()? {
        0 => rayon::current_num_threads(),
        n => n,
    })
}

/// The number of rayon threads a computation runs on with the current setting (what the pool of
/// [`compute`] gives; for the tests of `set_num_threads`).
#[pyfunction]
fn _pool_threads(py: Python<'_>) -> PyResult<usize> {
    compute(py, || Ok(rayon::current_num_threads()))
}

#[pymodule]
fn _funcorr(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(set_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(get_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(_pool_threads, m)?)?;
    m.add_function(wrap_pyfunction!(_cancel_threads, m)?)?;
    functions::register(m)?;
    prepared::register(m)?;
    matching::register(m)?;
    viewer::register(m)?;
    Ok(())
}
