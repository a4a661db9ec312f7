#!/usr/bin/env bash
# The pvpython samples write next to an RVE directory, never inside it: after render_rve.py and
# pv_open_rve.py run with their default output paths, the directory lists exactly what rvegen
# wrote, and `rvegen generate -o DIR` replaces it (exit 0) rather than refusing it.
# usage: samples_leave_rve.sh RVEGEN PVPYTHON WORK_DIR   (under an X server: run_headless.sh)
set -u
RVEGEN=$1
PVPYTHON=$2
WORK=$3
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
rm -rf "$WORK" && mkdir -p "$WORK"
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }
"$RVEGEN" generate -q -o "$WORK/rve" || fail "generate"
before=$(ls -A "$WORK/rve")
"$PVPYTHON" --force-offscreen-rendering "$ROOT/samples/render_rve.py" "$WORK/rve" >"$WORK/render.log" 2>&1 \
  || fail "render_rve.py: $(tail -3 "$WORK/render.log")"
"$PVPYTHON" --force-offscreen-rendering "$ROOT/samples/pv_open_rve.py" "$WORK/rve" >"$WORK/open.log" 2>&1 \
  || fail "pv_open_rve.py: $(tail -3 "$WORK/open.log")"
[ -s "$WORK/rve_rve.png" ] || fail "render_rve.py did not write $WORK/rve_rve.png"
[ -s "$WORK/rve_slice96.png" ] || fail "pv_open_rve.py did not write $WORK/rve_slice96.png"
[ "$(ls -A "$WORK/rve")" = "$before" ] || fail "the samples wrote into the RVE directory: $(ls -A "$WORK/rve" | tr '\n' ' ')"
"$RVEGEN" generate -q -o "$WORK/rve" || fail "rvegen generate refused the RVE directory after the samples"
[ "$fails" -eq 0 ] && echo "samples leave the RVE directory alone" || exit 1
