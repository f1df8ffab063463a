#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea-eval-attention as a user runs it: a synthetic viewer's recording of renderer/scenes/attention.json,
# then evaluate: the B/E/T ablation (8 rows), the baselines, the map-size sweep, A1 <= A2 <= A3, the
# random-pixel baseline below the full model; bad inputs are refused with a clear message.
set -u
EVAL=$1
SCENE=$2
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

echo "== --help states the synthetic viewer's caveat"
"$EVAL" synth-viewer --help | grep -q "shares assumptions with the model" || fail "synth-viewer --help: no caveat"

echo "== synth-viewer writes a recording"
out=$("$EVAL" synth-viewer --scene "$SCENE" --seconds 8 --seed 1 --width 160 --height 90 --out "$WORK/v.fgr" 2>&1) \
  || fail "synth-viewer: $out"
[ -s "$WORK/v.fgr" ] || fail "no v.fgr"
grep -q "480 samples" <<<"$out" || fail "summary: $out"
grep -q "optimistic" <<<"$out" || fail "no caveat in the output: $out"
out=$("$EVAL" synth-viewer --scene "$SCENE" --seconds 1 --out "$WORK/v.fgr" 2>&1) && fail "overwrote v.fgr"
grep -q "already exists" <<<"$out" || fail "unclear refusal: $out"

echo "== evaluate at 160x90, map 64"
out=$("$EVAL" evaluate --scene "$SCENE" --gaze "$WORK/v.fgr" --width 160 --height 90 --map-sizes 64 --out "$WORK/r" 2>&1) \
  || fail "evaluate: $out"
echo "$out"
CSV="$WORK/r/eval_attention.csv"
[ -s "$CSV" ] || fail "no eval_attention.csv"
[ -s "$WORK/r/report.md" ] || fail "no report.md"
grep -q "optimistic" "$WORK/r/report.md" || fail "report.md: no caveat for the synthetic viewer"
head -1 "$CSV" | grep -qx "section,method,B,E,T,map,frames,hits_1,hits_2,hits_3,A1,A2,A3,ms_per_frame" \
  || fail "CSV header: $(head -1 "$CSV")"
[ "$(grep -c '^ablation,fovea,' "$CSV")" -eq 8 ] || fail "ablation rows: $(cat "$CSV")"
for bet in 0,0,0 0,0,1 0,1,0 0,1,1 1,0,0 1,0,1 1,1,0 1,1,1; do
  grep -q "^ablation,fovea,$bet,64," "$CSV" || fail "no ablation row B,E,T=$bet"
done
for m in "random pixel" "opencv spectral residual,,,0" "opencv spectral residual,,,1" "opencv fine grained,,,0" \
         "opencv fine grained,,,1"; do
  grep -q "^baseline,$m" "$CSV" || fail "no baseline row '$m'"
done
grep -q "^map_size,fovea,1,1,1,64," "$CSV" || fail "no map-size row"
# Every row: frames > 0, hits_1 <= hits_2 <= hits_3 <= frames, A1 <= A2 <= A3 in [0, 1].
awk -F, 'NR > 1 { if (!($7 > 0 && $8 <= $9 && $9 <= $10 && $10 <= $7 && $11 <= $12 && $12 <= $13 && $11 >= 0 && $13 <= 1))
                  { print "bad row: " $0; bad = 1 } } END { exit bad }' "$CSV" || fail "A1 <= A2 <= A3 violated"
full_a3=$(awk -F, '$1 == "ablation" && $3 == 1 && $4 == 1 && $5 == 1 { print $13 }' "$CSV")
random_a3=$(awk -F, '$2 == "random pixel" { print $13 }' "$CSV")
awk -v r="$random_a3" -v f="$full_a3" 'BEGIN { exit !(r < f) }' || fail "random A3 $random_a3 not below the full model's A3 $full_a3"
grep -q "Feature groups (Lee 2009 Table 3.2)" <<<"$out" || fail "no ablation table printed"
grep -q "with the gaze on no foreground object" <<<"$out" || fail "misses not reported"

echo "== bad inputs are refused with a clear message"
out=$("$EVAL" evaluate --scene "$WORK/missing.json" --gaze "$WORK/v.fgr" 2>&1) && fail "accepted a missing scene"
grep -q "scene file not found" <<<"$out" || fail "unclear message for a missing scene: $out"
out=$("$EVAL" evaluate --scene "$SCENE" --gaze "$WORK/missing.fgr" 2>&1) && fail "accepted a missing recording"
grep -q "not found" <<<"$out" || fail "unclear message for a missing recording: $out"
out=$("$EVAL" evaluate --scene "$SCENE" --gaze "$WORK/v.fgr" --offset-s -100 --width 160 --height 90 --map-sizes 64 2>&1) \
  && fail "accepted a recording with no samples in the scene's time range"
grep -q "no gaze sample falls in the scene's time range" <<<"$out" || fail "unclear message: $out"
echo "not a recording" >"$WORK/junk.fgr"
out=$("$EVAL" evaluate --scene "$SCENE" --gaze "$WORK/junk.fgr" 2>&1) && fail "accepted a file that is not a recording"
grep -q "not a fovea recording" <<<"$out" || fail "unclear message for junk: $out"
out=$("$EVAL" evaluate --scene "$SCENE" --gaze "$WORK/v.fgr" --map-sizes 32 2>&1) && fail "accepted map size 32"
grep -q "allowed 64..512" <<<"$out" || fail "unclear message for map size: $out"
echo "PASS"
