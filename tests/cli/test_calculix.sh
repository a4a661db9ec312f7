#!/usr/bin/env bash
# The voxel mesh and its periodic decks, run by CalculiX (an outside solver, Debian calculix-ccx):
#  - the mesh is periodic: every node on an upper face, edge or corner has its image on the
#    lower one within 1e-9 of the box size; every such node is the first (eliminated) term of
#    exactly one equation per degree of freedom, and no master is eliminated;
#  - ccx runs the conductivity and elasticity decks with no error;
#  - with reduced-integration hexahedra (C3D8R), CalculiX solves the discrete problem of
#    rvegen's FFT solver (Willot's rotated scheme is that element, Schneider et al. 2016): the
#    conductivity agrees with the report to 1e-4, the stiffness within 3 % (CalculiX adds
#    hourglass control to C3D8R in mechanics); with full integration (C3D8, the decks' default)
#    the conductivity is stiffer, within 10 % on this coarse image (the two discretizations
#    meet as the voxels shrink: docs/benchmarks.md).
# usage: test_calculix.sh RVEGEN_BINARY SAMPLES_DIR WORK_DIR
set -u
RVEGEN=$1
SAMPLES=$2
WORK=$3
rm -rf "$WORK" && mkdir -p "$WORK"
source "$(dirname "$0")/lib.sh"
command -v ccx >/dev/null || { echo "FAIL: ccx (calculix-ccx) not installed"; exit 1; }

scene() {  # scene RESOLUTION PHYSICS_JSON
  echo "{\"box\":{\"size\":[1,1,1]},\"seed\":3,\"families\":[{\"name\":\"spheres\",\"shape\":\"sphere\",\"radius\":0.15,\"volume_fraction\":0.2}],\"voxels\":{\"resolution\":$1},\"materials\":{\"matrix\":{\"conductivity\":1,\"young\":3,\"poisson\":0.35},\"spheres\":{\"conductivity\":10,\"young\":70,\"poisson\":0.2}},\"homogenization\":{\"physics\":$2,\"voxel_rule\":\"plain\",\"tolerance\":1e-9},\"outputs\":[\"inclusions\",\"mesh_voxel\"]}"
}
scene 16 '["conductivity"]' >"$WORK/k.json"
scene 12 '["elasticity"]' >"$WORK/e.json"
"$RVEGEN" generate -q "$WORK/k.json" -o "$WORK/k" || fail "generate (conductivity)"
"$RVEGEN" generate -q "$WORK/e.json" -o "$WORK/e" || fail "generate (elasticity)"
# The materials give both physics: both decks are written (whatever the scene solves itself).
[ -s "$WORK/k/run_voxel_conductivity.inp" ] && [ -s "$WORK/k/run_voxel_elasticity.inp" ] \
  || fail "decks written: $(ls "$WORK/k")"
# Without elastic constants no elasticity deck (it could not run as written).
sed 's/,"young":3,"poisson":0.35//; s/,"young":70,"poisson":0.2//' "$WORK/k.json" >"$WORK/k_only.json"
"$RVEGEN" generate -q "$WORK/k_only.json" -o "$WORK/k_only" || fail "generate (conductivity only)"
[ -s "$WORK/k_only/run_voxel_conductivity.inp" ] && [ ! -e "$WORK/k_only/run_voxel_elasticity.inp" ] \
  || fail "decks written without elastic constants: $(ls "$WORK/k_only")"

# Periodicity of the mesh and the equations.
$py "$(dirname "$0")/check_periodic_deck.py" "$WORK/k/mesh_voxel.inp" \
  "$WORK/k/run_voxel_conductivity.inp" 1.0 17 || fail "periodic mesh and equations"

# The same mesh for Gmsh (format 4.1 with $Periodic) and ParaView (.vtu), read by meshio and Gmsh:
# every voxel a hexahedron with its phase, the periodic pairs one box length apart.
$py - "$WORK/k" <<'PY' || fail "mesh_voxel.msh / .vtu read by meshio"
import os, sys
import numpy as np, meshio
d = sys.argv[1]
m = meshio.read(os.path.join(d, "mesh_voxel.msh"))
v = meshio.read(os.path.join(d, "mesh_voxel.vtu"))
n = 16 ** 3
assert sum(len(c.data) for c in m.cells if c.type == "hexahedron") == n
assert len(v.cells) == 1 and v.cells[0].type == "hexahedron" and len(v.cells[0].data) == n
assert np.allclose(m.points, v.points)
# The phase of each hexahedron: physical tag - 1 in the .msh, cell data in the .vtu, by element id.
phase_vtu = v.cell_data["phase"][0]
for block, tags in zip(m.cells, m.cell_data["gmsh:physical"]):
    for nodes, tag in zip(block.data, tags):
        # The element's first node is its voxel's lower corner (i, j, k).
        i, j, k = np.rint(m.points[nodes[0]] * 16).astype(int)
        assert phase_vtu[i + 16 * (j + 16 * k)] == tag - 1
assert m.gmsh_periodic and len(m.gmsh_periodic) == 3
for dim, (slave, master), affine, pairs in m.gmsh_periodic:
    a = (slave - 2) // 2
    pairs = np.asarray(pairs)
    assert len(pairs) == 17 * 17
    diff = m.points[pairs[:, 0]] - m.points[pairs[:, 1]]
    want = np.zeros(3); want[a] = 1.0
    assert np.allclose(diff, want, atol=1e-12), (slave, diff[:2])
PY
gmsh -check "$WORK/k/mesh_voxel.msh" >"$WORK/gmsh.log" 2>&1 || fail "gmsh -check: $(tail -3 "$WORK/gmsh.log")"
grep -q "Error" "$WORK/gmsh.log" && fail "gmsh -check: $(grep Error "$WORK/gmsh.log" | head -3)"
grep -q "Done checking mesh coherence" "$WORK/gmsh.log" || fail "gmsh did not check the mesh: $(tail -3 "$WORK/gmsh.log")"

run() {  # run DIR NAME ELEMENT -> DIR_ELEMENT/NAME.dat
  local d="$1_$3"
  rm -rf "$d" && cp -r "$1" "$d"
  sed -i "s/TYPE=C3D8,/TYPE=$3,/" "$d/mesh_voxel.inp"
  (cd "$d" && ccx -i "$2" >ccx.log 2>&1) || fail "ccx $2 ($3): $(tail -5 "$d/ccx.log")"
  # CalculiX prints its errors and warnings as *ERROR and *WARNING (the iterative solver's
  # progress lines say "error=").
  grep -qi "\*ERROR\|\*WARNING\|over-constrained\|overconstrained" "$d/ccx.log" && fail "ccx $2 ($3) reports: $(grep -i "\*ERROR\|\*WARNING\|constrained" "$d/ccx.log" | head -3)"
  $py "$SAMPLES/ccx_effective.py" "$d" "$2" >"$d/effective.json" || fail "ccx_effective.py $d $2"
}
run "$WORK/k" run_voxel_conductivity C3D8R
run "$WORK/k" run_voxel_conductivity C3D8
run "$WORK/e" run_voxel_elasticity C3D8R
$py - "$WORK" <<'PY' || fail "CalculiX against the FFT solver"
import json, os, sys
w = sys.argv[1]
def rep(d, what):
    return json.load(open(os.path.join(w, d, "report.json")))["effective"][what]["tensor"]
def ccx(d):
    return list(json.load(open(os.path.join(w, d, "effective.json"))).values())[0]
k, kr, kf = rep("k", "conductivity"), ccx("k_C3D8R"), ccx("k_C3D8")
worst = max(abs(kr[i][j] - k[i][j]) for i in range(3) for j in range(3)) / k[0][0]
print("conductivity: FFT %s, CalculiX C3D8R %s (largest difference %.1e), C3D8 %s"
      % ([round(k[i][i], 5) for i in range(3)], [round(kr[i][i], 5) for i in range(3)], worst,
         [round(kf[i][i], 5) for i in range(3)]))
assert worst < 1e-4, worst
for i in range(3):
    assert k[i][i] < kf[i][i] < 1.10 * k[i][i], (i, kf[i][i], k[i][i])
c, cr = rep("e", "stiffness"), ccx("e_C3D8R")
worst = max(abs(cr[i][j] - c[i][j]) for i in range(6) for j in range(6)) / max(abs(x) for r in c for x in r)
print("stiffness: CalculiX C3D8R against FFT, largest difference %.2f %% of C_max" % (100 * worst))
assert worst < 0.03, worst
PY

# Transversely isotropic fibres (each core its own orientation along its axis, engineering
# constants, orthotropic conductivity) and voids (debonded spheres: 1e-6 of the stiffest modulus)
# in the decks: CalculiX, its local-frame output turned back by ccx_effective.py, against the FFT
# report on the same plain voxels. Conductivity to 1e-4 (the same discrete problem; the voids'
# 1e-6 is the difference); stiffness within 3 % for the fibres alone, 8 % with voids (C3D8R's
# hourglass control acts most in the soft voxels).
ti() {  # ti NAME FAMILIES_JSON MATERIALS_JSON
  echo "{\"box\":{\"size\":[1,1,1]},\"seed\":3,\"families\":$2,\"voxels\":{\"resolution\":12},\"materials\":{\"matrix\":{\"conductivity\":1,\"young\":3,\"poisson\":0.35}$3},\"homogenization\":{\"physics\":[\"conductivity\",\"elasticity\"],\"voxel_rule\":\"plain\",\"tolerance\":1e-9},\"outputs\":[\"inclusions\",\"mesh_voxel\"]}" >"$WORK/$1.json"
  "$RVEGEN" generate -q "$WORK/$1.json" -o "$WORK/$1" || fail "generate $1"
  run "$WORK/$1" run_voxel_conductivity C3D8R
  rm -rf "$WORK/$1_e" && cp -r "$WORK/$1" "$WORK/$1_e"
  run "$WORK/$1_e" run_voxel_elasticity C3D8R
}
FIB='{"name":"fibres","shape":"cylinder","radius":0.08,"aspect_ratio":3,"volume_fraction":0.15,"orientation":{"law":"isotropic"}}'
FIBMAT=',"fibres":{"axial_conductivity":20,"transverse_conductivity":2,"axial_young":200,"transverse_young":15,"axial_shear":20,"axial_poisson":0.25,"transverse_poisson":0.3}'
PORES='{"name":"pores","shape":"sphere","radius":0.12,"volume_fraction":0.1,"debonding":{"fraction":1,"gap":0.04}}'
ti ti "[$FIB]" "$FIBMAT"
ti tivoid "[$FIB,$PORES]" "$FIBMAT"',"pores":{"conductivity":5,"young":30,"poisson":0.25}'
grep -q "ORIENTATION=O" "$WORK/ti/run_voxel_elasticity.inp" || fail "no oriented sections for the fibres"
grep -q "ELSET=pores_void" "$WORK/tivoid/run_voxel_conductivity.inp" || fail "no section for the voids"
$py - "$WORK" <<'PY' || fail "CalculiX against the FFT solver, fibres and voids"
import json, os, sys
w = sys.argv[1]
def rel(a, b):
    return max(abs(x - y) for ra, rb in zip(a, b) for x, y in zip(ra, rb)) / max(abs(x) for r in a for x in r)
for d, stiff_tol in (("ti", 0.03), ("tivoid", 0.08)):
    rep = json.load(open(os.path.join(w, d, "report.json")))["effective"]
    k = list(json.load(open(os.path.join(w, d + "_C3D8R", "effective.json"))).values())[0]
    kk = rel(rep["conductivity"]["tensor"], k)
    c = json.load(open(os.path.join(w, d + "_e_C3D8R", "effective.json")))["stiffness"]
    cc = rel(rep["stiffness"]["tensor"], c)
    print("%s: conductivity %.1e, stiffness %.2f %% from the FFT report" % (d, kk, 100 * cc))
    assert kk < 1e-4, (d, kk)
    assert cc < stiff_tol, (d, cc)
PY

finish "CalculiX checks"
