# SPDX-License-Identifier: Apache-2.0
"""GazeClient: subscribes to fovea-trackerd, keeps the subscription alive, resubscribes by itself.

Behaviour follows the reference client (protocol/src/client.cpp, PROTOCOL.md sections 6.6, 10, 11
and 15): handshake with retransmission, heartbeats, a fresh handshake after silence or a refused
session, per-stream sequence tracking, NTP-style clock offset, and markers retransmitted until
their copy comes back on the marker stream.

All network work happens on one background thread; callbacks run on that thread, so keep them
short (hand work to your own thread or queue) or the receive buffer may overflow.
"""

from __future__ import annotations

import collections
import os
import select
import socket
import struct
import threading
import time
from dataclasses import dataclass, field, replace
from typing import Callable, Deque, Dict, List, Optional, Tuple

from . import protocol
from .protocol import (DEFAULT_PORT, MARKER_CLIENT_TIME, STREAM_EVENTS, STREAM_EYES, STREAM_MARKERS,
                       STREAM_PROVISIONAL, STREAM_SAMPLES, Challenge, ErrorCode, GazeEvent, GazeSample, Heartbeat, Hello, Marker,
                       Message, MessageType, ProtocolError, StatusReply, StatusRequest, Subscribe, Subscribed,
                       TimeSyncReply, TimeSyncRequest, Unsubscribe)

_MS = 1_000_000
_REFUSED_BACKOFF_NS = 2000 * _MS
_SUBSCRIBE_RESENDS = 10
_TIME_SYNC_KEEP = 8
_TIME_SYNC_FAST = 4  # replies accepted at 50 ms intervals before slowing to one per 2 s
_MARKER_RESEND_NS = 250 * _MS
_MARKER_ATTEMPTS = 8
_MARKER_PENDING_LIMIT = 4096
_SESSION_ERRORS = (ErrorCode.UNKNOWN_SESSION, ErrorCode.BAD_COOKIE, ErrorCode.COOKIE_EXPIRED,
                   ErrorCode.ADDRESS_MISMATCH)
_BACKOFF_ERRORS = (ErrorCode.TOO_MANY_SUBSCRIBERS, ErrorCode.UNSUPPORTED_VERSION)


def monotonic_ns() -> int:
    """This host's CLOCK_MONOTONIC in ns: the clock the protocol's client times are on."""
    return time.clock_gettime_ns(time.CLOCK_MONOTONIC)


def _random_id() -> int:
    while True:
        v = int.from_bytes(os.urandom(8), "little")
        if v:
            return v


# ---- sequence tracking ----------------------------------------------------------------------------


@dataclass
class SequenceCounts:
    received: int = 0
    lost: int = 0
    duplicated: int = 0
    reordered: int = 0
    implausible: int = 0
    resyncs: int = 0


class SequenceTracker:
    """Classifies arrivals of one stream as new, lost, duplicate or reordered (PROTOCOL.md section 10).

    A port of protocol/src/sequence_tracker.cpp: a 64-entry window; a jump of more than 2^24 is not
    taken on trust until 8 such arrivals that follow each other show the stream really moved.
    """

    NEW, DUPLICATE, REORDERED, TOO_OLD, IMPLAUSIBLE = "new", "duplicate", "reordered", "too old", "implausible"
    MAX_PLAUSIBLE_JUMP = 1 << 24
    RESYNC_RUN = 8
    _WINDOW_MASK = (1 << 64) - 1

    def __init__(self) -> None:
        self.counts = SequenceCounts()
        self._started = False
        self._from_first = False
        self._base = 0
        self._highest = 0
        self._window = 0
        self._run_last = 0
        self._run_length = 0

    def reset(self, first_expected: int) -> None:
        """A new session; arrivals before `first_expected` are too old. A plausible jump ahead of what
        was already followed counts the items published in between as lost."""
        if (self._started and first_expected > self._highest + 1
                and first_expected - self._highest <= self.MAX_PLAUSIBLE_JUMP):
            self.counts.lost += first_expected - self._highest - 1
        self._started = False
        self._from_first = False
        self._base = first_expected
        self._highest = 0
        self._window = 0
        self._run_length = 0

    def reset_from_first_arrival(self) -> None:
        """A new session of a stream whose next number the server does not say (markers, provisional)."""
        self.reset(0)
        self._from_first = True

    def _start_at(self, seq: int) -> None:
        self._started = True
        self._highest = seq
        self._window = 1
        self._run_length = 0
        self.counts.received += 1

    def _implausible(self, seq: int) -> str:
        self.counts.implausible += 1
        follows = self._run_length > 0 and seq > self._run_last and seq - self._run_last < 64
        self._run_length = self._run_length + 1 if follows else 1
        self._run_last = seq
        if self._run_length < self.RESYNC_RUN:
            return self.IMPLAUSIBLE
        self.counts.resyncs += 1
        self.counts.implausible -= self.RESYNC_RUN
        self.counts.received += self.RESYNC_RUN - 1  # the run's earlier members
        self._base = seq - (self.RESYNC_RUN - 1)
        self._start_at(seq)
        return self.NEW

    def on_arrival(self, seq: int) -> str:
        if seq < self._base:
            return self.TOO_OLD
        if not self._started and self._from_first:
            self._from_first = False
            self._base = seq
        if not self._started:
            if seq - self._base > self.MAX_PLAUSIBLE_JUMP:
                return self._implausible(seq)
            self.counts.lost += seq - self._base  # published between subscription and first arrival
            self._start_at(seq)
            return self.NEW
        if seq > self._highest:
            gap = seq - self._highest
            if gap > self.MAX_PLAUSIBLE_JUMP:
                return self._implausible(seq)
            self._run_length = 0
            self.counts.lost += gap - 1
            self._window = 1 if gap >= 64 else ((self._window << gap) | 1) & self._WINDOW_MASK
            self._highest = seq
            self.counts.received += 1
            return self.NEW
        age = self._highest - seq
        if age >= 64:
            return self.TOO_OLD
        self._run_length = 0
        bit = 1 << age
        if self._window & bit:
            self.counts.duplicated += 1
            return self.DUPLICATE
        self._window |= bit
        self.counts.reordered += 1
        self.counts.received += 1
        if self.counts.lost > 0:
            self.counts.lost -= 1
        return self.REORDERED


_DROPPED = (SequenceTracker.DUPLICATE, SequenceTracker.TOO_OLD, SequenceTracker.IMPLAUSIBLE)


# ---- time sync ------------------------------------------------------------------------------------


class ClockSync:
    """Server-minus-client clock offset from TIME_SYNC exchanges (PROTOCOL.md section 11).

    Keeps the last 8 accepted exchanges; the offset is that of the least-delay exchange among those
    within their own delay (1 ms at least) of the median offset, so a minority of bad replies
    cannot move it.
    """

    MAX_TIME = 1 << 60
    MAX_DELAY_NS = 10_000_000_000

    def __init__(self) -> None:
        self.offset_ns = 0
        self.round_trip_ns = -1  # -1 until an exchange has completed
        self.accepted = 0
        self._samples: Deque[Tuple[int, int]] = collections.deque(maxlen=_TIME_SYNC_KEEP)
        self._sent: Deque[int] = collections.deque(maxlen=_TIME_SYNC_KEEP)

    @property
    def known(self) -> bool:
        return self.round_trip_ns >= 0

    def clear(self) -> None:
        self.__init__()

    def request_sent(self, client_send_ns: int) -> None:
        self._sent.append(client_send_ns)

    def on_reply(self, t: TimeSyncReply, t4: int) -> bool:
        """Takes one reply received at client time t4; False when it was not acceptable."""
        if t.client_send_ns not in self._sent:
            return False  # not an answer to a request of ours
        self._sent.remove(t.client_send_ns)
        t1, t2, t3 = t.client_send_ns, t.server_receive_ns, t.server_send_ns
        if not (-self.MAX_TIME <= t2 <= self.MAX_TIME and -self.MAX_TIME <= t3 <= self.MAX_TIME):
            return False
        delay = (t4 - t1) - (t3 - t2)
        if not 0 <= delay <= self.MAX_DELAY_NS:
            return False
        self.accepted += 1
        self._samples.append((_trunc_half(t2 - t1) + _trunc_half(t3 - t4), delay))
        self._choose()
        return True

    def _choose(self) -> None:
        offsets = sorted(o for o, _ in self._samples)
        median = offsets[len(offsets) // 2]
        agreeing = [(d, o) for o, d in self._samples if abs(o - median) <= max(d, _MS)]
        if agreeing:
            self.round_trip_ns, self.offset_ns = min(agreeing)
        else:
            self.offset_ns, self.round_trip_ns = median, self._samples[-1][1]

    def to_client_ns(self, server_ns: int) -> int:
        return server_ns - self.offset_ns

    def to_server_ns(self, client_ns: int) -> int:
        return client_ns + self.offset_ns


def _trunc_half(v: int) -> int:
    """v / 2 truncated toward zero, as C++ integer division (PROTOCOL.md section 11)."""
    return -((-v) // 2) if v < 0 else v // 2


# ---- public value types ---------------------------------------------------------------------------


@dataclass
class Arrival:
    """What a callback or queue entry carries besides the message itself."""

    sequence: int = 0
    receive_ns: int = 0  # client clock (CLOCK_MONOTONIC)
    latency_ns: int = 0  # receive time minus the server's send time mapped to our clock
    host_receive_ns: int = 0  # GAZE_SAMPLE: when the sample reached the daemon (daemon clock)


@dataclass
class ClientStats:
    samples: SequenceCounts = field(default_factory=SequenceCounts)
    events: SequenceCounts = field(default_factory=SequenceCounts)
    markers: SequenceCounts = field(default_factory=SequenceCounts)
    provisional: SequenceCounts = field(default_factory=SequenceCounts)
    markers_sent: int = 0
    markers_confirmed: int = 0
    markers_unconfirmed: int = 0
    eye_samples: int = 0  # samples delivered with their GAZE_EYES (STREAM_EYES)
    rejected: int = 0  # datagrams that failed to decode, came from elsewhere, or were not ours
    decode_errors: Dict[str, int] = field(default_factory=dict)
    queue_dropped: int = 0
    subscriptions: int = 0
    errors_received: int = 0
    last_error: Optional[ErrorCode] = None
    clock_offset_ns: int = 0  # server clock minus client clock
    clock_round_trip_ns: int = -1


@dataclass
class _PendingMarker:
    marker: Marker
    sent_ns: int
    attempts: int = 1


_HELLO, _SUBSCRIBE, _SUBSCRIBED = "hello", "subscribe", "subscribed"


class GazeClient:
    """A subscription to fovea-trackerd.

    >>> with GazeClient("127.0.0.1", 47800) as client:
    ...     client.wait_subscribed(2.0)
    ...     sample = client.latest()

    streams: STREAM_SAMPLES | STREAM_EVENTS by default; add STREAM_MARKERS to receive markers (and to
    have mark() retransmit until confirmed), or pass provisional=True for provisional events. With
    STREAM_EYES, samples from a binocular source carry each eye's gaze (left_gaze, right_gaze).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, *,
                 streams: int = STREAM_SAMPLES | STREAM_EVENTS, provisional: bool = False,
                 lease_ms: int = 5000, heartbeat_interval_s: float = 0.5, retry_interval_s: float = 0.2,
                 name: str = "fovea-python", queue_size: int = 4096,
                 on_sample: Optional[Callable[[GazeSample, Arrival], None]] = None,
                 on_event: Optional[Callable[[GazeEvent, Arrival], None]] = None,
                 on_marker: Optional[Callable[[Marker, Arrival], None]] = None,
                 start: bool = True):
        if provisional:
            streams |= STREAM_PROVISIONAL
        if streams == 0 or streams & ~protocol.STREAM_MASK:
            raise ValueError(f"streams = 0x{streams:x}: non-zero, bits of 0x{protocol.STREAM_MASK:x} only")
        self.server = (socket.gethostbyname(host), port)
        self.streams = streams
        self.lease_ms = lease_ms
        self.name = name
        self.on_sample, self.on_event, self.on_marker = on_sample, on_event, on_marker
        self._heartbeat_ns = int(heartbeat_interval_s * 1e9)
        self._retry_ns = int(retry_interval_s * 1e9)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        # One socket for everything: the cookie and the session are bound to its address and port.
        self._sock.bind(("0.0.0.0", 0))
        self._sock.setblocking(False)
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._send_lock = threading.Lock()
        self._state = _HELLO
        self._nonce = 0
        self._cookie = bytes(16)
        self._request_seq = 0
        self._last_sent_ns = 0
        self._retry_after_ns = 0
        self._last_heard_ns = 0
        self._next_time_sync_ns = 0
        self._subscribe_attempts = 0
        self._session: Optional[Subscribed] = None
        self._latest: Optional[GazeSample] = None
        self._pending_eyes: Optional[Tuple[int, protocol.GazeEyes]] = None
        self._latest_arrival: Optional[Arrival] = None
        self._samples: Deque[Tuple[GazeSample, Arrival]] = collections.deque()
        self._events: Deque[Tuple[object, Arrival]] = collections.deque()
        self._queue_size = queue_size
        self._trackers = {s: SequenceTracker() for s in (STREAM_SAMPLES, STREAM_EVENTS, STREAM_MARKERS,
                                                          STREAM_PROVISIONAL)}
        self._clock = ClockSync()
        self._pending: List[_PendingMarker] = []
        self._confirmed: Deque[Marker] = collections.deque(maxlen=64)
        self._stats = ClientStats()
        self._running = False
        self._thread: Optional[threading.Thread] = None
        if start:
            self.start()

    # ---- life cycle ----

    def start(self) -> None:
        if self._running:
            return
        self._running = True
        self._thread = threading.Thread(target=self._loop, name="fovea-client", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stops the thread and sends one UNSUBSCRIBE (no reply comes; the lease covers a lost one)."""
        if not self._running:
            return
        self._running = False
        if self._thread is not None:
            self._thread.join()
        session = self.session
        if session is not None:
            self._send(Unsubscribe(session.session_id))
        with self._lock:
            self._state = _HELLO
            self._changed.notify_all()
        self._sock.close()

    stop = close

    def __enter__(self) -> "GazeClient":
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- what the application reads ----

    @property
    def subscribed(self) -> bool:
        return self._state == _SUBSCRIBED

    @property
    def session(self) -> Optional[Subscribed]:
        """The last SUBSCRIBED: session id, lease, rate, display geometry, multicast group."""
        with self._lock:
            return self._session

    def wait_subscribed(self, timeout: float) -> bool:
        with self._lock:
            return self._changed.wait_for(lambda: self._state == _SUBSCRIBED, timeout)

    def latest(self) -> Optional[GazeSample]:
        """The most recent sample (None before the first); for once-per-frame use."""
        with self._lock:
            return self._latest

    def latest_with_arrival(self) -> Optional[Tuple[GazeSample, Arrival]]:
        with self._lock:
            return None if self._latest is None else (self._latest, self._latest_arrival)

    def poll_samples(self, max_items: Optional[int] = None) -> List[Tuple[GazeSample, Arrival]]:
        """Queued samples, oldest first (the oldest are dropped beyond queue_size)."""
        return self._drain(self._samples, max_items)

    def poll_events(self, max_items: Optional[int] = None) -> List[Tuple[object, Arrival]]:
        """Queued GazeEvents (final and, if subscribed, provisional) and Markers, in arrival order."""
        return self._drain(self._events, max_items)

    def stats(self) -> ClientStats:
        with self._lock:
            s = replace(self._stats, decode_errors=dict(self._stats.decode_errors))
            s.samples = replace(self._trackers[STREAM_SAMPLES].counts)
            s.events = replace(self._trackers[STREAM_EVENTS].counts)
            s.markers = replace(self._trackers[STREAM_MARKERS].counts)
            s.provisional = replace(self._trackers[STREAM_PROVISIONAL].counts)
            s.clock_offset_ns = self._clock.offset_ns
            s.clock_round_trip_ns = self._clock.round_trip_ns
            return s

    # ---- clocks ----

    @property
    def clock_known(self) -> bool:
        with self._lock:
            return self._clock.known

    def wait_clock(self, timeout: float, exchanges: int = 1) -> bool:
        """Waits until `exchanges` TIME_SYNC exchanges of this session have been accepted.

        One gives an offset good to half its round trip; the first 4 come 50 ms apart, and with
        `exchanges=4` the offset is the least-delay one of them (what `fovea-ctl mark --time-ns`
        waits for): use it before marking with a `client_time_ns`. The offset's error is then at
        most `stats().clock_round_trip_ns / 2`.
        """
        if exchanges < 1:
            raise ValueError(f"wait_clock: exchanges must be at least 1, not {exchanges}")
        with self._lock:
            return self._changed.wait_for(lambda: self._clock.accepted >= exchanges, timeout)

    def to_client_ns(self, server_ns: int) -> int:
        """A daemon time (sample, event, marker) on this host's CLOCK_MONOTONIC."""
        with self._lock:
            return self._clock.to_client_ns(server_ns)

    def to_server_ns(self, client_ns: int) -> int:
        """A time of this host's CLOCK_MONOTONIC on the daemon's clock."""
        with self._lock:
            return self._clock.to_server_ns(client_ns)

    # ---- markers ----

    def mark(self, label: str, client_time_ns: Optional[int] = None) -> int:
        """Sends an experiment marker (PROTOCOL.md section 4.17); returns its marker_id.

        Without a time the daemon stamps it on arrival; with `client_time_ns` (this host's
        CLOCK_MONOTONIC, e.g. a display flip) it is mapped to the daemon's clock. With STREAM_MARKERS
        in the subscription it is resent every 250 ms until its copy comes back (at most 8 sends).
        Raises ValueError for a bad label, RuntimeError when not subscribed or (with a time) before
        the clock offset is known.
        """
        protocol.check_marker_label(label)
        with self._lock:
            if self._session is None or self._state != _SUBSCRIBED:
                raise RuntimeError("mark: not subscribed to a daemon")
            marker = Marker(session_id=self._session.session_id, marker_id=_random_id(), label=label)
            if client_time_ns is not None:
                if not self._clock.known:
                    raise RuntimeError("mark: the daemon's clock offset is not known yet")
                marker.flags = MARKER_CLIENT_TIME
                marker.time_ns = self._clock.to_server_ns(client_time_ns)
            self._stats.markers_sent += 1
            if self.streams & STREAM_MARKERS and len(self._pending) < _MARKER_PENDING_LIMIT:
                self._pending.append(_PendingMarker(replace(marker), monotonic_ns()))
        self._send(marker)
        return marker.marker_id

    def wait_marker(self, marker_id: int, timeout: float) -> Optional[Marker]:
        """The marker's copy as the daemon published it, once it came back (needs STREAM_MARKERS)."""
        def found() -> Optional[Marker]:
            return next((m for m in self._confirmed if m.marker_id == marker_id), None)
        with self._lock:
            self._changed.wait_for(lambda: found() is not None, timeout)
            return found()

    def status(self, timeout: float = 1.0) -> Optional[StatusReply]:
        """The daemon's STATUS_REPLY (asked from a separate socket), or None without an answer."""
        return query_status(self.server[0], self.server[1], timeout)

    # ---- the receive thread ----

    def _drain(self, queue: Deque, max_items: Optional[int]) -> list:
        with self._lock:
            n = len(queue) if max_items is None else min(max_items, len(queue))
            return [queue.popleft() for _ in range(n)]

    def _send(self, payload: protocol.Payload) -> None:
        with self._send_lock:
            now = monotonic_ns()
            data = protocol.encode(payload, self._request_seq, now, now)
            self._request_seq += 1
            try:
                self._sock.sendto(data, self.server)
            except OSError:
                pass  # e.g. ECONNREFUSED after an ICMP port unreachable: the retry schedule handles it
            self._last_sent_ns = now

    def _loop(self) -> None:
        self._begin_handshake(monotonic_ns(), fresh=True)
        while self._running:
            self._receive_all(0.01)
            self._run_schedule(monotonic_ns())

    def _receive_all(self, timeout: float) -> None:
        try:
            ready, _, _ = select.select([self._sock], [], [], timeout)
        except (OSError, ValueError):
            return
        for _ in range(256 if ready else 0):  # bounded, so the schedule below keeps running
            try:
                data, sender = self._sock.recvfrom(protocol.MAX_DATAGRAM_SIZE + 1)
            except BlockingIOError:
                return
            except OSError:
                continue  # an ICMP error (port unreachable while the daemon is down) reported on the socket
            self._on_datagram(data, sender, monotonic_ns())

    def _on_datagram(self, data: bytes, sender: Tuple[str, int], now: int) -> None:
        try:
            m = protocol.decode(data)
        except ProtocolError as e:
            with self._lock:
                self._stats.rejected += 1
                self._stats.decode_errors[e.reason.name] = self._stats.decode_errors.get(e.reason.name, 0) + 1
            return
        if sender != self.server:
            with self._lock:
                self._stats.rejected += 1  # not our server: never trusted
            return
        self._handle(m, now)

    def _handle(self, m: Message, now: int) -> None:
        t = m.type
        if t == MessageType.CHALLENGE:
            self._on_challenge(m.payload)
        elif t == MessageType.SUBSCRIBED:
            self._on_subscribed(m.payload, now)
        elif t == MessageType.HEARTBEAT:
            self._last_heard_ns = now
        elif t == MessageType.TIME_SYNC_REPLY:
            self._on_time_sync(m.payload, now)
        elif t == MessageType.ERROR:
            self._on_error(m.payload, now)
        elif t in (MessageType.GAZE_SAMPLE, MessageType.GAZE_EVENT):
            self._on_gaze(m, now)
        elif t == MessageType.MARKER:
            self._on_marker(m, now)
        elif t == MessageType.GAZE_EYES and self._state == _SUBSCRIBED and self.streams & STREAM_EYES:
            with self._lock:
                self._pending_eyes = (m.header.sequence, m.payload)  # joined to the sample that follows
        else:
            with self._lock:
                self._stats.rejected += 1

    def _begin_handshake(self, now: int, fresh: bool) -> None:
        with self._lock:
            self._state = _HELLO
        # Retransmissions keep the nonce, so a CHALLENGE that arrives after the next retry still matches.
        if fresh or self._nonce == 0:
            self._nonce = _random_id()
        name = self.name.encode("utf-8")[:31].decode("utf-8", "ignore")
        self._send(Hello(self._nonce, name))
        self._last_heard_ns = now

    def _send_subscribe(self) -> None:
        self._send(Subscribe(self._cookie, self._nonce, self.streams, self.lease_ms))

    def _on_challenge(self, c: Challenge) -> None:
        if self._state != _HELLO or c.client_nonce != self._nonce:
            return
        self._cookie = c.cookie
        self._state = _SUBSCRIBE
        self._subscribe_attempts = 0
        self._send_subscribe()

    def _on_subscribed(self, s: Subscribed, now: int) -> None:
        self._last_heard_ns = now
        with self._lock:
            if self._session is None or self._session.session_id != s.session_id:
                self._start_session(s, now)
            self._session = s
            self._state = _SUBSCRIBED
            self._changed.notify_all()

    def _start_session(self, s: Subscribed, now: int) -> None:
        """A new session (first, or the daemon restarted): numbering and clock start again."""
        self._trackers[STREAM_SAMPLES].reset(s.next_sample_sequence)
        self._trackers[STREAM_EVENTS].reset(s.next_event_sequence)
        self._trackers[STREAM_MARKERS].reset_from_first_arrival()
        self._trackers[STREAM_PROVISIONAL].reset_from_first_arrival()
        self._stats.subscriptions += 1
        self._clock.clear()
        self._next_time_sync_ns = now

    def _on_error(self, e: protocol.Error, now: int) -> None:
        with self._lock:
            self._stats.errors_received += 1
            self._stats.last_error = e.code
        if e.code in _SESSION_ERRORS:
            self._begin_handshake(now, fresh=True)  # our session or cookie is gone: subscribe again
        elif e.code in _BACKOFF_ERRORS:
            # Asking again at once will not help; the daemon may free a slot later.
            with self._lock:
                self._state = _HELLO
            self._retry_after_ns = now + _REFUSED_BACKOFF_NS

    def _on_time_sync(self, t: TimeSyncReply, now: int) -> None:
        with self._lock:
            if not self._clock.on_reply(t, now):
                self._stats.rejected += 1
            self._changed.notify_all()

    def _stream_of(self, m: Message) -> int:
        if m.type == MessageType.GAZE_SAMPLE:
            return STREAM_SAMPLES
        # Provisional events and their retractions come on a stream (and counter) of their own.
        return STREAM_PROVISIONAL if m.payload.provisional else STREAM_EVENTS

    def _on_gaze(self, m: Message, now: int) -> None:
        stream = self._stream_of(m)
        if self._state != _SUBSCRIBED or not self.streams & stream:
            return
        with self._lock:
            if self._trackers[stream].on_arrival(m.header.sequence) in _DROPPED:
                return  # not "heard": a stream the client cannot follow ends in a resubscription
            self._last_heard_ns = now
            arrival = Arrival(m.header.sequence, now, now - self._clock.to_client_ns(m.header.send_time_ns),
                              m.header.origin_time_ns)
            if stream == STREAM_SAMPLES:
                self._join_eyes(m.payload, m.header.sequence)
                self._latest, self._latest_arrival = m.payload, arrival
                self._enqueue(self._samples, (m.payload, arrival))
            else:
                self._enqueue(self._events, (m.payload, arrival))
        callback = self.on_sample if stream == STREAM_SAMPLES else self.on_event
        if callback:
            callback(m.payload, arrival)

    def _join_eyes(self, sample: GazeSample, sequence: int) -> None:
        """The held GAZE_EYES into its sample (same sequence and capture time), never into another."""
        if self._pending_eyes is None:
            return
        held_sequence, eyes = self._pending_eyes
        if held_sequence == sequence and eyes.tracker_time_ns == sample.tracker_time_ns:
            sample.left_gaze, sample.right_gaze = eyes.left, eyes.right
            self._stats.eye_samples += 1
        if held_sequence <= sequence:
            self._pending_eyes = None

    def _enqueue(self, queue: Deque, item: tuple) -> None:
        if len(queue) >= self._queue_size:
            queue.popleft()
            self._stats.queue_dropped += 1
        queue.append(item)

    def _on_marker(self, m: Message, now: int) -> None:
        if self._state != _SUBSCRIBED or not self.streams & STREAM_MARKERS:
            return
        marker: Marker = m.payload
        with self._lock:
            verdict = self._trackers[STREAM_MARKERS].on_arrival(m.header.sequence)
            self._confirm_marker(marker)
            if verdict in _DROPPED:
                return
            self._last_heard_ns = now
            arrival = Arrival(m.header.sequence, now, now - self._clock.to_client_ns(m.header.send_time_ns))
            self._enqueue(self._events, (marker, arrival))
        if self.on_marker:
            self.on_marker(marker, arrival)

    def _confirm_marker(self, marker: Marker) -> None:
        """Lock held: our own marker came back (a resent copy too): stop resending it."""
        mine = next((p for p in self._pending if p.marker.marker_id == marker.marker_id), None)
        if mine is None:
            return
        self._pending.remove(mine)
        self._stats.markers_confirmed += 1
        self._confirmed.append(marker)
        self._changed.notify_all()

    # ---- the schedule: retransmission, heartbeats, time sync ----

    def _run_schedule(self, now: int) -> None:
        if self._state == _HELLO:
            if now - self._last_sent_ns >= self._retry_ns and now >= self._retry_after_ns:
                self._begin_handshake(now, fresh=False)
        elif self._state == _SUBSCRIBE:
            if now - self._last_sent_ns >= self._retry_ns:
                self._subscribe_attempts += 1
                if self._subscribe_attempts > _SUBSCRIBE_RESENDS:
                    self._begin_handshake(now, fresh=True)
                else:
                    self._send_subscribe()
        else:
            self._keep_session(now)

    def _keep_session(self, now: int) -> None:
        if now - self._last_heard_ns > max(3 * self._heartbeat_ns, 1000 * _MS):
            self._begin_handshake(now, fresh=True)  # daemon stopped, restarted, or the network failed
            return
        session = self.session
        if now - self._last_sent_ns >= self._heartbeat_ns and session is not None:
            self._send(Heartbeat(session.session_id, self.lease_ms))
        self._resend_markers(now)
        if now >= self._next_time_sync_ns:
            self._send_time_sync(now)

    def _send_time_sync(self, now: int) -> None:
        request = TimeSyncRequest(monotonic_ns())
        with self._lock:
            self._clock.request_sent(request.client_send_ns)
            fast = self._clock.accepted < _TIME_SYNC_FAST
        self._send(request)
        self._next_time_sync_ns = now + (50 if fast else 2000) * _MS

    def _resend_markers(self, now: int) -> None:
        """Markers whose copy has not come back go out again, with the current session (a daemon
        restart in between gave us a new one), until 8 sends."""
        again: List[Marker] = []
        with self._lock:
            if self._session is None:
                return
            for p in list(self._pending):
                if now - p.sent_ns < _MARKER_RESEND_NS:
                    continue
                if p.attempts >= _MARKER_ATTEMPTS:
                    self._stats.markers_unconfirmed += 1
                    self._pending.remove(p)
                    continue
                p.attempts += 1
                p.sent_ns = now
                p.marker.session_id = self._session.session_id
                again.append(replace(p.marker))
        for marker in again:
            self._send(marker)


# ---- one-shot requests ----------------------------------------------------------------------------


def _exchange(host: str, port: int, request: protocol.Payload, reply_type: MessageType, timeout: float,
              resend: float) -> Optional[Message]:
    """Sends `request` with a random sequence from a fresh socket, resends it unchanged every `resend`
    seconds, and returns the first valid reply of `reply_type` from the server carrying that sequence."""
    server = (socket.gethostbyname(host), port)
    sequence = _random_id()
    now = monotonic_ns()
    data = protocol.encode(request, sequence, now, now)
    deadline = time.monotonic() + timeout
    next_send = 0.0
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("0.0.0.0", 0))
        while (left := deadline - time.monotonic()) > 0:
            if time.monotonic() >= next_send:
                sock.sendto(data, server)
                next_send = time.monotonic() + resend
            sock.settimeout(min(left, 0.02))
            try:
                reply, sender = sock.recvfrom(protocol.MAX_DATAGRAM_SIZE + 1)
                m = protocol.decode(reply)
            except (socket.timeout, OSError, ProtocolError):
                continue
            if sender == server and m.type == reply_type and m.header.sequence == sequence:
                return m
    return None


def query_status(host: str = "127.0.0.1", port: int = DEFAULT_PORT, timeout: float = 1.0) -> Optional[StatusReply]:
    """The daemon's STATUS_REPLY (needs no session), or None when none came within `timeout` s."""
    m = _exchange(host, port, StatusRequest(), MessageType.STATUS_REPLY, timeout, 0.25)
    return None if m is None else m.payload
