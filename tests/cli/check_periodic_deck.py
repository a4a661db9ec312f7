#!/usr/bin/python3
"""Checks a mesh rvegen wrote for Abaqus and its periodic deck, reading both as plain text:
 - every node of an upper face, edge or corner set has its image (the node at its coordinates
   brought to the lower ends along those axes) within 1e-9 of the box size;
 - each equation's first term (the eliminated one) is eliminated once per degree of freedom,
   no eliminated node appears in another equation as a master, and the eliminated nodes are
   exactly those of the upper faces.
usage: check_periodic_deck.py MESH.inp DECK.inp BOX_SIZE [EDGE_NODES]
EDGE_NODES: the number of nodes the edge EDGE_X0Y0 must hold (a voxel mesh's n + 1).
"""
import sys

mesh, deck, L = sys.argv[1], sys.argv[2], float(sys.argv[3])
edge_nodes = int(sys.argv[4]) if len(sys.argv) > 4 else None
nodes, sets, cur = {}, {}, None
for line in open(mesh):
    line = line.strip()
    if line.startswith("**"):
        continue
    if line.startswith("*"):
        cur = None
        if line.startswith("*NODE,"):
            cur = "node"
        elif line.startswith("*NSET, NSET="):
            cur = line.split("=")[1].split(",")[0]
            sets[cur] = []
        continue
    if cur == "node":
        w = line.split(",")
        nodes[int(w[0])] = tuple(float(x) for x in w[1:4])
    elif cur is not None:
        sets[cur] += [int(x) for x in line.split(",") if x.strip()]
tol = 1e-9 * L
cell = {}
for n, x in nodes.items():
    cell.setdefault(tuple(int(c // (100 * tol)) for c in x), []).append(n)


def find(x):
    """The node within tol of x, or None."""
    key = tuple(int(c // (100 * tol)) for c in x)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                for n in cell.get((key[0] + dx, key[1] + dy, key[2] + dz), []):
                    if max(abs(a - b) for a, b in zip(nodes[n], x)) <= tol:
                        return n
    return None


for name, axes in [("XMAX", [0]), ("YMAX", [1]), ("ZMAX", [2]), ("EDGE_X1Y1", [0, 1]),
                   ("EDGE_Y1Z1", [1, 2]), ("EDGE_X1Z1", [0, 2]), ("CORNER_X1Y1Z1", [0, 1, 2])]:
    assert sets[name], name
    for n in sets[name]:
        x = list(nodes[n])
        for a in axes:
            x[a] -= L
        assert find(x) is not None, ("no image", name, n, nodes[n])
assert len(sets["CORNER_X0Y0Z0"]) == 1, sets["CORNER_X0Y0Z0"]
if edge_nodes is not None:
    assert len(sets["EDGE_X0Y0"]) == edge_nodes, len(sets["EDGE_X0Y0"])
lines = open(deck).read().split("*EQUATION\n", 1)[1].split("*STEP", 1)[0].splitlines()
first, others, i = [], set(), 0
while i < len(lines):
    n = int(lines[i])
    i += 1
    terms = []
    while len(terms) < n:
        w = [x.strip() for x in lines[i].split(",")]
        i += 1
        terms += [(int(w[k]), int(w[k + 1]), float(w[k + 2])) for k in range(0, len(w), 3)]
    first.append((terms[0][0], terms[0][1]))
    others.update((t[0], t[1]) for t in terms[1:])
assert len(first) == len(set(first)), "a node eliminated twice"
assert not (set(first) & others), "an eliminated node is used as a master"
upper = set(sets["XMAX"]) | set(sets["YMAX"]) | set(sets["ZMAX"])
assert {n for n, _ in first} == upper, "eliminated nodes are not exactly those on upper faces"
print("mesh periodic: %d nodes, %d equations" % (len(nodes), len(first)))
