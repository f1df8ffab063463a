# SPDX-License-Identifier: Apache-2.0
"""Gaze recordings (.fgr): reader with recovery, and a writer.

Byte layout and recovery rules: protocol/RECORDING.md; the reference is protocol/src/recording.cpp
(`parse_recording`). The reader never rejects a damaged recording: it returns every intact record
and a RecoveryReport saying what it skipped, exactly as the C++ reader does.
"""

from __future__ import annotations

import enum
import math
import os
import struct
from dataclasses import dataclass, field
from typing import Iterator, List, Optional, Union

from . import protocol
from .protocol import DisplayGeometry, GazeEvent, GazeSample, Marker, MessageType, ProtocolError

FILE_MAGIC = b"FOVEAFGR"
HEADER_SIZE = 160
VERSION = 2
SYNC = b"\xf0\x7e\xa1\x52"
_RECORD_PREFIX = 16  # sync, type, flags, body_length, sequence
_RECORD_CRC = 4
_MIN_RECORD = _RECORD_PREFIX + _RECORD_CRC
_HAS_RECEIVE_TIME = 0x1
_RECORD_TYPES = (MessageType.GAZE_SAMPLE, MessageType.GAZE_EVENT, MessageType.MARKER)
# GAZE_EYES: a sample's per-eye gaze, right after the sample's record, joined into it when read.
_PARSED_TYPES = _RECORD_TYPES + (MessageType.GAZE_EYES,)

Item = Union[GazeSample, GazeEvent, Marker]


def _crc_table() -> List[int]:
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ 0x82F63B78 if c & 1 else c >> 1
        table.append(c)
    return table


_CRC_TABLE = _crc_table()


def crc32c(data: bytes, crc: int = 0) -> int:
    """CRC-32C (Castagnoli), as iSCSI and ext4: crc32c(b"123456789") == 0xE3069283."""
    crc ^= 0xFFFFFFFF
    table = _CRC_TABLE
    for b in data:
        crc = (crc >> 8) ^ table[(crc ^ b) & 0xFF]
    return crc ^ 0xFFFFFFFF


class RecordingClock(enum.IntEnum):
    MONOTONIC = 0
    REALTIME = 1


@dataclass
class RecordingHeader:
    device: str = ""
    display: DisplayGeometry = field(default_factory=DisplayGeometry)
    nominal_rate_hz: float = 0.0
    clock: RecordingClock = RecordingClock.MONOTONIC
    created_unix_ns: int = 0
    created_clock_ns: int = 0

    def to_unix_ns(self, t: int) -> int:
        """A record time as Unix time (RECORDING.md: created_unix_ns + (t - created_clock_ns))."""
        return self.created_unix_ns + (t - self.created_clock_ns)


@dataclass
class Record:
    sequence: int
    item: Item
    host_receive_ns: Optional[int] = None  # samples only: when the daemon received it from the tracker

    @property
    def time_ns(self) -> int:
        """Sample time, event end time, or marker time, on the record clock."""
        if isinstance(self.item, GazeSample):
            return self.item.tracker_time_ns
        if isinstance(self.item, Marker):
            return self.item.time_ns
        return self.item.start_time_ns + self.item.duration_ns


@dataclass
class RecoveryReport:
    header_valid: bool = False
    records: int = 0
    damaged_regions: int = 0  # maximal runs of bytes that were not intact records
    bytes_skipped: int = 0
    truncated_tail: bool = False  # the last damaged region runs to the end of the file
    eyes_unjoined: int = 0  # GAZE_EYES records whose sample record was not just before them

    def describe(self) -> str:
        s = f"{self.records} intact records"
        if not self.header_valid:
            s += "; header damaged (defaults used)"
        if self.damaged_regions:
            s += f"; skipped {self.bytes_skipped} bytes in {self.damaged_regions} damaged region(s)"
        if self.truncated_tail:
            s += "; file ends inside a record"
        if self.eyes_unjoined:
            s += f"; {self.eyes_unjoined} per-eye record(s) without their sample"
        return s


@dataclass
class Recording:
    header: RecordingHeader
    records: List[Record]
    report: RecoveryReport

    def samples(self) -> Iterator[GazeSample]:
        return (r.item for r in self.records if isinstance(r.item, GazeSample))

    def events(self) -> Iterator[GazeEvent]:
        return (r.item for r in self.records if isinstance(r.item, GazeEvent))

    def markers(self) -> Iterator[Marker]:
        return (r.item for r in self.records if isinstance(r.item, Marker))


# ---- header ---------------------------------------------------------------------------------------


def _display_valid(g: DisplayGeometry) -> bool:
    def metres(v: float) -> bool:
        return math.isfinite(v) and 0 < v <= 100
    return (1 <= g.width_px <= 65536 and 1 <= g.height_px <= 65536 and metres(g.width_m) and metres(g.height_m)
            and metres(g.viewing_distance_m))


def parse_header(data: bytes) -> Optional[RecordingHeader]:
    """The header if the first 160 bytes are an intact one, else None (nothing half-trusted)."""
    if len(data) < HEADER_SIZE or data[:8] != FILE_MAGIC:
        return None
    version, header_size = struct.unpack_from("<HH", data, 8)
    if not 1 <= version <= VERSION or header_size != HEADER_SIZE:
        return None
    if struct.unpack_from("<I", data, 156)[0] != crc32c(data[:156]):
        return None
    display = DisplayGeometry(*struct.unpack_from("<IIddd", data, 80))
    rate, clock = struct.unpack_from("<dB", data, 112)
    if not _display_valid(display) or not (math.isfinite(rate) and rate >= 0) or clock > 1:
        return None
    device = data[16:16 + 63].split(b"\0", 1)[0].decode("utf-8", "replace")
    created_unix, created_clock = struct.unpack_from("<qq", data, 128)
    return RecordingHeader(device, display, rate, RecordingClock(clock), created_unix, created_clock)


def encode_header(h: RecordingHeader) -> bytes:
    raw_device = h.device.encode("utf-8")
    if len(raw_device) > 63:
        raise ValueError(f"recording device name longer than 63 bytes: {h.device!r}")
    if any(b < 0x20 for b in raw_device):
        raise ValueError(f"recording device name contains a control character: {h.device!r}")
    if not (math.isfinite(h.nominal_rate_hz) and h.nominal_rate_hz >= 0):
        raise ValueError(f"recording nominal_rate_hz = {h.nominal_rate_hz} (allowed: finite, >= 0)")
    if int(h.clock) not in (0, 1):
        raise ValueError("recording clock must be 0 or 1")
    if not _display_valid(h.display):
        raise ValueError(f"recording display out of range: {h.display}")
    b = bytearray(HEADER_SIZE)
    b[0:8] = FILE_MAGIC
    struct.pack_into("<HH", b, 8, VERSION, HEADER_SIZE)
    b[16:16 + len(raw_device)] = raw_device
    g = h.display
    struct.pack_into("<IIddddB", b, 80, g.width_px, g.height_px, g.width_m, g.height_m, g.viewing_distance_m,
                     h.nominal_rate_hz, int(h.clock))
    struct.pack_into("<qq", b, 128, h.created_unix_ns, h.created_clock_ns)
    struct.pack_into("<I", b, 156, crc32c(bytes(b[:156])))
    return bytes(b)


# ---- records --------------------------------------------------------------------------------------


def _parse_record(data: bytes, pos: int) -> Optional[tuple]:
    """(Record, size) for an intact record starting at `pos`, else None."""
    if len(data) - pos < _MIN_RECORD or data[pos:pos + 4] != SYNC:
        return None
    type_raw, flags, body = struct.unpack_from("<BBH", data, pos + 4)
    if type_raw not in _PARSED_TYPES:
        return None
    t = MessageType(type_raw)
    if flags & ~_HAS_RECEIVE_TIME or (flags and t != MessageType.GAZE_SAMPLE):
        return None  # only samples carry a receive time
    extra = 8 if flags else 0
    if body != 8 + extra + protocol.payload_size(t):
        return None
    total = 8 + body + _RECORD_CRC
    if len(data) - pos < total:
        return None
    if struct.unpack_from("<I", data, pos + 8 + body)[0] != crc32c(data[pos + 4:pos + 8 + body]):
        return None
    try:
        item = protocol.decode_payload(t, data[pos + _RECORD_PREFIX + extra:pos + 8 + body])
    except ProtocolError:
        return None
    sequence = struct.unpack_from("<Q", data, pos + 8)[0]
    receive = struct.unpack_from("<q", data, pos + _RECORD_PREFIX)[0] if extra else None
    return Record(sequence, item, receive), total


def encode_record(r: Record) -> bytes:
    """One record's bytes; raises ProtocolError (a ValueError) for a payload the protocol would reject."""
    t = protocol.type_of(r.item)
    if t not in _RECORD_TYPES:
        raise ValueError(f"a recording holds samples, events and markers, not {t.name}")
    if r.host_receive_ns is not None and t != MessageType.GAZE_SAMPLE:
        raise ValueError("only gaze samples carry a host receive time in a recording")
    out = _encode_one(t, protocol.encode_payload(r.item), r.sequence, r.host_receive_ns)
    s = r.item
    if isinstance(s, GazeSample) and (s.left_gaze.valid or s.right_gaze.valid):
        eyes = protocol.GazeEyes(s.tracker_time_ns, s.left_gaze, s.right_gaze)
        out += _encode_one(MessageType.GAZE_EYES, protocol.encode_payload(eyes), r.sequence, None)
    return out


def _encode_one(t: MessageType, payload: bytes, sequence: int, host_receive_ns: Optional[int]) -> bytes:
    receive = b"" if host_receive_ns is None else struct.pack("<q", host_receive_ns)
    body = struct.pack("<BBHQ", t, _HAS_RECEIVE_TIME if receive else 0, 8 + len(receive) + len(payload), sequence)
    body += receive + payload
    return SYNC + body + struct.pack("<I", crc32c(body))


def _join_eyes(records: List[Record], sequence: int, eyes: "protocol.GazeEyes", report: "RecoveryReport") -> None:
    """A GAZE_EYES record into the sample record just before it (same sequence and time), else counted."""
    last = records[-1] if records else None
    s = last.item if last else None
    if (isinstance(s, GazeSample) and last.sequence == sequence and s.tracker_time_ns == eyes.tracker_time_ns
            and not (s.left_gaze.valid or s.right_gaze.valid)):
        s.left_gaze, s.right_gaze = eyes.left, eyes.right
    else:
        report.eyes_unjoined += 1


def _contains_a_record(data: bytes) -> bool:
    at = data.find(SYNC)
    while at >= 0:
        if _parse_record(data, at):
            return True
        at = data.find(SYNC, at + 1)
    return False


def parse_recording(data: bytes) -> Recording:
    """Every intact record of `data` and what was skipped; raises ValueError only if it is no recording."""
    data = bytes(data)
    report = RecoveryReport()
    header = parse_header(data)
    if header is not None:
        report.header_valid, pos = True, HEADER_SIZE
    elif data[:8] == FILE_MAGIC:
        header, pos = RecordingHeader(), 8  # damaged header: look for records after the magic
    elif _contains_a_record(data):
        header, pos = RecordingHeader(), 0  # a file that lost its first bytes
    else:
        raise ValueError("not a fovea recording (no .fgr header and no intact record)")
    records: List[Record] = []
    in_damage = False
    while pos < len(data):
        parsed = _parse_record(data, pos)
        if parsed and isinstance(parsed[0].item, protocol.GazeEyes):
            _join_eyes(records, parsed[0].sequence, parsed[0].item, report)
            pos += parsed[1]
            in_damage = False
            continue
        if parsed:
            records.append(parsed[0])
            pos += parsed[1]
            in_damage = False
            continue
        if not in_damage:
            report.damaged_regions += 1
            in_damage = True
        # Resynchronise at the next sync marker; a false one costs nothing (its record fails its checks).
        nxt = data.find(SYNC, pos + 1)
        if nxt < 0:
            nxt = len(data)
            report.truncated_tail = True
        report.bytes_skipped += nxt - pos
        pos = nxt
    report.records = len(records)
    return Recording(header, records, report)


def read_recording(path: Union[str, os.PathLike]) -> Recording:
    """Reads a .fgr file; raises OSError or ValueError naming the file when it cannot be read or is none."""
    with open(path, "rb") as f:
        data = f.read()
    if not data:
        raise ValueError(f"recording {os.fspath(path)} is empty")
    try:
        return parse_recording(data)
    except ValueError as e:
        raise ValueError(f"{os.fspath(path)}: {e}") from None


class RecordingWriter:
    """Writes a new .fgr file: the header at once, then one write per record (append-only)."""

    def __init__(self, path: Union[str, os.PathLike], header: RecordingHeader):
        head = encode_header(header)
        # O_EXCL: a recording is never overwritten.
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o644)
        self._file = os.fdopen(fd, "wb", buffering=0)
        self._file.write(head)
        self.path = os.fspath(path)
        self.records_written = 0

    def append(self, record: Record) -> None:
        self._file.write(encode_record(record))
        self.records_written += 1

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> "RecordingWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
