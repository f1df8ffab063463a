// SPDX-License-Identifier: Apache-2.0
#pragma once
// One canonical example of every protocol message, with distinctive field values, then variants of
// a message whose flags change its meaning (GAZE_EVENT provisional and retracted). The golden
// vectors in tests/data/golden and the worked examples in protocol/PROTOCOL.md are these bytes.
#include <string>
#include <utility>
#include <vector>

#include "fovea/protocol/messages.h"

namespace fovea::test {

inline std::vector<std::pair<std::string, protocol::Message>> canonical_messages() {
  using namespace protocol;
  const auto header = [](std::uint64_t seq) {
    Header h;
    h.sequence = seq;
    h.origin_time_ns = 1'000'000'000;  // 1 s
    h.send_time_ns = 1'000'250'000;    // 250 us later
    return h;
  };
  Cookie cookie{};
  for (std::size_t i = 0; i < cookie.size(); ++i) cookie[i] = static_cast<std::uint8_t>(0xC0 + i);
  DisplayGeometry display;  // 1920x1080, 0.5313 x 0.2989 m, 0.65 m

  std::vector<std::pair<std::string, Message>> out;
  Hello hello;
  hello.client_nonce = 0x0123456789ABCDEFULL;
  hello.client_name.value = "fovea-ctl watch";
  out.emplace_back("hello", Message{header(1), hello});
  out.emplace_back("challenge", Message{header(1), Challenge{0x0123456789ABCDEFULL, cookie, 10000}});
  out.emplace_back("subscribe", Message{header(2), Subscribe{cookie, 0x0123456789ABCDEFULL, kStreamSamples | kStreamEvents, 5000}});
  Subscribed sub;
  sub.session_id = 0x1122334455667788ULL;
  sub.streams = kStreamSamples | kStreamEvents;
  sub.lease_ms = 5000;
  sub.nominal_rate_hz = 250.0;
  sub.next_sample_sequence = 1000;
  sub.next_event_sequence = 20;
  sub.display = display;
  sub.multicast = MulticastInfo{0xEFFF2F50, 47801, 1};  // 239.255.47.80:47801
  out.emplace_back("subscribed", Message{header(2), sub});
  out.emplace_back("heartbeat", Message{header(3), Heartbeat{0x1122334455667788ULL, 5000}});
  out.emplace_back("unsubscribe", Message{header(4), Unsubscribe{0x1122334455667788ULL}});
  GazeSample s;
  s.tracker_time_ns = 1'000'000'000;
  s.x = 0.5f;
  s.y = 0.25f;
  s.x_deg = 0.0f;
  s.y_deg = -6.5625f;
  s.angular_velocity_deg_s = 12.5f;
  s.confidence = 0.75f;
  s.state = EyeMovement::Fixation;
  s.flags = kGazeValid;
  s.left = EyeData{kEyePupilValid | kEyeGlintValid, 323.5f, 214.0f, 3.5f, 0.25f, -6.0f};
  s.right = EyeData{kEyePupilValid, 317.0f, 214.0f, 3.5f, 0.0f, 0.0f};
  out.emplace_back("gaze_sample", Message{header(1000), s});
  GazeEvent e;
  e.kind = EyeMovement::Saccade;
  e.phase = EventPhase::End;
  e.start_time_ns = 999'960'000;
  e.duration_ns = 40'000'000;
  e.centroid_x = 0.75f;
  e.centroid_y = 0.5f;
  e.centroid_x_deg = 11.5f;
  e.centroid_y_deg = 0.0f;
  e.amplitude_deg = 8.0f;
  e.peak_velocity_deg_s = 350.0f;
  Header eh = header(20);
  eh.origin_time_ns = 999'960'000 + 40'000'000;
  out.emplace_back("gaze_event", Message{eh, e});
  out.emplace_back("status_request", Message{header(5), StatusRequest{}});
  StatusReply st;
  st.source.value = "replay:demo.fgr (x1, loop)";
  st.nominal_rate_hz = 250.0;
  st.uptime_ns = 60'000'000'000;
  st.samples_published = 15000;
  st.events_published = 800;
  st.datagrams_rejected = 3;
  st.subscribers = 2;
  st.source_state = SourceState::Running;
  st.display = display;
  out.emplace_back("status_reply", Message{header(5), st});
  out.emplace_back("time_sync_request", Message{header(6), TimeSyncRequest{5'000'000'000}});
  out.emplace_back("time_sync_reply", Message{header(6), TimeSyncReply{5'000'000'000, 1'000'100'000, 1'000'120'000}});
  out.emplace_back("error", Message{header(2), Error{ErrorCode::BadCookie, MessageType::Subscribe, kVersion}});
  ControlRequest control;
  control.command = ControlCommand::StartRecording;
  control.argument.value = "/var/lib/fovea/session-01.fgr";
  out.emplace_back("control_request", Message{header(7), control});
  ControlReply control_reply;
  control_reply.command = ControlCommand::StartRecording;
  control_reply.result = ControlResult::Ok;
  control_reply.message.value = "recording to /var/lib/fovea/session-01.fgr";
  out.emplace_back("control_reply", Message{header(7), control_reply});
  // As the daemon publishes it (session 0): the sender gave its own time (a display flip 2 ms before
  // the daemon received the marker), mapped to the daemon's clock.
  Marker marker;
  marker.marker_id = 0x0F0E0D0C0B0A0908ULL;
  marker.time_ns = 1'000'000'000;
  marker.received_ns = 1'002'000'000;
  marker.flags = kMarkerClientTime;
  marker.label.value = "trial 7: stimulus on";
  Header mh = header(3);
  mh.origin_time_ns = marker.time_ns;
  out.emplace_back("marker", Message{mh, marker});
  // The per-eye gaze of the canonical sample (same sequence and time): the eyes 1/32 of the screen
  // either side of the cyclopean point, as when looking at something behind a stereo display.
  GazeEyes eyes;
  eyes.tracker_time_ns = 1'000'000'000;
  eyes.left = EyeGaze{kEyeGazeValid, 0.46875f, 0.25f, -1.46875f, -6.5625f};
  eyes.right = EyeGaze{kEyeGazeValid, 0.53125f, 0.25f, 1.46875f, -6.5625f};
  out.emplace_back("gaze_eyes", Message{header(1000), eyes});
  // A provisional saccade onset (on the provisional stream, its own counter), said 12 ms after the
  // onset, and its retraction once the final labels have passed without confirming it.
  GazeEvent provisional;
  provisional.kind = EyeMovement::Saccade;
  provisional.phase = EventPhase::Start;
  provisional.flags = kEventProvisional;
  provisional.start_time_ns = 999'960'000;
  provisional.centroid_x = 0.5f;
  provisional.centroid_y = 0.5f;
  Header ph = header(7);
  ph.origin_time_ns = provisional.start_time_ns;
  ph.send_time_ns = 999'972'000;
  out.emplace_back("gaze_event_provisional", Message{ph, provisional});
  GazeEvent retracted = provisional;
  retracted.flags = kEventProvisional | kEventRetracted;
  Header rh = header(8);
  rh.origin_time_ns = provisional.start_time_ns;
  out.emplace_back("gaze_event_retracted", Message{rh, retracted});
  for (auto& [name, m] : out) m.header.type = type_of(m.payload);
  return out;
}

}  // namespace fovea::test
