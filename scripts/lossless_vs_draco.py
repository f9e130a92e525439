#!/usr/bin/env python3
"""Usage: lossless_vs_draco.py SUBWAVE BITS MESH... — the lossless codec beside Draco.

For each mesh: `SUBWAVE encode MESH --lossless --bits BITS` (bytes, base chunk bytes) and
`SUBWAVE decode` back to OBJ; Draco (DracoPy, compression level 10) at quantization_bits=BITS.
Both grids are `2^BITS - 1` steps over the longest side of the bounding box from its minimum
corner. The script checks that our decoded vertices are exactly the input rounded to the grid
(as multisets of grid coordinates) and counts the vertices where Draco's grid points differ
from ours (Draco quantizes in float32, so points within ~1e-4 step of a rounding tie may go
the other way), and prints the byte ratio ours / Draco.

Run with the peers' venv: /tmp/subwave-peers/bin/python (bash ../shared/peers/setup.sh).
"""
import re
import subprocess
import sys

import numpy as np
import DracoPy


def load(path):
    """Positions and fan-triangulated faces of an OBJ (`v` and `f` lines only, so that the
    vertices are exactly the file's, not split by texture coordinates)."""
    v, f = [], []
    with open(path) as fh:
        for line in fh:
            if line.startswith("v "):
                v.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("f "):
                c = [int(x.split("/")[0]) for x in line.split()[1:]]
                c = [i - 1 if i > 0 else len(v) + i for i in c]
                f.extend([c[0], c[k], c[k + 1]] for k in range(1, len(c) - 1))
    return np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int32)


def grid_points(v, lo, step):
    q = (v - lo) / step
    r = np.round(q)
    return r.astype(np.int64), float(np.abs(q - r).max())


exe, bits, meshes = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
print(f"{'input':<16} {'V':>8} {'bits':>4} {'ours':>9} {'base':>8} {'details':>9} {'draco':>9} {'ratio':>6}  check")
for path in meshes:
    name = path.rsplit("/", 1)[-1].rsplit(".", 1)[0]
    swv = f"/tmp/{name}.ll.swv"
    out = subprocess.run([exe, "encode", path, "-o", swv, "--lossless", "--bits", str(bits)],
                         capture_output=True, text=True, check=True).stdout
    total = int(re.search(r"wrote \S+: (\d+) bytes", out).group(1))
    base = int(re.search(r"base (\d+) B", out).group(1))
    header = int(re.search(r"header (\d+) B", out).group(1))
    dec = f"/tmp/{name}.ll.obj"
    subprocess.run([exe, "decode", swv, "-o", dec], capture_output=True, text=True, check=True)
    v, f = load(path)
    buf = DracoPy.encode(v.astype(np.float32), f, quantization_bits=bits, compression_level=10)
    d = DracoPy.decode(buf)
    vd = np.asarray(d.points, dtype=np.float64)
    lo = v.min(0)
    step = float((v.max(0) - lo).max()) / ((1 << bits) - 1)
    ours, _ = load(dec)
    srt = lambda q: q[np.lexsort(q.T[::-1])]
    qo, off_o = grid_points(ours, lo, step)
    qd, _ = grid_points(vd, lo, step)
    qv, _ = grid_points(v, lo, step)
    exact = len(qo) == len(qv) and np.array_equal(srt(qo), srt(qv))
    if len(qd) == len(qo):
        # Vertices of Draco's decoded set that are not in ours (multiset difference).
        from collections import Counter
        ndiff = str(sum((Counter(map(tuple, qd)) - Counter(map(tuple, qo))).values()))
    else:
        ndiff = "n/a"
    check = (f"ours == round(input): {exact} (off-grid {off_o:.0e} steps); "
             f"Draco's float32 grid points differing: {ndiff}")
    print(f"{name:<16} {len(v):>8} {bits:>4} {total:>9} {base:>8} {total - base - header:>9} "
          f"{len(buf):>9} {total / len(buf):>6.3f}  {check}")
