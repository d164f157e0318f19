"""Every function on the bundled FAUST pair, checked against what it must satisfy."""
import pickle

import numpy as np
import pytest
import scipy.sparse as sp

import funcorr

from conftest import DATA, X_PATH, Y_PATH


def test_read_and_write_mesh_round_trip(tmp_path, mesh_x):
    V, F = mesh_x
    assert V.shape == (4999, 3) and V.dtype == np.float64
    assert F.shape == (9994, 3) and F.dtype == np.int64 and F.min() == 0 and F.max() == 4998
    for ext in ("off", "ply"):
        p = tmp_path / f"x.{ext}"
        funcorr.write_mesh(p, V, F)
        V2, F2 = funcorr.read_mesh(p)
        assert np.array_equal(F2, F)
        assert np.allclose(V2, V, atol=1e-6)
    colors = np.zeros((len(V), 3), dtype=np.uint8)
    colors[:, 0] = 255
    funcorr.write_mesh(tmp_path / "c.ply", V, F, colors)
    with pytest.raises(ValueError, match="colors: expected shape"):
        funcorr.write_mesh(tmp_path / "c.ply", V, F, colors[:10])
    # A point cloud: no faces.
    funcorr.write_mesh(tmp_path / "p.ply", V[:100])
    Vp, Fp = funcorr.read_mesh(tmp_path / "p.ply")
    assert Vp.shape == (100, 3) and Fp.shape == (0, 3)
    bad = tmp_path / "bad.off"
    bad.write_text("OFF\n3 1 0\n0 0 0\n1 0 x\n")
    with pytest.raises(ValueError, match="bad.off:4: expected a number"):
        funcorr.read_mesh(bad)


def test_cotangent_laplacian(mesh_x):
    V, F = mesh_x
    W, A = funcorr.cotangent_laplacian(V, F)
    assert isinstance(W, sp.csr_matrix) and W.shape == (len(V), len(V))
    assert abs(W - W.T).max() < 1e-12
    assert np.abs(np.asarray(W.sum(axis=1))).max() < 1e-10
    assert np.all(W.diagonal() > 0)
    # A: barycentric areas summing to the surface area.
    e1, e2 = V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1).sum()
    assert A.shape == (len(V),) and np.isclose(A.sum(), area)
    # x ↦ xᵀ W x is the Dirichlet energy: zero on constants, positive on the coordinates.
    assert np.all(np.einsum("ij,ij->j", V, W @ V) > 0)


def test_point_cloud_laplacians(mesh_x):
    V, _ = mesh_x
    W, A = funcorr.knn_laplacian(V, k=10)
    assert np.all(A == 1.0) and abs(W - W.T).max() < 1e-12
    assert (W.getnnz(axis=1) >= 11).all()
    Wd, Ad = funcorr.knn_laplacian(V, k=10, vertex_weights="degree")
    assert np.allclose(Ad, Wd.diagonal())
    Wc, Ac = funcorr.cloud_laplacian(V)
    _, Am = funcorr.cotangent_laplacian(*funcorr.read_mesh(X_PATH))
    assert abs(Ac.sum() - Am.sum()) / Am.sum() < 0.05  # the cloud's area ≈ the mesh's


def test_eigenbasis_is_mass_orthonormal_and_deterministic(mesh_x):
    V, F = mesh_x
    evals, Phi, A = funcorr.eigenbasis(V, F, k=30)
    assert evals.shape == (30,) and Phi.shape == (len(V), 30) and A.shape == (len(V),)
    assert np.all(np.diff(evals) >= 0) and abs(evals[0]) < 1e-8
    assert np.abs(Phi.T @ (A[:, None] * Phi) - np.eye(30)).max() < 1e-8
    W, _ = funcorr.cotangent_laplacian(V, F)
    assert np.abs(W @ Phi - (A[:, None] * Phi) * evals).max() < 1e-5
    evals2, Phi2, _ = funcorr.eigenbasis(np.asfortranarray(V.astype(np.float64)), F.astype(np.int32), k=30)
    assert np.array_equal(evals, evals2) and np.array_equal(Phi, Phi2)


def test_prepared_shape_arrays_are_read_only_views(prepared_pair):
    X, _ = prepared_pair
    a, b = X.eigenvectors, X.eigenvectors
    assert np.shares_memory(a, b) and a.shape == (X.n, X.k) and not a.flags.writeable
    assert not X.eigenvalues.flags.writeable and not X.mass.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        a[0, 0] = 1.0
    del X  # the arrays keep the shape alive
    assert np.isfinite(a).all() and abs(a[:, 0].std()) < 1e-9  # φ₁ is constant


def test_prepared_shapes_pickle_bit_for_bit(prepared_pair):
    X, _ = prepared_pair
    Z = pickle.loads(pickle.dumps(X))
    assert isinstance(Z, funcorr.PreparedShape) and (Z.n, Z.k) == (X.n, X.k)
    for a in ("eigenvalues", "eigenvectors", "mass", "vertices", "faces"):
        assert np.array_equal(getattr(Z, a), getattr(X, a)), a
    assert (funcorr.stiffness(Z) != funcorr.stiffness(X)).nnz == 0
    # A point cloud prepared with the point-cloud Laplacian pickles too.
    P = funcorr.prepare(X.vertices[::5], k=10)
    Q = pickle.loads(pickle.dumps(P))
    assert Q.faces.shape == (0, 3) and np.array_equal(Q.eigenvectors, P.eigenvectors)


def test_descriptors(prepared_pair):
    X, _ = prepared_pair
    basis = (X.eigenvalues, X.eigenvectors, X.mass)
    h = funcorr.hks(X, count=20)
    assert h.shape == (X.n, 20) and np.all(np.isfinite(h))
    assert np.array_equal(h, funcorr.hks(basis, count=20))
    h_raw = funcorr.hks(X, times=[0.01, 0.1], normalize=False)
    # HKS at time t: Σ_i exp(-λ_i t) φ_i(x)²
    expected = (X.eigenvectors**2) @ np.exp(-np.outer(X.eigenvalues, [0.01, 0.1]))
    assert np.allclose(h_raw, expected)
    w = funcorr.wks(X, count=30)
    assert w.shape == (X.n, 30) and np.all(np.isfinite(w))
    assert funcorr.wks_recipe(X).shape == (X.n, 50)
    m = funcorr.hkm(X, [0, 10], count=3)
    assert m.shape == (X.n, 6)
    assert np.argmax(m[:, 0]) == 0 or m[0, 0] >= 0.5 * m[:, 0].max()  # peaks at its seed
    with pytest.raises(ValueError, match="seeds: entry 0 is 5000"):
        funcorr.hkm(X, [5000])


def test_segments_and_regions(prepared_pair, tmp_path):
    X, Y = prepared_pair
    labels = funcorr.persistence_segments(X)
    assert labels.shape == (X.n,) and labels.min() == 1 and labels.max() >= 3
    F, G = funcorr.regions(X, Y)
    assert F.shape[0] == X.n and G.shape[0] == Y.n and F.shape[1] == G.shape[1] >= 3
    lx = np.loadtxt(DATA / "tr_reg_000_tr_reg_001.tr_reg_000.seg.sym", dtype=np.int64)
    ly = np.loadtxt(DATA / "tr_reg_000_tr_reg_001.tr_reg_001.seg.sym", dtype=np.int64)
    F, G = funcorr.regions(X, Y, kind="labels", labels_x=lx, labels_y=ly)
    assert F.shape[1] == G.shape[1] == len(set(lx) & set(ly))
    with pytest.raises(ValueError, match="labels_y: 10 labels for 5000 vertices"):
        funcorr.regions(X, Y, kind="labels", labels_x=lx, labels_y=ly[:10])
    with pytest.raises(ValueError, match="kind"):
        funcorr.regions(X, Y, kind="voronoi")


def test_geodesics(mesh_y):
    V, F = mesh_y
    d0 = funcorr.geodesic_distances(mesh_y, 0)
    assert d0.shape == (len(V),) and d0[0] == 0 and np.all(d0[1:] > 0)
    # Exact distances are at least the straight-line distance and at most Dijkstra's.
    assert np.all(d0 >= np.linalg.norm(V - V[0], axis=1) - 1e-9)
    dj = funcorr.geodesic_distances(mesh_y, [0], method="dijkstra")[:, 0]
    assert np.all(d0 <= dj + 1e-9)
    heat = funcorr.geodesic_distances(mesh_y, [0], method="heat")[:, 0]
    assert np.median(np.abs(heat[1:] - d0[1:]) / d0[1:]) < 0.05
    D = funcorr.geodesic_distances(mesh_y, [0, 7, 99])
    assert D.shape == (len(V), 3) and np.array_equal(D[:, 0], d0)
    p = funcorr.geodesic_pairs(mesh_y, [[0, 7], [7, 0], [99, 99]])
    assert np.allclose(p[:2], [D[7, 0], D[0, 1]], rtol=1e-9) and p[2] == 0


def test_all_pairs_into_a_memmap(tmp_path):
    # A small mesh: the first 300 vertices of an icosphere-like patch of the FAUST mesh would
    # leave holes; use a subdivided octahedron instead.
    V, F = octasphere(3)
    n = len(V)
    out = np.memmap(tmp_path / "d.f64", dtype=np.float64, mode="w+", shape=(n, n))
    r = funcorr.geodesic_all_pairs((V, F), out, chunk=50)
    assert r is out
    D = funcorr.geodesic_distances((V, F), np.arange(n))
    assert np.array_equal(np.asarray(out), D.T)
    assert np.allclose(out, out.T, atol=1e-9)
    again = np.memmap(tmp_path / "d.f64", dtype=np.float64, mode="r", shape=(n, n))
    assert np.array_equal(again, D.T)
    fortran = np.zeros((n, n), order="F")
    funcorr.geodesic_all_pairs((V, F), fortran, method="dijkstra")
    assert np.all(fortran >= np.asarray(out) - 1e-9)


def octasphere(levels):
    V = [np.array(v, dtype=float) for v in [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]]
    F = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    for _ in range(levels):
        mid = {}

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = V[a] + V[b]
                V.append(p / np.linalg.norm(p))
                mid[key] = len(V) - 1
            return mid[key]

        F = [t for a, b, c in F for t in ([a, m(a, b), m(c, a)], [b, m(b, c), m(a, b)], [c, m(c, a), m(b, c)], [m(a, b), m(b, c), m(c, a)])]
    return np.array(V), np.array(F, dtype=np.int32)


def test_evaluation(mesh_y, ground_truth):
    gx, gy, gs = ground_truth
    # The template lists repeat some vertices of X: keep each once.
    _, first = np.unique(gx, return_index=True)
    gx, gy, gs = gx[first], gy[first], gs[first]
    # The ground-truth map itself: zero error.
    map_xy = np.zeros(4999, dtype=np.int64)
    map_xy[gx] = gy
    ev = funcorr.evaluate(map_xy, mesh_y, gx, gy)
    assert ev["mean"] == 0 and ev["at_005"] == 1 and np.all(ev["curve"] == 1)
    # Every point mapped to the mirrored point: large error, zero with symmetric flips allowed.
    map_xy[gx] = gs
    assert funcorr.evaluate(map_xy, mesh_y, gx, gy, geodesics="heat")["mean"] > 0.05
    ev = funcorr.evaluate(map_xy, mesh_y, gx, gy, gs)
    assert ev["mean"] == 0 and ev["symmetric"]
    t, c = funcorr.cumulative_curve([0.0, 0.01, 0.2])
    assert len(t) == 51 and c[0] == pytest.approx(1 / 3) and c[-1] == 1
    with pytest.raises(ValueError, match="map_xy: entry 0 is 5000"):
        funcorr.evaluate(np.full(4999, 5000), mesh_y, gx, gy)


def test_match_fmap_zoomout_icp_and_maps(prepared_pair, ground_truth):
    X, Y = prepared_pair
    gx, gy, gs = ground_truth
    r = funcorr.match(X, Y, method="fmap", data="wks:50", k=30, refine="none")
    assert r.C.shape == (30, 30) and r.map_xy.shape == (X.n,) and r.map_yx.shape == (Y.n,)
    assert r.map_xy.min() >= 0 and r.map_xy.max() < Y.n and r.map_yx.max() < X.n
    assert r.report["options"]["method"] == "fmap" and r.report["q"] == 50
    # The point maps of the method's own functional map.
    a, b = funcorr.maps_from_fmap(X, Y, r.C)
    assert np.array_equal(a, r.map_xy) and np.array_equal(b, r.map_yx)
    before = funcorr.evaluate(r.map_xy, Y, gx, gy, gs)["mean"]
    C_icp, m_icp = funcorr.icp_refine(X, Y, r.C, iterations=5)
    # Orthonormal between the unit-area bases: in the shapes' units C = √(area_Y / area_X) · Q.
    s = np.sqrt(Y.area / X.area)
    assert C_icp.shape == (30, 30) and np.allclose(C_icp @ C_icp.T, s**2 * np.eye(30), atol=1e-9)
    assert np.isclose(abs(r.C[0, 0]), s, rtol=1e-6) and np.isclose(X.area, X.mass.sum())
    C_zo, m_zo = funcorr.zoomout_refine(X, Y, r.C, k_final=60, step=5)
    assert C_zo.shape == (60, 60)
    after = funcorr.evaluate(m_zo, Y, gx, gy, gs)["mean"]
    assert after < before
    C_back = funcorr.fmap_from_map(X, Y, funcorr.maps_from_fmap(X, Y, C_zo)[1], 60)
    assert C_back.shape == (60, 60)
    with pytest.raises(ValueError, match="k_final"):
        funcorr.zoomout_refine(X, Y, r.C, k_final=61)
    # The same match from given data (F, G) = the descriptors of "wks:50".
    F, G = funcorr.wks(X, 50), funcorr.wks(Y, 50)
    r2 = funcorr.match(X, Y, method="fmap", data=(F, G), k=30, refine="none")
    assert np.array_equal(r2.map_xy, r.map_xy)


def test_completion_method_runs(prepared_pair):
    X, Y = prepared_pair
    r = funcorr.match(X, Y, method="completion", data="wks:20", kprime=40, k=10, max_iterations=5, refine="none")
    A, B = r.coefficients
    assert A.shape == (40, 10) and B.shape == (40, 10) and r.C_method.shape == (40, 40)
    assert r.report["solver"]["iterations"] <= 5


@pytest.mark.parametrize(
    "options",
    [
        dict(method="pokrass", k=20),
        dict(method="coupled", k=20),
        dict(method="completion", form="fixed-rank", kprime=40, k=10, max_iterations=3),
        dict(method="completion", form="low-norm", kprime=40, k=10, max_iterations=3),
    ],
)
def test_every_method_runs(prepared_pair, options):
    X, Y = prepared_pair
    r = funcorr.match(X, Y, data="wks:30", refine="none", **options)
    k = options.get("kprime", options["k"])
    assert r.C.shape == (k, k) and r.map_xy.shape == (X.n,) and r.map_yx.shape == (Y.n,)
    assert r.report["options"]["method"] == options["method"]
    if options["method"] == "completion":
        assert r.report["solver"]["iterations"] <= 3
        assert r.report["options"]["completion"]["form"] == options["form"]


def test_the_dense_low_rank_form_refuses_large_shapes(prepared_pair):
    X, Y = prepared_pair
    with pytest.raises(ValueError, match="invalid form: the convex low-rank form"):
        funcorr.match(X, Y, method="completion", form="low-rank", data="wks:30", kprime=40, k=10, refine="none")


def test_default_match_is_accurate_and_renders(default_match, ground_truth):
    gx, gy, gs = ground_truth
    ev = default_match.evaluate(gx, gy, gs)
    assert ev["mean"] < 0.03  # ×100 < 3: the README's demo quality
    img = default_match.render(320, 200)
    assert img.shape == (200, 320, 3) and img.dtype == np.uint8
    left, right = img[:, :160], img[:, 160:]
    # Both panels show a shape (non-white pixels), coloured alike through the map.
    for panel in (left, right):
        assert (panel.min(axis=2) < 250).mean() > 0.05
    img2 = funcorr.render_pair(X_PATH, Y_PATH, default_match.map_yx, 320, 200)
    assert np.array_equal(img, img2)
    one = funcorr.render(X_PATH, width=100, height=120, view=(90, 10))
    assert one.shape == (120, 100, 3)
    with pytest.raises(ValueError, match="elevation"):
        funcorr.render(X_PATH, view=(0, 120))


def test_point_clouds_and_feature_data(mesh_x, mesh_y, ground_truth):
    gx, gy, gs = ground_truth
    # X as a point cloud (the point-cloud Laplacian), Y as a mesh: the same pipeline.
    X = funcorr.prepare((mesh_x[0], None), k=60)
    assert X.faces.shape == (0, 3) and X.n == 4999
    Y = funcorr.prepare(mesh_y, k=60)
    r = funcorr.match(X, Y, method="fmap", data="wks:50", k=30, refine="zoomout", zoomout_to=60, zoomout_step=5)
    assert funcorr.evaluate(r.map_xy, Y, gx, gy, gs)["mean"] < 0.1
    # Abstract data (n × 5 features): the kNN graph Laplacian.
    rng = np.random.default_rng(0)
    P = funcorr.prepare(rng.normal(size=(300, 5)), k=10)
    assert P.vertices.shape == (300, 5) and abs(P.eigenvalues[0]) < 1e-8
    W, A = funcorr.knn_laplacian(P.vertices, k=10)
    assert (funcorr.stiffness(P) != W).nnz == 0
    Q = pickle.loads(pickle.dumps(P))
    assert np.array_equal(Q.eigenvectors, P.eigenvectors) and (funcorr.stiffness(Q) != W).nnz == 0
    with pytest.raises(ValueError, match="laplacian: X and Y are prepared already"):
        funcorr.match(X, Y, laplacian="knn")


def test_soft_map(prepared_pair):
    X, Y = prepared_pair
    r = funcorr.match(X, Y, method="fmap", data="wks:50", k=30, refine="none")
    t = funcorr.soft_map(X, Y, r.C, 100)
    assert t.shape == (Y.n,)
    # The soft map of vertex 100 peaks near the vertex the point map sends it to.
    d = funcorr.geodesic_distances(Y, int(r.map_xy[100]), method="dijkstra")
    assert d[np.argmax(t)] < 0.2 * d.max()
    with pytest.raises(ValueError, match="i: vertex 4999 of X does not exist"):
        funcorr.soft_map(X, Y, r.C, 4999)
