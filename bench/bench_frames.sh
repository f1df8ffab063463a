#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Whole-frame pass breakdown: renders every bundled scene headless with each backend and prints the
# per-pass timing summary from the one timing instrument (timings.csv).
# Usage: bench/bench_frames.sh [BUILD_DIR] [FRAMES] [WIDTHxHEIGHT]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build/default}
FRAMES=${2:-20}
SIZE=${3:-1024x768}
W=${SIZE%x*} H=${SIZE#*x}
RENDER=$BUILD/renderer/fovea-render
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
echo "# $0 $BUILD $FRAMES $SIZE  ($(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores)"
for scene in renderer/scenes/*.json; do
  for backend in embree gl; do
    run=()
    [ "$backend" = gl ] && run=(env -u DISPLAY)  # headless GL through EGL
    dir=$OUT/$(basename "$scene" .json)-$backend
    "${run[@]}" "$RENDER" --scene "$scene" --backend "$backend" --headless --frames "$FRAMES" --gaze none \
      --scene-set camera.width="$W" --scene-set camera.height="$H" --out "$dir" >/dev/null
    echo
    echo "## $(basename "$scene") $backend ${W}x${H}, $FRAMES frames (ms)"
    python3 - "$dir/timings.csv" <<'PY'
import csv, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1])))
passes = {}
for r in rows:
    passes.setdefault(r["pass"], []).append(float(r["ms"]))
# Drop the first frame (warm-up: BVH/shader builds, page faults) from the statistics.
print(f"{'pass':<10} {'median':>8} {'mean':>8} {'max':>8}")
for name, v in passes.items():
    v = v[1:] or v
    print(f"{name:<10} {statistics.median(v):>8.2f} {statistics.mean(v):>8.2f} {max(v):>8.2f}")
PY
  done
done
