#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea-calibrate run as a user runs it: headless on a recorded session of the synthetic viewer,
# live against fovea-trackerd (targets in a window under Xvfb, the synthetic viewer following them),
# loading the result into the running daemon, and the refusals.
# Usage: test_calibrate_run.sh CALIBRATE TRACKERD CTL WITH_XVFB
set -u
CAL=$1 TRACKERD=$2 CTL=$3 XVFB=$4
WORK=$(mktemp -d)
DPID=""
trap '[ -n "$DPID" ] && kill "$DPID" 2>/dev/null; rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; [ -f "$WORK/d.log" ] && tail -n 20 "$WORK/d.log"; exit 1; }
# Under ASan, LeakSanitizer's exit-time scan of a process running Mesa llvmpipe reports (or
# crashes on) the driver's own allocations; the GL process runs without leak detection, as in
# test_render_cli.sh (the headless runs and the daemon keep it).
XVFB_RUN=(env "ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0" "$XVFB")
json() { python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print(eval(sys.argv[2]))" "$@"; }

echo "== headless: a recorded session of the synthetic viewer (9 targets, head moved 20 mm)"
"$CTL" synth-calibration --out "$WORK/s.fgr" --points 9 --seed 2 --head-offset 20,-10,30 --eye-size 240x180 \
  >"$WORK/synth.out" 2>&1 || fail "synth-calibration: $(cat "$WORK/synth.out")"
"$CAL" run --headless --from "$WORK/s.fgr" --out "$WORK/cal.json" --report "$WORK/rep" >"$WORK/run.out" 2>&1 \
  || fail "headless run: $(cat "$WORK/run.out")"
grep -q "input: pupil-glint (right eye)" "$WORK/run.out" || fail "input: $(cat "$WORK/run.out")"
grep -q "^overall " "$WORK/run.out" || fail "no validation table: $(cat "$WORK/run.out")"
[ "$(json "$WORK/cal.json" "d['input']")" = pupil-glint ] || fail "input not recorded: $(cat "$WORK/cal.json")"
[ "$(json "$WORK/cal.json" "d['model']['kind']")" = poly2 ] || fail "auto model"
[ "$(json "$WORK/cal.json" "d['display']['width_px']")" = 1920.0 ] || fail "display not recorded"
acc=$(json "$WORK/cal.json" "d['validation']['accuracy_deg']")
python3 -c "import sys; sys.exit(0 if float('$acc') < 1.5 else 1)" || fail "validated accuracy $acc deg >= 1.5"
[ -f "$WORK/rep/errors.png" ] && [ -f "$WORK/rep/report.md" ] || fail "report missing: $(ls "$WORK/rep")"
echo "   validated accuracy $acc deg"
# The same session with an explicit model and an affine baseline: the affine map is worse.
"$CAL" run --headless --from "$WORK/s.fgr" --model affine --out "$WORK/affine.json" >/dev/null 2>&1 || fail "affine"
acc_affine=$(json "$WORK/affine.json" "d['validation']['accuracy_deg']")
python3 -c "import sys; sys.exit(0 if float('$acc_affine') > float('$acc') else 1)" \
  || fail "affine ($acc_affine deg) not worse than poly2 ($acc deg)"

echo "== headless refusals"
out=$("$CAL" run --headless --from "$WORK/s.fgr" --out "$WORK/cal.json" 2>&1) && fail "overwrote cal.json"
grep -q "exists" <<<"$out" || fail "unclear overwrite refusal: $out"
mv "$WORK/s.targets.csv" "$WORK/moved.csv"
out=$("$CAL" run --headless --from "$WORK/s.fgr" --out "$WORK/x.json" 2>&1) && fail "ran without a targets file"
grep -q "s.targets.csv: cannot open" <<<"$out" || fail "unclear missing-targets message: $out"
[ -e "$WORK/x.json" ] && fail "a calibration was written after an error"
"$CAL" run --headless --from "$WORK/s.fgr" --targets "$WORK/moved.csv" --out "$WORK/x.json" >/dev/null 2>&1 \
  || fail "--targets"
out=$("$CAL" run --headless --from "$WORK/moved.csv" --out "$WORK/y.json" 2>&1) && fail "read a CSV as a recording"
grep -q "moved.csv" <<<"$out" || fail "unclear bad-recording message: $out"
out=$("$CAL" run --out "$WORK/z.json" --server 127.0.0.1:1 --window 320x200 2>&1) && fail "live run without a daemon"
grep -q "no answer from fovea-trackerd" <<<"$out" || fail "unclear no-daemon message: $out"

echo "== live: fovea-trackerd's synthetic viewer follows the targets fovea-calibrate shows"
. "$(dirname "${BASH_SOURCE[0]}")/ports.sh"
PORT=$(free_udp_port)
"$TRACKERD" --source synthetic-eye --eye-script calibration:5:4 --eye-size 240x180 --port "$PORT" --control-dir "$WORK" \
  --log-level info >"$WORK/d.log" 2>&1 &
DPID=$!
sleep 0.5
"${XVFB_RUN[@]}" "$CAL" run --server "127.0.0.1:$PORT" --points 5 --seed 4 --window 480x270 --out "$WORK/live.json" \
  >"$WORK/live.out" 2>&1 || fail "live run: $(cat "$WORK/live.out")"
grep -q "calibration-load: ok" "$WORK/live.out" || fail "not loaded: $(cat "$WORK/live.out")"
[ "$(json "$WORK/live.json" "d['model']['kind']")" = homography ] || fail "auto model for 5 targets"
acc_live=$(json "$WORK/live.json" "d['validation']['accuracy_deg']")
python3 -c "import sys; sys.exit(0 if float('$acc_live') < 2.0 else 1)" || fail "live accuracy $acc_live deg >= 2"
echo "   live validated accuracy $acc_live deg"
sleep 0.3
grep -q "calibration (control request): .*live.json: homography on pupil-glint (right eye).*validated" "$WORK/d.log" \
  || fail "daemon did not load it"
# A reload keeps the calibration loaded by control.
kill -HUP "$DPID"
sleep 0.5
grep -q "kept over reloads" "$WORK/d.log" || fail "SIGHUP dropped the loaded calibration"
echo "== fovea-ctl calibration-load: a bad file is refused by name and the running one stays"
echo '{"format": "fovea-calibration", "version": 2}' >"$WORK/newer.json"
out=$("$CTL" --server "127.0.0.1:$PORT" calibration-load "$WORK/newer.json" 2>&1) && fail "loaded a newer file"
grep -q "failed: .*newer.json: written by a newer fovea" <<<"$out" || fail "unclear refusal: $out"
grep -q "keeping .*live.json" "$WORK/d.log" || fail "the running calibration was not kept"
out=$("$CTL" --server "127.0.0.1:$PORT" calibration-load "$WORK/missing.json" 2>&1) && fail "loaded a missing file"
grep -q "missing.json" <<<"$out" || fail "unclear missing-file message: $out"
"$CTL" --server "127.0.0.1:$PORT" calibration-load none >"$WORK/none.out" 2>&1 || fail "none: $(cat "$WORK/none.out")"
grep -q "ok: loaded none" "$WORK/none.out" || fail "none: $(cat "$WORK/none.out")"
(cd "$WORK" && "$CTL" --server "127.0.0.1:$PORT" calibration-load cal.json) >"$WORK/rel.out" 2>&1 \
  || fail "relative path: $(cat "$WORK/rel.out")"
grep -q "ok: loaded poly2 on pupil-glint, validated [0-9.]* deg" "$WORK/rel.out" \
  || fail "relative path: $(cat "$WORK/rel.out")"
"$CTL" --server "127.0.0.1:$PORT" calibration-load configured >/dev/null 2>&1 || fail "configured"
echo "== calibration-load of what is not a calibration file: refused at once, publishing and status go on"
# Issue 23 item 1: /dev/zero was read whole on the publishing thread (RSS without bound, SIGTERM
# ignored), a FIFO without a writer hung the daemon until one appeared.
mkfifo "$WORK/fifo"
head -c $((17 * 1024 * 1024)) /dev/zero >"$WORK/huge.json"
mkdir "$WORK/dir.json"
rss_before=$(awk '/VmRSS/ {print $2}' "/proc/$DPID/status")
# calibration-load reads only inside its directory (here --control-dir): /dev/zero is not even looked at.
for bad in /dev/zero:"outside the calibrations directory" "$WORK/fifo":"FIFO" "$WORK/huge.json":"the limit is 16777216" \
           "$WORK/dir.json":"directory"; do
  path=${bad%%:*} want=${bad#*:}
  start=$(date +%s%N)
  out=$(timeout 10 "$CTL" --server "127.0.0.1:$PORT" calibration-load "$path" 2>&1) && fail "loaded $path: $out"
  ms=$(( ($(date +%s%N) - start) / 1000000 ))
  [ "$ms" -lt 3000 ] || fail "$path took $ms ms"
  grep -q "$want" "$WORK/d.log" || fail "$path: the log does not say '$want': $(tail -n 3 "$WORK/d.log")"
  timeout 5 "$CTL" --server "127.0.0.1:$PORT" status >/dev/null 2>&1 || fail "status stopped answering after $path"
done
# Relative to before: a sanitizer build starts far above a release one. /dev/zero used to add GBs.
rss_kb=$(awk '/VmRSS/ {print $2}' "/proc/$DPID/status")
[ $((rss_kb - rss_before)) -lt 100000 ] || fail "the daemon's RSS grew from $rss_before to $rss_kb kB"
# A newline in a path cannot forge a log line; escape sequences do not reach a terminal.
evil="$WORK/x"$'\n'"2026-01-01 [info] FORGED"$'\e'"[2J"
timeout 10 "$CTL" --server "127.0.0.1:$PORT" calibration-load "$evil" >/dev/null 2>&1 && fail "loaded the evil path"
sleep 0.2
grep -q "^2026-01-01 \[info\] FORGED" "$WORK/d.log" && fail "a client forged a log line"
grep -q $'\e' "$WORK/d.log" && fail "an escape sequence reached the log"
grep -q 'x\\x0a2026-01-01 \[info\] FORGED\\x1b\[2J' "$WORK/d.log" || fail "the evil path is not in the log, escaped"
kill "$DPID"
wait "$DPID" 2>/dev/null
DPID=""
echo "PASS"
