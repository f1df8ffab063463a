#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# lod.switch_in_saccades (issue 25 goal 3): level changes moved into saccades, where saccadic
# suppression hides them, against blending (ULOD) or switching whenever the level moves (the other
# policies). Renders a field of 40 LOD objects (the bundled blob with its 4-level chain, on a 8 x 5
# grid at 4-8 m) headless, driven by a recorded viewer (tests/data/recordings: 62 s of synthetic
# gaze at 250 Hz, 151 saccades, its labels at their own time) on the 60 Hz frame clock, and reads
# lod.csv and timings.csv of each configuration, run one after the other in one call:
#   pops/s        objects whose drawn level changed outside a saccade (a change a viewer may see)
#   in-saccade/s  level changes during a saccade (hidden)
#   blended       share of object-frames drawn as a blend of two levels (ULOD's second pass)
#   lod ms        lod-select + the ULOD blend pass (median per frame), frame ms (median)
# Usage: bench/bench_lod_saccades.sh [BUILD_DIR] [FRAMES] [WIDTHxHEIGHT] [BACKEND]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build/default}
FRAMES=${2:-1200}
SIZE=${3:-480x270}
BACKEND=${4:-embree}
W=${SIZE%x*} H=${SIZE#*x}
RENDER=$BUILD/renderer/fovea-render
GAZE=tests/data/recordings/synthetic-250hz-62s.fgr
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
/usr/bin/python3 - "$OUT/field.json" "$PWD/renderer/scenes" <<'PY'
import json, sys
out, scenes = sys.argv[1], sys.argv[2]
base = json.load(open(scenes + "/attention.json"))
objects = [o for o in base["objects"] if o["name"] == "ground"]
for row in range(5):
    for col in range(8):
        objects.append({"name": "blob_%d_%d" % (row, col), "material": ["green", "red", "orange", "yellow"][(row + col) % 4],
                        "geometry": {"mesh": scenes + "/meshes/blob.obj"},
                        "transform": {"translation": [-4.2 + 1.2 * col, 0.4 + 0.55 * row, -4 - row], "scale": 0.45},
                        "task_importance": 0.1 + 0.02 * (row * 8 + col), "lod": {"simplify": [0.5, 0.25, 0.1]}})
base["objects"] = objects
base["name"] = "lod-field"
json.dump(base, open(out, "w"))
PY
echo "# $0 $BUILD $FRAMES $SIZE $BACKEND  ($(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores)"
echo
echo "| policy | lod.switch_in_saccades | pops/s | in-saccade/s | blended % | lod ms p50 | frame ms p50 |"
echo "|---|---|---:|---:|---:|---:|---:|"
for policy in gaze ulod; do
  for switch in false true; do
    run=()
    [ "$BACKEND" = gl ] && run=(env -u DISPLAY)
    dir=$OUT/$policy-$switch
    "${run[@]}" "$RENDER" --scene "$OUT/field.json" --backend "$BACKEND" --headless --no-images --frames "$FRAMES" \
      --fps 60 --gaze "file:$GAZE" --scene-set camera.width="$W" --scene-set camera.height="$H" \
      --set lod.policy=$policy --set lod.switch_in_saccades=$switch --set dof.enabled=false --out "$dir" >/dev/null
    /usr/bin/python3 - "$dir" "$policy" "$switch" "$FRAMES" <<'PY'
import csv, statistics, sys
d, policy, switch, frames = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
lod = list(csv.DictReader(open(d + "/lod.csv")))
seconds = frames / 60.0
pops = sum(int(r["pops"]) for r in lod) / seconds
hidden = sum(int(r["switched_in_saccade"]) for r in lod) / seconds
blended = 100.0 * sum(int(r["blended"]) for r in lod) / max(1, sum(int(r["objects"]) for r in lod))
per_frame = {}
for r in csv.DictReader(open(d + "/timings.csv")):
    f = int(r["frame"])
    if f == 0:
        continue  # warm-up
    if r["pass"] in ("lod-select", "gbuffer.ulod", "gpu.ulod_render", "gpu.ulod"):
        per_frame.setdefault(f, [0.0, 0.0])[0] += float(r["ms"])
    if r["pass"] == "frame":
        per_frame.setdefault(f, [0.0, 0.0])[1] = float(r["ms"])
lod_ms = statistics.median(v[0] for v in per_frame.values())
frame_ms = statistics.median(v[1] for v in per_frame.values())
print(f"| {policy} | {switch} | {pops:.2f} | {hidden:.2f} | {blended:.1f} | {lod_ms:.2f} | {frame_ms:.1f} |")
PY
  done
done
