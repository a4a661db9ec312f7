#!/usr/bin/env bash
# The conforming tetrahedral mesh (outputs "mesh_tet"), checked by other programs and against
# the exact geometry:
#  - meshio reads mesh_tet.vtu, mesh_tet.inp and mesh_tet.msh, and Gmsh checks the .msh;
#  - every element has a positive volume and a least dihedral angle of at least 5 degrees; each
#    phase's volume is within 1 % of the exact one (computed here from inclusions.json);
#  - opposite box faces carry the same nodes (every node on a face has its image on the opposite
#    face within 1e-9 of the box), and so do the .msh's $Periodic pairs;
#  - the periodic decks eliminate each upper-face node once per degree of freedom, and CalculiX
#    (an outside solver) runs the conductivity deck with no error: its effective conductivity
#    agrees with rvegen's FFT solver (laminate voxels, 32^3: 0.2 % from 64^3) within 2 %, with
#    spheres and transversely isotropic rods, each in its own orientation;
#  - the scene's "mesh_tet" sizes reach the mesher (a coarser chord error, fewer elements);
#  - inclusions the mesher cannot take are refused.
# (The mesh is not the same from run to run: Gmsh's HXT mesher varies, with one thread too.)
# usage: test_tet_mesh.sh RVEGEN_BINARY WORK_DIR SAMPLES_DIR
set -u
RVEGEN=$1
WORK=$2
SAMPLES=$3
rm -rf "$WORK" && mkdir -p "$WORK"
source "$(dirname "$0")/lib.sh"
command -v ccx >/dev/null || { echo "FAIL: ccx (calculix-ccx) not installed"; exit 1; }
# The analyst's sample scene (docs/analyst.md), its tetrahedral mesh alone.
sed 's/"outputs":.*/"outputs":["inclusions","mesh_tet"]}/' "$SAMPLES/scenes/fe_spheres_rods.json" \
  >"$WORK/scene.json"
expect_rc 0 "$RVEGEN" generate "$WORK/scene.json" -o "$WORK/a" -q
for f in mesh_tet.inp mesh_tet.msh mesh_tet.vtu run_tet_conductivity.inp run_tet_elasticity.inp; do
  [ -s "$WORK/a/$f" ] || fail "$f not written: $(ls "$WORK/a")"
done
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
# Conforming: no two nodes at one position, and every element face is shared by exactly two
# elements or lies in a box face (shared by one).
u = np.unique(np.round(pts / (1e-12 * L)).astype(np.int64), axis=0)
assert len(u) == len(pts), "%d nodes share a position" % (len(pts) - len(u))
faces = np.sort(np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 2, 3]], tets[:, [0, 1, 3]],
                                tets[:, [0, 1, 2]]]), axis=1)
f, count = np.unique(faces, axis=0, return_counts=True)
assert count.max() == 2, "a face shared by %d elements" % count.max()
single = f[count == 1]
on_plane = np.zeros(len(single), bool)
for a in range(3):
    for end in (0.0, L):
        on_plane |= np.all(np.abs(pts[single][:, :, a] - end) <= 1e-9 * L, axis=1)
assert on_plane.all(), "%d faces inside the box belong to one element" % (~on_plane).sum()
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
# The .msh: meshio reads it (the same nodes and elements as the .vtu, the phases as physical
# groups), its $Periodic pairs are one box size apart on each axis, and Gmsh checks it.
$py - "$WORK/a" <<'PY' || fail "mesh_tet.msh"
import sys
import numpy as np, meshio
d = sys.argv[1]
m = meshio.read(d + "/mesh_tet.msh")
v = meshio.read(d + "/mesh_tet.vtu")
assert np.allclose(m.points, v.points, atol=0, rtol=1e-15)
tets = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
tags = np.concatenate(m.cell_data["gmsh:physical"])
assert len(tets) == len(v.cells_dict["tetra"])
# The elements in .msh come phase by phase: compare as sets of (nodes, phase).
key = lambda t, p: set(zip(map(tuple, np.sort(t, axis=1)), p))
assert key(tets, tags - 1) == key(v.cells_dict["tetra"], v.cell_data_dict["phase"]["tetra"].astype(int))
L = 0.6
assert len(m.gmsh_periodic) == 3
for dim, (upper, lower), affine, pairs in m.gmsh_periodic:
    a = (upper - 2) // 2
    pairs = np.asarray(pairs)
    on_face = np.sum(np.abs(m.points[:, a] - L) <= 1e-9 * L)
    assert len(pairs) == on_face, (a, len(pairs), on_face)
    want = np.zeros(3); want[a] = L
    assert np.abs(m.points[pairs[:, 0]] - m.points[pairs[:, 1]] - want).max() <= 1e-9 * L
PY
gmsh -check "$WORK/a/mesh_tet.msh" >"$WORK/gmsh.log" 2>&1 || fail "gmsh -check: $(tail -3 "$WORK/gmsh.log")"
grep -q "Error" "$WORK/gmsh.log" && fail "gmsh -check: $(grep Error "$WORK/gmsh.log" | head -3)"
grep -q "Done checking mesh coherence" "$WORK/gmsh.log" || fail "gmsh did not check mesh_tet.msh"

# The decks: periodic equations, and CalculiX's conductivity against the FFT solver's.
for physics in conductivity elasticity; do
  $py "$(dirname "$0")/check_periodic_deck.py" "$WORK/a/mesh_tet.inp" \
    "$WORK/a/run_tet_$physics.inp" 0.6 || fail "periodic equations of run_tet_$physics.inp"
done
grep -q "ORIENTATION=O" "$WORK/a/run_tet_conductivity.inp" || fail "no oriented sections for the rods"
(cd "$WORK/a" && ccx -i run_tet_conductivity >ccx.log 2>&1) || fail "ccx: $(tail -5 "$WORK/a/ccx.log")"
grep -qi "\*ERROR\|\*WARNING\|over-constrained\|overconstrained" "$WORK/a/ccx.log" \
  && fail "ccx reports: $(grep -i "\*ERROR\|\*WARNING\|constrained" "$WORK/a/ccx.log" | head -3)"
$py "$SAMPLES/ccx_effective.py" "$WORK/a" run_tet_conductivity >"$WORK/a/effective.json" \
  || fail "ccx_effective.py"
$py - "$WORK/a" <<'PY' || fail "CalculiX on the tetrahedral mesh against the FFT solver"
import json, sys
d = sys.argv[1]
fft = json.load(open(d + "/report.json"))["effective"]["conductivity"]["tensor"]
fe = json.load(open(d + "/effective.json"))["conductivity"]
worst = max(abs(fe[i][j] - fft[i][j]) for i in range(3) for j in range(3)) / fft[0][0]
print("conductivity: CalculiX (tetrahedra) %s, FFT %s, largest difference %.2f %%"
      % ([round(fe[i][i], 4) for i in range(3)], [round(fft[i][i], 4) for i in range(3)], 100 * worst))
assert worst < 0.02, worst
PY

# The scene's sizes reach the mesher: a chord error ten times coarser gives fewer elements.
sed 's/"outputs"/"mesh_tet":{"chord_error":0.03},"outputs"/' "$WORK/scene.json" >"$WORK/coarse.json"
expect_rc 0 "$RVEGEN" generate "$WORK/coarse.json" -o "$WORK/coarse" -q --outputs mesh_tet
$py - "$WORK/a/report.json" "$WORK/coarse/report.json" <<'PY' || fail "mesh_tet.chord_error has no effect"
import json, sys
fine, coarse = (json.load(open(f))["mesh_tet"]["tetrahedra"] for f in sys.argv[1:3])
print("tetrahedra: chord error 0.003 %d, 0.03 %d" % (fine, coarse))
assert coarse < 0.7 * fine, (fine, coarse)
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
