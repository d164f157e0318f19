"""pyFM's ``TriMesh`` and ``FunctionalMapping`` on funcorr: change the import, keep the script.

::

    from funcorr.compat.pyfm import TriMesh, FunctionalMapping   # was: from pyFM.mesh import TriMesh
                                                                  #      from pyFM.functional import FunctionalMapping
    import funcorr.compat.pyfm as pyFM                            # pyFM.eval.accuracy(...)
    from funcorr.compat.pyfm.viz import plot_mesh, double_plot    # was: from pyFM.viz import plot_mesh

Both pyFM APIs run: the one before 1.3 (``preprocess(n_ev=(k1, k2))``, ``fit()``,
refinements stored and chosen by ``change_FM_type``) and 1.3's (``TriMesh.load``,
``fit(K=...)``, ``FM_12``, refinements returned, ``get_p2p(FM)``); one difference: after a
refinement, ``get_p2p()`` without an argument uses the refined map (the earlier API's
``FM_type`` rule), where pyFM 1.3 would use ``FM_12``.

Conventions are pyFM's: ``FM`` (k2 × k1) maps functions on mesh1 to mesh2 (funcorr's ``C`` with
X = mesh1, Y = mesh2), and ``p2p_21 = model.get_p2p()`` gives for each vertex of mesh2 a vertex
of mesh1 (funcorr's ``map_yx``).

What is computed by funcorr, and where it differs from pyFM:

* ``TriMesh.process(k)``: funcorr's cotangent Laplacian (barycentric mass, intrinsic
  mollification of degenerate triangles) and its eigenbasis; ``intrinsic=True`` /
  ``robust=True`` select funcorr's point-cloud Laplacian only for meshes without faces (funcorr
  has no intrinsic-Delaunay Laplacian; its cotangent Laplacian is used).
* Descriptors: funcorr's WKS / HKS (scale-normalized), subsampled and L²-normalized as pyFM
  does; landmark descriptors are heat kernel maps at the landmarks for both descriptor types.
* ``fit``: the same four terms (descriptor preservation, Laplacian commutativity with pyFM's
  (λ₁ − λ₂)² mask, descriptor commutativity, orientation) minimized exactly by funcorr's solver
  rather than by L-BFGS; each term is scale-free in funcorr, so the weights are comparable to
  pyFM's but not identical. The map is square: ``n_ev`` must be (k, k).
* ``icp_refine`` / ``zoomout_refine``: funcorr's ICP and ZoomOut on every vertex
  (``subsample`` is not used: funcorr's ZoomOut is fast enough on every vertex of 10⁴–10⁵-vertex
  meshes; a warning says so when it is given).
* ``geod_from`` / ``get_geodesic``: exact polyhedral geodesics (``robust=True``), or the heat
  method / Dijkstra.
* ``viz`` (pyFM's ``pyFM.viz``, PyVista; the ``double_plot`` of its notebooks, meshplot):
  ``plot_mesh`` and ``double_plot`` return funcorr's viewer (:class:`funcorr.Viewer`: inline in
  notebooks, ``.save(path)``) instead of a PyVista plotter; scalar functions are drawn with
  funcorr's blue–white–red map (``cmap``, ``clim``, extra ``points`` and vector fields are not
  drawn). ``vertices_to_rgb`` and ``normalize`` compute what pyFM's do.
"""

from __future__ import annotations

import copy
import sys
import types
import warnings
from typing import Optional

import numpy as np

import funcorr

__all__ = ["TriMesh", "FunctionalMapping", "eval", "viz", "plot_mesh", "double_plot"]


class TriMesh:
    """A triangle mesh: ``TriMesh(path)``, ``TriMesh(vertlist, facelist)`` or
    ``TriMesh(vertlist)`` (a point cloud), with ``area_normalize=``, ``center=``,
    ``rotation=``, ``translation=`` as in pyFM."""

    def __init__(self, *args, area_normalize: bool = False, center: bool = False, rotation=None, translation=None, **kwargs):
        if not 0 < len(args) < 3:
            raise ValueError("Provide a path or vertices / faces")
        if len(args) == 1 and isinstance(args[0], str) or hasattr(args[0], "__fspath__"):
            self.path = str(args[0])
            V, F = funcorr.read_mesh(args[0])
            self._vertlist, self._facelist = V, (F if len(F) else None)
        else:
            self.path = None
            self._vertlist = np.array(args[0], dtype=np.float64)
            self._facelist = None if len(args) == 1 or args[1] is None else np.asarray(args[1])
        if self._vertlist.ndim != 2 or self._vertlist.shape[1] != 3:
            raise ValueError("Vertex list requires 3D coordinates: shape (n, 3)")
        self._prepared: Optional[funcorr.PreparedShape] = None
        self.eigenvalues: Optional[np.ndarray] = None
        self.eigenvectors: Optional[np.ndarray] = None
        self._geod_cache = None
        if rotation is not None:
            self.rotate(np.asarray(rotation))
        if translation is not None:
            self.translate(translation)
        if area_normalize:
            c = self.center_mass
            self.translate(-c)
            self._vertlist = self._vertlist / self.sqrtarea
            self.translate(c)
        if center:
            self.translate(-self.center_mass)

    @classmethod
    def load(cls, path, **kwargs) -> "TriMesh":
        """``TriMesh.load(path, area_normalize=..., center=...)`` (pyFM ≥ 1.3)."""
        return cls(str(path), **kwargs)

    # geometry -------------------------------------------------------------------------------
    @property
    def vertlist(self) -> np.ndarray:
        """(n, 3) vertex positions."""
        return self._vertlist

    @vertlist.setter
    def vertlist(self, v):
        self._vertlist = np.array(v, dtype=np.float64)
        self._reset()

    @property
    def facelist(self) -> Optional[np.ndarray]:
        """(m, 3) triangles (None for a point cloud)."""
        return self._facelist

    @facelist.setter
    def facelist(self, f):
        self._facelist = None if f is None else np.asarray(f)
        self._reset()

    vertices = vertlist
    faces = facelist

    def _reset(self):
        self._prepared = None
        self.eigenvalues = self.eigenvectors = None
        self._geod_cache = None

    @property
    def n_vertices(self) -> int:
        return self._vertlist.shape[0]

    @property
    def n_faces(self) -> int:
        return 0 if self._facelist is None else self._facelist.shape[0]

    @property
    def face_areas(self) -> np.ndarray:
        V, F = self._vertlist, self._facelist
        return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)

    faces_areas = face_areas

    @property
    def area(self) -> float:
        return float(self.vertex_areas.sum())

    @property
    def sqrtarea(self) -> float:
        return float(np.sqrt(self.area))

    @property
    def vertex_areas(self) -> np.ndarray:
        """(n,) barycentric vertex areas (the lumped mass of the Laplacian)."""
        if self._prepared is not None:
            return self._prepared.mass
        if self._facelist is None:
            return funcorr.cloud_laplacian(self._vertlist)[1]
        return funcorr.cotangent_laplacian(self._vertlist, self._facelist)[1]

    @property
    def center_mass(self) -> np.ndarray:
        return np.average(self._vertlist, axis=0, weights=self.vertex_areas)

    @property
    def normals(self) -> np.ndarray:
        """(m, 3) unit face normals."""
        V, F = self._vertlist, self._facelist
        n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    def set_vertex_normal_weighting(self, weight_type: str):
        """``"area"`` (default) or ``"uniform"`` weights of the face normals in ``vertex_normals``."""
        if weight_type not in ("area", "uniform"):
            raise ValueError(f"weight_type: expected 'area' or 'uniform', got {weight_type!r}")
        self._normal_weighting = weight_type

    @property
    def vertex_normals(self) -> np.ndarray:
        """(n, 3) unit vertex normals: the sum of the adjacent faces' normals, weighted by area
        (default) or uniformly (``set_vertex_normal_weighting("uniform")``)."""
        V, F = self._vertlist, self._facelist
        n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        if getattr(self, "_normal_weighting", "area") == "uniform":
            n = n / np.linalg.norm(n, axis=1, keepdims=True)
        out = np.zeros_like(V)
        for c in range(3):
            np.add.at(out, F[:, c], n)
        return out / np.linalg.norm(out, axis=1, keepdims=True)

    @property
    def edges(self) -> np.ndarray:
        F = self._facelist
        e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        return np.unique(e, axis=0)

    def rotate(self, R):
        self._vertlist = self._vertlist @ np.asarray(R).T
        self._reset()
        return self

    def translate(self, t):
        self._vertlist = self._vertlist + np.asarray(t).reshape(1, 3)
        self._reset()
        return self

    def scale(self, alpha):
        self._vertlist = self._vertlist * alpha
        self._reset()
        return self

    # spectrum -------------------------------------------------------------------------------
    def _shape(self):
        return (self._vertlist, self._facelist)

    def process(self, k: int = 200, skip_normals: bool = True, intrinsic: bool = False, robust: bool = False, verbose: bool = False):
        """Computes the first k eigenpairs (funcorr's cotangent Laplacian; point clouds: the
        point-cloud Laplacian). Returns self."""
        if self.eigenvalues is not None and len(self.eigenvalues) >= k:
            self.eigenvalues = self.eigenvalues[:k]
            self.eigenvectors = self.eigenvectors[:, :k]
            return self
        self._prepared = funcorr.prepare(self._shape(), k=k)
        self.eigenvalues = self._prepared.eigenvalues
        self.eigenvectors = self._prepared.eigenvectors
        if verbose:
            print(f"\tComputed {k} eigenpairs (funcorr, block Lanczos)")
        return self

    @property
    def A(self):
        import scipy.sparse as sp

        return sp.diags(self.vertex_areas)

    @property
    def W(self):
        if self._prepared is None:
            raise ValueError("call process(k) first")
        return funcorr.stiffness(self._prepared)

    def l2_sqnorm(self, func) -> np.ndarray:
        f = np.asarray(func)
        a = self.vertex_areas
        return (a[:, None] * f * f).sum(0) if f.ndim == 2 else float((a * f * f).sum())

    def l2_inner(self, f, g):
        f, g = np.asarray(f), np.asarray(g)
        a = self.vertex_areas
        return (a[:, None] * f * g).sum(0) if f.ndim == 2 else float((a * f * g).sum())

    def integrate(self, func):
        f = np.asarray(func)
        return self.vertex_areas @ f

    def project(self, func, k: Optional[int] = None) -> np.ndarray:
        """Coefficients Φ_kᵀ A f of a function (n,) or functions (n, p) on the first k eigenvectors."""
        k = self.eigenvectors.shape[1] if k is None else k
        f = np.asarray(func)
        af = self.vertex_areas[:, None] * f if f.ndim == 2 else self.vertex_areas * f
        return self.eigenvectors[:, :k].T @ af

    def decode(self, projection) -> np.ndarray:
        c = np.asarray(projection)
        return self.eigenvectors[:, : c.shape[0]] @ c

    unproject = decode

    def reconstruct(self, func, k: Optional[int] = None):
        return self.decode(self.project(func, k=k))

    # geodesics ------------------------------------------------------------------------------
    def geod_from(self, i: int, robust: bool = True) -> np.ndarray:
        """(n,) geodesic distances from vertex i: exact polyhedral (``robust=True``) or the heat method."""
        return funcorr.geodesic_distances(self._shape(), int(i), method="exact" if robust else "heat")

    def get_geodesic(self, dijkstra: bool = False, robust: bool = True, save: bool = False, force_compute: bool = False, sym: bool = False, batch_size: int = 500, verbose: bool = False) -> np.ndarray:
        """(n, n) geodesic distances (the heat method, or Dijkstra on the edges with
        ``dijkstra=True``), symmetrized with ``sym=True``; cached on the mesh."""
        if self._geod_cache is None or force_compute:
            D = funcorr.geodesic_all_pairs(self._shape(), method="dijkstra" if dijkstra else "heat", chunk=batch_size)
            self._geod_cache = D
        D = self._geod_cache
        return 0.5 * (D + D.T) if sym else D

    def extract_fps(self, size: int, random_init: bool = True, geodesic: bool = False, verbose: bool = False) -> np.ndarray:
        """``size`` farthest-point samples (Euclidean), starting from vertex 0."""
        V = self._vertlist
        chosen = [0]
        d = np.linalg.norm(V - V[0], axis=1)
        for _ in range(1, min(size, len(V))):
            j = int(np.argmax(d))
            chosen.append(j)
            d = np.minimum(d, np.linalg.norm(V - V[j], axis=1))
        return np.array(chosen)

    farthest_point_sampling = extract_fps

    def export(self, filename: str, precision: Optional[int] = None):
        funcorr.write_mesh(filename, self._vertlist, self._facelist)
        return self


def _normalize(descr: np.ndarray, mesh: TriMesh) -> np.ndarray:
    return descr / np.sqrt(mesh.l2_sqnorm(descr))[None, :]


class FunctionalMapping:
    """A functional map between mesh1 and mesh2 (pyFM's conventions: ``FM`` (k2 × k1) maps
    functions on mesh1 to mesh2, ``p2p_21`` gives for each vertex of mesh2 a vertex of mesh1)."""

    def __init__(self, mesh1: TriMesh, mesh2: TriMesh):
        self.mesh1 = copy.copy(mesh1)
        self.mesh2 = copy.copy(mesh2)
        self.descr1 = None
        self.descr2 = None
        self._FM_type = "classic"
        self._FM_base = None
        self._FM_icp = None
        self._FM_zo = None
        self._k1 = self._k2 = None

    @property
    def k1(self):
        if self._k1 is None and self.mesh1.eigenvalues is not None:
            return len(self.mesh1.eigenvalues)
        return self._k1 if self._k1 is not None else (None if self.FM is None else self.FM.shape[1])

    @k1.setter
    def k1(self, k):
        self._k1 = k

    @property
    def k2(self):
        if self._k2 is None and self.mesh2.eigenvalues is not None:
            return len(self.mesh2.eigenvalues)
        return self._k2 if self._k2 is not None else (None if self.FM is None else self.FM.shape[0])

    @k2.setter
    def k2(self, k):
        self._k2 = k

    @property
    def FM_type(self) -> str:
        return self._FM_type

    @FM_type.setter
    def FM_type(self, t: str):
        if t.lower() not in ("classic", "icp", "zoomout"):
            raise ValueError(f"FM_type can only be 'classic', 'icp' or 'zoomout', not {t!r}")
        self._FM_type = t

    def change_FM_type(self, FM_type: str):
        self.FM_type = FM_type

    @property
    def FM(self) -> Optional[np.ndarray]:
        """The current functional map (k2 × k1, functions on mesh1 → mesh2) of ``FM_type``."""
        return {"classic": self._FM_base, "icp": self._FM_icp, "zoomout": self._FM_zo}[self._FM_type.lower()]

    @FM.setter
    def FM(self, FM):
        self._FM_base = FM

    @property
    def FM_12(self) -> Optional[np.ndarray]:
        """The fitted functional map (k2 × k1), before refinement (pyFM 1.3's attribute)."""
        return self._FM_base

    @FM_12.setter
    def FM_12(self, FM):
        self._FM_base = FM

    @property
    def has_spectral(self) -> bool:
        return self.mesh1.eigenvalues is not None and self.mesh2.eigenvalues is not None

    @property
    def preprocessed(self) -> bool:
        return self.descr1 is not None and self.descr2 is not None and self.mesh1.eigenvalues is not None

    @property
    def fitted(self) -> bool:
        return self.FM is not None

    def _lmks(self, landmarks):
        lm = np.asarray(landmarks)
        if lm.squeeze().ndim == 1:
            return lm.squeeze(), lm.squeeze().copy()
        return lm[:, 0], lm[:, 1]

    def preprocess(self, n_ev=None, n_descr: int = 100, descr_type: Optional[str] = "WKS", landmarks=None, subsample_step: int = 1, k_process: Optional[int] = None, verbose: bool = False, k_descr: Optional[int] = None, landmarks_only: bool = False, K=None):
        """Spectra (max(k, k_process = 200) eigenpairs), descriptors (``descr_type`` "WKS" or
        "HKS", ``n_descr`` of them from the first ``k_descr`` eigenpairs (default: k1 / k2 when
        ``n_ev`` is given, else 128), plus heat kernel maps at the ``landmarks`` ((p,) same
        indices, or (p, 2)); only those with ``landmarks_only``), every ``subsample_step``-th
        kept, L²-normalized. Both pyFM APIs: ``preprocess(n_ev=(k1, k2), ...)`` (before 1.3)
        and ``preprocess(n_descr, ...)`` with the size given to ``fit(K=...)`` (1.3). Returns self."""
        if isinstance(n_ev, (int, np.integer)) and not isinstance(n_ev, bool):
            n_descr, n_ev = int(n_ev), None  # pyFM 1.3: the first positional argument is n_descr
        if n_ev is None and K is not None:
            n_ev = K
        if n_ev is not None:
            self.k1, self.k2 = (n_ev, n_ev) if np.isscalar(n_ev) else n_ev
        k1 = self._k1 if self._k1 is not None else (k_descr or 128)
        k2 = self._k2 if self._k2 is not None else (k_descr or 128)
        kd1, kd2 = (k_descr, k_descr) if k_descr is not None else (k1, k2)
        k_process = 200 if k_process is None else k_process
        self.mesh1.process(max(k1, kd1, k_process), verbose=verbose)
        self.mesh2.process(max(k2, kd2, k_process), verbose=verbose)
        if descr_type is None:
            return self

        def basis(mesh, k):
            return (mesh.eigenvalues[:k], mesh.eigenvectors[:, :k], mesh.vertex_areas)

        b1, b2 = basis(self.mesh1, kd1), basis(self.mesh2, kd2)
        if descr_type == "WKS":
            d1, d2 = funcorr.wks(b1, n_descr), funcorr.wks(b2, n_descr)
        elif descr_type == "HKS":
            d1, d2 = funcorr.hks(b1, n_descr), funcorr.hks(b2, n_descr)
        else:
            raise ValueError(f'descr_type must be "WKS", "HKS", or None, got "{descr_type}"')
        if landmarks is not None and len(landmarks) > 0:
            l1, l2 = self._lmks(landmarks)
            # Heat kernel maps at the landmarks, n_descr times log-spaced on each shape as its HKS.
            m1, m2 = funcorr.hkm(b1, l1, count=n_descr), funcorr.hkm(b2, l2, count=n_descr)
            d1, d2 = (m1, m2) if landmarks_only else (np.hstack([d1, m1]), np.hstack([d2, m2]))
        self.descr1 = _normalize(d1[:, ::subsample_step], self.mesh1)
        self.descr2 = _normalize(d2[:, ::subsample_step], self.mesh2)
        if verbose:
            print(f"\n\t{self.descr1.shape[1]} descriptors kept")
        return self

    def add_descriptors(self, descr1, descr2, normalize: bool = True):
        """Appends descriptors (n1, p) and (n2, p) (L²-normalized unless ``normalize=False``)."""
        d1, d2 = np.asarray(descr1, dtype=np.float64), np.asarray(descr2, dtype=np.float64)
        if d1.ndim == 1:
            d1, d2 = d1[:, None], d2[:, None]
        if normalize:
            d1, d2 = _normalize(d1, self.mesh1), _normalize(d2, self.mesh2)
        self.descr1 = d1 if self.descr1 is None else np.hstack([self.descr1, d1])
        self.descr2 = d2 if self.descr2 is None else np.hstack([self.descr2, d2])
        return self

    def fit(self, w_descr: float = 1e-1, w_lap: float = 1e-3, w_dcomm: float = 1, w_orient: float = 0, orient_reversing: bool = False, optinit: str = "zeros", verbose: bool = False, K=None, use_resolvent_laplacian: Optional[bool] = None, resolvent_gamma: float = 0.5, factr=None, pgtol=None, normalize_weights: bool = True):
        """The functional map minimizing descriptor preservation (``w_descr``), Laplacian
        commutativity (``w_lap``; mask (λ₁ − λ₂)², or the resolvent mask with
        ``use_resolvent_laplacian=True``, the default when the size is given as ``K`` as in
        pyFM 1.3), descriptor commutativity (``w_dcomm``) and orientation preservation
        (``w_orient``; reversal with ``orient_reversing``), solved exactly by funcorr
        (``optinit``, ``factr``, ``pgtol`` are the L-BFGS settings of pyFM: checked, not needed).
        Sets ``FM_12`` (and ``FM``). Returns self."""
        if optinit not in ("random", "identity", "zeros"):
            raise ValueError(f"optinit arg should be 'random', 'identity' or 'zeros', not {optinit}")
        if resolvent_gamma != 0.5:
            raise ValueError("resolvent_gamma: funcorr's resolvent mask has γ = 0.5")
        if K is not None:
            self.k1, self.k2 = (K, K) if np.isscalar(K) else K
            if use_resolvent_laplacian is None:
                use_resolvent_laplacian = True
        if not self.preprocessed:
            self.preprocess()
        if self.k1 != self.k2:
            raise ValueError(f"n_ev: funcorr fits square functional maps, got (k1, k2) = ({self.k1}, {self.k2})")
        C, energy = funcorr.axiomatic_fmap(
            self.mesh1._prepared,
            self.mesh2._prepared,
            self.descr1,
            self.descr2,
            self.k1,
            w_descr=w_descr,
            w_lap=w_lap,
            w_dcomm=w_dcomm,
            w_orient=w_orient,
            mask="resolvent" if use_resolvent_laplacian else "standard",
            orientation="reverse" if orient_reversing else "preserve",
        )
        self.FM = C
        self._FM_icp = self._FM_zo = None
        self._FM_type = "classic"
        if verbose:
            print(f"\tFitted a {C.shape[0]}×{C.shape[1]} map, energy {energy:.3e}")
        return self

    def get_p2p(self, FM=None, use_adj: bool = False, n_jobs=None) -> np.ndarray:
        """(n2,) ``p2p_21``: vertex i of mesh2 matched to vertex p2p_21[i] of mesh1, from ``FM``
        (default: the current map, ``FM``)."""
        if isinstance(FM, bool):  # pyFM < 1.3: get_p2p(use_adj)
            FM, use_adj = None, FM
        FM = self.FM if FM is None else np.asarray(FM)
        if FM is None:
            raise ValueError("Model should be fit before computing the p2p map")
        return funcorr.maps_from_fmap(self.mesh1._prepared, self.mesh2._prepared, FM)[1]

    @property
    def p2p_21(self) -> np.ndarray:
        """``get_p2p()``: for each vertex of mesh2 a vertex of mesh1."""
        return self.get_p2p()

    @property
    def p2p(self) -> np.ndarray:
        return self.get_p2p()

    def icp_refine(self, FM=None, nit: int = 10, tol=None, use_adj: bool = False, overwrite: bool = True, verbose: bool = False, n_jobs=None):
        """ICP refinement of ``FM`` (default: the current map) with ``nit`` iterations at most
        (it stops when the point map no longer changes). Stores it as the "icp" map (the current
        one with ``overwrite``, as pyFM < 1.3) and returns it (as pyFM 1.3)."""
        if FM is not None and np.ndim(FM) == 0:  # pyFM < 1.3: icp_refine(nit, ...)
            FM, nit = None, int(FM)
        FM = self.FM if FM is None else np.asarray(FM)
        if FM is None:
            raise ValueError("The Functional map must be fit before refining it")
        self._FM_icp, _ = funcorr.icp_refine(self.mesh1._prepared, self.mesh2._prepared, FM, iterations=nit if nit is not None else 50)
        if overwrite:
            self.FM_type = "icp"
        return self._FM_icp

    def zoomout_refine(self, FM=None, nit: Optional[int] = None, step: Optional[int] = None, subsample=None, overwrite: bool = True, verbose: bool = False):
        """ZoomOut of ``FM`` (default: the current map): ``nit`` iterations of ``step`` (to
        k + nit · step). Stores it as the "zoomout" map (the current one with ``overwrite``, as
        pyFM < 1.3) and returns it (as pyFM 1.3)."""
        if FM is not None and np.ndim(FM) == 0:  # pyFM < 1.3: zoomout_refine(nit, step, ...)
            FM, nit, step = None, int(FM), (nit if nit is not None else step)
        nit = 10 if nit is None else nit
        step = 1 if step is None else step
        FM = self.FM if FM is None else np.asarray(FM)
        if FM is None:
            raise ValueError("The Functional map must be fit before refining it")
        if subsample:
            warnings.warn("funcorr's ZoomOut runs on every vertex; subsample is not used", stacklevel=2)
        k = FM.shape[0]
        need = k + nit * step
        for mesh in (self.mesh1, self.mesh2):
            if len(mesh.eigenvalues) < need:
                mesh.process(need)
        self._FM_zo, _ = funcorr.zoomout_refine(self.mesh1._prepared, self.mesh2._prepared, FM, k_final=need, step=step)
        if overwrite:
            self.FM_type = "zoomout"
        return self._FM_zo

    def project(self, func, k=None, mesh_ind: int = 1):
        mesh, kk = (self.mesh1, self.k1) if mesh_ind == 1 else (self.mesh2, self.k2)
        return mesh.project(func, k=kk if k is None else k)

    def decode(self, encoded_func, mesh_ind: int = 2):
        return (self.mesh1 if mesh_ind == 1 else self.mesh2).decode(encoded_func)

    def transport(self, encoded_func, reverse: bool = False):
        FM = self.FM
        c = np.asarray(encoded_func)
        return FM[:, : c.shape[0]] @ c if not reverse else FM.T[:, : c.shape[0]] @ c

    def transfer(self, func, reverse: bool = False):
        if not reverse:
            return self.decode(self.transport(self.project(func, mesh_ind=1)), mesh_ind=2)
        return self.decode(self.transport(self.project(func, mesh_ind=2), reverse=True), mesh_ind=1)


class _Eval:
    """``pyFM.eval``: ``accuracy(p2p, gt_p2p, D1_geod, return_all=False, sqrt_area=None)``."""

    @staticmethod
    def accuracy(p2p, gt_p2p, D1_geod, return_all: bool = False, sqrt_area=None):
        """Mean of D1_geod[p2p[i], gt_p2p[i]] (divided by ``sqrt_area``): maps from mesh2 to mesh1."""
        dists = np.asarray(D1_geod)[np.asarray(p2p), np.asarray(gt_p2p)].astype(np.float64)
        if sqrt_area is not None:
            dists = dists / sqrt_area
        return (dists.mean(), dists) if return_all else dists.mean()


eval = _Eval()


# ---- pyFM.viz (and the plots of pyFM's notebooks) on funcorr's viewer ---------------------------


def _mesh_geometry(mesh):
    """``(V, F)`` of a TriMesh (this module's or pyFM's), an object with ``.vertices`` /
    ``.faces``, a ``(V, F)`` tuple, or a path / PreparedShape (as :func:`funcorr.view` takes)."""
    if isinstance(mesh, TriMesh):
        return mesh.vertlist, mesh.facelist
    if hasattr(mesh, "vertlist"):
        return np.asarray(mesh.vertlist), getattr(mesh, "facelist", None)
    if hasattr(mesh, "vertices") and not isinstance(mesh, funcorr.PreparedShape):
        faces = getattr(mesh, "faces", None)
        return np.asarray(mesh.vertices), None if faces is None or len(faces) == 0 else np.asarray(faces)
    return mesh


def _n(geometry) -> int:
    if isinstance(geometry, tuple):
        return np.asarray(geometry[0]).shape[0]
    return funcorr._vertex_count(geometry)


def _scalars(scalars, n: int):
    """(colours, field): RGB (n, 3) values become colours, (n,) values a field; per-face values
    are not drawn (a warning)."""
    if scalars is None:
        return None, None
    a = np.asarray(scalars)
    if a.shape[0] != n:
        warnings.warn(f"funcorr's viewer draws per-vertex values ({n}); {a.shape[0]} values (per face?) are not drawn", stacklevel=3)
        return None, None
    if a.ndim == 2 and a.shape[1] == 3:
        return a, None
    return None, a.astype(np.float64).ravel()


_IGNORED = ("cmap", "clim", "points", "points_scalars", "vfield", "colormap", "shading")


def plot_mesh(mesh, scalars=None, *, title: Optional[str] = None, height: int = 620, **kwargs) -> "funcorr.Viewer":
    """pyFM's ``plot_mesh(mesh, scalars)``: one mesh (or point cloud) in funcorr's viewer.

    ``scalars``: (n, 3) RGB in [0, 1] (pyFM's ``vertices_to_rgb``) or uint8, or (n,) values (drawn
    with funcorr's blue–white–red map; the page shows the value under the pointer). ``wireframe``
    and ``smooth`` are the page's own controls; PyVista's options (``cmap``, ``points``,
    ``vfield``, …) are not drawn. Returns a :class:`funcorr.Viewer`."""
    unused = sorted(k for k in kwargs if kwargs[k] is not None and k in _IGNORED)
    if unused:
        warnings.warn(f"plot_mesh: {', '.join(unused)} not drawn by funcorr's viewer", stacklevel=2)
    geometry = _mesh_geometry(mesh)
    colors, values = _scalars(scalars, _n(geometry))
    fields = {"scalars": ("x", values)} if values is not None else None
    return funcorr.view(geometry, colors_x=colors, fields=fields, start="scalars" if fields else None, title=title or "mesh", height=height)


def double_plot(mesh1, mesh2, cmap1=None, cmap2=None, *, p2p_21=None, p2p_12=None, title: Optional[str] = None, height: int = 620, **kwargs) -> "funcorr.Viewer":
    """The ``double_plot(mesh1, mesh2, cmap1, cmap2)`` of pyFM's notebooks: two meshes side by
    side in linked cameras, coloured by ``cmap1``/``cmap2`` ((n, 3) RGB, e.g.
    ``cmap2 = cmap1[p2p_21]``) or by position. With ``p2p_21`` (for every vertex of mesh2 a
    vertex of mesh1) the page also marks the image of a clicked vertex, and mesh2 takes mesh1's
    colours through it when ``cmap2`` is None. Returns a :class:`funcorr.Viewer`."""
    unused = sorted(k for k in kwargs if kwargs[k] is not None and k in _IGNORED)
    if unused:
        warnings.warn(f"double_plot: {', '.join(unused)} not drawn by funcorr's viewer", stacklevel=2)
    g1, g2 = _mesh_geometry(mesh1), _mesh_geometry(mesh2)
    n1, n2 = _n(g1), _n(g2)
    c1, v1 = _scalars(cmap1, n1)
    c2, v2 = _scalars(cmap2, n2)
    fields = {}
    if v1 is not None:
        fields["cmap1 on mesh1"] = ("x", v1)
    if v2 is not None:
        fields["cmap2 on mesh2"] = ("y", v2)
    return funcorr.view(
        g1,
        g2,
        map_xy=p2p_12,
        map_yx=p2p_21,
        colors_x=c1,
        colors_y=c2,
        fields=fields or None,
        start=next(iter(fields)) if fields else None,
        title=title or "mesh1 → mesh2",
        height=height,
    )


def normalize(f, vmin: float = 0, vmax: float = 1):
    """pyFM's ``normalize``: each function (a vector, or each column of a matrix) affinely to
    [vmin, vmax]; a constant function becomes vmin."""
    f = np.asarray(f, dtype=np.float64)
    lo = f.min(axis=0, keepdims=f.ndim > 1)
    span = f.max(axis=0, keepdims=f.ndim > 1) - lo
    span = np.where(span == 0, 1, span)
    return vmin + (vmax - vmin) * (f - lo) / span


def vertices_to_rgb(vertices, param=(-2, -1, 3)):
    """pyFM's ``vertices_to_rgb``: RGB in [0, 1] (n, 3) from positions: the coordinates
    sign-flipped and reordered by ``param`` (a signed permutation of 1, 2, 3; as pyFM, the sign of
    entry j flips coordinate j before the reordering), normalized, through a cosine, normalized
    again."""
    param = np.asarray(param)
    if sorted(np.abs(param).tolist()) != [1, 2, 3]:
        raise ValueError("param: expected a signed permutation of (1, 2, 3), e.g. (-2, -1, 3)")
    v = np.asarray(vertices, dtype=np.float64)
    c = (np.sign(param)[None, :] * v)[:, np.abs(param) - 1]
    return normalize(np.cos(normalize(c)))


viz = types.ModuleType(__name__ + ".viz", "pyFM.viz on funcorr's viewer: plot_mesh, double_plot, vertices_to_rgb, normalize.")
viz.plot_mesh = plot_mesh
viz.double_plot = double_plot
viz.vertices_to_rgb = vertices_to_rgb
viz.normalize = normalize
viz.__all__ = ["plot_mesh", "double_plot", "vertices_to_rgb", "normalize"]
# ``from funcorr.compat.pyfm.viz import plot_mesh`` as ``from pyFM.viz import plot_mesh``.
sys.modules[viz.__name__] = viz
