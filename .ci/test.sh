#!/usr/bin/env bash
# Installs what is needed, builds and runs every test (GoogleTest suites including the
# million-pair property test, the command-line tests, and the pvpython plugin test with its
# image comparison under xvfb-run), then the sanitizer build's tests and a minute of fuzzing
# (.ci/sanitize.sh), then the packing's tests under ThreadSanitizer (.ci/tsan.sh). Exits non-zero
# when any test fails.
set -euo pipefail
cd "$(dirname "$0")/.."
bash .ci/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)"
ctest --test-dir build --output-on-failure -j"$(nproc)"
bash .ci/sanitize.sh
bash .ci/tsan.sh
