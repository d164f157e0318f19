"""pyFM's quickstart (examples/mesh_and_matching/basic_functions.ipynb of RobinMagnet/pyFM) with
only the import changed: the bundled FAUST pair instead of cat/lion, landmarks from the bundled
ground truth, the meshplot cells left out, and the evaluation on the ground-truth template
points (the bundled pair has no dense ground-truth map)."""
import numpy as np
import pytest

from conftest import DATA, X_PATH, Y_PATH


def test_pyfm_quickstart_runs_with_the_import_changed(tmp_path):
    # ---- the only changed lines: the imports ----
    from funcorr.compat.pyfm import FunctionalMapping, TriMesh
    import funcorr.compat.pyfm as pyFM

    # data of the bundled pair (pyFM's example: ../data/cat-00.off, ../data/lion-00.off, landmarks.txt)
    gx, gy = np.loadtxt(DATA / "tr_reg_000.vts", dtype=int) - 1, np.loadtxt(DATA / "tr_reg_001.vts", dtype=int) - 1
    np.savetxt(tmp_path / "landmarks.txt", np.stack([gx, gy], axis=1)[::700], fmt="%d")
    path1, path2, lmk_path = str(X_PATH), str(Y_PATH), str(tmp_path / "landmarks.txt")

    # ---- pyFM's quickstart from here on ----
    mesh1 = TriMesh(path1, area_normalize=True, center=False)
    mesh2 = TriMesh(mesh1.vertlist, mesh1.facelist)

    edges = mesh1.edges
    area = mesh1.area
    face_areas = mesh1.face_areas
    vertex_areas = mesh1.vertex_areas
    face_normals = mesh1.normals

    # AREA WEIGHTED VERTEX NORMALS
    vertex_normals_a = mesh1.vertex_normals

    # UNIFORM WEIGHTED VERTEX NORMALS
    mesh1.set_vertex_normal_weighting("uniform")
    vertex_normals_u = mesh1.vertex_normals

    dists = mesh1.geod_from(1000, robust=True)
    S1_geod = mesh1.get_geodesic(verbose=True)
    mesh1.process(k=100, intrinsic=False, verbose=True)

    mesh1 = TriMesh(path1)
    mesh2 = TriMesh(path2)
    print(f"Mesh 1 : {mesh1.n_vertices:4d} vertices, {mesh1.n_faces:5d} faces\n"
          f"Mesh 2 : {mesh2.n_vertices:4d} vertices, {mesh2.n_faces:5d} faces")

    process_params = {
        "n_ev": (35, 35),  # Number of eigenvalues on source and Target
        "landmarks": np.loadtxt(lmk_path, dtype=int)[:5],  # loading 5 landmarks
        "subsample_step": 5,  # In order not to use too many descriptors
        "descr_type": "WKS",  # WKS or HKS
    }
    model = FunctionalMapping(mesh1, mesh2)
    model.preprocess(**process_params, verbose=True)

    fit_params = {"w_descr": 1e0, "w_lap": 1e-2, "w_dcomm": 1e-1, "w_orient": 0}
    model.fit(**fit_params, verbose=True)

    p2p_21 = model.get_p2p(n_jobs=1)

    model.icp_refine(verbose=True)
    p2p_21_icp = model.get_p2p()

    model.change_FM_type("classic")  # We refine the first computed map, not the icp-refined one
    model.zoomout_refine(nit=15, step=1, verbose=True)
    print(model.FM.shape)
    p2p_21_zo = model.get_p2p()

    # Compute geodesic distance matrix on the cat mesh
    A_geod = mesh1.get_geodesic(verbose=True)
    # ---- end of the quickstart but for its last cell: evaluation on the template points below ----

    # What the quickstart's lines must have given.
    assert (mesh1.n_vertices, mesh1.n_faces, mesh2.n_vertices) == (4999, 9994, 5000)
    assert edges.shape[1] == 2 and face_areas.shape == (9994,) and vertex_areas.shape == (4999,)
    assert np.isclose(area, 1.0)  # area_normalize
    assert np.allclose(np.linalg.norm(face_normals, axis=1), 1) and np.allclose(np.linalg.norm(vertex_normals_a, axis=1), 1)
    assert dists.shape == (4999,) and dists[1000] == 0
    assert not np.allclose(vertex_normals_u, vertex_normals_a) and np.allclose(np.linalg.norm(vertex_normals_u, axis=1), 1)
    assert S1_geod.shape == (4999, 4999) and np.allclose(S1_geod[1000], dists, rtol=0.1, atol=0.02)
    assert model.descr1.shape[1] == model.descr2.shape[1] == 6 * 100 // 5
    assert model.FM is not None and model.FM.shape == (50, 50) and model.FM_type == "zoomout"
    model.change_FM_type("classic")
    assert model.FM.shape == (35, 35) and np.array_equal(model.p2p_21, p2p_21)
    for p in (p2p_21, p2p_21_icp, p2p_21_zo):
        assert p.shape == (5000,) and p.min() >= 0 and p.max() < 4999

    # pyFM.eval.accuracy on the template points: p2p maps mesh2 → mesh1, distances on mesh1.
    _, first = np.unique(gy, return_index=True)
    ty, tx = gy[first], gx[first]
    acc = {name: pyFM.eval.accuracy(p[ty], tx, A_geod, sqrt_area=mesh1.sqrtarea) for name, p in
           [("fit", p2p_21), ("icp", p2p_21_icp), ("zoomout", p2p_21_zo)]}
    print(acc)
    # Refinement helps, and ZoomOut ends near the README's quality (errors ×100, not ×1000).
    assert acc["zoomout"] < acc["fit"] and acc["zoomout"] < 0.06


def test_compat_conventions_agree_with_funcorr():
    import funcorr
    from funcorr.compat.pyfm import FunctionalMapping, TriMesh

    mesh1, mesh2 = TriMesh(str(X_PATH)), TriMesh(str(Y_PATH))
    model = FunctionalMapping(mesh1, mesh2)
    model.preprocess(n_ev=(30, 30), n_descr=50, subsample_step=2)
    model.fit(w_descr=1, w_lap=1e-2, w_dcomm=1e-1)
    # FM maps mesh1 → mesh2 (funcorr's C with X = mesh1, in the meshes' units: C[0, 0] is
    # ±√(area2 / area1)), p2p_21 is funcorr's map_yx. pyFM's search reads FM between the meshes'
    # own bases, funcorr's between unit-area ones: the same on meshes of equal area (pyFM's
    # area_normalize), up to ties.
    X, Y = model.mesh1._prepared, model.mesh2._prepared
    assert np.isclose(abs(model.FM[0, 0]), np.sqrt(mesh2.area / mesh1.area), rtol=1e-6)
    same = FunctionalMapping(TriMesh(str(X_PATH), area_normalize=True), TriMesh(str(Y_PATH), area_normalize=True))
    same.preprocess(n_ev=(30, 30), n_descr=50, subsample_step=2).fit(w_descr=1, w_lap=1e-2, w_dcomm=1e-1)
    map_xy, map_yx = funcorr.maps_from_fmap(same.mesh1._prepared, same.mesh2._prepared, same.FM)
    assert np.mean(same.p2p_21 == map_yx) > 0.999 and len(map_xy) == 4999
    # Non-square maps (pyFM's n_ev=(k1, k2)): FM_12 is k2 × k1.
    rect = FunctionalMapping(TriMesh(str(X_PATH)), TriMesh(str(Y_PATH))).preprocess(n_ev=(20, 30), n_descr=50)
    assert rect.fit().FM.shape == (30, 20)
    with pytest.raises(ValueError, match="optinit"):
        model.fit(optinit="ones")


def test_pyfm_13_workflow():
    """The workflow of pyFM 1.3 (FunctionalMapping's docstring in pyfmaps 1.3.1): the size given
    to fit(K=...), FM_12, refinements returned and FM_12 kept, get_p2p(FM)."""
    from funcorr.compat.pyfm import FunctionalMapping, TriMesh

    mesh1 = TriMesh.load(str(X_PATH), area_normalize=True, center=True)
    mesh2 = TriMesh.load(str(Y_PATH), area_normalize=True, center=True)
    model = FunctionalMapping(mesh1, mesh2)
    model.preprocess(descr_type="WKS")
    model.fit(K=(40, 40), w_descr=1e0, w_lap=1e-1, w_dcomm=1e0, w_orient=0)

    p2p = model.get_p2p()
    FM_icp = model.icp_refine()
    p2p_icp = model.get_p2p(FM_icp)
    FM_zo = model.zoomout_refine(model.FM_12, nit=10, step=5)
    p2p_zo = model.get_p2p(FM_zo)

    assert model.FM_12.shape == (40, 40) and FM_icp.shape == (40, 40) and FM_zo.shape == (90, 90)
    assert model.descr1.shape[1] == 100
    for p in (p2p, p2p_icp, p2p_zo):
        assert p.shape == (5000,) and p.max() < 4999
    assert not np.array_equal(p2p, p2p_zo)
    # pyFM 1.3: get_p2p() reads FM_12, whatever was refined.
    assert np.array_equal(model.get_p2p(), p2p)
    # The earlier API in the same model: refinements become the current map (FM_type),
    # positional zoomout_refine(nit, step).
    model.change_FM_type("classic")
    assert model.zoomout_refine(4, 5).shape == (60, 60) and model.FM_type == "zoomout"
    assert model.FM.shape == (60, 60)
