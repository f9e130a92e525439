#!/usr/bin/env python3
"""Usage: nn_distance.py REFERENCE.obj OURS.obj — vertex-set agreement of two refinements.

Matches every reference vertex to its nearest vertex of OURS (k-d tree) and prints the vertex
counts and the largest and mean distance relative to the reference's bounding-box diagonal.
Exit code 1 if the counts differ or the largest distance exceeds 1e-6 of the diagonal.
Run with the peers' Python (bash ../shared/peers/setup.sh).
"""
import sys
import numpy as np
import trimesh
from scipy.spatial import cKDTree

a = trimesh.load(sys.argv[1], process=False, force="mesh")
b = trimesh.load(sys.argv[2], process=False, force="mesh")
va, vb = np.asarray(a.vertices), np.asarray(b.vertices)
diag = np.linalg.norm(va.max(0) - va.min(0))
d, _ = cKDTree(vb).query(va)
rel = d.max() / diag
print(f"{sys.argv[2]}: V {len(va)} vs {len(vb)}; max/diag = {rel:.3e}, mean/diag = {d.mean() / diag:.3e}")
sys.exit(0 if len(va) == len(vb) and rel <= 1e-6 else 1)
