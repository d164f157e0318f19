#!/usr/bin/env python3
"""Summary of bench/pyfm_side_by_side.sh (standard library only).

    side_by_side_summary.py --out OUT --env ENV.json [--command CMD] DATASET...

Reads, for every pair folder OUT/<dataset>/<X>_<Y>/, the `funcorr eval --json` results
(eval.<tag>.{direct,sym}.json), the wall-clock seconds of both processes (funcorr.wall,
pyfm.wall) and pyFM's own stage timings (pyfm/pyfm.json), and writes OUT/summary.md (means per
data set and tool), OUT/per_pair.md (one row per pair) and OUT/results.json.

Conventions. Errors are mean geodesic errors / sqrt(area(Y)) ×100 at the template points.
"direct": no flip forgiven; "sym": per point the smaller of the errors against the ground truth
and its left-right mirror. A pair counts as *failed* when its direct error is above 3.0, and as
*flipped* when it failed and forgiving the flip removes at least 40 % of its error
(sym < 0.6 × direct): the map is then mostly a mirror image. pyFM's seconds are its pipeline up
to the ZoomOut map (load, spectrum, descriptors, fit, ZoomOut with its point-map conversion;
not the ICP map, which the recipe also computes) and, separately, the wall clock of its whole
Python process (imports included); funcorr's are the wall clock of `funcorr match`.
"""
import argparse
import json
import os
import statistics

TOOLS = [("funcorr", "funcorr match (defaults)"), ("pyfm-fmap", "pyFM fit"),
         ("pyfm-icp", "pyFM fit + ICP"), ("pyfm-zoomout", "pyFM fit + ZoomOut")]
FAIL = 3.0
FLIP = 0.6


def load_mean(path):
    try:
        with open(path) as f:
            return 100.0 * json.load(f)["summary"]["mean"]
    except (OSError, ValueError, KeyError):
        return None


def load_float(path):
    try:
        with open(path) as f:
            return float(f.read().strip())
    except (OSError, ValueError):
        return None


def pyfm_pipeline_seconds(path):
    try:
        with open(path) as f:
            p = json.load(f)
    except (OSError, ValueError):
        return None
    t, v = p["times"], p["variants"]["example"]["times"]
    parts = [t.get("load"), t.get("laplacian_eigen"), t.get("descriptors"), v.get("fit"), v.get("zoomout")]
    return None if any(x is None for x in parts) else sum(parts)


def load_peak(path):
    """The last line of a GNU time `-f %M` file (KB) in MiB, or None."""
    try:
        with open(path) as f:
            lines = [l.strip() for l in f if l.strip()]
        return int(lines[-1]) / 1024.0
    except (OSError, ValueError, IndexError):
        return None


def pair_rows(out, ds):
    rows = []
    root = os.path.join(out, ds)
    if not os.path.isdir(root):
        return rows
    for name in sorted(os.listdir(root)):
        d = os.path.join(root, name)
        if not os.path.isdir(d):
            continue
        r = {"dataset": ds, "pair": name, "tools": {}}
        for tag, _ in TOOLS:
            r["tools"][tag] = {"direct": load_mean(os.path.join(d, f"eval.{tag}.direct.json")),
                               "sym": load_mean(os.path.join(d, f"eval.{tag}.sym.json"))}
        r["funcorr_s"] = load_float(os.path.join(d, "funcorr.wall"))
        r["pyfm_wall_s"] = load_float(os.path.join(d, "pyfm.wall"))
        r["pyfm_pipeline_s"] = pyfm_pipeline_seconds(os.path.join(d, "pyfm", "pyfm.json"))
        # Peak resident memory of each process in MiB (GNU time's %M, KB), when measured.
        r["funcorr_mib"] = load_peak(os.path.join(d, "funcorr.maxrss"))
        r["pyfm_mib"] = load_peak(os.path.join(d, "pyfm.maxrss"))
        rows.append(r)
    return rows


def mean(vals):
    vals = [v for v in vals if v is not None]
    return statistics.mean(vals) if vals else None


def f2(v):
    return "—" if v is None else f"{v:.2f}"


def f0(v):
    return "—" if v is None else f"{v:.0f}"


def summarize(rows, tag):
    es = [r["tools"][tag] for r in rows if r["tools"][tag]["direct"] is not None and r["tools"][tag]["sym"] is not None]
    failed = [e for e in es if e["direct"] > FAIL]
    return {"n": len(es), "direct": mean(e["direct"] for e in es), "sym": mean(e["sym"] for e in es),
            "median_direct": statistics.median(e["direct"] for e in es) if es else None,
            "max_direct": max((e["direct"] for e in es), default=None),
            "failed": len(failed), "flipped": sum(1 for e in failed if e["sym"] < FLIP * e["direct"])}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--env", required=True)
    ap.add_argument("--command", default="bash bench/pyfm_side_by_side.sh")
    ap.add_argument("datasets", nargs="+")
    a = ap.parse_args()
    with open(a.env) as f:
        env = json.load(f)
    v = env.get("versions", {})
    head = [f"Command: `{a.command}`", "",
            f"Machine: {env.get('cpu_model')}, {env.get('nproc_cmd')} CPUs, {env.get('platform')}; "
            f"run {env.get('date_utc')}; funcorr {env.get('funcorr_version')} at commit {env.get('git_commit')}"
            f"{' (uncommitted changes in src)' if env.get('git_dirty_src') else ''}; pyfmaps {v.get('pyfmaps')}, "
            f"numpy {v.get('numpy')}, scipy {v.get('scipy')}.", ""]
    summary = head + ["| data set | tool | pairs | direct ×100 | sym ×100 | median direct | max direct "
                      f"| pairs > {FAIL:g} | flipped | seconds per pair |",
                      "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    per_pair = head + ["| data set | pair | funcorr direct | funcorr sym | funcorr s | pyFM ZoomOut direct "
                       "| pyFM ZoomOut sym | pyFM fit direct | pyFM ICP direct | pyFM s (pipeline / process) |",
                       "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    results = {"env": env, "command": a.command, "datasets": {}}
    for ds in a.datasets:
        rows = pair_rows(a.out, ds)
        stats = {}
        for tag, label in TOOLS:
            s = summarize(rows, tag)
            if tag == "funcorr":
                s["seconds"] = mean(r["funcorr_s"] for r in rows)
                s["peak_mib"] = mean(r["funcorr_mib"] for r in rows)
                secs = f"{f2(s['seconds'])}; {f0(s['peak_mib'])} MiB"
            elif tag == "pyfm-zoomout":
                s["seconds"] = mean(r["pyfm_pipeline_s"] for r in rows)
                s["process_seconds"] = mean(r["pyfm_wall_s"] for r in rows)
                s["peak_mib"] = mean(r["pyfm_mib"] for r in rows)
                secs = f"{f2(s['seconds'])} (process {f2(s['process_seconds'])}; {f0(s['peak_mib'])} MiB)"
            else:
                secs = ""
            stats[tag] = s
            summary.append(f"| {ds} | {label} | {s['n']} | {f2(s['direct'])} | {f2(s['sym'])} | "
                           f"{f2(s['median_direct'])} | {f2(s['max_direct'])} | {s['failed']} | {s['flipped']} | {secs} |")
        ratios = [r["funcorr_s"] / r["pyfm_wall_s"] for r in rows if r["funcorr_s"] and r["pyfm_wall_s"]]
        if ratios:
            stats["funcorr"]["wall_ratio_to_pyfm_process"] = {"mean": mean(ratios), "max": max(ratios)}
            summary.append(f"| {ds} | funcorr / pyFM process wall | {len(ratios)} | mean {mean(ratios):.3f}, "
                           f"max {max(ratios):.3f} | | | | | | |")
        for r in rows:
            t = r["tools"]
            per_pair.append(
                f"| {ds} | {r['pair']} | {f2(t['funcorr']['direct'])} | {f2(t['funcorr']['sym'])} | {f2(r['funcorr_s'])} | "
                f"{f2(t['pyfm-zoomout']['direct'])} | {f2(t['pyfm-zoomout']['sym'])} | {f2(t['pyfm-fmap']['direct'])} | "
                f"{f2(t['pyfm-icp']['direct'])} | {f2(r['pyfm_pipeline_s'])} / {f2(r['pyfm_wall_s'])} |")
        results["datasets"][ds] = {"summary": stats, "pairs": rows}
    note = ["", f"Errors ×100: `funcorr eval --geodesics exact`; direct: no flip forgiven; sym: the left–right "
            f"flip forgiven. Failed: direct > {FAIL:g}; flipped: failed and sym < {FLIP:g} × direct. Seconds: "
            "funcorr = wall clock of `funcorr match`; pyFM = load + spectrum + descriptors + fit + ZoomOut "
            "(pyfm.json) and, in parentheses, the wall clock of its Python process; MiB: mean peak resident "
            "memory of each process (GNU time)."]
    with open(os.path.join(a.out, "summary.md"), "w") as f:
        f.write("\n".join(summary + note) + "\n")
    with open(os.path.join(a.out, "per_pair.md"), "w") as f:
        f.write("\n".join(per_pair + note) + "\n")
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    print("\n".join(summary + note))


if __name__ == "__main__":
    main()
