#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea-trackerd --source pupil:HOST:PORT against a fake Pupil Capture (tests/fakes/fake_pupil_capture.py:
# Pupil Remote and the publisher, gaze on a surface "screen" and in the scene camera at 200 Hz, Pupil
# time 5000 s ahead and 30 ppm fast, every message sent 15 ms after its gaze was taken, "t" answers
# delayed 0..3 ms at random, low-confidence stretches, gaze leaving the surface, malformed messages).
# Two clients record what the daemon publishes; every sample must be a gaze the fake published: the
# surface point with y flipped (Pupil's origin is bottom-left), invalid below confidence 0.6, and its
# time, mapped from Pupil time, within 1 ms of when the gaze was taken, or within the clock's stated
# uncertainty (half the fastest "t" round trip) where that is larger (stamping arrival would be
# 15 ms late). Halfway the fake restarts (new publisher port, Pupil time jumps): the daemon follows.
# Then, without the surface: samples invalid, and the daemon says why.
# Usage: test_pupil.sh TRACKERD CTL SOURCE_DIR
set -u
TRACKERD=$1 CTL=$2 SRC=$3

. "$SRC/tests/integration/fake_tracker.sh"

echo "== a fake Pupil Capture: surface \"screen\", 200 Hz, 15 ms late, clock +5000 s and 30 ppm fast"
start_fake fake_pupil_capture.py --truth "$WORK/truth.csv" --rate 200 --time-offset 5000 --drift-ppm 30 --latency-ms 15 \
  --t-jitter-ms 3 --malformed-every 40
two_clients_across_a_restart "pupil:127.0.0.1:$FAKE_PORT" "the fake restarts: its publisher moves, Pupil time jumps 1000 s"
grep -q "connected (publisher on port" "$WORK/d.log" || fail "never connected"
grep -q "Pupil time jumped" "$WORK/d.log" || fail "the restart's clock jump was not noticed"

echo "== every sample a client got is a gaze the fake published: point, y flipped, validity, time"
/usr/bin/python3 - "$WORK" <<'PY' || fail "samples do not match what the fake published"
import bisect, csv, re, struct, sys
work = sys.argv[1]
f32 = lambda v: struct.unpack("f", struct.pack("f", v))[0]  # what a float on the wire holds
by_point, malformed = {}, 0
for row in csv.reader(open(f"{work}/truth.csv")):
    if row[0].startswith("# malformed"):
        malformed = int(row[0].split()[-1])
        continue
    if not row[0].isdigit():
        continue
    capture_ns, x, y_up, conf = int(row[1]), float(row[3]), float(row[4]), float(row[6])
    key = (f32(x), f32(1.0 - y_up), True) if conf >= 0.6 else (0.0, 0.0, False)
    by_point.setdefault(key, []).append(capture_ns)
for times in by_point.values():
    times.sort()
log = open(f"{work}/d.log").read()
m = re.search(r"(\d+) samples \((\d+) valid, (\d+) below confidence, (\d+) off the surface\), (\d+) scene-only, (\d+) malformed", log)
assert m, "no final counts in the daemon's log"
samples, valid, low, off, scene, refused = map(int, m.groups())
assert low > 0 and off > 0, f"the fake's low-confidence and off-surface gaze were not seen ({low}, {off})"
assert refused > 0, "no malformed message was refused"
# The mapping can be no better than half the fastest exchange's round trip, which the daemon states.
u = re.search(r"clock offset [-0-9.]+ ms \+- ([0-9.]+) ms", log)
bound_ns = max(1_000_000, int((float(u.group(1)) + 0.1) * 1e6)) if u else 1_000_000
# STATUS states the delay the bridge adds: the fake publishes 15 ms late.
d = re.search(r"delay p50 ([0-9.]+) / p99 ([0-9.]+) ms", log)
assert d and 14 < float(d.group(1)) < 25, f"the daemon's stated delay: {d.group(0) if d else None}"
for client in "ab":
    rows = [r for r in csv.reader(l for l in open(f"{work}/{client}.csv") if not l.startswith("#"))][1:]
    errors = []
    for r in rows:
        t, valid_ = int(r[1]), r[9] == "1"
        key = (f32(float(r[2])), f32(float(r[3])), True) if valid_ else (0.0, 0.0, False)
        assert key in by_point, f"{client}: {key} at {t} is no gaze the fake published (y not flipped?)"
        times = by_point[key]
        i = bisect.bisect_left(times, t)
        errors.append(min(abs(times[j] - t) for j in (i - 1, i) if 0 <= j < len(times)))
    # Half of what the fake published while the client recorded, apart from the restart's gap (not
    # of 200 Hz x 5 s: on a starved machine the Python fake itself falls behind its rate, and the
    # daemon takes longer to find the moved publisher; what is published before it subscribes is
    # gone, as with Pupil Capture itself).
    got = sorted(int(r[1]) for r in rows)
    gap = max(zip(got, got[1:]), key=lambda g: g[1] - g[0])
    assert gap[1] - gap[0] < 3e9, f"{client}: no samples for {(gap[1] - gap[0]) / 1e9:.1f} s around the restart"
    published = sum(got[0] <= c <= got[-1] and not gap[0] < c < gap[1] for times in by_point.values() for c in times)
    assert len(rows) > 100 and len(rows) > 0.5 * published, \
        f"{client}: only {len(rows)} samples of the {published} the fake published meanwhile (restart gap aside)"
    errors.sort()
    late = sum(e > bound_ns for e in errors)
    print(f"   {client}: {len(rows)} samples, time error p50 {errors[len(errors)//2]/1e6:.3f} ms, "
          f"p98 {errors[int(len(errors)*0.98)]/1e6:.3f} ms, max {errors[-1]/1e6:.3f} ms, "
          f"{sum(e > 1_000_000 for e in errors)} over 1 ms, {late} over the stated bound {bound_ns/1e6:.3f} ms")
    # Around the restart, gaze that arrives before the clock has heard of the jump is stamped on
    # arrival (15 ms late), and the first exchanges after it may be slow ones (the bound is the last
    # exchange's): at most a few dozen samples of one 50 ms poll and one exchange. A count, not a
    # share of the run: under ASan on a busy machine 29 of 657 samples came 1.0-1.045 ms off.
    assert late <= 40, f"{client}: {late} of {len(errors)} times are off by more than {bound_ns/1e6} ms"
    # Both times kept: the fake publishes each gaze 15 ms after it was taken, so it reaches the
    # daemon that much after its (mapped) time.
    delays = sorted(int(r[22]) - int(r[1]) for r in rows if r[22] != "")
    assert len(delays) > 0.9 * len(rows), f"{client}: {len(rows) - len(delays)} of {len(rows)} samples lack the receive time"
    p50 = delays[len(delays) // 2]
    assert 14_000_000 < p50 < 25_000_000, f"{client}: median receive delay {p50/1e6:.2f} ms, the fake's latency is 15 ms"
    print(f"   {client}: receive time after the tracker's: p50 {p50/1e6:.2f} ms, max {delays[-1]/1e6:.2f} ms")
print(f"   the daemon: {samples} surface samples ({valid} valid, {low} below confidence, {off} off the surface), "
      f"{refused} malformed messages refused of {malformed} sent")
PY

# One client records SECONDS of the daemon reading the running fake through SPEC (after "pupil:127.0.0.1:PORT")
# into $WORK/NAME.csv; then daemon and fake stop. The daemon's log is $WORK/d.log.
record_from_fake() {
  local spec=$1 name=$2 seconds=$3
  PORT=$(free_udp_port)
  "$TRACKERD" --source "pupil:127.0.0.1:$FAKE_PORT$spec" --port "$PORT" --control-socket none --log-level info \
    >"$WORK/d.log" 2>&1 &
  DPID=$!
  sleep 0.5
  "$CTL" --server "127.0.0.1:$PORT" record --duration "$seconds" "$WORK/$name.fgr" >"$WORK/$name.out" 2>&1 \
    || fail "client $name: $(cat "$WORK/$name.out")"
  stop "$DPID"; DPID=""
  stop "$FPID"; FPID=""
  "$CTL" convert "$WORK/$name.fgr" "$WORK/$name.csv" >/dev/null 2>&1 || fail "convert $name.fgr"
}

echo "== no surface: scene-camera gaze only, published invalid, and the daemon says why"
start_fake fake_pupil_capture.py --rate 200 --no-surface
record_from_fake "" c 3
grep -q 'only scene-camera gaze, no surface "screen"' "$WORK/d.log" || fail "the missing surface was not reported"
n=$(grep -vc '^#' "$WORK/c.csv")
[ "$n" -gt 200 ] || fail "only $n samples without a surface"
grep -v '^#' "$WORK/c.csv" | tail -n +2 | awk -F, '$10 != 0 {bad++} END {exit bad > 0}' || fail "scene-camera gaze was published as valid screen gaze"
echo "   $((n - 1)) samples, all invalid"

echo "== gaze=scene: the scene camera's gaze published as the point, y flipped, for a fovea calibration to map"
start_fake fake_pupil_capture.py --rate 200 --no-surface --truth "$WORK/scene-truth.csv"
record_from_fake "?gaze=scene" s 2
grep -q "publishes the scene camera's gaze .* map it with a fovea calibration" "$WORK/d.log" || fail "scene mode not announced"
grep -q "only scene-camera gaze" "$WORK/d.log" && fail "scene mode reported the missing surface as a problem"
/usr/bin/python3 - "$WORK" <<'PY' || fail "scene gaze does not match what the fake published"
import csv, struct, sys
work = sys.argv[1]
f32 = lambda v: struct.unpack("<f", struct.pack("<f", v))[0]
scene = {}
for line in open(f"{work}/scene-truth.csv"):
    if line[0].isdigit():
        n, cap, t, x, y_up, on, c, sx, sy = line.strip().split(",")
        scene[(f32(float(sx)), f32(1.0 - float(sy)))] = float(c)
rows = [r for r in csv.reader(l for l in open(f"{work}/s.csv") if not l.startswith("#"))][1:]
valid = [r for r in rows if r[9] == "1"]
assert len(rows) > 150, f"only {len(rows)} samples in 2 s at 200 Hz"
assert len(valid) > 0.5 * len(rows), f"only {len(valid)} of {len(rows)} scene samples valid"
for r in valid:
    key = (f32(float(r[2])), f32(float(r[3])))
    assert key in scene, f"{key} is no scene gaze the fake published (y not flipped?)"
    assert scene[key] >= 0.6, f"{key} has confidence {scene[key]}, below 0.6, yet is valid"
print(f"   {len(rows)} samples, {len(valid)} valid, each the fake's scene gaze with y flipped")
PY
echo "PASS"
