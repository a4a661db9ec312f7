#!/usr/bin/env bash
# The ThreadSanitizer run of the packing's tests (run by .ci/test.sh after .ci/sanitize.sh):
# clang with -fsanitize=thread (RVEGEN_TSAN), the packing's test binary alone, its tests on all
# cores; any report is an error. Under ThreadSanitizer the packing's parallel loops run on plain
# threads it can follow (src/rvegen/model/parallel.hpp): Debian's libtbb is not built for it.
set -euo pipefail
cd "$(dirname "$0")/.."
B=build-tsan
cmake -S . -B "$B" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRVEGEN_WITH_PARAVIEW=OFF \
  -DRVEGEN_BUILD_BENCHMARKS=OFF -DRVEGEN_TSAN=ON \
  -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -gline-tables-only -DNDEBUG"
cmake --build "$B" -j"$(nproc)" --target rvegen_packing_tests
TSAN_OPTIONS="halt_on_error=1 exitcode=66" "$B/bin/rvegen_packing_tests" \
  --gtest_filter='Threads.*:Md.*:MdParts.*:Neighbours.*:Chains.*:Audit.*:-Md.MixedShapesWithLawsNonPeriodicAndGap'
