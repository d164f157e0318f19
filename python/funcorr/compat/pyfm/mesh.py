"""``pyFM.mesh`` on funcorr: :class:`TriMesh` (pyFM 1.3's API and the older one).

Spectra, Laplacians, geodesics and file reading are funcorr's; the small geometric quantities
(normals, face areas, gradients) are numpy formulas as in pyFM. Units: everything is in the
mesh's own units, as in pyFM (``area_normalize=True`` scales the mesh to unit area first).

One module of ~800 lines because it is one class, pyFM's ``TriMesh`` with both of its APIs (the
file writers at the end are its ``save``'s).
"""

from __future__ import annotations

import copy as _copy
import os as _os
from typing import Optional

import numpy as np

import funcorr as _fc

from ._common import warn_once

__all__ = ["TriMesh"]

GEODESIC_METHODS = ("heat", "heat_pure", "dijkstra", "fast_marching", "exact")


class TriMesh:
    """A triangle mesh, or a point cloud when no faces are given.

    ``TriMesh(vertices (n, 3), faces (m, 3) = None, *, area_normalize=False, center=False,
    normalize=False, rotation=None, translation=None, name=None)``, ``TriMesh.load(path,
    **kwargs)``, or (pyFM before 1.3) ``TriMesh(path, **kwargs)``.

    Attributes: ``vertices`` / ``vertlist`` (n, 3), ``faces`` / ``facelist`` (m, 3) or None,
    ``eigenvalues`` (k,), ``eigenvectors`` (n, k) after :meth:`process`, ``stiffness`` / ``W``
    and ``mass`` / ``A`` (n × n scipy.sparse), ``path``, ``name``.
    """

    def __init__(self, vertices, faces=None, *args, area_normalize=False, center=False, normalize=False, rotation=None, translation=None, name=None, **kwargs):
        if args:
            raise TypeError("TriMesh(vertices, faces=None, *, ...): options are keywords")
        if kwargs:
            raise TypeError(f"TriMesh: unknown keyword(s) {', '.join(sorted(kwargs))}")
        self._init_all_attributes()
        self.name = name
        path = None
        if isinstance(vertices, (str, _os.PathLike)):
            if faces is not None:
                raise TypeError("Cannot give both a file path and a list of faces")
            path = _os.fspath(vertices)
            vertices, faces = _read(path)
        if normalize:
            area_normalize = center = True
        self.vertices = vertices
        self.faces = faces
        if path is not None:
            self.path = path
            if self.name is None:
                self.name = _os.path.splitext(_os.path.basename(path))[0]
        if rotation is not None:
            self.rotate(rotation)
        if translation is not None:
            self.translate(translation)
        if area_normalize:
            self.area_normalize()
        if center:
            self.translate(-self.center_mass)

    @classmethod
    def load(cls, path, **kwargs) -> "TriMesh":
        """Reads a mesh (OFF, OBJ, PLY; funcorr's readers) with the keywords of :class:`TriMesh`."""
        path = _os.fspath(path)
        vertices, faces = _read(path)
        mesh = cls(vertices, faces, **kwargs)
        mesh.path = path
        if mesh.name is None:
            mesh.name = _os.path.splitext(_os.path.basename(path))[0]
        return mesh

    from_file = load

    def __repr__(self):
        name = "" if self.name is None else f" {self.name!r}"
        if self.is_point_cloud:
            return f"<TriMesh{name}: {self.n_vertices} vertices (point cloud)>"
        return f"<TriMesh{name}: {self.n_vertices} vertices, {self.n_faces} faces>"

    # core data --------------------------------------------------------------------------------
    @property
    def vertices(self) -> np.ndarray:
        """(n, 3) vertex positions."""
        return self._vertices

    @vertices.setter
    def vertices(self, vertices):
        vertices = np.asarray(vertices, dtype=float)
        if vertices.ndim != 2:
            raise ValueError("Vertex list has to be 2D")
        if vertices.shape[1] != 3:
            raise ValueError(f"Vertex list requires 3D coordinates: shape (n, 3), got {vertices.shape}")
        if self._vertices is not None:
            self._modified = True
            self._normalized = False
        self._reset_vertex_attributes()
        self.path = None
        self._vertices = vertices.copy()

    @property
    def faces(self) -> Optional[np.ndarray]:
        """(m, 3) triangles, None for a point cloud."""
        return self._faces

    @faces.setter
    def faces(self, faces):
        if faces is None or len(faces) == 0:
            self._faces = None
        else:
            faces = np.asarray(faces)
            if faces.ndim != 2 or faces.shape[1] != 3:
                raise ValueError(f"Faces list has to be (m, 3), got {faces.shape}")
            self._faces = faces.astype(np.int64, copy=True)
        self._edges = None
        self._reset_vertex_attributes()
        self.path = None

    vertlist = vertices
    facelist = faces

    @property
    def is_point_cloud(self) -> bool:
        return self._faces is None

    def _require_faces(self, what):
        if self.is_point_cloud:
            raise ValueError(f"Cannot compute {what}: this mesh has no faces.")

    @property
    def n_vertices(self) -> int:
        return self._vertices.shape[0]

    @property
    def n_faces(self) -> int:
        return 0 if self._faces is None else self._faces.shape[0]

    # derived quantities -----------------------------------------------------------------------
    @property
    def edges(self) -> np.ndarray:
        """(p, 2) edges (sorted vertex pairs)."""
        if self._edges is None:
            self.compute_edges()
        return self._edges

    @property
    def edge_lengths(self) -> np.ndarray:
        e = self.edges
        return np.linalg.norm(self._vertices[e[:, 1]] - self._vertices[e[:, 0]], axis=1)

    edges_lengths = edge_lengths

    @property
    def face_normals(self) -> np.ndarray:
        """(m, 3) unit face normals."""
        if self._face_normals is None:
            self.compute_normals()
        return self._face_normals

    @face_normals.setter
    def face_normals(self, n):
        self._face_normals = n

    normals = face_normals

    @property
    def vertex_normals(self) -> np.ndarray:
        """(n, 3) unit vertex normals, weighted by face area (default) or uniformly."""
        if self._vertex_normals is None:
            self.compute_vertex_normals()
        return self._vertex_normals

    @vertex_normals.setter
    def vertex_normals(self, n):
        self._vertex_normals = n

    @property
    def face_areas(self) -> np.ndarray:
        """(m,) triangle areas."""
        self._require_faces("face areas")
        V, F = self._vertices, self._faces
        return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)

    faces_areas = face_areas

    @property
    def W(self):
        """Alias of ``stiffness``."""
        return self.stiffness

    @W.setter
    def W(self, value):
        self.stiffness = value

    @property
    def A(self):
        """Alias of ``mass``."""
        return self.mass

    @A.setter
    def A(self, value):
        self.mass = value

    @property
    def is_intrinsic(self) -> bool:
        """Whether the operators are those of the intrinsic Delaunay triangulation."""
        return self._intrinsic

    @property
    def vertex_areas(self) -> np.ndarray:
        """(n,) vertex areas: the diagonal of the mass matrix (barycentric when not processed)."""
        if self.mass is not None:
            return np.asarray(self.mass.sum(1)).ravel()
        if self.is_point_cloud:
            return np.ones(self.n_vertices)
        return _fc.cotangent_laplacian(self._vertices, self._faces)[1]

    @property
    def area(self):
        """Total area (None for an unprocessed point cloud)."""
        if self.mass is None:
            return None if self.is_point_cloud else float(self.face_areas.sum())
        return float(self.mass.sum())

    @property
    def sqrt_area(self) -> float:
        return float(np.sqrt(self.area))

    sqrtarea = sqrt_area

    @property
    def center_mass(self) -> np.ndarray:
        return np.average(self._vertices, axis=0, weights=self.vertex_areas)

    @property
    def is_normalized(self) -> bool:
        return self._normalized

    @property
    def is_modified(self) -> bool:
        return self._modified

    # bookkeeping ------------------------------------------------------------------------------
    def _init_all_attributes(self):
        self.path = None
        self.name = None
        self._vertices = None
        self._faces = None
        self._modified = False
        self._normalized = False
        self._vertex_normals_weighting = "area"
        self._edges = None
        self._reset_vertex_attributes()

    def _reset_vertex_attributes(self):
        self._face_normals = None
        self._vertex_normals = None
        self._intrinsic = False
        self._laplacian = None
        self.stiffness = None
        self.mass = None
        self.eigenvalues = None
        self.eigenvectors = None
        self._prepared = None
        self._geod_cache = {}

    def copy(self, deep: bool = True) -> "TriMesh":
        return _copy.deepcopy(self) if deep else _copy.copy(self)

    # transformations --------------------------------------------------------------------------
    def area_normalize(self) -> "TriMesh":
        """Scales the mesh to unit area, keeping its center of mass."""
        c = self.center_mass
        self.translate(-c)
        self.scale(1 / self.sqrt_area)
        self.translate(c)
        self._normalized = True
        return self

    def rotate(self, R) -> "TriMesh":
        R = np.asarray(R, dtype=float)
        if R.shape != (3, 3) or not np.isclose(np.linalg.det(R), 1):
            raise ValueError("Rotation should be a 3x3 matrix with unit determinant")
        self._vertices = self._vertices @ R.T
        if self._face_normals is not None:
            self._face_normals = self._face_normals @ R.T
        if self._vertex_normals is not None:
            self._vertex_normals = self._vertex_normals @ R.T
        self._geod_cache = {}
        return self

    def translate(self, t) -> "TriMesh":
        self._vertices = self._vertices + np.asarray(t, dtype=float).reshape(1, 3)
        return self

    def scale(self, alpha) -> "TriMesh":
        """Multiplies the mesh by alpha, and its areas, spectrum and distances accordingly."""
        self._vertices = self._vertices * alpha
        if self.mass is not None:
            self.mass = alpha**2 * self.mass
        if self.eigenvalues is not None:
            self.eigenvalues = self.eigenvalues / alpha**2
        if self.eigenvectors is not None:
            self.eigenvectors = self.eigenvectors / alpha
        # funcorr's prepared shape is of the unscaled mesh: rebuilt when a fit needs it.
        self._prepared = None
        self._geod_cache = {}
        self._modified = True
        self._normalized = False
        return self

    def center(self) -> "TriMesh":
        return self.translate(-self.center_mass)

    # Laplacian and spectrum -------------------------------------------------------------------
    def _choice(self, intrinsic: bool, robust: bool) -> str:
        if self.is_point_cloud:
            if intrinsic or robust:
                warn_once(
                    "cloud-laplacian",
                    "TriMesh of a point cloud: funcorr's point-cloud Laplacian (Sharp & Crane 2020, as "
                    "robust_laplacian's, without its mollification)",
                )
            return "cloud"
        if robust:
            warn_once(
                "robust",
                "robust=True: funcorr's intrinsic Delaunay Laplacian (robust_laplacian's tufted cover "
                "with mollification 1e-5 is not built; funcorr mollifies only near-degenerate triangles)",
            )
            return "intrinsic"
        return "intrinsic" if intrinsic else "cotan"

    def compute_operators(self, intrinsic: bool = False, robust: bool = False) -> "TriMesh":
        """Builds W (``stiffness``) and A (``mass``, diagonal) without the spectrum: the cotangent
        Laplacian, the intrinsic Delaunay one (``intrinsic``/``robust``) or, for point clouds,
        the point-cloud one."""
        choice = self._choice(intrinsic, robust)
        V, F = self._vertices, self._faces
        build = {"cloud": lambda: _fc.cloud_laplacian(V), "intrinsic": lambda: _fc.intrinsic_laplacian(V, F)}
        W, A = build.get(choice, lambda: _fc.cotangent_laplacian(V, F))()
        self._set_operators(W, A, choice)
        return self

    def _set_operators(self, W, A, choice):
        import scipy.sparse as sp

        self.stiffness, self.mass = W, sp.diags(A).tocsc()
        self._laplacian = choice
        self._intrinsic = choice == "intrinsic"

    def compute_spectrum(self, k, intrinsic: bool = False, return_spectrum: bool = True, robust: bool = False, verbose: bool = False):
        """The Laplacian (see :meth:`compute_operators`) and its first k eigenpairs (funcorr's
        block Lanczos; Φᵀ A Φ = I). Returns ``(eigenvalues (k,), eigenvectors (n, k))`` if
        asked."""
        import time

        if k <= 0:
            self.compute_operators(intrinsic=intrinsic, robust=robust)
            return None
        choice = self._choice(intrinsic, robust)
        t = time.time()
        P = _fc.prepare(self._shape(), k=int(k), laplacian=choice)
        self._set_operators(_fc.stiffness(P), P.mass, choice)
        self._prepared = P
        self.eigenvalues, self.eigenvectors = P.eigenvalues, P.eigenvectors
        if verbose:
            print(f"Computing {k} eigenvectors\n\tDone in {time.time() - t:.2f} s")
        return (self.eigenvalues, self.eigenvectors) if return_spectrum else None

    laplacian_spectrum = compute_spectrum

    def process(self, k: int = 200, skip_normals: bool = True, intrinsic: bool = False, robust: bool = False, verbose: bool = False) -> "TriMesh":
        """Computes (or truncates to) the first k eigenpairs. Returns self."""
        if not skip_normals and not self.is_point_cloud:
            _ = self.face_normals
        if self.eigenvalues is not None and self.eigenvectors is not None and len(self.eigenvalues) >= k:
            self.eigenvalues = self.eigenvalues[:k]
            self.eigenvectors = self.eigenvectors[:, :k]
            return self
        self.compute_spectrum(k, return_spectrum=False, intrinsic=intrinsic, robust=robust, verbose=verbose)
        return self

    def _shape(self):
        return (self._vertices, self._faces)

    def _prepared_shape(self, k: int):
        """funcorr's PreparedShape of this mesh with ≥ k eigenpairs (for fits): the one
        :meth:`process` computed, else a new one (after :meth:`scale`, or eigenvectors set by
        hand, which funcorr's fit does not read: a warning says so)."""
        P = self._prepared
        if P is not None and self.eigenvectors is not None and not _same_basis(P, self):
            warn_once(
                "custom-basis",
                "eigenvectors set by hand: funcorr's fit uses its own eigenbasis of the mesh (the conversions "
                "and refinements use yours)",
            )
        if P is None or P.k < k:
            P = _fc.prepare(self._shape(), k=int(k), laplacian=self._laplacian or "cotan")
            self._prepared = P
        return P

    def project(self, func, k: Optional[int] = None) -> np.ndarray:
        """Coefficients Φ_kᵀ A f of functions (n,) or (n, p): (k,) or (k, p)."""
        if k is None:
            return self.eigenvectors.T @ (self.mass @ func)
        if k <= self.eigenvectors.shape[1]:
            return self.eigenvectors[:, :k].T @ (self.mass @ func)
        raise ValueError(f"At least {k} eigenvectors should be computed before projecting")

    def unproject(self, projection) -> np.ndarray:
        """Φ_k c for coefficients (k,) or (k, p)."""
        k = projection.shape[0]
        if k <= self.eigenvectors.shape[1]:
            return self.eigenvectors[:, :k] @ projection
        raise ValueError(f"At least {k} eigenvectors should be computed before decoding")

    decode = unproject

    def reconstruct(self, func, k: Optional[int] = None) -> np.ndarray:
        return self.unproject(self.project(func, k=k))

    def l2_inner(self, func1, func2):
        """f₁ᵀ A f₂ per column: (p,) or a float."""
        func1, func2 = np.asarray(func1), np.asarray(func2)
        if func1.shape != func2.shape:
            raise ValueError("Shapes must be equal")
        A = self.mass if self.mass is not None else _diag(self.vertex_areas)
        if func1.ndim == 1:
            return float(func1 @ (A @ func2))
        return np.einsum("np,np->p", func1, A @ func2)

    def l2_sqnorm(self, func):
        return self.l2_inner(func, func)

    def h1_inner(self, func1, func2):
        """f₁ᵀ W f₂ per column (the H¹₀ inner product): (p,) or a float."""
        func1, func2 = np.asarray(func1), np.asarray(func2)
        if func1.shape != func2.shape:
            raise ValueError("Shapes must be equal")
        if self.stiffness is None:
            self.compute_operators()
        if func1.ndim == 1:
            return float(func1 @ (self.stiffness @ func2))
        return np.einsum("np,np->p", func1, self.stiffness @ func2)

    def h1_sqnorm(self, func):
        return self.h1_inner(func, func)

    def integrate(self, func):
        A = self.mass if self.mass is not None else _diag(self.vertex_areas)
        func = np.asarray(func)
        return float(np.sum(A @ func)) if func.ndim == 1 else np.sum(A @ func, axis=0)

    # geodesics --------------------------------------------------------------------------------
    def _geodesic_method(self, method: str) -> str:
        if method not in GEODESIC_METHODS:
            raise ValueError(f"method must be one of {GEODESIC_METHODS}, got {method!r}")
        if method == "heat_pure":
            warn_once("heat_pure", "method='heat_pure': funcorr has one heat method (on the intrinsic Delaunay triangulation)")
            return "heat"
        if method == "fast_marching":
            warn_once("fast_marching", "method='fast_marching': funcorr computes exact polyhedral geodesics instead")
            return "exact"
        return method

    def geodesic_from(self, i, method: str = "heat") -> np.ndarray:
        """Geodesic distances from vertex i ((n,)) or from each of the vertices i ((n, p)).
        ``method``: ``"heat"`` (default, funcorr's heat method on the intrinsic Delaunay
        triangulation, as potpourri3d's), ``"dijkstra"`` (mesh edges), ``"exact"`` (funcorr's exact
        polyhedral distances), ``"heat_pure"`` (= heat) and ``"fast_marching"`` (= exact) with a
        warning."""
        self._require_faces("geodesic distances")
        how = self._geodesic_method(method)
        if np.ndim(i) == 0:
            return _fc.geodesic_distances(self._shape(), int(i), method=how)
        return _fc.geodesic_distances(self._shape(), np.asarray(i, dtype=np.int64).ravel(), method=how)

    def geod_from(self, i, robust: bool = True, method: Optional[str] = None) -> np.ndarray:
        """pyFM's ``geod_from``: :meth:`geodesic_from` (``method`` as there; without it the heat
        method, pyFM's choice for ``robust=True`` and, on funcorr, for ``robust=False`` too)."""
        return self.geodesic_from(i, method="heat" if method is None else method)

    def geodesic_matrix(self, method: str = "heat", sym: bool = False, batch_size: int = 500, verbose: bool = False) -> np.ndarray:
        """(n, n) geodesic distances (row i: from vertex i) by ``method`` (as
        :meth:`geodesic_from`), symmetrized with ``sym`` (not for Dijkstra)."""
        self._require_faces("geodesic distances")
        how = self._geodesic_method(method)
        key = (how, bool(sym))
        if key not in self._geod_cache:
            D = _fc.geodesic_all_pairs(self._shape(), method=how, chunk=max(1, int(batch_size)))
            if sym and how != "dijkstra":
                D = 0.5 * (D + D.T)
            self._geod_cache = {key: D}
        return self._geod_cache[key]

    def get_geodesic(self, dijkstra: bool = False, robust: bool = True, save: bool = False, force_compute: bool = False, sym: bool = False, batch_size: int = 500, verbose: bool = False, method: Optional[str] = None) -> np.ndarray:
        """pyFM's ``get_geodesic``: :meth:`geodesic_matrix` with the heat method (or Dijkstra);
        read from ``{dir}/geod_cache/{name}[_n|_mod].npy`` beside the mesh's file when there
        (unless ``force_compute``), written there with ``save`` — as pyFM before 1.3 did."""
        how = method or ("dijkstra" if dijkstra else "heat")
        cache_file = self._geod_cache_file()
        if not force_compute and cache_file is not None and _os.path.isfile(cache_file):
            D = np.load(cache_file)
            if D.shape == (self.n_vertices, self.n_vertices):
                if verbose:
                    print(f"Loaded geodesic distances from {cache_file}")
                return D
        D = self.geodesic_matrix(method=how, sym=sym, batch_size=batch_size, verbose=verbose)
        if save:
            if cache_file is None:
                raise ValueError("No path specified")
            _os.makedirs(_os.path.dirname(cache_file), exist_ok=True)
            np.save(cache_file, D)
        return D

    def _geod_cache_file(self) -> Optional[str]:
        if self.path is None or self.name is None:
            return None
        suffix = "_n" if self.is_normalized else ("_mod" if self.is_modified else "")
        return _os.path.join(_os.path.dirname(self.path), "geod_cache", f"{self.name}{suffix}.npy")

    # sampling ---------------------------------------------------------------------------------
    def farthest_point_sampling(self, size: int, random_init: bool = True, geodesic: bool = True, distances=None, verbose: bool = False, no_load: bool = False) -> np.ndarray:
        """``size`` farthest-point samples (indices): by geodesic (heat method) or Euclidean
        distances, or from a given distance matrix; the first sample at random when
        ``random_init`` (as pyFM), else vertex 0 (the farthest from all the others with
        ``distances``)."""
        n = self.n_vertices
        size = min(int(size), n)
        if distances is not None:
            D = np.asarray(distances)

            def dist(i):
                return D[i]

            first = int(np.random.randint(n)) if random_init else int(np.argmax(D.sum(1)))
        else:
            if geodesic:

                def dist(i):
                    return self.geodesic_from(i)

            else:

                def dist(i):
                    return np.linalg.norm(self._vertices - self._vertices[i], axis=1)

            first = int(np.random.randint(n)) if random_init else 0
        chosen = [first]
        d = dist(first)
        for _ in range(1, size):
            j = int(np.argmax(d))
            chosen.append(j)
            d = np.minimum(d, dist(j))
        return np.array(chosen, dtype=np.int64)

    def extract_fps(self, size, random_init: bool = True, geodesic: bool = True, no_load: bool = False, verbose: bool = False):
        return self.farthest_point_sampling(size, random_init=random_init, geodesic=geodesic, verbose=verbose)

    def farthest_point_sampling_sub(self, size, sub_points, return_sub_inds: bool = False, random_init: bool = True, geodesic: bool = True, distances=None, verbose: bool = False):
        """Farthest-point sampling among ``sub_points`` (indices of this mesh)."""
        sub = np.asarray(sub_points, dtype=np.int64)
        size = min(int(size), len(sub))
        if distances is not None:
            D = np.asarray(distances)[np.ix_(sub, sub)]

            def dist(j):
                return D[j]

        else:

            def dist(j):
                if geodesic:
                    return self.geodesic_from(int(sub[j]))[sub]
                return np.linalg.norm(self._vertices[sub] - self._vertices[sub[j]], axis=1)

        first = int(np.random.randint(len(sub))) if random_init else 0
        chosen = [first]
        d = dist(first)
        for _ in range(1, size):
            j = int(np.argmax(d))
            chosen.append(j)
            d = np.minimum(d, dist(j))
        fps_sub = np.array(chosen, dtype=np.int64)
        return (sub[fps_sub], fps_sub) if return_sub_inds else sub[fps_sub]

    extract_fps_sub = farthest_point_sampling_sub

    # differential operators -------------------------------------------------------------------
    def _corner_gradients(self):
        """Per face, the gradient directions n × e_c / 2 of the three hat functions (unscaled by
        the face area), and the face areas."""
        self._require_faces("gradients")
        V, F = self._vertices, self._faces
        n = self.face_normals
        v1, v2, v3 = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
        g = (np.cross(n, v3 - v2) / 2, np.cross(n, v1 - v3) / 2, np.cross(n, v2 - v1) / 2)
        return g, self.face_areas

    def gradient(self, f, normalize: bool = False) -> np.ndarray:
        """Per-face gradient of a function on the vertices: f (n,) → (m, 3), or (n, p) →
        (m, p, 3) (linear interpolation; unit vectors with ``normalize``)."""
        (g1, g2, g3), area = self._corner_gradients()
        F = self._faces
        f = np.asarray(f, dtype=float)
        scale = 1.0 / area[:, None]
        if f.ndim == 1:
            grad = (f[F[:, 0], None] * g1 + f[F[:, 1], None] * g2 + f[F[:, 2], None] * g3) * scale
        else:
            grad = (
                f[F[:, 0]][:, :, None] * g1[:, None, :]
                + f[F[:, 1]][:, :, None] * g2[:, None, :]
                + f[F[:, 2]][:, :, None] * g3[:, None, :]
            ) * scale[:, :, None]
        if normalize:
            grad = grad / np.linalg.norm(grad, axis=-1, keepdims=True)
        return grad

    def divergence(self, f) -> np.ndarray:
        """Per-vertex divergence of a per-face vector field: (m, 3) → (n,), (m, p, 3) → (n, p):
        Σ over the faces around vertex i of area · ∇φ_i · X, over the vertex area."""
        (g1, g2, g3), _ = self._corner_gradients()
        F = self._faces
        X = np.asarray(f, dtype=float)
        a = self.vertex_areas
        if X.ndim == 2:
            out = np.zeros(self.n_vertices)
            for c, g in enumerate((g1, g2, g3)):
                np.add.at(out, F[:, c], np.einsum("ij,ij->i", g, X))
            return out / a
        out = np.zeros((self.n_vertices, X.shape[1]))
        for c, g in enumerate((g1, g2, g3)):
            np.add.at(out, F[:, c], np.einsum("ij,ipj->ip", g, X))
        return out / a[:, None]

    # normals and edges ------------------------------------------------------------------------
    def compute_normals(self) -> np.ndarray:
        self._require_faces("face normals")
        V, F = self._vertices, self._faces
        n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        self._face_normals = n / np.linalg.norm(n, axis=1, keepdims=True)
        return self._face_normals

    def compute_vertex_normals(self) -> np.ndarray:
        self._require_faces("vertex normals")
        V, F = self._vertices, self._faces
        n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        if self._vertex_normals_weighting == "uniform":
            n = n / np.linalg.norm(n, axis=1, keepdims=True)
        out = np.zeros_like(V)
        for c in range(3):
            np.add.at(out, F[:, c], n)
        self._vertex_normals = out / np.linalg.norm(out, axis=1, keepdims=True)
        return self._vertex_normals

    def compute_edges(self) -> np.ndarray:
        self._require_faces("edges")
        F = self._faces
        e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        self._edges = np.unique(e, axis=0)
        return self._edges

    def set_vertex_normal_weighting(self, weight_type: str):
        """``"area"`` (default) or ``"uniform"`` weights of the face normals in ``vertex_normals``."""
        weight_type = weight_type.lower()
        if weight_type not in ("area", "uniform"):
            raise ValueError(f"weight_type: expected 'area' or 'uniform', got {weight_type!r}")
        if weight_type != self._vertex_normals_weighting:
            self._vertex_normals_weighting = weight_type
            self._vertex_normals = None

    # files ------------------------------------------------------------------------------------
    def save(self, path, precision: Optional[int] = None, face_colors=None, vertex_normals=None, uv=None, texture=None, mtl_file: str = "material.mtl", verbose: bool = False) -> "TriMesh":
        """Writes the mesh as ``.off`` (default), ``.obj`` (with ``uv`` (n, 2) coordinates and a
        ``texture`` image: an ``.mtl`` beside it) or ``.ply``. ``precision`` (significant digits)
        and ``face_colors`` are pyFM's options for ``.off``."""
        path = _os.fspath(path)
        ext = _os.path.splitext(path)[1].lower()
        if ext == "":
            path, ext = path + ".off", ".off"
        if vertex_normals is True:
            vertex_normals = self.vertex_normals
        elif vertex_normals is False:
            vertex_normals = None
        if ext == ".obj":
            if face_colors is not None:
                raise ValueError("The .obj format cannot store face colors, use .off instead")
            _write_obj(path, self._vertices, self._faces, uv, vertex_normals, texture, mtl_file, precision)
            return self
        if ext not in (".off", ".ply"):
            raise ValueError(f"Cannot write {ext!r} files. Supported formats: .off, .obj, .ply")
        if uv is not None or vertex_normals is not None:
            raise ValueError(f"The {ext} format cannot store uv coordinates or vertex normals, use .obj instead")
        if precision is not None or face_colors is not None:
            _write_off(path, self._vertices, self._faces, precision, face_colors)
            return self
        _fc.write_mesh(path, self._vertices, self._faces)
        return self

    export = save

    def get_uv(self, ind1: int, ind2: int, mult_const: float, rotation=None) -> np.ndarray:
        """(n, 2) texture coordinates: coordinates ``ind1``, ``ind2`` of the (rotated) vertices,
        scaled to [0, 1] and repeated ``mult_const`` times (pyFM's rule)."""
        vert = self._vertices if rotation is None else self._vertices @ np.asarray(rotation).T
        uv = vert[:, [ind1, ind2]]
        lo = uv.min(0)
        span = (uv.max(0) - lo).max()
        return mult_const * (uv - lo) / span

    def export_texture(self, filename, uv, mtl_file: str = "material.mtl", texture_im: str = "texture_1.jpg", precision: Optional[int] = None, verbose: bool = False) -> "TriMesh":
        """Writes ``filename`` (.obj added) with ``uv`` coordinates and an ``.mtl`` naming the
        texture image ``texture_im`` (pyFM copies its bundled textures beside the file; here the
        image is named as given, and a warning says so if it is not there)."""
        filename = _os.fspath(filename)
        if _os.path.splitext(filename)[1] != ".obj":
            filename += ".obj"
        return self.save(filename, uv=uv, texture=texture_im, mtl_file=mtl_file, precision=precision, verbose=verbose)


def _same_basis(P, mesh) -> bool:
    ev = mesh.eigenvectors
    pe = P.eigenvectors
    return ev.shape[0] == pe.shape[0] and ev.shape[1] <= pe.shape[1] and (ev is pe or np.shares_memory(ev, pe) or np.array_equal(ev, pe[:, : ev.shape[1]]))


def _diag(a):
    import scipy.sparse as sp

    return sp.diags(a)


def _read(path):
    V, F = _fc.read_mesh(path)
    return V, (F if len(F) else None)


def _fmt(x, precision):
    return f"{x:.{precision}g}" if precision is not None else repr(float(x))


def _write_off(path, V, F, precision, face_colors):
    lines = ["OFF", f"{len(V)} {0 if F is None else len(F)} 0"]
    lines += [" ".join(_fmt(c, precision) for c in v) for v in V]
    if F is not None:
        for i, f in enumerate(F):
            row = f"3 {f[0]} {f[1]} {f[2]}"
            if face_colors is not None:
                row += " " + " ".join(str(int(c)) for c in np.asarray(face_colors)[i])
            lines.append(row)
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")


def _write_obj(path, V, F, uv, normals, texture, mtl_file, precision):
    lines = []
    if texture is not None:
        if uv is None:
            raise ValueError("uv coordinates are required to write a texture")
        mtl_path = mtl_file if _os.path.isabs(mtl_file) else _os.path.join(_os.path.dirname(_os.path.abspath(path)), mtl_file)
        with open(mtl_path, "w") as fh:
            fh.write(f"newmtl material_0\nKa 0.2 0.2 0.2\nKd 1 1 1\nKs 1 1 1\nillum 2\nmap_Kd {_os.path.basename(texture)}\n")
        if not _os.path.isfile(_os.path.join(_os.path.dirname(mtl_path), _os.path.basename(texture))):
            warn_once(
                "texture-image",
                f"export_texture: the .mtl names {_os.path.basename(texture)!r}; funcorr does not ship pyFM's texture "
                "images, put the image beside the .obj",
            )
        lines += [f"mtllib {_os.path.basename(mtl_path)}", "usemtl material_0"]
    lines += ["v " + " ".join(_fmt(c, precision) for c in v) for v in V]
    if uv is not None:
        lines += ["vt " + " ".join(_fmt(c, precision) for c in t) for t in np.asarray(uv)]
    if normals is not None:
        lines += ["vn " + " ".join(_fmt(c, precision) for c in t) for t in np.asarray(normals)]
    if F is not None:
        for f in F + 1:
            if uv is not None and normals is not None:
                lines.append("f " + " ".join(f"{i}/{i}/{i}" for i in f))
            elif uv is not None:
                lines.append("f " + " ".join(f"{i}/{i}" for i in f))
            elif normals is not None:
                lines.append("f " + " ".join(f"{i}//{i}" for i in f))
            else:
                lines.append(f"f {f[0]} {f[1]} {f[2]}")
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
