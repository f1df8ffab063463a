#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# bench/eval_classify_gazecom.py (issue 43's harness) scores what it should: on a made-up GazeCom
# recording with a fake fovea-ctl whose labels are known, every figure equals the one worked out by
# hand; the scoring module's kappa and event F1 on hand-checked cases; and, where the machine has
# GazeCom (../shared/data/gazecom), the real fovea-ctl on three of its recordings.
# Usage: test_eval_gazecom.sh CTL SOURCE_DIR
set -u
CTL=$1 SRC=$2
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

echo "== the scoring module on hand-checked cases"
PYTHONPATH="$SRC/bench" /usr/bin/python3 - <<'PY' || fail "classify_scoring"
import math
from classify_scoring import confusion, event_counts, f1_of, kappa, kappa_of
t = ["f"] * 6 + ["s"] * 2 + ["p"] * 2
p = ["f"] * 5 + ["s"] * 3 + ["f"] * 2
assert confusion(t, p, "f") == (5, 2, 1, 2), confusion(t, p, "f")
assert abs(f1_of(5, 2, 1) - 10 / 13) < 1e-12
# kappa: po = 7/10, pe = (6*7 + 4*3) / 100 = 0.54, (0.7 - 0.54) / 0.46
assert abs(kappa(t, p, "f") - 0.16 / 0.46) < 1e-12 and abs(kappa_of(5, 2, 1, 2) - 0.16 / 0.46) < 1e-12
# events: truth f [0,6) vs found f [0,5) IoU 5/6 hit, found f [8,10) no truth: fp; s [6,8) vs [5,8) IoU 2/3 hit
assert event_counts(t, p, "f") == (1, 1, 0) and event_counts(t, p, "s") == (1, 0, 0)
assert event_counts(t, p, "p") == (0, 0, 1) and math.isnan(f1_of(0, 0, 0))
# IoU below 0.5 is no hit: truth [0,4) vs found [3,10)
assert event_counts(["a"] * 4 + ["b"] * 6, ["b"] * 3 + ["a"] * 7, "a") == (0, 1, 1)
PY

echo "== the harness on a made-up recording and a fake fovea-ctl (everything fixation, lost rows lost)"
mkdir -p "$WORK/gc/ground_truth/clip"
{
  printf '@RELATION gaze_labels\n%%@METADATA width_px 1280\n%%@METADATA height_px 720\n'
  printf '%%@METADATA width_mm 400.00\n%%@METADATA height_mm 225.00\n%%@METADATA distance_mm 450.00\n'
  printf '@ATTRIBUTE time INTEGER\n@DATA\n'
  # truth: 6 fixation, 2 saccade, 2 pursuit, 1 noise (track loss at 0,0); coder 1 agrees, coder 2 absent
  i=0
  for l in 1 1 1 1 1 1 2 2 3 3 4; do
    x=640; [ "$l" = 4 ] && x=0
    y=360; [ "$l" = 4 ] && y=0
    echo "$((i * 4000)),$x,$y,1,$l,?,$l"
    i=$((i + 1))
  done
} >"$WORK/gc/ground_truth/clip/AAA_clip.arff"
cp "$SRC/tests/fakes/fake_classify_ctl.py" "$WORK/fake-ctl"  # every sample fixation, lost ones lost
/usr/bin/python3 "$SRC/bench/eval_classify_gazecom.py" "$WORK/fake-ctl" --data "$WORK/gc" --methods fake --diagnose \
  --json "$WORK/fake.json" >"$WORK/fake.txt" 2>&1 || fail "harness: $(cat "$WORK/fake.txt")"
/usr/bin/python3 - "$WORK/fake.json" <<'PY' || fail "harness figures: $(cat "$WORK/fake.txt")"
import json, math, sys
s = json.load(open(sys.argv[1]))
f = s["pooled"]["fake"]
# fixation: tp 6, fp 4 (2 saccade + 2 pursuit; the lost row is "other"), fn 0, tn 1
assert abs(f["fixation"]["f1"] - 12 / 16) < 1e-12, f
po, pe = 7 / 11, (6 * 10 + 5 * 1) / 121
assert abs(f["fixation"]["kappa"] - (po - pe) / (1 - pe)) < 1e-12, f
assert f["fixation"]["event_f1"] == 1.0, f  # [0,6) inside [0,10): IoU 0.6
assert f["saccade"]["f1"] == 0.0 and f["pursuit"]["event_f1"] == 0.0, f
assert s["pooled"]["coder 1"]["pursuit"]["f1"] == 1.0 and "coder 2" not in s["pooled"], s["pooled"].keys()
assert s["latency_ms"]["fake"]["fixation"]["p50"] == 100.0, s["latency_ms"]
assert s["recordings"] == 1 and list(s["per_video"]) == ["clip"], s
# --diagnose: fixation [0,6) inside the detected [0,10): 4 false after the offset, the expert's
# saccade and pursuit there missed whole; fovea's labels in missed ends: none.
d = s["diagnosis"]
assert d["fixation"]["false_end"] == 4 and d["fixation"]["missed_whole"] == 0, d["fixation"]
assert d["saccade"]["missed_whole"] == 2 and d["pursuit"]["missed_whole"] == 2, d
assert d["saccade"]["false_whole"] == 0 and d["fixation"]["fovea_in_missed_end"] == {}, d
PY

GAZECOM="$SRC/../shared/data/gazecom"
if [ -f "$GAZECOM/gazecom-ground-truth.tar.xz" ]; then
  echo "== the real fovea-ctl on three GazeCom recordings"
  XDG_CACHE_HOME="$WORK/cache" /usr/bin/python3 "$SRC/bench/eval_classify_gazecom.py" "$CTL" --data "$GAZECOM" \
    --limit 3 --methods ivvt,ivt --diagnose --json "$WORK/real.json" >"$WORK/real.txt" 2>&1 || fail "real run: $(cat "$WORK/real.txt")"
  /usr/bin/python3 - "$WORK/real.json" <<'PY' || fail "real figures: $(cat "$WORK/real.txt")"
import json, sys
s = json.load(open(sys.argv[1]))
assert s["recordings"] == 3, s
for m in ("ivvt", "ivt"):
    f = s["pooled"][m]
    assert 0.6 < f["fixation"]["f1"] <= 1 and 0.4 < f["saccade"]["f1"] <= 1, (m, f)
# ivt labels no pursuit at all; ivvt does
assert s["pooled"]["ivt"]["pursuit"]["f1"] == 0.0 and s["pooled"]["ivvt"]["pursuit"]["f1"] > 0, s["pooled"]
# --diagnose: saccade speeds at the edges are real speeds, well below a saccade's peak
edge = s["diagnosis"]["saccade_edge_speed_p50"]
assert all(v is not None and 0 < v < 200 for v in edge.values()), edge
PY
else
  echo "   (no GazeCom at $GAZECOM: the real-data part is skipped)"
fi
echo "PASS"
