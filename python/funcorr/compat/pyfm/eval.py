"""``pyFM.eval``: accuracy, continuity and coverage of a point map ``p2p`` from mesh2 to mesh1
(pyFM's direction: ``p2p[i]`` is the vertex of mesh1 for vertex i of mesh2)."""

from __future__ import annotations

import numpy as np

__all__ = ["accuracy", "continuity", "coverage"]


def accuracy(p2p, gt_p2p, D1_geod, return_all: bool = False, sqrt_area=None):
    """Mean geodesic error D1_geod[p2p[i], gt_p2p[i]] on mesh1 (divided by ``sqrt_area`` when
    given); with ``return_all`` also every error ((n2,))."""
    dists = np.asarray(D1_geod)[np.asarray(p2p), np.asarray(gt_p2p)].astype(np.float64)
    if sqrt_area is not None:
        dists = dists / sqrt_area
    return (dists.mean(), dists) if return_all else dists.mean()


def continuity(p2p, D1_geod, D2_geod, edges) -> float:
    """Mean over the edges (i, j) of mesh2 of d₁(p2p[i], p2p[j]) / d₂(i, j): how much the map
    stretches edges (1 for an isometry)."""
    p2p, edges = np.asarray(p2p), np.asarray(edges)
    source = np.asarray(D2_geod)[edges[:, 0], edges[:, 1]]
    target = np.asarray(D1_geod)[p2p[edges[:, 0]], p2p[edges[:, 1]]]
    return float(np.mean(target / source))


def coverage(p2p, A) -> float:
    """Fraction of mesh1's area at the vertices the map reaches; ``A`` mesh1's area matrix
    (n1 × n1) or vertex areas (n1,)."""
    a = np.asarray(A.sum(1)).ravel() if np.ndim(A) == 2 else np.asarray(A, dtype=float).ravel()
    return float(a[np.unique(np.asarray(p2p))].sum() / a.sum())
