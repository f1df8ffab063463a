#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# bench/eval_classify_lund.py (issue 43's harness for the Lund coders' recordings, which are not in
# the repository) reads Andersson et al.'s MATLAB files and scores as they do: on made-up recordings
# and a fake fovea-ctl whose labels are known, every figure equals the one worked out by hand;
# damaged files are refused with their name and what is wrong; and, where the machine has the shared
# EyeLink set, one of its sessions written as a Lund file scores with the real fovea-ctl exactly as
# bench/eval_classify_human.py scores the session itself.
# Usage: test_eval_lund.sh CTL SOURCE_DIR
set -u
CTL=$1 SRC=$2
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
H="$SRC/bench/eval_classify_lund.py"

echo "== made-up recordings: dots/rec1 coded by MN and RA, video/rec2 by MN alone"
/usr/bin/python3 - "$WORK/lund" <<'PY' || fail "writing the made-up recordings"
import os, sys
import numpy as np, scipy.io
root = os.path.join(sys.argv[1], "annotated_data", "data used in the article")
def write(kind, name, labels, lost=()):
    os.makedirs(os.path.join(root, kind), exist_ok=True)
    pos = np.zeros((len(labels), 6))
    pos[:, 3], pos[:, 4], pos[:, 5] = 500.0, 400.0, labels
    for i in lost:
        pos[i, 3:5] = 0.0
    scipy.io.savemat(os.path.join(root, kind, name), {"ETdata": {
        "pos": pos, "screenRes": np.array([1024.0, 768.0]), "screenDim": np.array([0.38, 0.30]),
        "viewDist": 0.67, "sampFreq": 500.0}})
write("dots", "rec1_labelled_MN.mat", [1, 1, 1, 1, 2, 2, 3, 1, 1, 6], lost=[9])
write("dots", "rec1_labelled_RA.mat", [1, 1, 1, 2, 2, 2, 3, 3, 1, 6], lost=[9])
write("video", "rec2_labelled_MN.mat", [4, 4, 4, 4, 4, 2, 2, 2])
open(os.path.join(root, "read me.txt"), "w").write("not a recording\n")
PY
cp "$SRC/tests/fakes/fake_classify_ctl.py" "$WORK/fake-ctl"  # every sample fixation, lost ones lost
/usr/bin/python3 "$H" "$WORK/fake-ctl" "$WORK/lund" --methods fake --json "$WORK/fake.json" >"$WORK/fake.txt" 2>&1 ||
  fail "harness: $(cat "$WORK/fake.txt")"
/usr/bin/python3 - "$WORK/fake.json" <<'PY' || fail "harness figures: $(cat "$WORK/fake.txt")"
import json, math, sys
s = json.load(open(sys.argv[1]))
assert s["recordings"] == 3 and s["coders"] == ["MN", "RA"], s
mn = s["methods"]["fake"]["MN"]
# dots, MN: fixation tp 6, fp 3 (saccade, saccade, PSO), fn 0, tn 1 (the lost sample: "other")
# po 7/10, pe (6*9 + 4*1)/100: kappa 0.12/0.42; no saccade found: kappa 0
assert abs(mn["dots"]["fixation"]["kappa"] - 0.12 / 0.42) < 1e-12, mn["dots"]
assert mn["dots"]["saccade"]["kappa"] == 0.0 and mn["dots"]["fixation"]["samples"] == 6, mn["dots"]
# videos, MN: no fixation in the truth, all fixation found: kappa 0; the mean over the two kinds
assert mn["videos"]["fixation"]["kappa"] == 0.0 and mn["videos"]["recordings"] == 1, mn["videos"]
assert abs(mn["mean_kappa_fixation_saccade"] - (0.12 / 0.42 / 2 + 0) / 2) < 1e-12, mn
# all coders, dots: MN's counts (6,3,0,1) + RA's (4,5,0,1): po 12/20, pe (10*18 + 10*2)/400 = 0.5
both = s["methods"]["fake"]["all"]
assert abs(both["dots"]["fixation"]["kappa"] - 0.2) < 1e-12 and both["dots"]["recordings"] == 2, both
assert "videos" not in s["methods"]["fake"]["RA"], s["methods"]["fake"]["RA"]
# RA against MN on rec1: fixation tp 4, fp 0, fn 2, tn 4 -> 0.32/0.52; saccade tp 2, fp 1, fn 0, tn 7 -> 0.28/0.38
h = s["coders_agreement"]["MN-RA"]
assert abs(h["dots"]["fixation"]["kappa"] - 0.32 / 0.52) < 1e-12, h
assert abs(h["dots"]["saccade"]["kappa"] - 0.28 / 0.38) < 1e-12 and h["dots"]["recordings"] == 1, h
assert "videos" not in h, h
PY
grep -q "fake against all coders" "$WORK/fake.txt" && grep -q "coder RA against coder MN" "$WORK/fake.txt" ||
  fail "tables: $(cat "$WORK/fake.txt")"

echo "== damaged files are refused, named, with what is wrong"
refused() {  # refused WHAT EXPECTED...: the harness fails and says each EXPECTED
  local what=$1
  shift
  if /usr/bin/python3 "$H" "$WORK/fake-ctl" "$WORK/bad" --methods fake >"$WORK/bad.txt" 2>&1; then
    fail "$what: accepted"
  fi
  for e in "$@"; do grep -q -- "$e" "$WORK/bad.txt" || fail "$what: no '$e' in: $(cat "$WORK/bad.txt")"; done
}
mkdir -p "$WORK/bad"
refused "no kind directories" "no dots/, img/ or video/ directory" "$WORK/bad"
mkdir -p "$WORK/bad/img"
refused "no recordings" "no \*_labelled_<coder>.mat"
/usr/bin/python3 - "$WORK/bad/img" <<'PY'
import sys, numpy as np, scipy.io
pos = np.zeros((5, 6))
scipy.io.savemat(sys.argv[1] + "/a_labelled_MN.mat", {"ETdata": {"pos": pos, "screenRes": np.array([1024.0, 768.0]),
                 "screenDim": np.array([0.38, 0.30]), "viewDist": 0.67}})
PY
refused "no sampling rate" "a_labelled_MN.mat" "no field 'sampFreq'"
echo "not matlab" >"$WORK/bad/img/a_labelled_MN.mat"
refused "not a MAT file" "a_labelled_MN.mat" "not a MATLAB file"
/usr/bin/python3 - "$WORK/bad/img" <<'PY'
import sys, numpy as np, scipy.io
scipy.io.savemat(sys.argv[1] + "/a_labelled_MN.mat", {"ETdata": {"pos": np.zeros((5, 4)), "screenRes": np.array([1024.0, 768.0]),
                 "screenDim": np.array([0.38, 0.30]), "viewDist": 0.67, "sampFreq": 500.0}})
PY
refused "too few columns" "a_labelled_MN.mat" "ETdata.pos is (5, 4)"
/usr/bin/python3 - "$WORK/bad/img" <<'PY'
import sys, numpy as np, scipy.io
scipy.io.savemat(sys.argv[1] + "/a_labelled_MN.mat", {"ETdata": {"pos": np.zeros((5, 6)), "screenRes": np.array([1024.0, 768.0]),
                 "screenDim": np.array([0.38, 0.30]), "viewDist": -1.0, "sampFreq": 500.0}})
PY
refused "negative distance" "a_labelled_MN.mat" "viewDist -1.0"

DATA="$SRC/../shared/data/irf-lookAtPoint_EL"
if [ -f "$DATA/lookAtPoint_EL_S1.npy" ]; then
  echo "== an EyeLink session as a Lund file scores as eval_classify_human.py scores the session"
  mkdir -p "$WORK/el"
  ln -s "$DATA/db_config.json" "$DATA/lookAtPoint_EL_S1.npy" "$WORK/el/"
  /usr/bin/python3 - "$DATA" "$WORK/ellund" <<'PY' || fail "writing the session as a Lund file"
import json, os, sys
import numpy as np, scipy.io
src, out = sys.argv[1], sys.argv[2]
g = json.load(open(os.path.join(src, "db_config.json")))["geom"]
w_px, h_px = int(g["display_width_pix"]), int(g["display_height_pix"])
w_mm, h_mm, d_mm = g["screen_width"], g["screen_height"], g["eye_distance"]
s = np.load(os.path.join(src, "lookAtPoint_EL_S1.npy"))
# the pixels eval_classify_human.py writes for fovea-ctl, (0, 0) where the tracker lost the eye
x = np.tan(np.radians(s["x"].astype(np.float64))) * d_mm / w_mm * w_px + w_px / 2
y = np.tan(np.radians(s["y"].astype(np.float64))) * d_mm / h_mm * h_px + h_px / 2
lost = ~s["status"] | ~np.isfinite(x) | ~np.isfinite(y)
x[lost], y[lost] = 0.0, 0.0
pos = np.zeros((len(s), 6))
pos[:, 3], pos[:, 4] = x, y
pos[:, 5] = [int(e) if int(e) in (1, 2, 3, 4, 5) else 6 for e in s["evt"]]
os.makedirs(os.path.join(out, "img"))
scipy.io.savemat(os.path.join(out, "img", "S1_labelled_EL.mat"), {"ETdata": {
    "pos": pos, "screenRes": np.array([w_px, h_px], float), "screenDim": np.array([w_mm, h_mm]) / 1000.0,
    "viewDist": d_mm / 1000.0, "sampFreq": 1.0 / float(np.median(np.diff(s["t"])))}})
PY
  /usr/bin/python3 "$H" "$CTL" "$WORK/ellund" --methods ivvt --json "$WORK/lund.json" >"$WORK/lund.txt" 2>&1 ||
    fail "harness on the session: $(cat "$WORK/lund.txt")"
  /usr/bin/python3 "$SRC/bench/eval_classify_human.py" "$CTL" "$WORK/el" --methods ivvt --json "$WORK/human.json" \
    >"$WORK/human.txt" 2>&1 || fail "eval_classify_human on the session: $(cat "$WORK/human.txt")"
  /usr/bin/python3 - "$WORK/lund.json" "$WORK/human.json" <<'PY' || fail "figures differ: $(cat "$WORK/lund.txt" "$WORK/human.txt")"
import json, sys
lund, human = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
got = lund["methods"]["ivvt"]["EL"]["images"]
for c in ("fixation", "saccade", "pso", "blink"):
    want = human["ivvt"]["per_session"]["kappa"][c][0]
    assert abs(got[c]["kappa"] - want) < 1e-9, (c, got[c]["kappa"], want)
assert got["fixation"]["kappa"] > 0.7, got
PY
else
  echo "   (no EyeLink set at $DATA: the real-data part is skipped)"
fi
echo "PASS"
