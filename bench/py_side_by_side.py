#!/usr/bin/env python3
"""funcorr-py beside pyFM in one script (issue 14), run by bench/py_side_by_side.sh in bench/.venv
(pyFM 1.3.1 from bench/requirements-pyfm.txt, funcorr from ./python).

1. Per stage, per pair: the same recipe code runs twice, once with pyFM's classes and once with
   funcorr.compat.pyfm's (the import is the only difference): load (area-normalized, centred),
   process (200 eigenpairs each), preprocess (WKS), fit (K = 30, weights 1 / 0.1 / 1 / 1 as in
   pyFM's example), point map, ICP, ZoomOut 30 -> 110 (nit 16, step 5). Then `funcorr.match`
   with its defaults (the whole pipeline, for reference). Every map is scored by funcorr.evaluate
   (exact geodesics, symmetric flips forgiven). The model is FunctionalMapping(Y, X), so that
   p2p_21 is the map X -> Y.
2. Batch throughput: funcorr.batch.match_pairs over the same pairs, engine "local"
   (2 jobs x 1 thread) and "ray" (ray.init(num_cpus=2)), pairs per minute.

    python bench/py_side_by_side.py --data ../shared/data/faust_r --pairs 5 --out bench/out/py_side_by_side
"""
import argparse
import json
import os
import time
import warnings
from pathlib import Path

import numpy as np

warnings.simplefilter("ignore", DeprecationWarning)


def recipe(TriMesh, FunctionalMapping, x, y, times):
    """pyFM's standard recipe; returns {stage: map X -> Y}. The same code for both libraries."""
    pc = time.perf_counter
    t = pc()
    mesh_y = TriMesh.load(y, area_normalize=True, center=True)
    mesh_x = TriMesh.load(x, area_normalize=True, center=True)
    times["load"] = pc() - t
    t = pc()
    mesh_y.process(k=200)
    mesh_x.process(k=200)
    times["process (2 shapes, k = 200)"] = pc() - t
    model = FunctionalMapping(mesh_y, mesh_x)
    t = pc()
    model.preprocess(n_descr=100, descr_type="WKS", subsample_step=2, k_process=200, k_descr=128)
    times["descriptors"] = pc() - t
    t = pc()
    model.fit(K=30, w_descr=1.0, w_lap=1e-1, w_dcomm=1.0, w_orient=1.0)
    times["fit (K = 30)"] = pc() - t
    t = pc()
    maps = {"fit": model.get_p2p(model.FM_12)}
    times["point map"] = pc() - t
    t = pc()
    fm_icp = model.icp_refine(model.FM_12, nit=10)
    maps["icp"] = model.get_p2p(fm_icp)
    times["ICP + point map"] = pc() - t
    t = pc()
    fm_zo = model.zoomout_refine(model.FM_12, nit=16, step=5)
    maps["zoomout"] = model.get_p2p(fm_zo)
    times["ZoomOut 30 -> 110 + point map"] = pc() - t
    return maps


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default="../shared/data/faust_r")
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--out", default="bench/out/py_side_by_side")
    ap.add_argument("--no-ray", action="store_true")
    a = ap.parse_args()

    import funcorr
    import funcorr.compat.pyfm as compat
    import pyFM.functional
    import pyFM.mesh
    from funcorr.batch import match_pairs

    data = Path(a.data)
    pairs = [tuple(l.split()[:2]) for l in (data / "pairs.txt").read_text().splitlines() if l.strip()][: a.pairs]
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for xn, yn in pairs:
        x, y = str(data / f"{xn}.off"), str(data / f"{yn}.off")
        gt = [funcorr.read_vts(data / "corres" / f"{n}.vts") for n in (xn, yn)]
        sym = funcorr.read_vts(data / "corres" / f"{yn}.sym.vts")

        def score(m):
            return 100 * funcorr.evaluate(m, y, gt[0], gt[1], sym)["mean"]

        row = {"pair": f"{xn} -> {yn}", "load": list(os.getloadavg())}
        for lib, (T, FM) in {
            "pyFM": (pyFM.mesh.TriMesh, pyFM.functional.FunctionalMapping),
            "funcorr-py": (compat.TriMesh, compat.FunctionalMapping),
        }.items():
            times = {}
            t0 = time.perf_counter()
            maps = recipe(T, FM, x, y, times)
            times["total"] = time.perf_counter() - t0
            row[lib] = {"seconds": times, "error_x100": {k: score(v) for k, v in maps.items()}}
        t0 = time.perf_counter()
        r = funcorr.match(x, y)
        row["funcorr.match"] = {"seconds": {"total": time.perf_counter() - t0}, "error_x100": {"default": score(r.map_xy)}}
        rows.append(row)
        print(json.dumps(row), flush=True)

    # Batch throughput.
    shapes = {n: str(data / f"{n}.off") for p in pairs for n in p}
    batch = {}
    t0 = time.perf_counter()
    local = match_pairs(shapes, pairs, engine="local", n_jobs=2, threads_per_job=1)
    batch["local (2 jobs x 1 thread)"] = time.perf_counter() - t0
    same = None
    if not a.no_ray:
        import ray

        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        t0 = time.perf_counter()
        remote = match_pairs(shapes, pairs, engine="ray")
        batch["ray (num_cpus = 2, 1 CPU per task)"] = time.perf_counter() - t0
        ray.shutdown()
        same = all(np.array_equal(p.map_xy, q.map_xy) for p, q in zip(local, remote))
    failures = sum(not r.ok for r in local)

    lines = [f"{len(pairs)} pairs of {data.name}; load average at start of each pair: "
             + ", ".join(f"{r['load'][0]:.2f}" for r in rows), ""]
    stages = list(rows[0]["pyFM"]["seconds"])
    lines += ["| stage (mean s per pair) | pyFM 1.3.1 | funcorr-py (compat) | speed-up |", "| --- | --- | --- | --- |"]
    for s in stages:
        p = np.mean([r["pyFM"]["seconds"][s] for r in rows])
        f = np.mean([r["funcorr-py"]["seconds"][s] for r in rows])
        lines.append(f"| {s} | {p:.3f} | {f:.3f} | {p / f:.1f}× |")
    m = np.mean([r["funcorr.match"]["seconds"]["total"] for r in rows])
    lines.append(f"| funcorr.match (defaults, whole pipeline) | | {m:.3f} | |")
    lines += ["", "| map (mean error ×100, symmetric, exact geodesics) | pyFM | funcorr-py (compat) |", "| --- | --- | --- |"]
    for k in ("fit", "icp", "zoomout"):
        p = np.mean([r["pyFM"]["error_x100"][k] for r in rows])
        f = np.mean([r["funcorr-py"]["error_x100"][k] for r in rows])
        lines.append(f"| {k} | {p:.2f} | {f:.2f} |")
    e = np.mean([r["funcorr.match"]["error_x100"]["default"] for r in rows])
    lines.append(f"| funcorr.match defaults | | {e:.2f} |")
    lines += ["", "| batch engine (funcorr.match defaults) | seconds | pairs per minute |", "| --- | --- | --- |"]
    for k, s in batch.items():
        lines.append(f"| {k} | {s:.1f} | {60 * len(pairs) / s:.1f} |")
    lines.append("")
    lines.append(f"local and Ray maps identical: {same}; failed pairs: {failures}")
    md = "\n".join(lines)
    print(md)
    (out / "summary.md").write_text(md + "\n")
    (out / "results.json").write_text(json.dumps({"rows": rows, "batch": batch, "same_maps": same}, indent=1))


if __name__ == "__main__":
    main()
