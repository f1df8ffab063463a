#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea-calibrate validate as a user runs it: fit on generated calibration points, then validate on
# separate points with --report (report.md, targets.csv, summary.json, errors.png); bad input gives
# an error naming the file, a non-zero exit and no report.
# Usage: test_calibrate_validate.sh FOVEA_CALIBRATE
set -u
cal="$1"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
display="1920x1080@531.3x298.9mm,650mm"

# raw = the target pulled 5 % towards the centre and 20 px low, plus a +-2 px wobble.
raw() { echo "$(( $1 - ($1 - 960) * 5 / 100 + $3 )),$(( $2 + 20 - $3 ))"; }
{
  echo "target_x_px,target_y_px,raw_x,raw_y"
  for tx in 192 960 1728; do
    for ty in 108 540 972; do
      for d in -2 0 2; do echo "$tx,$ty,$(raw $tx $ty $d)"; done
    done
  done
} > "$dir/points.csv"
# Validation targets in between, in time order; a blink (nan) and a target whose samples are all lost.
{
  echo "target_x_px,target_y_px,raw_x,raw_y"
  for t in "576 324" "1344 324" "576 756" "1344 756"; do
    set -- $t
    for d in -2 1 2 -1; do echo "$1,$2,$(raw "$1" "$2" "$d")"; done
  done
  echo "1344,756,nan,nan"
  echo "960,540,nan,nan"
  echo "960,540,nan,nan"
} > "$dir/val.csv"

"$cal" fit --points "$dir/points.csv" --model affine --out "$dir/affine.json" > "$dir/fit.txt" \
  || fail "fit: $(cat "$dir/fit.txt")"

# validate --report: the table on stdout, the four files.
"$cal" validate "$dir/affine.json" --points "$dir/val.csv" --display "$display" --report "$dir/rep" \
  > "$dir/out.txt" 2> "$dir/err.txt" || fail "validate: $(cat "$dir/out.txt" "$dir/err.txt")"
grep -q "^overall " "$dir/out.txt" || fail "no overall row: $(cat "$dir/out.txt")"
grep -q "acc deg" "$dir/out.txt" || fail "no accuracy column: $(cat "$dir/out.txt")"
grep -q "RMS deg" "$dir/out.txt" || fail "no precision column: $(cat "$dir/out.txt")"
grep -q "1 target(s) had only lost samples" "$dir/out.txt" || fail "lost-only target not reported: $(cat "$dir/out.txt")"
grep -qi "nan" "$dir/out.txt" && fail "NaN in the table: $(cat "$dir/out.txt")"
for f in report.md targets.csv summary.json errors.png; do
  [ -s "$dir/rep/$f" ] || fail "report file $f missing or empty"
done
[ "$(head -c 8 "$dir/rep/errors.png" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ] || fail "errors.png is not a PNG"
grep -q "Jensen & Pedersen 2009" "$dir/rep/report.md" || fail "report.md does not cite J&P"
grep -q "| \*\*overall\*\* |" "$dir/rep/report.md" || fail "report.md has no overall row"
grep -q "errors.png" "$dir/rep/report.md" || fail "report.md does not show the figure"
head -1 "$dir/rep/targets.csv" | grep -q "^target_x_px,target_y_px,samples,lost,accuracy_deg,accuracy_mm," \
  || fail "targets.csv header: $(head -1 "$dir/rep/targets.csv")"
[ "$(wc -l < "$dir/rep/targets.csv")" -eq 6 ] || fail "targets.csv: expected 5 targets: $(cat "$dir/rep/targets.csv")"
grep -q '^960,540,0,2,,' "$dir/rep/targets.csv" || fail "lost-only target's figures not empty: $(cat "$dir/rep/targets.csv")"
grep -q '"accuracy_deg"' "$dir/rep/summary.json" || fail "summary.json has no accuracy"
grep -q '"distance_mm": 650' "$dir/rep/summary.json" || fail "summary.json has no display"
ls "$dir/rep" | grep -q tmp && fail "temporary files left in the report directory"
# A calibration of screen points has a "before" (the uncorrected points).
if grep -q '"input": "screen"' "$dir/affine.json"; then
  grep -q "before" "$dir/out.txt" || fail "screen-input calibration without before columns"
fi

# The report is never overwritten; nothing else is written then.
"$cal" validate "$dir/affine.json" --points "$dir/val.csv" --display "$display" --report "$dir/rep" \
  > /dev/null 2> "$dir/err.txt" && fail "overwrote the report"
grep -q "rep/report.md: exists; refusing to overwrite it" "$dir/err.txt" || fail "overwrite message: $(cat "$dir/err.txt")"

# On top of another calibration: before = the base model alone.
"$cal" fit --points "$dir/points.csv" --model bilinear-grid --on-top-of "$dir/affine.json" --out "$dir/stack.json" \
  > /dev/null || fail "fit --on-top-of"
"$cal" validate "$dir/stack.json" --points "$dir/val.csv" --display "$display" > "$dir/out.txt" \
  || fail "validate stacked"
grep -q "before = affine alone" "$dir/out.txt" || fail "stacked: before not the base: $(head -3 "$dir/out.txt")"

# Bad input: an error naming the file (and line, column), exit 1, no report directory.
bad() {  # bad NAME EXPECTED ARGS...
  local name="$1" want="$2"
  shift 2
  "$cal" validate "$@" --report "$dir/bad-$name" > /dev/null 2> "$dir/err.txt"
  local rc=$?
  [ "$rc" -eq 1 ] || fail "$name: exit $rc, expected 1 ($(cat "$dir/err.txt"))"
  grep -qF -- "$want" "$dir/err.txt" || fail "$name: message '$(cat "$dir/err.txt")' lacks '$want'"
  [ ! -e "$dir/bad-$name" ] || fail "$name: wrote a report"
}
sed '4s/.*/576,324,abc,12/' "$dir/val.csv" > "$dir/badval.csv"
bad csv "badval.csv:4: column 3 (raw_x): 'abc' is not a number" "$dir/affine.json" --points "$dir/badval.csv" --display "$display"
sed '3s/.*/576,nan,500,300/' "$dir/val.csv" > "$dir/nantarget.csv"
bad nantarget "nantarget.csv:3: column 2 (target_y_px)" "$dir/affine.json" --points "$dir/nantarget.csv" --display "$display"
printf 'target_x_px,target_y_px,raw_x\n1,2,3\n' > "$dir/header.csv"
bad header "header.csv:1: header must be 'target_x_px,target_y_px,raw_x,raw_y'" "$dir/affine.json" --points "$dir/header.csv" --display "$display"
printf 'target_x_px,target_y_px,raw_x,raw_y\n1,2,nan,nan\n' > "$dir/alllost.csv"
bad alllost "alllost.csv: validate: no usable sample" "$dir/affine.json" --points "$dir/alllost.csv" --display "$display"
printf 'target_x_px,target_y_px,raw_x,raw_y\n' > "$dir/empty.csv"
bad empty "empty.csv: no samples" "$dir/affine.json" --points "$dir/empty.csv" --display "$display"
bad missing "nosuch.csv: cannot open" "$dir/affine.json" --points "$dir/nosuch.csv" --display "$display"
bad nocal "nosuch.json" "$dir/nosuch.json" --points "$dir/val.csv" --display "$display"
bad display "--display: display geometry '1920x1080@531.3mm' is not of the form" "$dir/affine.json" --points "$dir/val.csv" --display "1920x1080@531.3mm"
bad display0 "distance_mm" "$dir/affine.json" --points "$dir/val.csv" --display "1920x1080@531.3x298.9mm,0mm"
if ! grep -q '"display"' "$dir/affine.json"; then
  bad nodisplay "no display geometry: pass --display or calibrate with one" "$dir/affine.json" --points "$dir/val.csv"
fi
echo "fovea-calibrate validate: all checks passed"
