#!/usr/bin/env bash
# samples/pv_study.py as a user runs it (under an X server of its own): a small study of spheres
# at three sizes, then its charts drawn by ParaView. The table ParaView charted must be the
# study's own rows, and both pictures must be written.
# usage: test_pv_study.sh PVPYTHON RVEGEN SAMPLES_DIR WORK_DIR
set -eu
PVPYTHON=$1
RVEGEN=$2
SAMPLES=$3
WORK=$4
rm -rf "$WORK" && mkdir -p "$WORK"
cat >"$WORK/scene.json" <<'JSON'
{"box":{"size":[0.4,0.4,0.4]},"seed":2,"families":[
 {"name":"spheres","shape":"sphere","radius":0.04,"volume_fraction":0.25}],
 "voxels":{"resolution":16},
 "materials":{"matrix":{"conductivity":1},"spheres":{"conductivity":10}},
 "homogenization":{"physics":["conductivity"]}}
JSON
bash "$(dirname "$0")/../../tests/run_headless.sh" "$PVPYTHON" --force-offscreen-rendering \
  "$SAMPLES/pv_study.py" "$WORK/scene.json" -o "$WORK/study" --sizes 1,1.5,2 --realizations 4 \
  --rvegen "$RVEGEN" >"$WORK/out.txt" 2>&1 || { cat "$WORK/out.txt"; exit 1; }
grep -q "^conductivity.mean: recommended box edge" "$WORK/out.txt" || { cat "$WORK/out.txt"; exit 1; }
/usr/bin/python3 - "$WORK/study" <<'PY'
import csv, json, os, sys
d = sys.argv[1]
study = json.load(open(d + "/study.json"))
p = study["properties"]["conductivity.mean"]
rows = list(csv.DictReader(open(d + "/pv_study_chart.csv")))
assert len(rows) == 3, rows
law = p["variance_law"]
for r, want in zip(rows, p["per_size"]):
    for k in ("size", "volume", "mean"):
        assert abs(float(r[k]) - want[k]) <= 1e-4 * abs(want[k]), (k, r, want)
    assert abs(float(r["variance"]) - want["sd"] ** 2) <= 1e-4 * want["sd"] ** 2, (r, want)
    fit = law["K"] * want["volume"] ** -law["alpha"]
    assert abs(float(r["variance_law"]) - fit) <= 1e-4 * fit, (r, fit)
for png in ("pv_study_mean.png", "pv_study_variance.png"):
    assert os.path.getsize(os.path.join(d, png)) > 10000, png
print("pv_study sample: chart table matches study.json")
PY
