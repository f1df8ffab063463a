# SPDX-License-Identifier: Apache-2.0
"""The codec against the golden vectors shared with the C++ tests, and its strictness.

The golden directory is $FOVEA_GOLDEN_DIR, else tests/data/golden of this checkout. The expected
field values are those of tests/support/canonical_messages.h.
"""

import math
import os
import struct
import unittest
from pathlib import Path

from fovea import protocol
from fovea.client import ClockSync, SequenceTracker
from fovea.protocol import (DecodeError, DisplayGeometry, ErrorCode, EventPhase, EyeData, EyeMovement, Header,
                            MessageType, ProtocolError, SourceState)

GOLDEN = Path(os.environ.get("FOVEA_GOLDEN_DIR", Path(__file__).resolve().parents[2] / "tests" / "data" / "golden"))
COOKIE = bytes(range(0xC0, 0xD0))
NONCE = 0x0123456789ABCDEF
SESSION = 0x1122334455667788


def header(seq, origin=1_000_000_000, send=1_000_250_000):
    return Header(seq, origin, send)


def canonical():
    """name -> Message, as tests/support/canonical_messages.h builds them."""
    p = protocol
    display = DisplayGeometry()
    sample = p.GazeSample(1_000_000_000, 0.5, 0.25, 0.0, -6.5625, 12.5, 0.75, EyeMovement.FIXATION, p.GAZE_VALID,
                          EyeData(3, 323.5, 214.0, 3.5, 0.25, -6.0), EyeData(1, 317.0, 214.0, 3.5, 0.0, 0.0))
    event = p.GazeEvent(EyeMovement.SACCADE, EventPhase.END, 0, 999_960_000, 40_000_000, 0.75, 0.5, 11.5, 0.0, 8.0,
                        350.0)
    provisional = p.GazeEvent(EyeMovement.SACCADE, EventPhase.START, p.EVENT_PROVISIONAL, 999_960_000, 0, 0.5, 0.5)
    return {
        "hello": p.Message(header(1), p.Hello(NONCE, "fovea-ctl watch")),
        "challenge": p.Message(header(1), p.Challenge(NONCE, COOKIE, 10000)),
        "subscribe": p.Message(header(2), p.Subscribe(COOKIE, NONCE, 3, 5000)),
        "subscribed": p.Message(header(2), p.Subscribed(SESSION, 3, 5000, 250.0, 1000, 20, display, 0xEFFF2F50,
                                                          47801, 1)),
        "heartbeat": p.Message(header(3), p.Heartbeat(SESSION, 5000)),
        "unsubscribe": p.Message(header(4), p.Unsubscribe(SESSION)),
        "gaze_sample": p.Message(header(1000), sample),
        "gaze_event": p.Message(header(20, origin=1_039_960_000), event),
        "status_request": p.Message(header(5), p.StatusRequest()),
        "status_reply": p.Message(header(5), p.StatusReply("replay:demo.fgr (x1, loop)", 250.0, 60_000_000_000,
                                                             15000, 800, 3, 2, SourceState.RUNNING, display)),
        "time_sync_request": p.Message(header(6), p.TimeSyncRequest(5_000_000_000)),
        "time_sync_reply": p.Message(header(6), p.TimeSyncReply(5_000_000_000, 1_000_100_000, 1_000_120_000)),
        "error": p.Message(header(2), p.Error(ErrorCode.BAD_COOKIE, MessageType.SUBSCRIBE, 1)),
        "control_request": p.Message(header(7), p.ControlRequest(p.ControlCommand.START_RECORDING,
                                                                   "/var/lib/fovea/session-01.fgr")),
        "control_reply": p.Message(header(7), p.ControlReply(p.ControlCommand.START_RECORDING, p.ControlResult.OK,
                                                               "recording to /var/lib/fovea/session-01.fgr")),
        "marker": p.Message(header(3), p.Marker(0, 0x0F0E0D0C0B0A0908, 1_000_000_000, 1_002_000_000,
                                                p.MARKER_CLIENT_TIME, "trial 7: stimulus on")),
        "gaze_eyes": p.Message(header(1000), p.GazeEyes(1_000_000_000,
                                                        p.EyeGaze(1, 0.46875, 0.25, -1.46875, -6.5625),
                                                        p.EyeGaze(1, 0.53125, 0.25, 1.46875, -6.5625))),
        "gaze_event_provisional": p.Message(header(7, origin=999_960_000, send=999_972_000), provisional),
        "gaze_event_retracted": p.Message(header(8, origin=999_960_000),
                                          protocol.replace(provisional, flags=p.EVENT_PROVISIONAL | p.EVENT_RETRACTED)),
    }


def golden(name):
    return bytes(int(token, 16) for token in (GOLDEN / f"{name}.hex").read_text().split())


class GoldenVectors(unittest.TestCase):
    def test_every_golden_file_is_covered(self):
        self.assertTrue(GOLDEN.is_dir(), f"golden directory {GOLDEN} missing (set FOVEA_GOLDEN_DIR)")
        self.assertEqual(sorted(p.stem for p in GOLDEN.glob("*.hex")), sorted(canonical()))

    def test_decode_gives_the_canonical_fields(self):
        for name, message in canonical().items():
            with self.subTest(name):
                self.assertEqual(protocol.decode(golden(name)), message)

    def test_encode_gives_the_golden_bytes(self):
        for name, message in canonical().items():
            with self.subTest(name):
                self.assertEqual(protocol.encode(message), golden(name))

    def test_payload_sizes_match_the_table(self):
        sizes = {1: 48, 2: 32, 3: 32, 4: 80, 5: 16, 6: 8, 7: 76, 8: 48, 9: 128, 10: 128, 11: 24, 12: 24, 13: 8,
                 14: 72, 15: 72, 16: 104, 17: 48}
        for t, size in sizes.items():
            self.assertEqual(protocol.payload_size(t), size)

    def test_a_flipped_structural_byte_is_rejected(self):
        data = golden("gaze_sample")
        for offset, mask, reason in ((0, 0x40, DecodeError.BAD_MAGIC), (4, 0x40, DecodeError.BAD_VERSION),
                                     (5, 0x40, DecodeError.UNKNOWN_TYPE), (5, 0x01, DecodeError.BAD_PAYLOAD_LENGTH),
                                     (6, 0x40, DecodeError.BAD_PAYLOAD_LENGTH), (64, 0x40, DecodeError.OUT_OF_RANGE),
                                     (65, 0x40, DecodeError.RESERVED_NOT_ZERO), (63, 0x40, DecodeError.OUT_OF_RANGE)):
            with self.subTest(offset=offset, mask=mask):
                bad = bytearray(data)
                bad[offset] ^= mask
                with self.assertRaises(ProtocolError) as e:
                    protocol.decode(bytes(bad))
                self.assertEqual(e.exception.reason, reason, str(e.exception))

    def test_every_single_byte_flip_is_rejected_or_changes_the_message(self):
        for name, message in canonical().items():
            data = golden(name)
            for i in range(len(data)):
                bad = bytearray(data)
                bad[i] ^= 0x01
                try:
                    self.assertNotEqual(protocol.decode(bytes(bad)), message, f"{name} byte {i}")
                except ProtocolError:
                    pass


class StrictDecoding(unittest.TestCase):
    def assertRejected(self, data, reason, offset, field):
        with self.assertRaises(ProtocolError) as e:
            protocol.decode(bytes(data))
        self.assertEqual((e.exception.reason, e.exception.offset, e.exception.field), (reason, offset, field),
                         str(e.exception))
        self.assertIn(field, str(e.exception))
        return e.exception

    def patched(self, name, offset, fmt, value):
        data = bytearray(golden(name))
        struct.pack_into("<" + fmt, data, offset, value)
        return data

    def test_lengths(self):
        data = golden("heartbeat")
        self.assertRejected(data[:31], DecodeError.TOO_SHORT, 31, "datagram")
        self.assertRejected(data[:-1], DecodeError.TOO_SHORT, 47, "datagram")
        self.assertRejected(data + b"\0", DecodeError.TOO_LONG, 48, "datagram")
        self.assertRejected(data + bytes(500), DecodeError.TOO_LONG, 512, "datagram")

    def test_header(self):
        self.assertRejected(self.patched("heartbeat", 5, "B", 18), DecodeError.UNKNOWN_TYPE, 5, "type")
        self.assertRejected(self.patched("heartbeat", 5, "B", 0), DecodeError.UNKNOWN_TYPE, 5, "type")

    def test_non_finite_floats(self):
        for value in (math.nan, math.inf, -math.inf):
            self.assertRejected(self.patched("gaze_sample", 40, "f", value), DecodeError.NON_FINITE, 40, "x")
        self.assertRejected(self.patched("subscribed", 80, "d", math.nan), DecodeError.NON_FINITE, 80,
                            "display.width_m")

    def test_ranges(self):
        cases = [
            ("gaze_sample", 60, "f", 1.5, DecodeError.OUT_OF_RANGE, "confidence"),
            ("gaze_sample", 56, "f", -1.0, DecodeError.OUT_OF_RANGE, "angular_velocity_deg_s"),
            ("gaze_sample", 76, "f", -0.5, DecodeError.OUT_OF_RANGE, "left.pupil_diameter_mm"),
            ("gaze_sample", 64, "B", 5, DecodeError.OUT_OF_RANGE, "state"),
            ("gaze_sample", 66, "B", 4, DecodeError.RESERVED_NOT_ZERO, "left.flags"),
            ("gaze_event", 32, "B", 0, DecodeError.OUT_OF_RANGE, "kind"),
            ("gaze_event", 33, "B", 3, DecodeError.OUT_OF_RANGE, "phase"),
            ("gaze_event", 34, "B", 2, DecodeError.OUT_OF_RANGE, "flags"),
            ("gaze_event", 34, "B", 4, DecodeError.RESERVED_NOT_ZERO, "flags"),
            ("gaze_event", 48, "q", -1, DecodeError.OUT_OF_RANGE, "duration_ns"),
            ("subscribe", 56, "I", 0, DecodeError.OUT_OF_RANGE, "streams"),
            ("subscribe", 56, "I", 0x20, DecodeError.OUT_OF_RANGE, "streams"),
            ("subscribed", 72, "I", 0, DecodeError.OUT_OF_RANGE, "display.width_px"),
            ("subscribed", 76, "I", 65537, DecodeError.OUT_OF_RANGE, "display.height_px"),
            ("subscribed", 96, "d", 100.5, DecodeError.OUT_OF_RANGE, "display.viewing_distance_m"),
            ("subscribed", 48, "d", -1.0, DecodeError.OUT_OF_RANGE, "nominal_rate_hz"),
            ("status_reply", 88, "q", -1, DecodeError.OUT_OF_RANGE, "uptime_ns"),
            ("status_reply", 124, "B", 3, DecodeError.OUT_OF_RANGE, "source_state"),
            ("error", 32, "H", 9, DecodeError.OUT_OF_RANGE, "code"),
            ("error", 34, "B", 18, DecodeError.OUT_OF_RANGE, "request_type"),
            ("control_request", 32, "B", 5, DecodeError.OUT_OF_RANGE, "command"),
            ("control_reply", 33, "B", 3, DecodeError.OUT_OF_RANGE, "result"),
            ("marker", 40, "Q", 0, DecodeError.OUT_OF_RANGE, "marker_id"),
            ("marker", 64, "B", 2, DecodeError.RESERVED_NOT_ZERO, "flags"),
            ("marker", 64, "B", 0, DecodeError.OUT_OF_RANGE, "time_ns"),  # own time clear: time must equal receipt
        ]
        for name, offset, fmt, value, reason, field in cases:
            with self.subTest(name=name, field=field, value=value):
                reported = 48 if (name, field) == ("marker", "time_ns") else offset
                self.assertRejected(self.patched(name, offset, fmt, value), reason, reported, field)

    def test_gaze_eyes_rules(self):
        # Flags beyond bit 0, reserved bytes, an invalid eye that is not all zero, neither eye valid.
        self.assertRejected(self.patched("gaze_eyes", 41, "B", 3), DecodeError.RESERVED_NOT_ZERO, 41, "right.flags")
        self.assertRejected(self.patched("gaze_eyes", 47, "B", 1), DecodeError.RESERVED_NOT_ZERO, 47, "reserved")
        self.assertRejected(self.patched("gaze_eyes", 40, "B", 0), DecodeError.OUT_OF_RANGE, 48, "left.x")
        no_eye = bytearray(golden("gaze_eyes"))
        no_eye[40:42] = bytes(2)
        no_eye[48:80] = bytes(32)
        self.assertRejected(no_eye, DecodeError.OUT_OF_RANGE, 40, "left.flags")
        self.assertRejected(self.patched("gaze_eyes", 72, "f", float("nan")), DecodeError.NON_FINITE, 72, "right.x_deg")
        one_eye = bytearray(golden("gaze_eyes"))
        one_eye[41] = 0
        one_eye[64:80] = bytes(16)
        eyes = protocol.decode(bytes(one_eye)).payload
        self.assertTrue(eyes.left.valid)
        self.assertFalse(eyes.right.valid)

    def test_reserved_bytes(self):
        for name, offset in (("hello", 72), ("hello", 79), ("challenge", 60), ("heartbeat", 44), ("subscribed", 111),
                             ("gaze_event", 35), ("status_request", 100), ("status_reply", 125),
                             ("time_sync_request", 50), ("error", 37), ("control_request", 33), ("marker", 70)):
            with self.subTest(name=name, offset=offset):
                self.assertRejected(self.patched(name, offset, "B", 1), DecodeError.RESERVED_NOT_ZERO, offset,
                                    "reserved")

    def test_text_fields(self):
        hello = bytearray(golden("hello"))
        hello[40:72] = b"x" * 32
        self.assertRejected(hello, DecodeError.BAD_STRING, 40, "client_name")
        self.assertRejected(self.patched("hello", 60, "B", 0x41), DecodeError.BAD_STRING, 60, "client_name")
        self.assertRejected(self.patched("marker", 77, "B", 0x0A), DecodeError.BAD_STRING, 77, "label")
        self.assertRejected(self.patched("marker", 75, "B", 0xFF), DecodeError.BAD_STRING, 75, "label")
        c1 = bytearray(golden("marker"))
        c1[72:75] = b"\xc2\x85 "  # U+0085, a C1 control character
        self.assertRejected(c1, DecodeError.BAD_STRING, 72, "label")
        empty = bytearray(golden("marker"))
        empty[72:136] = bytes(64)
        self.assertRejected(empty, DecodeError.BAD_STRING, 72, "label")

    def test_utf8_labels_are_accepted(self):
        m = protocol.Marker(5, 7, 0, 0, 0, "Reiz an: Größe 3° ✓")
        self.assertEqual(protocol.decode(protocol.encode(m)).payload, m)


class StrictEncoding(unittest.TestCase):
    def test_encoder_refuses_what_the_decoder_would_reject(self):
        bad = [
            (protocol.GazeSample(x=math.nan), DecodeError.NON_FINITE, "x"),
            (protocol.GazeSample(confidence=2.0), DecodeError.OUT_OF_RANGE, "confidence"),
            (protocol.Hello(1, "n" * 32), DecodeError.BAD_STRING, "client_name"),
            (protocol.Marker(1, 1, 0, 0, 0, ""), DecodeError.BAD_STRING, "label"),
            (protocol.Marker(1, 0, 0, 0, 0, "x"), DecodeError.OUT_OF_RANGE, "marker_id"),
            (protocol.Subscribe(streams=0), DecodeError.OUT_OF_RANGE, "streams"),
            (protocol.Heartbeat(-1, 0), DecodeError.OUT_OF_RANGE, "session_id"),
            (protocol.GazeSample(x=1e39), DecodeError.OUT_OF_RANGE, "x"),
        ]
        for payload, reason, field in bad:
            with self.subTest(payload=payload):
                with self.assertRaises(ProtocolError) as e:
                    protocol.encode(payload)
                self.assertEqual((e.exception.reason, e.exception.field), (reason, field), str(e.exception))

    def test_marker_label_check(self):
        protocol.check_marker_label("trial 1: go")
        for label in ("", "x" * 64, "two\nlines", "tab\there", "del\x7f"):
            with self.assertRaises(ValueError):
                protocol.check_marker_label(label)


class DisplayMath(unittest.TestCase):
    def test_worked_example(self):
        g = DisplayGeometry()
        x_deg, y_deg = g.to_degrees(0.75, 0.5)
        self.assertAlmostEqual(x_deg, 11.55, places=2)
        self.assertEqual(y_deg, 0.0)
        x, y = g.from_degrees(x_deg, y_deg)
        self.assertAlmostEqual(x, 0.75)
        self.assertEqual(g.to_pixels(0.5, 0.25), (960.0, 270.0))


class SequenceTracking(unittest.TestCase):
    def test_loss_duplicates_reordering(self):
        t = SequenceTracker()
        t.reset(100)
        verdicts = [t.on_arrival(s) for s in (99, 100, 101, 103, 102, 102, 104, 40)]
        self.assertEqual(verdicts, ["too old", "new", "new", "new", "reordered", "duplicate", "new", "too old"])
        c = t.counts
        self.assertEqual((c.received, c.lost, c.duplicated, c.reordered), (5, 0, 1, 1))
        t.on_arrival(110)
        self.assertEqual(t.counts.lost, 5)

    def test_first_arrival_after_subscription_counts_the_gap(self):
        t = SequenceTracker()
        t.reset(10)
        self.assertEqual(t.on_arrival(13), "new")
        self.assertEqual(t.counts.lost, 3)

    def test_implausible_jump_then_resync(self):
        t = SequenceTracker()
        t.reset(0)
        t.on_arrival(0)
        self.assertEqual(t.on_arrival(1 << 40), "implausible")
        self.assertEqual(t.on_arrival(1), "new")  # the real stream goes on
        far = 1 << 50
        verdicts = [t.on_arrival(far + i) for i in range(8)]
        self.assertEqual(verdicts[:7], ["implausible"] * 7)
        self.assertEqual(verdicts[7], "new")
        self.assertEqual((t.counts.resyncs, t.counts.implausible), (1, 1))

    def test_marker_stream_starts_at_first_arrival(self):
        t = SequenceTracker()
        t.reset_from_first_arrival()
        self.assertEqual(t.on_arrival(57), "new")
        self.assertEqual(t.counts.lost, 0)

    def test_resubscription_counts_the_items_in_between(self):
        t = SequenceTracker()
        t.reset(0)
        for s in range(5):
            t.on_arrival(s)
        t.reset(10)
        self.assertEqual(t.counts.lost, 5)


class TimeSync(unittest.TestCase):
    def test_worked_example(self):
        c = ClockSync()
        c.request_sent(5_000_000_000)
        self.assertTrue(c.on_reply(protocol.TimeSyncReply(5_000_000_000, 1_000_100_000, 1_000_120_000), 5_000_400_000))
        self.assertEqual((c.offset_ns, c.round_trip_ns), (-4_000_090_000, 380_000))
        self.assertEqual(c.to_client_ns(1_000_000_000), 5_000_090_000)

    def test_unrequested_or_absurd_replies_are_ignored(self):
        c = ClockSync()
        self.assertFalse(c.on_reply(protocol.TimeSyncReply(1, 2, 3), 4))
        c.request_sent(10)
        self.assertFalse(c.on_reply(protocol.TimeSyncReply(10, 1 << 61, 1 << 61), 20))
        c.request_sent(30)
        self.assertFalse(c.on_reply(protocol.TimeSyncReply(30, 100, 150), 40))  # negative delay
        self.assertFalse(c.known)

    def test_a_minority_of_bad_offsets_does_not_move_it(self):
        c = ClockSync()
        for i in range(8):
            t1 = i * 1_000_000_000
            c.request_sent(t1)
            offset = 5_000_000_000 if i in (2, 5) else 1000  # two liars with the shortest delay
            delay = 10_000 if i in (2, 5) else 200_000
            server = t1 + offset + delay // 2
            c.on_reply(protocol.TimeSyncReply(t1, server, server), t1 + delay)
        self.assertEqual(c.offset_ns, 1000)


if __name__ == "__main__":
    unittest.main()
