"""The viewer page (``funcorr view``) in a real browser: headless Chromium driven over the
DevTools pipe (``cdp.py``). It waits for the first frame and checks that both shapes are drawn in
two known views, that a pick marks the map's image, that the heat map's colour at a vertex is
its error's, that a mouse click picks the vertex under it, and that the page fetches nothing.

Skipped when Chromium is missing, except in CI (``FUNCORR_CI`` set by ``.ci/run``, which installs
Debian's ``chromium``), where a missing browser fails.
"""

import os
import subprocess

import numpy as np
import pytest

import funcorr
from cdp import Browser, find_chromium
from conftest import DATA, X_PATH, Y_PATH

WIDTH, HEIGHT = 1200, 700


@pytest.fixture(scope="module")
def chromium():
    path = find_chromium()
    if path is None:
        if os.environ.get("FUNCORR_CI"):
            pytest.fail("chromium not found, but FUNCORR_CI is set: .ci/run installs it (apt-get install -y chromium)")
        pytest.skip("chromium not found: `apt-get install chromium` (or set FUNCORR_CHROMIUM) to run the browser test; CI runs it")
    return path


@pytest.fixture(scope="module")
def mesh_faces():
    return funcorr.read_mesh(X_PATH)[1]


@pytest.fixture(scope="module")
def scrambled(default_match, ground_truth, mesh_x):
    """The default map with the head's vertices sent to arbitrary vertices of Y: large errors
    there, small elsewhere (so that the heat map shows more than one colour)."""
    v = mesh_x[0]
    head = np.flatnonzero(v[:, 1] > v[:, 1].max() - 0.22)
    m = default_match.map_yx.shape[0]
    bad = default_match.map_xy.copy()
    bad[head] = (head * 7919 + 13) % m
    return bad, head


@pytest.fixture(scope="module")
def page(tmp_path_factory, default_match, cli, scrambled):
    """view.html of the scrambled map, written by the CLI, with heat-method errors."""
    d = tmp_path_factory.mktemp("viewer")
    bad, _ = scrambled
    np.savetxt(d / "map.txt", bad, fmt="%d")
    np.savetxt(d / "map_yx.txt", default_match.map_yx, fmt="%d")
    out = d / "view.html"
    subprocess.run(
        [str(cli), "view", str(X_PATH), str(Y_PATH), "--map", str(d / "map.txt"), "--map-yx", str(d / "map_yx.txt"),
         "--gt-source", str(DATA / "tr_reg_000.vts"), "--gt-target", str(DATA / "tr_reg_001.vts"),
         "--geodesics", "heat", "-o", str(out)],
        check=True,
        capture_output=True,
    )
    return out


@pytest.fixture(scope="module")
def browser(chromium, page):
    b = Browser(chromium, WIDTH, HEIGHT)
    url = page.resolve().as_uri()
    b.allowed = lambda u: u == url or u.startswith("about:")
    b.navigate(url)
    load = b.eval(
        "new Promise((ok, fail) => { const t0 = Date.now(); (function wait() {"
        " if (window.funcorr && window.funcorr.ready) window.funcorr.ready.then(ok);"
        " else if (Date.now() - t0 > 20000) fail(new Error('no window.funcorr'));"
        " else setTimeout(wait, 20); })(); })",
        timeout=30,
    )
    assert load > 0
    yield b
    b.close()


def canvas_rows(browser):
    r = browser.eval("(r => [r.top, r.bottom])(document.getElementById('view').getBoundingClientRect())")
    return int(np.ceil(r[0])), int(r[1])


def drawn(img, rows, x0, x1):
    """Fraction of the canvas strip [x0, x1) that is not the white background, and the number of
    distinct colours there."""
    strip = img[rows[0]:rows[1], x0:x1].reshape(-1, 3).astype(np.int32)
    mask = (strip < 245).any(axis=1)
    colours = np.unique(strip[mask] // 8, axis=0).shape[0] if mask.any() else 0
    return mask.mean(), colours


def test_first_frame_and_both_shapes_in_two_views(browser):
    assert browser.eval("window.funcorr.frames") >= 1
    stats = {}
    rows = canvas_rows(browser)
    assert rows[1] - rows[0] > 400
    for view in [(0, 0), (90, 0)]:
        browser.eval(f"window.funcorr.view({view[0]}, {view[1]})")
        img = browser.screenshot()
        assert img.shape == (HEIGHT, WIDTH, 3)
        left, right = drawn(img, rows, 0, WIDTH // 2), drawn(img, rows, WIDTH // 2, WIDTH)
        for name, (fraction, colours) in (("X", left), ("Y", right)):
            assert 0.01 < fraction < 0.6, f"view {view}: {name} covers {fraction:.3f} of its half"
            assert colours > 40, f"view {view}: {name} has {colours} colours (colour transfer missing?)"
        stats[view] = (left[0], right[0])
    # The side view of a standing human covers less than the front view (arms out).
    assert stats[(90, 0)][0] < 0.9 * stats[(0, 0)][0], stats
    assert browser.exceptions() == []


def visible_vertices(browser, ids, side="x"):
    got = browser.eval(f"{list(map(int, ids))}.map(i => window.funcorr.project(i, '{side}'))")
    return {i: p for i, p in zip(ids, got) if p and p["visible"]}


def test_a_pick_marks_the_image_of_a_vertex(browser, scrambled):
    bad, _ = scrambled
    browser.eval("window.funcorr.view(0, 0)")
    browser.eval("window.funcorr.set({mode: 'transfer', shading: 'smooth'})")
    # A vertex of X whose image is visible too (front view).
    candidates = np.random.default_rng(1).choice(len(bad), 400, replace=False)
    vis_x = visible_vertices(browser, candidates)
    vis_y = visible_vertices(browser, [int(bad[i]) for i in vis_x], "y")
    i = next(i for i in vis_x if int(bad[i]) in vis_y)
    j = int(bad[i])
    before = browser.screenshot().astype(np.int32)
    picked = browser.eval(f"window.funcorr.pick({int(i)})")
    assert picked == {"x": int(i), "y": j}
    after = browser.screenshot().astype(np.int32)
    top, bottom = canvas_rows(browser)
    changed = np.argwhere(np.abs(after - before)[top:bottom].sum(axis=2) > 60) + [top, 0]
    assert len(changed) > 30, "the pick drew nothing"
    px, py = vis_x[i], vis_y[j]
    near = lambda p: np.hypot(changed[:, 1] - p["x"], changed[:, 0] - p["y"]) < 30
    assert near(px).sum() > 10, "no marker at the picked vertex of X"
    assert near(py).sum() > 10, "no marker at its image on Y"
    assert (near(px) | near(py)).mean() > 0.95, "the pick changed pixels away from the two markers"
    # The markers are magenta.
    for p in (px, py):
        r, g, b = after[int(p["y"]), int(p["x"])]
        assert r > 200 and b > 200 and g < 80, (p, (r, g, b))
    # The reverse direction, through map_yx.
    back = browser.eval(f"window.funcorr.pick({j}, 'y')")
    assert back["y"] == j and back["x"] == browser.eval(f"window.funcorr.mapYX({j})")


def test_a_click_picks_the_vertex_under_the_pointer(browser):
    browser.eval("window.funcorr.view(0, 0)")
    vis = visible_vertices(browser, list(range(0, 4999, 97)))
    assert len(vis) > 10
    hits = 0
    for i, p in list(vis.items())[:8]:
        browser.click(p["x"], p["y"])
        status = browser.eval("document.getElementById('status').textContent")
        hits += status.startswith(f"X vertex {i} ")
    assert hits >= 7, f"{hits} of 8 clicks picked the vertex under the pointer"


def test_the_heat_map_colour_at_a_vertex_is_its_error(browser, scrambled, ground_truth, mesh_x, mesh_faces):
    bad, head = scrambled
    gt_x, gt_y, _ = ground_truth
    errors = funcorr.evaluate(bad, Y_PATH, gt_x, gt_y, geodesics="heat")["errors"]
    n = len(bad)
    total, count = np.zeros(n), np.zeros(n)
    np.add.at(total, gt_x, errors)
    np.add.at(count, gt_x, 1)
    measured = count > 0
    per_vertex = np.where(measured, total / np.maximum(count, 1), np.nan)
    # Vertices that are not template points take the error of the nearest template vertex.
    v = mesh_x[0]
    template = np.flatnonzero(measured)
    for i in np.flatnonzero(~measured):
        per_vertex[i] = per_vertex[template[np.argmin(((v[template] - v[i]) ** 2).sum(axis=1))]]
    page_values = np.array(browser.eval("Array.from({length: %d}, (_, i) => window.funcorr.errorAt(i))" % n))
    assert np.allclose(page_values, per_vertex, atol=1e-6), "the page's per-vertex errors"
    assert browser.eval("window.funcorr.measuredAt(%d)" % template[0]) is True
    # Vertices whose neighbours have nearly their error: the pixel there has the vertex's colour.
    spread = np.zeros(n)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        d = np.abs(per_vertex[mesh_faces[:, a]] - per_vertex[mesh_faces[:, b]])
        np.maximum.at(spread, mesh_faces[:, a], d)
        np.maximum.at(spread, mesh_faces[:, b], d)
    # ... and that face the camera (not on the silhouette, where the pixel is half background).
    tri = v[mesh_faces]
    face_normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals = np.zeros_like(v)
    for k in range(3):
        np.add.at(normals, mesh_faces[:, k], face_normals)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True) + 1e-300
    calm = np.flatnonzero((spread < 0.005) & (np.abs(normals[:, 2]) > 0.6))
    browser.eval("window.funcorr.set({mode: 'error', shading: 'unlit'})")
    bar = browser.eval("window.funcorr.bar('error')")
    lut = np.array(bar["colors"], dtype=np.float64)
    expected = lambda e: np.array([np.interp(min(max(e, 0), bar["max"]), np.linspace(0, bar["max"], len(lut)), lut[:, c]) for c in range(3)])
    for view in [(0, 0), (180, 0)]:
        browser.eval(f"window.funcorr.view({view[0]}, {view[1]})")
        img = browser.screenshot().astype(np.float64)
        rng = np.random.default_rng(view[0])
        vis = visible_vertices(browser, rng.choice(calm, min(300, len(calm)), replace=False))
        assert len(vis) >= 20, f"view {view}: only {len(vis)} calm visible vertices"
        ok, misses = 0, []
        for i, p in vis.items():
            got = img[int(p["y"]), int(p["x"])]
            good = np.abs(got - expected(per_vertex[i])).max() <= 24
            ok += good
            if not good:
                misses.append((int(i), round(per_vertex[i], 4), got.tolist(), expected(per_vertex[i]).round().tolist()))
        assert ok >= 0.85 * len(vis), f"view {view}: {ok} of {len(vis)} pixels have their vertex's error colour; misses {misses[:12]}"
    # Both ends of the scale are on screen: the scrambled head is dark, the body pale.
    browser.eval("window.funcorr.view(0, 0)")
    img = browser.screenshot().astype(np.float64)
    # (vertices whose neighbours all have errors beyond the top of the scale: the darkest colour)
    lowest = per_vertex.copy()
    for a, b in ((0, 1), (1, 2), (2, 0)):
        np.minimum.at(lowest, mesh_faces[:, a], per_vertex[mesh_faces[:, b]])
        np.minimum.at(lowest, mesh_faces[:, b], per_vertex[mesh_faces[:, a]])
    head_vis = visible_vertices(browser, [int(h) for h in head if lowest[h] > bar["max"]])
    dark = [img[int(p["y"]), int(p["x"])].sum() for p in head_vis.values()]
    assert len(head_vis) >= 3 and np.median(dark) < 300, f"high errors are not drawn dark: {dark}"
    browser.eval("window.funcorr.set({mode: 'transfer', shading: 'smooth'})")


def test_save_png_and_no_network_request(browser, page):
    png = browser.eval("window.funcorr.snapshot()")
    assert png.startswith("data:image/png;base64,") and len(png) > 20000
    url = page.resolve().as_uri()
    assert browser.blocked == [], f"the page asked for {browser.blocked}"
    assert [u for u in browser.requests if u != url] == [], browser.requests
    # The interception works: a request the page makes now is seen and failed.
    failed = browser.eval("fetch('http://127.0.0.1:9/probe').then(() => false, () => true)")
    assert failed and browser.blocked == ["http://127.0.0.1:9/probe"]
    assert browser.exceptions() == []


def test_the_notebook_view_renders_inside_its_iframe(chromium, default_match, tmp_path):
    """``MatchResult._repr_html_`` (an ``<iframe srcdoc>``, sandboxed) shows the viewer."""
    notebook = tmp_path / "notebook.html"
    notebook.write_text(
        "<!DOCTYPE html><html><body style='margin:0'><p>cell output:</p>" + default_match._repr_html_() + "</body></html>",
        encoding="utf-8",
    )
    b = Browser(chromium, 1000, 700)
    try:
        url = notebook.resolve().as_uri()
        b.allowed = lambda u: u == url or u.startswith("about:")
        b.navigate(url)
        deadline = __import__("time").monotonic() + 20
        while True:
            img = b.screenshot()
            box = b.eval("(r => [r.top, r.bottom, r.left, r.right])(document.querySelector('iframe').getBoundingClientRect())")
            top, bottom, left, right = (int(v) for v in box)
            inner = img[top + 120:bottom - 40, left + 5:right - 5].reshape(-1, 3).astype(int)
            coloured = ((inner.max(axis=1) - inner.min(axis=1)) > 40).mean()
            if coloured > 0.02 or __import__("time").monotonic() > deadline:
                break
        assert coloured > 0.02, f"the iframe shows no coloured shapes ({coloured:.4f})"
        assert b.blocked == [] and all(u == url or u.startswith("about:") for u in b.requests), b.requests
        assert b.exceptions() == []
    finally:
        b.close()
