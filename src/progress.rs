//! Progress and cancellation of long computations.
//!
//! A long computation (an eigenbasis, the matching pipeline, geodesics from many sources) calls
//! [`stage`] when it starts a stage, [`step`] as it advances inside one, and [`check`] at the
//! boundaries of its loops (solver iterations, ZoomOut steps, fit sizes, the basin search's
//! probes and correction rounds, geodesic sources). Each returns [`Error::Cancelled`] once the
//! computation is cancelled, which the computation passes up with `?`: it stops at the next
//! boundary, frees what it holds and returns, leaving no partial file (outputs are written
//! atomically or published whole, [`crate::io::staged`]). Between boundaries nothing is checked,
//! so the latency of a cancellation is the longest step between two checks (well under a second
//! on shapes of 50k vertices).
//!
//! Who asks, and how:
//! - **A process-wide interrupt** ([`interrupt`], set by [`interrupt_on_sigint`]'s SIGINT
//!   handler in the CLI): every computation of the process sees it, on every thread.
//! - **A [`Monitor`]**, one per computation (the Python bindings make one per call): it carries
//!   the computation's cancellation flag and its [`Status`] (stage and steps, for a progress bar
//!   drawn by whoever holds the monitor). A thread sees the monitor it runs under
//!   ([`Monitor::run`]); the worker threads of a pool built with [`Monitor::thread_pool`] run
//!   under it for their whole life, so the parallel parts of the computation see it too.
//!   Monitors are per thread, not global: cancelling one computation leaves the others running.
//!   (On rayon's global pool, whose workers serve every computation, only the thread that called
//!   [`Monitor::run`] sees the monitor; give a cancellable computation a pool of its own.)
//!
//! Without either, [`check`] costs a thread-local read and an atomic load, and [`stage`] and
//! [`step`] record nothing.

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use crate::error::{Error, Result};

/// What a computation is doing: its current stage and, when the stage counts its steps, how
/// many of how many are done (`total` 0: not counted).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Status {
    /// The stage's name (`"eigenbasis"`, `"zoomout"`, ...); empty before the first stage.
    pub stage: String,
    /// Steps done in the stage.
    pub done: usize,
    /// Steps of the stage (0: not counted).
    pub total: usize,
}

/// The cancellation flag and progress of one computation (module docs).
#[derive(Debug, Default)]
pub struct Monitor {
    cancelled: AtomicBool,
    status: Mutex<Status>,
}

thread_local! {
    /// The monitor the current thread runs under.
    static CURRENT: RefCell<Option<Arc<Monitor>>> = const { RefCell::new(None) };
}

/// Set by [`interrupt`]: every computation of the process is cancelled.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

impl Monitor {
    /// A monitor of a computation not yet cancelled, without a stage.
    pub fn new() -> Arc<Monitor> {
        Arc::new(Monitor::default())
    }

    /// Cancels the computation: its next [`check`] (on any thread running under this monitor)
    /// returns [`Error::Cancelled`]. Callable from any thread, any number of times.
    pub fn cancel(&self) {
        self.cancelled.store(true, Ordering::SeqCst);
    }

    /// Whether [`Monitor::cancel`] was called.
    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::SeqCst)
    }

    /// The computation's stage and steps now.
    pub fn status(&self) -> Status {
        self.status.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Runs `f` on this thread under this monitor (the one it ran under before is restored
    /// afterwards, also when `f` panics).
    pub fn run<T>(self: &Arc<Self>, f: impl FnOnce() -> T) -> T {
        struct Restore(Option<Arc<Monitor>>);
        impl Drop for Restore {
            fn drop(&mut self) {
                let previous = self.0.take();
                CURRENT.with(|c| *c.borrow_mut() = previous);
            }
        }
        let previous = CURRENT.with(|c| c.borrow_mut().replace(self.clone()));
        let _restore = Restore(previous);
        f()
    }

    /// A rayon pool builder of `threads` threads (0: rayon's default count) whose workers run
    /// under this monitor for their whole life: the parallel parts of a computation installed
    /// on that pool see its cancellation.
    pub fn thread_pool(self: &Arc<Self>, threads: usize) -> rayon::ThreadPoolBuilder {
        let monitor = self.clone();
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("funcorr-{i}"))
            .start_handler(move |_| CURRENT.with(|c| *c.borrow_mut() = Some(monitor.clone())))
    }

    /// Runs `f` under this monitor on a pool of `threads` threads of its own (0: rayon's
    /// default count), built with [`Monitor::thread_pool`]. Errors: the pool's threads cannot
    /// be started, and those of `f`.
    pub fn install<T: Send>(self: &Arc<Self>, threads: usize, f: impl FnOnce() -> Result<T> + Send) -> Result<T> {
        let pool = self
            .thread_pool(threads)
            .build()
            .map_err(|e| Error::numerical("thread pool", format!("could not start the threads: {e}")))?;
        pool.install(|| self.run(f))
    }

    fn set(&self, f: impl FnOnce(&mut Status)) {
        f(&mut self.status.lock().unwrap_or_else(|e| e.into_inner()));
    }
}

/// Cancels every computation of the process (their next [`check`] fails) until
/// [`clear_interrupt`]. Async-signal-safe: one atomic store, for signal handlers.
pub fn interrupt() {
    INTERRUPTED.store(true, Ordering::SeqCst);
}

/// Whether [`interrupt`] was called (and not cleared since).
pub fn is_interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// Undoes [`interrupt`]: computations started afterwards run normally.
pub fn clear_interrupt() {
    INTERRUPTED.store(false, Ordering::SeqCst);
}

/// The monitor the current thread runs under, if any.
pub fn current() -> Option<Arc<Monitor>> {
    CURRENT.with(|c| c.borrow().clone())
}

/// Whether the computation on this thread is cancelled (by [`interrupt`] or its monitor). For
/// the inside of parallel loops, which cannot return an error: skip the work when true, and
/// [`check`] after the loop.
pub fn cancelled() -> bool {
    INTERRUPTED.load(Ordering::Relaxed)
        || CURRENT.with(|c| c.borrow().as_ref().is_some_and(|m| m.cancelled.load(Ordering::Relaxed)))
}

/// [`Error::Cancelled`] when the computation on this thread is cancelled ([`cancelled`]), naming
/// its stage; else `Ok`.
pub fn check() -> Result<()> {
    if !cancelled() {
        return Ok(());
    }
    let stage = current().map(|m| m.status().stage).unwrap_or_default();
    Err(Error::Cancelled { stage })
}

/// Starts stage `name` of the computation on this thread (its steps reset to 0 of 0), after a
/// [`check`].
pub fn stage(name: &str) -> Result<()> {
    check()?;
    if let Some(m) = current() {
        m.set(|s| {
            if s.stage != name {
                s.stage.clear();
                s.stage.push_str(name);
            }
            (s.done, s.total) = (0, 0);
        });
    }
    Ok(())
}

/// Records `done` of `total` steps of the current stage, after a [`check`].
pub fn step(done: usize, total: usize) -> Result<()> {
    check()?;
    if let Some(m) = current() {
        m.set(|s| (s.done, s.total) = (done, total));
    }
    Ok(())
}

/// Makes SIGINT (Ctrl-C) [`interrupt`] every computation instead of killing the process; a second
/// SIGINT kills it as usual (the handler resets itself). For command-line programs: their
/// computations then stop at the next [`check`] with [`Error::Cancelled`], and the program can
/// clean up and exit with a message. Errors: the handler cannot be installed.
#[cfg(unix)]
pub fn interrupt_on_sigint() -> Result<()> {
    extern "C" fn on_sigint(_: libc::c_int) {
        interrupt();
    }
    // SAFETY: a zeroed sigaction is valid (empty mask, no flags); the handler only stores to an
    // atomic, which is async-signal-safe.
    let ok = unsafe {
        let mut action: libc::sigaction = std::mem::zeroed();
        action.sa_sigaction = on_sigint as extern "C" fn(libc::c_int) as libc::sighandler_t;
        action.sa_flags = libc::SA_RESETHAND | libc::SA_RESTART;
        libc::sigemptyset(&mut action.sa_mask);
        libc::sigaction(libc::SIGINT, &action, std::ptr::null_mut()) == 0
    };
    if ok {
        Ok(())
    } else {
        Err(Error::io("<SIGINT handler>", std::io::Error::last_os_error()))
    }
}

/// Without Unix signals: nothing to install (Ctrl-C ends the process as usual).
#[cfg(not(unix))]
pub fn interrupt_on_sigint() -> Result<()> {
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;
    use std::time::{Duration, Instant};

    #[test]
    fn a_cancelled_monitor_fails_the_checks_of_its_threads_only() {
        let m = Monitor::new();
        let other = Monitor::new();
        m.run(|| {
            stage("eigenbasis").unwrap();
            step(3, 10).unwrap();
            assert_eq!(m.status(), Status { stage: "eigenbasis".into(), done: 3, total: 10 });
            m.cancel();
            match check() {
                Err(Error::Cancelled { stage }) => assert_eq!(stage, "eigenbasis"),
                r => panic!("{r:?}"),
            }
            assert!(stage("zoomout").is_err() && step(4, 10).is_err());
            // Nested: another monitor's computation on this thread is not cancelled, and the
            // cancelled one is back afterwards.
            other.run(|| assert!(check().is_ok() && stage("other").is_ok()));
            assert!(check().is_err());
        });
        // Outside any monitor (and in another thread) nothing is cancelled.
        assert!(check().is_ok());
        std::thread::spawn(|| assert!(check().is_ok())).join().unwrap();
        assert_eq!(other.status().stage, "other");
        assert!(current().is_none());
    }

    #[test]
    fn the_workers_of_a_monitors_pool_see_its_cancellation() {
        let m = Monitor::new();
        // A parallel loop that skips its work once cancelled, then checks: cancelled from
        // another thread after 100 ms, it ends within a few iterations, with Cancelled.
        let canceller = {
            let m = m.clone();
            std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(100));
                m.cancel();
            })
        };
        let t = Instant::now();
        let r = m.install(2, || {
            stage("loop")?;
            let done: usize = (0..10_000)
                .into_par_iter()
                .map(|_| {
                    if cancelled() {
                        return 0;
                    }
                    std::thread::sleep(Duration::from_millis(5));
                    1
                })
                .sum();
            check()?;
            Ok(done)
        });
        canceller.join().unwrap();
        assert!(matches!(r, Err(Error::Cancelled { ref stage }) if stage == "loop"), "{r:?}");
        // 10,000 × 5 ms on 2 threads would take 25 s.
        assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
        // The same work under a monitor nobody cancels completes.
        let fresh = Monitor::new();
        let all = fresh.install(2, || Ok((0..100).into_par_iter().map(|_| usize::from(!cancelled())).sum::<usize>()));
        assert_eq!(all.unwrap(), 100);
    }
}
