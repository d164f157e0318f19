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

use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

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

/// Runs a library computation with the GIL released, on a pool of [`threads`] threads of its
/// own (so that concurrent calls from several Python threads or Ray workers each use that many
/// and no more), or on rayon's global pool when no thread count is set.
pub(crate) fn compute<T: Send>(py: Python<'_>, f: impl FnOnce() -> funcorr::Result<T> + Send) -> PyResult<T> {
    let n = threads()?;
    py.detach(|| -> PyResult<T> {
        if n == 0 {
            return f().map_err(to_py);
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .thread_name(|i| format!("funcorr-{i}"))
            .build()
            .map_err(|e| PyRuntimeError::new_err(format!("could not start {n} threads: {e}")))?;
        pool.install(f).map_err(to_py)
    })
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
    functions::register(m)?;
    prepared::register(m)?;
    matching::register(m)?;
    viewer::register(m)?;
    Ok(())
}
