#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea-trackerd as a service: configuration file and --check-config, sd_notify (READY, STATUS,
# WATCHDOG, RELOADING, STOPPING) on a fake NOTIFY_SOCKET, subscriber churn (kill -9), SIGHUP reload
# with a changed configuration that keeps existing subscribers, control commands from an allowed
# and a disallowed network, no leaked file descriptors, and a clean SIGTERM.
set -u
TRACKERD=$1 CTL=$2 SRC=$3 FLOOD=$4  # FLOOD: tests/tools/control_flood.cpp
WORK=$(mktemp -d)
PIDS=()
cleanup() { for p in "${PIDS[@]}"; do kill -9 "$p" 2>/dev/null; done; rm -rf "$WORK"; }
trap cleanup EXIT
fail() {
  echo "FAIL: $*"
  for f in "$WORK"/daemon*.log; do [ -f "$f" ] && { echo "--- $f"; tail -n 40 "$f"; }; done
  exit 1
}
. "$(dirname "${BASH_SOURCE[0]}")/ports.sh"
PORT=$(free_udp_port)
PORT2=$(free_udp_port)
SRV=127.0.0.1:$PORT

wait_status() {  # SERVER
  for _ in $(seq 1 100); do "$CTL" --server "$1" status >/dev/null 2>&1 && return 0; sleep 0.1; done
  return 1
}
fd_count() { ls "/proc/$1/fd" | wc -l; }
wait_for() {  # FILE PATTERN [tries]
  for _ in $(seq 1 "${3:-50}"); do grep -q -- "$2" "$1" 2>/dev/null && return 0; sleep 0.1; done
  return 1
}

write_config() {  # FILE LEASE_MS DISPLAY_W DISPLAY_H PORT ALLOW
  cat >"$1" <<EOF
# test configuration
[source]
spec = "synthetic"
rate = 250
seed = 7

[display]
width_px = $3
height_px = $4
width_mm = 531.3
height_mm = 298.9
distance_mm = 650

[network]
listen = "127.0.0.1"
port = $5
lease_ms = $2
max_subscribers = 16
control_allow = [$6]
control_dir = "$WORK"
calibration_dir = "$WORK/cals"

[calibration]
file = "cal.json"
EOF
}
# An identity calibration of the tracker's own gaze (affine x = u, y = v).
echo '{"format": "fovea-calibration", "version": 1, "model": {"kind": "affine", "a": [0, 1, 0, 0, 0, 1]},
 "input": "screen", "points_used": 9, "rms_residual": 0, "condition": 1, "created": "2026-11-23T00:00:00Z"}' >"$WORK/cal.json"

echo "== --check-config: the documented example, a good file, bad files"
"$TRACKERD" --check-config --config "$SRC/deploy/trackerd.toml" >"$WORK/check.out" 2>"$WORK/check.err" \
  || fail "deploy/trackerd.toml does not check: $(cat "$WORK/check.err")"
grep -q '^\[network\]' "$WORK/check.out" || fail "--check-config printed no effective configuration"
write_config "$WORK/good.toml" 5000 1920 1080 "$PORT" '"127.0.0.0/8"'
out=$("$TRACKERD" --check-config --config "$WORK/good.toml" --port 40000 2>&1) || fail "good config rejected: $out"
grep -q '^port = 40000$' <<<"$out" || fail "--check-config does not show the --port override: $out"
grep -q "file = \"$WORK/cal.json\"" <<<"$out" || fail "calibration path not resolved against the file's directory: $out"
printf '[network]\nport = 47800\nprot = 1\n[source]\nrate = 0\n' >"$WORK/bad.toml"
out=$("$TRACKERD" --check-config --config "$WORK/bad.toml" 2>&1) && fail "bad config accepted"
grep -q "bad.toml:3: network.prot: unknown key" <<<"$out" || fail "unknown key not named with file:line: $out"
grep -q "bad.toml:5: source.rate: 0 is out of range" <<<"$out" || fail "bad value not named with file:line: $out"
out=$("$TRACKERD" --check-config --config "$WORK/missing.toml" 2>&1) && fail "missing config accepted"
grep -q "missing.toml" <<<"$out" || fail "missing file not named: $out"
printf '[source]\nspec = "camera-typo"\n' >"$WORK/badsource.toml"
out=$("$TRACKERD" --check-config --config "$WORK/badsource.toml" 2>&1) && fail "unknown source kind accepted"
grep -q 'unknown source "camera-typo"' <<<"$out" || fail "unknown source not named: $out"
"$TRACKERD" --config "$WORK/bad.toml" >/dev/null 2>&1; rc=$?
[ $rc -eq 78 ] || fail "daemon with a bad config exited $rc, expected 78 (EX_CONFIG)"
# Issue 23 item 10: an unknown classifier passed the check and the daemon then exited 2.
printf '[classifier]\nmethod = "magic"\n' >"$WORK/magic.toml"
out=$("$TRACKERD" --check-config --config "$WORK/magic.toml" 2>&1) && fail "unknown classifier accepted"
grep -q 'magic.toml:2: classifier.method: unknown method "magic"; allowed: gbt, ivvt' <<<"$out" \
  || fail "unknown classifier not named: $out"
"$TRACKERD" --config "$WORK/magic.toml" >/dev/null 2>&1; rc=$?
[ $rc -eq 78 ] || fail "daemon with an unknown classifier exited $rc, expected 78 (EX_CONFIG)"
out=$("$TRACKERD" --classifier magic --duration 1 2>&1); rc=$?
[ $rc -eq 2 ] && grep -q -- '--classifier: unknown method "magic"' <<<"$out" || fail "--classifier magic: $rc $out"

echo "== daemon under a fake systemd: READY, STATUS, WATCHDOG"
NOTIFY="$WORK/notify.sock"
python3 - "$NOTIFY" "$WORK/notify.log" <<'EOF' &
import socket, sys
s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
s.bind(sys.argv[1])
with open(sys.argv[2], "a", buffering=1) as log:
    while True:
        log.write(s.recv(4096).decode().replace("\n", " ") + "\n")
EOF
PIDS+=($!); disown $!
for _ in $(seq 1 50); do [ -S "$NOTIFY" ] && break; sleep 0.1; done
[ -S "$NOTIFY" ] || fail "notify listener did not start"
NOTIFY_SOCKET=$NOTIFY WATCHDOG_USEC=1000000 bash -c 'export WATCHDOG_PID=$$; exec "$0" "$@"' \
  "$TRACKERD" --config "$WORK/good.toml" >"$WORK/daemon.log" 2>&1 &
DPID=$!; PIDS+=($DPID)
wait_status "$SRV" || fail "daemon did not answer status"
wait_for "$WORK/notify.log" "READY=1" || fail "no READY=1"
wait_for "$WORK/notify.log" "WATCHDOG=1" 30 || fail "no WATCHDOG=1 within 3 s at WatchdogSec=1s"
wait_for "$WORK/notify.log" "STATUS=synthetic.*subscribers" 30 || fail "no STATUS= line"
# The status names the active calibration and whether (and how well) it was validated.
grep -q "STATUS=.*calibration .*cal.json: affine on screen, 9 samples, not validated" "$WORK/notify.log" \
  || fail "STATUS= does not name the calibration: $(grep STATUS= "$WORK/notify.log" | tail -1)"
grep -q "calibration: .*cal.json" "$WORK/daemon.log" || fail "calibration file not logged"
sleep 0.5
FD0=$(fd_count $DPID)

echo "== subscribers come and go (kill -9); the long-lived ones are untouched"
"$CTL" --server "$SRV" watch --every 1000 >/dev/null 2>"$WORK/watch.err" &
W=$!; PIDS+=($W)
"$CTL" --server "$SRV" record "$WORK/client.fgr" 2>"$WORK/record.err" &
R=$!; PIDS+=($R)
for round in 1 2 3; do
  K=()
  for _ in 1 2 3; do "$CTL" --server "$SRV" watch --every 1000 >/dev/null 2>&1 & K+=($!); PIDS+=($!); done
  sleep 0.7
  kill -9 "${K[@]}"; wait "${K[@]}" 2>/dev/null
done
"$CTL" --server "$SRV" status | grep -q "subscribers *[0-9]" || fail "status after churn"

echo "== control from loopback: record-start / record-stop"
"$CTL" --server "$SRV" record-start "$WORK/ctl.fgr" >"$WORK/ctl.out" 2>&1 || fail "record-start: $(cat "$WORK/ctl.out")"
grep -q "ok: recording to $WORK/ctl.fgr" "$WORK/ctl.out" || fail "record-start reply: $(cat "$WORK/ctl.out")"
out=$("$CTL" --server "$SRV" record-start "$WORK/other.fgr" 2>&1) && fail "second record-start accepted"
grep -q "failed: already recording" <<<"$out" || fail "second record-start reply: $out"
sleep 1
"$CTL" --server "$SRV" record-stop >"$WORK/ctl.out" 2>&1 || fail "record-stop: $(cat "$WORK/ctl.out")"
grep -q "stopped recording" "$WORK/ctl.out" || fail "record-stop reply: $(cat "$WORK/ctl.out")"
n=$("$CTL" info "$WORK/ctl.fgr" | awk '/^samples/{print $2}')
[ "${n:-0}" -ge 150 ] || fail "control recording holds ${n:-0} samples after ~1 s at 250 Hz"
out=$("$CTL" --server "$SRV" record-start "$WORK/ctl.fgr" 2>&1) && fail "record-start overwrote a file"
grep -q "already exists" <<<"$out" || fail "overwrite refusal unclear: $out"
out=$("$CTL" --server "$SRV" record-stop 2>&1) && fail "record-stop without a recording succeeded"
grep -q "failed: not recording" <<<"$out" || fail "record-stop reply: $out"
# Issue 23 item 2: record-start wrote wherever the daemon could (a root daemon created files in
# /etc) and "../" walked out; now it writes only inside [network] control_dir.
for bad in /etc/fovea-test-$$.fgr ../outside-$$.fgr "$WORK/../outside-$$.fgr"; do
  out=$("$CTL" --server "$SRV" record-start "$bad" 2>&1) && fail "record-start $bad accepted"
  grep -q "outside the recordings directory\|outside the record" <<<"$out" || fail "record-start $bad: unclear refusal: $out"
done
[ ! -e /etc/fovea-test-$$.fgr ] && [ ! -e "$(dirname "$WORK")/outside-$$.fgr" ] || fail "a refused record-start wrote a file"
grep -q "record-start /etc/fovea-test-$$.fgr: outside the recordings directory $WORK" "$WORK/daemon.log" \
  || fail "the refusal is not logged in full"
# calibration-load is confined to [network] calibration_dir, and never follows a link out of it.
mkdir -p "$WORK/cals"; cp "$WORK/cal.json" "$WORK/cals/ok.json"; ln -s "$WORK/cal.json" "$WORK/cals/link.json"
"$CTL" --server "$SRV" calibration-load "$WORK/cals/ok.json" >"$WORK/ctl.out" 2>&1 || fail "calibration-load inside: $(cat "$WORK/ctl.out")"
out=$("$CTL" --server "$SRV" calibration-load "$WORK/cal.json" 2>&1) && fail "calibration-load outside accepted"
grep -q "failed: outside the calibrations directory" <<<"$out" || fail "calibration-load outside: unclear refusal: $out"
out=$("$CTL" --server "$SRV" calibration-load "$WORK/cals/link.json" 2>&1) && fail "calibration-load through a link accepted"
grep -q "failed: calibration file .*link.json: is a sy" <<<"$out" || fail "through a link: unclear refusal: $out"
grep -q "link.json: is a symbolic link (not followed)" "$WORK/daemon.log" || fail "the link refusal is not logged in full"
"$CTL" --server "$SRV" calibration-load configured >/dev/null 2>&1 || fail "calibration-load configured"

echo "== SIGHUP reloads a changed configuration without dropping subscribers"
write_config "$WORK/good.toml" 2000 1280 1024 $((PORT + 1)) '"127.0.0.0/8"'
kill -HUP $DPID
wait_for "$WORK/daemon.log" "reloaded: " || fail "no reload after SIGHUP"
# The new display reaches the subscribers at once (an unasked SUBSCRIBED): the client's recording,
# whose header names the old one, ends with a clear message and keeps what it wrote; the session
# of the watcher goes on. Another recording takes its place as a long-lived subscriber.
for _ in $(seq 1 100); do kill -0 $R 2>/dev/null || break; sleep 0.1; done
kill -0 $R 2>/dev/null && fail "the client's recording went on into another display: $(cat "$WORK/record.err")"
wait $R; rr=$?
[ $rr -eq 1 ] || fail "record across the reloaded display exited $rr: $(cat "$WORK/record.err")"
grep -q "the daemon's display changed from 1920x1080@.* to 1280x1024@.* (reloaded or restarted with another configuration); the recording ends here" \
  "$WORK/record.err" || fail "unclear display-change message: $(cat "$WORK/record.err")"
n=$("$CTL" info "$WORK/client.fgr" | awk '/^samples/{print $2}')
[ "${n:-0}" -ge 100 ] || fail "the client's recording before the reload holds ${n:-0} samples"
"$CTL" --server "$SRV" record "$WORK/client2.fgr" 2>"$WORK/record.err" &
R=$!; PIDS+=($R)
grep -q "network.port $PORT -> $((PORT + 1)): needs a restart" "$WORK/daemon.log" || fail "port change not reported as needing a restart"
grep -q "applied: network.lease_ms 5000 -> 2000" "$WORK/daemon.log" || fail "lease change not applied"
wait_for "$WORK/notify.log" "RELOADING=1" || fail "no RELOADING=1"
"$CTL" --server "$SRV" status >"$WORK/status.out" || fail "daemon does not answer on its old port after reload"
grep -q "display     1280x1024@" "$WORK/status.out" || fail "status does not show the reloaded display: $(cat "$WORK/status.out")"
# A broken file is refused as a whole; the daemon keeps running with what it had.
printf '[network]\nlease_ms = 1\n' >"$WORK/good.toml"
kill -HUP $DPID
wait_for "$WORK/daemon.log" "reload failed; keeping the running configuration" || fail "bad reload not reported"
grep -q "good.toml:2: network.lease_ms" "$WORK/daemon.log" || fail "bad reload does not name file:line and key"
write_config "$WORK/good.toml" 2000 1280 1024 "$PORT" '"127.0.0.0/8"'
"$CTL" --server "$SRV" reload >"$WORK/ctl.out" 2>&1 || fail "fovea-ctl reload: $(cat "$WORK/ctl.out")"
grep -q "ok: reloaded" "$WORK/ctl.out" || fail "reload reply: $(cat "$WORK/ctl.out")"
sleep 1

echo "== a flood of control commands starves neither status nor the subscribers"
# Issue 23 item 3: a flood of record-stop (each waiting for the publishing loop) made status fail
# 5/5 and a subscribed watcher lose its lease and ~9 s of gaze while reporting lost=0. Control now
# has its own socket and thread, apart from the thread that answers status and heartbeats.
# Beyond 50 a second they are answered "too many" and not executed; every one is answered.
F=(); for k in 1 2 3 4; do "$FLOOD" "$SRV" 150 >"$WORK/flood.$k" 2>&1 & F+=($!); done
ok=0
for _ in 1 2 3 4 5; do "$CTL" --server "$SRV" status >/dev/null 2>&1 && ok=$((ok + 1)); sleep 0.3; done
wait "${F[@]}"
[ $ok -eq 5 ] || fail "status answered $ok of 5 times during a control flood"
answered=$(cat "$WORK"/flood.* | grep -c "failed: not recording\|refused: too many control requests")
[ "$answered" -eq 600 ] || fail "$answered of the flood's 600 requests were answered: $(sort "$WORK"/flood.* | uniq -c | head)"
refused=$(cat "$WORK"/flood.* | grep -c "refused: too many control requests")
[ "$refused" -gt 0 ] || fail "none of 600 requests in ~2 s was refused: the limit of 50 a second does not hold"

echo "== the long-lived subscribers never noticed"
kill -INT $W $R; wait $W; rw=$?; wait $R; rr=$?
[ $rw -eq 0 ] && [ $rr -eq 0 ] || fail "watch/record exited $rw/$rr"
grep -q "summary received=" "$WORK/watch.err" || fail "watch printed no summary"
grep -q " lost=0 " "$WORK/watch.err" || fail "watch lost samples: $(cat "$WORK/watch.err")"
grep -q "subscriptions=1$" "$WORK/watch.err" || fail "watch had to resubscribe: $(cat "$WORK/watch.err")"
grep -q "subscriptions=1$" "$WORK/record.err" || fail "record had to resubscribe: $(cat "$WORK/record.err")"

echo "== no leaked file descriptors"
sleep 0.5
FD1=$(fd_count $DPID)
[ "$FD0" -eq "$FD1" ] || { ls -l /proc/$DPID/fd; fail "file descriptors: $FD0 before churn, $FD1 after"; }

echo "== control through the daemon's socket: its default path for the port, mode 0660, the sender logged"
sock=$(sed -n 's/.*control commands from \(.*\) (mode 0660.*/\1/p' "$WORK/daemon.log" | head -n 1)
[ -S "$sock" ] || fail "no control socket at '$sock': $(grep -i control "$WORK/daemon.log")"
[ "$(stat -c %a "$sock")" = 660 ] || fail "control socket mode $(stat -c %a "$sock")"
case "$sock" in */control-$PORT.sock) ;; *) fail "the socket's name does not carry the port: $sock" ;; esac
grep -q "control reload from the control socket (pid [0-9]* uid $(id -u) gid" "$WORK/daemon.log" \
  || fail "the sender of a socket command is not logged"
"$CTL" --server "$SRV" --control-socket "$WORK/nosuch.sock" status >/dev/null || fail "status needs no control socket"
out=$("$CTL" --server "$SRV" --control-socket "$WORK/nosuch.sock" record-stop 2>&1) && fail "a missing socket worked"
grep -q "control socket $WORK/nosuch.sock: No such file" <<<"$out" || fail "missing socket unclear: $out"

echo "== control over UDP is refused and counted, also where an old configuration allowed it"
write_config "$WORK/far.toml" 5000 1920 1080 "$PORT2" '"10.0.0.0/8"'
# No control socket: fovea-ctl then falls back to UDP, which this daemon allows from 10/8 only.
sed -i 's/^control_allow = .*/&\ncontrol_socket = "none"/' "$WORK/far.toml"
"$TRACKERD" --config "$WORK/far.toml" >"$WORK/daemon2.log" 2>&1 &
D2=$!; PIDS+=($D2)
wait_status "127.0.0.1:$PORT2" || fail "second daemon did not answer status"
for cmd in reload "record-start $WORK/never.fgr"; do
  out=$("$CTL" --server "127.0.0.1:$PORT2" $cmd 2>&1) && fail "$cmd from loopback accepted by a 10.0.0.0/8-only daemon"
  grep -q "refused: UDP control is off; use the daemon's control socket" <<<"$out" || fail "refusal unclear: $out"
done
[ ! -e "$WORK/never.fgr" ] || fail "a refused record-start was executed"
grep -q "network.control_allow (10.0.0.0/8) is ignored: control commands come only through the control socket" \
  "$WORK/daemon2.log" || fail "an old control_allow is not reported as ignored"
wait_for "$WORK/daemon2.log" "refused 2 control request(s)\|(2 refused so far)" 30 || fail "refusals not logged"
kill -TERM $D2; wait $D2; rc=$?
[ $rc -eq 0 ] || fail "second daemon exit status $rc"
grep -q "0 control requests, 2 control requests refused" "$WORK/daemon2.log" || fail "refusal counter not in the final log line"

echo "== SIGTERM: clean exit, STOPPING=1"
kill -TERM $DPID
for _ in $(seq 1 50); do kill -0 $DPID 2>/dev/null || break; sleep 0.1; done
kill -0 $DPID 2>/dev/null && fail "daemon still running 5 s after SIGTERM"
wait $DPID; rc=$?
[ $rc -eq 0 ] || fail "daemon exit status $rc after SIGTERM"
grep -q "shut down cleanly" "$WORK/daemon.log" || fail "no clean-shutdown log line"
grep -q "AddressSanitizer\|runtime error" "$WORK/daemon.log" && fail "errors in the daemon log"
wait_for "$WORK/notify.log" "STOPPING=1" || fail "no STOPPING=1"
echo "PASS"
