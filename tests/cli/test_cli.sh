#!/usr/bin/env bash
# End-to-end tests of the rvegen command line: outputs, exit codes, bad input, determinism.
# usage: test_cli.sh RVEGEN_BINARY WORK_DIR
set -u
RVEGEN=$1
WORK=$2
rm -rf "$WORK" && mkdir -p "$WORK"
source "$(dirname "$0")/lib.sh"

# Default scene: all four files, no overlap by the independent audit.
expect_rc 0 "$RVEGEN" generate -q --outputs inclusions,voxels,h5,amitex,levelsets -o "$WORK/default"
for f in inclusions.json inclusions.vtp voxels.vti report.json rve.h5 rve.xdmf material.vtk; do
  [ -s "$WORK/default/$f" ] || fail "default run did not write $f"
done
# Straight inclusions need no level set.
[ -e "$WORK/default/levelsets.vdb" ] && fail "levelsets.vdb written for straight inclusions"
# The HDF5 file read back with h5py: labels, partial volumes, inclusion table, metadata.
$py - "$WORK/default" <<'PY' || fail "rve.h5 read back"
import json, sys
import h5py
d = sys.argv[1]
report = json.load(open(d + "/report.json"))
inclusions = json.load(open(d + "/inclusions.json"))["inclusions"]
with h5py.File(d + "/rve.h5", "r") as f:
    assert f.attrs["format"] in (b"rvegen.h5/1", "rvegen.h5/1"), f.attrs["format"]
    phase = f["voxels/phase"][:]
    assert phase.shape == (64, 64, 64), phase.shape
    frac = f["voxels/fraction"][:]
    assert abs(frac.mean() - report["voxels"]["partial_volume_fraction"]) < 1e-6
    assert abs(frac.mean() - report["volume_fraction"]) < 0.005
    assert f["inclusions/center"].shape == (len(inclusions), 3)
    assert list(f["inclusions/id"][:]) == [i["id"] for i in inclusions]
    names = [n.decode() for n in f["phases/name"][:]]
    assert names == [p["name"] for p in report["phases"]], names
    assert json.loads(f.attrs["report"])["status"] == "ok"
PY
# The AMITEX material map: 10-line header, big-endian unsigned shorts 1..N.
$py - "$WORK/default/material.vtk" <<'PY' || fail "material.vtk"
import sys
import numpy as np
raw = open(sys.argv[1], "rb").read()
lines = raw.split(b"\n", 10)
assert lines[0] == b"# vtk DataFile Version 4.5" and lines[4] == b"DIMENSIONS 65 65 65", lines[:5]
data = np.frombuffer(lines[10], dtype=">u2")
assert data.size == 64 ** 3 and data.min() == 1 and data.max() == 4, (data.size, data.min(), data.max())
PY
ls -A "$WORK/default" | grep -q '^\.' && fail "temporary files left behind"
expect_rc 0 "$RVEGEN" check "$WORK/default/inclusions.json"
expect_rc 0 "$RVEGEN" check --json "$WORK/default/inclusions.json"
$py -c "import json,sys; d=json.load(open('$WORK/last.out')); sys.exit(0 if d['count']==0 and d['n']>500 else 1)" \
  || fail "check --json on the default RVE"
$py -c "import json,sys; r=json.load(open('$WORK/default/report.json')); sys.exit(0 if r['status']=='ok' and abs(r['volume_fraction']-r['target_volume_fraction'])<0.002 else 1)" \
  || fail "report.json of the default run"

# Same seed, same bytes.
expect_rc 0 "$RVEGEN" generate -q -o "$WORK/default2"
cmp -s "$WORK/default/inclusions.json" "$WORK/default2/inclusions.json" || fail "same seed gave a different RVE"

# Bad input: exit 2, a message naming the problem, nothing written.
bad() {  # bad NAME JSON EXPECTED_MESSAGE_PART
  echo "$2" >"$WORK/$1.json"
  expect_rc 2 "$RVEGEN" generate -q "$WORK/$1.json" -o "$WORK/out_$1"
  grep -q -- "$3" "$WORK/last.err" || fail "$1: message does not mention '$3': $(cat "$WORK/last.err")"
  [ -e "$WORK/out_$1" ] && fail "$1: output directory created on invalid input"
}
BOX='"box":{"size":[1,1,1]}'
bad unknown_key "{$BOX,\"families\":[{\"shape\":\"sphere\",\"radius\":0.1,\"count\":1}],\"sede\":3}" "sede"
bad negative_radius "{$BOX,\"families\":[{\"shape\":\"sphere\",\"radius\":-0.1,\"count\":1}]}" "families\[0\].radius"
bad nan_value "{$BOX,\"families\":[{\"shape\":\"sphere\",\"radius\":NaN,\"count\":1}]}" "not valid JSON"
bad impossible_fraction "{$BOX,\"families\":[{\"shape\":\"sphere\",\"radius\":0.05,\"volume_fraction\":0.75}]}" "exceeds"
bad box_too_small "{\"box\":{\"size\":[0.1,1,1]},\"families\":[{\"shape\":\"sphere\",\"radius\":0.06,\"count\":1}]}" "does not fit"
bad missing_size "{$BOX,\"families\":[{\"shape\":\"cylinder\",\"radius\":0.02,\"count\":1}]}" "aspect_ratio"
bad zero_count "{$BOX,\"families\":[{\"shape\":\"sphere\",\"radius\":0.1,\"count\":0}]}" "families\[0\].count: must be an integer in \[1, 1e8\]"
# A wave far shorter than the fibre's radius: refused up front (it hung in the packer).
bad tiny_wavelength "{$BOX,\"md\":{\"max_seconds\":20},\"families\":[{\"shape\":\"cylinder\",\"radius\":0.02,\"aspect_ratio\":5,\"volume_fraction\":0.1,\"waviness\":{\"amplitude\":0.2,\"wavelength\":1e-4}}]}" "families\[0\].waviness.wavelength: .*bends too sharply"
bad unknown_output "{$BOX,\"families\":[{\"shape\":\"sphere\",\"radius\":0.1,\"count\":1}],\"outputs\":[\"inclusions\",\"stl\"]}" "outputs\[1\]"

# Every output has a switch: exactly the files asked for (and report.json) are written; the
# tessellated mesh (surfaces.vtp) only when asked for, or for modified inclusions.
echo "{$BOX,\"families\":[{\"shape\":\"sphere\",\"radius\":0.1,\"count\":5}],\"outputs\":[\"inclusions\"]}" >"$WORK/only_inclusions.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/only_inclusions.json" -o "$WORK/out_only_inclusions"
[ "$(ls "$WORK/out_only_inclusions" | tr '\n' ' ')" = "inclusions.json inclusions.vtp report.json " ] \
  || fail "outputs [inclusions] wrote: $(ls "$WORK/out_only_inclusions" | tr '\n' ' ')"
echo "{$BOX,\"families\":[{\"shape\":\"sphere\",\"radius\":0.1,\"count\":5}],\"outputs\":[\"amitex\",\"mesh\"]}" >"$WORK/amitex_mesh.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/amitex_mesh.json" -o "$WORK/out_amitex_mesh"
[ "$(ls "$WORK/out_amitex_mesh" | tr '\n' ' ')" = "amitex_algorithm.xml amitex_loading.xml amitex_materials.xml amitex_run.sh material.vtk report.json surfaces.vtp zoneID.vtk " ] \
  || fail "outputs [amitex, mesh] wrote: $(ls "$WORK/out_amitex_mesh" | tr '\n' ' ')"
# The tetrahedral mesh from the command line (its full checks are test_tet_mesh.sh's, in the main
# build): the mesh files, the conductivity deck (only conductivities given: no elasticity deck),
# and the report's count beside the estimate the memory check made.
echo "{$BOX,\"seed\":2,\"families\":[{\"name\":\"beads\",\"shape\":\"sphere\",\"radius\":0.15,\"count\":3}],\"materials\":{\"matrix\":{\"conductivity\":1},\"beads\":{\"conductivity\":5}},\"outputs\":[\"mesh_tet\"],\"mesh_tet\":{\"chord_error\":0.05}}" >"$WORK/tet_small.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/tet_small.json" -o "$WORK/out_tet"
[ "$(ls "$WORK/out_tet" | tr '\n' ' ')" = "mesh_tet.inp mesh_tet.msh mesh_tet.vtu report.json run_tet_conductivity.inp " ] \
  || fail "outputs [mesh_tet] wrote: $(ls "$WORK/out_tet" | tr '\n' ' ')"
$py - "$WORK/out_tet/report.json" <<'PY' || fail "mesh_tet report"
import json, sys
m = json.load(open(sys.argv[1]))["mesh_tet"]
assert m["tetrahedra"] > 1000, m["tetrahedra"]
assert 0.6 < m["estimated_tetrahedra"] / m["tetrahedra"] < 1.6, (m["estimated_tetrahedra"], m["tetrahedra"])
PY
# Default outputs: one voxel file (voxels.vti, compressed), no rve.h5 or material.vtk; the last
# line gives the bytes written, which are the directory's.
expect_rc 0 "$RVEGEN" generate "$WORK/only_inclusions.json" --outputs inclusions,voxels -o "$WORK/out_cli_list"
[ "$(ls "$WORK/out_cli_list" | tr '\n' ' ')" = "inclusions.json inclusions.vtp report.json voxels.vti " ] \
  || fail "--outputs inclusions,voxels wrote: $(ls "$WORK/out_cli_list" | tr '\n' ' ')"
expect_rc 0 "$RVEGEN" generate -o "$WORK/out_default_outputs"
[ "$(ls "$WORK/out_default_outputs" | tr '\n' ' ')" = "inclusions.json inclusions.vtp report.json voxels.vti " ] \
  || fail "default outputs: $(ls "$WORK/out_default_outputs" | tr '\n' ' ')"
grep -q 'compressor="vtkZLibDataCompressor"' "$WORK/out_default_outputs/voxels.vti" \
  || fail "voxels.vti is not compressed"
cmp -s "$WORK/out_default_outputs/voxels.vti" "$WORK/default/voxels.vti" \
  || fail "voxels.vti differs between runs of the same scene"
bytes=$(du -cb "$WORK/out_default_outputs"/* | tail -1 | cut -f1)
$py - "$WORK/last.err" "$bytes" <<'PY' || fail "the last line does not give the bytes written: $(tail -1 "$WORK/last.err")"
import re, sys
last = open(sys.argv[1]).read().strip().splitlines()[-1]
m = re.search(r"\(([0-9.]+) (B|KB|MB|GB) in 4 files\)$", last)
assert m, last
value = float(m.group(1)) * {"B": 1, "KB": 1e3, "MB": 1e6, "GB": 1e9}[m.group(2)]
assert abs(value - int(sys.argv[2])) <= 0.05 * int(sys.argv[2]) + 1000, (value, sys.argv[2])
PY
# inclusions.vtp stays small: at most 300 bytes an inclusion (it took about 400 uncompressed).
echo "{$BOX,\"seed\":4,\"families\":[{\"shape\":\"sphere\",\"volume_fraction\":0.3,\"count\":3000}],\"outputs\":[\"inclusions\"]}" >"$WORK/vtp_size.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/vtp_size.json" -o "$WORK/vtp_size"
vtp_bytes=$(stat -c %s "$WORK/vtp_size/inclusions.vtp")
[ "$vtp_bytes" -le $((300 * 3000)) ] || fail "inclusions.vtp takes $((vtp_bytes / 3000)) bytes an inclusion"
grep -q 'compressor="vtkZLibDataCompressor"' "$WORK/vtp_size/inclusions.vtp" || fail "inclusions.vtp is not compressed"
# The statistics are an output: in the default report (g(r) of spheres, nearest neighbours, their
# timing), absent when the list leaves them out, back when it names them.
$py - "$WORK/out_default_outputs/report.json" "$WORK/out_cli_list/report.json" <<'PY' || fail "statistics output switch"
import json, sys
full, lean = (json.load(open(p)) for p in sys.argv[1:3])
assert "nearest_neighbour_distance" in full and "statistics" in full["timings"], full.keys()
assert "radial_distribution" in full["families"][0]
assert "nearest_neighbour_distance" not in lean and "statistics" not in lean["timings"]
assert "radial_distribution" not in lean["families"][0]
PY
expect_rc 0 "$RVEGEN" generate -q "$WORK/only_inclusions.json" --outputs inclusions,statistics -o "$WORK/out_stats"
$py - "$WORK/out_stats/report.json" <<'PY' || fail "--outputs inclusions,statistics lacks the statistics"
import json, sys
r = json.load(open(sys.argv[1]))
# five spheres of radius 0.1 that do not overlap: centres at least a diameter apart
assert r["nearest_neighbour_distance"]["min"] >= 0.2 - 1e-9, r["nearest_neighbour_distance"]
assert len(r["families"][0]["radial_distribution"]["g"]) == 50
PY
expect_rc 2 "$RVEGEN" generate "$WORK/only_inclusions.json" --outputs inclusions,voxel -o "$WORK/out_bad_list"
grep -q 'unknown output "voxel"' "$WORK/last.err" || fail "--outputs with a typo: $(cat "$WORK/last.err")"
[ -e "$WORK/out_bad_list" ] && fail "--outputs with a typo wrote $WORK/out_bad_list"
# Help on every command (exit 0, on stdout), the version, and a misspelled key named.
for c in generate check homogenize default-scene; do
  expect_rc 0 "$RVEGEN" $c --help
  grep -q "^usage: rvegen $c" "$WORK/last.out" || fail "$c --help: $(head -2 "$WORK/last.out")"
done
expect_rc 0 "$RVEGEN" --version
grep -Eq '^rvegen [0-9]+\.[0-9]+\.[0-9]+$' "$WORK/last.out" || fail "--version: $(cat "$WORK/last.out")"
expect_rc 2 "$RVEGEN" generate --no-such-option
grep -q "unknown option --no-such-option" "$WORK/last.err" || fail "unknown option not named"
# Argument errors: one line and a "did you mean", with the help a flag away (not printed).
for args in "generte" "generate --thread 2" "homogenize --quite a b" "check --max-pair 3 x" "study --job 2 s.json"; do
  expect_rc 2 "$RVEGEN" $args
  [ "$(wc -l <"$WORK/last.err")" -le 2 ] || fail "$args: $(wc -l <"$WORK/last.err") lines of error"
  grep -q "did you mean" "$WORK/last.err" || fail "$args: no suggestion: $(cat "$WORK/last.err")"
  grep -q -- "--help shows the usage" "$WORK/last.err" || fail "$args: no pointer to --help"
done
grep -q 'did you mean "--jobs"' "$WORK/last.err" || fail "study --job: $(cat "$WORK/last.err")"
expect_rc 2 "$RVEGEN" generate -q --outputs inclusions,voxel -o "$WORK/out_voxel_typo"
grep -q -- '--outputs: unknown output "voxel" (did you mean "voxels"?)' "$WORK/last.err" \
  || fail "--outputs typo: $(cat "$WORK/last.err")"
echo '{"box":{"size":[1,1,1]},"families":[{"shape":"sphere","radius":0.05,"volume_fraction":0.2}]}' >"$WORK/a_scene.json"
expect_rc 2 "$RVEGEN" check "$WORK/a_scene.json"
grep -q "this is a scene" "$WORK/last.err" || fail "check on a scene: $(cat "$WORK/last.err")"
echo '{"box":{"size":[1,1,1]},"families":[{"shape":"sphere","radius":0.05,"volume_fracion":0.2}]}' >"$WORK/typo.json"
expect_rc 2 "$RVEGEN" generate -q "$WORK/typo.json" -o "$WORK/out_typo"
grep -q 'families\[0\].volume_fracion: unknown key (did you mean "volume_fraction"?)' "$WORK/last.err" \
  || fail "misspelled key: $(cat "$WORK/last.err")"
[ -e "$WORK/out_typo" ] && fail "a misspelled key wrote $WORK/out_typo"
[ -e "$WORK/default/surfaces.vtp" ] && fail "surfaces.vtp written for plain inclusions without mesh"
expect_rc 2 "$RVEGEN" generate -q "$WORK/does_not_exist.json" -o "$WORK/out_missing"
expect_rc 2 "$RVEGEN" frobnicate

# A target RSA cannot reach: exit 3, report says so, the configuration has no overlap.
echo "{$BOX,\"seed\":3,\"method\":\"rsa\",\"families\":[{\"shape\":\"sphere\",\"radius\":0.07,\"volume_fraction\":0.5}],\"voxels\":{\"resolution\":16}}" >"$WORK/rsa_wall.json"
expect_rc 3 "$RVEGEN" generate -q "$WORK/rsa_wall.json" -o "$WORK/rsa_wall"
$py -c "import json,sys; r=json.load(open('$WORK/rsa_wall/report.json')); sys.exit(0 if r['status']=='target_not_reached' and 0.2<r['volume_fraction']<0.5 else 1)" \
  || fail "report of the unreachable target"
expect_rc 0 "$RVEGEN" check "$WORK/rsa_wall/inclusions.json"

# A target beyond random close packing for MD (70 % of monodisperse spheres): it jams, exits 3
# within its budget, and writes the best valid configuration, denser than RSA's.
echo "{$BOX,\"seed\":3,\"families\":[{\"shape\":\"sphere\",\"radius\":0.07,\"volume_fraction\":0.7}],\"voxels\":{\"resolution\":16}}" >"$WORK/md_wall.json"
expect_rc 3 "$RVEGEN" generate -q "$WORK/md_wall.json" -o "$WORK/md_wall"
$py -c "import json,sys; r=json.load(open('$WORK/md_wall/report.json')); sys.exit(0 if r['status']=='target_not_reached' and r['method']=='md' and 0.55<r['volume_fraction']<0.7 else 1)" \
  || fail "report of the target MD cannot reach"
expect_rc 0 "$RVEGEN" check "$WORK/md_wall/inclusions.json"

# Fibres above their jamming fraction (L/D 20, 0.40): exit 3 within the time budget (how far it got
# depends on the machine: the sanitizer build reaches 0.03 in 5 s), the
# orientation tensor of the written fibres still the law's, no overlap.
echo "{$BOX,\"seed\":3,\"md\":{\"max_seconds\":5},\"families\":[{\"shape\":\"cylinder\",\"radius\":0.015,\"aspect_ratio\":20,\"volume_fraction\":0.4,\"orientation\":{\"law\":\"tensor\",\"a2\":[[0.6,0.1,0],[0.1,0.3,0],[0,0,0.1]]}}],\"voxels\":{\"resolution\":16}}" >"$WORK/fibre_wall.json"
expect_rc 3 "$RVEGEN" generate -q "$WORK/fibre_wall.json" -o "$WORK/fibre_wall"
$py - "$WORK/fibre_wall" <<'PY' || fail "report of the fibre target above jamming"
import json, sys
d = sys.argv[1]
r = json.load(open(d + "/report.json"))
f = r["families"][0]
assert r["status"] == "target_not_reached" and 0.0 < r["volume_fraction"] < 0.4, r["volume_fraction"]
# A2 recomputed from the written inclusions, against the law's.
inc = json.load(open(d + "/inclusions.json"))["inclusions"]
a = [[0.0] * 3 for _ in range(3)]
for i in inc:
    h = i["half_axis"]
    n = sum(x * x for x in h) ** 0.5
    for p in range(3):
        for q in range(3):
            a[p][q] += h[p] * h[q] / (n * n * len(inc))
want = [[0.6, 0.1, 0], [0.1, 0.3, 0], [0, 0, 0.1]]
err = max(abs(a[p][q] - want[p][q]) for p in range(3) for q in range(3))
assert err < 1e-8 and f["orientation_tensor_error"] < 1e-8, (err, f["orientation_tensor_error"])
assert f["target_orientation_tensor"] == want
PY
expect_rc 0 "$RVEGEN" check "$WORK/fibre_wall/inclusions.json"

# check: overlapping pairs are listed with their type, exit 1.
cat >"$WORK/overlap.json" <<'JSON'
{"format": "rvegen.inclusions/1", "box": {"origin": [0,0,0], "size": [1,1,1], "periodic": true},
 "inclusions": [
  {"id": 0, "family": 0, "shape": "cylinder", "center": [0.5,0.5,0.5], "radius": 0.05, "half_axis": [0,0,0.2]},
  {"id": 1, "family": 0, "shape": "sphere", "center": [0.58,0.5,0.5], "radius": 0.05},
  {"id": 2, "family": 0, "shape": "sphere", "center": [0.02,0.2,0.2], "radius": 0.05},
  {"id": 3, "family": 0, "shape": "sphere", "center": [0.97,0.2,0.2], "radius": 0.05},
  {"id": 4, "family": 1, "shape": "ellipsoid", "center": [0.2,0.8,0.8], "semi_axes": [0.1,0.05,0.05],
   "rotation": [[1,0,0],[0,1,0],[0,0,1]]}]}
JSON
expect_rc 1 "$RVEGEN" check --json "$WORK/overlap.json"
$py - "$WORK/last.out" <<'PY' || fail "check --json listing"
import json, sys
d = json.load(open(sys.argv[1]))
pairs = sorted((p["a"], p["b"], p["type"]) for p in d["overlapping_pairs"])
assert d["n"] == 5 and d["count"] == 2, d
assert pairs == [(0, 1, "sc2"), (2, 3, "ss")], pairs
PY
echo '{"format": "rvegen.inclusions/1", "box": {"size": [1,1,1]}, "inclusions": [{"id": 0, "shape": "sphere", "center": [0,0,0], "radius": -1}]}' >"$WORK/bad_list.json"
expect_rc 2 "$RVEGEN" check "$WORK/bad_list.json"
grep -q "inclusions\[0\].radius" "$WORK/last.err" || fail "check error does not name the key"

# Modifiers: coated, wavy, deformed and debonded inclusions; level sets written and exact phases.
cat >"$WORK/modified.json" <<'JSON'
{"box": {"size": [1, 1, 1]}, "seed": 4,
 "families": [
  {"name": "coated", "shape": "sphere", "radius": 0.08, "volume_fraction": 0.1, "coating": {"thickness": 0.015}},
  {"name": "wavy", "shape": "cylinder", "radius": 0.025, "aspect_ratio": 5, "volume_fraction": 0.04,
   "waviness": {"amplitude": 0.01, "wavelength": 0.1}},
  {"name": "bumpy", "shape": "sphere", "radius": 0.06, "volume_fraction": 0.05, "deformation": {"amplitude": 0.2}},
  {"name": "debonded", "shape": "sphere", "radius": 0.06, "volume_fraction": 0.04,
   "debonding": {"fraction": 0.25, "gap": 0.01}}],
 "voxels": {"resolution": 80}, "levelsets": {"voxel_size": 0.01}}
JSON
expect_rc 0 "$RVEGEN" generate -q "$WORK/modified.json" -o "$WORK/modified"
[ -s "$WORK/modified/levelsets.vdb" ] || fail "modified scene: no levelsets.vdb"
expect_rc 0 "$RVEGEN" check "$WORK/modified/inclusions.json"
$py - "$WORK/modified/report.json" <<'PY' || fail "modified scene report"
import json, sys
r = json.load(open(sys.argv[1]))
kinds = sorted(p["kind"] for p in r["phases"])
assert kinds == ["core"] * 4 + ["interphase", "matrix", "void"], kinds
for p in r["phases"]:
    assert abs(p["volume_fraction"] - p["voxel_volume_fraction"]) < 0.004, p
# The coated spheres' shells are exact in closed form: no grid unless level sets are asked for.
names = sorted(g["name"] for g in r["levelsets"]["grids"])
assert names == ["bumpy_core", "wavy_core"], names
assert r["voxels"]["conflicts"] == 0
PY
expect_rc 0 "$RVEGEN" generate -q "$WORK/modified.json" -o "$WORK/modified_ls" --outputs inclusions,levelsets
$py -c "import json,sys; r=json.load(open('$WORK/modified_ls/report.json')); n=sorted(g['name'] for g in r['levelsets']['grids']); sys.exit(0 if n==['bumpy_core','coated_interphase','wavy_core'] else 1)" \
  || fail "levelsets asked for: the coated shells get their grid"

# Coated fibres: outputs sized to what they carry (no level set, no surface mesh of a straight
# coated fibre; within 2x of the uncoated twin's bytes), continuous fibres written as such.
for c in 0 0.002; do
  coat=""
  [ "$c" = 0 ] || coat=", \"coating\": {\"thickness\": $c}"
  echo "{\"box\": {\"size\": [1,1,0.2]}, \"seed\": 1, \"families\": [{\"name\": \"fibres\", \"shape\": \"cylinder\", \"radius\": 0.03, \"length\": \"through\", \"volume_fraction\": 0.55$coat}]}" >"$WORK/through_$c.json"
  expect_rc 0 "$RVEGEN" generate -q "$WORK/through_$c.json" -o "$WORK/through_$c"
  expect_rc 0 "$RVEGEN" check "$WORK/through_$c/inclusions.json"
done
[ ! -e "$WORK/through_0.002/levelsets.vdb" ] && [ ! -e "$WORK/through_0.002/surfaces.vtp" ] \
  || fail "coated straight fibres: a level set or surface mesh was written by default"
plain=$(du -sb "$WORK/through_0" | cut -f1); coated=$(du -sb "$WORK/through_0.002" | cut -f1)
[ "$coated" -le $((2 * plain)) ] || fail "coated output $coated bytes, more than twice the plain $plain"
$py - "$WORK/through_0.002" <<'PY' || fail "continuous coated fibres: report and inclusion list"
import json, sys
d = sys.argv[1]
r = json.load(open(d + "/report.json"))
assert r["status"] == "ok" and r["volume_fraction"] >= 0.55 - 1e-9, r["volume_fraction"]
inc = json.load(open(d + "/inclusions.json"))["inclusions"]
assert all(i["through"] and i["half_axis"] == [0.0, 0.0, 0.1] for i in inc)
shell = [p for p in r["phases"] if p["kind"] == "interphase"][0]
# A tube without caps: (r + t)^2 / r^2 - 1 of the cores.
want = r["volume_fraction"] * ((0.032 / 0.03) ** 2 - 1)
assert abs(shell["volume_fraction"] - want) < 1e-9, (shell, want)
assert abs(shell["voxel_volume_fraction"] - want) < 0.01, shell
PY
bad waviness_sphere '{"box": {"size": [1,1,1]}, "families": [{"shape": "sphere", "radius": 0.05, "volume_fraction": 0.1, "waviness": {"amplitude": 0.01, "wavelength": 0.1}}]}' \
  "families\[0\].waviness: waviness applies to cylinders only"
bad thick_coating '{"box": {"size": [1,1,1]}, "families": [{"shape": "sphere", "radius": 0.05, "volume_fraction": 0.5, "coating": {"thickness": 0.03}}]}' \
  "envelopes"
bad nan_gap '{"box": {"size": [1,1,1]}, "families": [{"shape": "sphere", "radius": 0.05, "volume_fraction": 0.1, "debonding": {"fraction": 0.2, "gap": -1}}]}' \
  "families\[0\].debonding.gap"

# --- Never a wrong success, never a crash ------------------------------------------------
# Non-periodic boxes with large inclusions once exited 0 with overlapping pairs.
echo '{"box":{"size":[1,1,1],"periodic":false},"seed":1,"families":[{"shape":"sphere","radius":0.3,"volume_fraction":0.2}],"voxels":{"resolution":16}}' >"$WORK/closed.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/closed"
expect_rc 0 "$RVEGEN" check "$WORK/closed/inclusions.json"
$py -c "import json,sys; r=json.load(open('$WORK/closed/report.json')); t=r['timings']; sys.exit(0 if 'audit' in t and r['audit_seconds']>=0 and r['seconds']>=sum(t.values())-1e-6 and r['peak_memory_mb']>0 else 1)" \
  || fail "report: audit time, timings of every phase within the total, peak memory"

# An RVE that fails the audit (fault injected after packing): exit 4, the previous set intact.
cp -r "$WORK/closed" "$WORK/closed.before"
RVEGEN_TEST_FAULT=overlap expect_rc 4 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/closed"
grep -q "failed the exact audit" "$WORK/last.err" || fail "audit failure message: $(cat "$WORK/last.err")"
diff -r "$WORK/closed" "$WORK/closed.before" >/dev/null || fail "audit failure changed the output directory"
ls -A "$WORK" | grep -q '\.rvegen-' && fail "audit failure left a staging directory"
RVEGEN_TEST_FAULT=overlap expect_rc 4 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/fresh_fault"
[ -e "$WORK/fresh_fault" ] && fail "audit failure created the output directory"

# Outputs that cannot be written are found before the packing (no progress line printed).
echo x >"$WORK/a_file"
expect_rc 1 "$RVEGEN" generate "$WORK/closed.json" -o "$WORK/a_file/sub"
grep -q "^md:" "$WORK/last.err" && fail "packed before finding the output unwritable"
mkdir -p "$WORK/mine" && echo notes >"$WORK/mine/notes.txt"
expect_rc 1 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/mine"
grep -q "notes.txt" "$WORK/last.err" || fail "foreign file not named: $(cat "$WORK/last.err")"
[ "$(cat "$WORK/mine/notes.txt")" = notes ] || fail "foreign file touched"

# A bend radius of 1e300 is a straight fibre (it overflowed R^2 and exhausted memory): packed
# like one, the bend kept in the inclusion list, no overlap.
echo "{\"box\":{\"size\":[0.4,0.4,0.4]},\"seed\":2,\"families\":[{\"shape\":\"cylinder\",\"radius\":0.02,\"aspect_ratio\":5,\"volume_fraction\":0.2,\"curvature\":{\"radius\":1e300}}],\"voxels\":{\"resolution\":16}}" >"$WORK/huge_bend.json"
expect_rc 0 "$RVEGEN" generate -q --outputs inclusions "$WORK/huge_bend.json" -o "$WORK/huge_bend"
expect_rc 0 "$RVEGEN" check "$WORK/huge_bend/inclusions.json"
grep -q '"bend_radius": 1e+300' "$WORK/huge_bend/inclusions.json" || fail "huge bend radius not kept"
# Fibres entangled from the start (waves ten radii wide, 0.1 of the box): not one finds a valid
# place within the budget (five steps: a step budget, the same on any machine; the contacts
# push them apart within about ten); exit 3, and an empty box is not written over the previous
# set.
expect_rc 0 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/entangled"
cp "$WORK/entangled/inclusions.json" "$WORK/entangled.before"
echo "{$BOX,\"md\":{\"max_steps\":5},\"families\":[{\"shape\":\"cylinder\",\"radius\":0.02,\"aspect_ratio\":5,\"volume_fraction\":0.1,\"waviness\":{\"amplitude\":0.2,\"wavelength\":0.05}}]}" >"$WORK/entangled.json"
expect_rc 3 "$RVEGEN" generate -q "$WORK/entangled.json" -o "$WORK/entangled"
grep -q "not one inclusion could be placed" "$WORK/last.err" || fail "nothing placed: $(cat "$WORK/last.err")"
cmp -s "$WORK/entangled/inclusions.json" "$WORK/entangled.before" || fail "an empty RVE replaced the previous set"
[ -e "$WORK/entangled/levelsets.vdb" ] && fail "an empty RVE wrote level sets"

# A directory under an rvegen file name is the user's: refused, its content kept.
expect_rc 0 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/with_dir"
mkdir "$WORK/with_dir/levelsets.vdb" && echo precious >"$WORK/with_dir/levelsets.vdb/mine.txt"
expect_rc 1 "$RVEGEN" generate -q "$WORK/modified.json" -o "$WORK/with_dir"
grep -q "levelsets.vdb (not a regular file)" "$WORK/last.err" || fail "directory under an output name: $(cat "$WORK/last.err")"
[ "$(cat "$WORK/with_dir/levelsets.vdb/mine.txt")" = precious ] || fail "a user's directory in DIR was deleted"
# DIR as a symbolic link: the directory it points to gets the new set, the link stays a link;
# a link to a directory holding the user's files is refused like the directory itself.
# (A small scene with a level set: what is tested is where the files go.)
echo '{"box":{"size":[0.3,0.3,0.3]},"seed":3,"families":[{"shape":"sphere","radius":0.05,"volume_fraction":0.1,"coating":{"thickness":0.01}}],"voxels":{"resolution":16},"levelsets":{"voxel_size":0.015},"outputs":["inclusions","voxels","levelsets"]}' >"$WORK/small_ls.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/link_target"
ln -s "$WORK/link_target" "$WORK/link_dir"
expect_rc 0 "$RVEGEN" generate -q "$WORK/small_ls.json" -o "$WORK/link_dir"
[ -L "$WORK/link_dir" ] || fail "the link DIR was replaced by a directory"
[ -e "$WORK/link_target/levelsets.vdb" ] || fail "the link's target did not get the new set"
ln -s "$WORK/mine" "$WORK/link_mine"
expect_rc 1 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/link_mine"
[ "$(cat "$WORK/mine/notes.txt")" = notes ] || fail "foreign file behind a link touched"

# A set without level sets replaces one with them: no stale levelsets.vdb.
expect_rc 0 "$RVEGEN" generate -q "$WORK/small_ls.json" -o "$WORK/swap"
[ -e "$WORK/swap/levelsets.vdb" ] || fail "coated scene wrote no levelsets.vdb"
expect_rc 0 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/swap"
[ -e "$WORK/swap/levelsets.vdb" ] && fail "stale levelsets.vdb survived a new set"

# Killed at any moment: the directory holds the old set or the new one, whole.
echo '{"box":{"size":[1,1,1]},"seed":5,"families":[{"shape":"sphere","radius":0.05,"volume_fraction":0.3}],"voxels":{"resolution":160}}' >"$WORK/kill_new.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/kill_new.json" -o "$WORK/kill_ref"
expect_rc 0 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/kill"
for delay in 0.2 0.5 0.9 1.4 2.0 3.0; do
  { timeout -s KILL "$delay" "$RVEGEN" generate -q "$WORK/kill_new.json" -o "$WORK/kill"; } >/dev/null 2>&1 || true
  # (report.json and rve.h5 hold the run's timings: they are checked for presence only.)
  same_set() {
    [ "$(ls -A "$1")" = "$(ls -A "$2")" ] || return 1
    for f in $(ls -A "$2"); do
      case "$f" in report.json | rve.h5) [ -s "$1/$f" ] || return 1 ;;
        *) cmp -s "$1/$f" "$2/$f" || return 1 ;; esac
    done
  }
  if cmp -s "$WORK/kill/inclusions.json" "$WORK/closed/inclusions.json"; then
    same_set "$WORK/kill" "$WORK/closed" || fail "kill after ${delay}s: old set damaged"
  elif cmp -s "$WORK/kill/inclusions.json" "$WORK/kill_ref/inclusions.json"; then
    same_set "$WORK/kill" "$WORK/kill_ref" || fail "kill after ${delay}s: new set incomplete"
    expect_rc 0 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/kill"  # back to the old set
  else
    fail "kill after ${delay}s: the directory holds neither set"
  fi
done
expect_rc 0 "$RVEGEN" generate -q "$WORK/closed.json" -o "$WORK/kill"
ls -A "$WORK" | grep -q '\.rvegen-' && fail "killed runs' staging directories were not cleaned"

# Another user's set in a parent both may write: the new set is swapped in, the old one cannot be
# deleted (its files are not ours); the run says so and names where the old set stays. Needs a
# second user: run as root, the second run drops to nobody (setpriv). The checkout may sit in a
# directory only root can enter (a clone in a mktemp directory), so the second user gets its own
# copy of the program and the build's libraries, its scene and the shared parent in a directory
# anyone may enter.
if [ "$(id -u)" = 0 ] && command -v setpriv >/dev/null; then
  other=$(mktemp -d /tmp/rvegen-other-user.XXXXXX)
  chmod 0755 "$other"
  mkdir "$other/lib"
  cp "$RVEGEN" "$other/rvegen"
  cp -P "$(dirname "$RVEGEN")"/../lib/*.so* "$other/lib/"
  cp "$WORK/kill_new.json" "$other/scene.json"
  chmod -R o+rX "$other"
  shared="$other/shared"
  mkdir -m 0777 "$shared"
  expect_rc 0 "$RVEGEN" generate -q "$WORK/closed.json" -o "$shared/set"
  cp "$shared/set/inclusions.json" "$WORK/shared_old.json"
  if setpriv --reuid=65534 --regid=65534 --clear-groups env LD_LIBRARY_PATH="$other/lib" \
      "$other/rvegen" generate -q "$other/scene.json" -o "$shared/set" 2>"$WORK/shared.err"; then
    grep -q "could not be removed.*stays at" "$WORK/shared.err" ||
      fail "another user's set: no word of the old set left behind: $(cat "$WORK/shared.err")"
    left=$(find "$shared" -maxdepth 1 -name '.set.rvegen-*' | head -1)
    [ -n "$left" ] && cmp -s "$left/inclusions.json" "$WORK/shared_old.json" ||
      fail "another user's set: the old set is not where the message says"
    grep -qF "$left" "$WORK/shared.err" || fail "another user's set: message names another place"
    [ "$(stat -c %u "$shared/set")" = 65534 ] || fail "another user's set: the new set is not in place"
  else
    fail "another user's set: the second user's run failed: $(cat "$WORK/shared.err")"
  fi
  rm -rf "$other"
else
  echo "note: not root; the two-user case of a shared parent is not exercised"
fi

# Many families: the report no longer fits an HDF5 attribute; it is a dataset.
fams=$($py -c "import json; print(json.dumps([{'shape':'sphere','radius':0.03,'count':3,'name':'family number %d with a long name' % k} for k in range(40)]))")
echo "{\"box\":{\"size\":[1,1,1]},\"families\":$fams,\"voxels\":{\"resolution\":16}}" >"$WORK/many.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/many.json" --outputs inclusions,h5,statistics -o "$WORK/many"
$py - "$WORK/many" <<'PY' || fail "rve.h5 report dataset"
import json, sys
import h5py
with h5py.File(sys.argv[1] + "/rve.h5", "r") as f:
    text = f["report"][()]
    report = json.loads(text.decode() if isinstance(text, bytes) else text)
    assert len(report["families"]) == 40
    assert "report" not in f.attrs  # too long for an attribute
PY

# Input the arithmetic cannot serve, and resources: exit 2 naming the problem, nothing written.
bad far_origin '{"box":{"size":[1,1,1],"origin":[1e200,0,0]},"families":[{"shape":"sphere","radius":0.05,"volume_fraction":0.1}]}' "box.origin\[0\]"
bad huge_box '{"box":{"size":[1e300,1e300,1e300]},"families":[{"shape":"sphere","radius":1e299,"volume_fraction":0.1}]}' "box.size\[0\]"
bad duplicate_key '{"box":{"size":[1,1,1]},"seed":1,"seed":2,"families":[{"shape":"sphere","radius":0.05,"volume_fraction":0.1}]}' "seed: key given twice"
bad overflow '{"box":{"size":[1,1e999,1]},"families":[{"shape":"sphere","radius":0.05,"volume_fraction":0.1}]}' "box.size\[1\]"
fams=$($py -c "import json; print(json.dumps([{'shape':'sphere','radius':0.01,'count':1,'coating':{'thickness':0.001}} for k in range(130)]))")
bad many_phases "{\"box\":{\"size\":[1,1,1]},\"families\":$fams}" "too many phases"
bad big_levelset_voxel '{"box":{"size":[1,1,1]},"families":[{"shape":"sphere","radius":0.05,"volume_fraction":0.1,"coating":{"thickness":0.01}}],"levelsets":{"voxel_size":10}}' "levelsets.voxel_size"
expect_rc 2 "$RVEGEN" generate -q /dev/zero -o "$WORK/out_zero"
grep -q "not a regular file" "$WORK/last.err" || fail "/dev/zero: $(cat "$WORK/last.err")"
expect_rc 2 "$RVEGEN" generate -q --max-memory 10M -o "$WORK/out_mem"
grep -q "needs about" "$WORK/last.err" || fail "memory estimate not shown: $(cat "$WORK/last.err")"
[ -e "$WORK/out_mem" ] && fail "output written past the memory limit"
echo '{"box":{"size":[1,1,1]},"families":[{"shape":"sphere","radius":0.05,"volume_fraction":0.1}],"voxels":{"resolution":4096}}' >"$WORK/res4096.json"
expect_rc 2 "$RVEGEN" generate -q "$WORK/res4096.json" -o "$WORK/out_res4096"
grep -q "needs about" "$WORK/last.err" || fail "4096^3 voxels: $(cat "$WORK/last.err")"

# check: a pile of 10,000 spheres stops at --max-pairs; a sphere far larger than the box is refused.
$py - "$WORK/pile.json" <<'PY'
import json, sys
incs = [{"id": k, "shape": "sphere", "center": [0.5, 0.5, 0.5], "radius": 0.01} for k in range(10000)]
json.dump({"format": "rvegen.inclusions/1", "box": {"size": [1, 1, 1]}, "inclusions": incs}, open(sys.argv[1], "w"))
PY
expect_rc 1 "$RVEGEN" check "$WORK/pile.json" --max-pairs 1000
grep -q "at least 1000 overlapping pairs" "$WORK/last.out" || fail "check pile: $(tail -1 "$WORK/last.out")"
echo '{"format":"rvegen.inclusions/1","box":{"size":[1,1,1]},"inclusions":[{"id":0,"shape":"sphere","center":[0.5,0.5,0.5],"radius":50}]}' >"$WORK/giant.json"
expect_rc 2 "$RVEGEN" check "$WORK/giant.json"

# Effective properties in the same run ("materials" + "homogenization"): the report's tensors
# are symmetric and lie within the Hashin-Shtrikman bounds it states; equal phases give their
# own properties back exactly; missing or bad materials are named, nothing written.
HOM_FAM='"families":[{"name":"spheres","shape":"sphere","radius":0.1,"volume_fraction":0.3}],"voxels":{"resolution":24}'
echo "{$BOX,\"seed\":3,$HOM_FAM,\"materials\":{\"matrix\":{\"conductivity\":1,\"young\":3,\"poisson\":0.35},\"spheres\":{\"conductivity\":10,\"young\":70,\"poisson\":0.2}},\"homogenization\":{\"physics\":[\"conductivity\",\"elasticity\"]}}" >"$WORK/hom.json"
expect_rc 0 "$RVEGEN" generate "$WORK/hom.json" -o "$WORK/hom"
grep -q "conductivity: \|homogenization: " "$WORK/last.err" || fail "no homogenization progress: $(cat "$WORK/last.err")"
$py - "$WORK/hom/report.json" <<'PY' || fail "effective properties in report.json"
import json, sys
e = json.load(open(sys.argv[1]))["effective"]
c = e["conductivity"]
t = c["tensor"]
assert c["converged"], c
assert all(abs(t[i][j] - t[j][i]) < 1e-4 * t[0][0] for i in range(3) for j in range(3)), t
lo, hi = c["bounds"]["hashin_shtrikman"]
assert lo < c["mean_of_diagonal"] < hi, (lo, c["mean_of_diagonal"], hi)
s = e["stiffness"]
assert s["converged"] and len(s["tensor"]) == 6
for m in ("bulk", "shear"):
    lo, hi = s["bounds"][m]["hashin_shtrikman"]
    assert lo < s["isotropic_projection"][m] < hi, (m, lo, s["isotropic_projection"][m], hi)
assert 0.2 < s["engineering_constants"]["nu12"] < 0.35
PY
echo "{$BOX,\"seed\":3,$HOM_FAM,\"materials\":{\"matrix\":{\"conductivity\":2.5},\"spheres\":{\"conductivity\":2.5}},\"homogenization\":{\"physics\":[\"conductivity\"]}}" >"$WORK/hom_equal.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/hom_equal.json" -o "$WORK/hom_equal"
$py -c "
import json, sys
t = json.load(open('$WORK/hom_equal/report.json'))['effective']['conductivity']['tensor']
sys.exit(0 if all(abs(t[i][j] - (2.5 if i == j else 0.0)) < 1e-10 for i in range(3) for j in range(3)) else 1)" \
  || fail "equal phases do not give their conductivity back"
# The same on the RVE already written: rvegen homogenize DIR SCENE prints the report's object.
expect_rc 0 "$RVEGEN" homogenize "$WORK/hom" "$WORK/hom.json"
$py - "$WORK/last.out" "$WORK/hom/report.json" <<'PY' || fail "homogenize DIR differs from generate's report"
import json, sys
a = json.load(open(sys.argv[1]))
b = json.load(open(sys.argv[2]))["effective"]
for phys in ("conductivity", "stiffness"):
    ta, tb = a[phys]["tensor"], b[phys]["tensor"]
    assert all(abs(x - y) <= 1e-12 * abs(tb[0][0]) for ra, rb in zip(ta, tb) for x, y in zip(ra, rb)), phys
PY
# --threads 1 --quiet: the same tensors to the last bit (the solver's sums run in a fixed
# order whatever the cores), and no progress on standard error.
cp "$WORK/last.out" "$WORK/hom_all_cores.out"
expect_rc 0 "$RVEGEN" homogenize "$WORK/hom" "$WORK/hom.json" --threads 1 --quiet
[ -s "$WORK/last.err" ] && fail "homogenize --quiet printed: $(head -c 300 "$WORK/last.err")"
$py - "$WORK/last.out" "$WORK/hom_all_cores.out" <<'PY' || fail "homogenize --threads 1 differs from all cores"
import json, sys
a, b = (json.load(open(f)) for f in sys.argv[1:])
for phys in ("conductivity", "stiffness"):
    assert a[phys]["tensor"] == b[phys]["tensor"], phys
    assert a[phys]["iterations"] == b[phys]["iterations"], phys
PY
expect_rc 2 "$RVEGEN" homogenize "$WORK/hom" "$WORK/hom.json" --threads 0
grep -q -- "--threads needs a whole number" "$WORK/last.err" \
  || fail "homogenize --threads 0: $(cat "$WORK/last.err")"
# A solve stopped above its tolerance is no effective property: everything is written, the
# report says "converged": false, a message names the load cases, exit 5 (generate and
# homogenize alike).
sed 's/"physics":\["conductivity","elasticity"\]/"physics":["conductivity"],"max_iterations":3/' "$WORK/hom.json" >"$WORK/hom_short.json"
expect_rc 5 "$RVEGEN" generate -q "$WORK/hom_short.json" -o "$WORK/hom_short"
grep -q 'homogenization did not converge.*conductivity: load cases 1, 2 and 3 stopped at 3 iterations' "$WORK/last.err" \
  || fail "no message for a solve that did not converge: $(cat "$WORK/last.err")"
$py -c "
import json, sys
c = json.load(open('$WORK/hom_short/report.json'))['effective']['conductivity']
sys.exit(0 if c['converged'] is False and c['iterations'] == [3, 3, 3] else 1)" \
  || fail "report.json of a solve that did not converge"
expect_rc 5 "$RVEGEN" homogenize "$WORK/hom_short" "$WORK/hom_short.json"
grep -q 'homogenization did not converge' "$WORK/last.err" \
  || fail "homogenize: no message for a solve that did not converge: $(cat "$WORK/last.err")"
# A breakdown is said as one, never as slow convergence: a matrix of Poisson's ratio
# 0.49999999999999994 (the largest double below 0.5: a bulk modulus 1e16 times its shear
# modulus) breaks the solver's arithmetic; the message says "broke down", not "stopped at",
# and names the phase whose stiffness spreads furthest; report.json lists the breakdowns.
sed 's/"physics":\["conductivity","elasticity"\]/"physics":["elasticity"]/; s/"matrix": *{\("conductivity":[^,]*,\)\? *"young": *\([^,]*\), *"poisson": *[^}]*}/"matrix":{"young":\2,"poisson":0.49999999999999994}/' "$WORK/hom.json" >"$WORK/hom_nu.json"
grep -q '0.49999999999999994' "$WORK/hom_nu.json" || fail "hom_nu.json: the matrix's Poisson's ratio was not set: $(cat "$WORK/hom_nu.json")"
expect_rc 5 "$RVEGEN" generate -q "$WORK/hom_nu.json" -o "$WORK/hom_nu"
grep -q 'elasticity: load case.* broke down (.*no slow convergence; phase "matrix" has stiffness eigenvalues' "$WORK/last.err" \
  || fail "a breakdown read as: $(cat "$WORK/last.err")"
grep -q 'stopped at' "$WORK/last.err" && fail "a breakdown said as slow convergence: $(cat "$WORK/last.err")"
$py -c "
import json, sys
s = json.load(open('$WORK/hom_nu/report.json'))['effective']['stiffness']
sys.exit(0 if s['converged'] is False and any(s['breakdown']) and 'matrix' in s['spread'] else 1)" \
  || fail "report.json of a breakdown"
# Insulating spheres (pores) with the default laminate voxels: converged, within the
# Hashin-Shtrikman upper bound k (1 - f) / (1 + f / 2), above plain voxels' value, which the
# pores' cut voxels run below (before, the solve stopped at 1,000 iterations, 1e-3 above the
# tolerance, and 12 % low at 32^3).
sed 's/"spheres":{"conductivity":10,"young":70,"poisson":0.2}/"spheres":{"conductivity":0}/; s/"physics":\["conductivity","elasticity"\]/"physics":["conductivity"]/' "$WORK/hom.json" >"$WORK/hom_pores.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/hom_pores.json" -o "$WORK/hom_pores"
sed 's/"physics":\["conductivity"\]/"physics":["conductivity"],"voxel_rule":"plain"/' "$WORK/hom_pores.json" >"$WORK/hom_pores_plain.json"
expect_rc 0 "$RVEGEN" homogenize "$WORK/hom_pores" "$WORK/hom_pores_plain.json"
$py - "$WORK/hom_pores/report.json" "$WORK/last.out" <<'PY' || fail "insulating spheres with laminate voxels"
import json, sys
e = json.load(open(sys.argv[1]))
c = e["effective"]["conductivity"]
plain = json.load(open(sys.argv[2]))["conductivity"]["mean_of_diagonal"]
f = e["volume_fraction"]  # exact, of the inclusions
hs = (1 - f) / (1 + f / 2)
assert c["converged"] and max(c["iterations"]) < 200, c["iterations"]
assert plain < c["mean_of_diagonal"] < hs, (plain, c["mean_of_diagonal"], hs)
PY
expect_rc 2 "$RVEGEN" homogenize "$WORK/default" "$WORK/hom.json"
grep -q "families: the scene's (spheres) are not the RVE's" "$WORK/last.err" \
  || fail "homogenize with other families: $(cat "$WORK/last.err")"
# A named pipe as the scene or as DIR/inclusions.json: refused at once ("not a regular file"),
# not waited on (the file was opened before it was checked).
mkfifo "$WORK/fifo_scene.json"
expect_rc 2 timeout 20 "$RVEGEN" generate -q "$WORK/fifo_scene.json" -o "$WORK/fifo_out"
grep -q "not a regular file" "$WORK/last.err" || fail "fifo scene: $(cat "$WORK/last.err")"
mkdir -p "$WORK/fifo_rve" && mkfifo "$WORK/fifo_rve/inclusions.json"
expect_rc 2 timeout 20 "$RVEGEN" homogenize "$WORK/fifo_rve" "$WORK/hom.json"
grep -q "not a regular file" "$WORK/last.err" || fail "fifo inclusion list: $(cat "$WORK/last.err")"

# homogenize estimates its memory before it allocates: at 2048^3 with 8 GB, exit 2 naming the
# need (it was std::bad_alloc, exit -6), given as --max-memory or as an address-space limit.
# (AddressSanitizer reserves terabytes of address space itself: a binary built with it cannot
# run under ulimit -v, so the sanitizer build tests the flag alone.)
sed 's/"resolution":24/"resolution":2048/' "$WORK/hom.json" >"$WORK/hom_huge.json"
expect_rc 2 "$RVEGEN" homogenize "$WORK/hom" "$WORK/hom_huge.json" --max-memory 8G
grep -q "the solve needs about .* above the --max-memory limit of 8.6 GB" "$WORK/last.err" || fail "homogenize 2048^3 --max-memory: $(cat "$WORK/last.err")"
if ! grep -qa __asan_init "$RVEGEN"; then
  expect_rc 2 bash -c "ulimit -v 8000000; exec \"\$0\" homogenize \"\$1\" \"\$2\"" "$RVEGEN" "$WORK/hom" "$WORK/hom_huge.json"
  grep -q "the solve needs about .* above the memory available" "$WORK/last.err" || fail "homogenize 2048^3 under ulimit -v: $(cat "$WORK/last.err")"
fi

# An RVE handed in is audited against the scene before any work: edited to overlap (deeply, or
# by 3 % of a radius), a family past the scene's, a coating the scene does not have, a box that
# is not the scene's: exit 2 naming the inclusion, never a tensor.
$py - "$WORK/hom" "$WORK/hom_bad" <<'PY' || fail "could not write the edited RVEs"
import json, math, os, shutil, sys
src, dst = sys.argv[1], sys.argv[2]
base = json.load(open(src + "/inclusions.json"))
def write(name, edit):
    d = json.loads(json.dumps(base))
    edit(d)
    os.makedirs(dst + "_" + name, exist_ok=True)
    json.dump(d, open(dst + "_" + name + "/inclusions.json", "w"))
def overlap(frac):
    def edit(d):
        a, b = d["inclusions"][0], d["inclusions"][1]
        r = a["radius"] + b["radius"]
        # b moved to 1 - frac of the contact distance from a, along x.
        b["center"] = [a["center"][0] + (1 - frac) * r, a["center"][1], a["center"][2]]
    return edit
write("deep", overlap(0.5))
write("shallow", overlap(0.03 * base["inclusions"][0]["radius"] / (2 * base["inclusions"][0]["radius"])))
write("family", lambda d: d["inclusions"][3].__setitem__("family", 7))
write("coated", lambda d: d["inclusions"][2].__setitem__("modifiers", {"coating": 0.01, "shells_may_touch": False}))
write("box", lambda d: d["box"].__setitem__("size", [1.1, 1, 1]))
PY
for k in deep shallow family coated box; do
  expect_rc 2 "$RVEGEN" homogenize "$WORK/hom_bad_$k" "$WORK/hom.json"
  [ -s "$WORK/last.out" ] && fail "homogenize of an RVE edited ($k) printed a result"
done
expect_rc 2 "$RVEGEN" homogenize "$WORK/hom_bad_deep" "$WORK/hom.json"
grep -q "inclusions.json: inclusions 0 and 1 overlap by" "$WORK/last.err" || fail "overlap not named: $(cat "$WORK/last.err")"
expect_rc 2 "$RVEGEN" homogenize "$WORK/hom_bad_shallow" "$WORK/hom.json"
grep -q "overlap by" "$WORK/last.err" || fail "a 3 % overlap not named: $(cat "$WORK/last.err")"
expect_rc 2 "$RVEGEN" homogenize "$WORK/hom_bad_family" "$WORK/hom.json"
grep -q "inclusion 3: family 7, but the scene has 1 family" "$WORK/last.err" || fail "family past the scene's: $(cat "$WORK/last.err")"
expect_rc 2 "$RVEGEN" homogenize "$WORK/hom_bad_coated" "$WORK/hom.json"
grep -q "inclusion 2: coating 0.01, but family \"spheres\" has 0" "$WORK/last.err" || fail "coating the scene lacks: $(cat "$WORK/last.err")"
expect_rc 2 "$RVEGEN" homogenize "$WORK/hom_bad_box" "$WORK/hom.json"
grep -q "box .* is not the scene's" "$WORK/last.err" || fail "another box: $(cat "$WORK/last.err")"
bad hom_missing "{$BOX,$HOM_FAM,\"materials\":{\"matrix\":{\"conductivity\":1}},\"homogenization\":{\"physics\":[\"conductivity\"]}}" "materials.spheres.conductivity: needed"
bad hom_unknown_phase "{$BOX,$HOM_FAM,\"materials\":{\"matrx\":{\"conductivity\":1}}}" "materials.matrx: no phase of this name"
bad hom_poisson "{$BOX,$HOM_FAM,\"materials\":{\"matrix\":{\"young\":1,\"poisson\":0.6}}}" "materials.matrix.poisson"
bad hom_key "{$BOX,$HOM_FAM,\"materials\":{\"matrix\":{\"conductivty\":1}}}" 'did you mean "conductivity"'
bad hom_physics "{$BOX,$HOM_FAM,\"homogenization\":{\"physics\":[\"thermal\"]}}" "unknown physics"
# Every material value on its own, whatever the physics; names that would make materials
# ambiguous; a homogenization that asks for nothing.
bad mat_young_neg "{$BOX,$HOM_FAM,\"materials\":{\"matrix\":{\"young\":-1,\"poisson\":0.3}}}" "materials.matrix.young: must be >= 0 and at most 1e100, got -1"
bad mat_poisson_m2 "{$BOX,$HOM_FAM,\"materials\":{\"matrix\":{\"young\":1,\"poisson\":-2}}}" "materials.matrix.poisson: must lie in (-1, 0.5), got -2"
bad mat_k_neg_elastic "{$BOX,$HOM_FAM,\"materials\":{\"matrix\":{\"conductivity\":-1,\"young\":3,\"poisson\":0.3},\"spheres\":{\"young\":70,\"poisson\":0.2}},\"homogenization\":{\"physics\":[\"elasticity\"]}}" "materials.matrix.conductivity: must be >= 0"
bad mat_huge "{$BOX,$HOM_FAM,\"materials\":{\"matrix\":{\"young\":3,\"poisson\":0.3},\"spheres\":{\"young\":1e308,\"poisson\":0.2}},\"homogenization\":{\"physics\":[\"elasticity\"]}}" "materials.spheres.young: must be >= 0 and at most 1e100, got 1e+308"
bad mat_half "{$BOX,$HOM_FAM,\"materials\":{\"matrix\":{\"young\":3}}}" "materials.matrix.poisson: missing"
bad mat_coating_uncoated "{$BOX,$HOM_FAM,\"materials\":{\"spheres.coating\":{\"conductivity\":3}}}" 'materials.spheres.coating: family "spheres" has no coating'
bad hom_no_physics "{$BOX,$HOM_FAM,\"homogenization\":{\"physics\":[]}}" "homogenization.physics: expected a non-empty array"
bad hom_physics_missing "{$BOX,$HOM_FAM,\"homogenization\":{\"tolerance\":1e-5}}" "homogenization"
bad fam_matrix "{$BOX,\"families\":[{\"name\":\"matrix\",\"shape\":\"sphere\",\"radius\":0.1,\"volume_fraction\":0.1}],\"materials\":{\"matrix\":{\"conductivity\":1}}}" 'families\[0\].name: "matrix" names the matrix'
bad fam_dotcoating "{$BOX,\"families\":[{\"name\":\"x.coating\",\"shape\":\"sphere\",\"radius\":0.1,\"volume_fraction\":0.1}],\"materials\":{\"matrix\":{\"conductivity\":1}}}" 'families\[0\].name: "x.coating" would read as'
bad fam_twice "{$BOX,\"families\":[{\"name\":\"a\",\"shape\":\"sphere\",\"radius\":0.1,\"volume_fraction\":0.1},{\"name\":\"a\",\"shape\":\"sphere\",\"radius\":0.05,\"volume_fraction\":0.1}],\"materials\":{\"a\":{\"conductivity\":1}}}" 'families\[1\].name: "a" is also families\[0\]'
bad fe_names "{$BOX,\"families\":[{\"name\":\"a b\",\"shape\":\"sphere\",\"radius\":0.1,\"volume_fraction\":0.1},{\"name\":\"a_b\",\"shape\":\"sphere\",\"radius\":0.05,\"volume_fraction\":0.1}],\"outputs\":[\"inclusions\",\"mesh_voxel\"]}" 'families\[1\].name: the phase "a_b" and families\[0\]'"'"'s "a b" would both be a_b in the finite-element decks'
bad tet_wavy "{$BOX,\"families\":[{\"shape\":\"cylinder\",\"radius\":0.02,\"aspect_ratio\":5,\"volume_fraction\":0.1,\"waviness\":{\"amplitude\":0.01,\"wavelength\":0.1}}],\"outputs\":[\"inclusions\",\"mesh_tet\"]}" 'outputs: mesh_tet meshes spheres, cylinders and ellipsoids.*family "cylinder" (families\[0\]) is wavy'
bad hom_rule "{$BOX,$HOM_FAM,\"homogenization\":{\"physics\":[\"conductivity\"],\"voxel_rule\":\"mean\"}}" 'homogenization.voxel_rule: unknown rule "mean"'
# Voxel rules: the report names the rule and counts the cut voxels; every rule's result lies
# within the bounds, and the rules differ (plain voxels ignore the cut shares).
for rule in plain laminate; do
  sed "s/\"physics\":\[\"conductivity\",\"elasticity\"\]/\"physics\":[\"conductivity\"],\"voxel_rule\":\"$rule\"/" "$WORK/hom.json" >"$WORK/hom_$rule.json"
  expect_rc 0 "$RVEGEN" homogenize "$WORK/hom" "$WORK/hom_$rule.json"
  cp "$WORK/last.out" "$WORK/eff_$rule.json"
done
$py - "$WORK/eff_plain.json" "$WORK/eff_laminate.json" <<'PY' || fail "voxel rules in the effective object"
import json, sys
p, l = (json.load(open(a)) for a in sys.argv[1:3])
assert p["voxel_rule"]["rule"] == "plain" and p["voxel_rule"]["cut_voxels"] == 0, p["voxel_rule"]
assert l["voxel_rule"]["rule"] == "laminate" and l["voxel_rule"]["cut_voxels"] > 1000, l["voxel_rule"]
for e in (p, l):
    c = e["conductivity"]
    lo, hi = c["bounds"]["hashin_shtrikman"]
    assert lo < c["mean_of_diagonal"] < hi, (lo, c["mean_of_diagonal"], hi)
assert abs(p["conductivity"]["mean_of_diagonal"] / l["conductivity"]["mean_of_diagonal"] - 1) > 1e-4
PY
# Transversely isotropic fibres, each turned to its own axis: fibres along z whose transverse
# conductivity is the matrix's leave a gradient across them undisturbed, so k_xx = k_yy = 1 and
# the off-diagonal terms vanish exactly (a fibre turned any other way would break this), while
# k_zz rises; the stiffness is stiffest along the fibres.
FIB_FAM='"families":[{"name":"fibres","shape":"cylinder","radius":0.04,"aspect_ratio":5,"volume_fraction":0.2,"orientation":{"law":"aligned","axis":[0,0,1]}}],"voxels":{"resolution":24}'
FIB_MAT='"matrix":{"conductivity":1,"young":3,"poisson":0.35},"fibres":{"axial_conductivity":100,"transverse_conductivity":1,"axial_young":230,"transverse_young":15,"axial_shear":27,"axial_poisson":0.2,"transverse_poisson":0.4}'
echo "{$BOX,\"seed\":5,$FIB_FAM,\"materials\":{$FIB_MAT},\"homogenization\":{\"physics\":[\"conductivity\",\"elasticity\"]}}" >"$WORK/fib.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/fib.json" -o "$WORK/fib"
$py - "$WORK/fib/report.json" <<'PY' || fail "transversely isotropic fibres"
import json, sys
e = json.load(open(sys.argv[1]))["effective"]
t = e["conductivity"]["tensor"]
assert abs(t[0][0] - 1) < 1e-10 and abs(t[1][1] - 1) < 1e-10, t
assert all(abs(t[i][j]) < 1e-10 for i in range(3) for j in range(3) if i != j), t
assert t[2][2] > 1.5, t
assert isinstance(e["conductivity"]["bounds"], str)
s = e["stiffness"]
c = s["engineering_constants"]
assert s["converged"] and c["E3"] > 1.5 * c["E1"] and abs(c["E1"] / c["E2"] - 1) < 0.05, c
m = s["tensor"]
assert all(abs(m[i][j] - m[j][i]) < 1e-6 * m[2][2] for i in range(6) for j in range(6)), m
PY
# AMITEX_FFTP inputs: zoneID.vtk numbers each fibre's voxels by the fibre's rank among the
# fibres present (1 elsewhere), the material file has one material per number of material.vtk
# with the scene's constants (Lame for the matrix; the fibre's stiffness in its own frame with
# its axis per zone), the loading file the six unit strains, the run script every file.
expect_rc 0 "$RVEGEN" generate -q "$WORK/fib.json" --outputs inclusions,h5,amitex -o "$WORK/fib_amitex"
$py - "$WORK/fib_amitex" <<'PY' || fail "AMITEX files"
import json, os, sys
import xml.etree.ElementTree as ET
import numpy as np, h5py
d = sys.argv[1]
def legacy(path):
    raw = open(path, "rb").read()
    lines = raw.split(b"\n", 10)
    assert lines[0].startswith(b"# vtk DataFile") and lines[2] == b"BINARY", lines[:3]
    kind = lines[8].split()[2].decode()
    return np.frombuffer(lines[10], dtype={"unsigned_short": ">u2", "int": ">i4"}[kind]).astype(int)
mat, zone = legacy(os.path.join(d, "material.vtk")), legacy(os.path.join(d, "zoneID.vtk"))
with h5py.File(os.path.join(d, "rve.h5"), "r") as h:
    phase = h["voxels/phase"][...].ravel()
    ids = h["voxels/inclusion_id"][...].ravel()
assert mat.size == zone.size == phase.size, (mat.size, zone.size, phase.size)
fib = phase == 1
present = np.unique(ids[fib])
rank = {int(i): k + 1 for k, i in enumerate(present)}
assert all(zone[fib] == [rank[int(i)] for i in ids[fib]]), "fibre zones"
assert (zone[~fib] == 1).all(), "zones outside the fibres"
root = ET.parse(os.path.join(d, "amitex_materials.xml")).getroot()
mats = root.findall("Material")
assert sorted(int(m.get("numM")) for m in mats) == sorted(set(mat.tolist())), [m.get("numM") for m in mats]
by = {m.get("numM"): m for m in mats}
iso = by["1"]
assert iso.get("Law") == "elasiso"
E, nu = 3.0, 0.35
lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
c = {int(k.get("Index")): k for k in iso.findall("Coeff")}
assert abs(float(c[1].get("Value")) - lam) < 1e-12 and abs(float(c[2].get("Value")) - mu) < 1e-12
ani = by["2"]
assert ani.get("Law") == "elasaniso"
c = {int(k.get("Index")): k for k in ani.findall("Coeff")}
# The fibre frame's stiffness, independently: the inverse of the compliance.
EL, ET_, GLT, nuLT, nuTT = 230.0, 15.0, 27.0, 0.2, 0.4
S = np.array([[1 / EL, -nuLT / EL, -nuLT / EL], [-nuLT / EL, 1 / ET_, -nuTT / ET_], [-nuLT / EL, -nuTT / ET_, 1 / ET_]])
C = np.linalg.inv(S)
want = [C[0, 0], C[0, 1], C[0, 2], C[1, 1], C[1, 2], C[2, 2], GLT, GLT, ET_ / (2 * (1 + nuTT))]
got = [float(c[k].get("Value")) for k in range(1, 10)]
assert np.allclose(got, want, rtol=1e-12), (got, want)
incs = {i["id"]: i for i in json.load(open(os.path.join(d, "inclusions.json")))["inclusions"]}
for k, i in enumerate(present):
    a = np.array(incs[int(i)]["half_axis"], float); a /= np.linalg.norm(a)
    e1 = [float(c[10 + j].find("Zone[@numZ='%d']" % (k + 1)).get("Value")) for j in range(3)]
    assert np.allclose(e1, a, atol=1e-12), (k, e1, a)
load = ET.parse(os.path.join(d, "amitex_loading.xml")).getroot().findall("Loading")
assert len(load) == 6
for n, l in enumerate(load):
    vals = [float(l.find(x).get("Value")) for x in ("xx", "yy", "zz", "xy", "xz", "yz")]
    assert vals == [1e-3 if j == n else 0.0 for j in range(6)], vals
ET.parse(os.path.join(d, "amitex_algorithm.xml"))
# rve.h5 lists the composite voxels the report's solve used: unit normals, shares in (0, 1).
with h5py.File(os.path.join(d, "rve.h5"), "r") as h:
    g = h["composite_voxels"]
    n, f = g["normal"][...], g["fraction"][...]
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0) and ((f > 0) & (f < 1)).all()
    rep = json.load(open(os.path.join(d, "report.json")))["effective"]["voxel_rule"]
    assert len(f) == rep["cut_voxels"] and g.attrs["voxels_cut_by_two_cores"][0] == rep["voxels_cut_by_two_cores"], (len(f), rep)
run = open(os.path.join(d, "amitex_run.sh")).read()
for f in ("material.vtk", "zoneID.vtk", "amitex_materials.xml", "amitex_loading.xml", "amitex_algorithm.xml"):
    assert f in run, f
# The fibres conduct transversely isotropically: no AMITEX law is written for them.
root = ET.parse(os.path.join(d, "amitex_conductivity_materials.xml")).getroot()
k = {m.get("numM"): m.find("CoeffK").get("Value") for m in root.findall("Material")}
assert k == {"1": "1", "2": "FILL_IN"}, k
PY
# AMITEX's diffusion files for isotropic conductivities: one Fourier_iso material per number of
# material.vtk with the phase's conductivity (matrix, beads, their coating), the reference the
# mean of the extremes, three unit gradients; the run script runs both problems. A scene with
# conductivities only runs diffusion alone.
MAT_K='"matrix":{"conductivity":1,"young":3,"poisson":0.35},"beads":{"conductivity":10,"young":70,"poisson":0.2},"beads.coating":{"conductivity":3,"young":10,"poisson":0.3}'
BEADS='"families":[{"name":"beads","shape":"sphere","radius":0.1,"count":12,"coating":{"thickness":0.02}}],"voxels":{"resolution":24}'
echo "{$BOX,\"seed\":2,$BEADS,\"materials\":{$MAT_K}}" >"$WORK/beads_k.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/beads_k.json" --outputs inclusions,h5,amitex -o "$WORK/beads_amitex"
echo "{$BOX,\"seed\":2,$BEADS,\"materials\":{\"matrix\":{\"conductivity\":1},\"beads\":{\"conductivity\":10},\"beads.coating\":{\"conductivity\":3}}}" >"$WORK/beads_konly.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/beads_konly.json" --outputs amitex -o "$WORK/beads_konly"
$py - "$WORK/beads_amitex" "$WORK/beads_konly" <<'PY' || fail "AMITEX diffusion files"
import os, sys
import xml.etree.ElementTree as ET
import numpy as np, h5py
d, only = sys.argv[1:3]
raw = open(os.path.join(d, "material.vtk"), "rb").read().split(b"\n", 10)
mat = np.frombuffer(raw[10], dtype=">u2").astype(int)
with h5py.File(os.path.join(d, "rve.h5"), "r") as h:
    phase = h["voxels/phase"][...].ravel()
# The conductivity of each phase label (0 matrix, 1 beads, 2 their coating), through
# material.vtk's numbering.
want = {0: 1.0, 1: 10.0, 2: 3.0}
root = ET.parse(os.path.join(d, "amitex_conductivity_materials.xml")).getroot()
assert float(root.find("Reference_MaterialD").get("K0")) == 5.5
mats = {int(m.get("numM")): m for m in root.findall("Material")}
assert sorted(mats) == sorted(set(mat.tolist())), sorted(mats)
for num, m in mats.items():
    assert m.get("LawK") == "Fourier_iso", m.attrib
    labels = set(phase[mat == num].tolist())
    assert len(labels) == 1, (num, labels)
    assert float(m.find("CoeffK").get("Value")) == want[labels.pop()], num
loads = ET.parse(os.path.join(d, "amitex_conductivity_loading.xml")).getroot().findall("Loading")
assert len(loads) == 3
for n, l in enumerate(loads):
    assert [l.find(c).get("Driving") for c in ("x0", "y0", "z0")] == ["GradD"] * 3
    assert [float(l.find(c).get("Value")) for c in ("x0", "y0", "z0")] == [float(j == n) for j in range(3)]
algo = ET.parse(os.path.join(d, "amitex_conductivity_algorithm.xml")).getroot()
assert algo.find("Diffusion/Stationary").get("Value") == "true"
run = open(os.path.join(d, "amitex_run.sh")).read()
assert "-m amitex_materials.xml" in run and "-m amitex_conductivity_materials.xml" in run, run
run = open(os.path.join(only, "amitex_run.sh")).read()
assert "-m amitex_materials.xml" not in run and "-m amitex_conductivity_materials.xml" in run, run
PY
# Local fields in rve.h5 ("fields": true): per load case, the mean strain is the unit strain,
# the mean stress the report's stiffness column (the mean flux its conductivity column), and
# the fields obey Hill-Mandel (<sigma : eps> = <sigma> : <eps>, which a mis-ordered or
# mis-scaled component would break); without the h5 output the scene is refused.
$py - "$WORK/fib.json" "$WORK/fib_fields.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
s["homogenization"]["fields"] = True
s["outputs"] = ["inclusions", "h5"]
json.dump(s, open(sys.argv[2], "w"))
PY
expect_rc 0 "$RVEGEN" generate -q "$WORK/fib_fields.json" -o "$WORK/fib_fields"
$py - "$WORK/fib_fields" <<'PY' || fail "local fields in rve.h5"
import json, os, sys
import numpy as np, h5py
d = sys.argv[1]
e = json.load(open(os.path.join(d, "report.json")))["effective"]
C = np.array(e["stiffness"]["tensor"]); K = np.array(e["conductivity"]["tensor"])
r2 = np.sqrt(2.0)
w = np.array([1, 1, 1, r2, r2, r2])  # tensor to Mandel
with h5py.File(os.path.join(d, "rve.h5"), "r") as h:
    for k in range(6):
        eps = h["fields/elasticity/load_%d/strain" % k][...].reshape(-1, 6).astype(float)
        sig = h["fields/elasticity/load_%d/stress" % k][...].reshape(-1, 6).astype(float)
        unit = np.eye(6)[k]
        assert np.allclose(eps.mean(0) * w, unit, atol=1e-5), (k, eps.mean(0))
        assert np.allclose(sig.mean(0) * w, C[:, k], rtol=1e-4, atol=1e-5 * abs(C).max()), (k, sig.mean(0) * w, C[:, k])
        dd = lambda a, b: (a[..., :3] * b[..., :3]).sum(-1) + 2 * (a[..., 3:] * b[..., 3:]).sum(-1)
        hm, mm = dd(sig, eps).mean(), dd(sig.mean(0), eps.mean(0))
        assert abs(hm / mm - 1) < 1e-3, (k, hm, mm)
    for k in range(3):
        q = h["fields/conductivity/load_%d/flux" % k][...].reshape(-1, 3).astype(float)
        assert np.allclose(q.mean(0), K[:, k], rtol=1e-4, atol=1e-6), (k, q.mean(0), K[:, k])
PY
grep -q 'fibres_load\|elasticity_load_5_stress' "$WORK/fib_fields/rve.xdmf" || fail "local fields not in rve.xdmf"
bad fields_no_h5 "{$BOX,$HOM_FAM,\"materials\":{\"matrix\":{\"conductivity\":1},\"spheres\":{\"conductivity\":10}},\"homogenization\":{\"physics\":[\"conductivity\"],\"fields\":true}}" 'homogenization.fields: the local fields go into rve.h5'
bad ti_matrix "{$BOX,$FIB_FAM,\"materials\":{\"matrix\":{\"axial_conductivity\":1,\"transverse_conductivity\":1}}}" "materials.matrix: transversely isotropic properties are for a family"
bad ti_sphere "{$BOX,$HOM_FAM,\"materials\":{\"spheres\":{\"axial_conductivity\":1,\"transverse_conductivity\":1}}}" "need an axis"
bad ti_half "{$BOX,$FIB_FAM,\"materials\":{\"fibres\":{\"axial_young\":230,\"transverse_young\":15}}}" "materials.fibres.axial_shear"
bad ti_both "{$BOX,$FIB_FAM,\"materials\":{\"fibres\":{\"conductivity\":3,\"axial_conductivity\":1,\"transverse_conductivity\":1}}}" "not both"
bad ti_unstable "{$BOX,$FIB_FAM,\"materials\":{\"fibres\":{\"axial_young\":1,\"transverse_young\":1,\"axial_shear\":1,\"axial_poisson\":0.9,\"transverse_poisson\":0.3}}}" "no stable material"

# --threads: the same inclusions.json, byte for byte, on one thread and on two.
cat >"$WORK/threads.json" <<'JSON'
{"box":{"size":[0.5,0.5,0.5]},"seed":4,"md":{"max_steps":300},"families":[
 {"shape":"sphere","radius":0.02,"volume_fraction":0.15},
 {"shape":"cylinder","radius":0.015,"aspect_ratio":6,"volume_fraction":0.05},
 {"shape":"cylinder","radius":0.02,"aspect_ratio":6,"count":5,
  "waviness":{"amplitude":0.02,"wavelength":0.2}}],"outputs":["inclusions"]}
JSON
expect_rc 0 "$RVEGEN" generate -q "$WORK/threads.json" -o "$WORK/threads1" --threads 1
for bad in 2.0 0x10 1e1 +2; do
  expect_rc 2 "$RVEGEN" generate -q "$WORK/threads.json" -o "$WORK/threads_bad" --threads "$bad"
done
expect_rc 0 "$RVEGEN" generate -q "$WORK/threads.json" -o "$WORK/threads2" --threads 2
cmp -s "$WORK/threads1/inclusions.json" "$WORK/threads2/inclusions.json" ||
  fail "--threads 1 and 2 give different inclusions.json"
expect_rc 2 "$RVEGEN" generate -q "$WORK/threads.json" -o "$WORK/threads0" --threads 0
grep -q -- "--threads" "$WORK/last.err" || fail "--threads 0 not named"

# rvegen study: realizations at two sizes, then resumed with more: the same statistics as a
# study run at once with the same seeds (one job against all cores); each realization is
# written once with its seed; counts scale with the volume; bad input names the option.
cat >"$WORK/study.json" <<'JSON'
{"box":{"size":[0.4,0.4,0.4]},"seed":2,"families":[
 {"name":"spheres","shape":"sphere","radius":0.04,"volume_fraction":0.2},
 {"name":"rods","shape":"cylinder","radius":0.015,"aspect_ratio":4,"count":6}],
 "voxels":{"resolution":20},
 "materials":{"matrix":{"conductivity":1},"spheres":{"conductivity":5},"rods":{"conductivity":20}},
 "homogenization":{"physics":["conductivity"]}}
JSON
expect_rc 0 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_a" --sizes 1,1.5 --realizations 2 -q
n_a=$(ls "$WORK/study_a/realizations" | wc -l)
[ "$n_a" -eq 4 ] || fail "study: $n_a realization files for 2 sizes x 2"
touch -d '2001-01-01' "$WORK/study_a/realizations/size_1_0.json"
expect_rc 0 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_a" --sizes 1,1.5 --realizations 3 -q
[ "$(stat -c %Y "$WORK/study_a/realizations/size_1_0.json")" = "$(date -d '2001-01-01' +%s)" ] ||
  fail "study: a kept realization was computed again"
expect_rc 0 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_b" --sizes 1,1.5 --realizations 3 -q --jobs 1
$py - "$WORK/study_a" "$WORK/study_b" <<'PY' || fail "study: resumed and direct studies differ"
import json, sys
a, b = (json.load(open(d + "/study.json")) for d in sys.argv[1:3])
assert a["properties"] == b["properties"], "properties differ"
p = a["properties"]
for k in ("volume_fraction.spheres", "voxel_fraction.spheres", "conductivity.mean",
          "nearest_neighbour.mean", "orientation.rods.a11", "radial_distribution.spheres.peak",
          "radial_distribution.spheres.peak_r"):
    assert k in p, k
    rows = p[k]["per_size"]
    assert [r["n"] for r in rows] == [3, 3], (k, rows)
    for r in rows:
        assert r["ci95"][0] <= r["mean"] <= r["ci95"][1], (k, r)
# Hard spheres: g(r) peaks above 1, at a distance of at least a diameter.
for r in p["radial_distribution.spheres.peak"]["per_size"]:
    assert r["mean"] > 1.0, r
for r in p["radial_distribution.spheres.peak_r"]["per_size"]:
    assert r["mean"] >= 0.08 - 0.4 / 50, r  # a diameter, less one bin of g(r)
# A conductivity between the matrix's and the best phase's, varying between realizations.
for r in p["conductivity.mean"]["per_size"]:
    assert 1.0 < r["mean"] < 20.0 and r["sd"] > 0, r
r0 = json.load(open(sys.argv[1] + "/realizations/size_1.5_2.json"))
assert r0["status"] == "ok" and r0["seed"] > 0 and r0["size"] == 1.5, r0
# The rods are given by count: 6 at size 1, 6 x 1.5^3 = 20 at size 1.5 (spheres by fraction).
assert abs(r0["volume"] - 0.6 ** 3) < 1e-12, r0["volume"]
PY
$py - "$WORK/study_a" <<'PY' || fail "study: the rods' count did not scale with the volume"
import json, sys
for size, want in (("1", 6), ("1.5", 20)):
    rec = json.load(open(sys.argv[1] + "/realizations/size_%s_0.json" % size))
    assert rec["properties"]["volume_fraction.rods"] > 0
    vf = rec["properties"]["volume_fraction.rods"] * rec["volume"]
    import math
    one = math.pi * 0.015 ** 2 * 0.12
    assert abs(vf / one - want) < 1e-6, (size, vf / one)
PY
head -1 "$WORK/study_a/study.csv" | grep -q "^property,size,volume,n,mean,sd,ci95_low,ci95_high" ||
  fail "study: study.csv has no header"
echo '{"box":{"size":[0.4,0.4,0.4]},"seed":3,"families":[{"shape":"sphere","radius":0.04,"volume_fraction":0.2}]}' >"$WORK/study_other.json"
expect_rc 2 "$RVEGEN" study "$WORK/study_other.json" -o "$WORK/study_a" --realizations 1 -q
grep -q "holds a study of another scene" "$WORK/last.err" || fail "study: other scene not named"
# Realizations whose homogenization stopped above its tolerance are counted and left out of
# the statistics (exit 5), as missed targets are.
sed 's/"physics":\["conductivity"\]/"physics":["conductivity"],"max_iterations":2/' "$WORK/study.json" >"$WORK/study_short.json"
expect_rc 5 "$RVEGEN" study "$WORK/study_short.json" -o "$WORK/study_short" --sizes 1 --realizations 2 -q
grep -q "homogenization of 2 realization(s) did not converge" "$WORK/last.err" \
  || fail "study: unconverged realizations not named: $(cat "$WORK/last.err")"
$py - "$WORK/study_short" <<'PY' || fail "study: unconverged realizations in the statistics"
import json, sys
s = json.load(open(sys.argv[1] + "/study.json"))
assert s["not_converged"] == [2] and s["not_reached"] == [0], (s["not_converged"], s["not_reached"])
r = json.load(open(sys.argv[1] + "/realizations/size_1_0.json"))
assert r["status"] == "not_converged" and "stopped at 2 iterations" in r["not_converged"], r
PY
expect_rc 2 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_c" --sizes 1,-2 -q
grep -q -- "--sizes" "$WORK/last.err" || fail "study: bad --sizes not named"
expect_rc 2 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_c" --realizations 0 -q
[ -e "$WORK/study_c" ] && fail "study: bad input left a directory behind"
expect_rc 2 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_c" --bogus -q
# A damaged record is named, with exit 2, and the statistics are not rewritten from it.
cp -r "$WORK/study_a" "$WORK/study_damaged"
echo '{"seed": 1, "status": "ok", "propert' >"$WORK/study_damaged/realizations/size_1.5_1.json"
cp "$WORK/study_damaged/study.json" "$WORK/study_damaged.before"
expect_rc 2 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_damaged" --sizes 1,1.5 --realizations 3 -q
grep -q "size_1.5_1.json is not a realization record" "$WORK/last.err" ||
  fail "study: the damaged record was not named: $(cat "$WORK/last.err")"
cmp -s "$WORK/study_damaged/study.json" "$WORK/study_damaged.before" ||
  fail "study: statistics rewritten from a damaged record"
# A record resumed from is checked before any work: a value edited (still a number), a string
# or null property, a seed of another study; each names the record and the key, and nothing is
# computed or rewritten.
for edit in 's/"conductivity.k11": [0-9.e-]*/"conductivity.k11": 99/@changed after the study wrote it' \
            's/"conductivity.k11": [0-9.e-]*/"conductivity.k11": "abc"/@properties.conductivity.k11: "abc" is not a finite number' \
            's/"volume_fraction": [0-9.e-]*/"volume_fraction": null/@properties.volume_fraction: null' \
            's/"seed": [0-9]*/"seed": 7/@seed: 7, where the study draws'; do
  rm -rf "$WORK/study_edited"
  cp -r "$WORK/study_a" "$WORK/study_edited"
  sed -i "${edit%%@*}" "$WORK/study_edited/realizations/size_1_1.json"
  expect_rc 2 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_edited" --sizes 1,1.5 --realizations 4 -q
  grep -qF "size_1_1.json: ${edit#*@}" "$WORK/last.err" || fail "study: edited record ($edit): $(cat "$WORK/last.err")"
  [ -e "$WORK/study_edited/realizations/size_1_3.json" ] && fail "study: computed before checking the records ($edit)"
  cmp -s "$WORK/study_edited/study.json" "$WORK/study_a/study.json" || fail "study: statistics rewritten ($edit)"
done
# Records that are not the study's: nested 100000 deep (it crashed the reader), not JSON (named
# plainly, not in the JSON library's words), a link to another file.
rm -rf "$WORK/study_edited" && cp -r "$WORK/study_a" "$WORK/study_edited"
$py -c "import sys; open(sys.argv[1], 'w').write('{\"a\": ' + '[' * 100000 + ']' * 100000 + '}')" "$WORK/study_edited/realizations/size_1_1.json"
expect_rc 2 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_edited" --sizes 1,1.5 --realizations 3 -q
grep -q "size_1_1.json is not a realization record: .*nested deeper than 256 levels" "$WORK/last.err" || fail "study: deep record: $(head -c 300 "$WORK/last.err")"
echo '{"seed": NaN}' >"$WORK/study_edited/realizations/size_1_1.json"
expect_rc 2 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_edited" --sizes 1,1.5 --realizations 3 -q
grep -q "size_1_1.json is not a realization record: .*line 1, column" "$WORK/last.err" && ! grep -q "json.exception" "$WORK/last.err" || fail "study: NaN record: $(cat "$WORK/last.err")"
rm "$WORK/study_edited/realizations/size_1_1.json"
ln -s "$WORK/study_a/realizations/size_1_1.json" "$WORK/study_edited/realizations/size_1_1.json"
expect_rc 2 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_edited" --sizes 1,1.5 --realizations 3 -q
grep -q "size_1_1.json is not a realization record: a link" "$WORK/last.err" || fail "study: linked record: $(cat "$WORK/last.err")"
# Continuous fibres in a box thin along them: what generate wrote, check and homogenize read.
echo '{"box":{"size":[1,1,0.02]},"seed":1,"families":[{"shape":"cylinder","radius":0.05,"length":"through","volume_fraction":0.5}],"voxels":{"resolution":[32,32,1]}}' >"$WORK/thin_through.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/thin_through.json" -o "$WORK/thin_through"
expect_rc 0 "$RVEGEN" check "$WORK/thin_through/inclusions.json"
# Shells that may touch, counted whole where three meet: the matrix's share is a lower bound,
# never below 0, the interphase's an upper one (it was -0.018).
echo '{"box":{"size":[1,1,1]},"seed":1,"families":[{"name":"s","shape":"sphere","radius":0.1,"volume_fraction":0.3,"coating":{"thickness":0.05,"shells_may_touch":true}}],"voxels":{"resolution":16}}' >"$WORK/merged_shells.json"
expect_rc 0 "$RVEGEN" generate -q "$WORK/merged_shells.json" -o "$WORK/merged_shells"
$py - "$WORK/merged_shells/report.json" <<'PY' || fail "merged shells: the phases' shares"
import json, sys
ph = {p["kind"]: p for p in json.load(open(sys.argv[1]))["phases"]}
assert ph["matrix"]["volume_fraction"] >= 0 and ph["matrix"]["bound"] == "lower", ph["matrix"]
assert ph["interphase"]["bound"] == "upper", ph["interphase"]
PY
# min_gap named when it is what keeps an inclusion out of the box.
echo '{"box":{"size":[1,1,1]},"min_gap":0.9,"families":[{"shape":"sphere","radius":0.1,"count":2}]}' >"$WORK/big_gap.json"
expect_rc 2 "$RVEGEN" generate -q "$WORK/big_gap.json" -o "$WORK/big_gap"
grep -q "plus twice min_gap" "$WORK/last.err" || fail "min_gap not named: $(cat "$WORK/last.err")"
echo '{"box":{"size":[1,1,1]}} trailing' >"$WORK/trailing.json"
expect_rc 2 "$RVEGEN" generate -q "$WORK/trailing.json" -o "$WORK/trailing"
grep -q "not valid JSON" "$WORK/last.err" && ! grep -q "json.exception" "$WORK/last.err" || fail "scene with trailing text: $(cat "$WORK/last.err")"
# A link planted where the study writes its statistics' temporary file is replaced, never
# followed (it overwrote the file it pointed to).
rm -rf "$WORK/study_link" && cp -r "$WORK/study_a" "$WORK/study_link" && echo precious >"$WORK/precious.txt"
ln -s "$WORK/precious.txt" "$WORK/study_link/study.json.part"
expect_rc 0 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_link" --sizes 1,1.5 --realizations 3 -q
[ "$(cat "$WORK/precious.txt")" = precious ] || fail "study: a planted link was followed"
[ -L "$WORK/study_link/study.json" ] && fail "study: study.json left a link"
rm -rf "$WORK/study_file" && mkdir -p "$WORK/study_file" && cp "$WORK/study_a/study_scene.json" "$WORK/study_file/" && touch "$WORK/study_file/realizations"
expect_rc 1 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_file" --sizes 1,1.5 -q
grep -q "realizations is not a directory" "$WORK/last.err" || fail "study: realizations a file: $(cat "$WORK/last.err")"
# Memory before any work: a size whose realization cannot fit is refused, naming the size; a
# limit that holds one realization but not two runs one at a time.
expect_rc 2 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_mem" --sizes 1,8 --max-memory 300M -q
grep -q "a realization at size 8 needs about .* above the --max-memory limit of 315 MB" "$WORK/last.err" ||
  fail "study --max-memory: $(cat "$WORK/last.err")"
[ -e "$WORK/study_mem" ] && fail "study: a refused study left a directory behind"
expect_rc 0 "$RVEGEN" study "$WORK/study.json" -o "$WORK/study_mem" --sizes 1 --realizations 2 --max-memory 100M --jobs 2
grep -q "study: 1 realization(s) at once (of 2)" "$WORK/last.err" || fail "study: jobs not fitted to memory: $(cat "$WORK/last.err")"
# The window method through the study: dilute spheres (phi 0.02, radius 0.01), whose integral
# range has a closed form, A3 = V_s S(0) / (1 - phi) with S(0) = (1 - phi)^4 / (1 + 2 phi)^2
# (tests/test_representativity.cpp says why): within 10 %.
echo '{"box":{"size":[1,1,1]},"seed":4,"method":"rsa","families":[{"name":"spheres","shape":"sphere","radius":0.01,"volume_fraction":0.02}],"voxels":{"resolution":120,"partial_volume":true}}' >"$WORK/dilute.json"
expect_rc 0 "$RVEGEN" study "$WORK/dilute.json" -o "$WORK/study_dilute" --sizes 1 --realizations 12 -q
$py - "$WORK/study_dilute" <<'PY' || fail "study: window integral range of dilute spheres"
import json, math, sys
w = json.load(open(sys.argv[1] + "/study.json"))["properties"]["volume_fraction"]["windows"]
phi, r = 0.02, 0.01
a3 = 4 / 3 * math.pi * r ** 3 * (1 - phi) ** 4 / (1 + 2 * phi) ** 2 / (1 - phi)
assert abs(w["integral_range"] / a3 - 1) < 0.10, (w["integral_range"], a3)
assert [v["k"] for v in w["per_window"]] == [2, 3, 4, 5, 6, 8], w["per_window"]
assert w["volume_for_target"] > 0, w
PY
# Labels only (no partial volume) and coated spheres: the windows measure the cores' share, not
# the cores' and coatings'.
echo '{"box":{"size":[1,1,1]},"seed":4,"method":"rsa","families":[{"name":"spheres","shape":"sphere","radius":0.01,"volume_fraction":0.05,"coating":{"thickness":0.005}}],"voxels":{"resolution":120}}' >"$WORK/coated_windows.json"
expect_rc 0 "$RVEGEN" study "$WORK/coated_windows.json" -o "$WORK/study_coated" --sizes 1 --realizations 2 -q
$py - "$WORK/study_coated" <<'PY' || fail "study: windows of coated spheres"
import json, sys
p = json.load(open(sys.argv[1] + "/study.json"))["properties"]
w, phi = p["volume_fraction"]["windows"], p["volume_fraction"]["per_size"][0]["mean"]
assert abs(w["mean"] - phi) < 0.01, (w["mean"], phi)  # the cores' 0.05, not the coated 0.17
PY
# No windows where the inclusions are too large for them (the rods of the first study).
$py - "$WORK/study_a" <<'PY' || fail "study: windows for inclusions too large for them"
import json, sys
assert "windows" not in json.load(open(sys.argv[1] + "/study.json"))["properties"]["volume_fraction"]
PY

finish "CLI tests"
