#!/usr/bin/python3
"""The effective tensor of a finished CalculiX run of a deck rvegen wrote.

usage: /usr/bin/python3 samples/ccx_effective.py DIR NAME

DIR holds NAME.dat from `ccx -i NAME` (NAME: run_voxel_conductivity or run_voxel_elasticity).
The decks print the heat flux or the stress at every integration point of every element
(*EL PRINT of EALL), one block per load step; the elements are equal voxels with equal weights,
so the plain mean of a block is the mean over the box. Conductivity: column k is minus the mean
flux of step k (a unit mean gradient along k; CalculiX's flux is -k grad T). Elasticity: column
k is the mean stress of step k (the unit Mandel strain k) in Mandel form (rows 11, 22, 33, 23,
13, 12, shear times sqrt 2), as rvegen's report states it. Elements with an orientation (the
cores of transversely isotropic fibres) print in their local frame, named at the end of the line:
the values are turned back to the box's frame with the *ORIENTATION cards of NAME.inp. Prints
JSON: {"conductivity": [[...]]} or {"stiffness": [[...]]}.
"""
import json
import math
import os
import sys


def orientations(path):
    """{NAME: 3x3 rotation whose columns are the local axes} of the *ORIENTATION cards
    (SYSTEM=RECTANGULAR: local 1 along a, local 2 in the plane of a and b)."""
    out, pending = {}, None
    with open(path) as f:
        for line in f:
            text = line.strip()
            if text.upper().startswith("*ORIENTATION"):
                pending = [w.split("=")[1].strip().upper() for w in text.split(",")
                           if w.strip().upper().startswith("NAME=")][0]
                continue
            if pending is not None:
                v = [float(w) for w in text.split(",")[:6]]
                a, b = v[:3], v[3:6]
                e1 = unit(a)
                e3 = unit(cross(a, b))
                e2 = cross(e3, e1)
                out[pending] = [[e1[i], e2[i], e3[i]] for i in range(3)]
                pending = None
    return out


def unit(v):
    n = math.sqrt(sum(x * x for x in v))
    return [x / n for x in v]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def to_box(kind, values, r):
    """Flux (3) or stress (xx, yy, zz, xy, xz, yz) from the local frame r to the box's."""
    if kind == "heat":
        return [sum(r[i][k] * values[k] for k in range(3)) for i in range(3)]
    xx, yy, zz, xy, xz, yz = values
    s = [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]
    g = [[sum(r[i][k] * s[k][l] * r[j][l] for k in range(3) for l in range(3)) for j in range(3)]
         for i in range(3)]
    return [g[0][0], g[1][1], g[2][2], g[0][1], g[0][2], g[1][2]]


def blocks(path, frames):
    """The rows of each printed block, in the box's frame: [(kind, [[values], ...])] in file
    order."""
    out, rows, kind = [], None, None
    with open(path) as f:
        for line in f:
            words = line.split()
            if not words:
                continue
            if words[0] in ("heat", "stresses"):
                kind = words[0]
                rows = []
                out.append((kind, rows))
                continue
            if rows is not None:
                # Element, integration point, the values; then, for elements with an
                # orientation, its name.
                values, frame = [], None
                for w in words[2:]:
                    try:
                        values.append(float(w))
                    except ValueError:
                        frame = w.upper()
                        break
                if frame is not None:
                    if frame not in frames:
                        sys.exit("orientation %s is not in the deck" % frame)
                    values = to_box(kind, values, frames[frame])
                rows.append(values)
    return out


def mean(rows):
    n = len(rows)
    return [sum(r[c] for r in rows) / n for c in range(len(rows[0]))]


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    directory, name = sys.argv[1:3]
    frames = orientations(os.path.join(directory, name + ".inp"))
    found = blocks(os.path.join(directory, name + ".dat"), frames)
    if not found:
        sys.exit("no flux or stress blocks in %s.dat" % name)
    kind = found[0][0]
    columns = [mean(rows) for _, rows in found]
    if kind == "heat":
        if len(columns) != 3:
            sys.exit("expected 3 load steps, found %d" % len(columns))
        k = [[-columns[j][i] for j in range(3)] for i in range(3)]
        print(json.dumps({"conductivity": k}))
    else:
        if len(columns) != 6:
            sys.exit("expected 6 load steps, found %d" % len(columns))
        r2 = math.sqrt(2.0)
        # CalculiX: sxx, syy, szz, sxy, sxz, syz -> Mandel 11, 22, 33, 23, 13, 12.
        mandel = [[c[0], c[1], c[2], r2 * c[5], r2 * c[4], r2 * c[3]] for c in columns]
        print(json.dumps({"stiffness": [[mandel[j][i] for j in range(6)] for i in range(6)]}))


if __name__ == "__main__":
    main()
