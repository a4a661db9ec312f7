#!/usr/bin/env bash
# rvegen homogenize under an MPI launcher: 2 and 3 ranks share the voxel grid in z slabs (the
# grid's sides are uneven, so the slabs and FFTW's transposed y slabs differ in size) and give
# one process's conductivity and stiffness to 1e-10 relative, with coated spheres, transversely
# isotropic rods and laminate voxels; an error is said once.
# usage: test_homogenize_mpi.sh RVEGEN_BINARY MPIRUN WORK_DIR
set -u
RVEGEN=$1
MPIRUN=$2
WORK=$3
rm -rf "$WORK" && mkdir -p "$WORK"
source "$(dirname "$0")/lib.sh"
ranks() { local n=$1; shift; "$MPIRUN" --allow-run-as-root --oversubscribe -np "$n" "$@"; }
cat >"$WORK/scene.json" <<'JSON'
{"box":{"size":[0.5,0.5,0.5]},"seed":3,"families":[
 {"name":"spheres","shape":"sphere","radius":0.05,"volume_fraction":0.2,"coating":{"thickness":0.01}},
 {"name":"rods","shape":"cylinder","radius":0.02,"aspect_ratio":5,"count":8}],
 "voxels":{"resolution":[30,28,25]},
 "materials":{"matrix":{"conductivity":1,"young":3,"poisson":0.35},
  "spheres":{"conductivity":10,"young":70,"poisson":0.2},
  "spheres.coating":{"conductivity":3,"young":10,"poisson":0.3},
  "rods":{"axial_conductivity":50,"transverse_conductivity":5,"axial_young":230,
          "transverse_young":15,"axial_shear":27,"axial_poisson":0.2,"transverse_poisson":0.4}},
 "homogenization":{"physics":["conductivity","elasticity"],"tolerance":1e-8}}
JSON
expect_rc 0 "$RVEGEN" generate "$WORK/scene.json" -o "$WORK/rve" -q --outputs inclusions
expect_rc 0 "$RVEGEN" homogenize "$WORK/rve" "$WORK/scene.json"
cp "$WORK/last.out" "$WORK/one.json"
for n in 2 3; do
  expect_rc 0 ranks $n "$RVEGEN" homogenize "$WORK/rve" "$WORK/scene.json"
  cp "$WORK/last.out" "$WORK/ranks$n.json"
done
$py - "$WORK" <<'PY' || fail "the ranks' result differs from one process's"
import json, sys
w = sys.argv[1]
one = json.load(open(w + "/one.json"))
assert "ranks" not in one
for n in (2, 3):
    many = json.load(open("%s/ranks%d.json" % (w, n)))
    assert many["ranks"] == n, many.get("ranks")
    assert many["phase_shares"] == one["phase_shares"], n
    assert many["voxel_rule"]["cut_voxels"] == one["voxel_rule"]["cut_voxels"] > 1000, n
    for physics in ("conductivity", "stiffness"):
        a, b = one[physics]["tensor"], many[physics]["tensor"]
        scale = max(abs(v) for row in a for v in row)
        err = max(abs(x - y) for ra, rb in zip(a, b) for x, y in zip(ra, rb)) / scale
        print("%d ranks, %s: %.1e relative" % (n, physics, err))
        assert err < 1e-10, (n, physics, err)
PY
# An error is said once, with one process's exit code, and nothing is printed.
sed 's/"tolerance":1e-8/"tolerance":-1/' "$WORK/scene.json" >"$WORK/bad.json"
expect_rc 2 ranks 2 "$RVEGEN" homogenize "$WORK/rve" "$WORK/bad.json"
[ "$(grep -c "tolerance" "$WORK/last.err")" -eq 1 ] ||
  fail "the error was not said once: $(cat "$WORK/last.err")"
[ -s "$WORK/last.out" ] && fail "a failed run printed a result"

finish "homogenize MPI tests"
