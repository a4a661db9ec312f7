#!/usr/bin/env bash
# Another copy of rvegen's libraries on LD_LIBRARY_PATH (an older install, a broken one) must not
# be loaded in place of the ones a binary was built or installed with. Open MPI's mpirun, started
# by its full path, puts /usr/lib first in LD_LIBRARY_PATH, so a copy in /usr/lib would otherwise
# break every run under it. Here the copies are empty files, which the loader refuses ("file too
# short") if it ever picks them.
# usage: test_library_path.sh LIBDIR WORK_DIR BINARY... [-- PVPYTHON PLUGIN]
set -u
LIBDIR=$1
WORK=$2
shift 2
rm -rf "$WORK" && mkdir -p "$WORK/stale"
source "$(dirname "$0")/lib.sh"
n=0
for lib in "$LIBDIR"/librvegen_*.so.*; do
  name=$(basename "$lib")
  case $name in *.so.[0-9]) : >"$WORK/stale/$name"; n=$((n + 1)) ;; esac
done
[ "$n" -ge 5 ] || fail "only $n libraries found in $LIBDIR"
while [ $# -gt 0 ] && [ "$1" != "--" ]; do
  expect_rc 0 env LD_LIBRARY_PATH="$WORK/stale" "$1" --version
  grep -q "^rvegen " "$WORK/last.out" || fail "$1 --version printed: $(cat "$WORK/last.out")"
  shift
done
if [ "${1:-}" = "--" ]; then
  pvpython=$2
  plugin=$3
  expect_rc 0 env LD_LIBRARY_PATH="$WORK/stale" "$pvpython" -c "
import paraview.simple as pv
pv.LoadPlugin('$plugin', remote=False)
print('plugin loaded', pv.RVEGenerator)"
  grep -q "plugin loaded" "$WORK/last.out" || fail "the plugin did not load: $(head -c 600 "$WORK/last.err")"
fi
finish "library path checks"
