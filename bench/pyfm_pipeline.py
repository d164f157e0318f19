#!/usr/bin/env python3
"""pyFM half of bench/pyfm_side_by_side.sh and bench/pyfm_stages.sh (run with the benchmark venv's python).

Sub-commands:
  env   --out ENV.json [--funcorr-bin PATH]
        machine, package versions (pyfmaps, numpy, scipy, scikit-learn, ...) and BLAS threads.
  run   --x X.off --y Y.off --out DIR [--variant NAME=w_descr,w_lap,w_dcomm,w_orient ...] [options]
        pyFM's standard pipeline (README quickstart / gallery "maps without correspondence"):
        TriMesh.load(area_normalize=True, center=True), TriMesh.process(k), preprocess (WKS),
        fit, get_p2p, icp_refine + get_p2p, zoomout_refine + get_p2p. Each stage is timed with
        time.perf_counter. Writes DIR/<variant>.<stage>.map.txt (0-based, for every vertex of X
        its vertex on Y) and DIR/pyfm.json (timings, parameters, fit diagnostics).
  funcorr-times --report report.json [--wall S]
        stage seconds of one `funcorr match` run (parsed from report.json's "log"), as JSON.
  table --env ENV.json --out RESULTS.json --md TABLE.md ROW.json...
        collects the per-pair rows written by the driver and prints the Markdown tables.

Map direction. pyFM's functional map FM_12 takes functions on mesh1 to functions on mesh2, and
its point maps are p2p_21: for every vertex of mesh2, a vertex of mesh1 (README "Notation
Convention"; FunctionalMapping.get_p2p docstring). The evaluator wants a map X -> Y (for every
vertex of X, a vertex of Y), so the model is built as FunctionalMapping(mesh1=Y, mesh2=X): then
p2p_21 is exactly that map, in pyFM's natural (pull-back) direction, with no inversion.
"""
import argparse
import json
import os
import platform
import re
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))

DEFAULT_VARIANTS = {
    # pyFM's gallery example (plot_05_maps_without_correspondence.py) and README quickstart:
    # fit(K=30, w_descr=1e0, w_lap=1e-1, w_dcomm=1e0, w_orient=1e0)
    "example": (1.0, 1e-1, 1.0, 1.0, True),
    # the same energy without descriptor commutativity and orientation: descriptor preservation
    # + Laplacian commutativity only, the closest pyFM analogue of funcorr's eq. (5) fmap
    "plain": (1.0, 1e-1, 0.0, 0.0, True),
    # "plain" with the standard Laplacian-commutativity mask (lambda_i - lambda_j)^2 instead of
    # pyFM's default resolvent mask (use_resolvent_laplacian=False): a diagnostic
    "plain-std": (1.0, 1e-1, 0.0, 0.0, False),
}


def sh(cmd):
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=60).stdout.strip()
    except Exception as e:  # noqa: BLE001
        return f"unavailable ({e.__class__.__name__})"


def loadavg():
    try:
        with open("/proc/loadavg") as f:
            return [float(x) for x in f.read().split()[:3]]
    except OSError:
        return None


# ----------------------------------------------------------------------------- env
def cmd_env(a):
    from importlib import metadata

    versions = {}
    for pkg in ("pyfmaps", "numpy", "scipy", "scikit-learn", "potpourri3d", "robust_laplacian",
                "tqdm", "threadpoolctl"):
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            versions[pkg] = None
    blas = []
    try:
        import numpy  # noqa: F401
        import scipy.sparse.linalg  # noqa: F401
        import sklearn  # noqa: F401
        from threadpoolctl import threadpool_info

        blas = [{k: d.get(k) for k in ("user_api", "internal_api", "version", "num_threads", "prefix")}
                for d in threadpool_info()]
    except Exception as e:  # noqa: BLE001
        blas = [f"unavailable: {e}"]
    cpu = ""
    try:
        with open("/proc/cpuinfo") as f:
            m = re.search(r"^model name\s*:\s*(.*)$", f.read(), re.M)
            cpu = m.group(1).strip() if m else ""
    except OSError:
        pass
    env = {
        "date_utc": sh(["date", "-u"]),
        "nproc": os.cpu_count(),
        "nproc_cmd": sh(["nproc"]),
        "cpu_model": cpu,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "versions": versions,
        "blas": blas,
        "thread_env": {k: os.environ.get(k) for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                                      "MKL_NUM_THREADS", "RAYON_NUM_THREADS")},
        "git_commit": sh(["git", "-C", os.path.dirname(HERE), "rev-parse", "--short", "HEAD"]),
        "git_dirty_src": sh(["git", "-C", os.path.dirname(HERE), "status", "--porcelain", "--", "src",
                             "Cargo.toml", "Cargo.lock"]) != "",
        "loadavg": loadavg(),
    }
    if a.funcorr_bin:
        env["funcorr_version"] = sh([a.funcorr_bin, "--version"])
    with open(a.out, "w") as f:
        json.dump(env, f, indent=1)


# ----------------------------------------------------------------------------- run (pyFM)
def write_map(path, p2p, n_x, n_y):
    """Writes a map X -> Y (0-based); checks its length (n_x) and range (vertices of Y)."""
    import numpy as np

    p2p = np.asarray(p2p, dtype=np.int64)
    if p2p.shape != (n_x,) or p2p.min() < 0 or p2p.max() >= n_y:
        raise ValueError(f"map of shape {p2p.shape}, range [{p2p.min()}, {p2p.max()}]: "
                         f"not a map X -> Y ({n_x} vertices -> {n_y})")
    np.savetxt(path, p2p, fmt="%d")


def parse_variant(s):
    """'example', 'plain', 'plain-std' or NAME=w_descr,w_lap,w_dcomm,w_orient[,std]
    (std: the standard (lambda_i - lambda_j)^2 commutativity mask instead of the resolvent one)."""
    if "=" not in s:
        if s not in DEFAULT_VARIANTS:
            raise SystemExit(f"unknown variant {s!r}; give NAME=w_descr,w_lap,w_dcomm,w_orient[,std]")
        return s, DEFAULT_VARIANTS[s]
    name, w = s.split("=", 1)
    parts = w.split(",")
    resolvent = True
    if parts and parts[-1].strip() == "std":
        resolvent = False
        parts = parts[:-1]
    if len(parts) != 4:
        raise SystemExit(f"variant {s!r}: need 4 weights w_descr,w_lap,w_dcomm,w_orient[,std]")
    return name, tuple(float(x) for x in parts) + (resolvent,)


def cmd_run(a):
    import warnings

    import numpy as np

    warnings.simplefilter("ignore", DeprecationWarning)
    from pyFM.functional import FunctionalMapping
    from pyFM.mesh import TriMesh

    os.makedirs(a.out, exist_ok=True)
    variants = [parse_variant(v) for v in (a.variant or ["example"])]
    pc = time.perf_counter
    res = {"x": a.x, "y": a.y, "params": {
        "load": {"area_normalize": True, "center": True},
        "process": {"k": a.k_process, "intrinsic": bool(a.intrinsic)},
        "preprocess": {"descr_type": "WKS", "n_descr": a.n_descr, "k_descr": a.k_descr,
                       "subsample_step": a.subsample_step},
        "fit": {"K": a.K, "optinit": "zeros", "use_resolvent_laplacian": "per variant (default True)",
                "normalize_weights": True, "factr": 1e7, "pgtol": 1e-5},
        "icp_refine": {"nit": a.icp_nit, "tol": 1e-10},
        "zoomout_refine": {"nit": a.zo_nit, "step": a.zo_step, "final_k": a.K + a.zo_nit * a.zo_step},
        "roles": "mesh1 = Y (target), mesh2 = X (source): p2p_21 is the map X -> Y",
    }, "times": {}, "variants": {}}
    T = res["times"]

    # mesh1 = Y, mesh2 = X (see the module docstring)
    t = pc()
    mesh_y = TriMesh.load(a.y, area_normalize=True, center=True)
    mesh_x = TriMesh.load(a.x, area_normalize=True, center=True)
    T["load"] = pc() - t
    for mesh, path in ((mesh_x, a.x), (mesh_y, a.y)):
        with open(path) as f:
            f.readline()
            nv = int(f.readline().split()[0])
        if mesh.n_vertices != nv:
            raise SystemExit(f"{path}: pyFM read {mesh.n_vertices} vertices, the file has {nv}")
    res["n_x"], res["n_y"] = int(mesh_x.n_vertices), int(mesh_y.n_vertices)

    # Laplacian + eigenpairs (TriMesh.process: cotan or intrinsic Laplacian, eigsh sigma=-0.01)
    t = pc()
    mesh_y.process(k=a.k_process, intrinsic=bool(a.intrinsic))
    t1 = pc()
    mesh_x.process(k=a.k_process, intrinsic=bool(a.intrinsic))
    t2 = pc()
    T["laplacian_eigen"] = t2 - t
    T["laplacian_eigen_per_mesh"] = {"y": t1 - t, "x": t2 - t1}
    res["lambda_k"] = {"x": float(mesh_x.eigenvalues[-1]), "y": float(mesh_y.eigenvalues[-1])}

    # Descriptors: preprocess() sees the cached spectrum (process() is a no-op then) and computes
    # WKS on both meshes, keeps every subsample_step-th column and L2(area)-normalizes them.
    base = FunctionalMapping(mesh_y, mesh_x)
    t = pc()
    base.preprocess(n_descr=a.n_descr, descr_type="WKS", subsample_step=a.subsample_step,
                    k_process=a.k_process, k_descr=a.k_descr, verbose=False)
    T["descriptors"] = pc() - t
    res["n_descriptors"] = int(base.descr1.shape[1])
    # pyFM's descriptors (descr2 is on mesh2 = X, descr1 on mesh1 = Y), for the cross-check that
    # feeds them to funcorr (`--data matrix:descr_x.npy,descr_y.npy`)
    np.save(os.path.join(a.out, "descr_x.npy"), np.ascontiguousarray(base.descr2, dtype=np.float64))
    np.save(os.path.join(a.out, "descr_y.npy"), np.ascontiguousarray(base.descr1, dtype=np.float64))

    import copy

    for name, (w_descr, w_lap, w_dcomm, w_orient, resolvent) in variants:
        V = {"weights": {"w_descr": w_descr, "w_lap": w_lap, "w_dcomm": w_dcomm, "w_orient": w_orient},
             "use_resolvent_laplacian": resolvent,
             "times": {}, "maps": {}, "errors": {}}
        res["variants"][name] = V
        VT = V["times"]
        model = copy.copy(base)  # shares the processed meshes and descriptors (fit only sets FM_12)
        model.FM_12 = None
        try:
            t = pc()
            model.fit(K=a.K, w_descr=w_descr, w_lap=w_lap, w_dcomm=w_dcomm, w_orient=w_orient,
                      use_resolvent_laplacian=resolvent, verbose=False)
            VT["fit"] = pc() - t
            fm = model.FM_12
            V["fm_shape"] = list(fm.shape)
            V["fm_orthogonality"] = float(np.linalg.norm(fm.T @ fm - np.eye(fm.shape[1])))

            t = pc()
            p2p = model.get_p2p()
            VT["p2p"] = pc() - t
            path = os.path.join(a.out, f"{name}.fmap.map.txt")
            write_map(path, p2p, res["n_x"], res["n_y"])
            V["maps"]["fmap"] = path
        except Exception as e:  # noqa: BLE001
            V["errors"]["fit"] = repr(e)
            print(f"[pyfm] {name}: fit failed: {e!r}", file=sys.stderr)
            continue

        for stage, refine in (
            ("icp", lambda: model.icp_refine(nit=a.icp_nit, verbose=False)),
            ("zoomout", lambda: model.zoomout_refine(nit=a.zo_nit, step=a.zo_step, verbose=False)),
        ):
            try:
                t = pc()
                fm_r = refine()
                t1 = pc()
                p2p = model.get_p2p(fm_r)
                t2 = pc()
                VT[stage] = t2 - t
                VT[stage + "_refine_only"] = t1 - t
                VT[stage + "_final_p2p"] = t2 - t1
                V[stage + "_fm_shape"] = list(fm_r.shape)
                path = os.path.join(a.out, f"{name}.{stage}.map.txt")
                write_map(path, p2p, res["n_x"], res["n_y"])
                V["maps"][stage] = path
            except Exception as e:  # noqa: BLE001
                V["errors"][stage] = repr(e)
                print(f"[pyfm] {name}: {stage} failed: {e!r}", file=sys.stderr)

    with open(os.path.join(a.out, "pyfm.json"), "w") as f:
        json.dump(res, f, indent=1)
    parts = [f"spectrum {T['laplacian_eigen']:.2f} s", f"descriptors {T['descriptors']:.2f} s"]
    for name, V in res["variants"].items():
        parts.append(name + ": " + ", ".join(f"{k} {v:.2f} s" for k, v in V["times"].items()
                                             if not k.endswith(("_only", "_p2p")) or k == "p2p"))
    print("[pyfm] " + " | ".join(parts), file=sys.stderr)


# ----------------------------------------------------------------------------- funcorr report
_LOG_RE = re.compile(r"^(?P<name>.*?)\s+(?P<val>[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)\s*s$")


def funcorr_times(report_path, wall=None):
    with open(report_path) as f:
        rep = json.load(f)
    acc = {}
    for entry in rep.get("log", []):
        m = _LOG_RE.match(entry.strip())
        if not m:
            continue
        acc.setdefault(m.group("name"), []).append(float(m.group("val")))
    lap = sum(acc.get("laplacian", [])) + sum(acc.get("eigenbasis", []))
    out = {
        "read": sum(acc.get("read", [])),
        "laplacian_eigen": lap,
        "laplacian": sum(acc.get("laplacian", [])),
        "eigenbasis": sum(acc.get("eigenbasis", [])),
        "descriptors": sum(acc.get("data", [])),
        "fit": sum(acc.get("functional map", [])),
        # the map X -> Y, with the refinement (ICP / ZoomOut iterations) when there is one
        "pointwise": sum(acc.get("point-wise map", [])),
        # the reverse map, used only for colour transfer / rendering; not part of map.txt
        "map_yx": sum(acc.get("map Y → X", [])),
        "log": rep.get("log", []),
        "final_k": rep.get("final_k"),
        "basis_size": rep.get("basis_size"),
        "q": rep.get("q"),
        "options": {k: rep.get("options", {}).get(k) for k in
                    ("method", "k", "commutativity", "refine", "icp", "zoomout_to", "zoomout_step")},
    }
    if wall is not None:
        out["wall"] = wall
    return out


def cmd_funcorr_times(a):
    json.dump(funcorr_times(a.report, a.wall), sys.stdout, indent=1)


# ----------------------------------------------------------------------------- table
STAGES = ("fmap", "icp", "zoomout")
STAGE_LABEL = {"fmap": "fmap → p2p", "icp": "+ ICP", "zoomout": "+ ZoomOut"}
ERR_FIELDS = ("err_sym", "at05_sym", "at10_sym", "err_nonsym", "at05_nonsym", "at10_nonsym", "time")
TIME_FIELDS = ("spectrum", "descriptors", "fit", "fmap", "icp", "zoomout", "to_zoomout")


def load_eval(path):
    if not path or not os.path.exists(path):
        return None
    try:
        with open(path) as f:
            d = json.load(f)
        s = d["summary"]
        return {"mean": s["mean"], "at_005": s.get("at_005"), "at_010": s.get("at_010"),
                "at_025": s.get("at_025"), "symmetric": d.get("symmetric")}
    except Exception:  # noqa: BLE001
        return None


def fmt(v, spec):
    return "—" if v is None else format(v, spec)


def mean_of(vals):
    vals = [v for v in vals if v is not None]
    return sum(vals) / len(vals) if vals else None


def error_rows(row):
    """One row per (tool, map stage): errors (×100 for the means) and the stage's seconds."""
    rows = []
    for tool in row["tools"]:
        for stage in STAGES:
            st = tool["stages"].get(stage)
            if st is None:
                continue
            es, en = st.get("eval_sym"), st.get("eval_nonsym")
            rows.append({
                "tool": tool["name"], "stage": stage,
                "err_sym": None if es is None else 100 * es["mean"],
                "at05_sym": None if es is None else es["at_005"],
                "at10_sym": None if es is None else es["at_010"],
                "err_nonsym": None if en is None else 100 * en["mean"],
                "at05_nonsym": None if en is None else en["at_005"],
                "at10_nonsym": None if en is None else en["at_010"],
                "time": st.get("time"),
            })
    return rows


def time_rows(row):
    """One row per tool: seconds of every stage, and the sum spectrum + descriptors + fit + ZoomOut."""
    rows = []
    for tool in row["tools"]:
        p = tool.get("pre", {})
        r = {"tool": tool["name"], "spectrum": p.get("laplacian_eigen"), "descriptors": p.get("descriptors"),
             "fit": p.get("fit")}
        for stage in STAGES:
            r[stage] = (tool["stages"].get(stage) or {}).get("time")
        parts = [r["spectrum"], r["descriptors"], r["fit"], r["zoomout"]]
        r["to_zoomout"] = None if any(v is None for v in parts) else sum(parts)
        rows.append(r)
    return rows


def md_errors(rows):
    out = ["| tool | stage | err ×100 sym | ≤0.05 sym | ≤0.10 sym | err ×100 non-sym | ≤0.05 non-sym "
           "| ≤0.10 non-sym | stage s |",
           "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        out.append(
            f"| {r['tool']} | {STAGE_LABEL[r['stage']]} | {fmt(r['err_sym'], '.2f')} | "
            f"{fmt(r['at05_sym'], '.3f')} | {fmt(r['at10_sym'], '.3f')} | {fmt(r['err_nonsym'], '.2f')} | "
            f"{fmt(r['at05_nonsym'], '.3f')} | {fmt(r['at10_nonsym'], '.3f')} | {fmt(r['time'], '.2f')} |")
    return out


def md_times(rows):
    out = ["| tool | spectrum s | descriptors s | fit s | fmap → p2p s | ICP s | ZoomOut s | "
           "spectrum → ZoomOut map s |",
           "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        out.append(f"| {r['tool']} | " + " | ".join(fmt(r[k], ".2f") for k in TIME_FIELDS) + " |")
    return out


def mean_rows(per_pair, keys, fields):
    order, acc = [], {}
    for rows in per_pair:
        for r in rows:
            key = tuple(r[k] for k in keys)
            if key not in acc:
                order.append(key)
                acc[key] = []
            acc[key].append(r)
    out = []
    for key in order:
        rs = acc[key]
        m = dict(zip(keys, key))
        for fld in fields:
            m[fld] = mean_of([r[fld] for r in rs])
        m["n"] = len(rs)
        out.append(m)
    return out


def cmd_table(a):
    with open(a.env) as f:
        env = json.load(f)
    rows = []
    for p in a.rows:
        with open(p) as f:
            rows.append(json.load(f))
    lines = []
    v = env.get("versions", {})
    lines.append(f"Machine: {env.get('cpu_model')}, {env.get('nproc_cmd')} CPUs (`nproc`), "
                 f"{env.get('platform')}; run {env.get('date_utc')}; load average at start "
                 f"{env.get('loadavg')}.")
    lines.append(f"pyFM side: Python {env.get('python')}, pyfmaps {v.get('pyfmaps')}, numpy {v.get('numpy')}, "
                 f"scipy {v.get('scipy')}, scikit-learn {v.get('scikit-learn')}, robust_laplacian "
                 f"{v.get('robust_laplacian')}, potpourri3d {v.get('potpourri3d')}. funcorr: "
                 f"{env.get('funcorr_version')} (repository at commit {env.get('git_commit')}).")
    lines.append("")
    err_pp, time_pp = [], []
    for row in rows:
        er, tr = error_rows(row), time_rows(row)
        err_pp.append(er)
        time_pp.append(tr)
        lines.append(f"#### {row['x_name']} → {row['y_name']} (n = {row.get('n_x')}, m = {row.get('n_y')})")
        lines.append("")
        lines += md_errors(er)
        lines.append("")
        lines += md_times(tr)
        lines.append("")
        if row.get("loadavg_before"):
            lines.append(f"Load average (1, 5, 15 min) before the timed runs of this pair "
                         f"{row['loadavg_before']}, after {row.get('loadavg_after')}.")
            lines.append("")
    me = mean_rows(err_pp, ("tool", "stage"), ERR_FIELDS)
    mt = mean_rows(time_pp, ("tool",), TIME_FIELDS)
    if rows:
        lines.append(f"#### Mean over the {len(rows)} pairs")
        lines.append("")
        lines += md_errors(me)
        lines.append("")
        lines += md_times(mt)
        lines.append("")
        short = [f"{r['tool']} {r.get('stage', '')} ({r['n']}/{len(rows)})".replace("  ", " ")
                 for r in me + mt if r["n"] != len(rows)]
        if short:
            lines.append("Means over fewer pairs (a stage failed): " + ", ".join(short))
            lines.append("")
    lines.append("Errors: `funcorr eval` (exact geodesics on Y / √area(Y) at the template points of "
                 "`corres/*.vts`) of the map X → Y; \"sym\" allows the left–right flip "
                 "(`--gt-target-sym`), \"non-sym\" does not. ≤0.05 / ≤0.10: fraction of the template "
                 "points with error at most 0.05 / 0.10. \"stage s\": that stage alone: the conversion "
                 "of the fitted map to a point map, or the refinement started from the fitted map "
                 "including its final point-map conversion. Timing table: spectrum = Laplacian + "
                 "eigenpairs of both shapes, descriptors = WKS of both shapes (for \"funcorr + pyFM's "
                 "WKS\": reading pyFM's saved descriptors), fit = the functional-map solve; the last "
                 "column is spectrum + descriptors + fit + ZoomOut. One run per pair: seconds are single "
                 "measurements.")
    text = "\n".join(lines)
    print(text)
    if a.md:
        with open(a.md, "w") as f:
            f.write(text + "\n")
    with open(a.out, "w") as f:
        json.dump({"env": env, "pairs": rows, "mean_errors": me, "mean_times": mt}, f, indent=1)


# ----------------------------------------------------------------------------- row
def cmd_row(a):
    """Assemble one pair's row from the pyFM json, funcorr reports and eval JSONs in DIR."""
    d = a.dir
    row = {"x": a.x, "y": a.y, "x_name": os.path.splitext(os.path.basename(a.x))[0],
           "y_name": os.path.splitext(os.path.basename(a.y))[0], "tools": []}
    try:
        with open(os.path.join(d, "loadavg")) as f:
            la = [[float(v) for v in line.split()] for line in f if line.strip()]
        row["loadavg_before"] = la[0] if la else None
        row["loadavg_after"] = la[1] if len(la) > 1 else None
    except (OSError, ValueError):
        pass
    # funcorr: its own pipeline (tag funcorr) and, for the cross-check, fed pyFM's descriptors
    # (tag funcorrx)
    for tag, label in (("funcorr", "funcorr"), ("funcorrx", "funcorr + pyFM's WKS")):
        fc = {"name": label, "tag": tag, "stages": {}, "pre": {}, "runs": {}}
        for stage, refine in (("fmap", "none"), ("icp", "icp"), ("zoomout", "zoomout")):
            rep = os.path.join(d, f"{tag}_{refine}", "report.json")
            if not os.path.exists(rep):
                continue
            wall = None
            wp = os.path.join(d, f"{tag}_{refine}.wall")
            if os.path.exists(wp):
                with open(wp) as f:
                    wall = float(f.read().strip())
            ft = funcorr_times(rep, wall)
            fc["runs"][refine] = ft
            if stage == "fmap":
                fc["pre"] = {"laplacian_eigen": ft["laplacian_eigen"], "descriptors": ft["descriptors"],
                             "fit": ft["fit"]}
            fc["stages"][stage] = {
                "time": ft["pointwise"],
                "eval_sym": load_eval(os.path.join(d, f"eval.{tag}.{stage}.sym.json")),
                "eval_nonsym": load_eval(os.path.join(d, f"eval.{tag}.{stage}.nonsym.json")),
            }
        if fc["runs"]:
            row["tools"].append(fc)
    pj = os.path.join(d, "pyfm", "pyfm.json")
    if os.path.exists(pj):
        with open(pj) as f:
            py = json.load(f)
        row["n_x"], row["n_y"] = py.get("n_x"), py.get("n_y")
        row["pyfm"] = py
        for name, V in py["variants"].items():
            tool = {"name": f"pyFM ({name})", "tag": f"pyfm-{name}", "stages": {},
                    "pre": {"laplacian_eigen": py["times"].get("laplacian_eigen"),
                            "descriptors": py["times"].get("descriptors"), "fit": V["times"].get("fit")}}
            for stage in STAGES:
                if stage not in V["maps"]:
                    continue
                tkey = "p2p" if stage == "fmap" else stage
                tool["stages"][stage] = {
                    "time": V["times"].get(tkey),
                    "eval_sym": load_eval(os.path.join(d, f"eval.pyfm-{name}.{stage}.sym.json")),
                    "eval_nonsym": load_eval(os.path.join(d, f"eval.pyfm-{name}.{stage}.nonsym.json")),
                }
            row["tools"].append(tool)
    with open(a.out, "w") as f:
        json.dump(row, f, indent=1)
    # progress line
    bits = []
    for tool in row["tools"]:
        for stage in STAGES:
            st = tool["stages"].get(stage)
            if st and st.get("eval_sym"):
                bits.append(f"{tool['name']} {stage} {100 * st['eval_sym']['mean']:.2f}")
    print(f"[bench] {row['x_name']} -> {row['y_name']}: err×100 sym: " + ", ".join(bits), file=sys.stderr)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)

    e = sub.add_parser("env")
    e.add_argument("--out", required=True)
    e.add_argument("--funcorr-bin")
    e.set_defaults(f=cmd_env)

    r = sub.add_parser("run")
    r.add_argument("--x", required=True, help="source shape X (.off)")
    r.add_argument("--y", required=True, help="target shape Y (.off)")
    r.add_argument("--out", required=True)
    r.add_argument("--variant", action="append",
                   help="'example', 'plain', 'plain-std' or NAME=w_descr,w_lap,w_dcomm,w_orient[,std] "
                        "(repeatable)")
    r.add_argument("--k-process", type=int, default=200, help="eigenpairs per mesh (pyFM default 200)")
    r.add_argument("--intrinsic", type=int, default=0, help="1: intrinsic (robust_laplacian) Laplacian")
    r.add_argument("--n-descr", type=int, default=100)
    r.add_argument("--k-descr", type=int, default=128)
    r.add_argument("--subsample-step", type=int, default=2)
    r.add_argument("--K", type=int, default=30, help="functional map size of fit()")
    r.add_argument("--icp-nit", type=int, default=10)
    r.add_argument("--zo-nit", type=int, default=16)
    r.add_argument("--zo-step", type=int, default=5)
    r.set_defaults(f=cmd_run)

    ft = sub.add_parser("funcorr-times")
    ft.add_argument("--report", required=True)
    ft.add_argument("--wall", type=float)
    ft.set_defaults(f=cmd_funcorr_times)

    rw = sub.add_parser("row")
    rw.add_argument("--dir", required=True)
    rw.add_argument("--x", required=True)
    rw.add_argument("--y", required=True)
    rw.add_argument("--out", required=True)
    rw.set_defaults(f=cmd_row)

    t = sub.add_parser("table")
    t.add_argument("--env", required=True)
    t.add_argument("--out", required=True)
    t.add_argument("--md")
    t.add_argument("rows", nargs="*")
    t.set_defaults(f=cmd_table)

    a = p.parse_args()
    a.f(a)


if __name__ == "__main__":
    main()
