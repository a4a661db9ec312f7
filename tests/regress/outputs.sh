#!/usr/bin/env bash
# Same seed, same RVE, across code changes: generates the default scene and every scene in
# samples/scenes/ and compares the SHA-256 of inclusions.json, voxels.vti (labels, ids and
# partial volumes) and material.vtk with the checked-in tests/regress/outputs.sha256. A change
# of the packing or of the representations shows here; one that is meant must update the file
# (--update) in the same commit, and say why.
# usage: outputs.sh RVEGEN WORK_DIR [--update]
set -euo pipefail
RVEGEN=$1
WORK=$2
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
EXPECTED="$HERE/outputs.sha256"
rm -rf "$WORK" && mkdir -p "$WORK"
scenes=(default "$ROOT"/samples/scenes/*.json)
: >"$WORK/actual.sha256"
for scene in "${scenes[@]}"; do
  name=$(basename "$scene" .json)
  if [ "$scene" = default ]; then
    "$RVEGEN" generate -q --outputs inclusions,voxels,amitex -o "$WORK/$name" || [ $? -eq 3 ]
  else
    "$RVEGEN" generate -q "$scene" --outputs inclusions,voxels,amitex -o "$WORK/$name" || [ $? -eq 3 ]
  fi
  for f in inclusions.json voxels.vti material.vtk; do
    echo "$(sha256sum <"$WORK/$name/$f" | cut -d' ' -f1)  $name/$f" >>"$WORK/actual.sha256"
  done
done
if [ "${3:-}" = "--update" ]; then
  cp "$WORK/actual.sha256" "$EXPECTED"
  echo "updated $EXPECTED"
  exit 0
fi
if ! diff -u "$EXPECTED" "$WORK/actual.sha256"; then
  echo "FAIL: outputs differ from tests/regress/outputs.sha256 (lines above)"
  exit 1
fi
echo "outputs identical for ${#scenes[@]} scenes"
