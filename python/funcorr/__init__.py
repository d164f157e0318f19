"""funcorr: dense shape correspondence with functional maps, from Python.

Bindings of the funcorr Rust library (the same code as the ``funcorr`` command-line tool).
Notation follows Kovnatsky et al. (CVPR 2015): the source shape X has n vertices, the target Y
has m; Φ (n × k) and Ψ (m × k) are their Laplacian eigenbases with Φᵀ diag(A_X) Φ = I.

Direction conventions (the same everywhere in funcorr):

* ``map_xy`` has length n: ``map_xy[i]`` is the vertex of Y matched to vertex i of X (the
  ``map.txt`` of ``funcorr match``); ``map_yx`` has length m, the other way.
* A functional map ``C`` (k_Y × k_X) maps coefficients of a function on X to coefficients on Y:
  ``g ≈ Ψ C Φᵀ diag(A_X) f``.

Shapes are given as a file path, a tuple ``(V, F)`` (V (n, 3) any float dtype, F (f, 3) int32 or
int64, 0-based, any memory order; F = None for a point cloud), an (n, d) array of points, or a
:class:`PreparedShape` (shape + Laplacian + eigenbasis, computed once by :func:`prepare`).

Units: eigenvalues, eigenvectors, vertex weights and functional maps are in the shapes' own
units (as :func:`cotangent_laplacian` gives them; ``C[0, 0] = ±√(area_Y / area_X)``), whatever
the library computes internally (each prepared shape scaled to unit area, so that the maps
between two shapes do not depend on their units).

Every computation releases the GIL and runs on its own rayon pool of
``set_num_threads(n)`` / ``$FUNCORR_NUM_THREADS`` threads (default: every core), so Python
threads and Ray workers run in parallel without oversubscribing the machine. Ctrl-C stops any
call within a fraction of a second (KeyboardInterrupt; nothing half-written is left, and the
process goes on normally). The long calls (:func:`match`, :func:`prepare`,
:func:`geodesic_all_pairs`, :func:`funcorr.batch.match_pairs`) show a progress bar when run in a
terminal or a notebook (``progress=``; ``$FUNCORR_PROGRESS=0`` for none).
"""

from __future__ import annotations

# The namespace holds the API only (``dir(funcorr)``): helpers are imported under private names,
# typing names only for the type checker (annotations are strings here).
import json as _json
from dataclasses import dataclass as _dataclass
from typing import TYPE_CHECKING as _TYPE_CHECKING

import numpy as _np

from . import _funcorr
from ._progress import reporting as _reporting
from ._funcorr import PreparedShape, get_num_threads

if _TYPE_CHECKING:
    from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

    ShapeLike = Any  # path | (V, F) | (n, d) array | PreparedShape
    BasisLike = Any  # PreparedShape | (eigenvalues, eigenvectors, mass)

__version__ = _funcorr.__version__

__all__ = [
    "PreparedShape",
    "MatchResult",
    "read_mesh",
    "write_mesh",
    "read_vts",
    "cotangent_laplacian",
    "intrinsic_laplacian",
    "knn_laplacian",
    "cloud_laplacian",
    "stiffness",
    "prepare",
    "eigenbasis",
    "hks",
    "wks",
    "wks_recipe",
    "hkm",
    "persistence_segments",
    "regions",
    "match",
    "icp_refine",
    "zoomout_refine",
    "maps_from_fmap",
    "nearest_rows",
    "soft_map",
    "fmap_from_map",
    "axiomatic_fmap",
    "geodesic_distances",
    "geodesic_pairs",
    "geodesic_all_pairs",
    "evaluate",
    "cumulative_curve",
    "render_pair",
    "render",
    "view",
    "Viewer",
    "set_num_threads",
    "get_num_threads",
]

_threads_setting = None  # the last set_num_threads argument (funcorr.batch restores it)


def set_num_threads(n: Optional[int] = None) -> None:
    """Threads each funcorr call uses (None or 0: every core, or ``$FUNCORR_NUM_THREADS`` when
    set). Each call runs on a rayon pool of that many threads of its own, with the GIL
    released, so k Python threads calling funcorr at once use k · n threads. A negative or
    non-integer ``n`` raises ValueError."""
    global _threads_setting
    _funcorr.set_num_threads(n)
    _threads_setting = n


def read_mesh(path) -> Tuple[_np.ndarray, _np.ndarray]:
    """Reads a mesh or point cloud (OFF, OBJ, PLY, XYZ/CSV/TXT/PTS, NPY).

    Returns ``(V, F)``: V (n, 3) float64, F (f, 3) int64, 0-based ((0, 3) for point clouds).
    Malformed files raise ValueError naming the file and line; missing ones FileNotFoundError.
    """
    return _funcorr.read_mesh(path)


def write_mesh(path, V, F=None, colors=None) -> None:
    """Writes V (n, 3), F (f, 3) and optional colours (n, 3) uint8 as OFF, PLY or NPY (by
    extension), atomically (a temporary file renamed into place)."""
    _funcorr.write_mesh(path, V, F, colors)


def read_vts(path, n: Optional[int] = None) -> _np.ndarray:
    """Reads a 1-based vertex list (.vts, one id per line) as 0-based int64 indices, each < n
    when n is given."""
    return _funcorr.read_vts(path, n)


def _csr(parts, n: int):
    import scipy.sparse as sp

    indptr, indices, data = parts
    return sp.csr_matrix((data, indices, indptr), shape=(n, n))


def cotangent_laplacian(V, F):
    """Cotangent Laplacian of a triangle mesh (paper eq. (2)), intrinsically mollified for
    degenerate triangles.

    Returns ``(W, A)``: W (n × n scipy.sparse.csr_matrix, symmetric positive semi-definite,
    zero row sums) and A (n,) the lumped (barycentric) vertex areas; L = diag(A)⁻¹ W.
    """
    parts, mass = _funcorr.cotangent_laplacian(V, F)
    return _csr(parts, len(mass)), mass


def intrinsic_laplacian(V, F):
    """The intrinsic Delaunay Laplacian of a triangle mesh: the cotangent Laplacian of the same
    surface re-triangulated by intrinsic edge flips (non-negative weights on meshes with obtuse
    or sliver triangles; the cotangent Laplacian itself on Delaunay meshes). Returns ``(W csr
    (n × n), A (n,))`` as :func:`cotangent_laplacian`."""
    parts, mass = _funcorr.intrinsic_laplacian(V, F)
    return _csr(parts, len(mass)), mass


def nearest_rows(reference, query) -> _np.ndarray:
    """For every row of ``query`` (q, d) the index of the nearest row of ``reference`` (r, d)
    (Euclidean): (q,) int64. The search that turns spectral embeddings into point maps."""
    return _funcorr.nearest_rows(reference, query)


def knn_laplacian(points, k: int = 10, sigma: Optional[float] = None, vertex_weights: str = "identity"):
    """The paper's kNN graph Laplacian (eq. (1)) of points (n, d): symmetric K nearest
    neighbours, Gaussian weights with self-tuning σ (or fixed ``sigma``), A = I
    (``vertex_weights="identity"``) or A = D (``"degree"``). Returns ``(W csr, A)``."""
    parts, mass = _funcorr.knn_laplacian(points, k, sigma, vertex_weights)
    return _csr(parts, len(mass)), mass


def cloud_laplacian(points, k: int = 30):
    """The point-cloud Laplacian (Sharp & Crane 2020) of 3-D points (n, 3) from local
    Delaunay fans over k neighbours. Returns ``(W csr, A)``."""
    parts, mass = _funcorr.cloud_laplacian(points, k)
    return _csr(parts, len(mass)), mass


def stiffness(shape: PreparedShape):
    """The stiffness matrix W (n × n csr) of a prepared shape's Laplacian."""
    return _csr(shape._stiffness(), shape.n)


def prepare(shape: ShapeLike, k: int = 200, cache_dir=None, progress=None, **laplacian) -> PreparedShape:
    """A shape with its Laplacian and first k eigenpairs, computed once for many pairs.

    ``shape``: a path, ``(V, F)``, ``(V, None)`` / an (n, d) array of points.
    ``laplacian``: ``laplacian="auto"|"cotan"|"intrinsic"|"cloud"|"knn"`` (auto: cotangent for
    meshes — on the geometry smoothed by one implicit step when the mesh is rough with noise,
    reported by ``.denoised``; ``"cotan"`` takes the mesh as it is —, the point-cloud Laplacian
    for 3-D points, kNN for other dimensions; ``"intrinsic"``:
    the cotangent Laplacian of the mesh's intrinsic Delaunay triangulation, for meshes with
    obtuse or sliver triangles — the cotangent Laplacian itself on Delaunay meshes),
    ``cloud_neighbours=30``, ``knn=10``, ``vertex_weights="identity"|"degree"``, ``sigma=None``.
    ``cache_dir``: a directory (or True for ``$FUNCORR_CACHE_DIR`` / ``~/.cache/funcorr``) where
    eigenbases are cached, keyed by the Laplacian; None (default): no cache. ``progress``: None
    (a bar in a terminal or a notebook), True, False, or a callable ``(stage, done, total)``
    (module ``funcorr._progress``). Ctrl-C stops the call (KeyboardInterrupt).

    The result has ``.eigenvalues`` (k,), ``.eigenvectors`` Φ (n, k), ``.mass`` A (n,) (in the
    shape's units: Φᵀ diag(A) Φ = I, Σ A = ``.area``), ``.vertices``, ``.faces``, ``.n``, ``.k``,
    ``.denoised`` (None, or what the smoothing of a noisy mesh did); it pickles (for Ray's
    object store).
    """
    with _reporting(progress, "funcorr.prepare") as report:
        return _funcorr.prepare(shape, k, cache_dir, report, **laplacian)


def eigenbasis(V, F=None, k: int = 100, **options) -> Tuple[_np.ndarray, _np.ndarray, _np.ndarray]:
    """First k eigenpairs of W φ = λ A φ (shift-invert block Lanczos, verified residuals,
    deterministic signs). V (n, 3) (or (n, d) points with F = None), F (f, 3).

    Returns ``(evals (k,), evecs Φ (n, k), mass A (n,))`` with Φᵀ diag(A) Φ = I. Options as
    :func:`prepare`."""
    p = prepare((V, F), k=k, **options)
    return p.eigenvalues, p.eigenvectors, p.mass


def hks(basis: BasisLike, count: int = 100, times=None, normalize: bool = True) -> _np.ndarray:
    """Heat kernel signatures (n, q): ``count`` times log-spaced as Sun et al. (or ``times``),
    scale-normalized. ``basis``: a PreparedShape or (eigenvalues, eigenvectors, mass)."""
    return _funcorr.hks(basis, count, times, normalize)


def wks(basis: BasisLike, count: int = 100, normalize: bool = True) -> _np.ndarray:
    """Wave kernel signatures (n, count) from the whole basis, scale-normalized."""
    return _funcorr.wks(basis, count, normalize)


def wks_recipe(basis: BasisLike, energies: int = 100, eigenpairs: int = 128, keep_every: int = 2) -> _np.ndarray:
    """The WKS of ``match``'s default data: ``energies`` energies from the first ``eigenpairs``
    eigenpairs, every ``keep_every``-th kept (pyFM's pipeline; 50 functions by default)."""
    return _funcorr.wks_recipe(basis, energies, eigenpairs, keep_every)


def hkm(basis: BasisLike, seeds, count: int = 10, times=None, normalize: bool = True) -> _np.ndarray:
    """Heat kernel maps k_t(p, ·) (n, len(seeds) · times), seed-major, for seed vertices p."""
    return _funcorr.hkm(basis, seeds, count, times, normalize)


def persistence_segments(shape: PreparedShape, **options) -> _np.ndarray:
    """Persistence-based segmentation of a prepared shape: labels 1..s (n,) int64. Options:
    ``seg_function="hks"|"agd"``, ``threshold=0.1``, ``hks_time=0.25``."""
    return _funcorr.persistence_segments(shape, **options)


def regions(X: PreparedShape, Y: PreparedShape, kind: str = "persistence", labels_x=None, labels_y=None, **options):
    """Matched regions of two prepared shapes as indicator functions: ``(F (n, q), G (m, q))``,
    column j of F and G the same region. ``kind``: ``"persistence"`` (segments matched by their
    signatures), ``"mser"`` (ShapeMSER, meshes), ``"labels"`` (``labels_x``, ``labels_y``
    per-vertex labels, matched by value)."""
    return _funcorr.regions(X, Y, kind, labels_x, labels_y, **options)


@_dataclass(repr=False)
class MatchResult:
    """The result of :func:`match`.

    ``map_xy`` (n,) int64: for every vertex i of X the vertex of Y (``map.txt`` of
    ``funcorr match``). ``map_yx`` (m,): for every vertex of Y a vertex of X (the pull-back of
    the final functional map; used to transfer colours from X to Y). ``C`` (k_Y × k_X): the
    final functional map, X coefficients → Y coefficients (between the shapes' own bases);
    ``C_method`` the method's own before refinement; ``coefficients`` (A, B) of the completion
    method's subspace form (k' × k), else None. ``X``, ``Y``: the prepared shapes (reusable).
    ``report``: options, sizes, solver and per-stage seconds (the report.json of
    ``funcorr match``; ``report["partial"]`` the partial detection; with landmarks
    ``report["landmark_check"]``: per landmark the median relative difference of its geodesic
    distances to the others on X and on Y, and the ``suspects`` that disagree with the others,
    which are used as given). ``coverage`` (m,) float64:
    when X was matched as a part of Y, for every vertex of Y the confidence in [0, 1] that X
    covers it (≥ ½: covered; ``coverage.npy`` of ``funcorr match``), else None.
    ``evaluation``: the last :meth:`evaluate`'s result (None before).
    """

    map_xy: _np.ndarray
    map_yx: _np.ndarray
    C: _np.ndarray
    C_method: _np.ndarray
    coefficients: Optional[Tuple[_np.ndarray, _np.ndarray]]
    stages: List[Tuple[str, float]]
    report: Dict[str, Any]
    q: int
    X: PreparedShape
    Y: PreparedShape
    coverage: Optional[_np.ndarray] = None
    evaluation: Optional[Dict[str, Any]] = None

    def __repr__(self) -> str:
        method = self.report.get("options", {}).get("method", "?") if isinstance(self.report, dict) else "?"
        seconds = sum(t for _, t in self.stages)
        text = (
            f"MatchResult(method={method!r}, n={len(self.map_xy)}, m={len(self.map_yx)}, "
            f"C {self.C.shape[0]}×{self.C.shape[1]}, q={self.q}, {seconds:.1f} s"
        )
        if self.evaluation is not None:
            text += f", mean error ×100 {100 * self.evaluation['mean']:.2f}"
        return text + ")"

    def evaluate(self, gt_x, gt_y, gt_y_sym=None, geodesics: str = "exact") -> Dict[str, Any]:
        """Geodesic errors of ``map_xy`` against ground truth (see :func:`evaluate`); kept as
        ``evaluation`` (and shown by ``repr``)."""
        self.evaluation = evaluate(self.map_xy, self.Y, gt_x, gt_y, gt_y_sym, geodesics)
        return self.evaluation

    def render(self, width: int = 1600, height: int = 900, view: Tuple[float, float] = (0.0, 0.0)) -> _np.ndarray:
        """X coloured by position beside Y coloured through ``map_yx``: (h, w, 3) uint8."""
        return render_pair(self.X, self.Y, self.map_yx, width, height, view)

    def show(self, gt=None, soft: Sequence[int] = (), geodesics: str = "exact", height: int = 620, **options) -> "Viewer":
        """The interactive viewer of the map (the ``view.html`` of ``funcorr match``): X and Y
        side by side, colour transfer, a click on a vertex marks its image. Displays inline in
        Jupyter and VS Code notebooks; ``.save(path)`` writes the page.

        ``gt``: ``(gt_x, gt_y)`` or ``(gt_x, gt_y, gt_y_sym)`` (0-based template points, e.g.
        from :func:`read_vts`) to colour X by the geodesic error of ``map_xy``. ``soft``:
        vertices i of X whose soft maps T δ_i (from ``C_method``) are offered as colourings of Y.
        Other options as :func:`view` (``title``, ``error_max``, ``fields``, ...)."""
        fields = dict(options.pop("fields", None) or {})
        for i in soft:
            fields[f"soft map T δ_{int(i)} on Y"] = ("y", soft_map(self.X, self.Y, self.C_method, int(i)), int(i))
        opts = self.report.get("options", {})
        method = options.pop("method", None) or f"method {opts.get('method', '?')}"
        return view(self.X, self.Y, self.map_xy, self.map_yx, gt=gt, fields=fields, method=method, geodesics=geodesics, height=height, **options)

    def _repr_html_(self) -> str:
        """The viewer, inline in a notebook (see :meth:`show`)."""
        return self.show()._repr_html_()


class Viewer:
    """An interactive viewer page (self-contained HTML written by funcorr's library, three.js
    inlined, nothing fetched from the network).

    In a Jupyter or VS Code notebook it displays inline (an ``<iframe srcdoc>``, no widget
    server). ``html`` is the page; ``save(path)`` writes it (open it in any browser).
    """

    def __init__(self, html: str, height: int = 620):
        self.html = html
        self.height = int(height)

    def save(self, path) -> None:
        """Writes the page to ``path`` (e.g. ``"view.html"``)."""
        with open(path, "w", encoding="utf-8") as f:
            f.write(self.html)

    def _repr_html_(self) -> str:
        import html as _html

        return (
            f'<iframe srcdoc="{_html.escape(self.html, quote=True)}" '
            f'style="width:100%;height:{self.height}px;border:1px solid #ddd" '
            'sandbox="allow-scripts allow-downloads" title="funcorr viewer"></iframe>'
        )

    def __repr__(self) -> str:
        return f"<funcorr.Viewer: {len(self.html) / 1e6:.1f} MB page; display it in a notebook or .save('view.html')>"


def _colors(c, n: int, name: str):
    """(n, 3) colours as uint8: uint8 as is, floats in [0, 1] (pyFM's colour maps) scaled."""
    if c is None:
        return None
    a = _np.asarray(c)
    if a.ndim != 2 or a.shape != (n, 3):
        raise ValueError(f"{name}: expected shape ({n}, 3), got {a.shape}")
    if a.dtype == _np.uint8:
        return _np.ascontiguousarray(a)
    if _np.issubdtype(a.dtype, _np.floating):
        return _np.ascontiguousarray(_np.clip(_np.round(255 * a), 0, 255).astype(_np.uint8))
    return _np.ascontiguousarray(_np.clip(a, 0, 255).astype(_np.uint8))


def _name(shape, default: str) -> str:
    from pathlib import Path

    if isinstance(shape, (str, Path)):
        return Path(shape).stem
    return default


def _vertex_count(shape) -> int:
    if isinstance(shape, PreparedShape):
        return shape.n
    return _n_vertices(shape)


def view(
    X: ShapeLike,
    Y: Optional[ShapeLike] = None,
    map_xy=None,
    map_yx=None,
    *,
    gt=None,
    fields: Optional[Dict[str, Any]] = None,
    colors_x=None,
    colors_y=None,
    title: Optional[str] = None,
    method: Optional[str] = None,
    geodesics: str = "exact",
    error_max: float = 0.25,
    start: Optional[str] = None,
    height: int = 620,
) -> Viewer:
    """The interactive viewer of any map X → Y (also pyFM's: ``map_xy = p2p_12``,
    ``map_yx = p2p_21``), or of one shape (``Y=None``): the page of ``funcorr view``.

    ``X``, ``Y``: paths, ``(V, F)``, point arrays or PreparedShapes. ``map_xy`` (n,): for every
    vertex of X a vertex of Y; ``map_yx`` (m,): the other way (colours Y as the PLY files of
    ``funcorr match`` and lets a click on Y show its image; without it Y takes the colour of the
    vertex of X whose image is nearest). ``gt``: ``(gt_x, gt_y[, gt_y_sym])`` 0-based template
    points: X coloured by the geodesic error of ``map_xy`` (``geodesics``: ``"exact"``,
    ``"heat"``, ``"dijkstra"``; colour bar up to ``error_max``). ``fields``: ``{name: (side,
    values)}`` or ``{name: (side, values, mark)}`` with side ``"x"`` or ``"y"``, values one per
    vertex of that shape (a descriptor channel, a soft map), ``mark`` a vertex of the other
    shape to mark. ``colors_x``/``colors_y``: (n, 3) colours (uint8, or floats in [0, 1]) instead
    of the colouring by position. ``start``: the colouring shown first (``"error"`` or a field's
    name; default the colour transfer).

    Returns a :class:`Viewer` (displays inline in notebooks; ``.save(path)``, ``.html``).
    """
    n = _vertex_count(X)
    m = _vertex_count(Y) if Y is not None else 0
    field_list = []
    for name, spec in (fields or {}).items():
        side, values, *rest = spec
        field_list.append((str(name), str(side), _np.asarray(values, dtype=_np.float64).ravel(), int(rest[0]) if rest and rest[0] is not None else None))
    gt_x = gt_y = gt_y_sym = None
    if gt is not None:
        gt_x, gt_y, *rest = gt
        gt_y_sym = rest[0] if rest else None
    xn, yn = _name(X, "X"), _name(Y, "Y")
    html = _funcorr.viewer_html(
        X,
        Y,
        None if map_xy is None else _np.asarray(map_xy),
        None if map_yx is None else _np.asarray(map_yx),
        _colors(colors_x, n, "colors_x"),
        _colors(colors_y, m, "colors_y") if Y is not None else None,
        None if gt_x is None else _np.asarray(gt_x),
        None if gt_y is None else _np.asarray(gt_y),
        None if gt_y_sym is None else _np.asarray(gt_y_sym),
        geodesics,
        error_max,
        field_list,
        title or (f"{xn} → {yn}" if Y is not None else xn),
        method,
        xn,
        yn,
        start,
    )
    return Viewer(html, height)


def match(X: ShapeLike, Y: ShapeLike, method: str = "axiomatic", data: Union[str, Tuple[Any, Any]] = "wks", progress=None, **options) -> MatchResult:
    """Dense correspondence X → Y: the pipeline of ``funcorr match`` (same defaults, same map).

    ``X``, ``Y``: paths, ``(V, F)`` tuples, point arrays or PreparedShapes (a raw shape is
    prepared with the eigenpairs the options need, 200 by default, no cache unless
    ``cache_dir=``). ``method``: ``"axiomatic"`` (default), ``"fmap"`` (eq. (5)),
    ``"pokrass"`` (eq. (6)), ``"coupled"`` (eq. (7)), ``"completion"`` (eqs. (8)–(11), see
    ``form``). ``data``: a ``--data`` spec (``"wks"``, ``"wks:100"``, ``"hks:N"``,
    ``"segments:X.seg,Y.seg"``, ``"persistence"``, ``"mser"``, ``"landmarks:pairs.txt"``,
    ``"rich"``, ``"matrix:F.npy,G.npy"``) or a tuple ``(F (n, q), G (m, q))``.

    ``options`` are the flags of ``funcorr match`` with ``_`` for ``-`` (the library's table of
    options, ``_funcorr.match_option_keys()``, with its defaults and checks): ``k``, ``kprime``,
    ``candidates``, ``orientation`` (``"preserve"|"reverse"|"ignore"``), ``signed``,
    ``w_descriptors``, ``w_laplacian``, ``w_commutativity``, ``w_orientation``, ``mask``,
    ``refine`` (``"none"|"icp"|"zoomout"``), ``zoomout_to``, ``zoomout_step``,
    ``zoomout_samples``, ``polish``, ``commutativity``, ``form``
    (``"subspace"|"fixed-rank"|"low-rank"|"low-norm"``), ``scaling``, ``mu1``, ``mu2``, ``mu3``,
    ``mu4``, ``xi``,
    ``init``, ``init_k``, ``optimizer``, ``max_iterations``, ``rel_tol``, ``extract``,
    ``refine_k``, ``icp_iterations``, ``completion_commutativity``,
    ``completion_commutativity_k``, ``completion_prior``, ``l1_samples``, ``l1_precision``
    (``"f32"|"f64"``; ``l1_f32`` True is the same as ``"f32"``),
    ``map_check_every``, ``map_tolerance``, ``precondition`` (``"off"|"quadratic"|"full"``),
    ``xi_stages``, ``multiscale``, ``near_above``, ``near_cells``, ``near_inverse_above``, ``near_certified_up_to``,
    ``near_inverse_certified_up_to``;
    ``partial`` (True: ``--partial``, X is a part of Y; False: ``--no-partial``; None, the
    default: detected); ``partial_ratio`` (the share of Y's area that the part X covers, in
    (0, 1.5], when known; implies ``partial=True``; default: estimated from the heat kernels);
    the Laplacian options of
    :func:`prepare`; ``seg_function``, ``threshold``, ``hks_time``; ``cache_dir``. An unknown
    keyword raises TypeError; a bad value ValueError naming it.

    ``landmarks``: known corresponding points for the default method, a (k, 2) integer array of
    0-based pairs ``(vertex of X, vertex of Y)`` or the path of a file of such pairs (``i j`` per
    line, as ``funcorr match --landmarks``). They join the fits' data, the choice among the
    candidates and every refinement step (``map_xy[i] == j`` for every pair): for pairs no
    intrinsic method can decide (non-isometric or strongly symmetric shapes). On a part X of Y
    (the partial path) they choose among the candidates and are pinned in the final map. A
    landmark that disagrees with the others is named in ``report["landmark_check"]["suspects"]``
    and by a ``UserWarning``, and used as given.

    ``progress``: None (default: a bar on stderr in a terminal, a notebook-friendly one in
    Jupyter, nothing when stderr is a file or a pipe; ``$FUNCORR_PROGRESS=0`` turns it off),
    True, False, or a callable ``(stage, done, total)`` (module ``funcorr._progress``). Ctrl-C
    stops the call within a fraction of a second with KeyboardInterrupt.

    Returns a :class:`MatchResult`; ``result.map_xy[i]`` is the vertex of Y matched to vertex i
    of X.
    """
    opts = dict(options)
    opts["method"] = method
    with _reporting(progress, "funcorr.match") as report:
        r = _funcorr.match_shapes(X, Y, data, opts, report)
    run_report = _json.loads(r["report"])
    _warn_landmarks(run_report)
    return MatchResult(
        map_xy=r["map_xy"],
        map_yx=r["map_yx"],
        C=r["C"],
        C_method=r["C_method"],
        coefficients=r["coefficients"],
        stages=list(r["stages"]),
        report=run_report,
        q=r["q"],
        X=r["X"],
        Y=r["Y"],
        coverage=r["coverage"],
    )


def _warn_landmarks(report: Dict[str, Any]) -> None:
    """A UserWarning naming the landmarks that disagree with the others
    (``report["landmark_check"]``, as ``funcorr match`` says on stderr); they were used as given."""
    check = report.get("landmark_check") or {}
    suspects = check.get("suspects") or []
    if not suspects:
        return
    import warnings

    d = check["discrepancy"]
    listed = ", ".join(f"pair {i + 1}: {100 * d[i]:.0f} %" for i in suspects)
    warnings.warn(
        "landmarks that disagree with the others (the median relative difference of their geodesic "
        f"distances to the other landmarks on X and on Y): {listed}; they were used as given - check that "
        "each is the right point (report['landmark_check'])",
        UserWarning,
        stacklevel=3,
    )


def icp_refine(X: PreparedShape, Y: PreparedShape, C, iterations: int = 10) -> Tuple[_np.ndarray, _np.ndarray]:
    """ICP refinement (Ovsjanikov et al. 2012) of C (k_Y × k_X, X → Y coefficients): alternates
    the point map (nearest rows of Ψ C for the rows of Φ) and the orthonormal C (between the
    unit-area bases; ``C[0, 0]`` stays ±√(area_Y / area_X) in the shapes' units). Returns
    ``(C, map_xy)``."""
    return _funcorr.icp_refine(X, Y, C, iterations)


def zoomout_refine(X: PreparedShape, Y: PreparedShape, C, k_final: int, step: int = 1) -> Tuple[_np.ndarray, _np.ndarray]:
    """ZoomOut (Melzi et al. 2019) of C (k × k, X → Y coefficients) up to k_final × k_final in
    steps of ``step``, every vertex. Returns ``(C, map_xy)``."""
    return _funcorr.zoomout_refine(X, Y, C, k_final, step)


def maps_from_fmap(X: PreparedShape, Y: PreparedShape, C, adjoint: bool = False) -> Tuple[_np.ndarray, _np.ndarray]:
    """Point maps of a functional map C (k_Y × k_X, X → Y coefficients): ``(map_xy (n,), map_yx
    (m,))`` by nearest neighbours in the spectral embedding: map_xy matches the rows of Φ to those
    of Ψ C, map_yx the rows of Ψ to those of Φ Cᵀ (pyFM's ``FM_to_p2p``), or with ``adjoint``
    the rows of Ψ C to those of Φ (``FM_to_p2p(use_adj=True)``)."""
    return _funcorr.maps_from_fmap(X, Y, C, adjoint)


def soft_map(X: PreparedShape, Y: PreparedShape, C, i: int) -> _np.ndarray:
    """The soft map T δ_i of vertex i of X: the function (m,) on Y that a functional map C
    (k × k, X → Y coefficients) gives the delta at i (``--soft i`` of ``funcorr match``)."""
    return _funcorr.soft_map(X, Y, C, i)


def fmap_from_map(X: PreparedShape, Y: PreparedShape, map_yx, k) -> _np.ndarray:
    """The functional map C = Ψ_{k_Y}ᵀ diag(A_Y) Π Φ_{k_X} (k_Y × k_X, X → Y coefficients) of a
    point map Y → X (``map_yx`` (m,), vertices of X); ``k`` an int (square) or (k_X, k_Y)."""
    return _funcorr.fmap_from_map(X, Y, map_yx, k)


def axiomatic_fmap(
    X: PreparedShape,
    Y: PreparedShape,
    F,
    G,
    k,
    w_descr: float = 1.0,
    w_lap: float = 0.1,
    w_dcomm: float = 1.0,
    w_orient: float = 0.0,
    mask: str = "resolvent",
    orientation: str = "preserve",
    fix_constant: bool = True,
) -> Tuple[_np.ndarray, float]:
    """The axiomatic functional map C (k × k, or k_Y × k_X for ``k = (k_X, k_Y)``; X → Y
    coefficients) from descriptors F (n, q) on X and G (m, q) on Y: the exact minimizer of descriptor preservation ``w_descr``, Laplacian
    commutativity ``w_lap`` (``mask="resolvent"|"standard"``), descriptor commutativity
    ``w_dcomm`` and orientation ``w_orient`` (``orientation="preserve"|"reverse"``), each term
    scale-free (funcorr's ``fmap::energy``), the first column fixed to map constants to
    constants. Returns ``(C, energy)``."""
    return _funcorr.axiomatic_fmap(X, Y, F, G, k, w_descr, w_lap, w_dcomm, w_orient, mask, orientation, fix_constant)


def geodesic_distances(mesh: ShapeLike, sources, method: str = "exact") -> _np.ndarray:
    """Geodesic distances on a triangle mesh from ``sources`` to every vertex.

    ``method``: ``"exact"`` (polyhedral, MMP window propagation), ``"heat"`` (heat method,
    ~2–4 % error), ``"dijkstra"`` (mesh edges, upper bound). A single source (an int) gives
    (n,), a list of s sources (n, s)."""
    if _np.isscalar(sources):
        return _funcorr.geodesic_distances(mesh, _np.array([sources]), method)[:, 0]
    return _funcorr.geodesic_distances(mesh, sources, method)


def geodesic_pairs(mesh: ShapeLike, pairs, method: str = "exact") -> _np.ndarray:
    """d(s, t) for every row (s, t) of ``pairs`` (p, 2); exact queries stop at their target."""
    return _funcorr.geodesic_pairs(mesh, pairs, method)


def geodesic_all_pairs(mesh: ShapeLike, out=None, method: str = "exact", chunk: int = 64, progress=None) -> _np.ndarray:
    """All-pairs geodesic distances written into ``out`` (n × n float64, writable, e.g.
    ``np.memmap(path, dtype=np.float64, mode="w+", shape=(n, n))``; None: a new array), row i the
    distances from vertex i, ``chunk`` sources at a time. ``progress``: as :func:`match` (the
    sources done). Ctrl-C stops the call between two chunks' sources (KeyboardInterrupt; the
    rows finished so far are in ``out``). Returns ``out``."""
    if out is None:
        n = mesh.n if isinstance(mesh, PreparedShape) else _n_vertices(mesh)
        out = _np.empty((n, n), dtype=_np.float64)
    with _reporting(progress, "funcorr.geodesic_all_pairs") as report:
        _funcorr.geodesic_all_pairs(mesh, out, method, chunk, report)
    return out


def _n_vertices(shape: ShapeLike) -> int:
    if isinstance(shape, tuple):
        return _np.asarray(shape[0]).shape[0]
    if isinstance(shape, _np.ndarray):
        return shape.shape[0]
    return read_mesh(shape)[0].shape[0]


def evaluate(map_xy, Y: ShapeLike, gt_x, gt_y, gt_y_sym=None, geodesics: str = "exact") -> Dict[str, Any]:
    """Princeton-protocol errors of a map X → Y (``map_xy`` (n,), vertices of Y).

    ``gt_x[i]`` on X corresponds to ``gt_y[i]`` on Y (0-based; ``read_vts`` reads the 1-based
    .vts files), ``gt_y_sym`` the mirrored counterparts (symmetric flips allowed). Error of
    point i: d_Y(map_xy[gt_x[i]], gt_y[i]) / √area(Y) (eq. (12)).

    Returns a dict: ``mean``, ``at_005``, ``at_010``, ``at_025`` (fractions ≤ 0.05, 0.10, 0.25),
    ``errors`` (per point), ``thresholds`` and ``curve`` (the cumulative curve), ``symmetric``,
    ``geodesics``."""
    return _funcorr.evaluate(map_xy, Y, gt_x, gt_y, gt_y_sym, geodesics)


def cumulative_curve(errors, thresholds=None) -> Tuple[_np.ndarray, _np.ndarray]:
    """``(thresholds, fraction of errors ≤ each)``; thresholds default to 0, 0.005, …, 0.25."""
    return _funcorr.cumulative_curve(errors, thresholds)


def render_pair(X: ShapeLike, Y: ShapeLike, map_yx, width: int = 1600, height: int = 900, view: Tuple[float, float] = (0.0, 0.0)) -> _np.ndarray:
    """X (left) coloured by position and Y (right) coloured by pulling X's colours back through
    ``map_yx`` (m,), CPU rasterizer: an (height, width, 3) uint8 image. ``view``: (azimuth,
    elevation) in degrees; (0, 0) looks along −Z with +Y up."""
    return _funcorr.render_pair(X, Y, map_yx, width, height, tuple(view))


def render(shape: ShapeLike, colors=None, width: int = 800, height: int = 900, view: Tuple[float, float] = (0.0, 0.0)) -> _np.ndarray:
    """One shape (colours (n, 3) uint8, default by position): (height, width, 3) uint8."""
    return _funcorr.render(shape, colors, width, height, tuple(view))


del annotations  # the __future__ import's name: not part of the API
