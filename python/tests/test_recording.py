# SPDX-License-Identifier: Apache-2.0
"""The .fgr reader: round trip, and the damaged-file cases of tests/unit/test_recording.cpp
(RecordingRecovery.*), ported. Test data: $FOVEA_TEST_DATA, else tests/data of this checkout."""

import bisect
import os
import random
import tempfile
import unittest
from pathlib import Path

from fovea import protocol
from fovea.protocol import DisplayGeometry, EventPhase, EyeData, EyeMovement
from fovea.recording import (HEADER_SIZE, Record, RecordingClock, RecordingHeader, RecordingWriter, crc32c,
                             encode_header, encode_record, parse_recording, read_recording)

DATA = Path(os.environ.get("FOVEA_TEST_DATA", Path(__file__).resolve().parents[2] / "tests" / "data"))


def test_header():
    return RecordingHeader("python test (seed 3)", DisplayGeometry(1280, 1024, 0.376, 0.301, 0.6), 500.0,
                           RecordingClock.MONOTONIC, 1_700_000_000_000_000_000, 1_000_000_000)


def random_records(n, seed):
    """Samples (some with a receive time), events and markers, with random in-range values."""
    rng = random.Random(seed)
    out = []
    for i in range(n):
        kind = rng.random()
        t = 1_000_000_000 + i * 4_000_000
        if kind < 0.7:
            eye = EyeData(rng.randint(0, 3), rng.uniform(0, 640), rng.uniform(0, 480), rng.uniform(2, 8),
                          rng.uniform(-10, 10), rng.uniform(-10, 10))
            item = protocol.GazeSample(t, rng.uniform(-0.2, 1.2), rng.uniform(0, 1), rng.uniform(-20, 20),
                                       rng.uniform(-15, 15), rng.uniform(0, 500), rng.random(),
                                       EyeMovement(rng.randint(0, 4)), rng.randint(0, 1), eye, eye)
            item = protocol.decode_payload(7, protocol.encode_payload(item))  # f32-rounded, as read back
            out.append(Record(i, item, t + 1000 if rng.random() < 0.5 else None))
        elif kind < 0.9:
            item = protocol.decode_payload(8, protocol.encode_payload(protocol.GazeEvent(
                EyeMovement(rng.randint(1, 4)), EventPhase(rng.randint(1, 2)), 0, t, rng.randint(0, 10**8),
                rng.random(), rng.random(), 1.5, -2.5, rng.uniform(0, 20), rng.uniform(0, 600))))
            out.append(Record(i, item))
        else:
            out.append(Record(i, protocol.Marker(0, rng.randint(1, 2**64 - 1), t, t, 0, f"trial {i}: go")))
    return out


def encode_file(header, records):
    """The file's bytes and the start offset of every record (plus the end)."""
    data = bytearray(encode_header(header))
    starts = []
    for r in records:
        starts.append(len(data))
        data += encode_record(r)
    starts.append(len(data))
    return bytes(data), starts


class Format(unittest.TestCase):
    def test_crc32c_check_value(self):
        self.assertEqual(crc32c(b"123456789"), 0xE3069283)

    def test_worked_example_of_recording_md(self):
        h = RecordingHeader("synthetic (seed 1)", DisplayGeometry(), 250.0, RecordingClock.MONOTONIC,
                            1_700_000_000_000_000_000, 1_000_000_000)
        head = encode_header(h)
        self.assertEqual(head[156:160], bytes.fromhex("603b44f9"))
        sample = protocol.decode(bytes(int(t, 16) for t in (DATA / "golden" / "gaze_sample.hex").read_text().split()))
        record = encode_record(Record(1000, sample.payload))
        self.assertEqual(len(record), 96)
        self.assertEqual(record[:16], bytes.fromhex("f07ea15207005400e803000000000000"))
        self.assertEqual(record[-4:], bytes.fromhex("cfae6ee4"))

    def test_writer_and_reader_round_trip(self):
        records = random_records(200, 11)
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "roundtrip.fgr"
            with RecordingWriter(path, test_header()) as w:
                for r in records:
                    w.append(r)
            with self.assertRaises(FileExistsError):
                RecordingWriter(path, test_header())
            rec = read_recording(path)
            self.assertEqual(path.read_bytes(), encode_file(test_header(), records)[0])
        self.assertEqual(rec.header, test_header())
        self.assertEqual(rec.records, records)
        self.assertEqual(rec.report.describe(), "200 intact records")
        self.assertTrue(rec.report.header_valid)

    def test_per_eye_gaze_follows_its_sample_and_is_joined_back(self):
        records = []
        for i in range(4):
            s = protocol.GazeSample(1_000_000_000 + i * 4_000_000, 0.5, 0.5, flags=protocol.GAZE_VALID)
            if i != 2:
                s.left_gaze = protocol.EyeGaze(1, 0.5, 0.5, -0.25, 0.0)
            if i in (0, 3):
                s.right_gaze = protocol.EyeGaze(1, 0.5, 0.5, 0.25, 0.0)
            records.append(Record(100 + i, s))
        self.assertEqual(len(encode_record(records[0])), 96 + 68)
        self.assertEqual(len(encode_record(records[2])), 96)
        data, _ = encode_file(test_header(), records)
        rec = parse_recording(data)
        self.assertEqual(rec.records, records)
        self.assertEqual(rec.report.describe(), "4 intact records")
        bad = bytearray(data)
        bad[HEADER_SIZE + 40] ^= 0xFF
        rec = parse_recording(bytes(bad))
        self.assertEqual(rec.records, records[1:])
        self.assertEqual(rec.report.eyes_unjoined, 1)

    def test_writer_refuses_invalid_content(self):
        with self.assertRaises(ValueError):
            encode_record(Record(0, protocol.GazeSample(x=float("nan"))))
        with self.assertRaises(ValueError):
            encode_record(Record(0, protocol.GazeEvent(), host_receive_ns=5))
        with self.assertRaises(ValueError):
            encode_header(RecordingHeader(device="a\nb"))

    def test_the_shared_synthetic_recording(self):
        rec = read_recording(DATA / "recordings" / "synthetic-250hz-62s.fgr")
        self.assertTrue(rec.report.header_valid)
        self.assertEqual(rec.header.device, "synthetic (seed 7, 250 Hz)")
        self.assertEqual(rec.header.nominal_rate_hz, 250.0)
        self.assertEqual(rec.report.records, 16185)
        self.assertEqual(sum(1 for _ in rec.samples()), 15500)
        self.assertEqual(sum(1 for s in rec.samples() if s.valid), 15021)
        ends = [e.kind.name for e in rec.events() if e.phase == EventPhase.END]
        self.assertEqual({k: ends.count(k) for k in set(ends)}, {"BLINK": 9, "FIXATION": 171, "PURSUIT": 11,
                                                                 "SACCADE": 151})
        times = [r.time_ns for r in rec.records if isinstance(r.item, protocol.GazeSample)]
        self.assertAlmostEqual((times[-1] - times[0]) / 1e9, 61.996, places=3)


class Recovery(unittest.TestCase):
    def test_every_cut_within_the_last_three_records(self):
        records = random_records(60, 21)
        data, starts = encode_file(test_header(), records)
        n = len(records)
        for cut in range(starts[n - 3], len(data) + 1):
            whole = bisect.bisect_right(starts, cut) - 1
            partial = cut - starts[whole]
            rec = parse_recording(data[:cut])
            with self.subTest(cut=cut):
                self.assertTrue(rec.report.header_valid)
                self.assertEqual(rec.header, test_header())
                self.assertEqual(rec.records, records[:whole])
                self.assertEqual(rec.report.truncated_tail, partial != 0)
                self.assertEqual(rec.report.bytes_skipped, partial)
                self.assertEqual(rec.report.damaged_regions, 1 if partial else 0)

    def expect_after_damage(self, starts, records, changed):
        """What the reader must find, derived from which bytes of the intact file changed."""
        n = len(records)
        hit = [False] * (n + 1)  # unit 0 is the header, unit i + 1 record i
        magic_hit = False
        for pos in changed:
            if pos < HEADER_SIZE:
                hit[0], magic_hit = True, magic_hit or pos < 8
            else:
                hit[bisect.bisect_right(starts, pos)] = True
        expected = dict(header_valid=not hit[0], records=[], damaged_regions=0, truncated_tail=hit[n],
                        bytes_skipped=(HEADER_SIZE if magic_hit else HEADER_SIZE - 8) if hit[0] else 0)
        for u in range(n + 1):
            if hit[u] and (u == 0 or not hit[u - 1]):
                expected["damaged_regions"] += 1
            if u and hit[u]:
                expected["bytes_skipped"] += starts[u] - starts[u - 1]
            elif u:
                expected["records"].append(records[u - 1])
        return expected

    def test_random_byte_flips_lose_only_the_records_hit(self):
        records = random_records(40, 31)
        data, starts = encode_file(test_header(), records)
        rng = random.Random(20240611)
        header_hits = record_hits = 0
        for trial in range(300):
            bad = bytearray(data)
            changed = []
            for _ in range(rng.randint(1, 5)):
                pos = rng.choice([rng.randint(0, HEADER_SIZE + 200), rng.randint(len(data) - 300, len(data) - 1),
                                  rng.randint(0, len(data) - 1), rng.randint(0, len(data) - 1)])
                bad[pos] ^= rng.randint(1, 255)
                changed.append(pos)
            want = self.expect_after_damage(starts, records, changed)
            header_hits += not want["header_valid"]
            record_hits += len(want["records"]) < len(records)
            rec = parse_recording(bytes(bad))
            got = dict(header_valid=rec.report.header_valid, records=rec.records,
                       damaged_regions=rec.report.damaged_regions, truncated_tail=rec.report.truncated_tail,
                       bytes_skipped=rec.report.bytes_skipped)
            self.assertEqual(got, want, f"trial {trial}, bytes {changed}")
            self.assertEqual(rec.report.records, len(want["records"]))
            if want["header_valid"]:
                self.assertEqual(rec.header, test_header())
        self.assertGreater(header_hits, 20)
        self.assertGreater(record_hits, 150)

    def test_damage_in_the_middle_of_a_record_loses_only_that_record(self):
        records = random_records(30, 41)
        data, starts = encode_file(test_header(), records)
        for victim in (0, 10, 28):
            for at in (0, 4, 6, 9, 40, 63):
                with self.subTest(victim=victim, at=at):
                    bad = bytearray(data)
                    bad[starts[victim] + at] ^= 0x5A
                    rec = parse_recording(bytes(bad))
                    self.assertTrue(rec.report.header_valid)
                    self.assertEqual(rec.records, records[:victim] + records[victim + 1:])
                    self.assertEqual(rec.report.damaged_regions, 1)
                    self.assertEqual(rec.report.bytes_skipped, starts[victim + 1] - starts[victim])
                    self.assertFalse(rec.report.truncated_tail)

    def test_garbage_between_records_is_skipped(self):
        records = random_records(20, 51)
        data, starts = encode_file(test_header(), records)
        false_sync = bytes([0xF0, 0x7E, 0xA1, 0x52, 0x07, 0x00, 0x54, 0x00, 0x01])
        for junk in [bytes((i * 7 + 1) % 256 for i in range(n)) for n in (1, 3, 5, 37)] + [false_sync]:
            with self.subTest(junk=junk):
                rec = parse_recording(data[:starts[7]] + junk + data[starts[7]:])
                self.assertEqual(rec.records, records)
                self.assertEqual(rec.report.damaged_regions, 1)
                self.assertEqual(rec.report.bytes_skipped, len(junk))
                self.assertFalse(rec.report.truncated_tail)
                self.assertTrue(rec.report.header_valid)

    def test_damaged_header_still_yields_the_records(self):
        records = random_records(25, 61)
        data, _ = encode_file(test_header(), records)
        for at in (3, 8, 20, 100, 158):
            with self.subTest(at=at):
                bad = bytearray(data)
                bad[at] ^= 0x01
                rec = parse_recording(bytes(bad))
                self.assertFalse(rec.report.header_valid)
                self.assertEqual(rec.header, RecordingHeader())  # defaults, nothing half-trusted
                self.assertEqual(rec.records, records)
                self.assertEqual(rec.report.damaged_regions, 1)
                self.assertEqual(rec.report.bytes_skipped, HEADER_SIZE if at < 8 else HEADER_SIZE - 8)
                self.assertIn("header damaged", rec.report.describe())

    def test_file_that_lost_its_beginning_still_yields_the_records(self):
        records = random_records(12, 71)
        data, starts = encode_file(test_header(), records)
        rec = parse_recording(data[starts[2] + 30:])
        self.assertFalse(rec.report.header_valid)
        self.assertEqual(rec.records, records[3:])
        self.assertEqual(rec.report.damaged_regions, 1)
        self.assertEqual(rec.report.bytes_skipped, starts[3] - starts[2] - 30)
        self.assertFalse(rec.report.truncated_tail)

    def test_header_only_and_truncated_header(self):
        head = encode_header(test_header())
        rec = parse_recording(head)
        self.assertTrue(rec.report.header_valid)
        self.assertEqual((rec.records, rec.report.damaged_regions), ([], 0))
        rec = parse_recording(head[:100])  # magic present, header cut short: damaged and empty
        self.assertFalse(rec.report.header_valid)
        self.assertEqual(rec.records, [])
        self.assertEqual(rec.report.bytes_skipped, 92)
        self.assertTrue(rec.report.truncated_tail)

    def test_not_a_recording_raises(self):
        rng = random.Random(81)
        garbage = bytes(rng.randint(0, 255) for _ in range(3000))
        for data in (garbage, garbage[:5], b"", b"sequence,tracker_time_ns,x,y\n0,1,0.5,0.5\n"):
            with self.assertRaisesRegex(ValueError, "not a fovea recording"):
                parse_recording(data)

    def test_read_errors_name_the_file(self):
        with tempfile.TemporaryDirectory() as d:
            missing = Path(d) / "missing.fgr"
            with self.assertRaises(OSError) as e:
                read_recording(missing)
            self.assertIn(str(missing), str(e.exception))
            empty = Path(d) / "empty.fgr"
            empty.write_bytes(b"")
            with self.assertRaisesRegex(ValueError, "empty.fgr is empty"):
                read_recording(empty)
            text = Path(d) / "notes.fgr"
            text.write_text("hello\n")
            with self.assertRaisesRegex(ValueError, "notes.fgr: not a fovea recording"):
                read_recording(text)


if __name__ == "__main__":
    unittest.main()
