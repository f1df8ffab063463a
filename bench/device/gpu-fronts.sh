#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The governor's depth-of-field and attention fronts of a GPU (issue 42: "the GPU passes become
# points the governor can choose"), in one command on the device machine:
#   bench_dof's accuracy-against-time rows, the CPU implementations beside the OpenGL ones (fragment
#   and, where the context has OpenGL 4.3, compute), at the size, CoC and reference the checked-in
#   fronts use (1024x768, mean CoC 16 px, 64-sample thin-lens ray tracing): $OUT/bench_dof_gl.csv;
#   bench_attention's times of the pixel stage on the CPU and in GL (fragment, compute) at the
#   checked-in run's sizes and maps: $OUT/bench_attention_gl.csv (accuracy: eval_attention.csv's A1).
#
# Here:   cmake --build --preset default && bench/device/make-bundle.sh build/default
# There:  the device tool's run with carry [".gpu-bundle"] and command
#         OUT=$OUT bash bench/device/gpu-fronts.sh
# Then here: copy the CSVs to bench/results/device/<card>/ and run
#         bench/make_fronts.py     (renderer/governor/fronts.json gains fronts for that card: the
#         governor takes it where FramePipeline::device() names the card; tests check the fronts)
# FRONTS="dof attention" chooses the fronts; METHODS (bench_dof's --methods), SIZE=WxH, SAMPLES=N (bench_dof), FRAMES=N, SIZES=WxH,... and MAPS=N,... (bench_attention) override the
# defaults (a quick check here: SIZE=128x96 SAMPLES=4 FRAMES=5 SIZES=320x180 MAPS=64 bash
# bench/device/gpu-fronts.sh); fronts for make_fronts need the defaults.
set -euo pipefail
cd "$(dirname "$0")/../.."
SIZE=${SIZE:-1024x768}
SAMPLES=${SAMPLES:-64}
FRAMES=${FRAMES:-20}
SIZES=${SIZES:-960x540,1920x1080}
MAPS=${MAPS:-64,256,512}
FRONTS=${FRONTS:-dof attention}  # which fronts to measure
OUT=${OUT:-$(mktemp -d)}
mkdir -p "$OUT"
. bench/device/unpack.sh
case " $FRONTS " in *" dof "*)
  [ -x "$run/bench_dof" ] || { echo "gpu-fronts: the bundle has no bench_dof (build it before make-bundle.sh)" >&2; exit 2; }
  methods=${METHODS:-lee-mipmap,lee-mipmap sigma=C/4,lee-mipmap gl,lee-splat,lee-splat gl,schedl-layered M=3,schedl-layered gl}
  env -u DISPLAY FOVEA_SOURCE_DIR="$PWD" "$run/bench_dof" --size "$SIZE" --cocs 16 --samples "$SAMPLES" --repeats 5 \
    --methods "$methods" --csv "$OUT/bench_dof_gl.csv" | tee -a "$OUT/gpu-fronts.txt"
  echo "gpu-fronts: $OUT/bench_dof_gl.csv ($(($(wc -l <"$OUT/bench_dof_gl.csv") - 1)) rows)" ;;
esac
case " $FRONTS " in *" attention "*)
  [ -x "$run/bench_attention" ] || { echo "gpu-fronts: the bundle has no bench_attention: no attention front" >&2; exit 2; }
  env -u DISPLAY FOVEA_SOURCE_DIR="$PWD" "$run/bench_attention" --frames "$FRAMES" --rounds 3 \
    --sizes "$SIZES" --maps "$MAPS" --csv "$OUT/bench_attention_gl.csv" | tee -a "$OUT/gpu-fronts.txt"
  echo "gpu-fronts: $OUT/bench_attention_gl.csv ($(($(wc -l <"$OUT/bench_attention_gl.csv") - 1)) rows)" ;;
esac
