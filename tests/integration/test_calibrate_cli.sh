#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea-calibrate as a user runs it: fit (every model, --on-top-of) and apply on a generated CSV; bad
# input gives an error naming the line, a non-zero exit and no output file.
# Usage: test_calibrate_cli.sh FOVEA_CALIBRATE
set -u
cal="$1"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# 3x3 targets on a 1680x1050 screen, 2 samples each, raw = a skewed, offset version of the target.
{
  echo "target_x_px,target_y_px,raw_x,raw_y"
  for tx in 100 840 1580; do
    for ty in 100 525 950; do
      for d in -2 2; do
        echo "$tx,$ty,$(( tx * 95 / 100 + 20 + d )),$(( ty * 105 / 100 - 15 - d ))"
      done
    done
  done
} > "$dir/points.csv"
printf 't_ms,raw_x,raw_y\n0,100,100\n4.5,820,540\n9,nan,nan\n13.5,1500,1000\n' > "$dir/raw.csv"

"$cal" --help > "$dir/help.txt" || fail "--help"
grep -q "calibrate a viewer on fovea-trackerd (run)" "$dir/help.txt" && grep -q "validate" "$dir/help.txt" || fail "--help does not name run and validate: $(cat "$dir/help.txt")"

for model in bilinear-grid poly2 affine homography; do
  "$cal" fit --points "$dir/points.csv" --model "$model" --out "$dir/$model.json" > "$dir/fit.txt" \
    || fail "fit $model: $(cat "$dir/fit.txt")"
  grep -q "points used: 18" "$dir/fit.txt" || fail "fit $model output: $(cat "$dir/fit.txt")"
  grep -q "rms residual:" "$dir/fit.txt" || fail "fit $model prints no residual"
  grep -q "condition:" "$dir/fit.txt" || fail "fit $model prints no condition"
  grep -q '"format": "fovea-calibration"' "$dir/$model.json" || fail "$model.json format"
  "$cal" apply "$dir/$model.json" "$dir/raw.csv" "$dir/out-$model.csv" > /dev/null || fail "apply $model"
  [ "$(head -1 "$dir/out-$model.csv")" = "t_ms,x_px,y_px" ] || fail "apply $model header"
  [ "$(wc -l < "$dir/out-$model.csv")" -eq 5 ] || fail "apply $model rows"
  grep -q '^9,nan,nan$' "$dir/out-$model.csv" || fail "apply $model: invalid sample not passed through"
done
# The affine fit is exact on this data (up to the +-2 px sample spread): the second row maps near (840, 525)?
awk -F, 'NR==3 { if ($2 < 780 || $2 > 900 || $3 < 470 || $3 > 580) exit 1 }' "$dir/out-affine.csv" \
  || fail "affine apply far off: $(cat "$dir/out-affine.csv")"

# On top of another calibration.
"$cal" fit --points "$dir/points.csv" --model bilinear-grid --on-top-of "$dir/affine.json" --out "$dir/stack.json" \
  > "$dir/fit.txt" || fail "fit --on-top-of"
grep -q "on top of affine" "$dir/fit.txt" || fail "--on-top-of not reported"
grep -q '"on_top_of"' "$dir/stack.json" || fail "on_top_of not written"

# Refusals: existing --out without --force, existing OUT.csv.
"$cal" fit --points "$dir/points.csv" --model affine --out "$dir/affine.json" 2> "$dir/err.txt" && fail "overwrote --out"
grep -q "refusing to overwrite" "$dir/err.txt" || fail "overwrite message: $(cat "$dir/err.txt")"
"$cal" fit --points "$dir/points.csv" --model affine --out "$dir/affine.json" --force > /dev/null || fail "--force"
"$cal" apply "$dir/affine.json" "$dir/raw.csv" "$dir/out-affine.csv" 2> "$dir/err.txt" && fail "overwrote OUT.csv"

# Bad CSV: error names the line and column, exit non-zero, nothing written.
sed '4s/.*/840,525,abc,12/' "$dir/points.csv" > "$dir/bad.csv"
"$cal" fit --points "$dir/bad.csv" --model affine --out "$dir/bad.json" 2> "$dir/err.txt" && fail "bad CSV accepted"
grep -q "bad.csv:4: column 3 (raw_x): 'abc' is not a number" "$dir/err.txt" || fail "bad CSV message: $(cat "$dir/err.txt")"
[ ! -e "$dir/bad.json" ] || fail "bad CSV still wrote a file"
printf 'target_x_px,target_y_px,raw_x,raw_y\n1,2,3\n' > "$dir/short.csv"
"$cal" fit --points "$dir/short.csv" --model affine --out "$dir/bad.json" 2> "$dir/err.txt" && fail "short row accepted"
grep -q "short.csv:2: 3 field(s); expected 4" "$dir/err.txt" || fail "short row message: $(cat "$dir/err.txt")"
printf 't_ms,raw_x,raw_y\n0,1,2\n1,2\n' > "$dir/badraw.csv"
"$cal" apply "$dir/affine.json" "$dir/badraw.csv" "$dir/bad.csv.out" 2> "$dir/err.txt" && fail "bad apply input accepted"
grep -q "badraw.csv:3:" "$dir/err.txt" || fail "apply bad input message: $(cat "$dir/err.txt")"
[ ! -e "$dir/bad.csv.out" ] || fail "bad apply input still wrote a file"

# Degenerate points: a clear error, nothing written.
printf 'target_x_px,target_y_px,raw_x,raw_y\n0,0,0,0\n10,10,1,1\n20,20,2,2\n30,30,3,3\n' > "$dir/line.csv"
"$cal" fit --points "$dir/line.csv" --model affine --out "$dir/line.json" 2> "$dir/err.txt" && fail "collinear accepted"
grep -q "collinear" "$dir/err.txt" || fail "collinear message: $(cat "$dir/err.txt")"
[ ! -e "$dir/line.json" ] || fail "collinear fit wrote a file"

# A file from a newer fovea.
echo '{"format":"fovea-calibration","version":7}' > "$dir/new.json"
"$cal" apply "$dir/new.json" "$dir/raw.csv" "$dir/out-new.csv" 2> "$dir/err.txt" && fail "newer version accepted"
grep -q "written by a newer fovea (version 7); this build reads version 1" "$dir/err.txt" || fail "version message: $(cat "$dir/err.txt")"
echo "fovea-calibrate CLI: all checks passed"
