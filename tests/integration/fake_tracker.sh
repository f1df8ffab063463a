# Sourced by the tests of the tracker bridges (test_gazepoint.sh, test_pupil.sh): a fake tracker
# from tests/fakes/ started and waited for, and processes stopped cleanly. Needs SRC, WORK and fail.

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
