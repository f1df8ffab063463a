# SPDX-License-Identifier: Apache-2.0
"""fovea: pure-Python client of fovea-trackerd (gaze protocol v1) and reader of .fgr recordings."""

from .protocol import (  # noqa: F401
    DEFAULT_PORT, STREAM_EVENTS, STREAM_EYES, STREAM_MARKERS, STREAM_PROVISIONAL, STREAM_SAMPLES, DecodeError,
    DisplayGeometry, ErrorCode, EventPhase, EyeData, EyeGaze, EyeMovement, GazeEvent, GazeEyes, GazeSample, Marker, Message, MessageType, ProtocolError,
    StatusReply, Subscribed, decode, encode)
from .recording import Record, Recording, RecoveryReport, RecordingHeader, parse_recording, read_recording  # noqa: F401
from .client import Arrival, ClientStats, GazeClient, SequenceCounts, SequenceTracker, query_status  # noqa: F401

__version__ = "0.1.0"
