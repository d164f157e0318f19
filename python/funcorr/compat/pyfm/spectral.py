"""``pyFM.spectral`` on funcorr: conversions between functional maps and point maps.

pyFM's conventions: ``FM_12`` (k2 × k1) takes coefficients on mesh1 to coefficients on mesh2;
``p2p_21`` (n2,) gives for every vertex of mesh2 a vertex of mesh1. The nearest-neighbour search
is funcorr's (:func:`funcorr.nearest_rows`).
"""

from __future__ import annotations

import numpy as np

import funcorr as _fc

from ._common import warn_once

__all__ = [
    "p2p_to_FM",
    "mesh_p2p_to_FM",
    "FM_to_p2p",
    "mesh_FM_to_p2p",
    "mesh_FM_to_p2p_precise",
    "knn_query",
    "area_SD",
    "conformal_SD",
    "compute_SD",
]


def knn_query(X, Y, k: int = 1, return_distance: bool = False, n_jobs=None):
    """For every row of Y the nearest row of X ((len(Y),) indices; ``k`` = 1 only)."""
    if k != 1:
        raise ValueError("knn_query: funcorr's search gives the nearest row only (k=1)")
    X, Y = np.asarray(X, dtype=float), np.asarray(Y, dtype=float)
    if X.ndim == 1:
        X, Y = X[:, None], Y[:, None]
    idx = _fc.nearest_rows(X, Y)
    if return_distance:
        return np.linalg.norm(Y - X[idx], axis=1), idx
    return idx


def p2p_to_FM(p2p_21, evects1, evects2, A2=None):
    """The functional map FM_12 (k2 × k1) of a point map ``p2p_21`` (n2,) (or a sparse (n2, n1)
    matrix): Ψᵀ A2 Φ[p2p_21] with the area A2 ((n2,) or (n2, n2)), else by least squares."""
    evects1, evects2 = np.asarray(evects1), np.asarray(evects2)
    pb = evects1[np.asarray(p2p_21)] if np.ndim(p2p_21) == 1 else p2p_21 @ evects1
    if A2 is not None:
        if A2.shape[0] != evects2.shape[0]:
            raise ValueError("Can't compute exact pseudo inverse with subsampled eigenvectors")
        if np.ndim(A2) == 1:
            return evects2.T @ (np.asarray(A2)[:, None] * pb)
        return evects2.T @ (A2 @ pb)
    return np.linalg.lstsq(evects2, pb, rcond=None)[0]


def _dims(dims, mesh1, mesh2):
    if dims is None:
        return len(mesh1.eigenvalues), len(mesh2.eigenvalues)
    if np.ndim(dims) == 0:
        return int(dims), int(dims)
    return int(dims[0]), int(dims[1])


def mesh_p2p_to_FM(p2p_21, mesh1, mesh2, dims=None, subsample=None):
    """FM_12 of ``p2p_21`` with ``dims`` = k or (k1, k2) eigenvectors (default: all), on
    ``subsample`` = (sub1, sub2) vertices (least squares) if given."""
    k1, k2 = _dims(dims, mesh1, mesh2)
    if subsample is None:
        return p2p_to_FM(p2p_21, mesh1.eigenvectors[:, :k1], mesh2.eigenvectors[:, :k2], A2=mesh2.vertex_areas)
    sub1, sub2 = subsample
    return p2p_to_FM(p2p_21, mesh1.eigenvectors[sub1, :k1], mesh2.eigenvectors[sub2, :k2], A2=None)


def FM_to_p2p(FM_12, evects1, evects2, use_adj: bool = False, n_jobs=None):
    """``p2p_21`` (n2,) of FM_12 (k2 × k1): every row of Ψ_k2 matched to the nearest row of
    Φ_k1 FM_12ᵀ, or with ``use_adj`` every row of Ψ_k2 FM_12 to the nearest row of Φ_k1."""
    FM_12 = np.asarray(FM_12)
    k2, k1 = FM_12.shape
    if k1 > evects1.shape[1]:
        raise ValueError(f"At least {k1} eigenvectors should be provided on the source, here only {evects1.shape[1]} are given")
    if k2 > evects2.shape[1]:
        raise ValueError(f"At least {k2} eigenvectors should be provided on the target, here only {evects2.shape[1]} are given")
    if use_adj:
        return _fc.nearest_rows(evects1[:, :k1], evects2[:, :k2] @ FM_12)
    return _fc.nearest_rows(evects1[:, :k1] @ FM_12.T, evects2[:, :k2])


def mesh_FM_to_p2p(FM_12, mesh1, mesh2, use_adj: bool = False, subsample=None, n_jobs=None):
    """:func:`FM_to_p2p` with the meshes' eigenvectors (on ``subsample`` = (sub1, sub2))."""
    k2, k1 = np.shape(FM_12)
    if subsample is None:
        return FM_to_p2p(FM_12, mesh1.eigenvectors[:, :k1], mesh2.eigenvectors[:, :k2], use_adj=use_adj)
    sub1, sub2 = subsample
    return FM_to_p2p(FM_12, mesh1.eigenvectors[sub1, :k1], mesh2.eigenvectors[sub2, :k2], use_adj=use_adj)


def mesh_FM_to_p2p_precise(FM_12, mesh1, mesh2, precompute_dmin=True, use_adj=True, batch_size=None, n_jobs=None, verbose=False):
    """pyFM's precise (barycentric) map is not in funcorr: the vertex-to-vertex map of
    :func:`mesh_FM_to_p2p` as a sparse (n2, n1) matrix, with a warning."""
    import scipy.sparse as sp

    warn_once("precise-map", "the precise (barycentric) map of Ezuz & Ben-Chen is not in funcorr: a vertex-to-vertex map instead")
    p2p = mesh_FM_to_p2p(FM_12, mesh1, mesh2, use_adj=use_adj)
    n2, n1 = mesh2.n_vertices, mesh1.n_vertices
    return sp.csr_matrix((np.ones(n2), (np.arange(n2), p2p)), shape=(n2, n1))


def area_SD(FM):
    """The area-based shape difference FMᵀ FM (k1 × k1)."""
    FM = np.asarray(FM)
    return FM.T @ FM


def conformal_SD(FM, evals1, evals2):
    """The conformal shape difference pinv(Λ1) FMᵀ Λ2 FM (k1 × k1)."""
    FM = np.asarray(FM)
    k2, k1 = FM.shape
    return np.linalg.pinv(np.diag(evals1[:k1])) @ FM.T @ (evals2[:k2, None] * FM)


def compute_SD(mesh1, mesh2, k1=None, k2=None, p2p=None, SD_type="spectral"):
    """Area and conformal shape differences of the map ``p2p`` (mesh2 → mesh1): (SD_a, SD_c)."""
    k1 = len(mesh1.eigenvalues) if k1 is None else k1
    k2 = len(mesh2.eigenvalues) if k2 is None else k2
    if p2p is None:
        raise ValueError("compute_SD needs the point map p2p (mesh2 → mesh1)")
    FM = mesh_p2p_to_FM(p2p, mesh1, mesh2, dims=(k1, k2))
    return area_SD(FM), conformal_SD(FM, mesh1.eigenvalues, mesh2.eigenvalues)
