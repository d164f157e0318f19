"""``pyFM.viz`` (and the ``plot_mesh`` / ``double_plot`` of pyFM's notebooks) on funcorr's viewer:
``plot_mesh``, ``double_plot``, ``vertices_to_rgb``, ``normalize``.

``plot_mesh`` and ``double_plot`` return funcorr's viewer (:class:`funcorr.Viewer`: inline in
notebooks, ``.save(path)``) instead of a PyVista plotter; scalar functions are drawn with
funcorr's blue–white–red map (``cmap``, ``clim``, extra ``points`` and vector fields are not
drawn: a warning says so). ``vertices_to_rgb`` and ``normalize`` compute what pyFM's do.
"""

from __future__ import annotations

import warnings
from typing import Optional

import numpy as np

import funcorr

from .mesh import TriMesh

__all__ = ["plot_mesh", "double_plot", "vertices_to_rgb", "normalize"]


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


