#!/usr/bin/python3
"""The effective tensor of a finished CalculiX run of a deck rvegen wrote.

usage: /usr/bin/python3 samples/ccx_effective.py DIR NAME

DIR holds NAME.dat from `ccx -i NAME` (NAME: run_voxel_conductivity, run_voxel_elasticity,
run_tet_conductivity or run_tet_elasticity). The decks print the heat flux or the stress at every
integration point of every element (*EL PRINT of EALL), one block per load step. The voxel
elements are equal, with equal weights, so the plain mean of a block is the mean over the box;
the tetrahedral decks also print every element's volume (a "volume" block after each flux or
stress block), and each integration point then weighs its element's volume over the element's
number of points (exact for the one-point C3D4, the four equal points of a C3D10 with straight
edges, and the eight equal points of a voxel). Conductivity: column k is minus the mean flux of step k (a unit mean gradient along k; CalculiX's flux is -k grad T). Elasticity: column
k is the mean stress of step k (the unit Mandel strain k) in Mandel form (rows 11, 22, 33, 23,
13, 12, shear times sqrt 2), as rvegen's report states it. Elements with an orientation (the
cores of transversely isotropic fibres) print in their local frame, named at the end of the line:
the values are turned back to the box's frame with the *ORIENTATION cards of NAME.inp. Prints
JSON: {"conductivity": [[...]]} or {"stiffness": [[...]]}.
"""
import array
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


class Block:
    """One printed block: the element of each row (integration point) and its values (width per
    row), in compact arrays (a deck of millions of elements prints tens of millions of rows)."""

    def __init__(self, kind):
        self.kind = kind
        self.elements = array.array("q")
        self.values = array.array("d")
        self.width = 0

    def add(self, element, values):
        self.width = len(values)
        self.elements.append(element)
        self.values.extend(values)


def blocks(path, frames):
    """The printed blocks one by one, in the box's frame: Block of kind "heat", "stresses" or
    "volume", in file order."""
    block = None
    with open(path) as f:
        for line in f:
            words = line.split()
            if not words:
                continue
            if words[0] in ("heat", "stresses", "volume"):
                if block is not None:
                    yield block
                block = Block(words[0])
                continue
            if block is None:
                continue
            if block.kind == "volume":
                block.add(int(words[0]), [float(words[1])])
                continue
            # Element, integration point, the values; then, for elements with an orientation,
            # its name.
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
                values = to_box(block.kind, values, frames[frame])
            block.add(int(words[0]), values)
    if block is not None:
        yield block


def mean(block, volumes):
    """The mean of the block's values: plain, or weighted by the volume block's element volumes,
    each shared among the element's integration points."""
    w, n = block.width, len(block.elements)
    if n == 0:
        sys.exit("an empty %s block" % block.kind)
    if volumes is None:
        return [sum(block.values[c::w]) / n for c in range(w)]
    top = max(max(block.elements), max(volumes.elements)) + 1
    points = array.array("l", bytes(8 * top))
    for e in block.elements:
        points[e] += 1
    volume = array.array("d", bytes(8 * top))
    listed = array.array("b", bytes(top))
    for e, v in zip(volumes.elements, volumes.values):
        volume[e] = v
        listed[e] = 1
    if any((points[e] > 0) != (listed[e] == 1) for e in range(top)):
        sys.exit("the volume block does not list the elements of the flux or stress block")
    total = sum(volumes.values)
    out = []
    for c in range(w):
        column = block.values[c::w]
        out.append(sum(volume[e] / points[e] * v for e, v in zip(block.elements, column)) / total)
    return out


def columns_of(found):
    """The mean of each load step's flux or stress block (weighted when a volume block follows
    it), and the kind of the blocks. Only one step's blocks are held at a time."""
    out, kind, pending = [], None, None
    for block in found:
        if block.kind == "volume":
            if pending is None:
                sys.exit("a volume block without its flux or stress block")
            out.append(mean(pending, block))
            pending = None
            continue
        if pending is not None:
            out.append(mean(pending, None))
        pending, kind = block, block.kind
    if pending is not None:
        out.append(mean(pending, None))
    return kind, out


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    directory, name = sys.argv[1:3]
    frames = orientations(os.path.join(directory, name + ".inp"))
    kind, columns = columns_of(blocks(os.path.join(directory, name + ".dat"), frames))
    if not columns:
        sys.exit("no flux or stress blocks in %s.dat" % name)
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
