// SPDX-License-Identifier: Apache-2.0
#pragma once
// The gaze protocol v1: message types and their fields. The byte layout of each is defined in
// codec.cpp and documented in protocol/PROTOCOL.md; the two must agree (tests check the golden
// vectors in tests/data/golden against both).
#include <array>
#include <cstdint>
#include <string>
#include <variant>

#include "fovea/protocol/display_geometry.h"

namespace fovea::protocol {

inline constexpr std::array<std::uint8_t, 4> kMagic = {'F', 'V', 'G', 'Z'};
inline constexpr std::uint8_t kVersion = 1;
inline constexpr std::size_t kHeaderSize = 32;
inline constexpr std::uint16_t kDefaultPort = 47800;
// Largest datagram a v1 peer sends or accepts.
inline constexpr std::size_t kMaxDatagramSize = 512;

enum class MessageType : std::uint8_t {
  Hello = 1,
  Challenge = 2,
  Subscribe = 3,
  Subscribed = 4,
  Heartbeat = 5,
  Unsubscribe = 6,
  GazeSample = 7,
  GazeEvent = 8,
  StatusRequest = 9,
  StatusReply = 10,
  TimeSyncRequest = 11,
  TimeSyncReply = 12,
  Error = 13,
  ControlRequest = 14,
  ControlReply = 15,
  Marker = 16,
  GazeEyes = 17,
};
inline constexpr std::uint8_t kMaxMessageType = 17;
const char* to_string(MessageType t);

// Subscription stream bits.
inline constexpr std::uint32_t kStreamSamples = 1u << 0;
inline constexpr std::uint32_t kStreamEvents = 1u << 1;
inline constexpr std::uint32_t kStreamMarkers = 1u << 2;
// Provisional GAZE_EVENTs (kEventProvisional) and their retractions, on a stream of their own.
inline constexpr std::uint32_t kStreamProvisional = 1u << 3;
// Each eye's own point of gaze (GAZE_EYES, sent just before the GAZE_SAMPLE it belongs to) from
// sources that measure both eyes; opt-in, so that v1 clients never see a message type they lack.
inline constexpr std::uint32_t kStreamEyes = 1u << 4;
inline constexpr std::uint32_t kStreamMask =
    kStreamSamples | kStreamEvents | kStreamMarkers | kStreamProvisional | kStreamEyes;

struct Header {
  MessageType type = MessageType::Hello;
  std::uint16_t payload_length = 0;
  // GAZE_SAMPLE / GAZE_EVENT: the stream's sequence number (one counter per stream, shared by all
  // subscribers). Requests: the sender's request counter. Replies: the request's sequence.
  std::uint64_t sequence = 0;
  // When the content came to be on the sender's clock (sample capture time for gaze samples).
  std::int64_t origin_time_ns = 0;
  // When the sender handed the datagram to the network, on the sender's clock.
  std::int64_t send_time_ns = 0;
  friend bool operator==(const Header&, const Header&) = default;
};

// Fixed-size NUL-padded UTF-8 text field.
template <std::size_t N>
struct FixedString {
  static constexpr std::size_t capacity = N;
  std::string value;  // at most N-1 bytes; the codec rejects longer text
  friend bool operator==(const FixedString&, const FixedString&) = default;
};

using Cookie = std::array<std::uint8_t, 16>;

struct Hello {
  std::uint64_t client_nonce = 0;
  FixedString<32> client_name;
  friend bool operator==(const Hello&, const Hello&) = default;
};

struct Challenge {
  std::uint64_t client_nonce = 0;  // echoed from HELLO
  Cookie cookie{};
  std::uint32_t cookie_lifetime_ms = 0;
  friend bool operator==(const Challenge&, const Challenge&) = default;
};

struct Subscribe {
  Cookie cookie{};
  std::uint64_t client_nonce = 0;
  std::uint32_t streams = kStreamSamples;
  std::uint32_t requested_lease_ms = 0;  // 0: server default
  friend bool operator==(const Subscribe&, const Subscribe&) = default;
};

struct MulticastInfo {
  std::uint32_t group_ipv4 = 0;  // host byte order; 0 = no multicast
  std::uint16_t port = 0;
  std::uint8_t ttl = 0;
  friend bool operator==(const MulticastInfo&, const MulticastInfo&) = default;
};

struct Subscribed {
  std::uint64_t session_id = 0;
  std::uint32_t streams = 0;
  std::uint32_t lease_ms = 0;
  double nominal_rate_hz = 0;
  std::uint64_t next_sample_sequence = 0;
  std::uint64_t next_event_sequence = 0;
  DisplayGeometry display;
  MulticastInfo multicast;
  friend bool operator==(const Subscribed&, const Subscribed&) = default;
};

struct Heartbeat {
  std::uint64_t session_id = 0;
  std::uint32_t lease_ms = 0;  // server reply: lease granted from now
  friend bool operator==(const Heartbeat&, const Heartbeat&) = default;
};

struct Unsubscribe {
  std::uint64_t session_id = 0;
  friend bool operator==(const Unsubscribe&, const Unsubscribe&) = default;
};

// Eye-movement classes, shared by GAZE_SAMPLE.state and GAZE_EVENT.kind.
enum class EyeMovement : std::uint8_t { Unknown = 0, Fixation = 1, Saccade = 2, Pursuit = 3, Blink = 4 };
inline constexpr std::uint8_t kMaxEyeMovement = 4;
const char* to_string(EyeMovement m);

inline constexpr std::uint8_t kEyePupilValid = 1u << 0;
inline constexpr std::uint8_t kEyeGlintValid = 1u << 1;
inline constexpr std::uint8_t kEyeFlagMask = kEyePupilValid | kEyeGlintValid;

struct EyeData {
  std::uint8_t flags = 0;  // kEyePupilValid | kEyeGlintValid
  float pupil_x_px = 0, pupil_y_px = 0;  // pupil centre in eye-camera pixels
  float pupil_diameter_mm = 0;
  float pupil_glint_x_px = 0, pupil_glint_y_px = 0;  // pupil centre minus glint centroid
  friend bool operator==(const EyeData&, const EyeData&) = default;
};

inline constexpr std::uint8_t kGazeValid = 1u << 0;
inline constexpr std::uint8_t kGazeFlagMask = kGazeValid;

// One eye's point of gaze on the screen, in the sample's coordinates (PROTOCOL.md §4.18). A
// binocular tracker measures each eye; the sample's x, y is their combination (cyclopean), which is
// all a monocular client needs. A stereo display needs each eye's: the two differ by the
// disparity of what is looked at, and a tracker's per-eye noise is independent.
inline constexpr std::uint8_t kEyeGazeValid = 1u << 0;
inline constexpr std::uint8_t kEyeGazeFlagMask = kEyeGazeValid;

struct EyeGaze {
  std::uint8_t flags = 0;  // kEyeGazeValid
  float x = 0, y = 0;          // normalized screen coordinates, as GazeSample's
  float x_deg = 0, y_deg = 0;  // visual angle from screen centre
  bool valid() const { return (flags & kEyeGazeValid) != 0; }
  friend bool operator==(const EyeGaze&, const EyeGaze&) = default;
};

struct GazeSample {
  std::int64_t tracker_time_ns = 0;
  float x = 0, y = 0;          // normalized screen coordinates, origin top-left, y down
  float x_deg = 0, y_deg = 0;  // visual angle from screen centre, x right, y down
  float angular_velocity_deg_s = 0;
  float confidence = 0;  // [0, 1]
  EyeMovement state = EyeMovement::Unknown;
  std::uint8_t flags = 0;  // kGazeValid
  EyeData left, right;
  // Each eye's point of gaze where the source measures both (not part of GAZE_SAMPLE's payload: a
  // server sends them as GAZE_EYES to kStreamEyes subscribers, and a client puts them back here).
  EyeGaze left_gaze, right_gaze;
  bool has_eye_gaze() const { return left_gaze.valid() || right_gaze.valid(); }
  friend bool operator==(const GazeSample&, const GazeSample&) = default;
};

// GAZE_EYES (17): the per-eye gaze of the GAZE_SAMPLE with the same sequence and tracker time.
struct GazeEyes {
  std::int64_t tracker_time_ns = 0;
  EyeGaze left, right;
  friend bool operator==(const GazeEyes&, const GazeEyes&) = default;
};

enum class EventPhase : std::uint8_t { Start = 1, End = 2 };

// GAZE_EVENT flags (PROTOCOL.md §4.9). 0: a final event, from the method's final labels.
// Provisional: said from the newest samples, before the final labels (provisional stream only).
// Retracted (always with Provisional): the provisional event of this kind, phase and start time was
// not confirmed by the final labels.
inline constexpr std::uint8_t kEventProvisional = 1u << 0;
inline constexpr std::uint8_t kEventRetracted = 1u << 1;
inline constexpr std::uint8_t kEventFlagMask = kEventProvisional | kEventRetracted;

struct GazeEvent {
  EyeMovement kind = EyeMovement::Fixation;
  EventPhase phase = EventPhase::Start;
  std::int64_t start_time_ns = 0;
  std::int64_t duration_ns = 0;  // 0 for Start
  float centroid_x = 0, centroid_y = 0;  // normalized (Start: position at onset)
  float centroid_x_deg = 0, centroid_y_deg = 0;
  float amplitude_deg = 0;
  float peak_velocity_deg_s = 0;
  std::uint8_t flags = 0;  // kEventProvisional | kEventRetracted; 0 = final
  bool provisional() const { return (flags & kEventProvisional) != 0; }
  friend bool operator==(const GazeEvent&, const GazeEvent&) = default;
};

struct StatusRequest {
  friend bool operator==(const StatusRequest&, const StatusRequest&) = default;
};

enum class SourceState : std::uint8_t { Running = 0, Ended = 1, Retrying = 2 };
inline constexpr std::uint8_t kMaxSourceState = 2;

struct StatusReply {
  FixedString<48> source;
  double nominal_rate_hz = 0;
  std::int64_t uptime_ns = 0;
  std::uint64_t samples_published = 0;
  std::uint64_t events_published = 0;
  std::uint64_t datagrams_rejected = 0;
  std::uint32_t subscribers = 0;
  SourceState source_state = SourceState::Running;
  DisplayGeometry display;
  friend bool operator==(const StatusReply&, const StatusReply&) = default;
};

// NTP-style exchange: t1 client send, t2 server receive, t3 server send (each on its own clock).
struct TimeSyncRequest {
  std::int64_t client_send_ns = 0;
  friend bool operator==(const TimeSyncRequest&, const TimeSyncRequest&) = default;
};
struct TimeSyncReply {
  std::int64_t client_send_ns = 0;
  std::int64_t server_receive_ns = 0;
  std::int64_t server_send_ns = 0;
  friend bool operator==(const TimeSyncReply&, const TimeSyncReply&) = default;
};

enum class ErrorCode : std::uint16_t {
  BadCookie = 1,
  CookieExpired = 2,
  UnknownSession = 3,
  UnsupportedVersion = 4,
  TooManySubscribers = 5,
  BadRequest = 6,
  AddressMismatch = 7,
  RateLimited = 8,
};
inline constexpr std::uint16_t kMaxErrorCode = 8;
const char* to_string(ErrorCode c);

struct Error {
  ErrorCode code = ErrorCode::BadRequest;
  MessageType request_type = MessageType::Hello;
  std::uint8_t supported_version = kVersion;
  friend bool operator==(const Error&, const Error&) = default;
};

// Operator commands (a compatible v1 extension): executed only for requests from the server's
// control allow-list (default: loopback); everyone else gets result Refused.
enum class ControlCommand : std::uint8_t { Reload = 1, StartRecording = 2, StopRecording = 3, LoadCalibration = 4 };
inline constexpr std::uint8_t kMaxControlCommand = 4;
const char* to_string(ControlCommand c);  // "reload", "record-start", "record-stop", "calibration-load"

enum class ControlResult : std::uint8_t { Ok = 0, Refused = 1, Failed = 2 };
inline constexpr std::uint8_t kMaxControlResult = 2;
const char* to_string(ControlResult r);  // "ok", "refused", "failed"

struct ControlRequest {
  ControlCommand command = ControlCommand::Reload;
  FixedString<64> argument;  // StartRecording: the recording path; LoadCalibration: the calibration
                             // file, "none" or "configured"; otherwise empty
  friend bool operator==(const ControlRequest&, const ControlRequest&) = default;
};

struct ControlReply {
  ControlCommand command = ControlCommand::Reload;  // echoed from the request
  ControlResult result = ControlResult::Ok;
  FixedString<64> message;  // what happened, for people (e.g. "recording to /var/lib/fovea/a.fgr")
  friend bool operator==(const ControlReply&, const ControlReply&) = default;
};

// An experimenter's event (stimulus onset, key press, trial start) on the gaze clock (PROTOCOL.md
// §4.17). A subscribed client sends it with its own session id; the server stamps its receive time
// and publishes it to the marker stream with session_id 0 (sessions are never disclosed).
inline constexpr std::uint8_t kMarkerClientTime = 1u << 0;  // time_ns was given by the sender
inline constexpr std::uint8_t kMarkerFlagMask = kMarkerClientTime;

struct Marker {
  std::uint64_t session_id = 0;  // client -> server: the sender's session; server -> client: 0
  std::uint64_t marker_id = 0;   // chosen by the sender (non-zero); a repeat of a recent one is a retransmission
  // Server clock. With kMarkerClientTime: when the event happened, as the sender mapped its own clock
  // through TIME_SYNC; without: 0 from the sender, and the receive time once the server publishes it.
  std::int64_t time_ns = 0;
  std::int64_t received_ns = 0;  // server clock when the server received it; 0 from the sender
  std::uint8_t flags = 0;        // kMarkerClientTime
  FixedString<64> label;         // 1..63 bytes of UTF-8 without control characters
  friend bool operator==(const Marker&, const Marker&) = default;
};

using Payload = std::variant<Hello, Challenge, Subscribe, Subscribed, Heartbeat, Unsubscribe, GazeSample,
                             GazeEvent, StatusRequest, StatusReply, TimeSyncRequest, TimeSyncReply, Error,
                             ControlRequest, ControlReply, Marker, GazeEyes>;

MessageType type_of(const Payload& p);

struct Message {
  Header header;
  Payload payload;
  friend bool operator==(const Message&, const Message&) = default;
};

}  // namespace fovea::protocol
