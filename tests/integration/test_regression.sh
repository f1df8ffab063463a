#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Replays every recorded input in DATA (.fgr or .csv) through a running fovea-trackerd and diffs
# what a subscribed client receives (samples by state, events with their times, amplitudes and
# positions) against DATA/<input>.expected. Regenerate after an intended change with
#   FOVEA_REGENERATE=1 bash tests/integration/test_regression.sh TRACKERD CLIENT DATA
# and review the diff of the .expected files like code.
set -u
TRACKERD=$1 CLIENT=$2 DATA=$3
SPEED=1  # real time: the classifier must see real velocities
. "$(dirname "${BASH_SOURCE[0]}")/ports.sh"
WORK=$(mktemp -d)
DAEMON=""
cleanup() { [ -n "$DAEMON" ] && kill -9 "$DAEMON" 2>/dev/null; rm -rf "$WORK"; }
trap cleanup EXIT
failures=0
count=0
for input in "$DATA"/*.fgr "$DATA"/*.csv; do
  [ -f "$input" ] || continue
  count=$((count + 1))
  name=$(basename "$input")
  port=$(free_udp_port)
  "$TRACKERD" --source "replay:$input" --speed $SPEED --wait-subscribers 1 --port $port \
    >"$WORK/$name.daemon.log" 2>&1 &
  DAEMON=$!
  ok=0
  for _ in $(seq 1 50); do
    if "$CLIENT" 127.0.0.1:$port --timeout 120 >"$WORK/$name.out" 2>"$WORK/$name.err"; then ok=1; break; fi
    grep -q "no answer" "$WORK/$name.err" || break  # only retry while the daemon is still starting
    sleep 0.1
  done
  kill -TERM "$DAEMON" 2>/dev/null; wait "$DAEMON" 2>/dev/null; DAEMON=""
  if [ $ok -ne 1 ]; then
    echo "FAIL $name: client failed: $(cat "$WORK/$name.err")"; tail -5 "$WORK/$name.daemon.log"
    failures=$((failures + 1)); continue
  fi
  if [ "${FOVEA_REGENERATE:-0}" = 1 ]; then
    cp "$WORK/$name.out" "$input.expected"; echo "regenerated $input.expected"; continue
  fi
  if ! diff -u "$input.expected" "$WORK/$name.out" >"$WORK/$name.diff"; then
    echo "FAIL $name: output differs from $name.expected:"; head -40 "$WORK/$name.diff"
    failures=$((failures + 1))
  else
    echo "ok   $name ($(grep -c '^ *[0-9]' "$WORK/$name.out") events)"
  fi
done
[ $count -gt 0 ] || { echo "FAIL: no inputs in $DATA"; exit 1; }
[ $failures -eq 0 ] && echo "PASS ($count inputs)" || exit 1
