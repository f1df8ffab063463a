// SPDX-License-Identifier: Apache-2.0
#include "live_feed.h"

#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/control_socket.h"

namespace fovea::monitor {

using nlohmann::json;
using protocol::monotonic_ns;

namespace {

double unix_ms() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

// Numbers for the page: finite, short.
std::string num(double v, int decimals = 3) {
  if (!std::isfinite(v)) return "null";
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

std::string dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

std::shared_ptr<const std::string> text(std::string s) { return std::make_shared<const std::string>(std::move(s)); }

std::string first_existing_socket(const std::vector<std::string>& candidates) {
  for (const std::string& c : candidates) {
    struct stat st {};
    if (::lstat(c.c_str(), &st) == 0 && S_ISSOCK(st.st_mode)) return c;
  }
  return {};
}

}  // namespace

std::string sample_row_json(const protocol::GazeSample& s) {
  // [t_ms, x, y (normalised), x_deg, y_deg, velocity deg/s, label, valid, confidence]
  return "[" + num(static_cast<double>(s.tracker_time_ns) * 1e-6) + "," + num(s.x, 5) + "," + num(s.y, 5) + "," +
         num(s.x_deg, 3) + "," + num(s.y_deg, 3) + "," + num(s.angular_velocity_deg_s, 1) + "," +
         std::to_string(static_cast<int>(s.state)) + "," + ((s.flags & protocol::kGazeValid) != 0 ? "1" : "0") + "," +
         num(s.confidence, 2) + "]";
}

std::string event_json(const protocol::GazeEvent& e) {
  return dump(json{{"kind", protocol::to_string(e.kind)},
                   {"phase", e.phase == protocol::EventPhase::Start ? "start" : "end"},
                   {"t_ms", static_cast<double>(e.start_time_ns) * 1e-6},
                   {"duration_ms", static_cast<double>(e.duration_ns) * 1e-6},
                   {"x", e.centroid_x},
                   {"y", e.centroid_y},
                   {"amplitude_deg", e.amplitude_deg},
                   {"peak_velocity_deg_s", e.peak_velocity_deg_s},
                   {"provisional", e.provisional()},
                   {"retracted", (e.flags & protocol::kEventRetracted) != 0}});
}

LiveFeed::LiveFeed(FeedOptions options, WebServer& web)
    : options_(std::move(options)),
      web_(web),
      control_socket_(!options_.control_socket.empty()
                          ? options_.control_socket
                          : first_existing_socket(protocol::control_socket_candidates(options_.server.port))),
      viewer_socket_(!options_.viewer_socket.empty() ? options_.viewer_socket
                     : control_socket_.empty()       ? std::string()
                                                     : protocol::viewer_socket_for(control_socket_)),
      client_([&] {
        protocol::ClientOptions o;
        o.server = options_.server;
        o.name = "fovea-monitor";
        o.streams = protocol::kStreamSamples | protocol::kStreamEvents | protocol::kStreamProvisional |
                    protocol::kStreamMarkers;
        return o;
      }()) {
  client_.on_sample([this](const protocol::GazeSample& s, const protocol::Arrival& a) {
    std::lock_guard lock(mutex_);
    if (samples_.size() < 20000) samples_.push_back({s, a});  // 20 s at 1 kHz: the pages are gone
    ++stats_.samples;
    const bool valid = (s.flags & protocol::kGazeValid) != 0;
    if (last_valid_ && !valid) ++dropouts_;
    last_valid_ = valid;
  });
  client_.on_event([this](const protocol::GazeEvent& e, const protocol::Arrival&) {
    std::lock_guard lock(mutex_);
    if (events_.size() < 2000) events_.push_back(e);
    ++stats_.events;
  });
  client_.on_marker([this](const protocol::Marker& m, const protocol::Arrival&) {
    std::lock_guard lock(mutex_);
    if (markers_.size() < 200) markers_.push_back(m);
  });
  client_.start();
  batch_thread_ = std::thread([this] { batch_loop(); });
  viewer_thread_ = std::thread([this] { viewer_loop(); });
  status_thread_ = std::thread([this] { status_loop(); });
}

LiveFeed::~LiveFeed() {
  stop_.store(true);
  commands_cv_.notify_all();
  for (std::thread* t : {&batch_thread_, &viewer_thread_, &status_thread_}) {
    if (t->joinable()) t->join();
  }
  client_.stop();
}

bool LiveFeed::controls() const { return !control_socket_.empty() && ::access(control_socket_.c_str(), W_OK) == 0; }

FeedStats LiveFeed::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

std::vector<Outgoing> LiveFeed::opening_messages() {
  json hello{{"type", "hello"},
             {"version", FOVEA_VERSION},
             {"server", options_.server.to_string()},
             {"controls", controls()},
             {"labels", {"unknown", "fixation", "saccade", "pursuit", "blink"}}};
  std::vector<Outgoing> out{{text(dump(hello)), Outgoing::Kind::Text}};
  std::lock_guard lock(mutex_);
  for (const auto& m : {last_status_, last_daemon_}) {
    if (m) out.push_back({m, Outgoing::Kind::Text});
  }
  if (last_frame_) out.push_back({last_frame_, Outgoing::Kind::EyeFrame});
  return out;
}

void LiveFeed::remember(std::shared_ptr<const std::string>& slot, const std::shared_ptr<const std::string>& value) {
  std::lock_guard lock(mutex_);
  slot = value;
}

// ---- gaze batches -------------------------------------------------------------------------------

void LiveFeed::batch_loop() {
  const auto period = std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / options_.batch_hz));
  auto next = std::chrono::steady_clock::now();
  while (!stop_.load()) {
    next += period;
    std::this_thread::sleep_until(next);
    send_batch();
  }
}

// {"type":"gaze","sent_unix_ms":..,"age_ms":..,"samples":[rows],"events":[..],"markers":[..]}. age_ms:
// how long ago the newest sample reached the daemon, on this host's clock (the page adds its own
// part to get the latency from the daemon to the screen).
void LiveFeed::send_batch() {
  std::vector<PendingSample> samples;
  std::vector<protocol::GazeEvent> events;
  std::vector<protocol::Marker> markers;
  {
    std::lock_guard lock(mutex_);
    samples.swap(samples_);
    events.swap(events_);
    markers.swap(markers_);
  }
  if (samples.empty() && events.empty() && markers.empty()) return;
  std::string age = "null";
  if (!samples.empty() && client_.clock_known()) {
    const std::int64_t offset = client_.stats().clock_offset_ns;
    const std::int64_t at_daemon = samples.back().arrival.host_receive_ns - offset;  // on our clock
    age = num(static_cast<double>(monotonic_ns() - at_daemon) * 1e-6);
  }
  std::string m = "{\"type\":\"gaze\",\"sent_unix_ms\":" + num(unix_ms()) + ",\"age_ms\":" + age + ",\"samples\":[";
  m.reserve(m.size() + samples.size() * 80);
  for (std::size_t i = 0; i < samples.size(); ++i) m += (i ? "," : "") + sample_row_json(samples[i].sample);
  m += "],\"events\":[";
  for (std::size_t i = 0; i < events.size(); ++i) m += (i ? "," : "") + event_json(events[i]);
  m += "],\"markers\":[";
  for (std::size_t i = 0; i < markers.size(); ++i) {
    m += (i ? "," : "") + dump(json{{"label", markers[i].label.value}, {"t_ms", static_cast<double>(markers[i].time_ns) * 1e-6}});
  }
  m += "]}";
  web_.broadcast({text(std::move(m)), Outgoing::Kind::Text});
  std::lock_guard lock(mutex_);
  ++stats_.batches;
}

// ---- the viewer feed ----------------------------------------------------------------------------

void LiveFeed::viewer_loop() {
  std::unique_ptr<protocol::ViewerFeedReader> reader;
  while (!stop_.load()) {
    if (!reader) {
      try {
        if (viewer_socket_.empty()) throw std::runtime_error("no control socket of a daemon on port " +
                                                             std::to_string(options_.server.port) +
                                                             " on this host (give --viewer-socket)");
        reader = std::make_unique<protocol::ViewerFeedReader>(viewer_socket_);
        std::lock_guard lock(mutex_);
        stats_.viewer_connected = true;
        stats_.viewer_problem.clear();
      } catch (const std::exception& e) {
        {
          std::lock_guard lock(mutex_);
          stats_.viewer_connected = false;
          stats_.viewer_problem = e.what();
        }
        for (int i = 0; i < 10 && !stop_.load(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
        continue;
      }
    }
    std::optional<protocol::ViewerMessage> m = reader->next(100);
    if (!m) {
      if (reader->closed()) {
        reader.reset();
        std::lock_guard lock(mutex_);
        stats_.viewer_connected = false;
        stats_.viewer_problem = "the daemon closed the viewer feed (restarting?)";
      }
      continue;
    }
    if (const auto* frame = std::get_if<protocol::EyeFrameMessage>(&*m)) {
      on_eye_frame(*frame);
    } else {
      on_daemon_status(std::get<protocol::DaemonStatusMessage>(*m).json);
    }
  }
}

// Binary to the page: [u32 little-endian length of the JSON][JSON: what the detector found, in the
// camera's pixels][JPEG of the (downscaled) image].
void LiveFeed::on_eye_frame(const protocol::EyeFrameMessage& f) {
  if (web_.stats().sessions == 0) return;  // nobody looks: no JPEG (a page that opens gets the next frame)
  const std::int64_t t0 = monotonic_ns();
  std::vector<std::uint8_t> jpeg;
  const cv::Mat image(f.height, f.width, CV_8UC1, const_cast<std::uint8_t*>(f.pixels.data()));
  if (!cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, options_.jpeg_quality})) return;
  const std::int64_t encode_ns = monotonic_ns() - t0;
  const protocol::EyeFrameInfo& i = f.info;
  json glints = json::array();
  for (std::size_t g = 0; g < i.glint_count; ++g) glints.push_back({i.glint_x[g], i.glint_y[g]});
  json meta{{"frame", i.frame},
            {"t_ms", static_cast<double>(i.time_ns) * 1e-6},
            {"width", f.width},
            {"height", f.height},
            {"source_width", i.source_width},
            {"source_height", i.source_height},
            {"pupil", (i.flags & protocol::kEyeFramePupil) != 0
                          ? json{i.pupil_x, i.pupil_y, i.pupil_major, i.pupil_minor, i.pupil_angle_deg}
                          : json(nullptr)},
            {"blink", (i.flags & protocol::kEyeFrameBlink) != 0},
            {"glint_valid", (i.flags & protocol::kEyeFrameGlint) != 0},
            {"used_roi", (i.flags & protocol::kEyeFrameRoi) != 0},
            {"confidence", i.confidence},
            {"roi", {i.roi_x, i.roi_y, i.roi_width, i.roi_height}},
            {"glints", glints},
            {"detect_ms", static_cast<double>(i.detect_ns) * 1e-6},
            {"encode_ms", static_cast<double>(encode_ns) * 1e-6},
            {"sent_unix_ms", unix_ms()}};
  if (client_.clock_known()) {
    meta["age_ms"] = static_cast<double>(monotonic_ns() - (i.time_ns - client_.stats().clock_offset_ns)) * 1e-6;
  }
  const std::string head = dump(meta);
  std::string out(4, '\0');
  const auto n = static_cast<std::uint32_t>(head.size());
  for (int b = 0; b < 4; ++b) out[static_cast<std::size_t>(b)] = static_cast<char>((n >> (8 * b)) & 0xFF);
  out += head;
  out.append(reinterpret_cast<const char*>(jpeg.data()), jpeg.size());
  const auto shared = text(std::move(out));
  remember(last_frame_, shared);
  web_.broadcast({shared, Outgoing::Kind::EyeFrame});
  std::lock_guard lock(mutex_);
  ++stats_.eye_frames;
  stats_.jpeg_ns_total += encode_ns;
}

// The daemon's own JSON, checked and passed on: {"type":"daemon","status":{...}}.
void LiveFeed::on_daemon_status(const std::string& text_in) {
  json status = json::parse(text_in, nullptr, false);
  if (status.is_discarded() || !status.is_object()) return;
  const auto shared = text(dump(json{{"type", "daemon"}, {"status", status}}));
  remember(last_daemon_, shared);
  web_.broadcast({shared, Outgoing::Kind::Text});
  std::lock_guard lock(mutex_);
  ++stats_.daemon_statuses;
}

// ---- status and commands ------------------------------------------------------------------------

void LiveFeed::status_loop() {
  auto next = std::chrono::steady_clock::now();
  while (!stop_.load()) {
    std::optional<Command> command;
    {
      std::unique_lock lock(mutex_);
      commands_cv_.wait_until(lock, next, [this] { return stop_.load() || !commands_.empty(); });
      if (!commands_.empty()) {
        command = std::move(commands_.front());
        commands_.pop_front();
      }
    }
    if (stop_.load()) return;
    if (command) {
      web_.send_to(command->session, {text(run_command(command->text)), Outgoing::Kind::Text});
      continue;
    }
    send_status();
    next = std::chrono::steady_clock::now() + std::chrono::seconds(1);
  }
}

void LiveFeed::send_status() {
  const std::optional<protocol::StatusReply> st = protocol::GazeClient::query_status(options_.server, 500);
  const protocol::ClientStats cs = client_.stats();
  const std::int64_t now = monotonic_ns();
  json j{{"type", "status"}, {"server", options_.server.to_string()}, {"reachable", st.has_value()},
         {"subscribed", client_.subscribed()}};
  if (st) {
    static const char* states[] = {"running", "ended", "retrying"};
    j["source"] = st->source.value;
    j["source_state"] = states[static_cast<int>(st->source_state)];
    j["nominal_rate_hz"] = st->nominal_rate_hz;
    j["uptime_s"] = static_cast<double>(st->uptime_ns) * 1e-9;
    j["samples_published"] = st->samples_published;
    j["events_published"] = st->events_published;
    j["subscribers"] = st->subscribers;
    j["rejected"] = st->datagrams_rejected;
    j["display"] = {{"width_px", st->display.width_px},     {"height_px", st->display.height_px},
                    {"width_m", st->display.width_m},       {"height_m", st->display.height_m},
                    {"viewing_distance_m", st->display.viewing_distance_m}};
  }
  j["received"] = cs.samples.received;
  j["lost"] = cs.samples.lost;
  j["latency_p50_ms"] = static_cast<double>(cs.latency_p50_ns) * 1e-6;
  j["latency_p99_ms"] = static_cast<double>(cs.latency_p99_ns) * 1e-6;
  FeedStats fs;
  {
    std::lock_guard lock(mutex_);
    j["dropouts"] = dropouts_;
    fs = stats_;
    if (client_.clock_known()) {
      j["clock_offset_ms"] = static_cast<double>(cs.clock_offset_ns) * 1e-6;
      j["clock_round_trip_ms"] = static_cast<double>(cs.clock_round_trip_ns) * 1e-6;
      if (!first_offset_) first_offset_ = std::pair{now, cs.clock_offset_ns};
      const double span_s = static_cast<double>(now - first_offset_->first) * 1e-9;
      // Drift: the offset's change per second, in parts per million, once 10 s tell it from jitter.
      j["clock_drift_ppm"] = span_s >= 10 ? json(static_cast<double>(cs.clock_offset_ns - first_offset_->second) * 1e-3 / span_s)
                                          : json(nullptr);
    }
  }
  j["viewer_feed"] = fs.viewer_connected ? json("connected") : json(fs.viewer_problem);
  j["eye_frames_received"] = fs.eye_frames;
  const auto shared = text(dump(j));
  remember(last_status_, shared);
  web_.broadcast({shared, Outgoing::Kind::Text});
}

void LiveFeed::on_page_message(WebServer::SessionId session, std::string text_in) {
  std::lock_guard lock(mutex_);
  if (commands_.size() >= 16) return;  // a page flooding commands: the rest are ignored
  commands_.push_back({session, std::move(text_in)});
  commands_cv_.notify_one();
}

// {"type":"mark","label":L} | {"type":"record-start","path":P} | {"type":"record-stop"}; the reply is
// {"type":"reply","command":..,"ok":..,"message":..}.
std::string LiveFeed::run_command(const std::string& text_in) {
  {
    std::lock_guard lock(mutex_);
    ++stats_.commands;
  }
  const json c = json::parse(text_in, nullptr, false);
  const std::string type = c.is_object() && c.contains("type") && c["type"].is_string() ? c["type"].get<std::string>() : "";
  json reply{{"type", "reply"}, {"command", type}, {"ok", false}};
  const auto answer = [&](bool ok, const std::string& message) {
    reply["ok"] = ok;
    reply["message"] = message;
    return dump(reply);
  };
  if (!controls()) return answer(false, "this fovea-monitor's user may not control the daemon (its control socket)");
  const auto string_field = [&](const char* key) {
    return c.contains(key) && c[key].is_string() ? c[key].get<std::string>() : std::string();
  };
  try {
    if (type == "mark") {
      const std::string label = string_field("label");
      protocol::GazeClient::check_marker_label(label);
      client_.mark(label);
      return answer(true, "marker \"" + label + "\" sent");
    }
    protocol::ControlRequest r;
    if (type == "record-start") {
      r.command = protocol::ControlCommand::StartRecording;
      r.argument.value = string_field("path");
    } else if (type == "record-stop") {
      r.command = protocol::ControlCommand::StopRecording;
    } else {
      return answer(false, "unknown command");
    }
    std::string error;
    const auto got = protocol::send_local_control(control_socket_, r, 3000, error);
    if (!got) return answer(false, error);
    return answer(got->result == protocol::ControlResult::Ok, got->message.value);
  } catch (const std::exception& e) {
    return answer(false, e.what());
  }
}

}  // namespace fovea::monitor
