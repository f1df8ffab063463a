#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Issue 42's whole GPU sweep in one device call: the effects (gpu-effects.sh: whole frames, fragment
# against compute against CPU, stereo at headset resolution, the passes alone), the governor's fronts
# (gpu-fronts.sh) and the glTF stand-in (gpu-gltf.sh), in that order. Each part runs under its own
# time limit and is packed into $OUT/<part>.tar.xz as soon as it ends, so a part that overruns
# loses only itself and what came before still comes back (the device tool returns at most 8 files).
#
# Here:   cmake --build --preset default && bench/device/make-bundle.sh build/default
# There:  the device tool's run with carry [".gpu-bundle"], timeout_s 330, and command
#         OUT=$OUT bash bench/device/gpu-sweep.sh [FRAMES]     (default 60)
# The limits come from the H200's runs (2026-11-29): the effects' GPU-path runs and passes ~75 s (and
# GI's two runs since, ~10 s by estimate), the fronts ~140 s (bench_dof's GL fragment splat alone
# ~30 s, bench_attention ~52 s), the glTF part 37 s.
# PARTS="effects fronts gltf" and LIMITS="110 150 40" (seconds per part) override what runs; the
# parts' own variables (SIZE, STEREO_SIZE, ...) pass through. A quick check here:
#   SIZE=160x120 STEREO_SIZE=160x160 OUT=/tmp/sweep bash bench/device/gpu-sweep.sh 4
set -uo pipefail
cd "$(dirname "$0")/../.."
FRAMES=${1:-60}
OUT=${OUT:-$(mktemp -d)}
PARTS=${PARTS:-effects fronts gltf}
LIMITS=${LIMITS:-110 150 40}
mkdir -p "$OUT"
read -r -a limits <<<"$LIMITS"
i=0
for part in $PARTS; do
  limit=${limits[$i]:-120}
  i=$((i + 1))
  dir=$(mktemp -d)/$part
  mkdir -p "$dir"
  case $part in
    effects) cmd=(bash bench/device/gpu-effects.sh "$FRAMES") ;;
    fronts) cmd=(bash bench/device/gpu-fronts.sh) ;;
    gltf) cmd=(bash bench/device/gpu-gltf.sh "$FRAMES") ;;
    *) echo "gpu-sweep: no part '$part' (effects, fronts, gltf)" >&2; exit 2 ;;
  esac
  start=$(date +%s)
  echo "== gpu-sweep: $part (limit ${limit} s)"
  OUT=$dir timeout --kill-after=5 "$limit" "${cmd[@]}" 2>&1 | tee "$dir/log.txt"
  rc=${PIPESTATUS[0]}
  echo "== gpu-sweep: $part ended with $rc after $(($(date +%s) - start)) s" | tee -a "$dir/log.txt" "$OUT/sweep.txt"
  tar -C "$(dirname "$dir")" -cJf "$OUT/$part.tar.xz" "$part"
done
