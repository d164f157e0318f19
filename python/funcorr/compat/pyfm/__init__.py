"""pyFM on funcorr: change the import, keep the script.

::

    from funcorr.compat.pyfm.mesh import TriMesh                 # was: from pyFM.mesh import TriMesh
    from funcorr.compat.pyfm.functional import FunctionalMapping # was: from pyFM.functional import ...
    import funcorr.compat.pyfm.eval                              # was: import pyFM.eval
    import funcorr.compat.pyfm as pyFM                           # pyFM.eval.accuracy(...), pyFM.refine, ...

The modules mirror pyFM's (pyfmaps 1.3): ``mesh`` (``TriMesh``), ``functional``
(``FunctionalMapping``), ``spectral`` (``p2p_to_FM``, ``FM_to_p2p``, ``mesh_*`` versions,
``knn_query``, shape differences), ``refine`` (ICP and ZoomOut on arrays and meshes, from a map
or a point map), ``signatures`` (HKS, WKS, their landmark versions, ``auto_*``, ``mesh_*``) and
``eval`` (``accuracy``, ``continuity``, ``coverage``), and ``viz`` (``plot_mesh``,
``double_plot``, ``vertices_to_rgb``, ``normalize`` on funcorr's viewer). Both pyFM APIs run: 1.3's
(``TriMesh.load``, ``geodesic_from(i, method=)``, ``fit(K=(k1, k2))`` setting ``FM_12``,
refinements returned, ``get_p2p(FM)``) and the earlier one (``TriMesh(path)``,
``geod_from``, ``get_geodesic(save=)``, ``preprocess(n_ev=(k1, k2))``, ``fit(descr_mu=...)``,
refinements kept and chosen by ``change_FM_type``, ``model.FM``).

Conventions are pyFM's: ``FM_12`` (k2 × k1) maps functions on mesh1 to mesh2 —
``transfer(f) = mesh2.unproject(FM_12 @ mesh1.project(f))`` — i.e. funcorr's ``C`` with X = mesh1
and Y = mesh2; ``p2p_21 = model.get_p2p()`` has length n2 and gives for every vertex of mesh2 a
vertex of mesh1 (funcorr's ``map_yx``); ``eval.accuracy(p2p_21, gt_p2p, D1)`` measures on mesh1.
Everything is in the meshes' own units (``C[0, 0] = ±√(area2 / area1)``), as in pyFM, and so
is the search behind ``get_p2p``: like pyFM's, its result depends on the meshes' areas unless
they are equal (``area_normalize=True``); funcorr's own :func:`funcorr.maps_from_fmap` searches
between unit-area bases and gives the same maps on meshes of equal area.

Computed by funcorr: Laplacians and spectra (block Lanczos, Φᵀ A Φ = I), geodesic distances,
the functional-map fit, the nearest-neighbour search of every point map, mesh files. As pyFM:
descriptors (its WKS/HKS formulas and parameters, L²-normalized), ICP and ZoomOut iterations,
conversions, evaluation.

What differs from pyFM, each said once by a :class:`FuncorrCompatWarning` when met:

* ``fit``: the four terms (descriptors, Laplacian commutativity with the resolvent mask — or the
  (λ₁ − λ₂)² mask of the earlier API —, descriptor commutativity, orientation) minimized
  exactly by funcorr's solver instead of L-BFGS (``optinit``, ``factr``, ``pgtol`` unused); each
  term is scale-free, so weights are comparable to pyFM's, not identical;
  ``normalize_weights=False`` (pyFM's legacy scaling) is not reproduced; ``resolvent_gamma``
  other than 0.5 is an error.
* ``process(intrinsic=True)``: funcorr's intrinsic Delaunay Laplacian (``laplacian="intrinsic"``;
  robust_laplacian's tufted intrinsic Laplacian without mollification is the same on manifold
  meshes); ``robust=True`` gives the same (no tufted cover, no 1e-5 mollification); point clouds:
  funcorr's point-cloud Laplacian.
* Geodesics: ``"heat"`` (the default, as potpourri3d's) is funcorr's heat method on the
  intrinsic Delaunay triangulation; ``"heat_pure"`` is the same heat method; ``"fast_marching"``
  gives funcorr's exact polyhedral distances; ``"exact"`` may be asked directly. ``geod_from``
  and ``get_geodesic`` use the heat method for ``robust=True`` and ``False`` alike (consistent
  with each other); ``get_geodesic(save=True)`` writes ``geod_cache/NAME.npy`` beside the mesh
  file and reads it back as pyFM before 1.3 did.
* ``get_precise_map`` / ``mesh_FM_to_p2p_precise`` (Ezuz & Ben-Chen): not in funcorr; the
  vertex-to-vertex map as a sparse matrix instead.
* ``zoomout_refine`` with too few eigenpairs computes more (pyFM raises); ZoomOut with an int
  ``subsample`` uses funcorr's geodesic farthest-point samples.
* ``export_texture`` / ``save(texture=)``: the ``.mtl`` names the image; pyFM's bundled texture
  images are not shipped.
* ``knn_query`` gives the nearest neighbour only (k = 1); ``n_jobs`` is unused everywhere
  (funcorr's thread count is ``funcorr.set_num_threads``).
* ``viz`` (pyFM's PyVista plots; the meshplot ``double_plot`` of its notebooks): funcorr's viewer
  (:class:`funcorr.Viewer`) instead of a PyVista plotter, scalars in funcorr's blue–white–red
  map; ``cmap``, ``clim``, extra ``points`` and vector fields are not drawn (a warning).
* Not provided: ``TriMesh.orientation_op`` (funcorr builds its orientation operators inside the
  fit), the ``FMN`` (map networks) and ``optimize`` modules.
"""

from . import eval, functional, mesh, refine, signatures, spectral, viz  # noqa: A004 (pyFM's name)
from ._common import FuncorrCompatWarning
from .functional import FunctionalMapping
from .mesh import TriMesh
from .viz import double_plot, plot_mesh

__all__ = [
    "TriMesh",
    "FunctionalMapping",
    "FuncorrCompatWarning",
    "mesh",
    "functional",
    "spectral",
    "refine",
    "signatures",
    "eval",
    "viz",
    "plot_mesh",
    "double_plot",
]
