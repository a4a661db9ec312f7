#!/usr/bin/env bash
# rvegen study under an MPI launcher: two ranks give the statistics of one process, share the
# realizations out (records from both), resume a study, and say an error once.
# usage: test_study_mpi.sh RVEGEN_BINARY MPIRUN WORK_DIR
set -u
RVEGEN=$1
MPIRUN=$2
WORK=$3
rm -rf "$WORK" && mkdir -p "$WORK"
source "$(dirname "$0")/lib.sh"
two() { "$MPIRUN" --allow-run-as-root --oversubscribe -np 2 "$@"; }
cat >"$WORK/study.json" <<'JSON'
{"box":{"size":[0.4,0.4,0.4]},"seed":5,"families":[
 {"name":"spheres","shape":"sphere","radius":0.04,"volume_fraction":0.2},
 {"name":"rods","shape":"cylinder","radius":0.015,"aspect_ratio":4,"count":6}],
 "voxels":{"resolution":16},
 "materials":{"matrix":{"conductivity":1},"spheres":{"conductivity":5},"rods":{"conductivity":20}},
 "homogenization":{"physics":["conductivity"]}}
JSON
expect_rc 0 "$RVEGEN" study "$WORK/study.json" -o "$WORK/one" --sizes 1,1.5 --realizations 3 -q --jobs 1
expect_rc 0 two "$RVEGEN" study "$WORK/study.json" -o "$WORK/two" --sizes 1,1.5 --realizations 3 -q
# Resumed under two ranks: 2 realizations first, then the third of each size.
expect_rc 0 two "$RVEGEN" study "$WORK/study.json" -o "$WORK/resumed" --sizes 1,1.5 --realizations 2 -q
expect_rc 0 two "$RVEGEN" study "$WORK/study.json" -o "$WORK/resumed" --sizes 1,1.5 --realizations 3
grep -q "2 to compute (4 kept)" "$WORK/last.err" || fail "resumed study computed more than the missing"
$py - "$WORK" <<'PY' || fail "two ranks and one process differ"
import glob, json, sys
w = sys.argv[1]
one, two, resumed = (json.load(open("%s/%s/study.json" % (w, d))) for d in ("one", "two", "resumed"))
assert one["ranks"] == 1 and two["ranks"] == 2, (one["ranks"], two["ranks"])
assert one["properties"] == two["properties"], "statistics of 2 ranks differ from 1 process"
assert one["properties"] == resumed["properties"], "resumed under 2 ranks differs"
assert "conductivity.mean" in two["properties"], list(two["properties"])
# Memory: every rank's peak, the largest as the study's.
peaks = two["peak_memory_mb_ranks"]
assert len(peaks) == 2 and min(peaks) > 1, peaks
assert two["peak_memory_mb"] == max(peaks), (two["peak_memory_mb"], peaks)
assert "peak_memory_mb_ranks" not in one and one["peak_memory_mb"] > 1, one["peak_memory_mb"]
ranks = sorted(json.load(open(f))["rank"] for f in glob.glob(w + "/two/realizations/*.json"))
assert ranks == [0, 0, 0, 1, 1, 1], ranks
# The records themselves: the same seeds, counts and properties as one process wrote.
for f in glob.glob(w + "/one/realizations/*.json"):
    a = json.load(open(f))
    b = json.load(open(f.replace("/one/", "/two/")))
    for k in ("seed", "count", "status", "properties"):
        assert a[k] == b[k], (f, k)
PY
# An error is said once, with the exit code of one process.
echo '{"box":{"size":[0.4,0.4,0.4]},"seed":3,"families":[{"shape":"sphere","radius":0.04,"volume_fraction":0.2}]}' >"$WORK/other.json"
expect_rc 2 two "$RVEGEN" study "$WORK/other.json" -o "$WORK/two" --realizations 1 -q
[ "$(grep -c "holds a study of another scene" "$WORK/last.err")" -eq 1 ] ||
  fail "the error was not said once: $(cat "$WORK/last.err")"
expect_rc 2 two "$RVEGEN" study "$WORK/study.json" -o "$WORK/bad" --sizes 1,-2 -q
[ "$(grep -c -- "--sizes" "$WORK/last.err")" -eq 1 ] || fail "bad --sizes not said once"
[ -e "$WORK/bad" ] && fail "bad input under two ranks left a directory behind"

finish "study MPI tests"
