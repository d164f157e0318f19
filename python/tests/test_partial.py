"""funcorr.match of a part of a shape to the whole: detected (or partial=True), the coverage of
Y in the result, partial=False matching as whole shapes, and partial=True for another method a
ValueError naming the keyword (`funcorr match --partial/--no-partial`); landmarks= on a part
(used by the partial path and pinned)."""
import numpy as np
import pytest

import funcorr

from conftest import X_PATH


def cut(V, F, direction, keep):
    """The faces of (V, F) with every vertex on the side d . (p - centroid) <= the `keep`
    quantile, their largest connected piece (as tests/partial.rs and make_partial.py): the part's
    vertices and faces, and for each of its vertices its vertex in V."""
    s = (V - V.mean(axis=0)) @ np.asarray(direction, dtype=float)
    limit = np.sort(s)[min(int(keep * len(V)), len(V) - 1)]
    F = F[(s[F] <= limit).all(axis=1)]
    # Connected pieces by union-find over the faces' edges.
    parent = np.arange(len(V))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b in np.concatenate([F[:, [0, 1]], F[:, [1, 2]]]):
        ra, rb = root(a), root(b)
        if ra != rb:
            parent[ra] = rb
    roots = np.array([root(i) for i in range(len(V))])
    used = np.unique(F)
    labels, counts = np.unique(roots[used], return_counts=True)
    big = labels[np.argmax(counts)]
    F = F[roots[F[:, 0]] == big]
    orig = np.unique(F)
    new = np.full(len(V), -1)
    new[orig] = np.arange(len(orig))
    return V[orig], new[F], orig


def edges_from_truth(V, Vp, Fp, map_xy, orig):
    """Distance from each vertex's image to its own vertex in V, in the part's mean edge lengths."""
    edges = np.concatenate([Fp[:, [0, 1]], Fp[:, [1, 2]], Fp[:, [2, 0]]])
    edge = np.linalg.norm(Vp[edges[:, 0]] - Vp[edges[:, 1]], axis=1).mean()
    return np.linalg.norm(V[map_xy] - V[orig], axis=1) / edge


def test_a_cut_copy_is_matched_to_its_whole_with_coverage():
    V, F = funcorr.read_mesh(X_PATH)
    Vp, Fp, orig = cut(V, F, [0.3, -0.9, 0.3], 0.7)
    assert 2000 < len(Vp) < 4500
    r = funcorr.match((Vp, Fp), (V, F))
    assert r.report["partial"]["partial"], r.report["partial"]
    # An open X may be a part: 200 eigenpairs per shape (the partial path reads them all).
    assert r.report["basis_size"] == 200
    assert r.map_xy.shape == (len(Vp),)
    # Every vertex near itself (tests/partial.rs measured a median of 1.0 mean edge lengths).
    d = edges_from_truth(V, Vp, Fp, r.map_xy, orig)
    assert np.median(d) <= 1.5 and np.percentile(d, 95) <= 4.0, (np.median(d), np.percentile(d, 95))
    # The coverage of Y against the part's vertices (0.934 in tests/partial.rs).
    assert r.coverage.shape == (len(V),)
    assert ((0 <= r.coverage) & (r.coverage <= 1)).all()
    truth = np.zeros(len(V), dtype=bool)
    truth[orig] = True
    covered = r.coverage >= 0.5
    iou = (covered & truth).sum() / (covered | truth).sum()
    assert iou >= 0.9, iou


def test_partial_false_matches_whole_shapes_and_other_methods_refuse_partial():
    V, F = funcorr.read_mesh(X_PATH)
    Vp, Fp, _ = cut(V, F, [0.3, -0.9, 0.3], 0.7)
    whole = funcorr.match((Vp, Fp), (V, F), partial=False)
    assert whole.coverage is None
    assert not whole.report["partial"]["partial"]
    # partial=False: X is matched whole, with the 128 eigenpairs per shape that path reads.
    assert whole.report["basis_size"] == 128
    with pytest.raises(ValueError, match="partial"):
        funcorr.match((Vp, Fp), (V, F), method="fmap", partial=True)


def test_landmarks_on_a_part_are_used_and_pinned():
    V, F = funcorr.read_mesh(X_PATH)
    Vp, Fp, orig = cut(V, F, [0.3, -0.9, 0.3], 0.7)
    idx = np.linspace(0, len(Vp) - 1, 5).astype(int)
    pairs = np.stack([idx, orig[idx]], axis=1)
    r = funcorr.match((Vp, Fp), (V, F), landmarks=pairs)
    assert r.report["partial"]["partial"], r.report["partial"]
    assert r.report["landmarks"] == 5
    assert (r.map_xy[idx] == orig[idx]).all()
    # The landmarks' own candidate is among the partial path's candidates.
    cands = r.report["candidates"]["candidates"]
    assert any(c.get("from_landmarks") for c in cands), cands
    d = edges_from_truth(V, Vp, Fp, r.map_xy, orig)
    assert np.median(d) <= 1.5, np.median(d)
