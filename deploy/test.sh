#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea's test command (README command 2; .ci/run runs exactly this):
#   installs dependencies if missing, builds the normal and the ASan+UBSan configurations (and the
#   libFuzzer targets when clang is present), runs ctest on each, runs the quick accuracy-cost report
#   against its checked-in baseline (bench/baseline-quick.json: ratios measured in the same run),
#   prints the summaries and exits non-zero on any failure.
set -uo pipefail
cd "$(dirname "$0")/.."
JOBS=${FOVEA_JOBS:-$(nproc)}

bash deploy/install-deps.sh || exit 1

status=0
summary=()

# The compiler cache (ccache, from install-deps) lives beside liblsl's in the user's cache
# directory, so a run on a fresh clone recompiles only the files that changed since the last one
# (CI: the two builds and the packages took 30 of its 50 minutes). Paths under the checkout are
# hashed relative to it; FOVEA_CCACHE=0 turns it off.
if [ "${FOVEA_CCACHE:-1}" = 1 ] && command -v ccache >/dev/null 2>&1; then
  export CCACHE_DIR=${CCACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/fovea/ccache}
  export CCACHE_BASEDIR=$PWD CCACHE_NOHASHDIR=1 CCACHE_MAXSIZE=${CCACHE_MAXSIZE:-5G}
  export CMAKE_C_COMPILER_LAUNCHER=ccache CMAKE_CXX_COMPILER_LAUNCHER=ccache
  ccache --zero-stats >/dev/null
fi
phase_start=$SECONDS
# phase NAME: the seconds since the previous phase ended, for the summary (CI has a time limit).
phase() { summary+=("  ($1: $((SECONDS - phase_start)) s)"); phase_start=$SECONDS; }
run_suite() {  # name preset ctest-args...
  local name=$1 preset=$2; shift 2
  echo "=== $name: configure + build"
  local built=$SECONDS
  if ! cmake --preset "$preset" >/dev/null || ! cmake --build --preset "$preset" -j "$JOBS"; then
    summary+=("$name: BUILD FAILED"); status=1; return
  fi
  summary+=("  ($name configure + build: $((SECONDS - built)) s)")
  echo "=== $name: ctest"
  local log
  log=$(mktemp)
  ctest --preset "$preset" -j "$JOBS" "$@" 2>&1 | tee "$log"
  local rc=${PIPESTATUS[0]}
  summary+=("$name: $(grep -E 'tests passed|tests failed' "$log" | tail -n 1)")
  rm -f "$log"
  [ "$rc" -eq 0 ] || status=1
}

# liblsl for the Lab Streaming Layer parts (issue 27): Debian has none, so it is built once from
# ../shared/third_party into a cached prefix; without that source the LSL parts and tests are skipped.
if lsl_prefix=$(bash deploy/build-liblsl.sh); then
  export CMAKE_PREFIX_PATH="$lsl_prefix${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
  summary+=("liblsl: $lsl_prefix (the LSL outlet and its tests are built)")
else
  summary+=("liblsl: none (no ../shared/third_party source): the LSL parts and their tests are skipped")
fi

# puppeteer-core for the browser test of fovea-monitor's page (tests/browser; the browser is Debian's
# chromium, from install-deps). From the npm registry at the version package-lock.json pins.
echo "=== npm ci (tests/browser: puppeteer-core)"
if ! npm ci --prefix tests/browser --no-audit --no-fund --loglevel=error; then
  summary+=("npm ci (tests/browser): FAILED: the browser test cannot run"); status=1
fi

phase "dependencies and liblsl"
run_suite "release" default
phase "release build and tests"

# The accuracy-cost report, quick: every effect's sweep in ~2 minutes, checked against the baseline.
echo "=== accuracy-cost report (fovea-bench report --quick)"
if bench/fovea-bench report --quick --force --out build/report-quick --check-baseline bench/baseline-quick.json; then
  summary+=("report --quick: baseline checks passed (build/report-quick/report.html)")
else
  summary+=("report --quick: FAILED (see build/report-quick/report.html)"); status=1
fi
phase "report --quick"

# The Debian packages: built from a copy of the tree (tests off: they ran above; unoptimised,
# --quick: the checks are about what the packages hold, not their speed) and checked (contents,
# --version, systemd-analyze verify, the SDK example, import fovea, lintian).
if command -v dpkg-buildpackage >/dev/null 2>&1 && command -v dh >/dev/null 2>&1; then
  echo "=== Debian packages (deploy/build-packages.sh)"
  if bash deploy/build-packages.sh --quick --out build/packages; then
    summary+=("packages: built and checked (build/packages)")
  else
    summary+=("packages: FAILED"); status=1
  fi
else
  summary+=("packages: skipped (dpkg-buildpackage or debhelper missing; deploy/install-deps.sh installs them)")
fi
phase "packages"

# Under ASan the OpenGL tests (label gl) run Mesa's llvmpipe instrumented: 686 of the suite's 2,380
# test-seconds on 2 cores (2026-11-30), for code the release suite above runs unchanged. The long
# whole-session tests (label long: calibrate_run, train_classifier, synth_calibration_cli) took
# 340 more on CI (2026-12-01); their libraries' unit tests do run under ASan. Both are left out of
# this pass to keep CI inside its time limit; FOVEA_ASAN_GL=1 and FOVEA_ASAN_LONG=1 put them back.
asan_skip=()
[ "${FOVEA_ASAN_GL:-0}" = 1 ] || asan_skip+=(gl)
[ "${FOVEA_ASAN_LONG:-0}" = 1 ] || asan_skip+=(long)
if [ ${#asan_skip[@]} -eq 0 ]; then
  run_suite "asan+ubsan" asan
else
  skip=$(IFS='|'; echo "${asan_skip[*]}")
  run_suite "asan+ubsan (without the labels $skip)" asan -LE "$skip"
fi
phase "asan+ubsan build and tests"

if command -v clang++ >/dev/null 2>&1; then
  echo "=== libFuzzer: configure + build"
  if cmake --preset fuzz >/dev/null && cmake --build build/fuzz -j "$JOBS" --target fuzz_decoder fuzz_recording fuzz_hid_descriptor fuzz_control_request fuzz_open_gaze fuzz_pupil_payload fuzz_gltf fuzz_gbt_trees; then
    log=$(mktemp)
    ctest --test-dir build/fuzz -R libfuzzer -j "$JOBS" --output-on-failure 2>&1 | tee "$log"
    rc=${PIPESTATUS[0]}
    summary+=("libfuzzer: $(grep -E 'tests passed|tests failed' "$log" | tail -n 1)")
    rm -f "$log"
    [ "$rc" -eq 0 ] || status=1
  else
    summary+=("libfuzzer: BUILD FAILED"); status=1
  fi
else
  summary+=("libfuzzer: skipped (no clang++)")
fi
phase "libfuzzer"
if [ -n "${CMAKE_CXX_COMPILER_LAUNCHER:-}" ]; then
  summary+=("ccache ($CCACHE_DIR): $(ccache --print-stats 2>/dev/null | awk -F'\t' '
    $1 == "direct_cache_hit" || $1 == "preprocessed_cache_hit" { hits += $2 }
    $1 == "cache_miss" { misses += $2 }
    END { printf "%d of %d compilations from the cache", hits, hits + misses }')")
fi
summary+=("  (in all: $SECONDS s)")

echo
echo "=== summary"
printf '%s\n' "${summary[@]}"
[ "$status" -eq 0 ] && echo "ALL PASSED" || echo "FAILURES (see above)"
exit "$status"
