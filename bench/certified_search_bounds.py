"""How much of Y a *provably exact* restricted nearest-neighbour search would have to read.

Issue 30 item 1 asks that the final point map touch every vertex once "with an exact or
provably-restricted search". funcorr's restricted search (`--near-above`) reads the vertices of
Y in the 16 cells around each sample's image: fast, but only equal to the exact search where the
true nearest row lies in those cells. A search that *proves* its answer exact prunes a cell C of
Y only when the triangle inequality rules it out for the query q:

    ||q - r_j|| >= ||q - e_C|| - R_C   for every row r_j in C   (e_C: a point, R_C: C's radius)

so C must be read whenever ||q - e_C|| - R_C < b(q), b(q) the distance to the best row found.
This script measures that "suspect" set on a real pair: for the pull-back embedding of the final
map X -> Y (queries: rows of Phi_k; references: rows of Psi_k C, C = C.npy of `funcorr match`,
i.e. C_yx^T), with Y split into the Euclidean Voronoi cells of `cells` random vertices,

  * per query, with b the exact nearest distance (the best case) and e_C the mean of the cell;
  * with e_C = the cell's seed row, b = the best seed, tightened by reading the query's own best
    cell first, and queries grouped by that cell (rows read = the union over the group): what a
    two-pass implementation would read.

It prints the rows read per query as a share of m, and the whole search's flops against the
brute force's (n * m). Inputs come from the funcorr CLI:

    funcorr spectrum X.off -k 128 -o bx.npz
    funcorr spectrum Y.off -k 128 -o by.npz
    funcorr match X.off Y.off --no-render -q -o out/       # out/C.npy
    bench/.venv/bin/python bench/certified_search_bounds.py bx.npz by.npz out/C.npy Y.off

(numpy and scipy as pinned in bench/requirements.txt.) Results: EXPERIMENTS.md, "A provably
exact restricted search for the final maps: measured, not built".
"""

import argparse

import numpy as np
from scipy.spatial import cKDTree


def read_off_vertices(path):
    """Vertex positions (V #V by 3) of an OFF file."""
    with open(path) as f:
        tokens = f.read().split()
    i = 1 if tokens[0] == "OFF" else 0
    n = int(tokens[i])
    return np.array(tokens[i + 3 : i + 3 + 3 * n], float).reshape(n, 3)


def exact_nearest(q, r, block=2000):
    """Distances and indices of the nearest row of r for every row of q (brute force, f64)."""
    rn = (r * r).sum(1)
    dist, arg = np.empty(len(q)), np.empty(len(q), int)
    for s in range(0, len(q), block):
        d = (q[s : s + block] ** 2).sum(1)[:, None] + rn[None, :] - 2 * q[s : s + block] @ r.T
        arg[s : s + block] = d.argmin(1)
        dist[s : s + block] = np.sqrt(np.maximum(d.min(1), 0))
    return dist, arg


def centre_distances(q, e):
    """||q_i - e_C|| for every query row and centre."""
    d = (q**2).sum(1)[:, None] + (e**2).sum(1)[None, :] - 2 * q @ e.T
    return np.sqrt(np.maximum(d, 0))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("basis_x")
    ap.add_argument("basis_y")
    ap.add_argument("c")
    ap.add_argument("y_off")
    ap.add_argument("--cells", default="1000,2000,4000")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    c = np.load(a.c)
    k = c.shape[0]
    q = np.load(a.basis_x)["eigenvectors"][:, :k]
    r = np.load(a.basis_y)["eigenvectors"][:, :k] @ c
    py = read_off_vertices(a.y_off)
    n, m = len(q), len(r)
    b, _ = exact_nearest(q, r)
    print(f"n {n}, m {m}, k {k}; median |q| {np.median(np.linalg.norm(q, axis=1)):.3g}, median b {np.median(b):.3g}")
    rng = np.random.default_rng(a.seed)
    for cells in [int(s) for s in a.cells.split(",")]:
        seeds = rng.choice(m, cells, replace=False)
        _, label = cKDTree(py[seeds]).query(py)
        count = np.bincount(label, minlength=cells)
        members = [np.nonzero(label == t)[0] for t in range(cells)]
        # Mean centres, exact b: the best case per query.
        mean = np.zeros((cells, k))
        np.add.at(mean, label, r)
        mean /= np.maximum(count, 1)[:, None]
        radius = np.zeros(cells)
        np.maximum.at(radius, label, np.linalg.norm(r - mean[label], axis=1))
        # Seed centres (rows of Y), two passes, grouped by the best seed's cell.
        seed_rows = r[seeds]
        seed_radius = np.zeros(cells)
        np.maximum.at(seed_radius, label, np.linalg.norm(r - seed_rows[label], axis=1))
        best_case = grouped = 0.0
        for s0 in range(0, n, 4000):
            qq = q[s0 : s0 + 4000]
            suspect = centre_distances(qq, mean) - radius[None, :] <= b[s0 : s0 + 4000, None]
            best_case += (suspect * count[None, :]).sum()
            dq = centre_distances(qq, seed_rows)
            own = dq.argmin(1)
            bound = dq.min(1)
            for t in range(len(qq)):
                rows = r[members[own[t]]]
                bound[t] = min(bound[t], np.sqrt(max(((rows - qq[t]) ** 2).sum(1).min(), 0)))
            suspect = dq - seed_radius[None, :] <= bound[:, None]
            order = np.argsort(own, kind="stable")
            for group in np.split(order, np.flatnonzero(np.diff(own[order])) + 1):
                grouped += len(group) * count[suspect[group].any(0)].sum()
        per_query, per_group = best_case / n, grouped / n
        print(
            f"cells {cells:6d}: rows read per query {per_query:8.0f} ({100 * per_query / m:5.2f} % of m, best case); "
            f"two passes, grouped {per_group:8.0f} ({100 * per_group / m:5.2f} %); "
            f"flops against the brute force {(per_group + cells) / m:.3f}"
        )


if __name__ == "__main__":
    main()
