"""Load time, frame time and file size of the viewer page (`funcorr view`) of a large pair, in
headless Chromium (software WebGL: SwiftShader, no GPU), driven over the DevTools pipe.

    python bench/viewer_timing.py [--levels 4] [--out /tmp/viewer-big]

The bundled FAUST pair (data/faust, ~5k vertices each) is subdivided `--levels` times by
`examples/subdivide.rs` (4 levels: 1.28 M vertices, 2.56 M triangles per shape). Subdivision
keeps vertex i of the coarse mesh as vertex i, so the map of `funcorr match` on the coarse pair
and the bundled ground truth still apply; every new vertex is mapped as its nearest coarse vertex.
Needs the release binaries (`cargo build --release -p funcorr-cli --example subdivide`), the
Python package (for the coarse match) and chromium. Prints one JSON object.
"""

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python" / "tests"))
from cdp import Browser, find_chromium  # noqa: E402

import funcorr  # noqa: E402


def run(args):
    t = time.perf_counter()
    subprocess.run([str(a) for a in args], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--levels", type=int, default=4)
    ap.add_argument("--out", default="/tmp/viewer-big")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--geodesics", default="dijkstra", help="for the errors of --gt (exact, heat, dijkstra; none: no errors)")
    ap.add_argument("--page", help="time this page instead of writing one")
    a = ap.parse_args()
    if a.page:
        print(json.dumps(measure(Path(a.page), a.frames, True), indent=1))
        return
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target")) / "release"
    cli, sub = target / "funcorr", target / "examples" / "subdivide"
    data = ROOT / "data" / "faust"
    report = {"levels": a.levels}
    fine = []
    for name in ("tr_reg_000", "tr_reg_001"):
        p = out / f"{name}_x{4 ** a.levels}.off"
        if not p.exists():
            run([sub, data / f"{name}.off", a.levels, p])
        fine.append(p)
    coarse = funcorr.match(data / "tr_reg_000.off", data / "tr_reg_001.off")
    vx, fx = funcorr.read_mesh(fine[0])
    vy, fy = funcorr.read_mesh(fine[1])
    n0, m0 = len(coarse.map_xy), len(coarse.map_yx)
    report.update(n=len(vx), m=len(vy), faces_x=len(fx), faces_y=len(fy))
    # New vertices take the map of their nearest coarse vertex.
    map_xy = coarse.map_xy[cKDTree(vx[:n0]).query(vx)[1]]
    map_yx = coarse.map_yx[cKDTree(vy[:m0]).query(vy)[1]]
    np.save(out / "map_xy.npy", map_xy.astype(np.uint64))
    np.save(out / "map_yx.npy", map_yx.astype(np.uint64))
    page = out / "view.html"
    args = [cli, "view", fine[0], fine[1], "--map", out / "map_xy.npy", "--map-yx", out / "map_yx.npy", "-o", page]
    if a.geodesics != "none":
        args += ["--gt-source", data / "tr_reg_000.vts", "--gt-target", data / "tr_reg_001.vts", "--geodesics", a.geodesics]
    report["write_seconds"] = round(run(args), 2)
    report.update(measure(page, a.frames, a.geodesics != "none"))
    print(json.dumps(report, indent=1))


def measure(page: Path, n_frames: int, errors: bool) -> dict:
    """Load and frame times of `page` in headless Chromium."""
    report = {"file_mb": round(page.stat().st_size / 1e6, 1)}
    b = Browser(find_chromium(), 1400, 800, timeout=120)
    try:
        url = page.resolve().as_uri()
        b.allowed = lambda u: u == url
        t = time.perf_counter()
        b.send("Page.navigate", {"url": url})
        ready = b.eval(
            "new Promise(ok => { (function w() { window.funcorr && window.funcorr.ready ?"
            " window.funcorr.ready.then(ok) : setTimeout(w, 20); })(); })",
            timeout=120,
        )
        report["load_to_first_frame_s"] = round(time.perf_counter() - t, 2)
        report["first_frame_page_ms"] = round(ready)
        frames = b.eval(f"window.funcorr.timeFrames({n_frames})", timeout=600)
        report["orbit_frame_ms"] = {k: round(frames[k], 1) for k in ("mean", "median", "max")}
        frames = b.eval(f"window.funcorr.timeFrames({n_frames}, true)", timeout=600)
        report["orbit_frame_ms_while_dragging"] = {k: round(frames[k], 1) for k in ("mean", "median", "max")}
        report["preview"] = frames.get("preview", False)
        t = time.perf_counter()
        b.eval("window.funcorr.pick(Math.floor(window.funcorr.meta.x.n / 2))", timeout=120)
        report["pick_s"] = round(time.perf_counter() - t, 2)
        if errors:
            b.eval("window.funcorr.set({mode: 'error'})", timeout=120)
            frames = b.eval(f"window.funcorr.timeFrames({n_frames})", timeout=600)
            report["orbit_frame_ms_error_map"] = round(frames["median"], 1)
        t = time.perf_counter()
        vertex = b.eval("(p => p.x)(window.funcorr.project(777))", timeout=120)
        report["hover_pick_s"] = round(time.perf_counter() - t, 2)
        report["exceptions"] = b.exceptions()
        report["requests_other_than_the_page"] = [u for u in b.requests if u != url]
        b.send("Page.captureScreenshot", {"format": "png"})
        del vertex
    finally:
        b.close()
    return report


if __name__ == "__main__":
    main()
