#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea-ctl synth-eye and detect-pupil as a user runs them, and the daemon's eye options at the
# command line.
set -u
TRACKERD=$1 CTL=$2
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

echo "== synth-eye writes images and their truth"
"$CTL" synth-eye --out "$WORK/eyes" --count 12 --seed 3 2>"$WORK/synth.err" || fail "synth-eye: $(cat "$WORK/synth.err")"
[ -f "$WORK/eyes/eye_0000.png" ] && [ -f "$WORK/eyes/eye_0011.png" ] || fail "images missing: $(ls "$WORK/eyes")"
head -1 "$WORK/eyes/truth.csv" | grep -qx "file,pupil_x,pupil_y,major,minor,angle_deg,closed,glint_count,glints,pupil_glint_x,pupil_glint_y" \
  || fail "truth.csv header: $(head -1 "$WORK/eyes/truth.csv")"
[ "$(wc -l <"$WORK/eyes/truth.csv")" -eq 13 ] || fail "truth.csv rows: $(wc -l <"$WORK/eyes/truth.csv")"
out=$("$CTL" synth-eye --out "$WORK/eyes" --count 1 2>&1) && fail "synth-eye wrote into a non-empty directory"
grep -q "not empty" <<<"$out" || fail "unclear refusal: $out"
"$CTL" synth-eye --out "$WORK/hard" --count 3 --hard --size 160x120 2>/dev/null || fail "synth-eye --hard"
out=$("$CTL" synth-eye --out "$WORK/bad" --size 10x10 2>&1) && fail "tiny size accepted"
grep -q -- "--size" <<<"$out" || fail "unclear size message: $out"
out=$("$CTL" synth-eye --out "$WORK/bad-iris" --pupil-iris-contrast 1 2>&1) && fail "contrast 1 accepted"
grep -q "pupil_iris_contrast.*= 1: allowed 2..150" <<<"$out" || fail "unclear contrast message: $out"
[ ! -e "$WORK/bad-iris" ] || fail "a refused synth-eye created its directory"
out=$("$CTL" synth-eye --out "$WORK/bad-lashes" --lash-length 9 2>&1) && fail "lash length 9 accepted"
grep -q -- "--lash-length" <<<"$out" || fail "unclear lash-length message: $out"
"$CTL" synth-eye --out "$WORK/lashes" --count 2 --lash-length 2.5 --lit-lashes 2>"$WORK/lashes.err" \
  || fail "synth-eye --lit-lashes: $(cat "$WORK/lashes.err")"
grep -q "(lashes 2.500x) (lit lashes)" "$WORK/lashes.err" || fail "lit lashes not reported: $(cat "$WORK/lashes.err")"
out=$("$CTL" synth-eye --out "$WORK/bad-lid" --lid-cover 1.5 2>&1) && fail "lid cover 1.5 accepted"
grep -q -- "--lid-cover" <<<"$out" || fail "unclear lid-cover message: $out"
"$CTL" synth-eye --out "$WORK/lid" --count 2 --lid-cover 0.15 2>"$WORK/lid.err" || fail "synth-eye --lid-cover: $(cat "$WORK/lid.err")"
grep -q "(upper lid over 0.150 of the pupil)" "$WORK/lid.err" || fail "lid cover not reported: $(cat "$WORK/lid.err")"
"$CTL" synth-eye --out "$WORK/no-lid" --count 1 2>/dev/null || fail "synth-eye"
cmp -s "$WORK/lid/eye_0000.png" "$WORK/no-lid/eye_0000.png" && fail "--lid-cover changed nothing"

echo "== dark irises (issue 44): detect-pupil finds the pupil, not the iris"
"$CTL" synth-eye --out "$WORK/dark" --count 8 --seed 5 --pupil-iris-contrast 9 2>/dev/null || fail "synth-eye --pupil-iris-contrast"
(cd "$WORK/dark" && "$CTL" detect-pupil eye_*.png --leds 2 >"$WORK/dark.csv" 2>/dev/null) || fail "detect-pupil on dark irises"
# Within 1.5 px and the pupil's size (major within 25 %), not the iris's, in at least 7 of 8.
good=$(awk -F, 'NR==FNR { if (FNR > 1) { tx[$1] = $2; ty[$1] = $3; tm[$1] = $4 } next }
                FNR > 1 && $2 != "" { dx = $2 - tx[$1]; dy = $3 - ty[$1]; r = $4 / tm[$1]
                                      if (dx*dx + dy*dy <= 2.25 && r > 0.75 && r < 1.25) n++ }
                END { print n + 0 }' "$WORK/dark/truth.csv" "$WORK/dark.csv")
[ "$good" -ge 7 ] || fail "only $good of 8 dark-iris pupils found: $(paste -d'\n' "$WORK/dark/truth.csv" "$WORK/dark.csv")"

echo "== detect-pupil finds the pupils synth-eye drew"
(cd "$WORK/eyes" && "$CTL" detect-pupil eye_*.png --leds 2 --out "$WORK/det.csv" >"$WORK/det.out" 2>"$WORK/det.err") \
  || fail "detect-pupil failed: $(cat "$WORK/det.err")"
cmp -s "$WORK/det.out" "$WORK/det.csv" || fail "--out differs from stdout"
head -1 "$WORK/det.csv" | grep -qx "file,pupil_x,pupil_y,major,minor,angle_deg,confidence,glint_count,glints" \
  || fail "detect-pupil header: $(head -1 "$WORK/det.csv")"
[ "$(wc -l <"$WORK/det.csv")" -eq 13 ] || fail "detect-pupil rows: $(cat "$WORK/det.csv")"
# Pupil centre within 1.5 px of the truth in at least 11 of 12 images.
good=$(awk -F, 'NR==FNR { if (FNR > 1) { tx[$1] = $2; ty[$1] = $3 } next }
                FNR > 1 && $2 != "" { dx = $2 - tx[$1]; dy = $3 - ty[$1]; if (dx*dx + dy*dy <= 2.25) n++ }
                END { print n + 0 }' "$WORK/eyes/truth.csv" "$WORK/det.csv")
[ "$good" -ge 11 ] || fail "only $good of 12 pupils within 1.5 px: $(paste -d'\n' "$WORK/eyes/truth.csv" "$WORK/det.csv")"
# Two glints (preset 2) in most rows, formatted x:y;x:y.
grep -Eq ',2,[0-9.]+:[0-9.]+;[0-9.]+:[0-9.]+$' "$WORK/det.csv" || fail "no row with two glints: $(cat "$WORK/det.csv")"
out=$("$CTL" detect-pupil "$WORK/eyes/eye_0000.png" --out "$WORK/det.csv" 2>&1) && fail "--out overwrote a file"
grep -q "already exists" <<<"$out" || fail "unclear overwrite refusal: $out"
"$CTL" detect-pupil "$WORK"/eyes/eye_000[0-3].png --track --downscale 4 >"$WORK/track.out" 2>/dev/null || fail "--track"
[ "$(wc -l <"$WORK/track.out")" -eq 5 ] || fail "--track rows: $(cat "$WORK/track.out")"

echo "== unreadable inputs are named, the others still processed, exit 1"
echo "not an image" >"$WORK/text.png"
"$CTL" detect-pupil "$WORK/eyes/eye_0001.png" "$WORK/missing.png" "$WORK/text.png" "$WORK/eyes/eye_0002.png" \
  >"$WORK/mixed.out" 2>"$WORK/mixed.err"
rc=$?
[ $rc -eq 1 ] || fail "exit status $rc with unreadable inputs (want 1)"
grep -q "$WORK/missing.png: no such file" "$WORK/mixed.err" || fail "missing file not named: $(cat "$WORK/mixed.err")"
grep -q "$WORK/text.png: cannot be read as an image" "$WORK/mixed.err" || fail "bad image not named: $(cat "$WORK/mixed.err")"
[ "$(wc -l <"$WORK/mixed.out")" -eq 3 ] || fail "the readable images were not all processed: $(cat "$WORK/mixed.out")"
# Issue 23 item 6: a small PNG declaring 20000x20000 took detect-pupil to 1.7 GB; a FIFO blocked it.
python3 -c "import sys; b = bytearray(open(sys.argv[1], 'rb').read()); b[16:24] = (20000).to_bytes(4, 'big') * 2; open(sys.argv[2], 'wb').write(b)" \
  "$WORK/eyes/eye_0000.png" "$WORK/bomb.png"
mkfifo "$WORK/fifo.png"
start=$(date +%s%N)
timeout 20 "$CTL" detect-pupil "$WORK/bomb.png" "$WORK/fifo.png" "$WORK/eyes/eye_0001.png" >"$WORK/bomb.out" 2>"$WORK/bomb.err"
rc=$?
ms=$(( ($(date +%s%N) - start) / 1000000 ))
[ $rc -eq 1 ] || fail "bomb: exit $rc (want 1): $(cat "$WORK/bomb.err")"
[ "$ms" -lt 5000 ] || fail "bomb and FIFO took $ms ms"
grep -q "bomb.png: cannot be read as an image: PNG declaring 20000x20000 pixels; at most 16777216 are decoded" \
  "$WORK/bomb.err" || fail "bomb not named: $(cat "$WORK/bomb.err")"
grep -q "fifo.png: is a FIFO, not a regular file" "$WORK/bomb.err" || fail "FIFO not named: $(cat "$WORK/bomb.err")"
[ "$(wc -l <"$WORK/bomb.out")" -eq 2 ] || fail "the good image after the bomb was not processed"
out=$("$CTL" detect-pupil "$WORK/eyes/eye_0001.png" --leds "1,2;x" 2>&1) && fail "bad --leds accepted"
grep -q "x" <<<"$out" && grep -q "LED layout" <<<"$out" || fail "unclear --leds message: $out"

echo "== fovea-trackerd eye options are checked"
out=$("$TRACKERD" --check-config --config /dev/null --source synthetic-eye --leds "1,2;oops" 2>&1) && fail "bad --leds passed --check-config"
grep -q "eye.leds" <<<"$out" && grep -q "oops" <<<"$out" || fail "--check-config does not name eye.leds: $out"
"$TRACKERD" --check-config --config /dev/null --source synthetic-eye --eye left --leds 4 --eye-size 640x480 --eye-hard \
  --pupil-downscale 4 --no-pupil-roi >"$WORK/eff.toml" 2>/dev/null || fail "valid eye options refused"
for line in 'side = "left"' 'leds = "4"' 'pupil_downscale = 4' 'pupil_roi = false' 'synthetic_width = 640' \
            'synthetic_height = 480' 'synthetic_hard = true' 'spec = "synthetic-eye"'; do
  grep -qF "$line" "$WORK/eff.toml" || fail "effective configuration lacks '$line': $(cat "$WORK/eff.toml")"
done
out=$("$TRACKERD" --source synthetic-eye --eye-size 20x20 2>&1) && fail "bad --eye-size accepted"
grep -q -- "--eye-size" <<<"$out" || fail "unclear --eye-size message: $out"
out=$("$TRACKERD" --source synthetic-eye --leds 9 --port 1 2>&1) && fail "LED preset 9 accepted"
grep -q "LED preset 9" <<<"$out" || fail "unclear LED message: $out"
"$TRACKERD" --help | grep -q "synthetic-eye" || fail "--help does not list synthetic-eye"
"$CTL" --help | grep -q "detect-pupil" || fail "fovea-ctl --help does not list detect-pupil"
echo "PASS"
