//! Cancellation (`funcorr::progress`): a computation cancelled through its monitor, or by the
//! process-wide interrupt of the CLI's Ctrl-C, stops within a second with `Error::Cancelled`, in
//! every stage of the default pipeline, and the next computation runs normally.
//!
//! One test function: the process-wide interrupt would cancel any test running beside it.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use funcorr::descriptors::signatures::{wks_recipe, WksRecipe};
use funcorr::matching::{run, MatchOptions};
use funcorr::prepared::{LaplacianChoice, PreparedShape};
use funcorr::progress::{self, Monitor};
use funcorr::shape::{Shape, TriMesh};
use funcorr::Error;

/// Largest time from a cancellation to the return of the computation.
const LATENCY: Duration = Duration::from_secs(1);

/// The bundled shape `name`, subdivided once (midpoint): 19,990 vertices.
fn mesh(name: &str) -> TriMesh {
    match Shape::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/faust").join(name)).unwrap() {
        Shape::Mesh(m) => funcorr::primitives::midpoint_subdivision(&m).unwrap(),
        Shape::Points(_) => panic!("{name} is not a mesh"),
    }
}

/// Runs `f` under a fresh monitor on 2 threads of its own, cancels it once its stage is `stage`
/// (after `delay` more), and returns (its result, the stage it was cancelled in, the time from
/// the cancellation to its return). None for the stage when `f` ended before reaching `stage`.
fn cancel_at<T: Send>(
    stage: &str,
    delay: Duration,
    f: impl FnOnce() -> funcorr::Result<T> + Send,
) -> (funcorr::Result<T>, Option<String>, Duration) {
    let monitor = Monitor::new();
    let done = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let watcher = {
        let (monitor, done, stage) = (monitor.clone(), done.clone(), stage.to_string());
        std::thread::spawn(move || {
            while !done.load(std::sync::atomic::Ordering::SeqCst) {
                if monitor.status().stage == stage {
                    std::thread::sleep(delay);
                    let at = monitor.status().stage;
                    monitor.cancel();
                    return Some((at, Instant::now()));
                }
                std::thread::sleep(Duration::from_millis(2));
            }
            None
        })
    };
    let r = monitor.install(2, f);
    let returned = Instant::now();
    done.store(true, std::sync::atomic::Ordering::SeqCst);
    match watcher.join().unwrap() {
        Some((at, cancelled)) => (r, Some(at), returned.duration_since(cancelled)),
        None => (r, None, Duration::ZERO),
    }
}

#[test]
fn cancelled_computations_stop_within_a_second_in_every_stage() {
    let opts = MatchOptions::default();
    let k = opts.basis_size();
    let (x, y) = (mesh("tr_reg_000.off"), mesh("tr_reg_001.off"));
    let prepare = |m: &TriMesh| PreparedShape::new(Shape::Mesh(m.clone()), LaplacianChoice::Auto, k, None);

    // The eigensolver, 0.3 s into its iterations.
    let (r, at, latency) = cancel_at("eigenbasis", Duration::from_millis(300), || prepare(&x));
    assert_eq!(at.as_deref(), Some("eigenbasis"));
    assert!(matches!(r, Err(Error::Cancelled { ref stage }) if stage == "eigenbasis"), "{:?}", r.err());
    eprintln!("cancelled in eigenbasis: returned {latency:?} later");
    assert!(latency < LATENCY, "eigenbasis: {latency:?} after the cancellation");

    // Every stage of the default pipeline, 20 ms after it started.
    let (px, py) = (prepare(&x).unwrap(), prepare(&y).unwrap());
    let w = WksRecipe::default();
    let (f, g) = (wks_recipe(&px.basis, &w).unwrap(), wks_recipe(&py.basis, &w).unwrap());
    let stages = [
        "descriptors",
        "functional maps",
        "search samples",
        "candidate probes",
        "correction",
        "zoomout",
        "polish",
        "map Y → X",
    ];
    let order = |s: &str| stages.iter().position(|&t| t == s).unwrap_or_else(|| panic!("unknown stage {s}"));
    for stage in stages {
        let (r, at, latency) = cancel_at(stage, Duration::from_millis(20), || run(&px, &py, &f, &g, &opts));
        let at = at.unwrap_or_else(|| panic!("the pipeline never reached {stage}"));
        match r {
            // The stage that saw the cancellation: the one it was made in, or a later one when
            // that one ended in between.
            Err(Error::Cancelled { stage: s }) => {
                assert!(order(&s) >= order(&at), "cancelled in {at}, reported in {s}")
            }
            // Cancelled in the last 20 ms of the last stage: nothing left to check.
            Ok(_) => assert_eq!(at, "map Y → X", "cancelled in {at}, the pipeline still finished"),
            Err(e) => panic!("{stage}: {e}"),
        }
        eprintln!("cancelled in {at}: returned {latency:?} later");
        assert!(latency < LATENCY, "{stage} (cancelled in {at}): {latency:?} after the cancellation");
    }
    // Uncancelled, the same pipeline runs to its end (the cancellations left nothing behind).
    let full = Monitor::new().install(2, || run(&px, &py, &f, &g, &opts)).unwrap();
    assert_eq!(full.map_xy.len(), x.n_vertices());

    // The process-wide interrupt cancels computations on any thread, also without a monitor
    // (rayon's global pool), until cleared.
    let small = funcorr::primitives::bumpy_sphere(3);
    let basis = || PreparedShape::new(Shape::Mesh(small.clone()), LaplacianChoice::Auto, 20, None);
    progress::interrupt();
    assert!(matches!(basis(), Err(Error::Cancelled { .. })));
    let on_worker = rayon::join(progress::check, progress::check);
    assert!(on_worker.0.is_err() && on_worker.1.is_err());
    progress::clear_interrupt();
    assert_eq!(basis().unwrap().basis.k(), 20);
}
