"""funcorr.batch.match_pairs: local threads and Ray give the same maps, the same as funcorr.match."""
import json

import numpy as np
import pytest

import funcorr
from funcorr.batch import match_pairs

from conftest import DATA, X_PATH, Y_PATH

OPTIONS = dict(method="fmap", data="wks:50", k=30, refine="icp")


@pytest.fixture(scope="module")
def collection(mesh_x, mesh_y):
    V, F = mesh_y
    mirrored = V * np.array([-1.0, 1.0, 1.0])
    bad = (np.zeros_like(V), F)  # every vertex at one point: no Laplacian
    shapes = {"x": str(X_PATH), "y": (V, F), "y_mirror": (mirrored, F[:, ::-1]), "bad": bad}
    pairs = [("x", "y"), ("y", "x"), ("x", "y_mirror"), ("x", "bad"), ("y", "y")]
    gt = {"x": funcorr.read_vts(DATA / "tr_reg_000.vts"), "y": funcorr.read_vts(DATA / "tr_reg_001.vts")}
    return shapes, pairs, gt


@pytest.fixture(scope="module")
def local_results(collection, tmp_path_factory):
    shapes, pairs, gt = collection
    out = tmp_path_factory.mktemp("batch")
    seen = []
    results = match_pairs(shapes, pairs, engine="local", n_jobs=2, threads_per_job=1, out_dir=out,
                          ground_truth=gt, callback=seen.append, **OPTIONS)
    return results, out, seen


def test_local_engine(collection, local_results):
    shapes, pairs, gt = collection
    results, out, seen = local_results
    assert [(r.x, r.y) for r in results] == pairs and len(seen) == len(pairs)
    ok = {(r.x, r.y): r for r in results if r.ok}
    assert set(ok) == {("x", "y"), ("y", "x"), ("x", "y_mirror"), ("y", "y")}
    bad = results[3]
    assert not bad.ok and "shape 'bad'" in bad.error and bad.map_xy is None
    # The same maps as funcorr.match on each pair.
    direct = funcorr.match(X_PATH, Y_PATH, **OPTIONS)
    assert np.array_equal(ok[("x", "y")].map_xy, direct.map_xy)
    assert np.array_equal(ok[("x", "y")].C, direct.C)
    assert ok[("y", "y")].evaluation["mean"] < 0.01  # a shape matched to itself
    ev = ok[("x", "y")].evaluation
    assert ev is not None and 0 < ev["mean"] < 0.2
    assert ok[("x", "y_mirror")].evaluation is None  # no ground truth for the mirror
    # Files: one map per successful pair (0-based, as funcorr bench), pairs.json with the failure.
    m = np.loadtxt(out / "maps" / "x__y.fmap.txt", dtype=np.int64)
    assert np.array_equal(m, direct.map_xy)
    records = json.loads((out / "pairs.json").read_text())
    assert [r["error"] is None for r in records] == [True, True, True, False, True]
    assert records[0]["mean"] == ev["mean"]


def test_bad_arguments_raise_before_any_work(collection):
    shapes, pairs, _ = collection
    with pytest.raises(ValueError, match="pairs: no shape named 'z'"):
        match_pairs(shapes, [("x", "z")])
    with pytest.raises(ValueError, match="engine"):
        match_pairs(shapes, pairs, engine="dask")
    with pytest.raises(ValueError, match="refine"):
        match_pairs(shapes, pairs, refine="magic")


def test_ray_engine_gives_the_same_maps(collection, local_results):
    ray = pytest.importorskip("ray")  # .ci/run installs funcorr[ray]: there it runs
    shapes, pairs, gt = collection
    local, _, _ = local_results
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        streamed = []
        results = match_pairs(shapes, pairs, engine="ray", ground_truth=gt, callback=streamed.append, **OPTIONS)
    finally:
        ray.shutdown()
    assert len(streamed) == len(pairs)
    for a, b in zip(local, results):
        assert (a.x, a.y, a.ok) == (b.x, b.y, b.ok)
        if a.ok:
            assert np.array_equal(a.map_xy, b.map_xy) and np.array_equal(a.map_yx, b.map_yx)
            assert np.array_equal(a.C, b.C)
            assert (a.evaluation is None) == (b.evaluation is None)
            if a.evaluation is not None:
                assert a.evaluation["mean"] == b.evaluation["mean"]
        else:
            assert "shape 'bad'" in b.error


def test_a_data_set_in_the_bench_layout(root, tmp_path):
    from funcorr.batch import load_dataset

    ds = load_dataset(root / "data" / "faust")
    assert ds.pairs == [("tr_reg_000", "tr_reg_001"), ("tr_reg_001", "tr_reg_000")]
    assert set(ds.ground_truth) == set(ds.symmetric) == {"tr_reg_000", "tr_reg_001"}
    results = ds.match(n_jobs=2, threads_per_job=1, geodesics="dijkstra", **OPTIONS)
    assert all(r.ok and r.evaluation["symmetric"] for r in results)
    direct = funcorr.match(X_PATH, Y_PATH, **OPTIONS)
    assert np.array_equal(results[0].map_xy, direct.map_xy)
    (tmp_path / "pairs.txt").write_text("a\tb\n")
    with pytest.raises(FileNotFoundError, match="names 'a'"):
        load_dataset(tmp_path)
