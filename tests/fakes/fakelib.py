# SPDX-License-Identifier: Apache-2.0
"""What the fake trackers (fake_gazepoint.py, fake_pupil_capture.py) share: the host clock they
stamp their ground truth with (the daemon's CLOCK_MONOTONIC), the ready file a test waits for,
their log lines on stderr, and their --flood option."""

import argparse
import os
import sys
import time


def now_ns():
    return time.clock_gettime_ns(time.CLOCK_MONOTONIC)


def write_ready_file(path, port):
    tmp = "%s.tmp.%d" % (path, os.getpid())
    with open(tmp, "w") as f:
        f.write("%d\n" % port)
    os.replace(tmp, path)   # atomic: a reader never sees a partial file


def make_log(name):
    def log(msg):
        print(name + ": " + msg, file=sys.stderr, flush=True)
    return log


def parse_flood(text):
    """--flood START,LEN: seconds, START >= 0, LEN > 0."""
    start, sep, length = text.partition(",")
    try:
        start, length = float(start), float(length)
    except ValueError:
        start = length = -1
    if not sep or start < 0 or length <= 0:
        raise argparse.ArgumentTypeError("expected START,LEN in seconds, e.g. 2,3")
    return start, length


def flood_due(rate, start_ns, sent, batch):
    """How many flood messages to send now: a batch, or with a rate (per second, 0: none) what is
    due since start_ns, at most a batch."""
    if not rate:
        return batch
    return min(batch, int((now_ns() - start_ns) * 1e-9 * rate) - sent)


def flood_next_ns(rate, start_ns, sent, batch):
    """When to send flood messages next: now, or with a rate when a quarter batch is due."""
    if not rate:
        return now_ns()
    return start_ns + (sent + max(1, batch // 4)) / rate * 1e9


def add_flood_options(opt, when, what):
    """--flood START,LEN and --flood-rate N, in the words of a fake: `when` the flood's clock starts
    ("ENABLE_SEND_DATA", "start"), `what` it sends ("records", "samples") and how (its help)."""
    opt("--flood", type=parse_flood, metavar="START,LEN",
        help="from START to START+LEN s after %s, %s; not in the truth" % (when, what))
    opt("--flood-rate", type=float, default=0.0, metavar="N",
        help="messages per second while flooding (default 0: as fast as they go)")
