# SPDX-License-Identifier: Apache-2.0
"""What the fake trackers (fake_gazepoint.py, fake_pupil_capture.py) share: the host clock they
stamp their ground truth with (the daemon's CLOCK_MONOTONIC), the ready file a test waits for, and
their log lines on stderr."""

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
