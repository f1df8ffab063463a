#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The frame benchmark on a machine with an NVIDIA GPU, in one command, from the bundle that
# bench/device/make-bundle.sh made here (.gpu-bundle, carried): unpacks fovea-render and its
# libraries, makes EGL find the NVIDIA driver, and runs bench/bench_gpu_frame.sh (readback path and
# GPU-resident path side by side, same run, same card). bench/device/gpu-effects.sh measures the
# GPU effects (issue 22). Results: stdout and $OUT/gpu-frame.md, the
# runs' timings in $OUT/gpu-frame-runs.tar.xz.
#
# Here:   bench/device/make-bundle.sh build/default
# There:  the device tool's run with carry [".gpu-bundle"] and command
#         bash bench/device/gpu-frame.sh [FRAMES]        (default 60)
#         EFFECTS="base scene" picks effects (default: every one bench_gpu_frame.sh has)
set -euo pipefail
cd "$(dirname "$0")/../.."
FRAMES=${1:-60}
OUT=${OUT:-$(mktemp -d)}
mkdir -p "$OUT"
. bench/device/unpack.sh

# One frame first: does the GPU path run, and on which device?
probe=$(mktemp -d)/probe
env -u DISPLAY "$run/fovea-render" --scene renderer/scenes/cornell.json --backend gl --headless --frames 2 \
  --gaze none --out "$probe" >/dev/null
grep "where" "$probe/plan.txt"

OUT=$OUT/runs bench/bench_gpu_frame.sh "$run/fovea-render" "$FRAMES" "640x480 1280x720 1920x1080" \
  "attention cornell" "${EFFECTS:-base base-noprepass base-allplanes scene gi}" | tee "$OUT/gpu-frame.md"
tar -C "$OUT" -cJf "$OUT/gpu-frame-runs.tar.xz" runs && rm -rf "$OUT/runs"
