#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# bench/train_classifier.py (issue 43) end to end on a made-up GazeCom: two "videos" of two
# recordings each (fixations, saccades, pursuit at 250 Hz with their true labels). It must fit a
# model, copy each recording as another tracker would record it, write the model in trees.h's
# format and find fovea-ctl agreeing with scikit-learn on every sample (its own check); --lovo
# must write one model per video. fovea-ctl must then label with the model, and refuse a damaged
# one naming the file and line, writing nothing. --nested, on three videos, must write a video's
# second stages fitted on rows from first stages that never saw it, and refuse a video not there.
# --offline-context-iterations and --offline-context-stride-ms must fit the offline chain's second
# stage alone larger and on denser rows, checked exact.
# --online-reach must give the daemon's chain a first stage of its own over features that reach less
# far ahead, each checked exact, reusing the first stages fitted before, and labels final sooner.
# Each chain's pursuit-onset hold (or none) must be fitted into every bundle
# (bench/fit_class_weights.py), each bundle's on the other video, unless --no-weights; a bundle with
# the wrong count of weights or a damaged hold is refused naming its line, and fovea-ctl's
# --pursuit-weight and --pursuit-hold override the model's.
# Usage: test_train_classifier.sh CTL SOURCE_DIR
set -u
CTL=$1 SRC=$2
WORK=$(mktemp -d)
trap '[ -n "${KEEP:-}" ] || rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

echo "== a made-up GazeCom: 2 videos x 2 recordings of 12 s"
make_gazecom() {  # ROOT VIDEO,VIDEO,...
/usr/bin/python3 - "$1" "$2" <<'PY'
import math, os, random, sys
root = sys.argv[1]
for video in sys.argv[2].split(","):
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
}
make_gazecom "$WORK/gc/ground_truth" clip_a,clip_b || fail "making the recordings"

echo "== one model per video held out, then one on everything"
export XDG_CACHE_HOME="$WORK/cache"
opts=(--data "$WORK/gc" --iterations 6 --leaves 7 --context-iterations 4 --context-stride-ms 16 --augment 1)
/usr/bin/python3 "$SRC/bench/train_classifier.py" "$CTL" "${opts[@]}" --lovo "$WORK/lovo" >"$WORK/lovo.txt" 2>&1 \
  || fail "lovo: $(cat "$WORK/lovo.txt")"
cat "$WORK/lovo.txt"
for v in clip_a clip_b; do
  [ -f "$WORK/lovo/$v.trees" ] && [ -f "$WORK/lovo/$v.frame.trees" ] || fail "lovo wrote $(ls "$WORK/lovo")"
  grep -q "GazeCom without $v" "$WORK/lovo/$v.trees" || fail "$v's model does not say what it left out"
  grep -Eq "^stage offline 0.512 weights 1 1 1( hold 0.144 0.[35] 0.02)?$" "$WORK/lovo/$v.trees" \
    || fail "$v's model has no offline stage with weights: $(grep '^stage' "$WORK/lovo/$v.trees")"
  grep -Eq "^stage online 0.032 weights 1 1 1( hold 0.144 0.[35] 0.02)?$" "$WORK/lovo/$v.trees" \
    || fail "$v's online stage has no weights: $(grep '^stage online' "$WORK/lovo/$v.trees")"
  grep -Eq "lovo/$v.trees: online weight 1(, hold 0.144 s ratio 0.[35] min 0.02 s)?, offline weight 1(, hold 0.144 s ratio 0.[35] min 0.02 s)?$" \
    "$WORK/lovo.txt" || fail "the setting fitted for $v is not reported: $(cat "$WORK/lovo.txt")"
done
for s in "weight 1" "weight 1, hold 0.144 s ratio 0.3 min 0.02 s" "weight 1, hold 0.144 s ratio 0.5 min 0.02 s" \
  "nested, the whole grid"; do
  for chain in online offline; do
    grep -q "$chain  *$s: mean 0\.[0-9]* (" "$WORK/lovo.txt" || fail "the $chain setting '$s' is not reported"
  done
done
grep -q "4 recordings and 1 copies of each" "$WORK/lovo.txt" || fail "the copies were not made"
[ "$(grep -c "disagree on 0 of" "$WORK/lovo.txt")" = 4 ] || fail "not every stage checked exact: $(cat "$WORK/lovo.txt")"
/usr/bin/python3 "$SRC/bench/train_classifier.py" "$CTL" "${opts[@]}" --lovo "$WORK/lovo" --out "$WORK/m.trees" \
  >"$WORK/train.txt" 2>&1 || fail "train: $(cat "$WORK/train.txt")"
cat "$WORK/train.txt"
! grep -q "frame.trees (" "$WORK/train.txt" || fail "the first stages fitted before were fitted again"
[ "$(grep -c "disagree on 0 of" "$WORK/train.txt")" = 4 ] || fail "no exactness check in: $(cat "$WORK/train.txt")"
head -1 "$WORK/m.trees" | grep -q "iterations 6, leaves 7" || fail "the model does not say how it was fitted"
grep -Eq "m.trees: online weight 1(, hold [0-9. a-z]*)?, offline weight 1(, hold [0-9. a-z]*)?$" "$WORK/train.txt" \
  || fail "the model's setting unfitted"

echo "== the offline chain's second stage larger and on denser rows than the daemon's"
/usr/bin/python3 "$SRC/bench/train_classifier.py" "$CTL" "${opts[@]}" --lovo "$WORK/lovo" --out "$WORK/moff.trees" \
  --no-weights --offline-context-iterations 7 --offline-context-stride-ms 8 >"$WORK/off.txt" 2>&1 \
  || fail "offline options: $(cat "$WORK/off.txt")"
for bad in "--offline-context-iterations 0" "--offline-context-stride-ms -8"; do
  # shellcheck disable=SC2086
  if /usr/bin/python3 "$SRC/bench/train_classifier.py" "$CTL" "${opts[@]}" --lovo "$WORK/lovo" $bad >"$WORK/bad.txt" 2>&1; then
    fail "$bad was taken"
  fi
  grep -q "must be" "$WORK/bad.txt" || fail "unclear: $(cat "$WORK/bad.txt")"
done
[ "$(grep -c "disagree on 0 of" "$WORK/off.txt")" = 4 ] || fail "not every stage checked exact: $(cat "$WORK/off.txt")"
head -1 "$WORK/moff.trees" | grep -q "second stage: iterations 4 (7 offline), leaves 127, a sample every 16 ms (8 offline)" \
  || fail "the model does not say how its second stages were fitted: $(head -1 "$WORK/moff.trees")"
stage_trees() {  # FILE STAGE: "TREES CLASSES" of that stage's ensemble
  awk -v s="$2" '$1 == "stage" { on = ($2 == s) } on && $1 == "classes" { c = $2 } on && $1 == "trees" { print $2, c; exit }' "$1"
}
read -r n c <<<"$(stage_trees "$WORK/moff.trees" offline)"
[ "${n:-0}" = "$((7 * ${c:-0}))" ] || fail "the offline second stage has $n trees for $c classes, not 7 iterations"
read -r n c <<<"$(stage_trees "$WORK/moff.trees" online)"
[ "${n:-0}" = "$((4 * ${c:-0}))" ] || fail "the online second stage has $n trees for $c classes, not 4 iterations"
# The offline stage learned from twice the rows: the note counts the online chain's.
n_online=$(sed -n 's/.*(\([0-9]*\) in the second stage).*/\1/p' "$WORK/moff.trees" | head -1)
n_plain=$(sed -n 's/.*(\([0-9]*\) in the second stage).*/\1/p' "$WORK/m.trees" | head -1)
[ -n "$n_online" ] && [ "$n_online" = "$n_plain" ] || fail "the online chain's rows changed: $n_online, $n_plain"

echo "== fovea-ctl labels with the model and refuses a damaged one"
in="$WORK/in.csv"
{ echo "t_ms,x_px,y_px"; for i in $(seq 0 499); do echo "$((i * 4)),$((640 + i / 10)),360"; done; } >"$in"
"$CTL" classify "$in" "$WORK/out.csv" 250 1280 720 400 225 450 --method gbt --model "$WORK/m.trees" 2>"$WORK/err" \
  || fail "classify with the model: $(cat "$WORK/err")"
[ "$(wc -l <"$WORK/out.csv")" = 501 ] || fail "one label per row: $(wc -l <"$WORK/out.csv")"
"$CTL" classify "$in" "$WORK/off.csv" 250 1280 720 400 225 450 --method gbt --model "$WORK/m.trees" --offline \
  2>"$WORK/err" || fail "classify --offline with the model: $(cat "$WORK/err")"
grep -Eq "online latency (8[0-9][0-9]|10[0-9][0-9]) ms" "$WORK/err" || fail "--offline does not wait for its look-ahead: $(cat "$WORK/err")"
# --pursuit-weight overrides the model's: more pursuit above, less below; refused for ivvt and at 0.
count_pursuit() { "$CTL" classify "$in" "$WORK/w.csv" 250 1280 720 400 225 450 --method "$1" --model "$WORK/m.trees" \
  --pursuit-weight "$2" --force 2>"$WORK/err" && grep -c ",pursuit" "$WORK/w.csv"; }
low=$(count_pursuit gbt 0.2) high=$(count_pursuit gbt 20)
[ "${low:-x}" -lt "${high:-0}" ] 2>/dev/null || fail "--pursuit-weight 20 gave no more pursuit than 0.2: $low, $high"
if count_pursuit ivvt 2 >/dev/null; then fail "ivvt took a pursuit weight"; fi
grep -q "classifier ivvt: only gbt weighs its classes" "$WORK/err" || fail "unclear: $(cat "$WORK/err")"
if count_pursuit gbt 0 >/dev/null; then fail "a pursuit weight of 0 was taken"; fi
grep -q "pursuit-weight: Value 0 not in range" "$WORK/err" || fail "unclear: $(cat "$WORK/err")"
# --pursuit-hold instead of the model's: the fixations before a pursuit become its start when every
# fixation is doubtful (ratio 0.01) and may wait a second; refused for ivvt, its options need it.
count_held() { "$CTL" classify "$in" "$WORK/h.csv" 250 1280 720 400 225 450 --method "$1" --model "$WORK/m.trees" \
  --pursuit-hold "$2" --pursuit-hold-ratio 0.01 --pursuit-hold-min 0 --force 2>"$WORK/err" && grep -c ",pursuit" "$WORK/h.csv"; }
none=$(count_held gbt 0) held=$(count_held gbt 1000)
echo "pursuit labels without a hold: $none, with: $held"
[ "${none:-x}" -lt "${held:-0}" ] 2>/dev/null || fail "--pursuit-hold 1000 gave no more pursuit than none: $none, $held"
if count_held ivvt 100 >/dev/null; then fail "ivvt took a pursuit hold"; fi
grep -q "classifier ivvt: only gbt holds doubtful fixations" "$WORK/err" || fail "unclear: $(cat "$WORK/err")"
if "$CTL" classify "$in" "$WORK/h.csv" 250 1280 720 400 225 450 --method gbt --pursuit-hold-min 10 --force 2>"$WORK/err"; then
  fail "--pursuit-hold-min without --pursuit-hold was taken"
fi
grep -q "pursuit-hold-min requires --pursuit-hold" "$WORK/err" || fail "unclear: $(cat "$WORK/err")"
online_at=$(grep -n "^stage online" "$WORK/m.trees" | cut -d: -f1)
check_refused() {  # sed-expression error-text
  sed "$1" "$WORK/m.trees" >"$WORK/bad.trees"
  if "$CTL" classify "$in" "$WORK/bad.csv" 250 1280 720 400 225 450 --method gbt --model "$WORK/bad.trees" 2>"$WORK/err"; then
    fail "a damaged model was taken ($1)"
  fi
  grep -qF "$2" "$WORK/err" || fail "the error does not name file, line and fault: $(cat "$WORK/err")"
  [ ! -e "$WORK/bad.csv" ] || fail "a damaged model left an output"
}
check_refused 's/^fovea-trees 1$/fovea-trees 7/' "bad.trees:5: format version is not 1"
check_refused 's/^stage online 0.032 .*$/stage online 2/' "bad.trees:$online_at: 'stage online' needs one look-ahead"
check_refused 's/^stage online 0.032 weights .*$/stage online 0.032 weights 1 1/' \
  "bad.trees:$online_at: 'stage online' has 2 weights for its 3 classes"
check_refused 's/^stage online 0.032 weights 1 /stage online 0.032 weights -1 /' \
  "bad.trees:$online_at: 'stage online': weight '-1' is not a positive number"
check_refused 's/^stage online 0.032 weights \([0-9 .]*\).*$/stage online 0.032 weights \1 hold 0.144 2 0.02/' \
  "bad.trees:$online_at: 'stage online': a pursuit hold's ratio 2.000000 is not in (0, 1]"
check_refused 's/^stage frame$/stage frames/' "bad.trees:3: stage 'frames' is none of frame, frame-online, online, offline"
check_refused "$((online_at + 4))s/^classes [0-9]* /classes 0 /" "bad.trees:$((online_at + 4)): classes '0' is not an integer"

echo "== --online-reach: the daemon's own first stage, over features 64 ms ahead"
/usr/bin/python3 "$SRC/bench/train_classifier.py" "$CTL" "${opts[@]}" --lovo "$WORK/lovo" --out "$WORK/m64.trees" \
  --online-reach 0.064 --no-weights >"$WORK/reach.txt" 2>&1 || fail "online reach: $(cat "$WORK/reach.txt")"
cat "$WORK/reach.txt"
! grep -q "/clip_a.frame.trees (" "$WORK/reach.txt" || fail "the whole reach's first stages were fitted again"
for v in clip_a clip_b; do
  [ -f "$WORK/lovo/$v.frame-online.trees" ] && grep -q "^stage frame-online 0.064$" "$WORK/lovo/$v.trees" \
    || fail "$v's bundle has no online first stage: $(grep '^stage' "$WORK/lovo/$v.trees")"
done
# 2 online first stages, the full model's 3 stages, and the first bundle's 2 second stages.
[ "$(grep -c "disagree on 0 of" "$WORK/reach.txt")" = 7 ] || fail "not every stage checked exact: $(cat "$WORK/reach.txt")"
[ "$(grep '^stage' "$WORK/m64.trees" | tr '\n' ' ')" = "stage frame stage frame-online 0.064 stage online 0.032 stage offline 0.512 " ] \
  || fail "the model's stages: $(grep '^stage' "$WORK/m64.trees")"
# The trees alone (no smoothing, no ivvt beside them): 75 ms fill-in + 64 ms reach + 32 ms look-ahead.
"$CTL" classify "$in" "$WORK/r.csv" 250 1280 720 400 225 450 --method gbt --model "$WORK/m64.trees" --trees-only \
  2>"$WORK/err" || fail "classify with the online-reach model: $(cat "$WORK/err")"
grep -q "online latency 171 ms" "$WORK/err" || fail "the online chain does not label 64 ms after: $(cat "$WORK/err")"
"$CTL" classify "$in" "$WORK/r.csv" 250 1280 720 400 225 450 --method gbt --model "$WORK/m64.trees" --trees-only \
  --offline --force 2>"$WORK/err" || fail "classify --offline with the online-reach model: $(cat "$WORK/err")"
grep -q "online latency 843 ms" "$WORK/err" || fail "the offline chain does not wait 256 + 512 ms: $(cat "$WORK/err")"

echo "== --nested: a video's second stages from first stages that never saw it"
make_gazecom "$WORK/gc3/ground_truth" clip_a,clip_b,clip_c || fail "making the recordings"
opts3=(--data "$WORK/gc3" --iterations 6 --leaves 7 --context-iterations 4 --context-stride-ms 16 --augment 1)
if /usr/bin/python3 "$SRC/bench/train_classifier.py" "$CTL" "${opts3[@]}" --lovo "$WORK/lovo3" --nested clip_x \
    >"$WORK/nested.txt" 2>&1; then
  fail "--nested took a video that is not there"
fi
grep -q "no video 'clip_x' (videos: clip_a, clip_b, clip_c)" "$WORK/nested.txt" || fail "unclear: $(cat "$WORK/nested.txt")"
/usr/bin/python3 "$SRC/bench/train_classifier.py" "$CTL" "${opts3[@]}" --lovo "$WORK/lovo3" --nested clip_a \
  >"$WORK/nested.txt" 2>&1 || fail "nested: $(cat "$WORK/nested.txt")"
grep -q "nested (no first stage behind its rows saw clip_a)" "$WORK/lovo3/nested/clip_a.trees" \
  || fail "the nested model does not say what it is: $(head -1 "$WORK/lovo3/nested/clip_a.trees")"
[ "$(ls "$WORK/lovo3/nested")" = "clip_a.trees" ] || fail "nested left $(ls "$WORK/lovo3/nested")"
"$CTL" classify "$in" "$WORK/nested.csv" 250 1280 720 400 225 450 --method gbt --model "$WORK/lovo3/nested/clip_a.trees" \
  2>"$WORK/err" || fail "classify with the nested model: $(cat "$WORK/err")"
echo "PASS"
