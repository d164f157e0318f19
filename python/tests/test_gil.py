"""The GIL is released around Rust computations: two Python threads compute at the same time."""
import threading
import time

import numpy as np

import funcorr


def test_two_threads_compute_at_the_same_time(mesh_y):
    funcorr.set_num_threads(1)  # one thread per call: two calls need two threads of their own
    try:
        # Calibrate a call of about 0.6 s (exact geodesics from s sources).
        s = 4
        while True:
            t0 = time.perf_counter()
            funcorr.geodesic_distances(mesh_y, np.arange(s))
            took = time.perf_counter() - t0
            if took > 0.6 or s > 4096:
                break
            s *= 2
        barrier = threading.Barrier(2)
        spans = {}
        results = {}

        def work(name, sources):
            barrier.wait()
            t0 = time.perf_counter()
            results[name] = funcorr.geodesic_distances(mesh_y, sources)
            spans[name] = (t0, time.perf_counter())

        threads = [
            threading.Thread(target=work, args=("a", np.arange(s))),
            threading.Thread(target=work, args=("b", np.arange(s, 2 * s))),
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        (a0, a1), (b0, b1) = spans["a"], spans["b"]
        overlap = min(a1, b1) - max(a0, b0)
        shorter = min(a1 - a0, b1 - b0)
        # Holding the GIL, one call would start only after the other returned (overlap ≤ 0 up
        # to the moment between the barrier and the call); released, they overlap almost fully.
        assert overlap > 0.5 * shorter, (spans, s, took)
        assert results["a"].shape == (len(mesh_y[0]), s)
        assert np.array_equal(results["a"][:, :1], funcorr.geodesic_distances(mesh_y, [0]))
    finally:
        funcorr.set_num_threads(None)


def test_python_runs_while_rust_computes(mesh_y):
    """The main thread keeps running Python while a thread is inside a long Rust call."""
    funcorr.set_num_threads(1)
    try:
        inside = threading.Event()
        done = threading.Event()

        def work():
            inside.set()
            funcorr.geodesic_distances(mesh_y, np.arange(64))
            done.set()

        t = threading.Thread(target=work)
        t.start()
        inside.wait()
        ticks = 0
        t0 = time.perf_counter()
        while not done.is_set():
            ticks += 1
        elapsed = time.perf_counter() - t0
        t.join()
        # Python-level loop iterations run at millions per second when the GIL is free; with a
        # held GIL the loop would be stuck for the whole call.
        assert elapsed > 0.05 and ticks / elapsed > 10_000, (ticks, elapsed)
    finally:
        funcorr.set_num_threads(None)
