#!/usr/bin/env python3
"""Reference cotangent Laplacian in numpy/scipy (independent of funcorr).

Used by the benchmark for two things:
  * a cross-check of the stiffness matrix / mass that funcorr writes with
    --save-laplacian (compare_spectra.py reports the largest difference);
  * testing the scipy half of the benchmark without the funcorr binary:
        python bench/cotan_laplacian.py SHAPE.off LAP.npz
    writes an npz in the same layout as `funcorr spectrum --save-laplacian`.

Conventions (the ones funcorr documents):
  W = D - C, C_ij = (cot a_ij + cot b_ij) / 2 for every edge ij (no clamping of
  negative cotangents), D = diag(row sums of C), so W is symmetric positive
  semi-definite with a positive diagonal;
  mass_i = sum over triangles touching i of area / 3 (lumped, barycentric).
"""
import sys

import numpy as np
import scipy.sparse as sp


def read_off(path):
    """ASCII OFF reader: returns (vertices (n,3) f64, faces (m,3) i64)."""
    with open(path, "r") as f:
        text = f.read()
    lines = [ln.split("#", 1)[0] for ln in text.splitlines()]
    tokens = " ".join(lines).split()
    if not tokens or not tokens[0].upper().endswith("OFF"):
        raise ValueError(f"{path}: not an OFF file")
    pos = 1
    nv, nf = int(tokens[pos]), int(tokens[pos + 1])
    pos += 3
    verts = np.asarray(tokens[pos:pos + 3 * nv], dtype=np.float64).reshape(nv, 3)
    pos += 3 * nv
    faces = np.empty((nf, 3), dtype=np.int64)
    for t in range(nf):
        cnt = int(tokens[pos])
        if cnt != 3:
            raise ValueError(f"{path}: face {t} has {cnt} vertices (triangles only)")
        faces[t] = [int(x) for x in tokens[pos + 1:pos + 4]]
        pos += 1 + cnt
    return verts, faces


def cotan_laplacian(verts, faces):
    """Return (W csc, mass) as described in the module docstring."""
    n = verts.shape[0]
    p = [verts[faces[:, c]] for c in range(3)]
    cross = np.cross(p[1] - p[0], p[2] - p[0])
    dblarea = np.linalg.norm(cross, axis=1)  # 2 * triangle area
    rows, cols, vals = [], [], []
    for c in range(3):
        a, b = (c + 1) % 3, (c + 2) % 3  # edge (a, b) is opposite corner c
        e1 = p[a] - p[c]
        e2 = p[b] - p[c]
        with np.errstate(divide="ignore", invalid="ignore"):
            cot = np.einsum("ij,ij->i", e1, e2) / dblarea
        cot = np.where(np.isfinite(cot), cot, 0.0)
        w = 0.5 * cot
        rows += [faces[:, a], faces[:, b]]
        cols += [faces[:, b], faces[:, a]]
        vals += [-w, -w]
    rows = np.concatenate(rows)
    cols = np.concatenate(cols)
    vals = np.concatenate(vals)
    off = sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsc()
    diag = -np.asarray(off.sum(axis=1)).ravel()
    W = (off + sp.diags(diag)).tocsc()
    W.sum_duplicates()
    W.sort_indices()
    mass = np.zeros(n)
    for c in range(3):
        np.add.at(mass, faces[:, c], dblarea / 6.0)
    return W, mass


def save_lap_npz(path, W, mass):
    W = sp.csc_matrix(W)
    np.savez(
        path,
        W_data=W.data.astype(np.float64),
        W_indices=W.indices.astype(np.int64),
        W_indptr=W.indptr.astype(np.int64),
        W_shape=np.asarray(W.shape, dtype=np.int64),
        mass=np.asarray(mass, dtype=np.float64),
    )


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        print("usage: cotan_laplacian.py SHAPE.off OUT_LAP.npz", file=sys.stderr)
        return 2
    v, f = read_off(argv[1])
    W, mass = cotan_laplacian(v, f)
    save_lap_npz(argv[2], W, mass)
    print(f"n={W.shape[0]} nnz={W.nnz} total_area={mass.sum():.6g}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
