#!/usr/bin/env python3
"""Comparison / reporting half of bench/spectrum_vs_scipy.sh.

Sub-commands (run with the benchmark venv's python):
  env   --out ENV.json [--funcorr-bin PATH]
        machine + toolchain + numpy/scipy/BLAS description.
  row   --name NAME --shape OFF --k K --lap LAP.npz --out ROW.json
        [--funcorr-out OUT.npz --funcorr-time T.txt... --funcorr-wall S... --funcorr-stderr E.txt...
         --funcorr-rc RC] [--scipy-run CONFIG J.json T.txt... --scipy-rc CONFIG RC...]
        [--check-laplacian]
        compares one (shape, k) run, writes ROW.json and prints a progress line on stderr.
  table --env ENV.json --out RESULTS.json ROW.json...
        writes all rows + machine info to RESULTS.json and prints the Markdown report on stdout.

Eigenvalue agreement: max_{i>=1} |lf_i - ls_i| / max(|ls_i|, 1e-12 * max|ls|); lambda_0 (the
constant mode, ~0) is excluded from the relative measure and reported in absolute value.
"""
import argparse
import json
import os
import platform
import re
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


# ----------------------------------------------------------------------------- helpers
def run(cmd):
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=60).stdout.strip()
    except Exception as e:
        return f"unavailable ({e.__class__.__name__})"


def parse_time_v(path):
    """Parse GNU `/usr/bin/time -v -o path` output."""
    out = {}
    try:
        with open(path) as f:
            text = f.read()
    except OSError:
        return out
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
    if m:
        out["peak_rss_mb"] = int(m.group(1)) / 1024.0
    m = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", text)
    if m:
        secs = 0.0
        for part in m.group(1).split(":"):
            secs = secs * 60 + float(part)
        out["elapsed_s"] = secs
    for key, pat in (("user_s", r"User time \(seconds\): ([\d.]+)"),
                     ("sys_s", r"System time \(seconds\): ([\d.]+)"),
                     ("cpu_percent", r"Percent of CPU this job got: (\d+)%"),
                     ("exit_status", r"Exit status: (\d+)")):
        m = re.search(pat, text)
        if m:
            out[key] = float(m.group(1))
    if "Command terminated by signal" in text:
        out["signal"] = re.search(r"Command terminated by signal (\d+)", text).group(1)
    return out


def loadavg():
    try:
        with open("/proc/loadavg") as f:
            return [float(x) for x in f.read().split()[:3]]
    except Exception:
        return None


NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
# one "|"-separated stage segment: "NAME SECONDS s" optionally followed by "(details)"
_STAGE_RE = re.compile(rf"^\s*(?P<name>[^\W\d][\w -]*?)\s+(?P<val>{NUM})\s*s(?!\w)\s*(?:\((?P<extra>[^)]*)\))?\s*$")
_ANSI_RE = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


def parse_stages(stderr_text):
    """Parse funcorr's timing line on stderr, e.g.

      funcorr: read 0.006 s | laplacian 0.008 s | factor 0.008 s | eigensolve 1.018 s (block-lanczos,
      2 restarts, 1184 solves) | write 0.035 s | n 4999 k 350 λ_k 7.011131e3 max residual 4.80e-10

    (one line). Uses the last line that contains "funcorr:" and at least one "NAME SECONDS s" stage;
    anything before "funcorr:" on that line (progress-bar remnants, ANSI codes) is ignored, unknown
    stages are kept, unknown segments are skipped. Returns
      {"stages_s": {stage: seconds}, "eigensolve_info": {"method", "restarts", "solves", ...},
       "n", "k", "lambda_k", "max_residual", "solver_s"}
    with solver_s = factor + eigensolve seconds (eigensolve alone if no factor stage is printed,
    None if there is no eigensolve stage, e.g. a cached basis). Empty dict if no such line."""
    text = _ANSI_RE.sub("", stderr_text or "")
    for line in reversed(text.splitlines()):
        pos = line.rfind("funcorr:")
        if pos < 0:
            continue
        body = line[pos + len("funcorr:"):]
        out = {"stages_s": {}}
        for seg in body.split("|"):
            m = _STAGE_RE.match(seg)
            if m:
                name = m.group("name").strip()
                out["stages_s"][name] = float(m.group("val"))
                if m.group("extra") is not None and name == "eigensolve":
                    info = {}
                    for part in (x.strip() for x in m.group("extra").split(",")):
                        mm = re.fullmatch(r"(\d+)\s+([A-Za-z][\w -]*)", part)
                        if mm:
                            info[mm.group(2).strip()] = int(mm.group(1))
                        elif part and "method" not in info:
                            info["method"] = part
                    out["eigensolve_info"] = info
                continue
            for key, pat, conv in (("n", r"(?:^|\s)n\s+(\d+)\b", int), ("k", r"(?:^|\s)k\s+(\d+)\b", int),
                                   ("lambda_k", rf"λ_k\s+({NUM})", float),
                                   ("max_residual", rf"max residual\s+({NUM})", float)):
                mm = re.search(pat, seg)
                if mm:
                    out[key] = conv(mm.group(1))
        if not out["stages_s"]:
            continue  # e.g. "funcorr: error: ..."
        st = out["stages_s"]
        out["solver_s"] = (st["eigensolve"] + st.get("factor", 0.0)) if "eigensolve" in st else None
        return out
    return {}


def load_lap(path):
    import scipy.sparse as sp
    z = np.load(path)
    shape = tuple(int(s) for s in z["W_shape"])
    W = sp.csc_matrix((z["W_data"].astype(np.float64), z["W_indices"].astype(np.int64),
                       z["W_indptr"].astype(np.int64)), shape=shape)
    return W, z["mass"].astype(np.float64)


def backward_errors(W, mass, vals, vecs):
    """Same measure as scipy_eigsh.residuals: ||Wx - lMx|| / ((||W||_1 + |l| ||M||_1) ||x||)."""
    normW = abs(W).sum(axis=0).max()
    normM = np.abs(mass).max()
    R = W @ vecs - (mass[:, None] * vecs) * vals[None, :]
    den = (normW + np.abs(vals) * normM) * np.linalg.norm(vecs, axis=0)
    return np.linalg.norm(R, axis=0) / np.maximum(den, np.finfo(float).tiny)


def eig_compare(lf, ls):
    lf = np.sort(np.asarray(lf, dtype=np.float64))
    ls = np.sort(np.asarray(ls, dtype=np.float64))
    out = {"lambda0_funcorr": float(lf[0]) if lf.size else None,
           "lambda0_scipy": float(ls[0]) if ls.size else None}
    m = min(lf.size, ls.size)
    if lf.size != ls.size:
        out["count_mismatch"] = [int(lf.size), int(ls.size)]
    if m < 2:
        out["max_rel_diff"] = None
        return out
    lmax = np.abs(ls[:m]).max()
    a, b = lf[1:m], ls[1:m]
    rel = np.abs(a - b) / np.maximum(np.abs(b), 1e-12 * lmax)
    i = int(np.argmax(rel))
    out.update({"max_rel_diff": float(rel[i]), "argmax_index": i + 1,
                "median_rel_diff": float(np.median(rel)),
                "max_abs_diff": float(np.abs(a - b).max()),
                "lambda_max_scipy": float(ls[m - 1]), "lambda_max_funcorr": float(lf[m - 1])})
    return out


def fmt_s(x):
    if x is None:
        return "–"
    if x < 1:
        return f"{x:.3f}"
    if x < 100:
        return f"{x:.2f}"
    return f"{x:.1f}"


# ----------------------------------------------------------------------------- env
def cmd_env(args):
    import numpy
    import scipy
    info = {"python": platform.python_version(), "numpy": numpy.__version__, "scipy": scipy.__version__,
            "platform": platform.platform(), "kernel": platform.release()}
    lscpu = run(["lscpu"])
    info["lscpu"] = lscpu
    fields = {}
    for line in lscpu.splitlines():
        if ":" in line:
            k, v = line.split(":", 1)
            fields[k.strip()] = v.strip()
    info["cpu_model"] = fields.get("Model name")
    info["cpu_vendor"] = fields.get("Vendor ID")
    info["cpu_family_model"] = f"family {fields.get('CPU family')} model {fields.get('Model')}"
    info["cpus"] = fields.get("CPU(s)")
    info["hypervisor"] = fields.get("Hypervisor vendor")
    flags = fields.get("Flags", "").split()
    info["simd"] = [f for f in ("avx2", "fma", "avx512f") if f in flags]
    info["nproc"] = os.cpu_count()
    try:
        with open("/proc/meminfo") as f:
            kb = int(re.search(r"MemTotal:\s+(\d+)", f.read()).group(1))
        info["mem_total_gib"] = round(kb / 1024 ** 2, 1)
    except Exception:
        info["mem_total_gib"] = None
    info["rustc"] = run(["rustc", "-V"])
    info["cargo"] = run(["cargo", "-V"])
    info["git_commit"] = run(["git", "rev-parse", "--short", "HEAD"]) or "(no commit yet)"
    info["loadavg_at_start"] = loadavg()
    info["git_dirty"] = bool(run(["git", "status", "--porcelain", "--untracked-files=no"]))
    if args.funcorr_bin:
        info["funcorr_bin"] = args.funcorr_bin
        info["funcorr_version"] = run([args.funcorr_bin, "--version"])
        # default --tol of `funcorr spectrum` (the benchmark does not pass --tol)
        m = re.search(r"--tol\b.*?\[default:\s*([^\]\s]+)\s*\]", run([args.funcorr_bin, "spectrum", "--help"]), re.S)
        try:
            info["funcorr_default_tol"] = float(m.group(1)) if m else None
        except ValueError:
            info["funcorr_default_tol"] = None
    for mod, name in ((numpy, "numpy"), (scipy, "scipy")):
        try:
            cfg = mod.show_config(mode="dicts")
            deps = cfg.get("Build Dependencies", {})
            info[f"{name}_blas"] = {k: {kk: deps[k].get(kk) for kk in ("name", "version", "openblas configuration")}
                                    for k in ("blas", "lapack") if k in deps}
        except Exception as e:
            info[f"{name}_blas"] = f"unavailable: {e!r}"
    sys.path.insert(0, HERE)
    from scipy_eigsh import thread_info
    info["threads"] = thread_info()
    with open(args.out, "w") as f:
        json.dump(info, f, indent=1)
    return 0


# ----------------------------------------------------------------------------- row
def best_of(walls, times):
    """Pick the repeat with the smallest wall time; peak RSS = max over repeats."""
    recs = []
    for i, w in enumerate(walls):
        t = parse_time_v(times[i]) if i < len(times) else {}
        recs.append({"wall_s": w, **t})
    if not recs:
        return None, []
    best = min(recs, key=lambda r: r["wall_s"])
    peaks = [r["peak_rss_mb"] for r in recs if "peak_rss_mb" in r]
    return {"wall_s": best["wall_s"], "peak_rss_mb": max(peaks) if peaks else None,
            "user_s": best.get("user_s"), "sys_s": best.get("sys_s"),
            "cpu_percent": best.get("cpu_percent")}, recs


def blas_label(label, nthreads=None):
    if label == "default":
        return f"default ({nthreads} threads)" if nthreads else "default threads"
    return f"{label} thread" + ("" if str(label) == "1" else "s")


def scipy_summary(label, runs):
    """Fastest eigsh call among the repeats of one BLAS configuration; peak RSS = max over repeats."""
    best = min(runs, key=lambda d: d["seconds"])
    pools = (best.get("threads") or {}).get("threadpools")
    nthreads = sorted({p.get("num_threads") for p in pools if p.get("user_api") == "blas"}) \
        if isinstance(pools, list) else []
    return {"eigsh_s": best["seconds"], "repeats_eigsh_s": [d["seconds"] for d in runs],
            "blas_num_threads": nthreads,
            "blas_env": {k: v for k, v in ((best.get("threads") or {}).get("env") or {}).items() if v is not None},
            "peak_rss_mb": max(d["peak_rss_mb"] for d in runs),
            "process_wall_s": best.get("process", {}).get("elapsed_s"),
            "process_peak_rss_mb": best.get("process", {}).get("peak_rss_mb"),
            "process_cpu_percent": best.get("process", {}).get("cpu_percent"),
            "load_s": best.get("load_seconds"), "max_backward_error": best.get("max_residual"),
            "sigma": best.get("sigma"), "n": best.get("n"), "eigenvalues": best["eigenvalues"],
            "threads": best.get("threads")}


def threads_desc(sc):
    """'1' or '2 (default)' from a scipy summary."""
    if not sc:
        return "–"
    nt = "/".join(str(x) for x in sc.get("blas_num_threads") or []) or "?"
    return nt + (" (default)" if sc.get("blas_config") == "default" else "")


def cmd_row(args):
    row = {"name": args.name, "shape": args.shape, "k": args.k, "status": "ok", "errors": [],
           "loadavg_after": loadavg()}
    W = mass = None
    if args.lap and os.path.exists(args.lap):
        W, mass = load_lap(args.lap)
        row["n"] = int(W.shape[0])
        row["nnz"] = int(W.nnz)
        row["total_area"] = float(mass.sum())
    else:
        row["errors"].append("no Laplacian (LAP.npz) from funcorr --save-laplacian")

    # -- funcorr
    lf = None
    if args.funcorr_rc is not None and args.funcorr_rc != 0:
        row["errors"].append(f"funcorr exited with {args.funcorr_rc}")
    if args.funcorr_wall:
        summary, recs = best_of([float(w) for w in args.funcorr_wall], args.funcorr_time or [])
        row["funcorr"] = summary
        row["funcorr_repeats"] = recs
    # one stderr file per repeat (same order as --funcorr-wall; a failed last repeat may add one more)
    stderrs = [p for p in (args.funcorr_stderr or []) if os.path.exists(p)]
    if stderrs:
        fc = row.setdefault("funcorr", {})
        parsed = []
        for i, p in enumerate(stderrs):
            with open(p, errors="replace") as f:
                text = f.read()
            parsed.append(parse_stages(text[-4000:]))
            if i < len(row.get("funcorr_repeats", [])):
                row["funcorr_repeats"][i]["stderr"] = parsed[-1]
            fc["stderr_tail"] = text[-4000:]
        ok = [d for d in parsed[:len(row.get("funcorr_repeats", []))] if d.get("solver_s") is not None]
        if ok:
            best = min(ok, key=lambda d: d["solver_s"])
            fc["solver_s"] = best["solver_s"]  # factor + eigensolve, fastest repeat
            fc["repeats_solver_s"] = [d["solver_s"] for d in ok]
            fc["stages_s"] = best["stages_s"]
            fc["eigensolve_info"] = best.get("eigensolve_info")
            fc["stderr_max_residual"] = best.get("max_residual")
        elif args.funcorr_wall:
            row["errors"].append("no factor/eigensolve timings in funcorr's stderr")
    if (args.funcorr_rc in (None, 0)) and args.funcorr_out and os.path.exists(args.funcorr_out):
        try:
            z = np.load(args.funcorr_out)
            lf = np.asarray(z["eigenvalues"], dtype=np.float64)
            fc = row.setdefault("funcorr", {})
            fc["eigenvalues"] = lf.tolist()
            if "residuals" in z.files:
                fc["reported_max_residual"] = float(np.max(z["residuals"]))
            if W is not None and "eigenvectors" in z.files:
                V = np.asarray(z["eigenvectors"], dtype=np.float64)
                if V.shape == (W.shape[0], lf.size):
                    fc["max_backward_error"] = float(backward_errors(W, mass, lf, V).max())
                    G = V.T @ (mass[:, None] * V)
                    fc["max_M_orthonormality_error"] = float(np.abs(G - np.eye(lf.size)).max())
                else:
                    row["errors"].append(f"eigenvectors shape {V.shape} != ({W.shape[0]}, {lf.size})")
            if mass is not None and "mass" in z.files:
                fc["mass_vs_lap_max_abs_diff"] = float(np.abs(z["mass"] - mass).max())
        except Exception as e:
            row["errors"].append(f"cannot read funcorr output: {e!r}")
    elif args.funcorr_rc in (None, 0):
        row["errors"].append("no funcorr output npz")

    # -- scipy: one entry per BLAS configuration ("1": OPENBLAS/OMP_NUM_THREADS=1, "default": unset)
    ls = None
    scipy_ok = True
    for label, rc in (args.scipy_rc or []):
        if int(rc) != 0:
            row["errors"].append(f"scipy ({blas_label(label)}) exited with {rc}")
            scipy_ok = False
    runs = {}
    for label, jpath, tpath in (args.scipy_run or []):
        if not os.path.exists(jpath):
            continue
        with open(jpath) as f:
            d = json.load(f)
        d["process"] = parse_time_v(tpath)
        runs.setdefault(label, []).append(d)
    configs = {label: scipy_summary(label, rs) for label, rs in runs.items()}
    if configs:
        row["scipy_configs"] = configs
        chosen = min(configs, key=lambda lb: configs[lb]["eigsh_s"])
        row["scipy"] = dict(configs[chosen], blas_config=chosen)
        ls = np.asarray(row["scipy"]["eigenvalues"], dtype=np.float64)
        if "n" not in row:
            row["n"] = row["scipy"].get("n")
        if len(configs) > 1:  # the BLAS thread count must not change the answer
            vals = [c["eigenvalues"] for c in configs.values()]
            row["scipy_configs_max_rel_diff"] = eig_compare(vals[0], vals[1]).get("max_rel_diff")
    elif scipy_ok:
        row["errors"].append("no scipy result")

    # -- comparison
    if lf is not None and ls is not None:
        row["comparison"] = eig_compare(lf, ls)
    sc_s = (row.get("scipy") or {}).get("eigsh_s")
    fc = row.get("funcorr") or {}
    if sc_s and fc.get("wall_s"):
        row["speedup_wall"] = sc_s / fc["wall_s"]
    if sc_s and fc.get("solver_s"):
        row["speedup_solver"] = sc_s / fc["solver_s"]

    # -- independent Laplacian check
    if args.check_laplacian and W is not None:
        try:
            sys.path.insert(0, HERE)
            from cotan_laplacian import cotan_laplacian, read_off
            v, fcs = read_off(args.shape)
            Wr, mr = cotan_laplacian(v, fcs)
            if Wr.shape != W.shape:
                row["laplacian_check"] = {"error": f"shape {W.shape} vs reference {Wr.shape}"}
            else:
                dW = abs(W - Wr).max()
                row["laplacian_check"] = {
                    "W_max_abs_diff_rel": float(dW / abs(Wr).max()),
                    "mass_max_abs_diff_rel": float(np.abs(mass - mr).max() / np.abs(mr).max()),
                    "W_symmetry_max_abs": float(abs(W - W.T).max()),
                    "W_row_sum_max_abs": float(np.abs(np.asarray(W.sum(axis=1))).max()),
                }
        except Exception as e:
            row["laplacian_check"] = {"error": repr(e)}

    if row["errors"]:
        row["status"] = "failed" if ("comparison" not in row) else "warning"
    with open(args.out, "w") as f:
        json.dump(row, f)

    # progress line
    fc, sc, cmp_ = row.get("funcorr", {}), row.get("scipy", {}), row.get("comparison", {})
    msg = (f"[bench] {args.name} n={row.get('n')} k={args.k}: "
           f"funcorr {fmt_s(fc.get('wall_s'))} s / {fmt_mb(fc.get('peak_rss_mb'))} MB, "
           f"solver {fmt_s(fc.get('solver_s'))} s, "
           f"scipy eigsh " + (", ".join(f"{blas_label(lb, '/'.join(map(str, c.get('blas_num_threads') or [])))} "
                                        f"{fmt_s(c.get('eigsh_s'))} s"
                                        for lb, c in (row.get("scipy_configs") or {}).items()) or "– s")
           + f" / {fmt_mb(sc.get('peak_rss_mb'))} MB, "
           f"speed-up wall {fmt_x(row.get('speedup_wall'))} solver {fmt_x(row.get('speedup_solver'))}, "
           f"max rel diff {fmt_e(cmp_.get('max_rel_diff'))}")
    if row["errors"]:
        msg += "  [" + "; ".join(row["errors"]) + "]"
    lc = row.get("laplacian_check", {})
    if lc.get("W_max_abs_diff_rel", 0) > 1e-8 or lc.get("mass_max_abs_diff_rel", 0) > 1e-8 or "error" in lc:
        msg += f"  [Laplacian differs from numpy reference: {lc}]"
    print(msg, file=sys.stderr, flush=True)
    return 0


def fmt_mb(x):
    return "–" if x is None else f"{x:.0f}"


def fmt_x(x):
    return "–" if x is None else f"{x:.2f}×"


def fmt_e(x):
    return "–" if x is None else f"{x:.1e}"


# ----------------------------------------------------------------------------- table
def fmt_tol(x):
    if x is None:
        return "?"
    m, e = f"{x:.0e}".split("e")
    return f"{m}e{int(e)}"


def fmt_list(xs):
    return "[" + ", ".join(fmt_s(x) for x in xs) + "]"


def cmd_table(args):
    with open(args.env) as f:
        env = json.load(f)
    rows = []
    for p in args.rows:
        with open(p) as f:
            rows.append(json.load(f))
    with open(args.out, "w") as f:
        json.dump({"machine": env, "rows": rows}, f, indent=1)

    def blas_desc(key):
        b = env.get(key, {})
        b = b.get("blas", {}) if isinstance(b, dict) else {}
        return f"{b.get('name')} {b.get('version')}"
    sigma = next((r["scipy"].get("sigma") for r in rows if r.get("scipy")), -0.01)
    tol = env.get("funcorr_default_tol")
    # thread count of the "default" BLAS configuration, as seen by threadpoolctl inside scipy_eigsh.py
    dflt = sorted({t for r in rows for t in ((r.get("scipy_configs") or {}).get("default") or {})
                   .get("blas_num_threads") or []})
    dflt_desc = "/".join(map(str, dflt)) if dflt else "?"
    repeats = max([len(r.get("funcorr_repeats") or []) for r in rows]
                  + [len(c.get("repeats_eigsh_s") or []) for r in rows
                     for c in (r.get("scipy_configs") or {}).values()] + [0])

    out = []
    out.append("### funcorr `spectrum` vs `scipy.sparse.linalg.eigsh` (shift-invert)\n")
    out.append(f"- Machine: {env.get('cpu_model')} ({env.get('cpu_vendor')}, {env.get('cpu_family_model')}), "
               f"{env.get('cpus')} CPUs, {env.get('mem_total_gib')} GiB RAM"
               + (f", {env.get('hypervisor')} VM" if env.get('hypervisor') else "")
               + f", SIMD: {', '.join(env.get('simd', []))}; {env.get('platform')}")
    out.append(f"- {env.get('funcorr_version') or 'funcorr'}: commit {env.get('git_commit')}{' (dirty tree)' if env.get('git_dirty') else ''}, "
               f"{env.get('rustc')}, `cargo build --release`; run as `funcorr spectrum SHAPE -k K -o OUT.npz --no-cache` "
               f"(default `--tol {fmt_tol(tol)}`)")
    out.append(f"- scipy side: Python {env.get('python')}, numpy {env.get('numpy')}, scipy {env.get('scipy')}, "
               f"BLAS/LAPACK: numpy {blas_desc('numpy_blas')}, scipy {blas_desc('scipy_blas')}; "
               "eigsh's shift-invert factorisation is SuperLU (single-threaded). Every eigsh run is done in two BLAS "
               "configurations, `OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1` and the library default "
               f"({dflt_desc} threads, thread variables unset), because multi-threaded OpenBLAS can spin on ARPACK's "
               "small matrix-vector products; the table reports the faster one, the details both.")
    out.append(f"- Timings: fastest of {repeats} run{'s' if repeats != 1 else ''} for each side and each scipy "
               "BLAS configuration.")
    loads = [r.get("loadavg_after", [None])[0] for r in rows if r.get("loadavg_after")]
    out.append(f"- Load average (1 min) at start {(env.get('loadavg_at_start') or ['?'])[0]}, after each row "
               f"{', '.join(str(x) for x in loads) or '?'} (≈ 1–2 is the benchmark itself: funcorr and scipy's "
               "default BLAS configuration use both cores; more means other work competed for the CPUs)")
    start = (env.get("loadavg_at_start") or [0])[0]
    if start > 0.5 or any(x is not None and x > 2.5 for x in loads):
        out.append("- **Warning: other processes were using the CPUs during this run (see the load averages); "
                   "timings, especially scipy's with multi-threaded OpenBLAS, are unreliable. "
                   "Re-run on an idle machine before citing them.**")
    out.append(f"- scipy call: `eigsh(W, k=k, M=diag(mass), sigma={sigma}, which='LM')` (σ: see † below the table) on the W and mass "
               "that funcorr saved with `--save-laplacian` (same matrices for both).")
    out.append("")
    out.append("| shape | n | k | funcorr wall s | funcorr eigensolve s | funcorr peak MB | scipy eigsh s † | "
               "scipy BLAS threads | scipy peak MB | speed-up (wall) | speed-up (solver) | max rel. eigenvalue diff |")
    out.append("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for r in rows:
        fc, sc, c = r.get("funcorr") or {}, r.get("scipy") or {}, r.get("comparison") or {}
        diff = fmt_e(c.get("max_rel_diff"))
        if r.get("status") == "failed":
            diff = "failed"
        out.append(f"| {r['name']} | {r.get('n') or '–'} | {r['k']} | {fmt_s(fc.get('wall_s'))} | "
                   f"{fmt_s(fc.get('solver_s'))} | {fmt_mb(fc.get('peak_rss_mb'))} | {fmt_s(sc.get('eigsh_s'))} | "
                   f"{threads_desc(sc)} | {fmt_mb(sc.get('peak_rss_mb'))} | "
                   f"{fmt_x(r.get('speedup_wall'))} | {fmt_x(r.get('speedup_solver'))} | {diff} |")
    out.append("")
    out.append("- **funcorr wall s / peak MB**: the whole `funcorr spectrum` process — process start-up, OFF parsing, "
               "Laplacian assembly, factorisation and eigensolve, writing the .npz — measured with `/usr/bin/time -v`.")
    out.append("- **funcorr eigensolve s**: the `factor` + `eigensolve` stage seconds that funcorr prints on stderr "
               "(factorisation of the shifted matrix and the block Lanczos iteration with its residual checks), "
               "i.e. the work that corresponds to scipy's `eigsh` call.")
    out.append("- **scipy eigsh s**: the `eigsh` call alone (`time.perf_counter`: SuperLU factorisation + ARPACK), "
               "excluding Python start-up, imports and loading the matrices, in the faster BLAS configuration "
               "(**scipy BLAS threads**; `(default)` = OpenBLAS's own choice). **scipy peak MB**: `ru_maxrss` of "
               "that Python process (includes the interpreter and numpy/scipy).")
    out.append("- **speed-up (solver)** = scipy eigsh s / funcorr eigensolve s: the like-for-like comparison "
               "(factorisation + iterative eigensolver on the same matrices, on both sides). "
               "**speed-up (wall)** = scipy eigsh s / funcorr wall s: conservative for funcorr, whose time then "
               "includes reading, assembly, writing and start-up that the scipy time leaves out.")
    out.append("- Each time column is the minimum over the repeats, taken independently per column.")
    out.append("- **max rel. eigenvalue diff** = max over i ≥ 1 of |λᶠᵢ − λˢᵢ| / max(|λˢᵢ|, 1e-12·λmax); "
               "λ₀ (≈ 0) is excluded and listed below.")
    out.append("")
    # footnote on sigma, with this run's lambda_1 per shape
    seen, l1 = set(), []
    for r in rows:
        ev = (r.get("scipy") or {}).get("eigenvalues") or []
        if r["name"] not in seen and len(ev) > 1 and ev[1] > 0:
            seen.add(r["name"])
            l1.append(f"{r['name']} λ₁ = {ev[1]:.2g} (|σ|/λ₁ ≈ {abs(sigma) / ev[1]:.2g})")
    out.append(f"† σ = {sigma} is the standard call in shape-analysis code and is used unchanged on every "
               "mesh. On the large-area TOSCA meshes the spectrum starts at λ₁ ≈ 3e-4, so σ lies far below it "
               "(tens of λ₁ away): the wanted eigenvalues 1/(λᵢ − σ) of the shift-inverted operator are then less "
               "well separated than with a shift near the bottom of the spectrum, which can cost ARPACK extra "
               "iterations. The comparison uses the standard call as is; a mesh-adapted σ might make scipy faster "
               "there." + (f" This run: {'; '.join(l1)}." if l1 else ""))
    out.append("")

    extra = []
    for r in rows:
        c, fc, sc = r.get("comparison") or {}, r.get("funcorr") or {}, r.get("scipy") or {}
        lines = [f"- {r['name']} k={r['k']}:"]
        walls = [x.get("wall_s") for x in r.get("funcorr_repeats") or []]
        if walls:
            t = f"  - funcorr: wall {fmt_list(walls)} s"
            if fc.get("repeats_solver_s"):
                t += f", factor + eigensolve {fmt_list(fc['repeats_solver_s'])} s"
            st = fc.get("stages_s") or {}
            if st:
                parts = []
                for name, v in st.items():
                    bit = f"{name} {fmt_s(v)}"
                    info = fc.get("eigensolve_info") or {}
                    if name == "eigensolve" and info:
                        bit += " (" + ", ".join(str(v2) if k2 == "method" else f"{v2} {k2}"
                                                for k2, v2 in info.items()) + ")"
                    parts.append(bit)
                t += f"; stages of its fastest solve (s): {', '.join(parts)}"
            lines.append(t)
        for lb, cf in (r.get("scipy_configs") or {}).items():
            nt = "/".join(map(str, cf.get("blas_num_threads") or [])) or None
            mark = " ← table" if lb == sc.get("blas_config") else ""
            lines.append(f"  - scipy eigsh, {blas_label(lb, nt)}: {fmt_list(cf.get('repeats_eigsh_s') or [])} s, "
                         f"best {fmt_s(cf.get('eigsh_s'))} s, peak {fmt_mb(cf.get('peak_rss_mb'))} MB{mark}")
        if r.get("scipy_configs_max_rel_diff") is not None:
            lines.append(f"  - the two scipy BLAS configurations' eigenvalues agree to {fmt_e(r['scipy_configs_max_rel_diff'])}")
        bits = []
        if c:
            bits.append(f"|λ₀| funcorr {abs(c['lambda0_funcorr']):.1e}, scipy {abs(c['lambda0_scipy']):.1e}")
        if fc.get("max_backward_error") is not None:
            bits.append(f"backward error funcorr {fc['max_backward_error']:.1e}")
        if sc.get("max_backward_error") is not None:
            bits.append(f"scipy {sc['max_backward_error']:.1e}")
        if fc.get("reported_max_residual") is not None:
            bits.append(f"funcorr's own max ‖Wφ−λAφ‖_{{A⁻¹}}/λ_k {fc['reported_max_residual']:.1e} "
                        f"(tol {fmt_tol(tol)})")
        if fc.get("max_M_orthonormality_error") is not None:
            bits.append(f"funcorr ‖ΦᵀMΦ−I‖max {fc['max_M_orthonormality_error']:.1e}")
        lc = r.get("laplacian_check") or {}
        if "W_max_abs_diff_rel" in lc:
            bits.append(f"W vs numpy reference {lc['W_max_abs_diff_rel']:.1e}")
        elif "error" in lc:
            bits.append(f"Laplacian check failed: {lc['error']}")
        if bits:
            lines.append("  - " + ", ".join(bits))
        if r.get("errors"):
            lines.append("  - errors: " + "; ".join(r["errors"]))
        if len(lines) == 1:
            lines[0] += " no data"
        extra.extend(lines)
    out.append("<details><summary>λ₀, all timings (both scipy BLAS configurations), backward errors, checks</summary>\n")
    out.append("Backward error of a pair: ‖Wx−λMx‖₂ / ((‖W‖₁+|λ|‖M‖₁)‖x‖₂), the same formula for both sides, "
               "computed by this script. The stopping rules differ: funcorr stops when every pair's relative "
               f"residual ‖Wφ−λAφ‖_{{A⁻¹}}/λ_k is ≤ `--tol` (default {fmt_tol(tol)}, used here; \"funcorr's own\" "
               "below), while eigsh runs ARPACK with its default `tol=0` (machine precision) on the shift-inverted "
               "operator, so scipy's backward errors are expected to be smaller; the eigenvalue column shows what "
               "the difference means for λ. Timings are lists over the repeats, in seconds.\n")
    out.extend(extra)
    out.append("\n</details>")
    print("\n".join(out))
    return 2 if any(r.get("status") == "failed" for r in rows) else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("env")
    e.add_argument("--out", required=True)
    e.add_argument("--funcorr-bin")
    r = sub.add_parser("row")
    r.add_argument("--name", required=True)
    r.add_argument("--shape", required=True)
    r.add_argument("--k", type=int, required=True)
    r.add_argument("--lap")
    r.add_argument("--out", required=True)
    r.add_argument("--funcorr-out")
    r.add_argument("--funcorr-time", action="append")
    r.add_argument("--funcorr-wall", action="append")
    r.add_argument("--funcorr-rc", type=int)
    r.add_argument("--funcorr-stderr", action="append", help="one per repeat")
    r.add_argument("--scipy-run", nargs=3, action="append", metavar=("CONFIG", "JSON", "TIME"),
                   help="one scipy_eigsh.py repeat: BLAS configuration ('1' or 'default'), its JSON, its time -v file")
    r.add_argument("--scipy-rc", nargs=2, action="append", metavar=("CONFIG", "RC"))
    r.add_argument("--check-laplacian", action="store_true")
    t = sub.add_parser("table")
    t.add_argument("--env", required=True)
    t.add_argument("--out", required=True)
    t.add_argument("rows", nargs="+")
    args = ap.parse_args()
    return {"env": cmd_env, "row": cmd_row, "table": cmd_table}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
