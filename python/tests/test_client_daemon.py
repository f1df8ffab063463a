# SPDX-License-Identifier: Apache-2.0
"""GazeClient against a real fovea-trackerd (synthetic source), cross-checked with fovea-ctl.

Needs $FOVEA_TRACKERD (and $FOVEA_CTL for the cross-checks); skipped without them.
"""

import os
import socket
import subprocess
import sys
import threading
import time
import unittest
from pathlib import Path

from fovea import protocol
from fovea.client import GazeClient, monotonic_ns, query_status

TRACKERD = os.environ.get("FOVEA_TRACKERD", "")
CTL = os.environ.get("FOVEA_CTL", "")
ALL_STREAMS = protocol.STREAM_SAMPLES | protocol.STREAM_EVENTS | protocol.STREAM_MARKERS


def free_udp_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Daemon:
    """fovea-trackerd --source synthetic on a loopback port, stopped with SIGTERM."""

    def __init__(self, port, duration=60):
        self.port = port
        self.proc = subprocess.Popen([TRACKERD, "--source", "synthetic", "--port", str(port), "--control-socket",
                                      "none", "--duration", str(duration), "--log-level", "warn"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        deadline = time.monotonic() + 5
        while query_status("127.0.0.1", port, 0.1) is None:
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise RuntimeError(f"fovea-trackerd did not answer on port {port}: {self.proc.stderr.read()!r}")

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.proc.stderr.close()


def wait_for(predicate, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()


class CtlWatch:
    """`fovea-ctl watch --events-only` (events and markers), its output collected line by line."""

    def __init__(self, port):
        self.proc = subprocess.Popen([CTL, "--server", f"127.0.0.1:{port}", "watch", "--events-only",
                                      "--duration", "30"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True)
        self.lines = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.proc.stdout:
            self.lines.append(line)

    def text(self):
        return "".join(self.lines)

    def wait_for(self, text, timeout):
        return wait_for(lambda: any(text in line for line in list(self.lines)), timeout)

    def stop(self):
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.reader.join(5)
        self.proc.stdout.close()


@unittest.skipUnless(TRACKERD and os.access(TRACKERD, os.X_OK), "FOVEA_TRACKERD (path of fovea-trackerd) not set")
class AgainstDaemon(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.port = free_udp_port()
        cls.daemon = Daemon(cls.port)

    @classmethod
    def tearDownClass(cls):
        cls.daemon.stop()

    def client(self, **kwargs):
        c = GazeClient("127.0.0.1", self.port, name="python unittest", **kwargs)
        self.addCleanup(c.close)
        self.assertTrue(c.wait_subscribed(3.0), "no SUBSCRIBED within 3 s")
        return c

    def test_status(self):
        reply = query_status("127.0.0.1", self.port, 1.0)
        self.assertIsNotNone(reply)
        self.assertIn("synthetic", reply.source)
        self.assertEqual(reply.nominal_rate_hz, 250.0)
        self.assertEqual(reply.display, protocol.DisplayGeometry())

    def test_samples_arrive_with_contiguous_sequences(self):
        c = self.client()
        first = c.session.next_sample_sequence
        self.assertEqual(c.session.nominal_rate_hz, 250.0)
        time.sleep(1.2)
        samples = c.poll_samples()
        self.assertGreater(len(samples), 200)
        sequences = [a.sequence for _, a in samples]
        self.assertEqual(sequences, list(range(first, first + len(sequences))))
        times = [s.tracker_time_ns for s, _ in samples]
        self.assertEqual(times, sorted(times))
        self.assertEqual(c.latest(), c.latest_with_arrival()[0])
        stats = c.stats()
        self.assertEqual((stats.samples.lost, stats.samples.duplicated, stats.rejected), (0, 0, 0))
        self.assertEqual(stats.subscriptions, 1)

    def test_events_and_callbacks(self):
        got = {"samples": 0, "events": []}
        lock = threading.Lock()

        def on_sample(sample, arrival):
            with lock:
                got["samples"] += 1

        def on_event(event, arrival):
            with lock:
                got["events"].append(event)

        c = self.client(on_sample=on_sample, on_event=on_event, provisional=True)
        self.assertTrue(wait_for(lambda: len(got["events"]) >= 3, 5.0), "fewer than 3 events in 5 s")
        with lock:
            self.assertGreater(got["samples"], 0)
            finals = [e for e in got["events"] if not e.provisional]
        self.assertTrue(finals)
        self.assertTrue(all(e.kind != protocol.EyeMovement.UNKNOWN for e in finals))
        stats = c.stats()
        self.assertEqual(stats.events.lost, 0)
        self.assertEqual(stats.events.received + stats.provisional.received, len(c.poll_events()))

    def test_time_sync_on_one_machine_is_near_zero(self):
        c = self.client()
        self.assertTrue(c.wait_clock(2.0))
        stats = c.stats()
        self.assertGreaterEqual(stats.clock_round_trip_ns, 0)
        # Zero within the exchange's bound, half its round trip (1 ms when that was short).
        self.assertLessEqual(abs(stats.clock_offset_ns), max(1_000_000, stats.clock_round_trip_ns // 2 + 1000),
                             "one host, one CLOCK_MONOTONIC")
        sample, arrival = wait_for(c.latest_with_arrival, 2.0) and c.latest_with_arrival()
        self.assertLess(abs(c.to_client_ns(sample.tracker_time_ns) - monotonic_ns()), 1_000_000_000)
        self.assertLess(arrival.latency_ns, 100_000_000)

    def test_marker_round_trip_and_fovea_ctl_sees_it(self):
        watch = CtlWatch(self.port) if CTL else None
        try:
            if watch:
                # Its first event line shows it subscribed (a fixed pause was too short under ASan).
                self.assertTrue(watch.wait_for("EVENT", 10.0), f"fovea-ctl watch printed no event: {watch.text()!r}")
            self.check_marker_round_trip()
            if watch:
                for label in ('MARKER "python: stimulus on"', 'MARKER "flip"'):
                    self.assertTrue(watch.wait_for(label, 5.0), f"{label} not in {watch.text()!r}")
        finally:
            if watch:
                watch.stop()

    def check_marker_round_trip(self):
        c = self.client(streams=ALL_STREAMS)
        marker_id = c.mark("python: stimulus on")
        back = c.wait_marker(marker_id, 2.0)
        self.assertIsNotNone(back, "the marker did not come back on the marker stream")
        self.assertEqual((back.label, back.session_id, back.flags), ("python: stimulus on", 0, 0))
        self.assertEqual(back.time_ns, back.received_ns)
        self.assertTrue(c.wait_clock(2.0, exchanges=4))
        self.assertGreaterEqual(c._clock.accepted, 4)
        with self.assertRaises(ValueError):
            c.wait_clock(1.0, exchanges=0)
        flip = monotonic_ns() - 20_000_000
        back = c.wait_marker(c.mark("flip", client_time_ns=flip), 2.0)
        self.assertTrue(back.client_time)
        self.assertLess(abs(c.to_client_ns(back.time_ns) - flip), 1_000_000)
        self.assertEqual(c.stats().markers_confirmed, 2)
        with self.assertRaises(ValueError):
            c.mark("two\nlines")

    @unittest.skipUnless(CTL, "FOVEA_CTL (path of fovea-ctl) not set")
    def test_a_marker_sent_by_fovea_ctl_reaches_the_client(self):
        labels = []
        c = self.client(streams=ALL_STREAMS, on_marker=lambda m, a: labels.append(m.label))
        done = subprocess.run([CTL, "--server", f"127.0.0.1:{self.port}", "mark", "from fovea-ctl"],
                              capture_output=True, text=True, timeout=10)
        self.assertEqual(done.returncode, 0, done.stdout + done.stderr)
        self.assertTrue(wait_for(lambda: "from fovea-ctl" in labels, 2.0), labels)
        self.assertEqual(c.stats().markers.received, len(labels))

    def test_the_experiment_example_runs(self):
        example = Path(__file__).resolve().parents[1] / "examples" / "experiment.py"
        env = dict(os.environ, PYTHONPATH=str(example.parents[1]))
        done = subprocess.run([sys.executable, str(example), "--port", str(self.port), "--trials", "2"],
                              capture_output=True, text=True, env=env, timeout=30)
        self.assertEqual(done.returncode, 0, done.stdout + done.stderr)
        self.assertEqual(done.stdout.count("marker confirmed"), 2, done.stdout)

    def test_close_unsubscribes(self):
        before = query_status("127.0.0.1", self.port, 1.0).subscribers
        c = GazeClient("127.0.0.1", self.port)
        self.assertTrue(c.wait_subscribed(3.0))
        self.assertEqual(query_status("127.0.0.1", self.port, 1.0).subscribers, before + 1)
        c.close()
        self.assertTrue(wait_for(lambda: query_status("127.0.0.1", self.port, 1.0).subscribers == before, 1.0),
                        "the session outlived close(): no UNSUBSCRIBE?")


@unittest.skipUnless(TRACKERD and os.access(TRACKERD, os.X_OK), "FOVEA_TRACKERD (path of fovea-trackerd) not set")
class DaemonRestart(unittest.TestCase):
    def test_resubscribes_after_the_daemon_restarts_on_the_same_port(self):
        port = free_udp_port()
        daemon = Daemon(port)
        self.addCleanup(lambda: daemon.stop())
        with GazeClient("127.0.0.1", port) as c:
            self.assertTrue(c.wait_subscribed(3.0))
            first_session = c.session.session_id
            time.sleep(0.3)
            daemon.stop()
            self.assertTrue(wait_for(lambda: not c.subscribed, 3.0), "silence was not noticed")
            daemon = Daemon(port)
            self.assertTrue(c.wait_subscribed(5.0), "no resubscription after the restart")
            self.assertNotEqual(c.session.session_id, first_session)
            c.poll_samples()
            time.sleep(0.5)
            after = c.poll_samples()
            self.assertGreater(len(after), 50)
            sequences = [a.sequence for _, a in after]
            self.assertEqual(sequences, list(range(sequences[0], sequences[0] + len(sequences))))
            stats = c.stats()
            self.assertEqual(stats.subscriptions, 2)
            self.assertEqual(stats.samples.duplicated, 0)
            self.assertLess(sequences[0], 1000, "the new daemon numbers from 0 again")


if __name__ == "__main__":
    unittest.main()
