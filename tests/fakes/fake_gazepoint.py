#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Fake Gazepoint "Open Gaze API" v2 server (GP3 eye tracker) for integration tests.

Written from the public API description: single-line XML elements ending in "\\r\\n"
over TCP; the client sends <SET ID=".." STATE=".." /> and <GET ID=".." />, the server
answers <ACK .../> or <NACK .../> and, once ENABLE_SEND_DATA is 1, streams one
<REC .../> per sample period. The gaze follows a known trajectory of the counter CNT
and the tracker clock has a known offset and drift, so a test can compare what the
daemon reports with the ground-truth CSV written by --truth.

How tests use it: start it in the background with --port 0 --ready-file R --truth T.csv
(plus --rate, --malformed-every N, --drop-after S as needed); wait for R, read the port
from it and point the daemon at 127.0.0.1:PORT; read T.csv while it runs (one flushed
line per record); SIGUSR1 forces a disconnect; SIGTERM stops it (exit 0, T.csv then
ends with "# malformed N"). Standard library only; one client at a time, others wait.

--flood START,LEN makes it a server gone wrong: from START to START+LEN seconds after
ENABLE_SEND_DATA it writes records as fast as the client takes them (or --flood-rate N a
second), TIME advancing one declared period per record (as a server looping over its buffer
would), then goes back to its pace and its real clock. Flood records are not in the truth;
the log says how many.
"""
import argparse
import math
import re
import select
import signal
import socket
import sys

from fakelib import add_flood_options, flood_due, flood_next_ns, make_log, now_ns, write_ready_file

log = make_log("fake_gazepoint")

EYE_DISPARITY = 0.01  # each eye's point this far (screen widths) left and right of the best point
ENABLE_IDS = tuple("ENABLE_SEND_" + n for n in (
    "DATA COUNTER TIME TIME_TICK POG_FIX POG_BEST POG_LEFT POG_RIGHT "
    "PUPIL_LEFT PUPIL_RIGHT EYE_LEFT EYE_RIGHT").split())
TICK_FREQ = 10_000_000
MAX_LINE = 64 * 1024     # longest command line we buffer; longer ones are dropped
MAX_OUTBUF = 1 << 20     # a client that stops reading is disconnected, not buffered forever
FLOOD_HIGH = 256 * 1024  # --flood: write more only while less than this waits for the client
FLOOD_BATCH = 256        # records per write while flooding
FIX_LEN = 30             # samples per synthetic fixation
TRUTH_HEADER = "cnt,host_send_ns,tracker_time_s,bpogx,bpogy,bpogv\n"
MALFORMED_KINDS = ("unterminated", "nan", "missing_bpogy", "garbage", "out_of_range", "abc", "long_line")

CMD_RE = re.compile(r"<\s*(SET|GET)\b([^>]*)>")
ID_RE = re.compile(r'\bID\s*=\s*"([^"]*)"')
STATE_RE = re.compile(r'\bSTATE\s*=\s*"([^"]*)"')


class Server:
    """Process-wide state. Signal handlers only set stop/drop; the loops act on them."""

    def __init__(self, args, wake, truth):
        self.args, self.wake, self.truth = args, wake, truth
        self.start_ns = now_ns()
        self.end_ns = self.start_ns + args.duration * 1e9 if args.duration > 0 else None
        self.stop = self.drop = False
        self.malformed = 0


class Client:
    """Per-connection state: a new connection starts from scratch."""

    def __init__(self, sock):
        self.sock, self.inbuf, self.outbuf = sock, b"", b""
        self.discarding = False      # inside an over-long line, skip to its end
        self.enabled = dict.fromkeys(ENABLE_IDS, 0)
        self.cnt = self.malformed_idx = 0
        # Absolute CLOCK_MONOTONIC deadlines; next_ns is a float so period rounding never accumulates.
        self.next_ns = self.drop_at = None
        self.long_sent, self.last_fields = False, []
        self.held = []   # --burst: records taken, not yet written
        self.data_start_ns = None        # when ENABLE_SEND_DATA was set
        self.flood_t = None              # --flood: the TIME of the next flood record, while flooding
        self.flood_sent = self.flood_start_ns = 0


class Closed(Exception):
    """The connection is over (peer closed, error, or we drop it)."""


def element(tag, fields):
    return ("<%s%s />\r\n" % (tag, "".join(' %s="%s"' % kv for kv in fields))).encode("ascii")


def gaze(cnt):
    phase = 2 * math.pi * cnt / 300
    return 0.5 + 0.3 * math.cos(phase), 0.5 + 0.2 * math.sin(phase)


def tracker_time(srv, host_ns):
    a = srv.args
    return (host_ns - srv.start_ns) * 1e-9 * (1 + a.drift_ppm * 1e-6) + a.time_offset


def record_fields(client, rate, t):
    """Fields of one REC in protocol order, plus the BPOG values for the truth file."""
    on, cnt = client.enabled, client.cnt
    x, y = gaze(cnt)
    valid = not 20 <= cnt % 50 <= 24   # a blink-like gap every 50 samples
    best = ("%.5f" % x, "%.5f" % y, "1") if valid else ("0.00000", "0.00000", "0")
    pupil = "%.5f" % (24.0 + math.sin(cnt / 20))
    f = []
    if on["ENABLE_SEND_COUNTER"]:
        f.append(("CNT", str(cnt)))
    if on["ENABLE_SEND_TIME"]:
        f.append(("TIME", "%.5f" % t))
    if on["ENABLE_SEND_TIME_TICK"]:
        f.append(("TIME_TICK", str(round(t * TICK_FREQ))))
    if on["ENABLE_SEND_POG_FIX"]:
        dur = (cnt % FIX_LEN) / rate
        f += [("FPOGX", "%.5f" % x), ("FPOGY", "%.5f" % y), ("FPOGS", "%.5f" % (t - dur)),
              ("FPOGD", "%.5f" % dur), ("FPOGID", str(cnt // FIX_LEN)), ("FPOGV", "1")]
    if on["ENABLE_SEND_POG_BEST"]:
        f += [("BPOGX", best[0]), ("BPOGY", best[1]), ("BPOGV", best[2])]
    # Each eye's point: EYE_DISPARITY either side of the best point (its mean), valid with it.
    for side, sign in (("LEFT", -1), ("RIGHT", 1)):
        if on["ENABLE_SEND_POG_" + side]:
            ex = "%.5f" % (x + sign * EYE_DISPARITY) if valid else "0.00000"
            f += [(side[0] + "POGX", ex), (side[0] + "POGY", best[1]), (side[0] + "POGV", best[2])]
    for side, cx in (("LEFT", "0.40000"), ("RIGHT", "0.60000")):
        if on["ENABLE_SEND_PUPIL_" + side]:
            s = side[0]
            f += [(s + "PCX", cx), (s + "PCY", "0.50000"), (s + "PD", pupil),
                  (s + "PS", "1.0"), (s + "PV", "1")]
    return f, best


def with_value(fields, key, value):
    """Copy of fields with key set to value (appended if absent)."""
    out = [(k, value if k == key else v) for k, v in fields]
    return out if any(k == key for k, _ in fields) else out + [(key, value)]


def next_malformed(client):
    """The next hostile line in the cycle; the 100000-'A' line only once per connection."""
    while True:
        kind = MALFORMED_KINDS[client.malformed_idx % len(MALFORMED_KINDS)]
        client.malformed_idx += 1
        if kind != "long_line" or not client.long_sent:
            break
    base = client.last_fields   # same CNT/TIME as the real record: a lenient client shows a duplicate
    bad = {"nan": "nan", "abc": "abc", "out_of_range": "1e308"}
    if kind in bad:
        return element("REC", with_value(base, "BPOGX", bad[kind]))
    if kind == "missing_bpogy":
        return element("REC", [kv for kv in with_value(base, "BPOGX", "0.50000") if kv[0] != "BPOGY"])
    if kind == "unterminated":
        return b'<REC CNT="x" BPOGX="0.5"\r\n'
    if kind == "garbage":
        return b"garbage\x01\x02\r\n"
    client.long_sent = True
    return b"A" * 100000 + b"\r\n"


def send(client, data):
    """Queue and push what the socket takes now; never block the paced loop."""
    client.outbuf += data
    if len(client.outbuf) > MAX_OUTBUF:
        raise Closed("client stopped reading")
    try:
        sent = client.sock.send(client.outbuf)
    except (BlockingIOError, InterruptedError):
        sent = 0
    except OSError as e:
        raise Closed(str(e))
    client.outbuf = client.outbuf[sent:]


def handle_command(srv, client, line):
    m = CMD_RE.search(line)
    if not m:
        return   # not a command: ignore, like a tolerant server
    verb, attrs = m.groups()
    idm, stm = ID_RE.search(attrs), STATE_RE.search(attrs)
    ident = idm.group(1) if idm else ""
    if verb == "SET" and ident in ENABLE_IDS and stm and stm.group(1) in ("0", "1"):
        state = int(stm.group(1))
        if ident == "ENABLE_SEND_DATA" and state and not client.enabled[ident]:
            client.next_ns = float(now_ns())   # first record right away, then on the grid
            client.data_start_ns = client.next_ns
            if srv.args.drop_after > 0 and client.drop_at is None:
                client.drop_at = client.next_ns + srv.args.drop_after * 1e9
        client.enabled[ident] = state
        reply = ("ACK", [("ID", ident), ("STATE", str(state))])
    elif verb == "GET" and ident in ENABLE_IDS:
        reply = ("ACK", [("ID", ident), ("STATE", str(client.enabled[ident]))])
    elif verb == "GET" and ident == "SCREEN_SIZE":
        w, h = srv.args.screen
        reply = ("ACK", [("ID", ident), ("X", "0"), ("Y", "0"), ("WIDTH", str(w)), ("HEIGHT", str(h))])
    elif verb == "GET" and ident == "TIME_TICK_FREQUENCY":
        reply = ("ACK", [("ID", ident), ("FREQ", str(TICK_FREQ))])
    else:
        reply = ("NACK", [("ID", ident)])
    send(client, element(*reply))


def read_commands(srv, client):
    try:
        data = client.sock.recv(65536)
    except (BlockingIOError, InterruptedError):
        return
    except OSError as e:
        raise Closed(str(e))
    if not data:
        raise Closed("peer closed")
    client.inbuf += data
    while b"\n" in client.inbuf:
        line, client.inbuf = client.inbuf.split(b"\n", 1)
        if client.discarding:   # tail of an over-long line
            client.discarding = False
            continue
        handle_command(srv, client, line.rstrip(b"\r").decode("latin-1"))
    if len(client.inbuf) > MAX_LINE:   # bound memory: drop the line, skip to its newline
        client.inbuf, client.discarding = b"", True


def send_due_records(srv, client):
    args = srv.args
    while client.enabled["ENABLE_SEND_DATA"] and now_ns() >= client.next_ns:
        host_ns = now_ns()   # just before the write, as the daemon would timestamp it
        if host_ns - client.next_ns > 1e9:   # stalled for a second: resync instead of bursting
            client.next_ns = float(host_ns)
        if args.burst > 1:
            # A tracker whose transport batches: the record is taken on schedule and written
            # with the next ones, so its receive time lags its capture by up to burst-1 periods.
            host_ns = int(client.next_ns)
        t = tracker_time(srv, host_ns)
        fields, best = record_fields(client, args.rate, t)
        # The truth lists what was written: records still held when the connection ends never are.
        client.held.append((element("REC", fields), "%d,%d,%.5f,%s,%s,%s\n" % ((client.cnt, host_ns, t) + best)))
        if len(client.held) >= args.burst:
            send(client, b"".join(rec for rec, _ in client.held))
            if srv.truth:
                srv.truth.write("".join(line for _, line in client.held))
                srv.truth.flush()
            client.held = []
        client.last_fields = fields
        client.cnt += 1
        client.next_ns += 1e9 / args.rate
        if args.malformed_every and client.cnt % args.malformed_every == 0:
            send(client, next_malformed(client))
            srv.malformed += 1


def flood_window(srv, client):
    """(start, end) CLOCK_MONOTONIC ns of this connection's flood, or None."""
    if not srv.args.flood or client.data_start_ns is None:
        return None
    start = client.data_start_ns + srv.args.flood[0] * 1e9
    return start, start + srv.args.flood[1] * 1e9


def send_flood_records(srv, client):
    """One batch of flood records, if the client has taken the last ones."""
    rate = srv.args.rate
    if client.flood_t is None:
        client.flood_t, client.flood_start_ns = tracker_time(srv, now_ns()), now_ns()
        log("flooding: records %s, TIME one period (%.5f s) apart" % (
            "%g a second" % srv.args.flood_rate if srv.args.flood_rate else "as fast as the client takes them", 1 / rate))
    count = flood_due(srv.args.flood_rate, client.flood_start_ns, client.flood_sent, FLOOD_BATCH)
    if len(client.outbuf) >= FLOOD_HIGH or count <= 0:
        return
    # One template per batch: CNT and TIME change per record, the rest is the batch's first record.
    fields, _ = record_fields(client, rate, client.flood_t)
    slots = {"CNT": "{cnt}", "TIME": "{t:.5f}", "TIME_TICK": "{tick}"}
    template = element("REC", [(k, slots.get(k, v)) for k, v in fields]).decode("ascii")
    batch = []
    for _ in range(count):
        t = client.flood_t
        batch.append(template.format(cnt=client.cnt, t=t, tick=round(t * TICK_FREQ)))
        client.cnt += 1
        client.flood_t += 1 / rate
    client.flood_sent += count
    send(client, "".join(batch).encode("ascii"))


def end_flood(client):
    seconds = (now_ns() - client.flood_start_ns) / 1e9
    log("flood over: %d records in %.2f s (%.0f/s); back to the pace and the real clock"
        % (client.flood_sent, seconds, client.flood_sent / max(seconds, 1e-9)))
    client.flood_t = None
    client.next_ns = float(now_ns())


def wait(srv, rlist, wlist, deadlines):
    """select() until a socket is ready, the earliest deadline passes, or a signal arrives."""
    deadlines = [d for d in deadlines + [srv.end_ns] if d is not None]
    timeout = max(0, min(deadlines) - now_ns()) / 1e9 if deadlines else None
    r, w, _ = select.select(rlist + [srv.wake], wlist, [], timeout)
    if srv.wake in r:
        try:
            while srv.wake.recv(4096):
                pass
        except OSError:   # drained
            pass
    return r, w


def serve_client(srv, client):
    """Serve one connection; returns at stop or --duration, raises Closed when it ends."""
    while not srv.stop:
        if srv.drop:
            raise Closed("SIGUSR1")
        data_at = client.next_ns if client.enabled["ENABLE_SEND_DATA"] else None
        flood = flood_window(srv, client)
        flooding = flood is not None and flood[0] <= now_ns() < flood[1] and client.enabled["ENABLE_SEND_DATA"]
        if flooding:   # more as soon as the client has taken some (and --flood-rate allows); the pace after
            data_at = flood[1] if len(client.outbuf) >= FLOOD_HIGH else (
                now_ns() if client.flood_t is None else
                flood_next_ns(srv.args.flood_rate, client.flood_start_ns, client.flood_sent, FLOOD_BATCH))
        r, w = wait(srv, [client.sock], [client.sock] if client.outbuf else [], [data_at, client.drop_at])
        if client.sock in r:
            read_commands(srv, client)
        if w:
            send(client, b"")
        now = now_ns()
        if srv.end_ns and now >= srv.end_ns:
            return
        if client.drop_at and now >= client.drop_at:
            raise Closed("--drop-after")
        if flooding and now < flood[1]:
            send_flood_records(srv, client)
            continue
        if client.flood_t is not None:
            end_flood(client)
        send_due_records(srv, client)


def serve(srv, listener):
    while not srv.stop and not (srv.end_ns and now_ns() >= srv.end_ns):
        if listener not in wait(srv, [listener], [], [])[0]:
            continue
        try:
            sock, peer = listener.accept()
        except OSError:   # the client gave up between select() and accept()
            continue
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)   # records are latency-sensitive
        srv.drop = False   # a SIGUSR1 while idle must not drop the next client
        log("client %s:%d connected" % peer)
        try:
            serve_client(srv, Client(sock))
        except Closed as e:
            log("client closed: %s" % e)
        sock.close()


def parse_screen(text):
    w, sep, h = text.lower().partition("x")
    if not (sep and w.isdigit() and h.isdigit()):
        raise argparse.ArgumentTypeError("expected WxH, e.g. 1920x1080")
    return int(w), int(h)


def parse_args(argv):
    p = argparse.ArgumentParser(description="Fake Gazepoint Open Gaze API v2 server for tests.")
    opt = p.add_argument
    opt("--port", type=int, default=0, help="TCP port on 127.0.0.1 (0 = ephemeral)")
    opt("--ready-file", help="write the bound port here (atomically) once listening")
    opt("--rate", type=float, default=150.0, help="records per second (default 150)")
    opt("--screen", type=parse_screen, default=(1920, 1080), metavar="WxH",
        help="screen size reported by GET SCREEN_SIZE (default 1920x1080)")
    opt("--time-offset", type=float, default=1000.0, help="tracker TIME at fake start, s (default 1000)")
    opt("--drift-ppm", type=float, default=50.0, help="tracker clock rate error, ppm (default 50)")
    opt("--truth", help="ground-truth CSV, one flushed line per record sent")
    opt("--malformed-every", type=int, default=0, metavar="N",
        help="after every N-th record send one malformed line (0 = never)")
    opt("--drop-after", type=float, default=0.0, metavar="S",
        help="close the connection S s after ENABLE_SEND_DATA is set (0 = never)")
    opt("--burst", type=int, default=1, metavar="N",
        help="write records N at a time, each stamped when it was taken: the truth's host_send_ns is "
             "then the capture time, and the receive delay grows to N-1 periods (default 1)")
    add_flood_options(opt, "ENABLE_SEND_DATA", "write records as fast as the client takes them, TIME one "
                      "period apart (a looping server)")
    opt("--duration", type=float, default=0.0, metavar="S",
        help="exit 0 after S seconds (0 = run until SIGTERM/SIGINT)")
    args = p.parse_args(argv)
    if args.rate <= 0 or args.malformed_every < 0 or args.burst < 1 or args.flood_rate < 0:
        p.error("--rate must be > 0, --malformed-every and --flood-rate >= 0 and --burst >= 1")
    return args


def main(argv=None):
    args = parse_args(argv)
    # The wakeup socket makes select() return as soon as a signal arrives.
    wake, wake_w = socket.socketpair()
    for s in (wake, wake_w):
        s.setblocking(False)
    signal.set_wakeup_fd(wake_w.fileno())
    truth = open(args.truth, "w") if args.truth else None
    srv = Server(args, wake, truth)
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: setattr(srv, "stop", True))
    signal.signal(signal.SIGUSR1, lambda *_: setattr(srv, "drop", True))
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    listener.bind(("127.0.0.1", args.port))
    listener.listen(8)   # clients arriving while one is served wait here
    listener.setblocking(False)
    if truth:
        truth.write(TRUTH_HEADER)
        truth.flush()
    port = listener.getsockname()[1]
    if args.ready_file:
        write_ready_file(args.ready_file, port)
    log("listening on 127.0.0.1:%d" % port)
    try:
        serve(srv, listener)
    finally:
        if truth:
            truth.write("# malformed %d\n" % srv.malformed)
            truth.close()
        listener.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
