"""How well `funcorr::matching::landmarks::landmark_check` tells a wrong landmark from right ones.

For every pair of a data set (`pairs.txt`, ground truth `corres/*.vts`), L ground-truth landmarks:
template points far apart on X (the first at random, seeded, then farthest in space), with their
ground-truth images. The check's discrepancy of every landmark (the median over the other
landmarks of |d_X − d_Y| / ((d_X + d_Y) / 2), shortest paths along the edges at unit area — the
formula of the library, which gives the same numbers to 8 digits on the bundled pair) for the
clean set, and for the set with one landmark (at random) moved to the image of a random template
point more than 0.3 √area from its true image on Y. One JSON line per pair; with --summary, the
false alarms (clean sets with a suspect), detections (the moved landmark a suspect) and other
landmarks flagged in the moved sets, for the library's rule.

    python bench/landmark_check_study.py ../shared/data/faust_r 5 > lm5_faust_r.jsonl
    python bench/landmark_check_study.py --summary lm5_faust_r.jsonl

Needs numpy and scipy (e.g. the virtualenv `.ci/run` makes, target/ci-venv).
"""

import json
import statistics
import sys

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

# The library's rule (src/matching/landmarks.rs).
SUSPECT_DISCREPANCY = 0.2
SUSPECT_FACTOR = 2.0


def read_off(path):
    t = open(path).read().split()
    n, f = int(t[1]), int(t[2])
    v = np.array(t[4:4 + 3 * n], float).reshape(n, 3)
    faces = np.array(t[4 + 3 * n:4 + 3 * n + 4 * f], int).reshape(f, 4)[:, 1:]
    return v, faces


def edge_graph(v, f):
    """The edge graph at unit area (edge lengths / sqrt(total area))."""
    e = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1), axis=0)
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1).sum()
    w = np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1) / np.sqrt(area)
    return sp.coo_matrix((w, (e[:, 0], e[:, 1])), (len(v), len(v))).tocsr()


def discrepancy(dx, dy):
    n = len(dx)
    mean = np.maximum((dx + dy) / 2, 1e-300)
    e = np.where((dx + dy) > 0, np.abs(dx - dy) / mean, 0.0)
    return [float(np.median([e[i, k] for k in range(n) if k != i])) for i in range(n)]


def suspects(d):
    typical = statistics.median(d)
    return [i for i, x in enumerate(d) if x >= SUSPECT_DISCREPANCY and (len(d) <= 3 or x >= SUSPECT_FACTOR * typical)]


def study(folder, count):
    rng = np.random.default_rng(0)
    for line in open(f"{folder}/pairs.txt"):
        x, y = line.split()[:2]
        vx_, fx = read_off(f"{folder}/{x}.off")
        vy_, fy = read_off(f"{folder}/{y}.off")
        tx = np.loadtxt(f"{folder}/corres/{x}.vts", int) - 1
        ty = np.loadtxt(f"{folder}/corres/{y}.vts", int) - 1
        ok = np.where((tx >= 0) & (ty >= 0))[0]
        p = vx_[tx[ok]]
        sel = [int(rng.integers(len(ok)))]
        for _ in range(count - 1):
            d = np.min(np.linalg.norm(p[:, None, :] - p[sel][None], axis=2), axis=1)
            sel.append(int(np.argmax(d)))
        t = ok[sel]
        ax, ay = tx[t], ty[t]
        gy = edge_graph(vy_, fy)
        fields_y = dijkstra(gy, directed=False, indices=ay)
        dx = dijkstra(edge_graph(vx_, fx), directed=False, indices=ax)[:, ax]
        clean = discrepancy(dx, fields_y[:, ay])
        i = int(rng.integers(count))
        far = np.where(fields_y[i][ty[ok]] > 0.3)[0]
        moved = ay.copy()
        if len(far):
            moved[i] = ty[ok][rng.choice(far)]
        dy_moved = dijkstra(gy, directed=False, indices=moved)[:, moved]
        print(json.dumps({"x": x, "y": y, "clean": clean, "i": i, "moved": discrepancy(dx, dy_moved)}), flush=True)


def summary(path):
    rows = [json.loads(line) for line in open(path)]
    alarms = sum(1 for r in rows if suspects(r["clean"]))
    found = sum(1 for r in rows if r["i"] in suspects(r["moved"]))
    others = sum(1 for r in rows if any(j != r["i"] for j in suspects(r["moved"])))
    print(f"{path}: {len(rows)} pairs, clean sets flagged {alarms}, moved landmark found {found}, "
          f"other landmarks flagged in the moved sets {others}")


if __name__ == "__main__":
    if sys.argv[1] == "--summary":
        for p in sys.argv[2:]:
            summary(p)
    else:
        study(sys.argv[1], int(sys.argv[2]))
