"""The viewer page from Python: funcorr.view, MatchResult.show / _repr_html_, the pyFM-style
plots of funcorr.compat.pyfm (the page is the library's, as `funcorr view` writes it; the
browser test is test_viewer_browser.py)."""

import html as html_lib
import json
import re

import numpy as np
import pytest

import funcorr
from conftest import X_PATH, Y_PATH


def meta(page: str) -> dict:
    m = re.search(r'<script type="application/json" id="funcorr-meta">(.*?)</script>', page, re.S)
    return json.loads(m.group(1))


def test_show_returns_the_viewer_and_displays_inline(default_match, ground_truth, tmp_path):
    r = default_match
    v = r.show()
    assert isinstance(v, funcorr.Viewer)
    m = meta(v.html)
    assert (m["x"]["n"], m["y"]["n"], m["errors"], m["map_yx_inferred"]) == (4999, 5000, None, False)
    assert "axiomatic" in m["method"]
    assert "THREE" in v.html and v.html.startswith("<!DOCTYPE html>")
    inline = r._repr_html_()
    assert inline.startswith("<iframe srcdoc=") and 'sandbox="allow-scripts' in inline
    assert html_lib.unescape(inline.split('srcdoc="', 1)[1].split('" style=', 1)[0]) == v.html
    gt_x, gt_y, gt_sym = ground_truth
    v = r.show(gt=(gt_x, gt_y, gt_sym), soft=[3], title="bundled pair")
    m = meta(v.html)
    ev = r.evaluate(gt_x, gt_y, gt_sym)
    assert m["errors"]["mean"] == pytest.approx(ev["mean"], abs=1e-12) and m["errors"]["symmetric"]
    assert [mode["label"] for mode in m["modes"]] == ["colour transfer", "error on X", "soft map T δ_3 on Y"]
    assert m["title"] == "bundled pair" and m["modes"][2]["mark"] == {"side": "x", "vertex": 3}
    v.save(tmp_path / "v.html")
    assert (tmp_path / "v.html").read_text(encoding="utf-8") == v.html
    assert "MB page" in repr(v)


def test_view_takes_any_map_and_one_shape(default_match, mesh_x, mesh_y):
    v = funcorr.view(X_PATH, Y_PATH, default_match.map_xy)
    m = meta(v.html)
    assert m["map_yx_inferred"] and m["title"] == "tr_reg_000 → tr_reg_001"
    one = meta(funcorr.view(mesh_x).html)
    assert one["y"] is None and one["modes"][0]["label"] == "colours"
    values = mesh_x[0][:, 1]
    f = meta(funcorr.view(mesh_x, fields={"height": ("x", values)}, start="height").html)
    assert f["start"] == "field0" and f["fields"][0]["absmax"] == pytest.approx(np.abs(values).max())
    colours = np.random.default_rng(0).random((len(mesh_y[0]), 3))
    assert meta(funcorr.view(mesh_x, mesh_y, colors_y=colours).html)["y"]["n"] == len(mesh_y[0])
    points = meta(funcorr.view((mesh_x[0], None)).html)
    assert points["x"]["triangles"] is None


def test_view_rejects_inputs_that_do_not_fit(default_match, mesh_x, ground_truth):
    with pytest.raises(ValueError, match="map_xy"):
        funcorr.view(X_PATH, Y_PATH, default_match.map_xy[:-1])
    with pytest.raises(ValueError, match="map_yx"):
        funcorr.view(X_PATH, Y_PATH, default_match.map_xy, np.full(5000, 4999))
    with pytest.raises(ValueError, match="needs the target shape Y"):
        funcorr.view(X_PATH, None, default_match.map_xy)
    with pytest.raises(ValueError, match="map_xy"):
        funcorr.view(X_PATH, Y_PATH, gt=ground_truth[:2])
    with pytest.raises(ValueError, match="soft"):
        funcorr.view(X_PATH, Y_PATH, default_match.map_xy, fields={"soft": ("y", np.zeros(3))})
    with pytest.raises(ValueError, match="fields"):
        funcorr.view(X_PATH, Y_PATH, default_match.map_xy, fields={"soft": ("z", np.zeros(5000))})
    with pytest.raises(ValueError, match="colors_x"):
        funcorr.view(mesh_x, colors_x=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="start"):
        funcorr.view(mesh_x, start="nothing")
    with pytest.raises(ValueError, match="error_max"):
        funcorr.view(X_PATH, Y_PATH, default_match.map_xy, gt=ground_truth[:2], error_max=0)


def test_pyfm_style_plots(mesh_x, mesh_y, default_match):
    from funcorr.compat.pyfm import TriMesh, viz
    from funcorr.compat.pyfm.viz import double_plot, plot_mesh, vertices_to_rgb

    mesh1, mesh2 = TriMesh(*mesh_x), TriMesh(*mesh_y)
    cmap1 = vertices_to_rgb(mesh1.vertlist)
    assert cmap1.shape == (mesh1.n_vertices, 3) and cmap1.min() == 0 and cmap1.max() == 1
    v = meta(plot_mesh(mesh1, cmap1).html)
    assert v["y"] is None and v["modes"][0]["label"] == "colours"
    s = meta(plot_mesh(mesh1, mesh1.vertlist[:, 0]).html)
    assert s["start"] == "field0" and s["modes"][1]["label"] == "scalars"
    with pytest.warns(UserWarning, match="cmap"):
        plot_mesh(mesh1, cmap="viridis")
    p2p_21 = default_match.map_yx
    d = meta(double_plot(mesh1, mesh2, cmap1, cmap1[p2p_21], p2p_21=p2p_21).html)
    assert d["x"]["n"] == 4999 and d["y"]["n"] == 5000 and d["map_yx"] is not None
    assert viz.normalize(np.array([2.0, 4.0, 3.0])).tolist() == [0.0, 1.0, 0.5]
    assert viz.normalize(np.ones(3)).tolist() == [0.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="param"):
        vertices_to_rgb(mesh1.vertlist, param=(1, 1, 2))
