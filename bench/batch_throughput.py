"""Batch throughput of funcorr's default pipeline over a whole data set (issue 30 item 6).

Three ways to run every pair of DATA/pairs.txt with `funcorr match`'s defaults, every shape
prepared (Laplacian, eigenbasis) once and reused by all its pairs, no basis cache on disk:

1. `funcorr bench --methods axiomatic` (the CLI; pairs run in parallel, one per core);
2. `funcorr.batch.match_pairs(engine="local")` (2 jobs x 1 rayon thread);
3. `funcorr.batch.match_pairs(engine="ray")` (ray.init(num_cpus=2), 1 CPU per task).

Reported: wall seconds, pairs per minute, the CLI's mean / median / worst error x100 (exact
geodesics, no flip forgiven; its time includes that evaluation) and failed pairs (> 3.0), and
whether the Python runs (timed without evaluation) gave the CLI's maps.
Run it through bench/batch_throughput.sh (which makes the virtualenv).
"""

import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np


def summary(name, seconds, errors, n_pairs):
    e = list(errors.values())
    return {
        "run": name,
        "pairs": n_pairs,
        "seconds": seconds,
        "pairs_per_minute": 60.0 * n_pairs / seconds,
        "mean": statistics.mean(e) if e else None,
        "median": statistics.median(e) if e else None,
        "worst": max(e) if e else None,
        "failed": sum(x > 3.0 for x in e),
        "errors": len(e),
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default="../shared/data/faust_r")
    ap.add_argument("--pairs", type=int, default=0, help="first N pairs (0: all)")
    ap.add_argument("--funcorr", default="target/release/funcorr")
    ap.add_argument("--out", default="bench/out/batch_throughput")
    ap.add_argument("--no-ray", action="store_true")
    a = ap.parse_args()

    import funcorr
    from funcorr.batch import match_pairs

    data = Path(a.data)
    pairs = [tuple(l.split()[:2]) for l in (data / "pairs.txt").read_text().splitlines() if l.strip()]
    if a.pairs:
        pairs = pairs[: a.pairs]
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    names = sorted({n for p in pairs for n in p})
    gt = {n: funcorr.read_vts(data / "corres" / f"{n}.vts") for n in names}
    rows, maps = [], {}

    # 1. The CLI's bench command (its own pair file, so --pairs N is honoured).
    with tempfile.TemporaryDirectory() as tmp:
        pf = Path(tmp) / "pairs.txt"
        pf.write_text("".join(f"{x} {y}\n" for x, y in pairs))
        cli_out = out / "cli"
        t0 = time.perf_counter()
        subprocess.run(
            [a.funcorr, "bench", "--dataset", str(data), "--pairs", str(pf), "--methods", "axiomatic", "--data", "wks",
             "--no-symmetric", "--no-html", "--no-cache", "-q", "-o", str(cli_out)],
            check=True,
        )
        seconds = time.perf_counter() - t0
    per_pair = json.loads((cli_out / "pairs.json").read_text())
    errs = {(r["source"], r["target"]): 100 * r["summary"]["mean"] for r in per_pair if r["status"] == "ok"}
    cli_maps = {}
    for x, y in pairs:
        f = cli_out / "maps" / f"{x}__{y}.axiomatic.txt"
        if f.exists():
            cli_maps[(x, y)] = np.loadtxt(f, dtype=np.int64)
    rows.append(summary("funcorr bench --methods axiomatic --data wks (CLI, one pair per core, with its exact-geodesic evaluation)", seconds, errs, len(pairs)))
    maps["cli"] = cli_maps

    shapes = {n: str(data / f"{n}.off") for n in names}
    ground_truth = {n: gt[n] for n in names}

    def run(engine, label, **kw):
        # No ground truth: the matching alone is timed; the maps are compared with the CLI's,
        # whose errors then hold for them too.
        t0 = time.perf_counter()
        res = match_pairs(shapes, pairs, engine=engine, **kw)
        seconds = time.perf_counter() - t0
        rows.append(summary(label, seconds, {}, len(pairs)))
        rows[-1]["failed_runs"] = sum(not r.ok for r in res)
        maps[engine] = {(r.x, r.y): np.asarray(r.map_xy) for r in res if r.ok}

    run("local", "funcorr.batch.match_pairs, local (2 jobs x 1 thread), no evaluation", n_jobs=2, threads_per_job=1)
    if not a.no_ray:
        import ray

        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        run("ray", "funcorr.batch.match_pairs, Ray (num_cpus = 2, 1 CPU per task), no evaluation")
        ray.shutdown()

    same = {}
    for k in maps:
        if k == "cli":
            continue
        common = set(maps[k]) & set(maps["cli"])
        same[f"{k} vs cli"] = sum(np.array_equal(maps[k][p], maps["cli"][p]) for p in common), len(common)

    lines = [f"{len(pairs)} pairs of {data.name}; load average at the end: {os.getloadavg()[0]:.2f}", "",
             "| run | pairs | seconds | pairs per minute | mean ×100 | median | worst | failed (> 3) |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        f = lambda v: "–" if v is None else f"{v:.3f}"
        lines.append(f"| {r['run']} | {r['pairs']} | {r['seconds']:.1f} | {r['pairs_per_minute']:.1f} | "
                     f"{f(r['mean'])} | {f(r['median'])} | {f(r['worst'])} | {r['failed']} |")
    lines.append("")
    lines.append("identical maps: " + ", ".join(f"{k}: {s} of {n}" for k, (s, n) in same.items()))
    md = "\n".join(lines)
    print(md)
    (out / "summary.md").write_text(md + "\n")
    (out / "results.json").write_text(json.dumps({"rows": rows, "same_maps": same}, indent=1))


if __name__ == "__main__":
    main()
