#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Issue 41 on a machine with an NVIDIA GPU: the Sponza-sized glTF stand-in (generated there by the
# carried make_gltf_standin: its 28 MB stay here) through fovea-render's OpenGL backend at 1920x1080,
# the GPU-resident frame (target: G-buffer + tone map <= 2 ms), then attention + focus + DOF, LOD and
# GI, and the bundled attention.json as the same-run baseline. Per run: median ms per pass over the
# frames after the first (timings.csv; gpu.* are the GPU's own times from timer queries), the load
# line (--verbose) and peak RSS.
# Here:   cmake --build --preset default && bench/device/make-bundle.sh build/default
# There:  the device tool's run with carry [".gpu-bundle"] and command
#         OUT=$OUT bash bench/device/gpu-gltf.sh [FRAMES]   (default 60; SIZE=WxH overrides 1920x1080)
set -euo pipefail
cd "$(dirname "$0")/../.."
FRAMES=${1:-60}
SIZE=${SIZE:-1920x1080}
W=${SIZE%x*} H=${SIZE#*x}
OUT=${OUT:-$(mktemp -d)}
mkdir -p "$OUT"
. bench/device/unpack.sh
[ -x "$run/make_gltf_standin" ] || { echo "device: make_gltf_standin not in the bundle (build it here first)" >&2; exit 2; }
scene=$(mktemp -d)
"$run/make_gltf_standin" "$scene" | tail -1
cat >"$scene/around.json" <<JSON
{"gltf": {"file": "standin.gltf"},
 "camera": {"width": $W, "height": $H, "lens": {"type": "human-eye", "focus_distance_m": 6}},
 "display": {"width_px": $W, "height_px": $H, "width_mm": 600, "height_mm": $((600 * H / W)), "viewing_distance_mm": 650}}
JSON
summarise() {
  python3 - "$1/timings.csv" <<'PY'
import csv, statistics, sys
passes = {}
for r in csv.DictReader(open(sys.argv[1])):
    passes.setdefault(r["pass"], []).append(float(r["ms"]))
for name, v in passes.items():
    v = v[1:] or v
    print(f"  {name:<18} median {statistics.median(v):9.3f} ms")
PY
}
for config in "standin gbuffer:attention.enabled=false dof.enabled=false lod.enabled=false" \
              "standin dof:attention.enabled=true dof.enabled=true lod.enabled=false" \
              "standin lod:lod.enabled=true dof.enabled=false" \
              "standin gi:gi.enabled=true dof.enabled=false lod.enabled=false attention.enabled=false" \
              "attention.json base:"; do
  name=${config%%:*} sets=${config#*:}
  scene_file=$scene/around.json
  [ "${name%% *}" = attention.json ] && scene_file=renderer/scenes/attention.json
  args=()
  for s in $sets; do args+=(--set "$s"); done
  dir=$OUT/${name// /-}
  /usr/bin/time -f "%M" -o "$OUT/rss" env -u DISPLAY "$run/fovea-render" --scene "$scene_file" --backend gl \
    --headless --frames "$FRAMES" --gaze none --no-images --verbose --scene-set camera.width="$W" \
    --scene-set camera.height="$H" "${args[@]}" --out "$dir" 2>"$OUT/err" >/dev/null ||
    { echo "$name failed: $(tail -3 "$OUT/err")"; continue; }
  echo "## $name ${W}x${H}, $FRAMES frames, peak RSS $(( $(cat "$OUT/rss") / 1024 )) MiB" | tee -a "$OUT/gpu-gltf.md"
  grep "load" "$OUT/err" | tee -a "$OUT/gpu-gltf.md" || true
  grep -E "where" "$dir/plan.txt" | tee -a "$OUT/gpu-gltf.md" || true
  summarise "$dir" | tee -a "$OUT/gpu-gltf.md"
done
