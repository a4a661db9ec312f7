#!/usr/bin/env bash
# Runs a command under an X server of its own (Xvfb). Xvfb picks a free display number itself
# and reports it once it accepts connections (-displayfd), so tests starting together never
# share or race for a display (xvfb-run -a could hand out the same number twice).
# -noreset: by default Xvfb resets itself when its last client leaves, and a command that runs
# two programs in turn (samples_leave_rve.sh) could connect during the reset and abort with "bad
# X server connection" (1 run in 5 once the plugin also loaded Gmsh's libraries; 0 in 8 with
# -noreset).
# A run killed by a signal (an abort while the X server creates a window has been seen once
# under load) is tried once more with a fresh server; a test that fails by its own checks
# (exit 1) is not retried.
# usage: run_headless.sh COMMAND [ARGS...]
set -u
run_once() {
numfile=$(mktemp)
xlog=$(mktemp)
Xvfb -displayfd 3 -screen 0 1280x1024x24 -nolisten tcp -noreset 3>"$numfile" >"$xlog" 2>&1 &
pid=$!
for _ in $(seq 300); do
  if [ -s "$numfile" ] || ! kill -0 "$pid" 2>/dev/null; then break; fi
  sleep 0.1
done
display=$(tr -dc '0-9' <"$numfile")
rm -f "$numfile"
if [ -z "$display" ] || ! kill -0 "$pid" 2>/dev/null; then
  echo "run_headless: could not start an X server" >&2
  kill "$pid" 2>/dev/null
  return 1
fi
DISPLAY=":$display" "$@"
rc=$?
if [ "$rc" -ne 0 ]; then
  # What the X server said, and whether it was still there.
  kill -0 "$pid" 2>/dev/null && echo "run_headless: Xvfb :$display still running" >&2 \
    || echo "run_headless: Xvfb :$display had exited" >&2
  ls -la /tmp/.X11-unix >&2 2>/dev/null
  sed 's/^/Xvfb: /' "$xlog" | tail -20 >&2
fi
rm -f "$xlog"
kill "$pid" 2>/dev/null
wait "$pid" 2>/dev/null
return "$rc"
}
run_once "$@"
rc=$?
if [ "$rc" -ge 128 ]; then
  echo "run_headless: the command died of signal $((rc - 128)); trying once more" >&2
  run_once "$@"
  rc=$?
fi
exit "$rc"
