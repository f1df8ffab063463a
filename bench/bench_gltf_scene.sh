#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# A scene of realistic size (issue 41): the Sponza-sized stand-in that bench/make_gltf_standin
# generates (262k triangles, 25 materials, 70 textures of 1-2k pixels; the real Crytek Sponza's
# licence keeps it out of the repository), measured
#   1. bench_gltf: load phases with a cold and then a warm LOD cache, resident memory, the G-buffer
#      per backend, Embree against OpenGL as PSNR;
#   2. fovea-render headless per backend and effect (G-buffer + tone map alone, attention + focus +
#      DOF with the human eye's lens, LOD, GI), median ms per pass from timings.csv, peak RSS (GNU time).
# Usage: bench/bench_gltf_scene.sh [BUILD_DIR] [FRAMES] [WIDTHxHEIGHT] [SCENE.gltf]
# (default: the stand-in, generated into BUILD_DIR/standin on first use).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build/default}
FRAMES=${2:-6}
SIZE=${3:-1280x720}
W=${SIZE%x*} H=${SIZE#*x}
SCENE=${4:-}
RENDER=$BUILD/renderer/fovea-render
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
if [ -z "$SCENE" ]; then
  SCENE=$BUILD/standin/standin.gltf
  if [ ! -f "$SCENE" ]; then
    start=$(date +%s.%N)
    "$BUILD/bench/make_gltf_standin" "$BUILD/standin" >/dev/null
    echo "# generated the stand-in in $(echo "$(date +%s.%N) - $start" | bc) s: $(du -sh "$BUILD/standin" | cut -f1)"
  fi
fi
# A JSON scene around the asset: the human eye's lens for DOF, the display it is seen on.
cat >"$OUT/around.json" <<JSON
{"gltf": {"file": "$(realpath "$SCENE")"},
 "camera": {"width": $W, "height": $H, "lens": {"type": "human-eye", "focus_distance_m": 6}},
 "display": {"width_px": $W, "height_px": $H, "width_mm": 600, "height_mm": $((600 * H / W)), "viewing_distance_mm": 650}}
JSON
echo "# $0 $BUILD $FRAMES $SIZE $SCENE  ($(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores)"
export FOVEA_LOD_CACHE=$OUT/lod-cache
echo
echo "## bench_gltf, LOD cache cold"
env -u DISPLAY "$BUILD/bench/bench_gltf" --scene "$SCENE" --width "$W" --height "$H" --frames "$FRAMES"
echo
echo "## bench_gltf, LOD cache warm"
env -u DISPLAY "$BUILD/bench/bench_gltf" --scene "$SCENE" --width "$W" --height "$H" --frames "$FRAMES" | head -3

declare -A EFFECT=(
  [gbuffer]="attention.enabled=false dof.enabled=false lod.enabled=false gi.enabled=false"
  [dof]="attention.enabled=true dof.enabled=true lod.enabled=false gi.enabled=false"
  [lod]="attention.enabled=true dof.enabled=false lod.enabled=true gi.enabled=false"
  [gi]="attention.enabled=false dof.enabled=false lod.enabled=false gi.enabled=true"
)
for backend in embree gl; do
  # Attention alone is not a configuration: it runs only when focus, DOF or LOD consumes it.
  for effect in gbuffer dof lod gi; do
    sets=()
    for s in ${EFFECT[$effect]}; do sets+=(--set "$s"); done
    dir=$OUT/$effect-$backend
    /usr/bin/time -f "%M" -o "$OUT/rss" env -u DISPLAY "$RENDER" --scene "$OUT/around.json" --backend "$backend" \
      --headless --frames "$FRAMES" --gaze none --no-images "${sets[@]}" --out "$dir" >/dev/null 2>"$OUT/err" \
      || { echo "$effect $backend failed: $(tail -3 "$OUT/err")"; continue; }
    echo
    echo "## $effect, $backend ${W}x${H}, $FRAMES frames: peak RSS $(( $(cat "$OUT/rss") / 1024 )) MiB"
    python3 - "$dir/timings.csv" <<'PY'
import csv, statistics, sys
passes = {}
for r in csv.DictReader(open(sys.argv[1])):
    passes.setdefault(r["pass"], []).append(float(r["ms"]))
for name, v in passes.items():
    v = v[1:] or v  # the first frame warms up (BVH refits, shader compiles)
    if name.startswith("load.") or name in ("frame", "gbuffer", "attention", "dof", "lod-select", "gi", "tonemap"):
        print(f"  {name:<14} median {statistics.median(v):9.1f} ms")
PY
  done
done
