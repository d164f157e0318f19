"""Many pairs at once: every shape prepared once, then the pair jobs, on this machine or on Ray.

::

    from funcorr.batch import match_pairs
    results = match_pairs({"a": "a.off", "b": "b.off", "c": "c.off"}, [("a", "b"), ("a", "c")],
                          engine="local", n_jobs=2)              # or engine="ray" (pip install funcorr[ray])
    results[0].map_xy                                              # vertex of "b" for every vertex of "a"

Engines:

* ``"local"`` (default, nothing to install): a thread pool of ``n_jobs`` workers. funcorr
  releases the GIL, so the jobs run in parallel; each uses ``threads_per_job`` rayon threads
  (default: the cores divided among the jobs).
* ``"ray"``: every shape is prepared by a Ray task and kept once in Ray's object store; the pair
  tasks take references to them (no copy per pair), ``num_cpus=threads_per_job`` each, and
  their results are streamed back with ``ray.wait`` as they finish. The same call runs on a
  laptop (``ray.init()``) or a cluster (``ray.init(address=...)``); ``ray.init()`` is called
  with its defaults when Ray is not initialized yet.

The maps are the same whatever the engine, the number of jobs or threads (funcorr's results do
not depend on the thread count), and the same as :func:`funcorr.match` on each pair. A pair that
fails (a shape that cannot be prepared, a numerical failure) is reported in its result's
``error``, not raised; bad arguments (an unknown shape name, a bad option) raise before any work.

Progress: a bar of the shapes prepared, then of the pairs done (``progress=``, as
:func:`funcorr.match`). Ctrl-C stops every job (the local engine's threads, or Ray's tasks by
``ray.cancel``) and raises KeyboardInterrupt; ``out_dir`` is then left as it was (it is written
only once every pair is done).
"""

from __future__ import annotations

import json
import os
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

import funcorr
from funcorr import _funcorr
from funcorr._progress import reporting

__all__ = ["PairResult", "Dataset", "load_dataset", "match_pairs"]


@dataclass
class PairResult:
    """One pair of :func:`match_pairs`: ``x`` → ``y`` (shape names).

    ``map_xy`` (n,): for every vertex of x the vertex of y; ``map_yx`` (m,) the other way; ``C``
    the final functional map (x coefficients → y coefficients); ``evaluation`` the geodesic
    errors when ground truth was given (see :func:`funcorr.evaluate`); ``seconds`` the pair
    job's wall time; ``error`` the failure message (then the maps are None)."""

    x: str
    y: str
    map_xy: Optional[np.ndarray] = None
    map_yx: Optional[np.ndarray] = None
    C: Optional[np.ndarray] = None
    evaluation: Optional[Dict[str, Any]] = None
    seconds: float = 0.0
    stages: List[Tuple[str, float]] = field(default_factory=list)
    error: Optional[str] = None

    @property
    def ok(self) -> bool:
        return self.error is None


GroundTruth = Mapping[str, Any]


@dataclass
class Dataset:
    """A data set in the layout ``funcorr bench`` reads: shapes ``NAME.off``, ``pairs.txt``
    (``X<tab>Y`` per line) and template points ``corres/NAME.vts`` (or ``NAME.vts``) with their
    mirrored ``NAME.sym.vts``; the arguments of :func:`match_pairs`."""

    shapes: Dict[str, str]
    pairs: List[Tuple[str, str]]
    ground_truth: Dict[str, np.ndarray]
    symmetric: Dict[str, np.ndarray]

    def match(self, **kwargs) -> List["PairResult"]:
        """:func:`match_pairs` on every pair, evaluated against the ground truth."""
        return match_pairs(self.shapes, self.pairs, ground_truth=self.ground_truth, symmetric=self.symmetric, **kwargs)


def load_dataset(path, limit: Optional[int] = None) -> Dataset:
    """Reads a data set (see :class:`Dataset`): the first ``limit`` pairs of ``pairs.txt``."""
    root = Path(path)
    lines = [l.split() for l in (root / "pairs.txt").read_text().splitlines() if l.strip()]
    pairs = [(l[0], l[1]) for l in lines][:limit]
    names = sorted({n for p in pairs for n in p})
    shapes, gt, sym = {}, {}, {}
    for n in names:
        shape = root / f"{n}.off"
        if not shape.exists():
            raise FileNotFoundError(f"{root / 'pairs.txt'} names {n!r}, but {shape} does not exist")
        shapes[n] = str(shape)
        for d in (root / "corres", root):
            if (d / f"{n}.vts").exists():
                gt[n] = funcorr.read_vts(d / f"{n}.vts")
                if (d / f"{n}.sym.vts").exists():
                    sym[n] = funcorr.read_vts(d / f"{n}.sym.vts")
                break
    return Dataset(shapes, pairs, gt, sym)


def _names(shapes) -> Dict[str, Any]:
    if isinstance(shapes, Mapping):
        return {str(k): v for k, v in shapes.items()}
    out = {}
    for i, s in enumerate(shapes):
        name = Path(s).stem if isinstance(s, (str, os.PathLike)) else str(i)
        if name in out:
            raise ValueError(f"shapes: two shapes are named {name!r}; pass a dict name → shape")
        out[name] = s
    return out


def _prepare(shape, k: int, threads: int, laplacian: Dict[str, Any]):
    """Prepares one shape; returns (PreparedShape, None) or (None, error message)."""
    if isinstance(shape, funcorr.PreparedShape):
        return shape, None
    try:
        funcorr.set_num_threads(threads)
        return funcorr.prepare(shape, k=k, progress=False, **laplacian), None
    except Exception as e:  # reported per pair
        return None, f"{type(e).__name__}: {e}"


def _pair_job(x_name: str, y_name: str, X, Y, x_err, y_err, data, options: Dict[str, Any], gt, threads: int) -> PairResult:
    """One pair: match, then evaluate when ground truth is given. Never raises."""
    t0 = time.perf_counter()
    if x_err or y_err:
        which = f"shape {x_name!r}: {x_err}" if x_err else f"shape {y_name!r}: {y_err}"
        return PairResult(x_name, y_name, error=f"not prepared: {which}")
    try:
        funcorr.set_num_threads(threads)
        r = funcorr.match(X, Y, data=data, progress=False, **options)
        ev = None
        if gt is not None:
            gx, gy, gs, how = gt
            ev = funcorr.evaluate(r.map_xy, Y, gx, gy, gs, how)
            ev = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in ev.items()}
        return PairResult(x_name, y_name, r.map_xy, r.map_yx, r.C, ev, time.perf_counter() - t0, r.stages)
    except Exception as e:
        return PairResult(x_name, y_name, seconds=time.perf_counter() - t0, error=f"{type(e).__name__}: {e}")


def _ground_truth(ground_truth, symmetric, geodesics, x: str, y: str):
    if ground_truth is None:
        return None
    gx, gy = ground_truth.get(x), ground_truth.get(y)
    if gx is None or gy is None:
        return None
    gs = None if symmetric is None else symmetric.get(y)
    return (np.asarray(gx), np.asarray(gy), None if gs is None else np.asarray(gs), geodesics)


def _write(out_dir: Path, results: Sequence[PairResult], method: str) -> None:
    maps = out_dir / "maps"
    maps.mkdir(parents=True, exist_ok=True)
    records = []
    for r in results:
        rec = {"x": r.x, "y": r.y, "seconds": r.seconds, "error": r.error}
        if r.ok:
            tmp = maps / f".{r.x}__{r.y}.{method}.txt.tmp"
            np.savetxt(tmp, r.map_xy, fmt="%d")
            os.replace(tmp, maps / f"{r.x}__{r.y}.{method}.txt")
            if r.evaluation is not None:
                rec.update({k: r.evaluation[k] for k in ("mean", "at_005", "at_010", "at_025")})
        records.append(rec)
    tmp = out_dir / ".pairs.json.tmp"
    tmp.write_text(json.dumps(records, indent=1))
    os.replace(tmp, out_dir / "pairs.json")


def match_pairs(
    shapes: Union[Mapping[str, Any], Sequence[Any]],
    pairs: Iterable[Tuple[Any, Any]],
    engine: str = "local",
    n_jobs: Optional[int] = None,
    out_dir=None,
    data: Union[str, Tuple[Any, Any]] = "wks",
    ground_truth: Optional[Mapping[str, Any]] = None,
    symmetric: Optional[Mapping[str, Any]] = None,
    geodesics: str = "exact",
    threads_per_job: Optional[int] = None,
    callback: Optional[Callable[[PairResult], None]] = None,
    progress=None,
    **match_options,
) -> List[PairResult]:
    """Matches every pair ``(x, y)`` of ``pairs`` (names of ``shapes``).

    ``shapes``: a dict name → shape (path, ``(V, F)``, points or PreparedShape), or a list
    (named by file stem, or by index). Every shape is prepared once with the eigenpairs the
    options need (as :func:`funcorr.match`). ``engine``: ``"local"`` or ``"ray"``; ``n_jobs``:
    pair jobs at a time (local; default: one per core); ``threads_per_job``: rayon threads of
    each job (default: the cores divided by ``n_jobs``; on Ray, 1 CPU per task unless given).
    The local engine sets :func:`funcorr.set_num_threads` to ``threads_per_job`` while it runs
    and restores the earlier setting afterwards.
    ``data`` and ``match_options``: those of :func:`funcorr.match` (e.g. ``method="fmap"``).
    ``ground_truth``: name → 0-based template points (e.g. ``funcorr.read_vts(...)``) for
    evaluating each pair on them (``symmetric``: name → mirrored template points,
    ``geodesics``: "exact" | "heat" | "dijkstra"). ``out_dir``: also writes
    ``maps/X__Y.METHOD.txt`` (0-based, as ``funcorr bench``) and ``pairs.json``. ``callback``
    is called with each result as it arrives. ``progress``: as :func:`funcorr.match` (stages
    ``"shapes"`` and ``"pairs"``, counted). Ctrl-C stops every job and raises KeyboardInterrupt
    (nothing is written to ``out_dir``).

    Returns the results in the order of ``pairs``; failed pairs have ``error`` set.
    """
    named = _names(shapes)
    pairs = [(str(x), str(y)) for x, y in pairs]
    for x, y in pairs:
        for s in (x, y):
            if s not in named:
                raise ValueError(f"pairs: no shape named {s!r} (shapes: {', '.join(sorted(named)[:10])}…)")
    if engine not in ("local", "ray"):
        raise ValueError(f"engine: {engine!r}: expected 'local' or 'ray'")
    laplacian_keys = ("laplacian", "cloud_neighbours", "knn", "vertex_weights", "sigma")
    laplacian = {k: match_options[k] for k in laplacian_keys if k in match_options}
    options = {k: v for k, v in match_options.items() if k not in laplacian_keys}
    # Bad options fail here, before any work (the same parser as funcorr.match).
    k = _funcorr.match_basis_size(data, dict(options))
    method = str(options.get("method", "axiomatic"))
    used = sorted({s for p in pairs for s in p})
    cores = os.cpu_count() or 1
    with reporting(progress, "funcorr.batch") as report:
        report = report or (lambda stage, done, total: None)
        if engine == "local":
            jobs = n_jobs or cores
            threads = threads_per_job or max(1, cores // jobs)
            results = _run_local(named, used, pairs, k, laplacian, data, options, ground_truth, symmetric, geodesics, jobs, threads, callback, report)
        else:
            threads = threads_per_job or 1
            results = _run_ray(named, used, pairs, k, laplacian, data, options, ground_truth, symmetric, geodesics, threads, callback, report)
    if out_dir is not None:
        _write(Path(out_dir), results, method)
    return results


def _run_local(named, used, pairs, k, laplacian, data, options, ground_truth, symmetric, geodesics, jobs, threads, callback, report):
    previous = funcorr._threads_setting  # restored below
    workers = set()  # the worker threads' idents, for cancelling their computations

    def tracked(f, *args):
        workers.add(threading.get_ident())
        return f(*args)

    pool = ThreadPoolExecutor(max_workers=jobs)
    submitted = []

    def submit(*args):
        f = pool.submit(tracked, *args)
        submitted.append(f)
        return f

    try:
        shape_jobs = {submit(_prepare, named[s], k, threads, laplacian): s for s in used}
        prepared = {}
        for f in _as_completed(shape_jobs, "shapes", report):
            prepared[shape_jobs[f]] = f.result()
        futures = {}
        for i, (x, y) in enumerate(pairs):
            (X, ex), (Y, ey) = prepared[x], prepared[y]
            gt = _ground_truth(ground_truth, symmetric, geodesics, x, y)
            futures[submit(_pair_job, x, y, X, Y, ex, ey, data, options, gt, threads)] = i
        results: List[Optional[PairResult]] = [None] * len(pairs)
        for f in _as_completed(futures, "pairs", report):
            r = f.result()
            results[futures[f]] = r
            if callback is not None:
                callback(r)
        pool.shutdown()
        return results
    except BaseException:
        # Ctrl-C (or a callback's exception): the queued jobs never start, the running ones
        # stop at their next check (KeyboardInterrupt in their threads, not reported); a job
        # that was just starting is cancelled by the next round.
        pool.shutdown(wait=False, cancel_futures=True)
        running = [f for f in submitted if not f.done()]
        while running:
            _funcorr._cancel_threads(list(workers))
            _, running = wait(running, timeout=0.05)
        pool.shutdown(wait=True)
        raise
    finally:
        funcorr.set_num_threads(previous)


def _as_completed(futures, stage: str, report):
    """The futures as they complete, reporting (stage, done, total) at least every 0.2 s."""
    pending, total = set(futures), len(futures)
    report(stage, 0, total)
    while pending:
        done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
        for f in done:
            yield f
        report(stage, total - len(pending), total)


def _ray_prepare(shape, k, threads, laplacian):
    return _prepare(shape, k, threads, laplacian)


def _ray_pair(x, y, prepared_x, prepared_y, data, options, gt, threads):
    (X, ex), (Y, ey) = prepared_x, prepared_y
    return _pair_job(x, y, X, Y, ex, ey, data, options, gt, threads)


def _run_ray(named, used, pairs, k, laplacian, data, options, ground_truth, symmetric, geodesics, threads, callback, report):
    try:
        import ray
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("engine='ray' needs Ray: pip install 'funcorr[ray]'") from e
    if not ray.is_initialized():
        ray.init()
    prepare = ray.remote(num_cpus=threads)(_ray_prepare)
    pair = ray.remote(num_cpus=threads)(_ray_pair)
    # Each shape once in the object store: the pair tasks receive references, resolved by Ray.
    refs = {s: prepare.remote(named[s], k, threads, laplacian) for s in used}
    pending = {}
    for i, (x, y) in enumerate(pairs):
        gt = _ground_truth(ground_truth, symmetric, geodesics, x, y)
        pending[pair.remote(x, y, refs[x], refs[y], data, options, gt, threads)] = i
    results: List[Optional[PairResult]] = [None] * len(pairs)
    waiting = list(pending)
    try:
        report("pairs", 0, len(pairs))
        while waiting:
            done, waiting = ray.wait(waiting, num_returns=1, timeout=0.2)
            for ref in done:
                i = pending[ref]
                x, y = pairs[i]
                try:
                    r = ray.get(ref)
                except Exception as e:  # a task or worker that died: reported for this pair
                    r = PairResult(x, y, error=f"{type(e).__name__}: {e}")
                results[i] = r
                if callback is not None:
                    callback(r)
            report("pairs", len(pairs) - len(waiting), len(pairs))
    except BaseException:
        # Ctrl-C: Ray interrupts the running tasks (KeyboardInterrupt in their workers, which
        # funcorr's calls there obey) and drops the queued ones.
        for ref in waiting + list(refs.values()):
            try:
                ray.cancel(ref)
            except Exception:
                pass
        raise
    return results
