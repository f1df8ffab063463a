#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""A gaze-contingent loop for experimenters: print fixations, and put a marker on the gaze clock at
each "stimulus".

Try it against the synthetic source:

    build/default/trackerd/fovea-trackerd --source synthetic --port 47870 &
    PYTHONPATH=python python3 python/examples/experiment.py --port 47870 --trials 5

Each trial waits for a fixation to start, "shows" a stimulus where the eyes are (here: prints it),
and sends a marker with the stimulus onset time on this host's CLOCK_MONOTONIC; fovea maps it to the
daemon's clock, so the marker lines up with the gaze samples in a `--record`ed .fgr file.
In a PsychoPy experiment the onset time would be the flip time (see python/README.md).
"""

import argparse
import queue
import sys
import time

import fovea
from fovea import protocol
from fovea.client import monotonic_ns


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, default=fovea.DEFAULT_PORT)
    p.add_argument("--trials", type=int, default=5)
    p.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for a fixation per trial")
    return p.parse_args()


def describe_fixation(event, display):
    px, py = display.to_pixels(event.centroid_x, event.centroid_y)
    what = f"fixation at ({px:.0f}, {py:.0f}) px = ({event.centroid_x_deg:+.1f}, {event.centroid_y_deg:+.1f}) deg"
    if event.phase == protocol.EventPhase.END:
        what += f", {event.duration_ns / 1e6:.0f} ms"
    return what


def run_trial(client, fixations, trial, timeout):
    """Waits for the next fixation onset, shows the stimulus there and marks its onset."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            event = fixations.get(timeout=0.1)
        except queue.Empty:
            continue
        print(f"trial {trial}: {describe_fixation(event, client.session.display)}")
        if event.phase != protocol.EventPhase.START:
            continue
        onset = monotonic_ns()  # with PsychoPy: the time win.flip() returned, on CLOCK_MONOTONIC
        marker_id = client.mark(f"trial {trial}: stimulus on", client_time_ns=onset)
        confirmed = client.wait_marker(marker_id, 2.0)
        print(f"trial {trial}: stimulus on, marker {'confirmed' if confirmed else 'NOT confirmed'}")
        return True
    print(f"trial {trial}: no fixation within {timeout:g} s", file=sys.stderr)
    return False


def main():
    args = parse_args()
    fixations = queue.Queue()

    def on_event(event, arrival):
        # Runs on the client's receive thread: hand over, do not work here.
        if event.kind == protocol.EyeMovement.FIXATION:
            fixations.put(event)

    streams = fovea.STREAM_SAMPLES | fovea.STREAM_EVENTS | fovea.STREAM_MARKERS
    with fovea.GazeClient(args.host, args.port, streams=streams, on_event=on_event, name="experiment.py") as client:
        if not client.wait_subscribed(3.0) or not client.wait_clock(2.0):
            sys.exit(f"no fovea-trackerd answering at {args.host}:{args.port}")
        ok = sum(run_trial(client, fixations, trial, args.timeout) for trial in range(1, args.trials + 1))
        stats = client.stats()
        print(f"{ok}/{args.trials} trials; {stats.samples.received} samples ({stats.samples.lost} lost), "
              f"{stats.markers_confirmed} markers confirmed, clock offset {stats.clock_offset_ns / 1e3:.1f} us")
    return 0 if ok == args.trials else 1


if __name__ == "__main__":
    sys.exit(main())
