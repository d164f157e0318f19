"""Inputs: dtypes, memory orders, and a ValueError naming the argument for every bad one."""
import numpy as np
import pytest

import funcorr

from conftest import X_PATH


def laplacian(V, F):
    W, A = funcorr.cotangent_laplacian(V, F)
    return W.toarray() if W.shape[0] < 100 else W, A


def small_mesh():
    # An octahedron: 6 vertices, 8 faces.
    V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64)
    F = np.array(
        [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]], dtype=np.int64
    )
    return V, F


def test_every_float_dtype_and_memory_order_gives_the_same_laplacian(mesh_x):
    V, F = mesh_x
    W0, A0 = funcorr.cotangent_laplacian(V, F)
    variants = [
        (V.astype(np.float32).astype(np.float64), F),  # reference for float32 below
        (np.asfortranarray(V), np.asfortranarray(F)),
        (V, F.astype(np.int32)),
        (V, F.astype(np.uint32)),
        (np.repeat(V, 2, axis=1)[:, ::2], F),  # strided view
        (np.hstack([V, V])[:, :3], F[:, :]),  # non-contiguous view
        (V.astype(">f8"), F.astype(">i4")),  # big-endian
    ]
    for i, (v, f) in enumerate(variants):
        W, A = funcorr.cotangent_laplacian(v, f)
        if i == 0:
            W32, A32 = funcorr.cotangent_laplacian(V.astype(np.float32), F)
            assert (W32 != W).nnz == 0 and np.array_equal(A32, A), "float32 is widened to float64 exactly"
            continue
        assert (W != W0).nnz == 0 and np.array_equal(A, A0), f"variant {i}"
    # float16 is accepted too (widened).
    Wh, Ah = funcorr.cotangent_laplacian(small_mesh()[0].astype(np.float16), small_mesh()[1])
    Wd, Ad = funcorr.cotangent_laplacian(small_mesh()[0], small_mesh()[1])
    assert np.allclose(Ah, Ad)


@pytest.mark.parametrize(
    "V, F, needle",
    [
        (np.zeros((6, 2)), small_mesh()[1], "V: expected shape (n, 3)"),
        (np.zeros((6, 3, 1)), small_mesh()[1], "V: expected shape (n, 3)"),
        (np.zeros((6, 3), dtype=np.int64), small_mesh()[1], "V: expected a floating-point array"),
        (np.zeros((6, 3), dtype=np.complex128), small_mesh()[1], "V: expected a floating-point array"),
        ("not an array", small_mesh()[1], "V:"),
        (small_mesh()[0], small_mesh()[1].astype(np.float64), "F: expected an integer array"),
        (small_mesh()[0], small_mesh()[1][:, :2], "F: expected shape (f, 3)"),
        (small_mesh()[0], small_mesh()[1] + 1, "F: face 4 has vertex index 6 out of range [0, 6)"),
        (small_mesh()[0], small_mesh()[1] - 1, "F: face 0 has vertex index -1 out of range"),
        (small_mesh()[0], np.zeros((0, 3), dtype=np.int64), "F: a triangle mesh needs at least one face"),
    ],
)
def test_bad_arrays_raise_value_errors_naming_the_argument(V, F, needle):
    with pytest.raises(ValueError) as e:
        funcorr.cotangent_laplacian(V, F)
    assert needle in str(e.value)


def test_nan_and_inf_vertices_are_named():
    V, F = small_mesh()
    for bad in (np.nan, np.inf, -np.inf):
        W = V.copy()
        W[3, 1] = bad
        with pytest.raises(ValueError, match=r"V: row 3 has a NaN or infinite coordinate"):
            funcorr.cotangent_laplacian(W, F)
    with pytest.raises(ValueError, match=r"shape\[0\] \(vertices\): row 3"):
        funcorr.prepare((W, F), k=2)


def test_shape_arguments_are_checked(mesh_x):
    V, F = mesh_x
    with pytest.raises(ValueError, match=r"shape\[1\] \(faces\): face 0 has vertex index"):
        funcorr.prepare((V, F + len(V)), k=5)
    with pytest.raises(ValueError, match="expected \\(V, F\\)"):
        funcorr.prepare((V, F, F), k=5)
    with pytest.raises(ValueError, match=r"k: k asks for 5000 eigenpairs, but the shape has n = 4999"):
        funcorr.prepare((V, F), k=5000)
    with pytest.raises(FileNotFoundError):
        funcorr.prepare("/nonexistent/shape.off")
    with pytest.raises(ValueError, match="laplacian"):
        funcorr.prepare((V, F), k=5, laplacian="spectral")
    with pytest.raises(TypeError, match="unexpected keyword argument \"bogus\""):
        funcorr.prepare((V, F), k=5, bogus=1)


def test_match_options_are_checked_before_any_work(mesh_x):
    X = str(X_PATH)
    with pytest.raises(ValueError, match="method"):
        funcorr.match(X, X, method="magic")
    with pytest.raises(ValueError, match="data"):
        funcorr.match(X, X, data="wsk")
    with pytest.raises(ValueError, match="refine: the axiomatic method refines with ZoomOut"):
        funcorr.match(X, X, refine="icp")
    with pytest.raises(ValueError, match="candidates"):
        funcorr.match(X, X, candidates=[0, 10])
    with pytest.raises(ValueError, match="zoomout_step"):
        funcorr.match(X, X, zoomout_step=0)
    with pytest.raises(ValueError, match="kprime: 20 eigenpairs per shape are fewer than the 128"):
        funcorr.match(X, X, kprime=20)
    with pytest.raises(ValueError, match="w_orientation: must be finite and ≥ 0"):
        funcorr.match(X, X, w_orientation=-1.0)
    with pytest.raises(ValueError, match="k: expected a non-negative integer"):
        funcorr.match(X, X, method="fmap", k=-3)
    with pytest.raises(ValueError, match="l1_precision: \"f16\": expected one of f64, f32"):
        funcorr.match(X, X, method="completion", data="wks:30", l1_precision="f16")
    with pytest.raises(ValueError, match="l1_f32: give either l1_precision or l1_f32"):
        funcorr.match(X, X, method="completion", data="wks:30", l1_precision="f64", l1_f32=True)
    with pytest.raises(TypeError, match="zoomout-to|zoomout_too"):
        funcorr.match(X, X, zoomout_too=50)
    V, F = mesh_x
    with pytest.raises(ValueError, match="data: F has 4999 rows and G 10"):
        funcorr.match((V, F), (V, F), data=(np.ones((len(V), 3)), np.ones((10, 3))))
    with pytest.raises(ValueError, match=r"data\[1\] \(G\): entry \(0, 0\) is NaN"):
        G = np.ones((len(V), 3))
        G[0, 0] = np.nan
        funcorr.match((V, F), (V, F), data=(np.ones((len(V), 3)), G))


def test_index_arguments_are_checked(prepared_pair, mesh_y):
    X, Y = prepared_pair
    with pytest.raises(ValueError, match=r"sources: entry 1 is 5000, out of range \[0, 5000\)"):
        funcorr.geodesic_distances(mesh_y, [0, 5000])
    with pytest.raises(ValueError, match="sources: expected an integer array"):
        funcorr.geodesic_distances(mesh_y, [0.5])
    with pytest.raises(ValueError, match="map_yx: length 10 but Y has m = 5000"):
        funcorr.render_pair(X, Y, np.zeros(10, dtype=np.int64))
    with pytest.raises(ValueError, match="C: expected a square"):
        funcorr.zoomout_refine(X, Y, np.eye(10)[:, :5], k_final=20)
    assert funcorr.icp_refine(X, Y, np.eye(10)[:, :5])[0].shape == (10, 5)  # k_Y × k_X maps
    with pytest.raises(ValueError, match="C: a 70 × 70 map \\(k_Y × k_X\\) needs 70 eigenpairs on X"):
        funcorr.icp_refine(X, Y, np.eye(70))
    with pytest.raises(ValueError, match="X: expected a PreparedShape"):
        funcorr.icp_refine(mesh_y, Y, np.eye(10))
    with pytest.raises(ValueError, match="out: expected shape \\(5000, 5000\\)"):
        funcorr.geodesic_all_pairs(mesh_y, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="out: expected a writable"):
        funcorr.geodesic_all_pairs(mesh_y, np.zeros((5000, 5000), dtype=np.float32))
    with pytest.raises(ValueError, match="method"):
        funcorr.geodesic_distances(mesh_y, [0], method="euclid")
    with pytest.raises(ValueError, match="basis: expected a PreparedShape or a tuple"):
        funcorr.hks(np.eye(3))


def test_thread_count_setting(monkeypatch):
    from funcorr import _funcorr

    monkeypatch.delenv("FUNCORR_NUM_THREADS", raising=False)
    try:
        # Computations run on a pool of exactly the threads asked for.
        for n in (1, 3):
            funcorr.set_num_threads(n)
            assert funcorr.get_num_threads() == n and _funcorr._pool_threads() == n
        funcorr.set_num_threads(None)
        assert _funcorr._pool_threads() == funcorr.get_num_threads() >= 1
        monkeypatch.setenv("FUNCORR_NUM_THREADS", "3")
        assert funcorr.get_num_threads() == 3 and _funcorr._pool_threads() == 3
        funcorr.set_num_threads(2)  # the call's setting wins over the environment
        assert _funcorr._pool_threads() == 2
        funcorr.set_num_threads(None)
        monkeypatch.setenv("FUNCORR_NUM_THREADS", "many")
        with pytest.raises(ValueError, match="FUNCORR_NUM_THREADS"):
            funcorr.cotangent_laplacian(*small_mesh())
    finally:
        funcorr.set_num_threads(None)


def test_shape_arguments_name_the_shape_and_the_expected_array():
    V, F = funcorr.read_mesh(X_PATH)
    flat = V[:, :2]
    for args, name in (((flat, X_PATH), "X"), ((X_PATH, flat), "Y")):
        with pytest.raises(ValueError) as e:
            funcorr.match(*args)
        msg = str(e.value)
        assert msg.startswith(f"{name}: ") and "(n, 3)" in msg and "(4999, 2)" in msg, msg
    # 2-D points stay usable where no surface is needed.
    P = funcorr.prepare(flat[:300], k=5)
    assert P.n == 300 and not P.is_mesh


def test_thread_counts_are_value_errors():
    for bad in (-1, 2.5, "4", True, 1 << 40):
        with pytest.raises(ValueError, match="n: expected a number of threads"):
            funcorr.set_num_threads(bad)
    funcorr.set_num_threads(None)


def test_the_namespace_holds_the_api():
    public = {n for n in dir(funcorr) if not n.startswith("_")}
    assert not public & {"np", "json", "Dict", "Any", "Optional", "dataclass", "field", "annotations", "TYPE_CHECKING"}
    assert set(funcorr.__all__) <= public
    assert public - set(funcorr.__all__) <= {"batch", "compat"}


def test_results_have_a_short_repr(default_match, ground_truth):
    r = default_match
    text = repr(r)
    assert len(text) < 160 and "axiomatic" in text and "n=4999" in text and "m=5000" in text, text
    r.evaluate(*ground_truth)
    assert "mean error ×100" in repr(r)
    assert len(repr(r.X)) < 80


def test_a_noisy_mesh_is_smoothed_and_a_clean_one_is_not(mesh_x):
    # Gaussian noise of σ = 0.5 % of the bounding-box diagonal (seeded): the mesh is rough, and
    # its Laplacian is built on the geometry smoothed by one step (`laplacian="auto"`, the
    # default); the clean mesh, and the noisy one with `laplacian="cotan"`, are used as they are.
    V, F = mesh_x
    diag = np.linalg.norm(V.max(0) - V.min(0))
    noisy = V + np.random.default_rng(27).normal(scale=0.005 * diag, size=V.shape)
    assert funcorr.prepare((V, F), k=10).denoised is None
    P = funcorr.prepare((noisy, F), k=10)
    d = P.denoised
    assert d["roughness_before"] > 0.05 and d["roughness_after"] <= 0.04 and d["time"] > 0, d
    assert d["folded_after"] <= d["folded_before"], d
    np.testing.assert_array_equal(P.vertices, noisy)
    assert funcorr.prepare((noisy, F), k=10, laplacian="cotan").denoised is None
