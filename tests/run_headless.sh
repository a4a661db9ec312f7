#!/usr/bin/env bash
# Runs a command under an X server of its own (Xvfb): a display number nobody uses, started and
# checked ready before the command runs, stopped and waited for after. (xvfb-run -a can hand two
# tests starting together, or one starting while another's server shuts down, the same number.)
# usage: run_headless.sh COMMAND [ARGS...]
set -u
start=$((100 + $$ % 400))
for n in $(seq "$start" 999); do
  if [ -e "/tmp/.X$n-lock" ] || [ -e "/tmp/.X11-unix/X$n" ]; then continue; fi
  Xvfb ":$n" -screen 0 1280x1024x24 -nolisten tcp >/dev/null 2>&1 &
  pid=$!
  for _ in $(seq 100); do
    if [ -e "/tmp/.X11-unix/X$n" ] || ! kill -0 "$pid" 2>/dev/null; then break; fi
    sleep 0.1
  done
  if kill -0 "$pid" 2>/dev/null && [ -e "/tmp/.X11-unix/X$n" ]; then
    DISPLAY=":$n" "$@"
    rc=$?
    kill "$pid" 2>/dev/null
    wait "$pid" 2>/dev/null
    exit "$rc"
  fi
  wait "$pid" 2>/dev/null  # lost the race for this number: try the next one
done
echo "run_headless: could not start an X server" >&2
exit 1
