#!/usr/bin/env bash
# Installs what is needed, builds, installs into ./install, generates the built-in default
# scene into out/default (inclusions.json, inclusions.vtp, voxels.vti, report.json) and renders
# it headless to out/default_rve.png (next to the RVE, not inside it).
set -euo pipefail
cd "$(dirname "$0")/.."
bash .ci/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX="$PWD/install"
cmake --build build -j"$(nproc)"
cmake --install build >/dev/null
./install/bin/rvegen generate -o out/default
./install/bin/rvegen check out/default/inclusions.json
# The picture (one more try if the X server connection fails, as it has been seen to under load).
for attempt in 1 2; do
  xvfb-run -a -s "-screen 0 1280x1024x24" pvpython --force-offscreen-rendering \
    samples/render_rve.py out/default out/default_rve.png && break
  [ "$attempt" -eq 2 ] && exit 1
  echo "quickstart: rendering failed; trying once more" >&2
done
