"""Error of a map between subdivided shapes whose coarse vertex ids are kept (examples/subdivide.rs;
the truth is the identity on the coarse ids), as in BENCHMARKS.md "Restricted searches without
gathers, in register tiles, through finer levels".

Usage: python bench/subdivided_error.py Y_fine.off Y_coarse.off map_fine.txt map_coarse.txt OUT_DIR

Prints the Euclidean proxy ||y_pi(i) - y_i|| / sqrt(area(Y)) x100 on 1000 seeded random coarse
vertices for the fine map and for a map computed on the coarse pair, and writes to OUT_DIR
`snapped_map.txt` (the fine map of the coarse vertices of X, each image snapped to the nearest
coarse vertex of Y) and `gt500.vts` (500 seeded random coarse ids, 1-based), to score with exact
geodesics on the coarse surface:
    funcorr eval --source X_coarse.off --target Y_coarse.off --map OUT_DIR/snapped_map.txt \
        --gt-source OUT_DIR/gt500.vts --gt-target OUT_DIR/gt500.vts
Needs numpy and scipy (bench/requirements.txt).
"""
import os
import random
import sys

import numpy as np
from scipy.spatial import cKDTree


def read_off(path):
    with open(path) as f:
        if f.readline().strip() != "OFF":
            raise SystemExit(f"{path}: not an OFF file")
        nv, nf, _ = map(int, f.readline().split())
        v = np.loadtxt(f, max_rows=nv)
        t = np.loadtxt(f, max_rows=nf, dtype=np.int64)[:, 1:]
    return v, t


def main():
    if len(sys.argv) != 6:
        raise SystemExit(__doc__)
    yf, _ = read_off(sys.argv[1])
    yc, tc = read_off(sys.argv[2])
    mf = np.loadtxt(sys.argv[3], dtype=np.int64)
    mc = np.loadtxt(sys.argv[4], dtype=np.int64)
    out = sys.argv[5]
    nc = len(yc)
    if len(mc) != nc or len(mf) < nc or len(yf) < nc:
        raise SystemExit("the coarse map must cover the coarse vertices, the fine shapes must keep them")
    e = yc[tc[:, 1]] - yc[tc[:, 0]]
    f = yc[tc[:, 2]] - yc[tc[:, 0]]
    area = 0.5 * np.linalg.norm(np.cross(e, f), axis=1).sum()
    ids = np.array(sorted(random.Random(7).sample(range(nc), 1000)))
    ef = np.linalg.norm(yf[mf[ids]] - yf[ids], axis=1) / np.sqrt(area) * 100
    ec = np.linalg.norm(yc[mc[ids]] - yc[ids], axis=1) / np.sqrt(area) * 100
    print(f"Euclidean proxy x100 on 1000 coarse ids: fine map {ef.mean():.3f}, coarse map {ec.mean():.3f}")
    os.makedirs(out, exist_ok=True)
    snapped = cKDTree(yc).query(yf[mf[:nc]])[1]
    np.savetxt(os.path.join(out, "snapped_map.txt"), snapped, fmt="%d")
    with open(os.path.join(out, "gt500.vts"), "w") as g:
        g.write("\n".join(str(i + 1) for i in sorted(random.Random(7).sample(range(nc), 500))) + "\n")


if __name__ == "__main__":
    main()
