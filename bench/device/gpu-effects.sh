#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The perceptual effects on a machine with an NVIDIA GPU, in one command (issue 22's targets at
# 1920x1080), whole attention.json frames on the GPU-resident path, same run, same card
# (bench/bench_gpu_frame.sh; gpu-side ms per pass from timer queries):
#   dof-f11.2, dof-f2.8, dof-f0.7   lee-mipmap alone at a quarter, 1x and 4x the scene's aperture
#                                   (gpu.dof: target <= 1 ms, independent of the CoC)
#   dof-cpu                         the same DOF with dof.device=cpu (read back, CPU, upload)
#   dof-schedl                      schedl-layered, M = 3 (gpu.peel + gpu.dof: target <= 3 ms)
#   dof-splat                       lee-splat with its hidden image (gpu.peel + gpu.dof: target <= 5 ms
#                                   at mean CoC 16; the scene's lens gives its own CoC, see the table)
#   attention, attention-cpu        attention + focus, attention's pixel stage on the GPU (gpu.attention:
#                                   target <= 0.5 ms) and with attention.device=cpu
#   scene                           attention + focus + LOD + lee-mipmap (target: frame <= 4 ms)
#   ulod                            the scene with lod.policy=ulod (its blend on the GPU: gpu.ulod; the next levels' render: gpu.ulod_render)
#   gi, gi-cpu                      the hybrid renderer, 20k photons traced by Embree on the CPU (on a
#                                   worker thread, gi.overlap): gathered on the GPU (gi.device=auto) and
#                                   by the CPU's radius estimate (gi.device=cpu), same estimate (target:
#                                   the gaze area <= 4 ms); the GI stages in a table of their own
#   dof-fN+fragment, ulod+fragment, the same with frame.effect_passes=fragment: the fragment passes
#   attention+fragment              against the compute passes auto takes on a GPU (issue 42), same run
# Then stereo at headset resolution (issue 42's target: 2 x 2160x2160 with the scene's effects
# <= 11 ms, 90 Hz): "scene+stereo" and "base+stereo" at 2160x2160 per eye (STEREO_SIZE overrides),
# the frame being both eyes' renders, with each eye's p50 and what the left eye did once for both.
# Then the passes alone (bench_gl, where the bundle has it): attention's pixel stage at map 64 and
# 128, lee-mipmap at f/11.2, 2.8, 0.7, schedl-layered at f/2.8, 0.7 and ULOD's blend, fragment
# against compute at 1920x1080, each
# ending with glFinish, into $OUT/gpu-passes.txt.
# Results: stdout and $OUT/gpu-effects.md, the runs in $OUT/gpu-effects-runs.tar.xz. The agreement
# of the GL passes with the CPU implementation does not depend on the card's speed and is tested
# here (tests/gl/test_gl_lee_mipmap.cpp); the frames' plan.txt files carry the where line.
#
# Here:   cmake --build --preset default && bench/device/make-bundle.sh build/default
# There:  the device tool's run with carry [".gpu-bundle"] and command
#         OUT=$OUT bash bench/device/gpu-effects.sh [FRAMES]     (default 100)
# SIZE=WxH overrides 1920x1080 (a quick check here: SIZE=320x240 bash bench/device/gpu-effects.sh 8);
# EFFECTS, STEREO_EFFECTS (bench_gpu_frame.sh's names; empty: no stereo runs) and PASSES (bench_gl's
# filter; empty: none) choose what runs. The GPU path alone by default (PATHS=true: the readback path's
# figures are issue 21's, and took half of the time); PATHS="false true" adds it.
set -euo pipefail
cd "$(dirname "$0")/../.."
FRAMES=${1:-100}
SIZE=${SIZE:-1920x1080}
EFFECTS=${EFFECTS:-base attention attention+fragment attention-cpu dof-f11.2 dof-f2.8 dof-f0.7 dof-f11.2+fragment dof-f2.8+fragment dof-f0.7+fragment dof-cpu dof-schedl dof-splat scene ulod ulod+fragment gi gi-cpu}
STEREO_EFFECTS=${STEREO_EFFECTS-base+stereo scene+stereo}
PASSES=${PASSES-^attention/|lee_mipmap|schedl_layered|ulod_blend}
PATHS=${PATHS:-true}
OUT=${OUT:-$(mktemp -d)}
mkdir -p "$OUT"
. bench/device/unpack.sh

# One frame first: does the DOF run on the GPU, and on which device?
probe=$(mktemp -d)/probe
env -u DISPLAY "$run/fovea-render" --scene renderer/scenes/attention.json --backend gl --headless --frames 2 \
  --gaze none --out "$probe" >/dev/null
grep -E "where|  run   (dof|attention)" "$probe/plan.txt"

export PATHS
OUT=$OUT/runs bench/bench_gpu_frame.sh "$run/fovea-render" "$FRAMES" "$SIZE" attention "$EFFECTS" | tee "$OUT/gpu-effects.md"
if [ -n "$STEREO_EFFECTS" ]; then
  OUT=$OUT/runs-stereo bench/bench_gpu_frame.sh "$run/fovea-render" "$FRAMES" "${STEREO_SIZE:-2160x2160}" attention \
    "$STEREO_EFFECTS" | tee "$OUT/gpu-stereo.md"
fi
tar -C "$OUT" -cJf "$OUT/gpu-effects-runs.tar.xz" runs $([ -d "$OUT/runs-stereo" ] && echo runs-stereo) &&
  rm -rf "$OUT/runs" "$OUT/runs-stereo"
if [ -z "$PASSES" ]; then
  echo "gpu-effects: PASSES is empty: the passes alone not measured"
elif [ -x "$run/bench_gl" ]; then
  env -u DISPLAY FOVEA_SOURCE_DIR="$PWD" "$run/bench_gl" --benchmark_filter="$PASSES" \
    --benchmark_min_time=0.5 --benchmark_repetitions=3 --benchmark_report_aggregates_only=true | tee "$OUT/gpu-passes.txt"
else
  echo "gpu-effects: the bundle has no bench_gl (build it before make-bundle.sh): the passes alone not measured"
fi
