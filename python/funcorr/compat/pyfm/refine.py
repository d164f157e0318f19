"""``pyFM.refine`` on funcorr: ICP and ZoomOut of pyFM's functional maps FM_12 (k2 × k1).

The iterations are pyFM's (ICP: point map ``p2p_21`` from FM_12, FM_12 back from it, projected
on the nearest (rectangular) orthogonal matrix; ZoomOut: ``p2p_21`` from FM_12, then the map of
size (k1 + step, k2 + step)), built on funcorr's point-map search. funcorr's own ICP
(:func:`funcorr.icp_refine`) iterates in the other direction (map X → Y).
"""

from __future__ import annotations

import numpy as np

from . import spectral as _spectral
from ._common import warn_once

__all__ = [
    "icp_iteration",
    "icp_refine",
    "mesh_icp_refine",
    "mesh_icp_refine_p2p",
    "zoomout_iteration",
    "zoomout_refine",
    "mesh_zoomout_refine",
    "mesh_zoomout_refine_p2p",
]


def icp_iteration(FM_12, evects1, evects2, A2=None, use_adj: bool = False, n_jobs=None):
    """One ICP step: the orthogonal (k2 × k1) map nearest to the map of ``FM_to_p2p(FM_12)``."""
    k2, k1 = np.shape(FM_12)
    p2p_21 = _spectral.FM_to_p2p(FM_12, evects1, evects2, use_adj=use_adj)
    FM = _spectral.p2p_to_FM(p2p_21, evects1[:, :k1], evects2[:, :k2], A2=A2)
    U, _, VT = np.linalg.svd(FM)
    return U @ np.eye(k2, k1) @ VT


def icp_refine(FM_12, evects1, evects2, A2=None, nit=10, tol=1e-10, use_adj: bool = False, return_p2p: bool = False, n_jobs=None, verbose: bool = False):
    """``nit`` ICP steps (``nit`` None or 0: until FM_12 changes by at most ``tol``). Returns
    FM_12 (k2 × k1), and ``p2p_21`` with ``return_p2p``."""
    use_tol = nit is None or nit == 0
    current = np.asarray(FM_12, dtype=float).copy()
    refined = current
    for _ in range(10000 if use_tol else int(nit)):
        refined = icp_iteration(current, evects1, evects2, A2=A2, use_adj=use_adj)
        if use_tol and np.max(np.abs(current - refined)) <= tol:
            break
        current = refined
    if return_p2p:
        return refined, _spectral.FM_to_p2p(refined, evects1, evects2, use_adj=use_adj)
    return refined


def mesh_icp_refine(FM_12, mesh1, mesh2, nit=10, tol=1e-10, use_adj: bool = False, return_p2p: bool = False, n_jobs=None, verbose: bool = False):
    """:func:`icp_refine` with the meshes' eigenvectors and mesh2's vertex areas."""
    return icp_refine(FM_12, mesh1.eigenvectors, mesh2.eigenvectors, A2=mesh2.vertex_areas, nit=nit, tol=tol, use_adj=use_adj, return_p2p=return_p2p)


def mesh_icp_refine_p2p(p2p_21, mesh1, mesh2, k_init, nit=10, tol=1e-10, use_adj: bool = False, return_p2p: bool = False, n_jobs=None, verbose: bool = False):
    """:func:`mesh_icp_refine` from the map of a point map (``k_init`` = k or (k1, k2))."""
    FM = _spectral.mesh_p2p_to_FM(p2p_21, mesh1, mesh2, dims=k_init)
    return mesh_icp_refine(FM, mesh1, mesh2, nit=nit, tol=tol, use_adj=use_adj, return_p2p=return_p2p)


def _steps(step):
    if np.ndim(step) == 0:
        return int(step), int(step)
    return int(step[0]), int(step[1])


def zoomout_iteration(FM_12, evects1, evects2, step=1, A2=None, n_jobs=None):
    """One ZoomOut step: ``p2p_21`` of FM_12, then its (k2 + step) × (k1 + step) map."""
    k2, k1 = np.shape(FM_12)
    s1, s2 = _steps(step)
    p2p_21 = _spectral.FM_to_p2p(FM_12, evects1, evects2)
    return _spectral.p2p_to_FM(p2p_21, evects1[:, : k1 + s1], evects2[:, : k2 + s2], A2=A2)


def zoomout_refine(FM_12, evects1, evects2, nit=10, step=1, A2=None, subsample=None, return_p2p: bool = False, n_jobs=None, verbose: bool = False):
    """``nit`` ZoomOut steps of ``step`` (or (step1, step2)) from FM_12 (k2 × k1) to
    (k2 + nit·step2) × (k1 + nit·step1), on every vertex or on ``subsample`` = (sub1, sub2).
    Returns the map, and ``p2p_21`` with ``return_p2p``."""
    k2, k1 = np.shape(FM_12)
    s1, s2 = _steps(step)
    if k1 + nit * s1 > evects1.shape[1]:
        raise ValueError(f"Not enough eigenvectors on source: {k1 + nit * s1} are needed when {evects1.shape[1]} are provided")
    if k2 + nit * s2 > evects2.shape[1]:
        raise ValueError(f"Not enough eigenvectors on target: {k2 + nit * s2} are needed when {evects2.shape[1]} are provided")
    FM = np.asarray(FM_12, dtype=float).copy()
    for _ in range(int(nit)):
        if subsample is not None:
            sub1, sub2 = subsample
            FM = zoomout_iteration(FM, evects1[sub1], evects2[sub2], step=step, A2=None)
        else:
            FM = zoomout_iteration(FM, evects1, evects2, step=step, A2=A2)
    if return_p2p:
        return FM, _spectral.FM_to_p2p(FM, evects1, evects2)
    return FM


def mesh_zoomout_refine(FM_12, mesh1, mesh2, nit=10, step=1, subsample=None, return_p2p: bool = False, n_jobs=None, verbose: bool = False):
    """:func:`zoomout_refine` with the meshes' eigenvectors and mesh2's vertex areas;
    ``subsample`` an int (farthest-point samples of each mesh) or (sub1, sub2)."""
    if subsample is not None and np.ndim(subsample) == 0:
        warn_once("zoomout-subsample", "ZoomOut subsample: funcorr's farthest-point samples (geodesic, heat method) differ from pyFM's")
        subsample = (mesh1.farthest_point_sampling(int(subsample)), mesh2.farthest_point_sampling(int(subsample)))
    return zoomout_refine(FM_12, mesh1.eigenvectors, mesh2.eigenvectors, nit=nit, step=step, A2=mesh2.vertex_areas, subsample=subsample, return_p2p=return_p2p)


def mesh_zoomout_refine_p2p(p2p_21, mesh1, mesh2, k_init, nit=10, step=1, subsample=None, return_p2p: bool = False, n_jobs=None, verbose: bool = False):
    """:func:`mesh_zoomout_refine` from the map of a point map (``k_init`` = k or (k1, k2))."""
    FM = _spectral.mesh_p2p_to_FM(p2p_21, mesh1, mesh2, dims=k_init)
    return mesh_zoomout_refine(FM, mesh1, mesh2, nit=nit, step=step, subsample=subsample, return_p2p=return_p2p)
