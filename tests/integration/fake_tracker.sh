# SPDX-License-Identifier: Apache-2.0
# Sourced by the tests of the tracker bridges (test_gazepoint.sh, test_pupil.sh, test_*_flood.sh),
# after they set TRACKERD, CTL and SRC: a work directory removed at exit with the fake and the
# daemon, fail (which shows both logs), a fake tracker from tests/fakes/ started and waited for,
# processes stopped cleanly; for the flood tests a fake systemd notify socket and one recording.
. "$(dirname "${BASH_SOURCE[0]}")/ports.sh"
WORK=$(mktemp -d)
FPID="" DPID="" NPID=""
trap 'kill $FPID $DPID $NPID 2>/dev/null; rm -rf "$WORK"' EXIT
fail() {
  echo "FAIL: $*"
  for f in d.log fake.log; do [ -f "$WORK/$f" ] && { echo "--- $f"; tail -n 15 "$WORK/$f"; }; done
  exit 1
}

# start_fake SCRIPT ARGS...: the fake on an ephemeral port; sets FPID and FAKE_PORT.
start_fake() {
  rm -f "$WORK/port"
  /usr/bin/python3 -B "$SRC/tests/fakes/$1" --port 0 --ready-file "$WORK/port" "${@:2}" >"$WORK/fake.log" 2>&1 &
  FPID=$!
  for _ in $(seq 50); do [ -s "$WORK/port" ] && break; sleep 0.1; done
  [ -s "$WORK/port" ] || fail "the fake did not start: $(cat "$WORK/fake.log")"
  FAKE_PORT=$(cat "$WORK/port")
}

# stop PID: SIGTERM, and it must exit 0.
stop() {
  kill -TERM "$1"
  wait "$1" || fail "process $1 did not exit cleanly"
}

# two_clients_across_a_restart SOURCE WHAT: the daemon on SOURCE (log d.log); two clients record 5 s
# of it (a.fgr, b.fgr); 2.5 s in, SIGUSR1 makes the fake drop its connection or restart (WHAT says
# which, for the log). Then the fake and the daemon stop cleanly. Needs TRACKERD, CTL.
two_clients_across_a_restart() {
  local port
  port=$(free_udp_port)
  "$TRACKERD" --source "$1" --port "$port" --control-socket none --log-level info >"$WORK/d.log" 2>&1 &
  DPID=$!
  sleep 0.5
  "$CTL" --server "127.0.0.1:$port" record --duration 5 "$WORK/a.fgr" >"$WORK/a.out" 2>&1 &
  local a=$!
  "$CTL" --server "127.0.0.1:$port" record --duration 5 "$WORK/b.fgr" >"$WORK/b.out" 2>&1 &
  local b=$!
  sleep 2.5
  echo "== $2"
  kill -USR1 "$FPID"
  wait "$a" || fail "client a: $(cat "$WORK/a.out")"
  wait "$b" || fail "client b: $(cat "$WORK/b.out")"
  stop "$FPID"; FPID=""
  sleep 0.5
  stop "$DPID"; DPID=""
  for c in a b; do "$CTL" convert "$WORK/$c.fgr" "$WORK/$c.csv" >/dev/null 2>&1 || fail "convert $c.fgr"; done
}

# start_notify_listener: a fake systemd notify socket ($WORK/notify.sock); each datagram becomes a
# line of $WORK/notify.log (STATUS= lines: the daemon's status, once a second). Sets NPID.
start_notify_listener() {
  /usr/bin/python3 - "$WORK/notify.sock" "$WORK/notify.log" <<'PY' &
import socket, sys
s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
s.bind(sys.argv[1])
with open(sys.argv[2], "a", buffering=1) as log:
    while True:
        log.write(s.recv(65536).decode(errors="replace").replace("\n", " ") + "\n")
PY
  NPID=$!
  for _ in $(seq 50); do [ -S "$WORK/notify.sock" ] && break; sleep 0.1; done
  [ -S "$WORK/notify.sock" ] || fail "the notify listener did not start"
}

# flood_and_record SOURCE SECONDS: the daemon on SOURCE (log d.log, STATUS to the notify listener);
# one client records SECONDS of it (r.fgr, r.csv); then the fake and the daemon stop cleanly.
# wait_for_flood_to_end: the daemon drains what the fake wrote during its flood at its own pace (under
# ASan about 8000 records a second, so a 3 s flood of 57000 lasts 7 s there); wait up to 30 s for it
# to log the flood's end and for a STATUS line after that, so the checks see the clock after it.
wait_for_flood_to_end() {
  local i
  for i in $(seq 300); do
    if grep -q "the flood ended" "$WORK/d.log" 2>/dev/null &&
       [ -n "$(grep "STATUS=" "$WORK/notify.log" 2>/dev/null | tail -n 1 | grep -v FLOODING)" ]; then
      return 0
    fi
    sleep 0.1
  done
  fail "the daemon did not report the flood's end within 30 s"
}

flood_and_record() {
  local port
  port=$(free_udp_port)
  NOTIFY_SOCKET="$WORK/notify.sock" "$TRACKERD" --source "$1" --port "$port" --control-socket none --log-level info \
    >"$WORK/d.log" 2>&1 &
  DPID=$!
  sleep 0.3
  "$CTL" --server "127.0.0.1:$port" record --duration "$2" "$WORK/r.fgr" >"$WORK/r.out" 2>&1 \
    || fail "the client: $(cat "$WORK/r.out")"
  wait_for_flood_to_end
  stop "$FPID"; FPID=""
  stop "$DPID"; DPID=""
  "$CTL" convert "$WORK/r.fgr" "$WORK/r.csv" >/dev/null 2>&1 || fail "convert r.fgr"
}

# expect_flood_handled FAKE KIND DECLARED_HZ SECONDS WHAT FAKE_ARGS...: the fake (FAKE.py) at
# DECLARED_HZ floods from 1.5 s to 4.5 s (FAKE_ARGS: its --flood-rate); the daemon on
# KIND:127.0.0.1:PORT is recorded for SECONDS (flood_and_record, STATUS through the notify listener);
# the fake must have flooded (its log's "flood over: N WHAT"), the daemon must pass check_flood.py.
expect_flood_handled() {
  local fake=$1 kind=$2 hz=$3 seconds=$4 what=$5
  shift 5
  echo "== a fake $fake at $hz Hz that floods from 1.5 s to 4.5 s ($*)"
  start_fake "$fake" --rate "$hz" --flood 1.5,3 "$@"
  start_notify_listener
  flood_and_record "$kind:127.0.0.1:$FAKE_PORT" "$seconds"
  grep -q "flood over: [0-9]* $what" "$WORK/fake.log" || fail "the fake did not flood"
  echo "   the fake: $(grep -o 'flood over: [^;]*' "$WORK/fake.log")"
  echo "== the flood warned of, shown in STATUS, capped, counted"
  /usr/bin/python3 -B "$SRC/tests/integration/check_flood.py" "$WORK" "$hz" || fail "the flood was not handled"
}
