#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea-ctl synth-calibration as a user runs it: a recorded calibration session of the synthetic
# viewer (SESSION.fgr) with the targets it was shown (SESSION.targets.csv), never overwriting.
set -u
CTL=$1
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

echo "== --help says what it is for"
"$CTL" synth-calibration --help | grep -q "fovea-calibrate run --headless --from" || fail "--help: $("$CTL" synth-calibration --help)"

echo "== writes the session and its targets"
out=$("$CTL" synth-calibration --out "$WORK/s.fgr" --points 5 --validation-points 4 --eye-size 160x120 --seed 3 \
      --head-offset 10,-5,20 2>"$WORK/err") || fail "synth-calibration: $(cat "$WORK/err")"
[ "$(wc -l <<<"$out")" -eq 1 ] || fail "summary is not one line: $out"
grep -q "s.fgr" <<<"$out" && grep -q "s.targets.csv" <<<"$out" || fail "summary does not name the files: $out"
grep -q "5 calibration + 4 validation targets" <<<"$out" || fail "summary: $out"
[ -s "$WORK/s.fgr" ] || fail "no s.fgr"
[ -f "$WORK/s.targets.csv" ] || fail "no s.targets.csv"
head -1 "$WORK/s.targets.csv" | grep -qx "index,phase,x_px,y_px,onset_ns,collect_from_ns,collect_to_ns" \
  || fail "targets header: $(head -1 "$WORK/s.targets.csv")"
[ "$(grep -c ',calibrate,' "$WORK/s.targets.csv")" -eq 5 ] || fail "calibration rows: $(cat "$WORK/s.targets.csv")"
[ "$(grep -c ',validate,' "$WORK/s.targets.csv")" -eq 4 ] || fail "validation rows: $(cat "$WORK/s.targets.csv")"
info=$("$CTL" info "$WORK/s.fgr" 2>&1) || fail "info: $info"
grep -qi "sample" <<<"$info" || fail "info says nothing of samples: $info"
# The first target's onset is within the recording's span (same clock).
"$CTL" convert "$WORK/s.fgr" "$WORK/s.csv" 2>/dev/null || fail "convert"

echo "== never overwrites, never leaves half a pair"
sum=$(md5sum <"$WORK/s.fgr")
out=$("$CTL" synth-calibration --out "$WORK/s.fgr" --points 5 --eye-size 160x120 2>&1) && fail "overwrote s.fgr"
grep -q "already exists" <<<"$out" || fail "unclear refusal: $out"
[ "$(md5sum <"$WORK/s.fgr")" = "$sum" ] || fail "s.fgr changed"
rm "$WORK/s.fgr"
out=$("$CTL" synth-calibration --out "$WORK/s.fgr" --points 5 --eye-size 160x120 2>&1) && fail "wrote beside an existing targets file"
grep -q "s.targets.csv already exists" <<<"$out" || fail "unclear refusal: $out"
[ ! -e "$WORK/s.fgr" ] || fail "left s.fgr without its targets"

echo "== bad options are named"
out=$("$CTL" synth-calibration --out "$WORK/b.fgr" --head-offset 1,2 2>&1) && fail "--head-offset 1,2 accepted"
grep -q -- "--head-offset" <<<"$out" || fail "unclear head offset message: $out"
out=$("$CTL" synth-calibration --out "$WORK/b.fgr" --head-offset 0,0,900 2>&1) && fail "--head-offset 0,0,900 accepted"
grep -q -- "--head-offset" <<<"$out" || fail "unclear head offset message: $out"
out=$("$CTL" synth-calibration --out "$WORK/b.fgr" --points 7 2>&1) && fail "--points 7 accepted"
[ ! -e "$WORK/b.fgr" ] && [ ! -e "$WORK/b.targets.csv" ] || fail "files left after an error"
echo "PASS"
