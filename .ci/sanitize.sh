#!/usr/bin/env bash
# The sanitizer build and the fuzzer (run by .ci/test.sh after the main build's tests):
#  - the core, the command line and their tests built with clang, AddressSanitizer and
#    UndefinedBehaviorSanitizer (every report is an error), without the ParaView parts;
#  - the unit and command-line tests run in it (the million-pair property tests, the output
#    hashes, which hold for the main build's compiler, five long tests whose code smaller ones
#    run here, and the command-line test of the tetrahedral mesh run in the main build only);
#  - the libFuzzer target rvegen_fuzz runs for FUZZ_SECONDS (default 60) from the checked-in
#    corpus; any crash, sanitizer report, uncaught exception or hang (20 s) fails. Its coverage
#    feedback is compiled into the code that reads and checks input only (src/CMakeLists.txt):
#    in every library it made this build's tests twice as slow (565 s against 298 s, 2 cores).
set -euo pipefail
cd "$(dirname "$0")/.."
B=build-sanitize
# Line tables only for the debug information: the reports' file and line, a build 12 % faster and
# a third of the size (179 s against 204 s from scratch, 155 MB against 498 MB).
cmake -S . -B "$B" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRVEGEN_WITH_PARAVIEW=OFF \
  -DRVEGEN_BUILD_BENCHMARKS=OFF -DRVEGEN_SANITIZE=ON -DRVEGEN_FUZZ=ON \
  -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -gline-tables-only -DNDEBUG"
cmake --build "$B" -j"$(nproc)"
# Three accuracy tests at full scale run in the main build only: under the sanitizers they took
# 111 s, 94 s and 76 s of the 2-core CI budget, and the code they run is run here by smaller
# tests (partial volumes: the other Voxels and Modifiers cases; packing deformed spheres to
# jamming: DeformedSupport.PackingReachesHalf..., Md.*; every orientation law: the other
# FibreOrientation cases). So do two more that run no code the others do not (99 s and 49 s
# here): the packer-against-audit sweep of two deformed grains (the round pairs' contact with
# support functions runs in the grain_sphere sweep, the audit of two grains in
# DeformedSupport.PackingReachesHalf...) and the same-seed check of
# the modified RVE (its packing runs in the other Modifiers cases, the reading back of its
# inclusion file in the command-line test).
# The command-line test of the tetrahedral mesh (cli_tet_mesh: 76 s alone under the sanitizers,
# 160-200 s beside the other tests) runs in the main build only too: the mesher's own code runs
# here in the TetMesh cases (the cell, the node moves and insertions, second order, the volume
# check, the estimate), and the writers of its files and decks in TetMeshFiles; what that test
# adds is Gmsh on larger scenes, CalculiX and meshio, none of which the sanitizers instrument.
main_build_only="Voxels.PartialVolumesMatchBruteForcePerVoxel|DeformedSupport.AboveJammingStopsJammedWithTheAuditPassed|FibreOrientation.EveryLawIsDeliveredNearItsDensityLimit|AllKinds/PairKindSweep.PackerAndAuditDecideAlike/grain_grain|Modifiers.SameSeedSameModifiedRve|cli_tet_mesh"
# Order: a fresh clone has no timing history, and ctest would start the GoogleTest cases in the
# order they are declared, so a long one declared late ran alone at the end. The longest cases'
# seconds under the sanitizers (a fresh-clone run, this machine) go where ctest keeps its history,
# so that it starts them first; the scripts carry a COST (tests/CMakeLists.txt). A build with its
# own history keeps it.
costs="$B/Testing/Temporary/CTestCostData.txt"
if [ ! -s "$costs" ]; then
  mkdir -p "$(dirname "$costs")"
  cat >"$costs" <<'EOF'
ChainRestarts.IntertwinedChainsGoBackToTheBestConfigurationAndPackFurther 1 45
TetMesh.OverlappingShellsAreMeshedOnceAndTheirVolumesAreExact 1 25
Md.MixedShapesWithLawsNonPeriodicAndGap 1 23
DeformedSupport.PackingReachesHalfAndTrueSurfacesDoNotOverlap 1 17
LevelSets.OnlyForWhatNeedsOneAndSignsMatchTheRegions 1 17
Chains.WavyFibresPackPastTheirEnvelopesWithoutTrueOverlap 1 15
Modifiers.PackedBodiesDoNotOverlap 1 14
AllKinds/PairKindSweep.PackerAndAuditDecideAlike/grain_sphere 1 14
Modifiers.PhaseVolumeFractionsAreExactAndVoxelsAgree 1 14
AllKinds/PairKindSweep.PackerAndAuditDecideAlike/chain_grain 1 12
TetMesh.TheVolumeTheChordsCutOffIsGivenBackToEveryPhase 1 11
FibreOrientation.EllipsoidsWithATensorKeepIt 1 10
Threads.SameRveOnAnyNumberOfThreads 1 10
---
EOF
fi
ctest --test-dir "$B" --output-on-failure -j"$(nproc)" -LE "property|regress" -E "^($main_build_only)\$"
rm -rf "$B/fuzz-new" && mkdir -p "$B/fuzz-new"
"$B/bin/rvegen_fuzz" -max_total_time="${FUZZ_SECONDS:-60}" -timeout=20 -rss_limit_mb=4096 \
  -print_final_stats=1 "$B/fuzz-new" tests/fuzz/corpus
