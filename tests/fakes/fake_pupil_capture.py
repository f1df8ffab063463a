#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Fake Pupil Labs Pupil Capture / Pupil Service "Network API" for integration tests.

Written from Pupil Labs' public network API documentation: Pupil Remote is a ZeroMQ REP
socket taking single-frame string requests ("SUB_PORT", "PUB_PORT", "t", "T <s>", "v",
"R"/"r") and multipart notifications ("notify.<subject>" + msgpack map); data goes out on a
PUB socket as two-frame messages, the topic string and a msgpack map. Gaze ("gaze.3d.01.")
and surface ("surfaces.<name>") data follow known trajectories of the sample counter n, and
the Pupil clock has a known offset and drift, so a test can compare what the daemon reports
with the ground-truth CSV written by --truth.

How tests use it: start it with /usr/bin/python3 in the background with --port 0
--ready-file R --truth T.csv (plus --rate, --latency-ms, --malformed-every N, --drop-after S
as needed); wait for R, read the Pupil Remote port from it and point the daemon at
127.0.0.1:PORT; read T.csv while it runs (one flushed line per sample published); SIGUSR1
simulates a Pupil Capture restart (Pupil Remote back on the same port, the publisher on a new
one, the clock at a new offset); SIGTERM stops it (exit 0, T.csv then ends with
"# malformed N"). Needs python3-zmq and python3-msgpack; otherwise standard library only.

Two ways to misbehave, for the daemon's arrival rules: --flood START,LEN publishes gaze and
surface messages as fast as it can (or --flood-rate N a second) from START to START+LEN s
after start, each stamped with Pupil time as it is sent (not in the truth; the log says how
many); --future-ms F sends the last 20 of every 100 samples early, the k-th of them F*k/20 ms
before its own timestamp (Pupil time at capture, so the truth stays right).
"""
import argparse
import math
import os
import random
import signal
import sys
import time

import msgpack
import zmq

from fakelib import add_flood_options, flood_due, flood_next_ns, make_log, now_ns, write_ready_file

log = make_log("fake_pupil_capture")

GAZE_TOPIC = "gaze.3d.01."
FLOOD_BATCH = 100         # --flood: samples per turn of the loop
MAX_REQUEST = 64 * 1024   # longer Pupil Remote frames are answered "Unknown command." unread
MAX_FRAME = 4 << 20       # zmq drops a peer sending more; bounds our memory
UNKNOWN = "Unknown command."
TRUTH_HEADER = "n,capture_host_ns,pupil_time_s,surface_x,surface_y_up,on_surf,confidence,scene_x,scene_y_up\n"
IDENTITY = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
# (kind, sent on the surface topic); the surface ones are skipped with --no-surface.
MALFORMED_KINDS = (("not_msgpack", False), ("list", False), ("int", True), ("no_norm_pos", False),
                   ("short_norm_pos", False), ("str_norm_pos", False), ("nan_confidence", False),
                   ("nan_timestamp", False), ("str_timestamp", False), ("gos_not_list", True),
                   ("single_frame", False), ("three_frames", False), ("huge", False))


class Fake:
    """Process-wide state. Signal handlers only set flags; the loop acts on them."""

    def __init__(self, args, truth):
        self.args, self.truth = args, truth
        self.rng = random.Random(args.seed)
        self.ctx = zmq.Context()
        self.rep = self.pub = self.sink = None
        self.rep_port = self.pub_port = self.sink_port = 0
        self.stop = self.restart = False
        self.restarts = self.malformed = self.malformed_idx = self.n = 0
        self.pending_t = None   # CLOCK_MONOTONIC ns at which the deferred "t" reply is due
        self.last = None        # latest real (gaze, surface) payloads, the base of hostile ones
        reset_time_base(self, args.time_offset)
        self.end_ns = self.start_ns + int(args.duration * 1e9) if args.duration > 0 else None
        self.flood = None if args.flood is None else (
            self.start_ns + int(args.flood[0] * 1e9), self.start_ns + int(sum(args.flood) * 1e9))
        self.flood_sent = self.flood_started_ns = 0
        self.flood_t = -1e300   # the last flood timestamp: strictly increasing
        self.early_sent, self.max_early_ms = 0, 0.0
        self.drop_at = self.start_ns + int(args.drop_after * 1e9) if args.drop_after > 0 else None


def reset_time_base(fake, offset):
    """Pupil time restarts here; the schedule restarts with it (first capture right now)."""
    fake.start_ns, fake.offset = now_ns(), offset
    fake.origin_ns, fake.origin_n = fake.start_ns, fake.n


def pupil_time(fake, host_ns):
    return (host_ns - fake.start_ns) * 1e-9 * (1 + fake.args.drift_ppm * 1e-6) + fake.offset


def capture_ns(fake, n):
    # Absolute deadlines from one origin: period rounding never accumulates.
    return fake.origin_ns + round((n - fake.origin_n) * 1e9 / fake.args.rate)


def early_ms(fake, n):
    """--future-ms: how long before its capture time sample n is sent (0: on time)."""
    k = n % 100 - 79
    return fake.args.future_ms * k / 20 if fake.args.future_ms > 0 and k > 0 else 0.0


def send_ns(fake, n):
    early = early_ms(fake, n)
    if early > 0:
        return capture_ns(fake, n) - int(early * 1e6)
    return capture_ns(fake, n) + int(fake.args.latency_ms * 1e6)


def scene_gaze(n):
    phase = 2 * math.pi * n / 400
    return 0.5 + 0.25 * math.cos(phase), 0.5 + 0.15 * math.sin(phase)


def surface_gaze(n):
    """Gaze on the surface, origin bottom-left, y up; off the surface for n % 300 in 100..119."""
    phase = 2 * math.pi * n / 300
    x, y_up = 0.5 + 0.3 * math.cos(phase), 0.5 + 0.2 * math.sin(phase)
    if 100 <= n % 300 <= 119:
        x = 1.2
    return x, y_up, 0 <= x <= 1 and 0 <= y_up <= 1


def confidence(n):
    return 0.3 if 40 <= n % 100 <= 49 else 0.95   # below Pupil's usual 0.6 threshold


def gaze_datum(n, t, c):
    sx, sy = scene_gaze(n)
    point = [(sx - 0.5) * 800.0, (0.5 - sy) * 600.0, 600.0]   # scene camera coordinates, mm
    centers = {0: [20.0, 15.0, -20.0], 1: [-40.0, 15.0, -20.0]}   # int keys, as Pupil sends them
    normals = {}
    for eye, e in centers.items():
        d = [p - q for p, q in zip(point, e)]
        norm = math.sqrt(sum(v * v for v in d))
        normals[eye] = [v / norm for v in d]
    return {"topic": GAZE_TOPIC, "norm_pos": [sx, sy], "confidence": c, "timestamp": t,
            "base_data": [{"topic": "pupil.%d.3d" % eye, "timestamp": t, "confidence": c} for eye in (0, 1)],
            "gaze_point_3d": point, "eye_centers_3d": centers, "gaze_normals_3d": normals}


def surface_datum(name, n, t, c):
    x, y_up, on = surface_gaze(n)
    hit = {"topic": GAZE_TOPIC + "_on_surface", "norm_pos": [x, y_up], "confidence": c,
           "on_surf": on, "base_data": [GAZE_TOPIC, t], "timestamp": t}
    return {"topic": "surfaces." + name, "name": name, "uid": "1601234567.8901", "timestamp": t,
            "gaze_on_surfaces": [hit], "fixations_on_surfaces": [],
            "surf_to_img_trans": IDENTITY, "img_to_surf_trans": IDENTITY,
            "surf_to_dist_img_trans": IDENTITY, "dist_img_to_surf_trans": IDENTITY}


def pack(obj):
    return msgpack.packb(obj, use_bin_type=True)   # Python floats go out as float64


def publish_sample(fake, flood_t=None):
    """Sample n, stamped at its capture time, or at flood_t (Pupil time, flooding: not in the truth)."""
    args, n = fake.args, fake.n
    cap = capture_ns(fake, n)
    t, c = pupil_time(fake, cap), confidence(n)   # stamped at capture, not at send
    if flood_t is not None:
        t = flood_t
    elif early_ms(fake, n) > 0:
        fake.early_sent += 1
        fake.max_early_ms = max(fake.max_early_ms, (cap - now_ns()) / 1e6)
    gaze = gaze_datum(n, t, c)
    surf = surface_datum(args.surface_name, n, t, c)
    fake.pub.send_multipart([GAZE_TOPIC.encode(), pack(gaze)])
    if not args.no_surface:
        fake.pub.send_multipart([surf["topic"].encode(), pack(surf)])
    fake.last = gaze, surf
    if fake.truth and flood_t is None:
        # The very floats that were packed, so a test can compare for equality.
        (sx, sy), hit = gaze["norm_pos"], surf["gaze_on_surfaces"][0]
        (x, y_up), on = hit["norm_pos"], hit["on_surf"]
        fake.truth.write("%d,%d,%r,%r,%r,%d,%r,%r,%r\n" % (n, cap, t, x, y_up, on, c, sx, sy))
        fake.truth.flush()
    fake.n += 1
    if args.malformed_every and fake.n % args.malformed_every == 0:
        fake.pub.send_multipart(malformed_message(fake))
        fake.malformed += 1


def malformed_message(fake):
    """The next hostile message in the cycle, built from the latest real payloads, so a
    client that accepts one shows a duplicate timestamp rather than a plausible new sample."""
    kinds = [k for k in MALFORMED_KINDS if not (fake.args.no_surface and k[1])]
    kind, on_surface = kinds[fake.malformed_idx % len(kinds)]
    fake.malformed_idx += 1
    gaze, surf = (dict(d) for d in fake.last)
    topic = (surf["topic"] if on_surface else GAZE_TOPIC).encode()
    garbage = b"\xc1" + fake.rng.randbytes(31)   # 0xc1 is never valid msgpack
    if kind == "not_msgpack":
        return [topic, garbage]
    if kind == "single_frame":
        return [topic]
    if kind == "three_frames":
        return [topic, pack(gaze), garbage]
    payload = {"list": [1, 2, 3], "int": 42}.get(kind, gaze)
    if kind == "no_norm_pos":
        del gaze["norm_pos"]
    elif kind in ("short_norm_pos", "str_norm_pos"):
        gaze["norm_pos"] = [0.5] if kind == "short_norm_pos" else [0.5, "abc"]
    elif kind in ("nan_confidence", "nan_timestamp", "str_timestamp"):
        key = "confidence" if kind == "nan_confidence" else "timestamp"
        gaze[key] = "abc" if kind == "str_timestamp" else float("nan")
    elif kind == "gos_not_list":
        surf["gaze_on_surfaces"], payload = {"not": "a list"}, surf
    elif kind == "huge":
        gaze["padding"] = bytes(2 << 20)   # 2 MiB: a client must bound what it accepts
    return [topic, pack(payload)]


def flood_batch(fake):
    """--flood: a batch of samples at once (or what --flood-rate has due), each stamped with
    Pupil time as it is sent."""
    if not fake.flood_started_ns:
        fake.flood_started_ns = now_ns()
        log("flooding: gaze and surface messages, %s" % (
            "%g a second" % fake.args.flood_rate if fake.args.flood_rate else "as fast as they go"))
    for _ in range(flood_due(fake.args.flood_rate, fake.flood_started_ns, fake.flood_sent, FLOOD_BATCH)):
        fake.flood_t = max(pupil_time(fake, now_ns()), fake.flood_t + 1e-9)
        publish_sample(fake, fake.flood_t)
        fake.flood_sent += 1


def end_flood(fake):
    seconds = (now_ns() - fake.flood_started_ns) / 1e9
    log("flood over: %d samples in %.2f s (%.0f/s); back to the pace"
        % (fake.flood_sent, seconds, fake.flood_sent / max(seconds, 1e-9)))
    fake.flood = None
    fake.origin_ns, fake.origin_n = now_ns(), fake.n   # the schedule goes on from here


def handle_request(fake, frames):
    """Reply text for one Pupil Remote request, or None when the reply is deferred ("t")."""
    if any(len(f) > MAX_REQUEST for f in frames):
        return UNKNOWN
    if len(frames) == 2 and frames[0].startswith(b"notify."):
        try:
            ok = isinstance(msgpack.unpackb(frames[1], raw=False), dict)
        except Exception:   # any garbage: still exactly one reply
            ok = False
        return "Notification received." if ok else UNKNOWN
    if len(frames) != 1:
        return UNKNOWN
    try:
        msg = frames[0].decode("utf-8")
    except UnicodeDecodeError:
        return UNKNOWN
    if msg == "SUB_PORT":
        return str(fake.pub_port)
    if msg == "PUB_PORT":
        return str(fake.sink_port)
    if msg == "v":
        return fake.args.pupil_version
    if msg in ("R", "r") or msg.startswith("R "):
        return "OK"   # recording: accepted, nothing recorded
    if msg == "t":
        # Delay before the clock is read: the reply leg of the round trip is the long one.
        delay_ms = fake.args.t_reply_delay_ms + fake.rng.uniform(0, fake.args.t_jitter_ms)
        fake.pending_t = now_ns() + int(delay_ms * 1e6)
        return None
    if msg.startswith("T "):
        try:
            target = float(msg[2:])
        except ValueError:
            return UNKNOWN
        if not math.isfinite(target):
            return UNKNOWN
        fake.offset += target - pupil_time(fake, now_ns())
        return "Timesync successful."
    return UNKNOWN


def serve_rep(fake):
    try:
        frames = fake.rep.recv_multipart(zmq.NOBLOCK)
    except zmq.Again:
        return
    reply = handle_request(fake, frames)
    if reply is not None:
        fake.rep.send_string(reply)


def reply_time(fake):
    fake.pending_t = None
    fake.rep.send_string(repr(pupil_time(fake, now_ns())))   # read just before sending


def drain_sink(fake):
    """What clients publish on PUB_PORT is read and dropped, so it never piles up."""
    try:
        while True:
            fake.sink.recv_multipart(zmq.NOBLOCK)
    except zmq.Again:
        pass


def bind(sock, port, retry_s=0.0):
    """Bind on 127.0.0.1 (port 0 = ephemeral) and return the port; retry while a just-closed
    zmq socket still holds it (zmq closes listeners asynchronously)."""
    deadline = time.monotonic() + retry_s
    while True:
        try:
            sock.bind("tcp://127.0.0.1:%s" % (port or "*"))
            break
        except zmq.ZMQError as e:
            if e.errno != zmq.EADDRINUSE or time.monotonic() > deadline:
                raise
            time.sleep(0.01)
    return int(sock.getsockopt_string(zmq.LAST_ENDPOINT).rsplit(":", 1)[1])


def new_socket(fake, kind):
    sock = fake.ctx.socket(kind)
    sock.setsockopt(zmq.LINGER, 0)
    sock.setsockopt(zmq.MAXMSGSIZE, MAX_FRAME)
    return sock


def open_sockets(fake):
    """Publisher and sink on fresh ports (bound before the old ones close, so they differ),
    then Pupil Remote on its fixed port."""
    pub, sink = new_socket(fake, zmq.PUB), new_socket(fake, zmq.SUB)
    sink.setsockopt(zmq.SUBSCRIBE, b"")
    pub_port, sink_port = bind(pub, 0), bind(sink, 0)
    close_sockets(fake)
    fake.pub, fake.sink, fake.pub_port, fake.sink_port = pub, sink, pub_port, sink_port
    fake.rep = new_socket(fake, zmq.REP)
    fake.rep_port = bind(fake.rep, fake.rep_port, retry_s=5.0)


def close_sockets(fake):
    for sock in (fake.rep, fake.pub, fake.sink):
        if sock is not None:
            sock.close(linger=0)
    fake.rep = fake.pub = fake.sink = None


def restart(fake, why):
    """As when Pupil Capture restarts: sockets recreated, deferred replies and samples not
    yet sent are lost, Pupil time starts again at a new offset."""
    fake.restart, fake.pending_t = False, None
    fake.restarts += 1
    open_sockets(fake)
    reset_time_base(fake, fake.args.time_offset + 1000.0 * fake.restarts)
    log("restart (%s): Pupil Remote %d, SUB_PORT %d, PUB_PORT %d, time offset %r"
        % (why, fake.rep_port, fake.pub_port, fake.sink_port, fake.offset))


def serve(fake, wake):
    while not fake.stop:
        now = now_ns()
        if fake.end_ns and now >= fake.end_ns:
            return
        if fake.drop_at and now >= fake.drop_at:
            fake.drop_at = None
            restart(fake, "--drop-after")
        if fake.restart:
            restart(fake, "SIGUSR1")
        if fake.pending_t is not None and now_ns() >= fake.pending_t:
            reply_time(fake)
        flooding = fake.flood is not None and fake.flood[0] <= now < fake.flood[1]
        if flooding:
            flood_batch(fake)
        elif fake.flood is not None and now >= fake.flood[1]:
            end_flood(fake)
        if not flooding and now_ns() - send_ns(fake, fake.n) > 1e9:   # stalled for a second: resync, no burst
            log("stalled; skipping ahead")
            fake.origin_ns, fake.origin_n = now_ns(), fake.n
        while not flooding and now_ns() >= send_ns(fake, fake.n):
            publish_sample(fake)
        poller = zmq.Poller()
        poller.register(wake, zmq.POLLIN)
        poller.register(fake.sink, zmq.POLLIN)
        if fake.pending_t is None:   # a REP socket takes no new request before it replies
            poller.register(fake.rep, zmq.POLLIN)
        deadlines = [d for d in (send_ns(fake, fake.n), fake.pending_t, fake.drop_at, fake.end_ns) if d]
        if fake.flood is not None:
            deadlines.append(fake.flood[0] if not flooding else flood_next_ns(
                fake.args.flood_rate, fake.flood_started_ns, fake.flood_sent, FLOOD_BATCH))
        wait = min(deadlines) - now_ns()
        events = dict(poller.poll(min(100, max(0, wait // 1_000_000))))
        if not events and 0 < wait < 1_000_000:   # zmq polls in whole ms: sleep the rest
            time.sleep(wait / 1e9)
        if wake in events:
            try:
                while os.read(wake, 4096):
                    pass
            except BlockingIOError:
                pass
        if fake.rep in events:
            serve_rep(fake)
        if fake.sink in events:
            drain_sink(fake)


def parse_args(argv):
    p = argparse.ArgumentParser(description="Fake Pupil Capture Network API (Pupil Remote + PUB) for tests.")
    opt = p.add_argument
    opt("--port", type=int, default=0,
        help="Pupil Remote (REP) port on 127.0.0.1 (0 = ephemeral); kept across restarts")
    opt("--ready-file", help="write the Pupil Remote port here (atomically) once all sockets are bound")
    opt("--rate", type=float, default=200.0, help="samples per second (default 200)")
    opt("--time-offset", type=float, default=5000.0, help="Pupil time at start, s (default 5000)")
    opt("--drift-ppm", type=float, default=30.0, help="Pupil clock rate error, ppm (default 30)")
    opt("--latency-ms", type=float, default=0.0, metavar="L",
        help="send each sample L ms after its capture time (its timestamp) (default 0)")
    opt("--t-reply-delay-ms", type=float, default=0.0, metavar="D",
        help='wait D ms before reading the clock for a "t" reply (default 0)')
    opt("--t-jitter-ms", type=float, default=0.0, metavar="J",
        help='plus a random extra wait uniform in [0, J] ms before a "t" reply (default 0)')
    opt("--surface-name", default="screen", help='surface name; topic "surfaces.NAME" (default screen)')
    opt("--no-surface", action="store_true", help="publish gaze only, no surface data")
    opt("--pupil-version", default="3.5.7", help='reply to "v" (default 3.5.7)')
    opt("--truth", help="ground-truth CSV, one flushed line per sample published")
    opt("--malformed-every", type=int, default=0, metavar="N",
        help="after every N-th sample publish one malformed message (0 = never)")
    opt("--drop-after", type=float, default=0.0, metavar="S",
        help="simulate a Pupil Capture restart (as SIGUSR1) once, S s after start (0 = never)")
    add_flood_options(opt, "start", "publish as fast as it goes, each sample stamped with Pupil time as it "
                      "is sent")
    opt("--future-ms", type=float, default=0.0, metavar="F",
        help="send the last 20 of every 100 samples early, the k-th F*k/20 ms before its own "
             "timestamp (default 0: never)")
    opt("--duration", type=float, default=0.0, metavar="S",
        help="exit 0 after S seconds (0 = run until SIGTERM/SIGINT)")
    opt("--seed", type=int, default=0, help="seed for the jitter and garbage bytes (default 0)")
    args = p.parse_args(argv)
    delays = (args.latency_ms, args.t_reply_delay_ms, args.t_jitter_ms, args.future_ms)
    if args.rate <= 0 or args.malformed_every < 0 or min(delays) < 0 or args.flood_rate < 0:
        p.error("--rate must be > 0; --malformed-every and the delays must be >= 0")
    return args


def main(argv=None):
    args = parse_args(argv)
    # The wakeup pipe makes the poll return as soon as a signal arrives.
    wake, wake_w = os.pipe2(os.O_NONBLOCK | os.O_CLOEXEC)
    signal.set_wakeup_fd(wake_w)
    truth = open(args.truth, "w") if args.truth else None
    fake = Fake(args, truth)
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: setattr(fake, "stop", True))
    signal.signal(signal.SIGUSR1, lambda *_: setattr(fake, "restart", True))
    try:
        fake.rep_port = args.port
        open_sockets(fake)
        reset_time_base(fake, args.time_offset)   # first sample at the time we are ready
        if truth:
            truth.write(TRUTH_HEADER)
            truth.flush()
        if args.ready_file:
            write_ready_file(args.ready_file, fake.rep_port)
        log("Pupil Remote on 127.0.0.1:%d, SUB_PORT %d, PUB_PORT %d"
            % (fake.rep_port, fake.pub_port, fake.sink_port))
        serve(fake, wake)
    finally:
        if args.future_ms > 0:
            log("sent %d samples early, up to %.1f ms before their time" % (fake.early_sent, fake.max_early_ms))
        if truth:
            truth.write("# malformed %d\n" % fake.malformed)
            truth.close()
        close_sockets(fake)
        fake.ctx.term()
    return 0


if __name__ == "__main__":
    sys.exit(main())
