#!/usr/bin/env bash
# fovea's test command (README command 2; .ci/run runs exactly this):
#   installs dependencies if missing, builds the normal and the ASan+UBSan configurations (and the
#   libFuzzer targets when clang is present), runs ctest on each, prints the summaries and exits
#   non-zero on any failure.
set -uo pipefail
cd "$(dirname "$0")/.."
JOBS=${FOVEA_JOBS:-$(nproc)}

bash deploy/install-deps.sh || exit 1

status=0
summary=()
run_suite() {  # name preset ctest-args...
  local name=$1 preset=$2; shift 2
  echo "=== $name: configure + build"
  if ! cmake --preset "$preset" >/dev/null || ! cmake --build --preset "$preset" -j "$JOBS"; then
    summary+=("$name: BUILD FAILED"); status=1; return
  fi
  echo "=== $name: ctest"
  local log
  log=$(mktemp)
  ctest --preset "$preset" -j "$JOBS" "$@" 2>&1 | tee "$log"
  local rc=${PIPESTATUS[0]}
  summary+=("$name: $(grep -E 'tests passed|tests failed' "$log" | tail -n 1)")
  rm -f "$log"
  [ "$rc" -eq 0 ] || status=1
}

run_suite "release" default
run_suite "asan+ubsan" asan

if command -v clang++ >/dev/null 2>&1; then
  echo "=== libFuzzer: configure + build"
  if cmake --preset fuzz >/dev/null && cmake --build build/fuzz -j "$JOBS" --target fuzz_decoder fuzz_recording fuzz_hid_descriptor; then
    log=$(mktemp)
    ctest --test-dir build/fuzz -R libfuzzer --output-on-failure 2>&1 | tee "$log"
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

echo
echo "=== summary"
printf '%s\n' "${summary[@]}"
[ "$status" -eq 0 ] && echo "ALL PASSED" || echo "FAILURES (see above)"
exit "$status"
