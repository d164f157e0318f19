"""funcorr.match gives exactly the map of the command-line tool on the same inputs."""
import subprocess

import numpy as np
import pytest

import funcorr

from conftest import X_PATH, Y_PATH


def cli_match(cli, tmp_path, *flags):
    out = tmp_path / "out"
    cmd = [str(cli), "match", str(X_PATH), str(Y_PATH), "-o", str(out), "--no-cache", "--no-render", "-q", *flags]
    subprocess.run(cmd, check=True, capture_output=True)
    map_txt = np.loadtxt(out / "map.txt", dtype=np.int64)
    return map_txt, np.load(out / "C.npy")


def test_default_match_equals_the_cli(cli, tmp_path, default_match):
    map_txt, C = cli_match(cli, tmp_path)
    assert map_txt.shape == default_match.map_xy.shape == (4999,)
    assert np.array_equal(map_txt, default_match.map_xy)
    assert np.array_equal(C, default_match.C)


@pytest.mark.parametrize(
    "flags, options",
    [
        (
            ["--method", "fmap", "--data", "wks:50", "-k", "30", "--refine", "icp"],
            dict(method="fmap", data="wks:50", k=30, refine="icp"),
        ),
        (
            ["--data", "hks:40", "--candidates", "20,30", "--polish", "0", "--zoomout-to", "80", "--w-orientation", "1"],
            dict(data="hks:40", candidates=[20, 30], polish=0, zoomout_to=80, w_orientation=1.0),
        ),
        (
            ["--method", "completion", "--data", "wks:30", "--kprime", "40", "-k", "10", "--max-iterations", "5",
             "--mu3", "0.5", "--init", "svd", "--refine", "zoomout", "--zoomout-to", "60", "--zoomout-step", "10"],
            dict(method="completion", data="wks:30", kprime=40, k=10, max_iterations=5, mu3=0.5, init="svd",
                 refine="zoomout", zoomout_to=60, zoomout_step=10),
        ),
        (
            # Issue 12's options: the L1 term on samples, the stopping rule on the map, and the
            # large-pair searches forced on.
            ["--method", "completion", "--data", "wks:30", "--kprime", "40", "-k", "10", "--max-iterations", "30",
             "--l1-samples", "500", "--map-check-every", "5", "--map-tolerance", "0.01"],
            dict(method="completion", data="wks:30", kprime=40, k=10, max_iterations=30, l1_samples=500,
                 map_check_every=5, map_tolerance=0.01),
        ),
        (
            # The L1 term's products in f32.
            ["--method", "completion", "--data", "wks:30", "--kprime", "40", "-k", "10", "--max-iterations", "10",
             "--l1-f32"],
            dict(method="completion", data="wks:30", kprime=40, k=10, max_iterations=10, l1_f32=True),
        ),
        (
            # The paper's literal setting instead of the default speed settings: every vertex,
            # f64 products, one scale.
            ["--method", "completion", "--data", "wks:30", "--kprime", "40", "-k", "10", "--max-iterations", "10",
             "--l1-samples", "0", "--l1-precision", "f64", "--multiscale", "1"],
            dict(method="completion", data="wks:30", kprime=40, k=10, max_iterations=10, l1_samples=0,
                 l1_precision="f64", multiscale=1),
        ),
        (
            ["--near-above", "0", "--near-cells", "8", "--zoomout-samples", "1000"],
            dict(near_above=0, near_cells=8, zoomout_samples=1000),
        ),
    ],
)
def test_options_match_the_cli_flags(cli, tmp_path, flags, options):
    map_txt, C = cli_match(cli, tmp_path, *flags)
    r = funcorr.match(X_PATH, Y_PATH, **options)
    assert np.array_equal(map_txt, r.map_xy)
    assert np.array_equal(C, r.C)
