#!/usr/bin/env bash
# The conforming tetrahedral mesh (outputs "mesh_tet"), checked by other programs' readers and
# against the exact geometry: meshio reads mesh_tet.vtu and mesh_tet.inp; every element has a
# positive volume and a least dihedral angle of at least 5 degrees; each phase's volume is
# within 1 % of the exact one (computed here from inclusions.json); opposite box faces carry the
# same nodes (every node on a face has its image on the opposite face within 1e-9 of the box);
# inclusions the mesher cannot take are refused. (The mesh is not the same from run to run:
# Gmsh's HXT mesher varies, with one thread too.)
# usage: test_tet_mesh.sh RVEGEN_BINARY WORK_DIR
set -u
RVEGEN=$1
WORK=$2
rm -rf "$WORK" && mkdir -p "$WORK"
source "$(dirname "$0")/lib.sh"
cat >"$WORK/scene.json" <<'JSON'
{"box":{"size":[0.6,0.6,0.6]},"seed":5,"min_gap":0.03,"families":[
 {"name":"spheres","shape":"sphere","radius":0.1,"volume_fraction":0.15},
 {"name":"rods","shape":"cylinder","radius":0.05,"aspect_ratio":3,"count":4}],
 "outputs":["inclusions","mesh_tet"]}
JSON
expect_rc 0 "$RVEGEN" generate "$WORK/scene.json" -o "$WORK/a" -q
$py - "$WORK/a" <<'PY' || fail "tetrahedral mesh"
import json, math, sys
import numpy as np
import meshio
d = sys.argv[1]
incs = json.load(open(d + "/inclusions.json"))
L = incs["box"]["size"][0]
m = meshio.read(d + "/mesh_tet.vtu")
pts = m.points
tets = m.cells_dict["tetra"]
phase = np.asarray(m.cell_data_dict["phase"]["tetra"]).astype(int)
inp = meshio.read(d + "/mesh_tet.inp", file_format="abaqus")
assert len(inp.cells_dict["tetra"]) == len(tets), "the .inp and the .vtu differ in elements"
# Volumes: positive, and per phase within 1 % of the exact ones.
P = pts[tets]
vol = np.einsum("ij,ij->i", P[:, 1] - P[:, 0], np.cross(P[:, 2] - P[:, 0], P[:, 3] - P[:, 0])) / 6
assert vol.min() > 0, "an element has volume %g" % vol.min()
exact = {}
for i in incs["inclusions"]:
    if i["shape"] == "sphere":
        v = 4 / 3 * math.pi * i["radius"] ** 3
    elif i["shape"] == "cylinder":
        v = math.pi * i["radius"] ** 2 * 2 * np.linalg.norm(i["half_axis"])
    else:
        raise AssertionError("unexpected shape " + i["shape"])
    exact[i["family"] + 1] = exact.get(i["family"] + 1, 0.0) + v
exact[0] = L ** 3 - sum(exact.values())
for label, v in exact.items():
    got = vol[phase == label].sum()
    assert abs(got / v - 1) < 0.01, "phase %d: volume %g, exact %g" % (label, got, v)
assert abs(vol.sum() / L ** 3 - 1) < 1e-9, "the elements do not fill the box: %g" % vol.sum()
# Least dihedral angle of every element.
least = np.full(len(tets), 180.0)
for i in range(4):
    for j in range(i + 1, 4):
        k, l = [x for x in range(4) if x not in (i, j)]
        e = P[:, j] - P[:, i]
        e /= np.linalg.norm(e, axis=1)[:, None]
        u = P[:, k] - P[:, i]; w = P[:, l] - P[:, i]
        u -= np.einsum("ij,ij->i", u, e)[:, None] * e
        w -= np.einsum("ij,ij->i", w, e)[:, None] * e
        c = np.einsum("ij,ij->i", u, w) / np.linalg.norm(u, axis=1) / np.linalg.norm(w, axis=1)
        least = np.minimum(least, np.degrees(np.arccos(np.clip(c, -1, 1))))
assert least.min() >= 5.0, "least dihedral angle %.2f degrees" % least.min()
rep = json.load(open(d + "/report.json"))["mesh_tet"]
assert rep["tetrahedra"] == len(tets) and rep["min_dihedral_degrees"]["below_5_degrees"] == 0
assert abs(rep["min_dihedral_degrees"]["min"] - least.min()) < 1e-6, (rep["min_dihedral_degrees"]["min"], least.min())
# Periodic: the nodes of each face, brought to the opposite one, are its nodes.
tol = 1e-9 * L
for a in range(3):
    lo = pts[np.abs(pts[:, a]) <= tol]
    hi = pts[np.abs(pts[:, a] - L) <= tol]
    assert len(lo) == len(hi) and len(lo) > 0, (a, len(lo), len(hi))
    others = [b for b in range(3) if b != a]
    key = lambda q: set(map(tuple, np.round(q[:, others] / tol).astype(np.int64)))
    klo, khi = key(lo), key(hi)
    # rounding may put a coordinate pair one step apart: compare nearest instead when sets differ
    if klo != khi:
        from scipy.spatial import cKDTree
        dist, _ = cKDTree(lo[:, others]).query(hi[:, others])
        assert dist.max() <= tol, "axis %d: a face node has no image (%g)" % (a, dist.max())
# The node sets of the faces and edges: as many on each side.
ps = inp.point_sets
for a in "XYZ":
    assert len(ps[a + "MIN"]) == len(ps[a + "MAX"]) > 0, a
for s in ("EDGE_Y0Z0", "EDGE_Y1Z1", "EDGE_X0Z1", "CORNER_X1Y1Z1", "CORNER_X0Y0Z0"):
    assert len(ps[s]) >= 1, s
print("tets %d, least dihedral %.2f, volumes within 1 %%" % (len(tets), least.min()))
PY
# What the mesher cannot take is refused, naming the family, with nothing written.
cat >"$WORK/coated.json" <<'JSON'
{"box":{"size":[0.6,0.6,0.6]},"seed":5,"families":[
 {"name":"coated","shape":"sphere","radius":0.08,"volume_fraction":0.1,"coating":{"thickness":0.01}}],
 "outputs":["inclusions","mesh_tet"]}
JSON
expect_rc 2 "$RVEGEN" generate "$WORK/coated.json" -o "$WORK/c" -q
grep -q 'family "coated"' "$WORK/last.err" || fail "the refused family is not named: $(cat "$WORK/last.err")"
[ -e "$WORK/c" ] && fail "a refused mesh left a directory"
cat >"$WORK/ellipsoids.json" <<'JSON'
{"box":{"size":[0.6,0.6,0.6]},"seed":5,"families":[
 {"name":"grains","shape":"ellipsoid","semi_axes":[0.08,0.05,0.04],"count":4}],
 "outputs":["inclusions","mesh_tet"]}
JSON
expect_rc 2 "$RVEGEN" generate "$WORK/ellipsoids.json" -o "$WORK/e" -q
grep -q 'family "grains" has ellipsoids' "$WORK/last.err" || fail "ellipsoids not refused by name"
finish "tetrahedral mesh tests"
