# SPDX-License-Identifier: Apache-2.0
"""The fovea gaze protocol, version 1: message dataclasses, encoder and strict decoder.

Byte layouts and validation rules are those of protocol/PROTOCOL.md (sections 2-5); the reference
implementation is protocol/src/codec.cpp. Every message is described once, as a table of fields
(`_LAYOUTS`), which both the encoder and the decoder follow, so the two cannot drift apart.

A datagram that breaks any rule raises ProtocolError, which names the message, the field, its byte
offset in the datagram, the value and the rule. The encoder checks what it wrote with the decoder's
rules, so nothing invalid is ever sent (PROTOCOL.md section 5, last paragraph).
"""

from __future__ import annotations

import dataclasses
import enum
import math
import struct
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

MAGIC = b"FVGZ"
VERSION = 1
HEADER_SIZE = 32
MAX_DATAGRAM_SIZE = 512
DEFAULT_PORT = 47800

STREAM_SAMPLES = 0x1
STREAM_EVENTS = 0x2
STREAM_MARKERS = 0x4
STREAM_PROVISIONAL = 0x8
STREAM_EYES = 0x10  # GAZE_EYES: each eye's point of gaze, joined to its sample (PROTOCOL.md section 4.18)
STREAM_MASK = STREAM_SAMPLES | STREAM_EVENTS | STREAM_MARKERS | STREAM_PROVISIONAL | STREAM_EYES

GAZE_VALID = 0x1
EYE_PUPIL_VALID = 0x1
EYE_GLINT_VALID = 0x2
EYE_GAZE_VALID = 0x1
EVENT_PROVISIONAL = 0x1
EVENT_RETRACTED = 0x2
MARKER_CLIENT_TIME = 0x1


class MessageType(enum.IntEnum):
    HELLO = 1
    CHALLENGE = 2
    SUBSCRIBE = 3
    SUBSCRIBED = 4
    HEARTBEAT = 5
    UNSUBSCRIBE = 6
    GAZE_SAMPLE = 7
    GAZE_EVENT = 8
    STATUS_REQUEST = 9
    STATUS_REPLY = 10
    TIME_SYNC_REQUEST = 11
    TIME_SYNC_REPLY = 12
    ERROR = 13
    CONTROL_REQUEST = 14
    CONTROL_REPLY = 15
    MARKER = 16
    GAZE_EYES = 17


class EyeMovement(enum.IntEnum):
    UNKNOWN = 0
    FIXATION = 1
    SACCADE = 2
    PURSUIT = 3
    BLINK = 4


class EventPhase(enum.IntEnum):
    START = 1
    END = 2


class SourceState(enum.IntEnum):
    RUNNING = 0
    ENDED = 1
    RETRYING = 2


class ErrorCode(enum.IntEnum):
    BAD_COOKIE = 1
    COOKIE_EXPIRED = 2
    UNKNOWN_SESSION = 3
    UNSUPPORTED_VERSION = 4
    TOO_MANY_SUBSCRIBERS = 5
    BAD_REQUEST = 6
    ADDRESS_MISMATCH = 7
    RATE_LIMITED = 8


class ControlCommand(enum.IntEnum):
    RELOAD = 1
    START_RECORDING = 2
    STOP_RECORDING = 3
    LOAD_CALIBRATION = 4


class ControlResult(enum.IntEnum):
    OK = 0
    REFUSED = 1
    FAILED = 2


class DecodeError(enum.IntEnum):
    """Why a datagram was rejected (the numbers of DecodeError in codec.h; never on the wire)."""

    TOO_SHORT = 1
    TOO_LONG = 2
    BAD_MAGIC = 3
    BAD_VERSION = 4
    UNKNOWN_TYPE = 5
    BAD_PAYLOAD_LENGTH = 6
    RESERVED_NOT_ZERO = 7
    NON_FINITE = 8
    OUT_OF_RANGE = 9
    BAD_STRING = 10


class ProtocolError(ValueError):
    """A datagram (or a message to encode) breaks a rule of PROTOCOL.md.

    `reason` is the DecodeError, `offset` the byte offset in the datagram (or payload, when only a
    payload was decoded), `field` the field's name ("header" for header checks).
    """

    def __init__(self, reason: DecodeError, offset: int, field_name: str, detail: str, message: str = ""):
        self.reason = reason
        self.offset = offset
        self.field = field_name
        self.detail = detail
        self.message_name = message
        where = f"{message} " if message else ""
        super().__init__(f"{where}{field_name} (byte {offset}): {detail} [{reason.name}]")


# ---- message dataclasses --------------------------------------------------------------------------


@dataclass
class Header:
    sequence: int = 0
    origin_time_ns: int = 0
    send_time_ns: int = 0


@dataclass
class DisplayGeometry:
    """The physical screen that normalized coordinates refer to (PROTOCOL.md section 4.1, 13)."""

    width_px: int = 1920
    height_px: int = 1080
    width_m: float = 0.5313
    height_m: float = 0.2989
    viewing_distance_m: float = 0.65

    def to_pixels(self, x: float, y: float) -> Tuple[float, float]:
        """Normalized (0,0 top-left, y down) to pixels from the top-left corner."""
        return x * self.width_px, y * self.height_px

    def to_degrees(self, x: float, y: float) -> Tuple[float, float]:
        """Normalized position to visual angle from the screen centre (x right, y down)."""
        dx = math.atan2((x - 0.5) * self.width_m, self.viewing_distance_m)
        dy = math.atan2((y - 0.5) * self.height_m, self.viewing_distance_m)
        return math.degrees(dx), math.degrees(dy)

    def from_degrees(self, x_deg: float, y_deg: float) -> Tuple[float, float]:
        """Visual angle to normalized position; angles are clamped to +-89 deg to stay on a flat screen."""
        ax = math.radians(min(max(x_deg, -89.0), 89.0))
        ay = math.radians(min(max(y_deg, -89.0), 89.0))
        return (0.5 + math.tan(ax) * self.viewing_distance_m / self.width_m,
                0.5 + math.tan(ay) * self.viewing_distance_m / self.height_m)


@dataclass
class EyeData:
    flags: int = 0  # EYE_PUPIL_VALID | EYE_GLINT_VALID; the fields are meaningful only when set
    pupil_x_px: float = 0.0
    pupil_y_px: float = 0.0
    pupil_diameter_mm: float = 0.0
    pupil_glint_x_px: float = 0.0
    pupil_glint_y_px: float = 0.0


@dataclass
class Hello:
    client_nonce: int = 0
    client_name: str = ""


@dataclass
class Challenge:
    client_nonce: int = 0
    cookie: bytes = bytes(16)
    cookie_lifetime_ms: int = 0


@dataclass
class Subscribe:
    cookie: bytes = bytes(16)
    client_nonce: int = 0
    streams: int = STREAM_SAMPLES | STREAM_EVENTS
    requested_lease_ms: int = 0


@dataclass
class Subscribed:
    session_id: int = 0
    streams: int = 0
    lease_ms: int = 0
    nominal_rate_hz: float = 0.0
    next_sample_sequence: int = 0
    next_event_sequence: int = 0
    display: DisplayGeometry = field(default_factory=DisplayGeometry)
    multicast_group: int = 0  # IPv4 address as a number, first octet most significant; 0 = none
    multicast_port: int = 0
    multicast_ttl: int = 0


@dataclass
class Heartbeat:
    session_id: int = 0
    lease_ms: int = 0


@dataclass
class Unsubscribe:
    session_id: int = 0


@dataclass
class EyeGaze:
    """One eye's point of gaze, in GazeSample's coordinates; all zero unless valid."""

    flags: int = 0
    x: float = 0.0
    y: float = 0.0
    x_deg: float = 0.0
    y_deg: float = 0.0

    @property
    def valid(self) -> bool:
        return bool(self.flags & EYE_GAZE_VALID)


@dataclass
class GazeSample:
    tracker_time_ns: int = 0
    x: float = 0.0
    y: float = 0.0
    x_deg: float = 0.0
    y_deg: float = 0.0
    angular_velocity_deg_s: float = 0.0
    confidence: float = 0.0
    state: EyeMovement = EyeMovement.UNKNOWN
    flags: int = 0
    left: EyeData = field(default_factory=EyeData)
    right: EyeData = field(default_factory=EyeData)
    # Each eye's gaze, from the GAZE_EYES sent with this sample (STREAM_EYES; not in GAZE_SAMPLE's bytes).
    left_gaze: EyeGaze = field(default_factory=EyeGaze, compare=True)
    right_gaze: EyeGaze = field(default_factory=EyeGaze, compare=True)

    @property
    def valid(self) -> bool:
        """x, y, x_deg, y_deg are meaningful only when this is true (e.g. false during a blink)."""
        return bool(self.flags & GAZE_VALID)


@dataclass
class GazeEvent:
    kind: EyeMovement = EyeMovement.FIXATION
    phase: EventPhase = EventPhase.START
    flags: int = 0
    start_time_ns: int = 0
    duration_ns: int = 0
    centroid_x: float = 0.0
    centroid_y: float = 0.0
    centroid_x_deg: float = 0.0
    centroid_y_deg: float = 0.0
    amplitude_deg: float = 0.0
    peak_velocity_deg_s: float = 0.0

    @property
    def provisional(self) -> bool:
        return bool(self.flags & EVENT_PROVISIONAL)

    @property
    def retracted(self) -> bool:
        return bool(self.flags & EVENT_RETRACTED)

    @property
    def end_time_ns(self) -> int:
        return self.start_time_ns + self.duration_ns


@dataclass
class StatusRequest:
    pass


@dataclass
class StatusReply:
    source: str = ""
    nominal_rate_hz: float = 0.0
    uptime_ns: int = 0
    samples_published: int = 0
    events_published: int = 0
    datagrams_rejected: int = 0
    subscribers: int = 0
    source_state: SourceState = SourceState.RUNNING
    display: DisplayGeometry = field(default_factory=DisplayGeometry)


@dataclass
class TimeSyncRequest:
    client_send_ns: int = 0


@dataclass
class TimeSyncReply:
    client_send_ns: int = 0
    server_receive_ns: int = 0
    server_send_ns: int = 0


@dataclass
class Error:
    code: ErrorCode = ErrorCode.BAD_REQUEST
    request_type: MessageType = MessageType.HELLO
    supported_version: int = VERSION


@dataclass
class ControlRequest:
    command: ControlCommand = ControlCommand.RELOAD
    argument: str = ""


@dataclass
class ControlReply:
    command: ControlCommand = ControlCommand.RELOAD
    result: ControlResult = ControlResult.OK
    message: str = ""


@dataclass
class Marker:
    session_id: int = 0
    marker_id: int = 0
    time_ns: int = 0
    received_ns: int = 0
    flags: int = 0
    label: str = ""

    @property
    def client_time(self) -> bool:
        """time_ns was given by the sender (else it is the daemon's receive time)."""
        return bool(self.flags & MARKER_CLIENT_TIME)


@dataclass
class GazeEyes:
    """GAZE_EYES (17): the per-eye gaze of the GAZE_SAMPLE with the same sequence and tracker time."""

    tracker_time_ns: int = 0
    left: EyeGaze = field(default_factory=EyeGaze)
    right: EyeGaze = field(default_factory=EyeGaze)


Payload = Union[Hello, Challenge, Subscribe, Subscribed, Heartbeat, Unsubscribe, GazeSample, GazeEvent,
                StatusRequest, StatusReply, TimeSyncRequest, TimeSyncReply, Error, ControlRequest, ControlReply,
                Marker, GazeEyes]


@dataclass
class Message:
    header: Header
    payload: Payload

    @property
    def type(self) -> MessageType:
        return type_of(self.payload)


# ---- field rules ----------------------------------------------------------------------------------

# A rule returns None when the value is acceptable, else (reason, description of the rule).
Rule = Callable[[Any], Optional[Tuple[DecodeError, str]]]


def _at_least(lo: float) -> Rule:
    return lambda v: None if v >= lo else (DecodeError.OUT_OF_RANGE, f"must be >= {lo:g}")


def _in_range(lo: float, hi: float) -> Rule:
    return lambda v: None if lo <= v <= hi else (DecodeError.OUT_OF_RANGE, f"allowed {lo:g}..{hi:g}")


def _metres(v: float) -> Optional[Tuple[DecodeError, str]]:
    return None if 0 < v <= 100 else (DecodeError.OUT_OF_RANGE, "allowed (0, 100] metres")


def _flag_bits(mask: int) -> Rule:
    return lambda v: None if v & ~mask == 0 else (DecodeError.RESERVED_NOT_ZERO, f"undefined flag bits set (allowed mask 0x{mask:x})")


def _streams_subscribe(v: int) -> Optional[Tuple[DecodeError, str]]:
    if v == 0 or v & ~STREAM_MASK:
        return DecodeError.OUT_OF_RANGE, f"must be non-zero with no bit outside 0x{STREAM_MASK:x}"
    return None


def _streams_granted(v: int) -> Optional[Tuple[DecodeError, str]]:
    return None if v & ~STREAM_MASK == 0 else (DecodeError.OUT_OF_RANGE, f"no bit outside 0x{STREAM_MASK:x}")


def _event_flags(v: int) -> Optional[Tuple[DecodeError, str]]:
    if v & ~(EVENT_PROVISIONAL | EVENT_RETRACTED):
        return DecodeError.RESERVED_NOT_ZERO, "bits 2-7 must be zero"
    if v == EVENT_RETRACTED:
        return DecodeError.OUT_OF_RANGE, "retracted (0x02) only together with provisional (0x01)"
    return None


def _non_zero(v: int) -> Optional[Tuple[DecodeError, str]]:
    return None if v != 0 else (DecodeError.OUT_OF_RANGE, "must be non-zero")


def _enum(kind: type, lo: int, hi: int) -> Rule:
    return lambda v: None if lo <= v <= hi else (DecodeError.OUT_OF_RANGE, f"allowed {lo}..{hi} ({kind.__name__})")


@dataclass(frozen=True)
class _Num:
    name: str
    offset: int
    fmt: str  # struct format character
    rules: Tuple[Rule, ...] = ()
    convert: Optional[type] = None  # an IntEnum to wrap the value in


@dataclass(frozen=True)
class _Bytes:
    name: str
    offset: int
    size: int


@dataclass(frozen=True)
class _Text:
    name: str
    offset: int
    size: int
    label: bool = False  # MARKER label: 1..size-1 bytes of printable UTF-8


@dataclass(frozen=True)
class _Reserved:
    offset: int
    size: int


@dataclass(frozen=True)
class _Check:
    """A rule between fields, applied at this point of the field order and reported at `offset`."""

    name: str
    offset: int
    rule: Callable[[Dict[str, Any]], Optional[Tuple[DecodeError, str]]]


def _display(prefix: str, off: int) -> List[Any]:
    px = _in_range(1, 65536)
    return [_Num(f"{prefix}.width_px", off, "I", (px,)), _Num(f"{prefix}.height_px", off + 4, "I", (px,)),
            _Num(f"{prefix}.width_m", off + 8, "d", (_metres,)), _Num(f"{prefix}.height_m", off + 16, "d", (_metres,)),
            _Num(f"{prefix}.viewing_distance_m", off + 24, "d", (_metres,))]


def _eye(prefix: str, off: int) -> List[Any]:
    return [_Num(f"{prefix}.pupil_x_px", off, "f"), _Num(f"{prefix}.pupil_y_px", off + 4, "f"),
            _Num(f"{prefix}.pupil_diameter_mm", off + 8, "f", (_at_least(0),)),
            _Num(f"{prefix}.pupil_glint_x_px", off + 12, "f"), _Num(f"{prefix}.pupil_glint_y_px", off + 16, "f")]


def _eye_gaze(prefix: str, off: int) -> List[Any]:
    return [_Num(f"{prefix}.x", off, "f"), _Num(f"{prefix}.y", off + 4, "f"), _Num(f"{prefix}.x_deg", off + 8, "f"),
            _Num(f"{prefix}.y_deg", off + 12, "f"), _Check(f"{prefix}.x", off, _invalid_eye_is_zero(prefix))]


def _invalid_eye_is_zero(prefix: str) -> Callable[[Dict[str, Any]], Optional[Tuple[DecodeError, str]]]:
    def rule(values: Dict[str, Any]) -> Optional[Tuple[DecodeError, str]]:
        if values[f"{prefix}.flags"] & EYE_GAZE_VALID:
            return None
        if any(values[f"{prefix}.{k}"] != 0 for k in ("x", "y", "x_deg", "y_deg")):
            return DecodeError.OUT_OF_RANGE, "an eye without the valid bit carries zeros"
        return None
    return rule


def _some_eye_valid(values: Dict[str, Any]) -> Optional[Tuple[DecodeError, str]]:
    if (values["left.flags"] | values["right.flags"]) & EYE_GAZE_VALID:
        return None
    return DecodeError.OUT_OF_RANGE, "neither eye is valid"


def _marker_time(values: Dict[str, Any]) -> Optional[Tuple[DecodeError, str]]:
    if values["flags"] & MARKER_CLIENT_TIME == 0 and values["time_ns"] != values["received_ns"]:
        return DecodeError.OUT_OF_RANGE, "without flag bit 0 time_ns must equal received_ns"
    return None


_RATE = (_at_least(0),)
_EYE_FLAGS = _flag_bits(EYE_PUPIL_VALID | EYE_GLINT_VALID)

# Payload layouts, offsets within the payload, in the order the reference decoder checks them.
_LAYOUTS: Dict[MessageType, Tuple[type, int, List[Any]]] = {
    MessageType.HELLO: (Hello, 48, [
        _Num("client_nonce", 0, "Q"), _Text("client_name", 8, 32), _Reserved(40, 8)]),
    MessageType.CHALLENGE: (Challenge, 32, [
        _Num("client_nonce", 0, "Q"), _Bytes("cookie", 8, 16), _Num("cookie_lifetime_ms", 24, "I"),
        _Reserved(28, 4)]),
    MessageType.SUBSCRIBE: (Subscribe, 32, [
        _Bytes("cookie", 0, 16), _Num("client_nonce", 16, "Q"), _Num("streams", 24, "I", (_streams_subscribe,)),
        _Num("requested_lease_ms", 28, "I")]),
    MessageType.SUBSCRIBED: (Subscribed, 80, [
        _Num("session_id", 0, "Q"), _Num("streams", 8, "I", (_streams_granted,)), _Num("lease_ms", 12, "I"),
        _Num("nominal_rate_hz", 16, "d", _RATE), _Num("next_sample_sequence", 24, "Q"),
        _Num("next_event_sequence", 32, "Q"), *_display("display", 40), _Num("multicast_group", 72, "I"),
        _Num("multicast_port", 76, "H"), _Num("multicast_ttl", 78, "B"), _Reserved(79, 1)]),
    MessageType.HEARTBEAT: (Heartbeat, 16, [
        _Num("session_id", 0, "Q"), _Num("lease_ms", 8, "I"), _Reserved(12, 4)]),
    MessageType.UNSUBSCRIBE: (Unsubscribe, 8, [_Num("session_id", 0, "Q")]),
    MessageType.GAZE_SAMPLE: (GazeSample, 76, [
        _Num("tracker_time_ns", 0, "q"), _Num("x", 8, "f"), _Num("y", 12, "f"), _Num("x_deg", 16, "f"),
        _Num("y_deg", 20, "f"), _Num("angular_velocity_deg_s", 24, "f", (_at_least(0),)),
        _Num("confidence", 28, "f", (_in_range(0, 1),)),
        _Num("state", 32, "B", (_enum(EyeMovement, 0, 4),), EyeMovement),
        _Num("flags", 33, "B", (_flag_bits(GAZE_VALID),)),
        _Num("left.flags", 34, "B", (_EYE_FLAGS,)), *_eye("left", 36),
        _Num("right.flags", 35, "B", (_EYE_FLAGS,)), *_eye("right", 56)]),
    MessageType.GAZE_EVENT: (GazeEvent, 48, [
        _Num("kind", 0, "B", (_enum(EyeMovement, 1, 4),), EyeMovement),
        _Num("phase", 1, "B", (_enum(EventPhase, 1, 2),), EventPhase),
        _Num("flags", 2, "B", (_event_flags,)), _Reserved(3, 5), _Num("start_time_ns", 8, "q"),
        _Num("duration_ns", 16, "q", (_at_least(0),)), _Num("centroid_x", 24, "f"), _Num("centroid_y", 28, "f"),
        _Num("centroid_x_deg", 32, "f"), _Num("centroid_y_deg", 36, "f"),
        _Num("amplitude_deg", 40, "f", (_at_least(0),)), _Num("peak_velocity_deg_s", 44, "f", (_at_least(0),))]),
    MessageType.STATUS_REQUEST: (StatusRequest, 128, [_Reserved(0, 128)]),
    MessageType.STATUS_REPLY: (StatusReply, 128, [
        _Text("source", 0, 48), _Num("nominal_rate_hz", 48, "d", _RATE), _Num("uptime_ns", 56, "q", (_at_least(0),)),
        _Num("samples_published", 64, "Q"), _Num("events_published", 72, "Q"), _Num("datagrams_rejected", 80, "Q"),
        _Num("subscribers", 88, "I"), _Num("source_state", 92, "B", (_enum(SourceState, 0, 2),), SourceState),
        _Reserved(93, 3), *_display("display", 96)]),
    MessageType.TIME_SYNC_REQUEST: (TimeSyncRequest, 24, [_Num("client_send_ns", 0, "q"), _Reserved(8, 16)]),
    MessageType.TIME_SYNC_REPLY: (TimeSyncReply, 24, [
        _Num("client_send_ns", 0, "q"), _Num("server_receive_ns", 8, "q"), _Num("server_send_ns", 16, "q")]),
    MessageType.ERROR: (Error, 8, [
        _Num("code", 0, "H", (_enum(ErrorCode, 1, 8),), ErrorCode),
        _Num("request_type", 2, "B", (_enum(MessageType, 1, 17),), MessageType),
        _Num("supported_version", 3, "B"), _Reserved(4, 4)]),
    MessageType.CONTROL_REQUEST: (ControlRequest, 72, [
        _Num("command", 0, "B", (_enum(ControlCommand, 1, 4),), ControlCommand), _Reserved(1, 7),
        _Text("argument", 8, 64)]),
    MessageType.CONTROL_REPLY: (ControlReply, 72, [
        _Num("command", 0, "B", (_enum(ControlCommand, 1, 4),), ControlCommand),
        _Num("result", 1, "B", (_enum(ControlResult, 0, 2),), ControlResult), _Reserved(2, 6),
        _Text("message", 8, 64)]),
    MessageType.MARKER: (Marker, 104, [
        _Num("session_id", 0, "Q"), _Num("marker_id", 8, "Q", (_non_zero,)), _Num("time_ns", 16, "q"),
        _Num("received_ns", 24, "q"), _Num("flags", 32, "B", (_flag_bits(MARKER_CLIENT_TIME),)),
        _Check("time_ns", 16, _marker_time), _Reserved(33, 7), _Text("label", 40, 64, label=True)]),
    MessageType.GAZE_EYES: (GazeEyes, 48, [
        _Num("tracker_time_ns", 0, "q"), _Num("left.flags", 8, "B", (_flag_bits(EYE_GAZE_VALID),)),
        _Num("right.flags", 9, "B", (_flag_bits(EYE_GAZE_VALID),)), _Reserved(10, 6), *_eye_gaze("left", 16),
        *_eye_gaze("right", 32), _Check("left.flags", 8, _some_eye_valid)]),
}

_TYPE_OF_CLASS = {cls: t for t, (cls, _, _) in _LAYOUTS.items()}
_NESTED = {"display": DisplayGeometry, "left": EyeData, "right": EyeData}
_NESTED_IN = {GazeEyes: {"left": EyeGaze, "right": EyeGaze}}  # where a class nests other types


def payload_size(t: Union[MessageType, int]) -> int:
    return _LAYOUTS[MessageType(t)][1]


def type_of(payload: Payload) -> MessageType:
    try:
        return _TYPE_OF_CLASS[type(payload)]
    except KeyError:
        raise TypeError(f"not a fovea protocol payload: {type(payload).__name__}") from None


# ---- decoding -------------------------------------------------------------------------------------


def _label_problem(raw: bytes) -> Optional[Tuple[int, str]]:
    """Where a marker label stops being printable UTF-8 (PROTOCOL.md section 4.17), or None."""
    if not raw:
        return 0, "must hold 1..63 bytes"
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        return e.start, f"byte {e.start} is not UTF-8"
    at = 0
    for ch in text:
        cp = ord(ch)
        if cp < 0x20 or 0x7F <= cp <= 0x9F:
            return at, f"byte {at} is a control character (U+{cp:04X})"
        at += len(ch.encode("utf-8"))
    return None


def _read_text(buf: bytes, f: _Text, base: int, msg: str) -> str:
    chunk = buf[f.offset:f.offset + f.size]
    end = chunk.find(b"\0")
    if end < 0:
        raise ProtocolError(DecodeError.BAD_STRING, base + f.offset, f.name,
                            f"no terminating NUL in {f.size} bytes", msg)
    bad = next((i for i in range(end, f.size) if chunk[i]), None)
    if bad is not None:
        raise ProtocolError(DecodeError.BAD_STRING, base + f.offset + bad, f.name,
                            "non-NUL byte after the terminating NUL", msg)
    raw = chunk[:end]
    if f.label:
        problem = _label_problem(raw)
        if problem:
            raise ProtocolError(DecodeError.BAD_STRING, base + f.offset + problem[0], f.name, problem[1], msg)
    # surrogateescape: free-text fields need not be UTF-8 on the wire, and must encode back unchanged.
    return raw.decode("utf-8", "surrogateescape")


def _read_num(buf: bytes, f: _Num, base: int, msg: str) -> Any:
    value = struct.unpack_from("<" + f.fmt, buf, f.offset)[0]
    if f.fmt in "fd" and not math.isfinite(value):
        raise ProtocolError(DecodeError.NON_FINITE, base + f.offset, f.name, f"{value} is not finite", msg)
    for rule in f.rules:
        broken = rule(value)
        if broken:
            raise ProtocolError(broken[0], base + f.offset, f.name, f"{value!r}: {broken[1]}", msg)
    return f.convert(value) if f.convert else value


def _read_reserved(buf: bytes, f: _Reserved, base: int, msg: str) -> None:
    for i in range(f.offset, f.offset + f.size):
        if buf[i]:
            raise ProtocolError(DecodeError.RESERVED_NOT_ZERO, base + i, "reserved",
                                f"byte is 0x{buf[i]:02x}, must be zero", msg)


def _build(cls: type, values: Dict[str, Any]) -> Any:
    top: Dict[str, Any] = {}
    nested: Dict[str, Dict[str, Any]] = {}
    for name, value in values.items():
        outer, _, inner = name.partition(".")
        if inner:
            nested.setdefault(outer, {})[inner] = value
        else:
            top[name] = value
    for outer, fields in nested.items():
        top[outer] = _NESTED_IN.get(cls, _NESTED)[outer](**fields)
    return cls(**top)


def decode_payload(t: Union[MessageType, int], payload: bytes, base_offset: int = 0) -> Payload:
    """Decodes and validates one payload of type `t`; offsets in errors are `base_offset` + payload offset."""
    try:
        t = MessageType(t)
    except ValueError:
        raise ProtocolError(DecodeError.UNKNOWN_TYPE, 0, "type", f"{t} is not a message type (1..17)") from None
    cls, size, layout = _LAYOUTS[t]
    msg = t.name
    if len(payload) != size:
        raise ProtocolError(DecodeError.BAD_PAYLOAD_LENGTH, base_offset, "payload",
                            f"{len(payload)} bytes, {msg} has {size}", msg)
    values: Dict[str, Any] = {}
    for f in layout:
        if isinstance(f, _Num):
            values[f.name] = _read_num(payload, f, base_offset, msg)
        elif isinstance(f, _Text):
            values[f.name] = _read_text(payload, f, base_offset, msg)
        elif isinstance(f, _Bytes):
            values[f.name] = bytes(payload[f.offset:f.offset + f.size])
        elif isinstance(f, _Reserved):
            _read_reserved(payload, f, base_offset, msg)
        else:
            broken = f.rule(values)
            if broken:
                raise ProtocolError(broken[0], base_offset + f.offset, f.name, broken[1], msg)
    return _build(cls, values)


def decode(datagram: bytes) -> Message:
    """Decodes one datagram with every check of PROTOCOL.md section 5, in its order; raises ProtocolError."""
    n = len(datagram)
    if n > MAX_DATAGRAM_SIZE:
        raise ProtocolError(DecodeError.TOO_LONG, MAX_DATAGRAM_SIZE, "datagram", f"{n} bytes, at most {MAX_DATAGRAM_SIZE}")
    if n < HEADER_SIZE:
        raise ProtocolError(DecodeError.TOO_SHORT, n, "datagram", f"{n} bytes, shorter than the {HEADER_SIZE}-byte header")
    for i in range(4):
        if datagram[i] != MAGIC[i]:
            raise ProtocolError(DecodeError.BAD_MAGIC, i, "magic", f"{bytes(datagram[:4])!r} is not b'FVGZ'")
    if datagram[4] != VERSION:
        raise ProtocolError(DecodeError.BAD_VERSION, 4, "version", f"{datagram[4]}, this decoder speaks {VERSION}")
    raw_type = datagram[5]
    if not 1 <= raw_type <= 17:
        raise ProtocolError(DecodeError.UNKNOWN_TYPE, 5, "type", f"{raw_type} is not a message type (1..17)")
    t = MessageType(raw_type)
    length, sequence, origin, send = struct.unpack_from("<HQqq", datagram, 6)
    size = payload_size(t)
    if length != size:
        raise ProtocolError(DecodeError.BAD_PAYLOAD_LENGTH, 6, "payload_length", f"{length}, {t.name} has {size}", t.name)
    if n < HEADER_SIZE + length:
        raise ProtocolError(DecodeError.TOO_SHORT, n, "datagram", f"{n} bytes, {t.name} has {HEADER_SIZE + length}", t.name)
    if n > HEADER_SIZE + length:
        raise ProtocolError(DecodeError.TOO_LONG, HEADER_SIZE + length, "datagram",
                            f"{n} bytes, {t.name} has {HEADER_SIZE + length}", t.name)
    payload = decode_payload(t, bytes(datagram[HEADER_SIZE:]), HEADER_SIZE)
    return Message(Header(sequence, origin, send), payload)


# ---- encoding -------------------------------------------------------------------------------------


def _get(payload: Any, name: str) -> Any:
    for part in name.split("."):
        payload = getattr(payload, part)
    return payload


def _write_text(buf: bytearray, f: _Text, value: str, msg: str) -> None:
    raw = value.encode("utf-8", "surrogateescape")
    if len(raw) >= f.size:
        raise ProtocolError(DecodeError.BAD_STRING, f.offset, f.name,
                            f"{value!r} is {len(raw)} bytes, at most {f.size - 1} fit", msg)
    if b"\0" in raw:
        raise ProtocolError(DecodeError.BAD_STRING, f.offset + raw.index(b"\0"), f.name, "text contains a NUL byte", msg)
    buf[f.offset:f.offset + len(raw)] = raw


def _write_num(buf: bytearray, f: _Num, value: Any, msg: str) -> None:
    try:
        struct.pack_into("<" + f.fmt, buf, f.offset, value)
    except (struct.error, OverflowError, TypeError) as e:
        raise ProtocolError(DecodeError.OUT_OF_RANGE, f.offset, f.name, f"{value!r} does not fit ({e})", msg) from None


def encode_payload(payload: Payload) -> bytes:
    """The payload's bytes; raises ProtocolError for anything the decoder would reject."""
    t = type_of(payload)
    _, size, layout = _LAYOUTS[t]
    buf = bytearray(size)
    for f in layout:
        if isinstance(f, _Num):
            _write_num(buf, f, _get(payload, f.name), t.name)
        elif isinstance(f, _Text):
            _write_text(buf, f, _get(payload, f.name), t.name)
        elif isinstance(f, _Bytes):
            raw = bytes(_get(payload, f.name))
            if len(raw) != f.size:
                raise ProtocolError(DecodeError.OUT_OF_RANGE, f.offset, f.name, f"{len(raw)} bytes, must be {f.size}", t.name)
            buf[f.offset:f.offset + f.size] = raw
    # Nothing invalid reaches the wire or a file: check what was written with the decoder's rules.
    decode_payload(t, bytes(buf))
    return bytes(buf)


def encode(payload: Union[Payload, Message], sequence: int = 0, origin_time_ns: int = 0, send_time_ns: int = 0) -> bytes:
    """A whole datagram: header (from a Message, or the keyword values) and payload."""
    if isinstance(payload, Message):
        sequence, origin_time_ns, send_time_ns = (payload.header.sequence, payload.header.origin_time_ns,
                                                  payload.header.send_time_ns)
        payload = payload.payload
    body = encode_payload(payload)
    t = type_of(payload)
    try:
        header = struct.pack("<4sBBHQqq", MAGIC, VERSION, t, len(body), sequence, origin_time_ns, send_time_ns)
    except struct.error as e:
        raise ProtocolError(DecodeError.OUT_OF_RANGE, 8, "header", f"sequence or times do not fit ({e})", t.name) from None
    return header + body


def check_marker_label(label: str) -> None:
    """Raises ValueError unless `label` is 1..63 bytes of UTF-8 without control characters."""
    raw = label.encode("utf-8", "surrogateescape")
    if not 1 <= len(raw) <= 63:
        raise ValueError(f"marker label must be 1..63 bytes; {label!r} is {len(raw)}")
    problem = _label_problem(raw)
    if problem:
        raise ValueError(f"marker label {label!r}: {problem[1]}")


def replace(payload: Any, **changes: Any) -> Any:
    """dataclasses.replace, re-exported for callers that build variants of a message."""
    return dataclasses.replace(payload, **changes)
