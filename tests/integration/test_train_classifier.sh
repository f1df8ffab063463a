#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# bench/train_classifier.py (issue 43) end to end on a made-up GazeCom: two "videos" of two
# recordings each (fixations, saccades, pursuit at 250 Hz with their true labels). It must fit a
# model, copy each recording as another tracker would record it, write the model in trees.h's
# format and find fovea-ctl agreeing with scikit-learn on every sample (its own check); --lovo
# must write one model per video. fovea-ctl must then label with the model, and refuse a damaged
# one naming the file and line, writing nothing.
# Usage: test_train_classifier.sh CTL SOURCE_DIR
set -u
CTL=$1 SRC=$2
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

echo "== a made-up GazeCom: 2 videos x 2 recordings of 12 s"
/usr/bin/python3 - "$WORK/gc/ground_truth" <<'PY' || fail "making the recordings"
import math, os, random, sys
root = sys.argv[1]
for video in ("clip_a", "clip_b"):
    os.makedirs(os.path.join(root, video))
    for observer in ("AAA", "BBB"):
        rng = random.Random(f"{video}{observer}")
        rows, t, x, y = [], 0, 0.0, 0.0
        while t < 3000:  # 4 ms samples: 12 s
            kind = rng.choice(["fixation", "fixation", "pursuit", "blink"])
            dur = {"fixation": rng.randint(50, 100), "pursuit": rng.randint(80, 150), "blink": rng.randint(20, 50)}[kind]
            vx, vy = rng.uniform(-3, 3) / 250 * 3, rng.uniform(-3, 3) / 250 * 3  # pursuit ~10 deg/s
            for _ in range(dur):
                if kind == "pursuit":
                    x, y = x + vx, y + vy
                rows.append((t, x + rng.gauss(0, 0.03), y + rng.gauss(0, 0.03), {"fixation": 1, "pursuit": 3, "blink": 4}[kind]))
                t += 1
            tx, ty = rng.uniform(-10, 10), rng.uniform(-6, 6)  # then a saccade of 10 samples
            for k in range(1, 11):
                f = (1 - math.cos(math.pi * k / 10)) / 2
                rows.append((t, x + f * (tx - x), y + f * (ty - y), 2))
                t += 1
            x, y = tx, ty
        with open(os.path.join(root, video, f"{observer}_{video}.arff"), "w") as out:
            out.write("@RELATION gaze_labels\n%@METADATA width_px 1280\n%@METADATA height_px 720\n"
                      "%@METADATA width_mm 400.00\n%@METADATA height_mm 225.00\n%@METADATA distance_mm 450.00\n"
                      "@ATTRIBUTE time INTEGER\n@DATA\n")
            for t, xd, yd, label in rows:
                px = (math.tan(math.radians(xd)) * 450 / 400 + 0.5) * 1280
                py = (math.tan(math.radians(yd)) * 450 / 225 + 0.5) * 720
                if label == 4:
                    px = py = 0
                out.write(f"{t * 4000},{px:.2f},{py:.2f},{0 if label == 4 else 1},{label},?,{label}\n")
PY

echo "== one model on everything, one per video held out"
export XDG_CACHE_HOME="$WORK/cache"
/usr/bin/python3 "$SRC/bench/train_classifier.py" "$CTL" --data "$WORK/gc" --out "$WORK/m.trees" --iterations 8 \
  --leaves 15 --augment 1 >"$WORK/train.txt" 2>&1 || fail "train: $(cat "$WORK/train.txt")"
cat "$WORK/train.txt"
grep -q "disagree on 0 of" "$WORK/train.txt" || fail "no exactness check in: $(cat "$WORK/train.txt")"
grep -q "4 recordings and 1 copies of each" "$WORK/train.txt" || fail "the copies were not made"
head -1 "$WORK/m.trees" | grep -q "iterations 8, leaves 15" || fail "the model does not say how it was fitted"
/usr/bin/python3 "$SRC/bench/train_classifier.py" "$CTL" --data "$WORK/gc" --lovo "$WORK/lovo" --iterations 4 \
  --leaves 7 --augment 0 >"$WORK/lovo.txt" 2>&1 || fail "lovo: $(cat "$WORK/lovo.txt")"
[ -f "$WORK/lovo/clip_a.trees" ] && [ -f "$WORK/lovo/clip_b.trees" ] || fail "lovo wrote $(ls "$WORK/lovo")"
grep -q "GazeCom without clip_a" "$WORK/lovo/clip_a.trees" || fail "clip_a's model does not say what it left out"

echo "== fovea-ctl labels with the model and refuses a damaged one"
in="$WORK/in.csv"
{ echo "t_ms,x_px,y_px"; for i in $(seq 0 499); do echo "$((i * 4)),$((640 + i / 10)),360"; done; } >"$in"
"$CTL" classify "$in" "$WORK/out.csv" 250 1280 720 400 225 450 --method gbt --model "$WORK/m.trees" 2>"$WORK/err" \
  || fail "classify with the model: $(cat "$WORK/err")"
[ "$(wc -l <"$WORK/out.csv")" = 501 ] || fail "one label per row: $(wc -l <"$WORK/out.csv")"
sed 's/^fovea-trees 1$/fovea-trees 7/' "$WORK/m.trees" >"$WORK/bad.trees"
if "$CTL" classify "$in" "$WORK/bad.csv" 250 1280 720 400 225 450 --method gbt --model "$WORK/bad.trees" 2>"$WORK/err"; then
  fail "a damaged model was taken"
fi
grep -q "bad.trees:2: format version is not 1" "$WORK/err" || fail "the error does not name file and line: $(cat "$WORK/err")"
[ ! -e "$WORK/bad.csv" ] || fail "a damaged model left an output"
echo "PASS"
