"""The GIL is released around Rust computations: two Python threads compute at the same time,
and Python keeps running meanwhile."""
import threading
import time

import numpy as np

import funcorr


def calibrated_sources(mesh, seconds=0.8):
    """Sources whose exact geodesics take about `seconds` on one thread."""
    s = 4
    while True:
        t0 = time.perf_counter()
        funcorr.geodesic_distances(mesh, np.arange(s))
        took = time.perf_counter() - t0
        if took > seconds or s >= 1024:
            return s, took
        s *= 2


def run_with_ticks(mesh, jobs):
    """Runs `jobs` (lists of sources) on worker threads while this thread runs a Python loop;
    returns the workers' (start, end) and the times of the loop's iterations."""
    barrier = threading.Barrier(len(jobs) + 1)
    spans, results = {}, {}

    def work(i, sources):
        barrier.wait()
        t0 = time.perf_counter()
        results[i] = funcorr.geodesic_distances(mesh, sources)
        spans[i] = (t0, time.perf_counter())

    threads = [threading.Thread(target=work, args=(i, s)) for i, s in enumerate(jobs)]
    for t in threads:
        t.start()
    barrier.wait()
    ticks = []
    while any(t.is_alive() for t in threads):
        ticks.append(time.perf_counter())
    for t in threads:
        t.join()
    return spans, np.array(ticks), results


def largest_gap(ticks, start, end):
    inside = ticks[(ticks > start) & (ticks < end)]
    points = np.concatenate([[start], inside, [end]])
    return np.diff(points).max()


def test_two_threads_compute_at_the_same_time(mesh_y):
    P = funcorr.prepare(mesh_y, k=5)  # a prepared mesh: the calls convert no numpy input
    funcorr.set_num_threads(1)  # one thread per call: each call needs a thread of its own
    try:
        s, took = calibrated_sources(P)
        spans, ticks, results = run_with_ticks(P, [np.arange(s), np.arange(s, 2 * s)])
        (a0, a1), (b0, b1) = spans[0], spans[1]
        both = (max(a0, b0), min(a1, b1))
        # The two calls overlap in time ...
        assert both[1] - both[0] > 0.5 * min(a1 - a0, b1 - b0), (spans, s, took)
        # ... and while both were inside Rust, this thread kept running Python: with the GIL
        # held by a computation, it would have stopped for the whole computation (≈ `took`).
        assert largest_gap(ticks, *both) < 0.25 * took, (largest_gap(ticks, *both), took)
        assert results[0].shape == (P.n, s)
        assert np.array_equal(results[0][:, :1], funcorr.geodesic_distances(P, [0]))
    finally:
        funcorr.set_num_threads(None)


def test_python_runs_while_rust_computes(mesh_y):
    P = funcorr.prepare(mesh_y, k=5)
    funcorr.set_num_threads(1)
    try:
        s, took = calibrated_sources(P)
        spans, ticks, _ = run_with_ticks(P, [np.arange(s)])
        t0, t1 = spans[0]
        assert t1 - t0 > 0.5 * took
        assert largest_gap(ticks, t0, t1) < 0.25 * took, (largest_gap(ticks, t0, t1), took)
    finally:
        funcorr.set_num_threads(None)
