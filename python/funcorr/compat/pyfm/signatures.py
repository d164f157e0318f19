"""``pyFM.signatures`` on funcorr: heat and wave kernel signatures with pyFM's parameters.

HKS and heat kernel maps are funcorr's (:func:`funcorr.hks`, :func:`funcorr.hkm` with the given
times); the WKS with given energies and σ is the wave kernel formula of Aubry et al. with
pyFM's choices (constant eigenpairs left out, σ = 7 (e_max − e_min) / num_E, ±2σ margins), which
differ from funcorr's own :func:`funcorr.wks` (σ factor 6, scale-normalized by the area).
Outputs are (n, num) arrays (landmark versions: (n, p · num), landmark-major).
"""

from __future__ import annotations

import numpy as np

import funcorr as _fc

__all__ = ["HKS", "lm_HKS", "auto_HKS", "mesh_HKS", "WKS", "lm_WKS", "auto_WKS", "mesh_WKS"]


def _basis(evals, evects):
    evects = np.asarray(evects, dtype=float)
    n = evects.shape[0]
    # Unit total weight: funcorr's scale normalization |A| / Σ e^{−λt} is then pyFM's 1 / Σ e^{−λt}.
    return (np.abs(np.asarray(evals, dtype=float)).ravel(), evects, np.full(n, 1.0 / n))


def HKS(evals, evects, time_list, scaled: bool = False) -> np.ndarray:
    """Σ_k e^{−λ_k t} φ_k(x)² for each t of ``time_list``: (n, T); divided by Σ_k e^{−λ_k t}
    with ``scaled``."""
    return _fc.hks(_basis(evals, evects), times=np.atleast_1d(np.asarray(time_list, dtype=float)), normalize=scaled)


def lm_HKS(evals, evects, landmarks, time_list, scaled: bool = False) -> np.ndarray:
    """Heat kernel maps Σ_k e^{−λ_k t} φ_k(l) φ_k(x) at the landmarks l: (n, p · T)."""
    seeds = np.atleast_1d(np.asarray(landmarks, dtype=np.int64))
    return _fc.hkm(_basis(evals, evects), seeds, times=np.atleast_1d(np.asarray(time_list, dtype=float)), normalize=scaled)


def _times(evals, num_T):
    abs_ev = np.sort(np.abs(np.asarray(evals, dtype=float)))
    return np.geomspace(4 * np.log(10) / abs_ev[-1], 4 * np.log(10) / abs_ev[1], num_T)


def auto_HKS(evals, evects, num_T, landmarks=None, scaled: bool = True) -> np.ndarray:
    """HKS (or heat kernel maps at ``landmarks``) at ``num_T`` times log-spaced in
    [4 ln 10 / λ_max, 4 ln 10 / λ_1]."""
    t = _times(evals, num_T)
    if landmarks is None:
        return HKS(evals, evects, t, scaled=scaled)
    return lm_HKS(evals, evects, landmarks, t, scaled=scaled)


def mesh_HKS(mesh, num_T, landmarks=None, k=None) -> np.ndarray:
    """:func:`auto_HKS` of a processed TriMesh's first k eigenpairs (all by default), scaled."""
    evals, evects = _mesh_basis(mesh, k)
    return auto_HKS(evals, evects, num_T, landmarks=landmarks, scaled=True)


def _nonconstant(evals, evects):
    evals = np.asarray(evals, dtype=float).ravel()
    keep = evals > 1e-8 * evals.max()
    return evals[keep], np.asarray(evects, dtype=float)[:, keep]


def _wks_coefficients(evals, energy_list, sigma):
    if not sigma > 0:
        raise ValueError(f"sigma: should be positive, got {sigma}")
    e = np.atleast_1d(np.asarray(energy_list, dtype=float))
    return np.exp(-((e[:, None] - np.log(np.abs(evals))[None, :]) ** 2) / (2 * sigma**2))  # (E, K)


def WKS(evals, evects, energy_list, sigma, scaled: bool = False) -> np.ndarray:
    """Σ_k g_e(λ_k) φ_k(x)², g_e(λ) = exp(−(e − ln λ)² / 2σ²), for each energy e: (n, E); divided
    by Σ_k g_e(λ_k) with ``scaled``. Constant eigenpairs are left out."""
    evals, evects = _nonconstant(evals, evects)
    g = _wks_coefficients(evals, energy_list, sigma)
    out = (evects**2) @ g.T
    return out / g.sum(1)[None, :] if scaled else out


def lm_WKS(evals, evects, landmarks, energy_list, sigma, scaled: bool = False) -> np.ndarray:
    """Wave kernel maps Σ_k g_e(λ_k) φ_k(l) φ_k(x) at the landmarks l: (n, p · E),
    landmark-major."""
    evals, evects = _nonconstant(evals, evects)
    g = _wks_coefficients(evals, energy_list, sigma)
    lm = np.atleast_1d(np.asarray(landmarks, dtype=np.int64))
    if scaled:
        g = g / g.sum(1)[:, None]
    cols = [evects @ (g[j] * evects[l]) for l in lm for j in range(g.shape[0])]
    return np.stack(cols, axis=1)


def auto_WKS(evals, evects, num_E, landmarks=None, scaled: bool = True) -> np.ndarray:
    """WKS (or wave kernel maps at ``landmarks``) at ``num_E`` energies, pyFM's rule: e in
    [ln λ_1 + 2σ, ln λ_max − 2σ], σ = 7 (ln λ_max − ln λ_1) / num_E."""
    abs_ev = np.sort(np.abs(np.asarray(evals, dtype=float)))
    order = np.argsort(np.abs(np.asarray(evals, dtype=float)))
    evects = np.asarray(evects, dtype=float)[:, order]
    e_min, e_max = np.log(abs_ev[1]), np.log(abs_ev[-1])
    sigma = 7 * (e_max - e_min) / num_E
    energies = np.linspace(e_min + 2 * sigma, e_max - 2 * sigma, num_E)
    if landmarks is None:
        return WKS(abs_ev, evects, energies, sigma, scaled=scaled)
    return lm_WKS(abs_ev, evects, landmarks, energies, sigma, scaled=scaled)


def mesh_WKS(mesh, num_E, landmarks=None, k=None) -> np.ndarray:
    """:func:`auto_WKS` of a processed TriMesh's first k eigenpairs (all by default), scaled."""
    evals, evects = _mesh_basis(mesh, k)
    return auto_WKS(evals, evects, num_E, landmarks=landmarks, scaled=True)


def _mesh_basis(mesh, k):
    if mesh.eigenvalues is None:
        raise ValueError("Eigenvalues should be processed: call mesh.process() first")
    if k is None:
        k = len(mesh.eigenvalues)
    elif len(mesh.eigenvalues) < k:
        raise ValueError(f"At least {k} eigenvalues should be computed, not {len(mesh.eigenvalues)}")
    return mesh.eigenvalues[:k], mesh.eigenvectors[:, :k]
