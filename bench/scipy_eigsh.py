#!/usr/bin/env python3
"""scipy reference for `funcorr spectrum`: the k smallest eigenpairs of
W phi = lambda diag(mass) phi with scipy.sparse.linalg.eigsh in shift-invert mode.

    python bench/scipy_eigsh.py LAP.npz K [--sigma -0.01] [--json OUT.json] [--npz OUT.npz]

LAP.npz is what `funcorr spectrum --save-laplacian` writes: W_data, W_indices,
W_indptr, W_shape (CSC stiffness, positive semi-definite) and mass (lumped areas).

The call is the one used throughout the shape-analysis literature:
    eigsh(W, k=K, M=diag(mass), sigma=-0.01, which='LM')
(ARPACK, shift-invert: SuperLU factorisation of W + 0.01 M, then Lanczos).
Only the eigsh call is timed (time.perf_counter). Peak RSS is the whole
process's ru_maxrss (interpreter + numpy/scipy + matrices + eigsh).
This script does not change the BLAS thread count: spectrum_vs_scipy.sh runs it
once with OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 and once with the library
default (variables unset) and keeps the faster; the thread settings actually in
force (environment and threadpoolctl's view) are recorded in the JSON.

Prints one JSON object on stdout (and writes it to --json if given):
  {"seconds", "peak_rss_mb", "eigenvalues", "n", "nnz", "k", "sigma",
   "load_seconds", "max_residual", "threads": {...}, "versions": {...}}
"""
import argparse
import json
import os
import platform
import resource
import sys
import time

import numpy as np
import scipy
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh

THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
              "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")


def load_lap(path):
    z = np.load(path)
    shape = tuple(int(s) for s in z["W_shape"])
    W = sp.csc_matrix((z["W_data"].astype(np.float64),
                       z["W_indices"].astype(np.int64),
                       z["W_indptr"].astype(np.int64)), shape=shape)
    mass = z["mass"].astype(np.float64)
    if mass.shape[0] != shape[0] or shape[0] != shape[1]:
        raise ValueError(f"inconsistent shapes: W {shape}, mass {mass.shape}")
    return W, mass


def thread_info():
    info = {"env": {k: os.environ.get(k) for k in THREAD_ENV},
            "cpu_count": os.cpu_count(),
            "sched_affinity": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None}
    try:
        from threadpoolctl import threadpool_info
        info["threadpools"] = [
            {k: d.get(k) for k in ("user_api", "internal_api", "num_threads", "version",
                                   "threading_layer", "architecture")}
            for d in threadpool_info()]
    except Exception as e:  # threadpoolctl is optional
        info["threadpools"] = f"unavailable: {e!r}"
    return info


def residuals(W, mass, vals, vecs):
    """Normwise backward error of each pair:
    ||W x - l M x||_2 / ((||W||_1 + |l| ||M||_1) ||x||_2).
    Well defined for the zero eigenvalue too."""
    normW = abs(W).sum(axis=0).max()
    normM = np.abs(mass).max()
    R = W @ vecs - (mass[:, None] * vecs) * vals[None, :]
    num = np.linalg.norm(R, axis=0)
    den = (normW + np.abs(vals) * normM) * np.linalg.norm(vecs, axis=0)
    return num / np.maximum(den, np.finfo(float).tiny)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("lap")
    ap.add_argument("k", type=int)
    ap.add_argument("--sigma", type=float, default=-0.01)
    ap.add_argument("--json", help="also write the JSON result here")
    ap.add_argument("--npz", help="save sorted eigenvalues (and eigenvectors with --save-vectors) here")
    ap.add_argument("--save-vectors", action="store_true")
    args = ap.parse_args()

    t0 = time.perf_counter()
    W, mass = load_lap(args.lap)
    M = sp.diags(mass, format="csc")
    load_s = time.perf_counter() - t0

    t0 = time.perf_counter()
    vals, vecs = eigsh(W, k=args.k, M=M, sigma=args.sigma, which="LM")
    eig_s = time.perf_counter() - t0
    peak_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # kB on Linux

    order = np.argsort(vals)
    vals = vals[order]
    vecs = vecs[:, order]
    res = residuals(W, mass, vals, vecs)

    if args.npz:
        payload = {"eigenvalues": vals}
        if args.save_vectors:
            payload["eigenvectors"] = vecs
        np.savez(args.npz, **payload)

    out = {
        "seconds": eig_s,
        "peak_rss_mb": peak_kb / 1024.0,
        "eigenvalues": vals.tolist(),
        "n": int(W.shape[0]),
        "nnz": int(W.nnz),
        "k": args.k,
        "sigma": args.sigma,
        "which": "LM",
        "load_seconds": load_s,
        "max_residual": float(res.max()),
        "threads": thread_info(),
        "versions": {"python": platform.python_version(), "numpy": np.__version__,
                     "scipy": scipy.__version__},
    }
    text = json.dumps(out)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
