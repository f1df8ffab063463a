// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/codec.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/wire.h"

namespace fovea::protocol {

using wire::load_le;
using wire::store_le;

const char* to_string(MessageType t) {
  switch (t) {
    case MessageType::Hello: return "HELLO";
    case MessageType::Challenge: return "CHALLENGE";
    case MessageType::Subscribe: return "SUBSCRIBE";
    case MessageType::Subscribed: return "SUBSCRIBED";
    case MessageType::Heartbeat: return "HEARTBEAT";
    case MessageType::Unsubscribe: return "UNSUBSCRIBE";
    case MessageType::GazeSample: return "GAZE_SAMPLE";
    case MessageType::GazeEvent: return "GAZE_EVENT";
    case MessageType::StatusRequest: return "STATUS_REQUEST";
    case MessageType::StatusReply: return "STATUS_REPLY";
    case MessageType::TimeSyncRequest: return "TIME_SYNC_REQUEST";
    case MessageType::TimeSyncReply: return "TIME_SYNC_REPLY";
    case MessageType::Error: return "ERROR";
    case MessageType::ControlRequest: return "CONTROL_REQUEST";
    case MessageType::ControlReply: return "CONTROL_REPLY";
    case MessageType::Marker: return "MARKER";
    case MessageType::GazeEyes: return "GAZE_EYES";
  }
  return "?";
}

const char* to_string(ControlCommand c) {
  switch (c) {
    case ControlCommand::Reload: return "reload";
    case ControlCommand::StartRecording: return "record-start";
    case ControlCommand::StopRecording: return "record-stop";
    case ControlCommand::LoadCalibration: return "calibration-load";
  }
  return "?";
}

const char* to_string(ControlResult r) {
  switch (r) {
    case ControlResult::Ok: return "ok";
    case ControlResult::Refused: return "refused";
    case ControlResult::Failed: return "failed";
  }
  return "?";
}

const char* to_string(EyeMovement m) {
  switch (m) {
    case EyeMovement::Unknown: return "unknown";
    case EyeMovement::Fixation: return "fixation";
    case EyeMovement::Saccade: return "saccade";
    case EyeMovement::Pursuit: return "pursuit";
    case EyeMovement::Blink: return "blink";
  }
  return "?";
}

const char* to_string(ErrorCode c) {
  switch (c) {
    case ErrorCode::BadCookie: return "bad cookie";
    case ErrorCode::CookieExpired: return "cookie expired";
    case ErrorCode::UnknownSession: return "unknown session";
    case ErrorCode::UnsupportedVersion: return "unsupported version";
    case ErrorCode::TooManySubscribers: return "too many subscribers";
    case ErrorCode::BadRequest: return "bad request";
    case ErrorCode::AddressMismatch: return "address mismatch";
    case ErrorCode::RateLimited: return "rate limited";
  }
  return "?";
}

const char* to_string(DecodeError e) {
  switch (e) {
    case DecodeError::Ok: return "ok";
    case DecodeError::TooShort: return "too short";
    case DecodeError::TooLong: return "too long";
    case DecodeError::BadMagic: return "bad magic";
    case DecodeError::BadVersion: return "bad version";
    case DecodeError::UnknownType: return "unknown message type";
    case DecodeError::BadPayloadLength: return "payload length does not match message type";
    case DecodeError::ReservedNotZero: return "reserved bytes or bits set";
    case DecodeError::NonFinite: return "non-finite floating-point field";
    case DecodeError::OutOfRange: return "field out of range";
    case DecodeError::BadString: return "malformed text field";
  }
  return "?";
}

std::uint64_t DecodeCounters::rejected() const {
  std::uint64_t total = 0;
  for (std::size_t i = 1; i < kDecodeErrorCount; ++i) total += counts_[i].load(std::memory_order_relaxed);
  return total;
}

namespace {


std::size_t size_of(MessageType t) {
  switch (t) {
    case MessageType::Hello: return 48;
    case MessageType::Challenge: return 32;
    case MessageType::Subscribe: return 32;
    case MessageType::Subscribed: return 80;
    case MessageType::Heartbeat: return 16;
    case MessageType::Unsubscribe: return 8;
    case MessageType::GazeSample: return 76;
    case MessageType::GazeEvent: return 48;
    case MessageType::StatusRequest: return 128;
    case MessageType::StatusReply: return 128;
    case MessageType::TimeSyncRequest: return 24;
    case MessageType::TimeSyncReply: return 24;
    case MessageType::Error: return 8;
    case MessageType::ControlRequest: return 72;  // as large as CONTROL_REPLY: no amplification
    case MessageType::ControlReply: return 72;
    case MessageType::Marker: return 104;
    case MessageType::GazeEyes: return 48;
  }
  return 0;
}

// ---- writing ---------------------------------------------------------------------------------

struct Writer {
  std::span<std::uint8_t> buf;
  template <typename T>
  void put(std::size_t off, T v) { store_le<T>(buf, off, v); }
  void f32(std::size_t off, float v) { put<float>(off, v); }
  void f64(std::size_t off, double v) { put<double>(off, v); }
  void bytes(std::size_t off, std::span<const std::uint8_t> b) {
    for (std::size_t i = 0; i < b.size(); ++i) buf[off + i] = b[i];
  }
  template <std::size_t N>
  void text(std::size_t off, const FixedString<N>& s) {
    if (s.value.size() >= N) {
      throw std::invalid_argument("text field of " + std::to_string(N) + " bytes cannot hold \"" + s.value +
                                  "\" (" + std::to_string(s.value.size()) + " bytes; at most " +
                                  std::to_string(N - 1) + ")");
    }
    for (std::size_t i = 0; i < N; ++i) buf[off + i] = i < s.value.size() ? static_cast<std::uint8_t>(s.value[i]) : 0;
  }
  void display(std::size_t off, const DisplayGeometry& g) {
    put<std::uint32_t>(off, g.width_px);
    put<std::uint32_t>(off + 4, g.height_px);
    f64(off + 8, g.width_m);
    f64(off + 16, g.height_m);
    f64(off + 24, g.viewing_distance_m);
  }
  void eye(std::size_t off, const EyeData& e) {
    f32(off, e.pupil_x_px);
    f32(off + 4, e.pupil_y_px);
    f32(off + 8, e.pupil_diameter_mm);
    f32(off + 12, e.pupil_glint_x_px);
    f32(off + 16, e.pupil_glint_y_px);
  }
  void eye_gaze(std::size_t off, const EyeGaze& e) {
    f32(off, e.x);
    f32(off + 4, e.y);
    f32(off + 8, e.x_deg);
    f32(off + 12, e.y_deg);
  }

  void operator()(const Hello& m) {
    put<std::uint64_t>(0, m.client_nonce);
    text(8, m.client_name);
  }
  void operator()(const Challenge& m) {
    put<std::uint64_t>(0, m.client_nonce);
    bytes(8, m.cookie);
    put<std::uint32_t>(24, m.cookie_lifetime_ms);
  }
  void operator()(const Subscribe& m) {
    bytes(0, m.cookie);
    put<std::uint64_t>(16, m.client_nonce);
    put<std::uint32_t>(24, m.streams);
    put<std::uint32_t>(28, m.requested_lease_ms);
  }
  void operator()(const Subscribed& m) {
    put<std::uint64_t>(0, m.session_id);
    put<std::uint32_t>(8, m.streams);
    put<std::uint32_t>(12, m.lease_ms);
    f64(16, m.nominal_rate_hz);
    put<std::uint64_t>(24, m.next_sample_sequence);
    put<std::uint64_t>(32, m.next_event_sequence);
    display(40, m.display);
    put<std::uint32_t>(72, m.multicast.group_ipv4);
    put<std::uint16_t>(76, m.multicast.port);
    put<std::uint8_t>(78, m.multicast.ttl);
  }
  void operator()(const Heartbeat& m) {
    put<std::uint64_t>(0, m.session_id);
    put<std::uint32_t>(8, m.lease_ms);
  }
  void operator()(const Unsubscribe& m) { put<std::uint64_t>(0, m.session_id); }
  void operator()(const GazeSample& m) {
    put<std::int64_t>(0, m.tracker_time_ns);
    f32(8, m.x);
    f32(12, m.y);
    f32(16, m.x_deg);
    f32(20, m.y_deg);
    f32(24, m.angular_velocity_deg_s);
    f32(28, m.confidence);
    put<std::uint8_t>(32, static_cast<std::uint8_t>(m.state));
    put<std::uint8_t>(33, m.flags);
    put<std::uint8_t>(34, m.left.flags);
    put<std::uint8_t>(35, m.right.flags);
    eye(36, m.left);
    eye(56, m.right);
  }
  void operator()(const GazeEvent& m) {
    put<std::uint8_t>(0, static_cast<std::uint8_t>(m.kind));
    put<std::uint8_t>(1, static_cast<std::uint8_t>(m.phase));
    put<std::uint8_t>(2, m.flags);
    put<std::int64_t>(8, m.start_time_ns);
    put<std::int64_t>(16, m.duration_ns);
    f32(24, m.centroid_x);
    f32(28, m.centroid_y);
    f32(32, m.centroid_x_deg);
    f32(36, m.centroid_y_deg);
    f32(40, m.amplitude_deg);
    f32(44, m.peak_velocity_deg_s);
  }
  void operator()(const StatusRequest&) {}
  void operator()(const StatusReply& m) {
    text(0, m.source);
    f64(48, m.nominal_rate_hz);
    put<std::int64_t>(56, m.uptime_ns);
    put<std::uint64_t>(64, m.samples_published);
    put<std::uint64_t>(72, m.events_published);
    put<std::uint64_t>(80, m.datagrams_rejected);
    put<std::uint32_t>(88, m.subscribers);
    put<std::uint8_t>(92, static_cast<std::uint8_t>(m.source_state));
    display(96, m.display);
  }
  void operator()(const TimeSyncRequest& m) { put<std::int64_t>(0, m.client_send_ns); }
  void operator()(const TimeSyncReply& m) {
    put<std::int64_t>(0, m.client_send_ns);
    put<std::int64_t>(8, m.server_receive_ns);
    put<std::int64_t>(16, m.server_send_ns);
  }
  void operator()(const Error& m) {
    put<std::uint16_t>(0, static_cast<std::uint16_t>(m.code));
    put<std::uint8_t>(2, static_cast<std::uint8_t>(m.request_type));
    put<std::uint8_t>(3, m.supported_version);
  }
  void operator()(const ControlRequest& m) {
    put<std::uint8_t>(0, static_cast<std::uint8_t>(m.command));
    text(8, m.argument);
  }
  void operator()(const ControlReply& m) {
    put<std::uint8_t>(0, static_cast<std::uint8_t>(m.command));
    put<std::uint8_t>(1, static_cast<std::uint8_t>(m.result));
    text(8, m.message);
  }
  void operator()(const Marker& m) {
    put<std::uint64_t>(0, m.session_id);
    put<std::uint64_t>(8, m.marker_id);
    put<std::int64_t>(16, m.time_ns);
    put<std::int64_t>(24, m.received_ns);
    put<std::uint8_t>(32, m.flags);
    text(40, m.label);
  }
  void operator()(const GazeEyes& m) {
    put<std::int64_t>(0, m.tracker_time_ns);
    put<std::uint8_t>(8, m.left.flags);
    put<std::uint8_t>(9, m.right.flags);
    eye_gaze(16, m.left);
    eye_gaze(32, m.right);
  }
};

// ---- reading ---------------------------------------------------------------------------------

// Reads fields and records the first violation; later reads keep going harmlessly so each decoder
// can be written as straight-line code and checked once at the end.
struct Reader {
  std::span<const std::uint8_t> buf;
  DecodeResult result{};

  void fail(DecodeError e, std::size_t off) {
    if (result.error == DecodeError::Ok) result = DecodeResult{e, off};
  }
  template <typename T>
  T get(std::size_t off) { return load_le<T>(buf, off); }
  float f32(std::size_t off) {
    const float v = get<float>(off);
    if (!std::isfinite(v)) fail(DecodeError::NonFinite, off);
    return v;
  }
  double f64(std::size_t off) {
    const double v = get<double>(off);
    if (!std::isfinite(v)) fail(DecodeError::NonFinite, off);
    return v;
  }
  float f32_at_least(std::size_t off, float lo) {
    const float v = f32(off);
    if (!(v >= lo)) fail(DecodeError::OutOfRange, off);
    return v;
  }
  double f64_positive(std::size_t off) {
    const double v = f64(off);
    if (!(v > 0)) fail(DecodeError::OutOfRange, off);
    return v;
  }
  void zero(std::size_t off, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      if (buf[off + i] != 0) {
        fail(DecodeError::ReservedNotZero, off + i);
        return;
      }
    }
  }
  std::uint8_t flags(std::size_t off, std::uint8_t mask) {
    const auto v = get<std::uint8_t>(off);
    if ((v & ~mask) != 0) fail(DecodeError::ReservedNotZero, off);
    return v;
  }
  template <std::size_t N>
  void text(std::size_t off, FixedString<N>& s) {
    std::size_t len = 0;
    while (len < N && buf[off + len] != 0) ++len;
    if (len == N) {
      fail(DecodeError::BadString, off);
      return;
    }
    for (std::size_t i = len; i < N; ++i) {
      if (buf[off + i] != 0) {
        fail(DecodeError::BadString, off + i);
        return;
      }
    }
    s.value.assign(reinterpret_cast<const char*>(buf.data() + off), len);
  }
  void bytes(std::size_t off, std::span<std::uint8_t> out) {
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = buf[off + i];
  }
  DisplayGeometry display(std::size_t off) {
    DisplayGeometry g;
    g.width_px = get<std::uint32_t>(off);
    g.height_px = get<std::uint32_t>(off + 4);
    if (g.width_px == 0) fail(DecodeError::OutOfRange, off);
    if (g.height_px == 0) fail(DecodeError::OutOfRange, off + 4);
    g.width_m = f64_positive(off + 8);
    g.height_m = f64_positive(off + 16);
    g.viewing_distance_m = f64_positive(off + 24);
    if (result && !validate(g).empty()) fail(DecodeError::OutOfRange, off);  // the same limits everywhere
    return g;
  }
  EyeData eye(std::size_t off, std::uint8_t eye_flags) {
    EyeData e;
    e.flags = eye_flags;
    e.pupil_x_px = f32(off);
    e.pupil_y_px = f32(off + 4);
    e.pupil_diameter_mm = f32_at_least(off + 8, 0.0f);
    e.pupil_glint_x_px = f32(off + 12);
    e.pupil_glint_y_px = f32(off + 16);
    return e;
  }
  // An eye without the valid bit carries zeros: nothing on the wire is both present and meaningless.
  EyeGaze eye_gaze(std::size_t off, std::uint8_t eye_flags) {
    EyeGaze e;
    e.flags = eye_flags;
    e.x = f32(off);
    e.y = f32(off + 4);
    e.x_deg = f32(off + 8);
    e.y_deg = f32(off + 12);
    if (!e.valid() && (e.x != 0 || e.y != 0 || e.x_deg != 0 || e.y_deg != 0)) fail(DecodeError::OutOfRange, off);
    return e;
  }
  template <typename E>
  E enumeration(std::size_t off, unsigned lo, unsigned hi) {
    using U = std::underlying_type_t<E>;
    const U v = get<U>(off);
    if (v < lo || v > hi) fail(DecodeError::OutOfRange, off);
    return static_cast<E>(v);
  }

  // Payload layout: PROTOCOL.md §4.2
  Hello read_hello() {
    Hello m;
    m.client_nonce = get<std::uint64_t>(0);
    text(8, m.client_name);
    zero(40, 8);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.3
  Challenge read_challenge() {
    Challenge m;
    m.client_nonce = get<std::uint64_t>(0);
    bytes(8, m.cookie);
    m.cookie_lifetime_ms = get<std::uint32_t>(24);
    zero(28, 4);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.4
  Subscribe read_subscribe() {
    Subscribe m;
    bytes(0, m.cookie);
    m.client_nonce = get<std::uint64_t>(16);
    m.streams = get<std::uint32_t>(24);
    if (m.streams == 0 || (m.streams & ~kStreamMask) != 0) fail(DecodeError::OutOfRange, 24);
    m.requested_lease_ms = get<std::uint32_t>(28);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.5
  Subscribed read_subscribed() {
    Subscribed m;
    m.session_id = get<std::uint64_t>(0);
    m.streams = get<std::uint32_t>(8);
    if ((m.streams & ~kStreamMask) != 0) fail(DecodeError::OutOfRange, 8);
    m.lease_ms = get<std::uint32_t>(12);
    m.nominal_rate_hz = f64(16);
    if (m.nominal_rate_hz < 0) fail(DecodeError::OutOfRange, 16);
    m.next_sample_sequence = get<std::uint64_t>(24);
    m.next_event_sequence = get<std::uint64_t>(32);
    m.display = display(40);
    m.multicast.group_ipv4 = get<std::uint32_t>(72);
    m.multicast.port = get<std::uint16_t>(76);
    m.multicast.ttl = get<std::uint8_t>(78);
    zero(79, 1);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.6
  Heartbeat read_heartbeat() {
    Heartbeat m;
    m.session_id = get<std::uint64_t>(0);
    m.lease_ms = get<std::uint32_t>(8);
    zero(12, 4);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.7
  Unsubscribe read_unsubscribe() {
    Unsubscribe m;
    m.session_id = get<std::uint64_t>(0);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.8
  GazeSample read_gaze_sample() {
    GazeSample m;
    m.tracker_time_ns = get<std::int64_t>(0);
    m.x = f32(8);
    m.y = f32(12);
    m.x_deg = f32(16);
    m.y_deg = f32(20);
    m.angular_velocity_deg_s = f32_at_least(24, 0.0f);
    m.confidence = f32_at_least(28, 0.0f);
    if (m.confidence > 1.0f) fail(DecodeError::OutOfRange, 28);
    m.state = enumeration<EyeMovement>(32, 0, kMaxEyeMovement);
    m.flags = flags(33, kGazeFlagMask);
    m.left = eye(36, flags(34, kEyeFlagMask));
    m.right = eye(56, flags(35, kEyeFlagMask));
    return m;
  }
  // Payload layout: PROTOCOL.md §4.9
  GazeEvent read_gaze_event() {
    GazeEvent m;
    m.kind = enumeration<EyeMovement>(0, 1, kMaxEyeMovement);
    m.phase = enumeration<EventPhase>(1, 1, 2);
    m.flags = get<std::uint8_t>(2);
    if ((m.flags & ~kEventFlagMask) != 0) fail(DecodeError::ReservedNotZero, 2);
    if (m.flags == kEventRetracted) fail(DecodeError::OutOfRange, 2);  // a retraction is of a provisional event
    zero(3, 5);
    m.start_time_ns = get<std::int64_t>(8);
    m.duration_ns = get<std::int64_t>(16);
    if (m.duration_ns < 0) fail(DecodeError::OutOfRange, 16);
    m.centroid_x = f32(24);
    m.centroid_y = f32(28);
    m.centroid_x_deg = f32(32);
    m.centroid_y_deg = f32(36);
    m.amplitude_deg = f32_at_least(40, 0.0f);
    m.peak_velocity_deg_s = f32_at_least(44, 0.0f);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.10
  StatusRequest read_status_request() {
    zero(0, 128);
    return StatusRequest{};
  }
  // Payload layout: PROTOCOL.md §4.11
  StatusReply read_status_reply() {
    StatusReply m;
    text(0, m.source);
    m.nominal_rate_hz = f64(48);
    if (m.nominal_rate_hz < 0) fail(DecodeError::OutOfRange, 48);
    m.uptime_ns = get<std::int64_t>(56);
    if (m.uptime_ns < 0) fail(DecodeError::OutOfRange, 56);
    m.samples_published = get<std::uint64_t>(64);
    m.events_published = get<std::uint64_t>(72);
    m.datagrams_rejected = get<std::uint64_t>(80);
    m.subscribers = get<std::uint32_t>(88);
    m.source_state = enumeration<SourceState>(92, 0, kMaxSourceState);
    zero(93, 3);
    m.display = display(96);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.12
  TimeSyncRequest read_time_sync_request() {
    TimeSyncRequest m;
    m.client_send_ns = get<std::int64_t>(0);
    zero(8, 16);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.13
  TimeSyncReply read_time_sync_reply() {
    TimeSyncReply m;
    m.client_send_ns = get<std::int64_t>(0);
    m.server_receive_ns = get<std::int64_t>(8);
    m.server_send_ns = get<std::int64_t>(16);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.14
  Error read_error() {
    Error m;
    m.code = enumeration<ErrorCode>(0, 1, kMaxErrorCode);
    m.request_type = enumeration<MessageType>(2, 1, kMaxMessageType);
    m.supported_version = get<std::uint8_t>(3);
    zero(4, 4);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.15
  ControlRequest read_control_request() {
    ControlRequest m;
    m.command = enumeration<ControlCommand>(0, 1, kMaxControlCommand);
    zero(1, 7);
    text(8, m.argument);
    return m;
  }
  // Payload layout: PROTOCOL.md §4.16
  ControlReply read_control_reply() {
    ControlReply m;
    m.command = enumeration<ControlCommand>(0, 1, kMaxControlCommand);
    m.result = enumeration<ControlResult>(1, 0, kMaxControlResult);
    zero(2, 6);
    text(8, m.message);
    return m;
  }

  // Payload layout: PROTOCOL.md §4.17. The label is shown to people and written to logs and CSV:
  // one or more characters, valid UTF-8, no control characters.
  Marker read_marker() {
    Marker m;
    m.session_id = get<std::uint64_t>(0);
    m.marker_id = get<std::uint64_t>(8);
    if (m.marker_id == 0) fail(DecodeError::OutOfRange, 8);
    m.time_ns = get<std::int64_t>(16);
    m.received_ns = get<std::int64_t>(24);
    m.flags = flags(32, kMarkerFlagMask);
    if ((m.flags & kMarkerClientTime) == 0 && m.time_ns != m.received_ns) fail(DecodeError::OutOfRange, 16);
    zero(33, 7);
    text(40, m.label);
    std::size_t bad = 0;
    if (result && m.label.value.empty()) fail(DecodeError::BadString, 40);
    if (result && !printable_utf8(m.label.value, &bad)) fail(DecodeError::BadString, 40 + bad);
    return m;
  }

  // Payload layout: PROTOCOL.md §4.18. At least one eye is valid (else the message says nothing).
  GazeEyes read_gaze_eyes() {
    GazeEyes m;
    m.tracker_time_ns = get<std::int64_t>(0);
    const std::uint8_t left = flags(8, kEyeGazeFlagMask), right = flags(9, kEyeGazeFlagMask);
    zero(10, 6);
    m.left = eye_gaze(16, left);
    m.right = eye_gaze(32, right);
    if (result && !m.left.valid() && !m.right.valid()) fail(DecodeError::OutOfRange, 8);
    return m;
  }

  Payload read(MessageType t) {
    switch (t) {
      case MessageType::Hello: return read_hello();
      case MessageType::Challenge: return read_challenge();
      case MessageType::Subscribe: return read_subscribe();
      case MessageType::Subscribed: return read_subscribed();
      case MessageType::Heartbeat: return read_heartbeat();
      case MessageType::Unsubscribe: return read_unsubscribe();
      case MessageType::GazeSample: return read_gaze_sample();
      case MessageType::GazeEvent: return read_gaze_event();
      case MessageType::StatusRequest: return read_status_request();
      case MessageType::StatusReply: return read_status_reply();
      case MessageType::TimeSyncRequest: return read_time_sync_request();
      case MessageType::TimeSyncReply: return read_time_sync_reply();
      case MessageType::Error: return read_error();
      case MessageType::ControlRequest: return read_control_request();
      case MessageType::ControlReply: return read_control_reply();
      case MessageType::Marker: return read_marker();
      case MessageType::GazeEyes: return read_gaze_eyes();
    }
    fail(DecodeError::UnknownType, 0);
    return StatusRequest{};
  }
};

}  // namespace

std::size_t payload_size(MessageType t) { return size_of(t); }

MessageType type_of(const Payload& p) {
  return static_cast<MessageType>(p.index() + 1);  // variant order follows the type numbers
}

void encode_payload(const Payload& p, std::span<std::uint8_t> out) {
  const MessageType t = type_of(p);
  const std::size_t n = size_of(t);
  if (out.size() < n) throw std::invalid_argument("encode_payload: buffer too small");
  for (std::size_t i = 0; i < n; ++i) out[i] = 0;
  std::visit(Writer{out.first(n)}, p);
  // Nothing invalid reaches the wire or a file: check what was written with the decoder's rules.
  Payload check;
  const DecodeResult r = decode_payload(t, out.first(n), check);
  if (!r) {
    throw std::invalid_argument(std::string("cannot encode ") + to_string(t) + ": " + to_string(r.error) +
                                " at payload byte " + std::to_string(r.offset));
  }
}

DecodeResult decode_payload(MessageType t, std::span<const std::uint8_t> in, Payload& out) {
  const auto raw = static_cast<std::uint8_t>(t);
  if (raw < 1 || raw > kMaxMessageType) return {DecodeError::UnknownType, 0};
  if (in.size() != size_of(t)) return {DecodeError::BadPayloadLength, 0};
  Reader r{in};
  Payload p = r.read(t);
  if (r.result) out = std::move(p);
  return r.result;
}

std::size_t encode_into(const Message& m, std::span<std::uint8_t, kMaxDatagramSize> out) {
  const MessageType t = type_of(m.payload);
  const std::size_t n = size_of(t);
  std::span<std::uint8_t> buf(out.data(), kHeaderSize + n);
  for (std::size_t i = 0; i < 4; ++i) buf[i] = kMagic[i];
  store_le<std::uint8_t>(buf, 4, kVersion);
  store_le<std::uint8_t>(buf, 5, static_cast<std::uint8_t>(t));
  store_le<std::uint16_t>(buf, 6, static_cast<std::uint16_t>(n));
  store_le<std::uint64_t>(buf, 8, m.header.sequence);
  store_le<std::int64_t>(buf, 16, m.header.origin_time_ns);
  store_le<std::int64_t>(buf, 24, m.header.send_time_ns);
  encode_payload(m.payload, buf.subspan(kHeaderSize));
  return kHeaderSize + n;
}

std::vector<std::uint8_t> encode(const Message& m) {
  std::array<std::uint8_t, kMaxDatagramSize> buf{};
  const std::size_t n = encode_into(m, buf);
  return {buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(n)};
}

DecodeResult decode(std::span<const std::uint8_t> d, Message& out) {
  if (d.size() > kMaxDatagramSize) return {DecodeError::TooLong, kMaxDatagramSize};
  if (d.size() < kHeaderSize) return {DecodeError::TooShort, d.size()};
  for (std::size_t i = 0; i < 4; ++i) {
    if (d[i] != kMagic[i]) return {DecodeError::BadMagic, i};
  }
  if (d[4] != kVersion) return {DecodeError::BadVersion, 4};
  const std::uint8_t raw_type = d[5];
  if (raw_type < 1 || raw_type > kMaxMessageType) return {DecodeError::UnknownType, 5};
  const auto t = static_cast<MessageType>(raw_type);
  const auto length = load_le<std::uint16_t>(d, 6);
  if (length != size_of(t)) return {DecodeError::BadPayloadLength, 6};
  if (d.size() < kHeaderSize + length) return {DecodeError::TooShort, d.size()};
  if (d.size() > kHeaderSize + length) return {DecodeError::TooLong, kHeaderSize + length};

  Message m;
  m.header.type = t;
  m.header.payload_length = length;
  m.header.sequence = load_le<std::uint64_t>(d, 8);
  m.header.origin_time_ns = load_le<std::int64_t>(d, 16);
  m.header.send_time_ns = load_le<std::int64_t>(d, 24);
  DecodeResult r = decode_payload(t, d.subspan(kHeaderSize), m.payload);
  if (!r) {
    r.offset += kHeaderSize;
    return r;
  }
  out = std::move(m);
  return r;
}

}  // namespace fovea::protocol
