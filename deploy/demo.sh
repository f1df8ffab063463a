#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea's main job on bundled defaults, no hardware needed:
#   installs dependencies if missing, builds, starts fovea-trackerd replaying the bundled gaze
#   recording, connects four clients — fovea-ctl watch (live lines), fovea-ctl record (a .fgr file)
#   and two headless fovea-render clients (Embree and OpenGL backends) writing frames and per-pass
#   timings — runs ~10 s, stops everything cleanly and prints a summary.
# Environment: FOVEA_DEMO_SECONDS (default 10), FOVEA_DEMO_PORT (default 47810),
#              FOVEA_DEMO_SCENE (default renderer/scenes/attention.json), FOVEA_DEMO_FPS (default 10).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
SECONDS_TO_RUN=${FOVEA_DEMO_SECONDS:-10}
PORT=${FOVEA_DEMO_PORT:-47810}
SERVER=127.0.0.1:$PORT
RECORDING=$ROOT/tests/data/recordings/synthetic-250hz-62s.fgr
SCENE=${FOVEA_DEMO_SCENE:-$ROOT/renderer/scenes/attention.json}
FPS=${FOVEA_DEMO_FPS:-10}
OUT=$ROOT/out/demo/$(date +%Y%m%d-%H%M%S)
mkdir -p "$OUT"

bash deploy/install-deps.sh
echo "demo: building (log: $OUT/build.log)"
if ! { cmake --preset default && cmake --build --preset default; } >"$OUT/build.log" 2>&1; then
  tail -n 40 "$OUT/build.log"; echo "demo: build failed (full log: $OUT/build.log)" >&2; exit 1
fi
BIN=$ROOT/build/default/trackerd
RENDER=$ROOT/build/default/renderer/fovea-render

PIDS=()
cleanup() { for p in "${PIDS[@]}"; do kill -TERM "$p" 2>/dev/null || true; done; }
trap cleanup EXIT INT TERM

echo "demo: starting fovea-trackerd on $SERVER replaying $(basename "$RECORDING") (log: $OUT/trackerd.log)"
"$BIN/fovea-trackerd" --source "replay:$RECORDING" --loop --port "$PORT" >"$OUT/trackerd.log" 2>&1 &
DAEMON=$!
PIDS+=("$DAEMON")
for _ in $(seq 1 50); do
  "$BIN/fovea-ctl" --server "$SERVER" status >/dev/null 2>&1 && break
  kill -0 "$DAEMON" 2>/dev/null || { cat "$OUT/trackerd.log"; echo "demo: fovea-trackerd exited" >&2; exit 1; }
  sleep 0.1
done
"$BIN/fovea-ctl" --server "$SERVER" status

FRAMES=$(python3 -c "print(max(1, round($SECONDS_TO_RUN * $FPS)))")
echo "demo: four clients for ${SECONDS_TO_RUN} s: 'fovea-ctl watch' (every 25th sample and all events below),"
echo "      'fovea-ctl record $OUT/gaze.fgr', and fovea-render (embree, gl) rendering $(basename "$SCENE") at $FPS fps"
RENDER_ARGS=(--scene "$SCENE" --headless --frames "$FRAMES" --fps "$FPS" --gaze "udp://$SERVER"
             --scene-set camera.width=320 --scene-set camera.height=240)
"$RENDER" "${RENDER_ARGS[@]}" --backend embree --out "$OUT/render-embree" >"$OUT/render-embree.log" 2>&1 &
RENDER_EMBREE=$!
PIDS+=("$RENDER_EMBREE")
# The OpenGL client renders headless through EGL: no X server, DISPLAY unset.
env -u DISPLAY "$RENDER" "${RENDER_ARGS[@]}" --backend gl --out "$OUT/render-gl" \
  >"$OUT/render-gl.log" 2>&1 &
RENDER_GL=$!
PIDS+=("$RENDER_GL")
"$BIN/fovea-ctl" --server "$SERVER" record "$OUT/gaze.fgr" --duration "$SECONDS_TO_RUN" \
  --stats-json "$OUT/record.json" 2>"$OUT/record.log" &
RECORDER=$!
PIDS+=("$RECORDER")
"$BIN/fovea-ctl" --server "$SERVER" watch --every 25 --duration "$SECONDS_TO_RUN" \
  --stats-json "$OUT/watch.json" 2>"$OUT/watch.log" | tee "$OUT/watch.txt"
wait "$RECORDER" || { cat "$OUT/record.log"; echo "demo: recorder failed" >&2; exit 1; }
render_failed=0
for r in embree gl; do
  pid_var="RENDER_${r^^}"
  if ! wait "${!pid_var}"; then
    echo "demo: fovea-render ($r) failed:" >&2; tail -n 20 "$OUT/render-$r.log" >&2; render_failed=1
  fi
done

kill -TERM "$DAEMON"
wait "$DAEMON" && daemon_rc=0 || daemon_rc=$?
trap - EXIT INT TERM

echo
echo "demo: summary (latency = daemon send -> client receive, same host)"
python3 - "$OUT/watch.json" "$OUT/record.json" <<'PY'
import json, sys
rows = [json.load(open(p)) for p in sys.argv[1:]]
print(f"{'client':<8} {'samples':>8} {'lost':>5} {'dup':>4} {'reord':>5} {'events':>6} {'p50 ms':>8} {'p99 ms':>8} {'max ms':>8}")
for r in rows:
    print(f"{r['client']:<8} {r['received']:>8} {r['lost']:>5} {r['duplicated']:>4} {r['reordered']:>5} {r['events']:>6} "
          f"{r['latency_p50_ns']/1e6:>8.3f} {r['latency_p99_ns']/1e6:>8.3f} {r['latency_max_ns']/1e6:>8.3f}")
PY
"$BIN/fovea-ctl" info "$OUT/gaze.fgr"
grep -E "stopped:|shut down" "$OUT/trackerd.log" | sed 's/^/trackerd: /'
for r in embree gl; do
  echo
  echo "demo: fovea-render --backend $r: $(ls "$OUT/render-$r"/frame-*.png 2>/dev/null | wc -l) frames in $OUT/render-$r"
  sed -n '/^pass/,$p' "$OUT/render-$r.log"
done
echo
echo "demo: outputs in $OUT (frames: render-*/frame-*.png, per-pass timings: render-*/timings.csv,"
echo "      frame plans: render-*/plan.txt, gaze per frame: render-*/gaze.csv, recording: gaze.fgr)"
if [ "$daemon_rc" -ne 0 ]; then echo "demo: fovea-trackerd exited with status $daemon_rc" >&2; exit 1; fi
if [ "$render_failed" -ne 0 ]; then exit 1; fi
