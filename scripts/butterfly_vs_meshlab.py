#!/usr/bin/env python3
"""Usage: butterfly_vs_meshlab.py INPUT.obj MESHLAB_LEVEL1.obj OURS_LEVEL1.obj

Which edge points of one level of butterfly subdivision agree with MeshLab's, by edge class.

Recomputes, from INPUT, the unmodified 8-point butterfly of Dyn, Levin & Gregory as vcg's
`MidPointButterfly` does it (4-point rule on boundary edges; a wing whose face is missing is
replaced by the vertex of the edge's own face on that side), and compares it and subwave's
modified butterfly (OURS: vertex V + e is the point of edge e, edges numbered in order of first
appearance in the face scan) with the nearest MeshLab vertex. Prints, per class of edge (both
ends valence 6 / one end extraordinary / both extraordinary / next to a boundary / boundary),
the largest distances relative to the bounding-box diagonal. Exit code 1 unless both
agree with MeshLab within 1e-6 of the diagonal where they should: ours on edges whose ends have
valence 6 away from boundaries, the recomputed 8-point rule on every interior edge.
Run with the peers' Python.
"""
import sys
from collections import defaultdict

import numpy as np
from scipy.spatial import cKDTree


def read_obj(path):
    v, f = [], []
    with open(path) as fh:
        for line in fh:
            t = line.split()
            if not t:
                continue
            if t[0] == "v":
                v.append([float(x) for x in t[1:4]])
            elif t[0] == "f":
                idx = [int(x.split("/")[0]) for x in t[1:]]
                f.append([i - 1 if i > 0 else len(v) + i for i in idx])
    return np.array(v), f


inp, ref, ours = sys.argv[1:4]
V, F = read_obj(inp)
R, _ = read_obj(ref)
O, _ = read_obj(ours)
diag = np.linalg.norm(V.max(0) - V.min(0))
tree = cKDTree(R)

# Edges in subwave's order; directed half-edges -> opposite vertex.
edges, eid, he = [], {}, {}
for face in F:
    n = len(face)
    for i in range(n):
        a, b = face[i], face[(i + 1) % n]
        he[(a, b)] = face[(i + 2) % n]
        k = (min(a, b), max(a, b))
        if k not in eid:
            eid[k] = len(edges)
            edges.append((a, b))
valence = defaultdict(int)
for a, b in edges:
    valence[a] += 1
    valence[b] += 1
boundary_vertex = set()
for a, b in edges:
    if (a, b) not in he or (b, a) not in he:
        boundary_vertex.update((a, b))


def dlg(a, b):
    if (a, b) not in he or (b, a) not in he:
        return None  # boundary edge: handled below
    c, d = he[(a, b)], he[(b, a)]
    w = lambda x, y, z: he.get((x, y), z)  # wing across x->y, else the face's own z
    wings = [w(a, c, b), w(c, b, a), w(b, d, a), w(d, a, b)]
    return 0.5 * (V[a] + V[b]) + 0.125 * (V[c] + V[d]) - sum(V[x] for x in wings) / 16.0, wings


stats = defaultdict(lambda: [0, 0.0, 0.0])
nv = len(V)
for e, (a, b) in enumerate(edges):
    r = dlg(a, b)
    if r is None:
        cls = "boundary edge"
        ours_p = O[nv + e]
        ref_p = None
    else:
        p, wings = r
        ext = (valence[a] != 6) + (valence[b] != 6)
        near_b = any(x in boundary_vertex for x in (a, b, he[(a, b)], he[(b, a)]))
        cls = "next to boundary" if near_b else ["both valence 6", "one extraordinary", "both extraordinary"][ext]
        ref_p = p
    d_ours, _ = tree.query(O[nv + e])
    s = stats[cls]
    s[0] += 1
    s[1] = max(s[1], d_ours / diag)
    if ref_p is not None:
        d_dlg, _ = tree.query(ref_p)
        s[2] = max(s[2], d_dlg / diag)
print(f"{inp}: {len(edges)} edges, diag {diag:.4g}")
for cls in ["both valence 6", "one extraordinary", "both extraordinary", "next to boundary", "boundary edge"]:
    if cls in stats:
        n, a, b = stats[cls]
        dl = f"{b:.2e}" if cls != "boundary edge" else "   -    "
        print(f"  {cls:20s} {n:6d} edges: ours-meshlab max/diag {a:.2e}, 8-point-meshlab max/diag {dl}")
ok = stats["both valence 6"][1] <= 1e-6 and all(
    s[2] <= 1e-6 for c, s in stats.items() if c != "boundary edge"
)
sys.exit(0 if ok else 1)
