# SPDX-License-Identifier: Apache-2.0
"""Command line: python3 -m fovea {status,watch,info} (a small subset of fovea-ctl, for checking a setup)."""

from __future__ import annotations

import argparse
import sys
import time
from typing import List, Optional

from . import protocol
from .client import GazeClient, query_status
from .recording import read_recording


def _server(text: str) -> tuple:
    host, _, port = text.rpartition(":")
    return (host or "127.0.0.1", int(port))


def _status(args: argparse.Namespace) -> int:
    reply = query_status(*args.server, timeout=2.0)
    if reply is None:
        print(f"no answer from {args.server[0]}:{args.server[1]}", file=sys.stderr)
        return 1
    print(f"source      {reply.source} ({reply.source_state.name.lower()})")
    print(f"rate        {reply.nominal_rate_hz:g} Hz (nominal)")
    print(f"uptime      {reply.uptime_ns / 1e9:.1f} s")
    print(f"published   {reply.samples_published} samples, {reply.events_published} events")
    print(f"subscribers {reply.subscribers}")
    return 0


def _watch(args: argparse.Namespace) -> int:
    streams = protocol.STREAM_EVENTS | protocol.STREAM_MARKERS
    if not args.events_only:
        streams |= protocol.STREAM_SAMPLES
    with GazeClient(*args.server, streams=streams, name="python -m fovea watch") as client:
        if not client.wait_subscribed(3.0):
            print(f"no subscription from {args.server[0]}:{args.server[1]}", file=sys.stderr)
            return 1
        end = time.monotonic() + args.duration if args.duration else float("inf")
        while time.monotonic() < end:
            for sample, a in client.poll_samples():
                print(f"SAMPLE seq {a.sequence} x {sample.x:.4f} y {sample.y:.4f} {sample.state.name.lower()}"
                      f"{'' if sample.valid else ' (invalid)'}")
            for item, a in client.poll_events():
                if isinstance(item, protocol.Marker):
                    print(f"MARKER seq {a.sequence} {item.label!r} at {item.time_ns}")
                else:
                    print(f"EVENT seq {a.sequence} {item.kind.name.lower()} {item.phase.name.lower()} "
                          f"at ({item.centroid_x:.3f}, {item.centroid_y:.3f})")
            time.sleep(0.02)
        s = client.stats()
        print(f"summary samples={s.samples.received} lost={s.samples.lost} events={s.events.received} "
              f"markers={s.markers.received} subscriptions={s.subscriptions}")
    return 0


def _info(args: argparse.Namespace) -> int:
    try:
        rec = read_recording(args.file)
    except (OSError, ValueError) as e:
        print(f"fovea info: {e}", file=sys.stderr)
        return 1
    h = rec.header
    print(f"device      {h.device}")
    print(f"display     {h.display.width_px}x{h.display.height_px}, {h.display.width_m * 1000:.1f}x"
          f"{h.display.height_m * 1000:.1f} mm at {h.display.viewing_distance_m * 1000:.1f} mm")
    print(f"rate        {h.nominal_rate_hz:g} Hz (nominal)")
    print(f"samples     {sum(1 for _ in rec.samples())}")
    print(f"events      {sum(1 for _ in rec.events())}")
    print(f"markers     {sum(1 for _ in rec.markers())}")
    print(f"integrity   {rec.report.describe()}")
    return 0


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python3 -m fovea", description=__doc__)
    parser.add_argument("--server", type=_server, default=("127.0.0.1", protocol.DEFAULT_PORT), help="HOST:PORT")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("status", help="print the daemon's status").set_defaults(run=_status)
    watch = sub.add_parser("watch", help="print samples, events and markers")
    watch.add_argument("--duration", type=float, default=0.0, help="seconds (default: until Ctrl-C)")
    watch.add_argument("--events-only", action="store_true")
    watch.set_defaults(run=_watch)
    info = sub.add_parser("info", help="describe a .fgr recording")
    info.add_argument("file")
    info.set_defaults(run=_info)
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
