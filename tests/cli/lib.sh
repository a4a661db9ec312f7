# What the command-line test scripts share (sourced, after WORK is set): counting failures,
# running a command with the exit code it must give, and the verdict at the end.
fails=0
py=/usr/bin/python3
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }
expect_rc() {  # expect_rc WANT CMD...: stdout to $WORK/last.out, stderr to $WORK/last.err
  local want=$1; shift
  "$@" >"$WORK/last.out" 2>"$WORK/last.err"
  local rc=$?
  [ "$rc" -eq "$want" ] || fail "exit $rc (want $want): $* -- $(head -c 600 "$WORK/last.err")"
}
finish() {  # finish WHAT: exit 1 after any failure
  if [ "$fails" -ne 0 ]; then
    echo "$fails failure(s)"
    exit 1
  fi
  echo "all $1 passed"
}
