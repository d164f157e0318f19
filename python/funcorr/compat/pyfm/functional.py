"""``pyFM.functional`` on funcorr: :class:`FunctionalMapping` (pyFM 1.3's API and the older one).

Conventions are pyFM's: ``FM_12`` (k2 × k1) takes coefficients of functions on mesh1 to
coefficients on mesh2 (funcorr's ``C`` with X = mesh1, Y = mesh2, in the meshes' own units), and
``p2p_21 = model.get_p2p()`` gives for every vertex of mesh2 a vertex of mesh1 (funcorr's
``map_yx``).
"""

from __future__ import annotations

import copy as _copy
import warnings as _warnings
from typing import Optional

import numpy as np

import funcorr as _fc

from . import refine as _refine
from . import signatures as _sg
from . import spectral as _spectral
from ._common import warn_once
from .mesh import TriMesh

__all__ = ["FunctionalMapping"]

_OLD_WEIGHTS = {"descr_mu": "w_descr", "lap_mu": "w_lap", "descr_comm_mu": "w_dcomm", "orient_mu": "w_orient"}


class FunctionalMapping:
    """A functional map between ``mesh1`` and ``mesh2``.

    pyFM 1.3: ``preprocess(n_descr, descr_type, ...)``, ``fit(K=(k1, k2), ...)`` sets ``FM_12``,
    refinements return their map, ``get_p2p(FM)``. Before 1.3: ``preprocess(n_ev=(k1, k2),
    ...)``, ``fit(...)`` (also ``descr_mu=`` …), refinements kept and chosen by
    ``change_FM_type``, ``model.FM`` the current one, ``get_p2p()`` from it. A model that used
    the older API (``n_ev``, ``*_mu`` weights, ``FM``, ``change_FM_type``) follows its rules.
    """

    def __init__(self, mesh1: TriMesh, mesh2: TriMesh):
        # Shallow copies, as pyFM's deep ones behave: processing here does not touch the callers'
        # meshes (their arrays are replaced, never changed in place).
        self.mesh1 = _copy.copy(mesh1)
        self.mesh2 = _copy.copy(mesh2)
        self.descr1: Optional[np.ndarray] = None
        self.descr2: Optional[np.ndarray] = None
        self.FM_12: Optional[np.ndarray] = None
        self._k1 = self._k2 = None
        self._legacy = False
        self._FM_type = "classic"
        self._FM_icp = self._FM_zo = None

    # sizes and status -------------------------------------------------------------------------
    @property
    def k1(self):
        return self.FM_12.shape[1] if self.FM_12 is not None else self._k1

    @property
    def k2(self):
        return self.FM_12.shape[0] if self.FM_12 is not None else self._k2

    def _set_k(self, k):
        if np.ndim(k) == 0:
            self._k1 = self._k2 = int(k)
        else:
            self._k1, self._k2 = (int(k[0]), int(k[1]))
        self.FM_12 = None
        self._FM_icp = self._FM_zo = None

    @property
    def has_spectral(self) -> bool:
        return all(m.eigenvalues is not None and m.eigenvectors is not None for m in (self.mesh1, self.mesh2))

    @property
    def preprocessed(self) -> bool:
        return self.has_spectral and self.descr1 is not None

    @property
    def fitted(self) -> bool:
        return self.FM_12 is not None

    # the API before 1.3: FM_type --------------------------------------------------------------
    @property
    def FM_type(self) -> str:
        return self._FM_type

    @FM_type.setter
    def FM_type(self, t: str):
        if t.lower() not in ("classic", "icp", "zoomout"):
            raise ValueError(f"FM_type can only be 'classic', 'icp' or 'zoomout', not {t!r}")
        self._FM_type = t.lower()

    def change_FM_type(self, FM_type: str):
        """Chooses which map ``FM`` (and ``get_p2p()``) gives: "classic", "icp" or "zoomout"."""
        self._legacy = True
        self.FM_type = FM_type

    @property
    def FM(self) -> Optional[np.ndarray]:
        """The current map (k2 × k1) of ``FM_type`` (the fitted one, or its ICP / ZoomOut)."""
        self._legacy = True
        return self._current()

    @FM.setter
    def FM(self, FM):
        self.FM_12 = None if FM is None else np.asarray(FM, dtype=float)
        self._FM_type = "classic"

    def _current(self) -> Optional[np.ndarray]:
        return {"classic": self.FM_12, "icp": self._FM_icp, "zoomout": self._FM_zo}[self._FM_type]

    # point maps -------------------------------------------------------------------------------
    def get_p2p(self, FM=None, use_adj: bool = False, n_jobs=None) -> np.ndarray:
        """``p2p_21`` (n2,): for every vertex of mesh2 a vertex of mesh1, from ``FM`` (default:
        ``FM_12``; with the older API the current map of ``FM_type``), by the map (or with
        ``use_adj`` its adjoint) as pyFM's ``FM_to_p2p``."""
        if isinstance(FM, (bool, np.bool_)):  # before 1.3: get_p2p(use_adj)
            FM, use_adj = None, bool(FM)
        if FM is None:
            FM = self._current() if self._legacy else self.FM_12
            if FM is None:
                raise ValueError("No FM available — run fit() first or pass an FM.")
        return _spectral.mesh_FM_to_p2p(np.asarray(FM), self.mesh1, self.mesh2, use_adj=use_adj)

    @property
    def p2p_21(self) -> np.ndarray:
        return self.get_p2p()

    p2p = p2p_21

    def get_precise_map(self, FM=None, precompute_dmin=True, use_adj=True, batch_size=None, n_jobs=None, verbose=False):
        """pyFM's precise map is not in funcorr: the vertex map as a sparse (n2, n1) matrix,
        with a warning."""
        FM = self.FM_12 if FM is None else FM
        if FM is None:
            raise ValueError("No FM available — run fit() first or pass an FM.")
        return _spectral.mesh_FM_to_p2p_precise(FM, self.mesh1, self.mesh2, use_adj=use_adj)

    # descriptors ------------------------------------------------------------------------------
    def _parse_landmarks(self, landmarks):
        lm = np.asarray(landmarks).squeeze()
        if lm.ndim == 1:
            return lm, lm.copy()
        return lm[:, 0], lm[:, 1]

    def compute_spectral_descriptors(self, n_descr=100, descr_type="WKS", k_descr=128, landmarks=None, landmarks_only=False, subsample_step=1, normalization="l2", k_descr2=None):
        """Descriptors of both meshes with pyFM's recipe (:mod:`.signatures`): ``n_descr`` WKS
        or HKS from the first ``k_descr`` eigenpairs, plus the landmark versions at
        ``landmarks`` ((p,) or (p, 2)), every ``subsample_step``-th column kept, L²-normalized."""
        kd1 = k_descr
        kd2 = k_descr if k_descr2 is None else k_descr2
        if descr_type not in ("WKS", "HKS"):
            raise ValueError(f'descr_type must be "HKS", "WKS", or None, got "{descr_type}"')
        sig = _sg.mesh_WKS if descr_type == "WKS" else _sg.mesh_HKS
        use_lm = landmarks is not None and len(landmarks) > 0
        l1, l2 = self._parse_landmarks(landmarks) if use_lm else (None, None)
        d1, d2 = [np.empty((self.mesh1.n_vertices, 0))], [np.empty((self.mesh2.n_vertices, 0))]
        if not use_lm or not landmarks_only:
            d1.append(sig(self.mesh1, n_descr, k=kd1))
            d2.append(sig(self.mesh2, n_descr, k=kd2))
        if use_lm:
            d1.append(sig(self.mesh1, n_descr, landmarks=l1, k=kd1))
            d2.append(sig(self.mesh2, n_descr, landmarks=l2, k=kd2))
        descr1 = np.hstack(d1)[:, ::subsample_step]
        descr2 = np.hstack(d2)[:, ::subsample_step]
        if normalization == "l2":
            descr1 = descr1 / np.sqrt(self.mesh1.l2_sqnorm(descr1))[None, :]
            descr2 = descr2 / np.sqrt(self.mesh2.l2_sqnorm(descr2))[None, :]
        elif normalization not in (None, "none"):
            raise ValueError(f"Unknown normalization: {normalization}")
        self.descr1, self.descr2 = descr1, descr2
        return self

    def preprocess(self, n_ev=None, n_descr: int = 100, descr_type: Optional[str] = "WKS", landmarks=None, subsample_step: int = 1, k_process: Optional[int] = None, verbose: bool = False, k_descr: Optional[int] = None, landmarks_only: bool = False, K=None):
        """Spectra (``k_process`` = 200 eigenpairs, more if the sizes need them) and descriptors
        (:meth:`compute_spectral_descriptors`; ``descr_type=None``: none). pyFM 1.3:
        ``preprocess(n_descr, descr_type, ...)`` (descriptors from ``k_descr`` = 128
        eigenpairs). Before: ``preprocess(n_ev=(k1, k2), ...)`` (descriptors from k1 / k2
        eigenpairs; ``K=`` likewise). Returns self."""
        if isinstance(n_ev, (int, np.integer)) and not isinstance(n_ev, bool):
            n_descr, n_ev = int(n_ev), None  # pyFM 1.3: the first positional argument is n_descr
        if n_ev is None and K is not None:
            n_ev = K
        if n_ev is not None:
            self._legacy = True
            self._set_k(n_ev)
        if self._k1 is not None and k_descr is None:
            kd1, kd2 = self._k1, self._k2
        else:
            kd1 = kd2 = 128 if k_descr is None else int(k_descr)
        k_process = 200 if k_process is None else int(k_process)
        self.mesh1.process(max(k_process, kd1, self._k1 or 0), verbose=verbose)
        self.mesh2.process(max(k_process, kd2, self._k2 or 0), verbose=verbose)
        if descr_type is None:
            return self
        self.compute_spectral_descriptors(n_descr=n_descr, descr_type=descr_type, k_descr=kd1, k_descr2=kd2, landmarks=landmarks, landmarks_only=landmarks_only, subsample_step=subsample_step)
        if verbose:
            print(f"\n\t{self.descr1.shape[1]} descriptors kept")
        return self

    def add_descriptors(self, descr1, descr2, normalize: bool = True):
        """Appends descriptors (n1, p) and (n2, p) (L²-normalized unless ``normalize=False``)."""
        d1, d2 = np.asarray(descr1, dtype=float), np.asarray(descr2, dtype=float)
        if d1.ndim == 1:
            d1, d2 = d1[:, None], d2[:, None]
        if d1.shape[0] != self.mesh1.n_vertices or d2.shape[0] != self.mesh2.n_vertices:
            raise ValueError(f"descr1 / descr2 must have {self.mesh1.n_vertices} / {self.mesh2.n_vertices} rows, got {d1.shape[0]} / {d2.shape[0]}")
        if d1.shape[1] != d2.shape[1]:
            raise ValueError(f"descr1 and descr2 must have the same number of columns, got {d1.shape[1]} and {d2.shape[1]}")
        if normalize:
            d1 = d1 / np.sqrt(self.mesh1.l2_sqnorm(d1))[None, :]
            d2 = d2 / np.sqrt(self.mesh2.l2_sqnorm(d2))[None, :]
        self.descr1 = d1 if self.descr1 is None else np.hstack([self.descr1, d1])
        self.descr2 = d2 if self.descr2 is None else np.hstack([self.descr2, d2])
        return self

    # fit --------------------------------------------------------------------------------------
    def fit(self, K=None, w_descr: float = 1e-1, w_lap: float = 1e-3, w_dcomm: float = 1, w_orient: float = 0, orient_reversing: bool = False, use_resolvent_laplacian: Optional[bool] = None, resolvent_gamma: float = 0.5, optinit: str = "zeros", factr=1e7, pgtol=1e-5, normalize_weights: bool = True, verbose: bool = False, **old):
        """The functional map FM_12 (k2 × k1) minimizing descriptor preservation (``w_descr``),
        Laplacian commutativity (``w_lap``; the resolvent mask with
        ``use_resolvent_laplacian``, the default except with sizes from ``preprocess(n_ev=)``,
        where it is pyFM's earlier (λ₁ − λ₂)² mask), descriptor commutativity (``w_dcomm``) and
        orientation (``w_orient``, reversing with ``orient_reversing``), solved exactly by
        funcorr; the first column maps constants to constants. ``K`` = k or (k1, k2) (default:
        the sizes of ``preprocess(n_ev=)``, else (50, 50) as pyFM 1.3). The older keywords
        ``descr_mu``, ``lap_mu``, ``descr_comm_mu``, ``orient_mu`` name the same weights. Sets
        ``FM_12``; returns self."""
        for key, value in old.items():
            if key not in _OLD_WEIGHTS:
                raise TypeError(f"fit() got an unexpected keyword argument {key!r}")
            self._legacy = True
            if _OLD_WEIGHTS[key] == "w_descr":
                w_descr = value
            elif _OLD_WEIGHTS[key] == "w_lap":
                w_lap = value
            elif _OLD_WEIGHTS[key] == "w_dcomm":
                w_dcomm = value
            else:
                w_orient = value
        if optinit not in ("random", "identity", "zeros"):
            raise ValueError(f'optinit must be "zeros", "identity" or "random", got "{optinit}"')
        if resolvent_gamma != 0.5:
            raise ValueError("resolvent_gamma: funcorr's resolvent mask has γ = 0.5")
        if not normalize_weights:
            warn_once("normalize_weights", "fit(normalize_weights=False): pyFM's legacy weight scaling is not reproduced; funcorr's terms are scale-free")
        if w_descr + w_lap + w_dcomm + w_orient <= 0:
            raise ValueError("At least one of the weights must be positive")
        warn_once(
            "fit-solver",
            "fit: funcorr minimizes the same four terms exactly (no L-BFGS: optinit, factr, pgtol unused), each "
            "term scale-free, so the weights are comparable to pyFM's, not identical",
        )
        if K is not None:
            self._set_k(K)
            resolvent_default = True
        elif self._k1 is not None:
            resolvent_default = not self._legacy
        else:
            self._set_k((50, 50))
            resolvent_default = True
        if use_resolvent_laplacian is None:
            use_resolvent_laplacian = resolvent_default
        k1, k2 = self._k1, self._k2
        if not self.has_spectral:
            self.preprocess(verbose=verbose)
        if self.descr1 is None:
            raise ValueError("No descriptors set — call add_descriptors() or preprocess() with a descr_type before fitting.")
        for name, k, mesh in (("k1", k1, self.mesh1), ("k2", k2, self.mesh2)):
            if k > len(mesh.eigenvalues):
                raise ValueError(f"Requested {name}={k} exceeds the {len(mesh.eigenvalues)} eigenvalues computed on mesh{name[1]}. Call preprocess() with a larger k_process.")
        P1, P2 = self.mesh1._prepared_shape(k1), self.mesh2._prepared_shape(k2)
        C, energy = _fc.axiomatic_fmap(
            P1,
            P2,
            self.descr1,
            self.descr2,
            (k1, k2),
            w_descr=w_descr,
            w_lap=w_lap,
            w_dcomm=w_dcomm,
            w_orient=w_orient,
            mask="resolvent" if use_resolvent_laplacian else "standard",
            orientation="reverse" if orient_reversing else "preserve",
        )
        self.FM_12 = C
        self._FM_icp = self._FM_zo = None
        self._FM_type = "classic"
        if verbose:
            print(f"\tFitted a {C.shape[0]}×{C.shape[1]} map, energy {energy:.3e}")
        return self

    # refinement -------------------------------------------------------------------------------
    def _map_arg(self, FM, what):
        if FM is None:
            FM = self._current() if self._legacy else self.FM_12
            if FM is None:
                raise ValueError(f"No FM available — run fit() first or pass an FM to {what}.")
        return np.asarray(FM, dtype=float)

    def icp_refine(self, FM=None, nit: int = 10, tol: float = 1e-10, use_adj: bool = False, n_jobs=None, verbose: bool = False, overwrite: bool = True):
        """pyFM's ICP (:func:`.refine.mesh_icp_refine`) of ``FM`` (default: FM_12, or the current
        map with the older API): ``nit`` steps (0 or None: until it changes by ≤ ``tol``).
        Returns the map (k2 × k1); with the older API it becomes the current one (``overwrite``)."""
        if FM is not None and np.ndim(FM) == 0:  # before 1.3: icp_refine(nit, ...)
            FM, nit = None, int(FM)
        FM = self._map_arg(FM, "icp_refine")
        self._FM_icp = _refine.mesh_icp_refine(FM, self.mesh1, self.mesh2, nit=nit, tol=tol, use_adj=use_adj)
        if overwrite and self._legacy:
            self._FM_type = "icp"
        return self._FM_icp

    def zoomout_refine(self, FM=None, nit: int = 10, step=1, subsample=None, verbose: bool = False, overwrite: bool = True, use_ANN: bool = False):
        """ZoomOut (:func:`.refine.mesh_zoomout_refine`) of ``FM`` (default as
        :meth:`icp_refine`): ``nit`` steps of ``step``, to (k2 + nit·step) × (k1 + nit·step), on
        every vertex or on ``subsample`` farthest-point samples. Returns the map; with the older
        API it becomes the current one."""
        if FM is not None and np.ndim(FM) == 0:  # before 1.3: zoomout_refine(nit, step, ...)
            FM, nit, step = None, int(FM), (nit if nit != 10 else step)
        FM = self._map_arg(FM, "zoomout_refine")
        k2, k1 = FM.shape
        s = step if np.ndim(step) else (step, step)
        for mesh, need in ((self.mesh1, k1 + nit * s[0]), (self.mesh2, k2 + nit * s[1])):
            if len(mesh.eigenvalues) < need:
                warn_once("zoomout-process", "zoomout_refine: more eigenpairs computed on the fly (pyFM raises)")
                mesh.process(need)
        self._FM_zo = _refine.mesh_zoomout_refine(FM, self.mesh1, self.mesh2, nit=nit, step=step, subsample=subsample)
        if overwrite and self._legacy:
            self._FM_type = "zoomout"
        return self._FM_zo

    # functions --------------------------------------------------------------------------------
    def compute_SD(self):
        """Area and conformal shape differences of FM_12 (``SD_a``, ``SD_c``)."""
        if not self.fitted:
            raise ValueError("Fit the model before computing shape difference operators.")
        self.SD_a = _spectral.area_SD(self.FM_12)
        self.SD_c = _spectral.conformal_SD(self.FM_12, self.mesh1.eigenvalues, self.mesh2.eigenvalues)

    def project(self, func, k=None, mesh_ind: int = 1):
        _deprecated("project", "model.mesh1.project() or model.mesh2.project()")
        if mesh_ind == 1:
            return self.mesh1.project(func, k=k if k is not None else self.k1)
        return self.mesh2.project(func, k=k if k is not None else self.k2)

    def decode(self, coeffs, mesh_ind: int = 2):
        _deprecated("decode", "model.mesh1.unproject() or model.mesh2.unproject()")
        return (self.mesh1 if mesh_ind == 1 else self.mesh2).unproject(coeffs)

    def transport(self, coeffs, reverse: bool = False):
        _deprecated("transport", "FM_12 @ coefficients")
        FM = self._map_arg(None, "transport")
        c = np.asarray(coeffs)
        return FM.T @ c if reverse else FM @ c

    def transfer(self, func, reverse: bool = False):
        """A function (n1,) or (n1, p) on mesh1 carried to mesh2 by the map (with ``reverse``,
        from mesh2 to mesh1 by its transpose)."""
        FM = self._map_arg(None, "transfer")
        k2, k1 = FM.shape
        if not reverse:
            return self.mesh2.unproject(FM @ self.mesh1.project(func, k=k1))
        return self.mesh1.unproject(FM.T @ self.mesh2.project(func, k=k2))


def _deprecated(name, instead):
    _warnings.warn(f"`{name}()` is deprecated, use {instead} instead.", DeprecationWarning, stacklevel=3)
