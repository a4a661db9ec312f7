#!/usr/bin/python3
"""The effective tensor of a finished CalculiX run of a deck rvegen wrote.

usage: /usr/bin/python3 samples/ccx_effective.py DIR NAME

DIR holds NAME.dat from `ccx -i NAME` (NAME: run_voxel_conductivity or run_voxel_elasticity).
The decks print the heat flux or the stress at every integration point of every element
(*EL PRINT of EALL), one block per load step; the elements are equal voxels with equal weights,
so the plain mean of a block is the mean over the box. Conductivity: column k is minus the mean
flux of step k (a unit mean gradient along k; CalculiX's flux is -k grad T). Elasticity: column
k is the mean stress of step k (the unit Mandel strain k) in Mandel form (rows 11, 22, 33, 23,
13, 12, shear times sqrt 2), as rvegen's report states it. Prints JSON:
{"conductivity": [[...]]} or {"stiffness": [[...]]}.
"""
import json
import math
import os
import sys


def blocks(path):
    """The numeric rows of each printed block: {block header: [[values], ...]} in file order."""
    out, rows = [], None
    with open(path) as f:
        for line in f:
            words = line.split()
            if not words:
                continue
            if words[0] in ("heat", "stresses"):
                rows = []
                out.append((words[0], rows))
                continue
            if rows is not None:
                rows.append([float(w) for w in words[2:]])
    return out


def mean(rows):
    n = len(rows)
    return [sum(r[c] for r in rows) / n for c in range(len(rows[0]))]


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    directory, name = sys.argv[1:3]
    found = blocks(os.path.join(directory, name + ".dat"))
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
