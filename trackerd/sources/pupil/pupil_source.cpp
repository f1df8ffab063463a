// SPDX-License-Identifier: Apache-2.0
#include "sources/pupil/pupil_source.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <vector>
#include <zmq.hpp>

#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/clock.h"

namespace fovea::trackerd::pupil {

namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr int kRequestTimeoutMs = 1000;            // Pupil Remote answers in well under that
constexpr std::int64_t kSyncEveryNs = 1000 * kMs;  // one "t" exchange a second
// ... or every 100 ms for 3 s after the clock (re)started while the fastest exchange kept is slower
// than 2 ms (a busy machine): the mapping settles within a few exchanges of a quiet moment, not a
// second later (a CI run saw 65 samples stamped 15 ms off after a restart when it waited). Not for
// longer: over a network every exchange may be that slow, and Pupil Remote is not to be pestered.
constexpr std::int64_t kSettleEveryNs = 100 * kMs;
constexpr std::int64_t kSettleForNs = 3000 * kMs;
constexpr std::int64_t kSettledNs = 1 * kMs;  // uncertainty (half the round trip) counted as settled
// A burst of exchanges when the clock starts (or restarts): the fastest of them sets the offset,
// and Pupil Capture's answers wait on its busy main loop for a few ms at random.
constexpr int kBurstExchanges = 16;
constexpr std::int64_t kSurfaceStaleNs = 2000 * kMs;  // no surface for this long: scene gaze only
constexpr std::int64_t kSilenceNs = 3000 * kMs;       // no message at all: ask for the publisher again
// What a hostile publisher can make us hold: ZeroMQ drops a peer that sends a larger frame, and
// queues at most kReceiveQueue messages: 256 KiB x 1000 = 256 MB at worst, about 5 s of real gaze.
constexpr std::int64_t kMaxMessageBytes = static_cast<std::int64_t>(kMaxPayloadBytes);
constexpr int kReceiveQueue = 1000;
constexpr std::int64_t kClockSlackNs = 5 * kMs;     // a mapped time this far after arrival: the clock is off
constexpr std::int64_t kMaxLatencyNs = 1000 * kMs;  // ... or this far before

std::string endpoint(const std::string& host, std::uint16_t port) { return "tcp://" + host + ":" + std::to_string(port); }

}  // namespace

// One connection: Pupil Remote and the subscription, with what they last said.
struct PupilSource::Connection {
  zmq::context_t& context;
  zmq::socket_t remote{context, zmq::socket_type::req};
  zmq::socket_t sub{context, zmq::socket_type::sub};
  std::uint16_t sub_port = 0;
  std::int64_t next_sync_ns = 0;
  std::int64_t settle_until_ns = 0;  // the clock (re)started: exchanges may come faster until then
  std::int64_t last_message_ns = 0;

  explicit Connection(zmq::context_t& ctx) : context(ctx) {}

  // The next "t" exchange: soon while the clock settles after a (re)start, else in a second.
  void schedule_sync(std::int64_t now, std::int64_t uncertainty_ns) {
    const bool settling = now < settle_until_ns && uncertainty_ns > kSettledNs;
    next_sync_ns = now + (settling ? kSettleEveryNs : kSyncEveryNs);
  }

  void open_remote(const PupilSpec& spec) {
    remote.set(zmq::sockopt::linger, 0);
    remote.set(zmq::sockopt::rcvtimeo, kRequestTimeoutMs);
    remote.set(zmq::sockopt::sndtimeo, kRequestTimeoutMs);
    remote.connect(endpoint(spec.host, spec.port));
  }

  // One request and its answer; nullopt when Pupil Remote does not answer in time (the REQ socket
  // is then unusable: the caller drops the connection).
  std::optional<std::string> request(const std::string& text) {
    if (!remote.send(zmq::buffer(text), zmq::send_flags::none)) return std::nullopt;
    zmq::message_t reply;
    if (!remote.recv(reply, zmq::recv_flags::none)) return std::nullopt;
    if (reply.more()) return std::nullopt;  // Pupil Remote answers in one frame
    return std::string(static_cast<const char*>(reply.data()), std::min<std::size_t>(reply.size(), 256));
  }

  void subscribe(const PupilSpec& spec, std::uint16_t port) {
    sub = zmq::socket_t(context, zmq::socket_type::sub);
    sub.set(zmq::sockopt::linger, 0);
    sub.set(zmq::sockopt::maxmsgsize, kMaxMessageBytes);
    sub.set(zmq::sockopt::rcvhwm, kReceiveQueue);
    if (!spec.scene_gaze) sub.set(zmq::sockopt::subscribe, "surfaces." + spec.surface);
    sub.set(zmq::sockopt::subscribe, "gaze.");
    sub.connect(endpoint(spec.host, port));
    sub_port = port;
  }
};

PupilSource::PupilSource(PupilSpec spec, protocol::DisplayGeometry display, double nominal_rate_hz)
    : ReaderSource(display, nominal_rate_hz), spec_(std::move(spec)) {
  if (spec_.scene_gaze) {
    spdlog::warn("{}: publishes the scene camera's gaze (its image, normalised), not screen gaze: map it with a fovea "
                 "calibration of input \"screen\" (fovea-calibrate run, then --calibration or fovea-ctl "
                 "calibration-load), with the head as still as during calibration",
                 description());
  }
  start_reader([this] { run(); });
}

void PupilSource::set_problem(Problem kind, std::string text) {
  problem_kind_ = kind;
  problem_.set(std::move(text));
}

PupilStats PupilSource::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

std::string PupilSource::status_detail() const {
  const PupilStats s = stats();
  std::string out = std::to_string(s.samples) + " samples (" + std::to_string(s.valid) + " valid, " +
                    std::to_string(s.low_confidence) + " below confidence, " + std::to_string(s.off_surface) +
                    " off the surface), " + std::to_string(s.scene_only) + " scene-only, " +
                    std::to_string(s.malformed) + " malformed, " + std::to_string(s.gaps) + " dropouts";
  out += arrivals_.status();
  if (s.stamped_unsynced > 0) {
    out += ", " + std::to_string(s.stamped_unsynced) + " stamped on arrival while the clock re-synced";
  }
  char clock[256];
  std::snprintf(clock, sizeof clock,
                ", clock offset %.3f ms +- %.3f ms over %llu exchanges, drift %s ppm, delay p50 %.2f / p99 %.2f ms",
                static_cast<double>(s.clock_offset_ns) / 1e6, static_cast<double>(s.clock_uncertainty_ns) / 1e6,
                static_cast<unsigned long long>(s.clock_exchanges),
                s.clock_drift_ppm ? std::to_string(static_cast<long>(std::lround(*s.clock_drift_ppm))).c_str() : "?",
                static_cast<double>(s.delay_p50_ns) / 1e6, static_cast<double>(s.delay_p99_ns) / 1e6);
  out += clock;
  if (s.connects > 1) out += ", " + std::to_string(s.connects - 1) + " reconnections";
  if (s.malformed > 0) out += "; last refused: " + protocol::escape_for_log(s.last_malformed, 80);
  return out;
}

void PupilSource::count_malformed(const std::string& why) {
  std::lock_guard lock(mutex_);
  ++stats_.malformed;
  stats_.last_malformed = why;
}

// ---- the reader thread -----------------------------------------------------------------------

void PupilSource::run() {
  zmq::context_t context(1);
  while (!stopping()) {
    {
      Connection c(context);
      try {
        serve(c);
      } catch (const zmq::error_t& e) {
        set_problem(Problem::Lost, description() + ": " + e.what() + "; reconnecting every second");
      }
    }
    {
      std::lock_guard lock(mutex_);
      stats_.connected = false;
    }
    for (int i = 0; i < 20 && !stopping(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

// One "t" exchange fed to the clock (false: no valid answer); a jump restarts the order check.
bool PupilSource::sync_clock(Connection& c) {
  const std::int64_t sent = protocol::monotonic_ns();
  const auto reply = c.request("t");
  const std::int64_t received = protocol::monotonic_ns();
  const auto t = reply ? parse_time_reply(*reply) : std::nullopt;
  if (!t) return false;
  const std::uint64_t resets = clock_.resets();
  clock_.add(sent, received, *t);
  std::lock_guard lock(mutex_);
  if (clock_.resets() != resets) {
    spdlog::info("{}: Pupil time jumped (Pupil Capture restarted?)", description());
    last_timestamp_ = -1e300;  // the new clock may start below the old one
  }
  clock_suspect_ = false;
  stats_.clock_exchanges = clock_.exchanges();
  stats_.clock_resets = clock_.resets();
  stats_.clock_offset_ns = clock_.offset_ns();
  stats_.clock_uncertainty_ns = clock_.uncertainty_ns();
  stats_.clock_last_rtt_ns = clock_.last_round_trip_ns();
  stats_.clock_drift_ppm = clock_.drift_ppm();
  return true;
}

// Connects (Pupil Remote, clock, publisher) and reads until Pupil Capture stops answering or the
// source stops. Returns to be reconnected.
void PupilSource::serve(Connection& c) {
  c.open_remote(spec_);
  const auto lost = [&](const std::string& what) {
    set_problem(Problem::Lost, description() + ": " + what + " (is Pupil Capture running, with Pupil Remote on port " +
                std::to_string(spec_.port) + "?); reconnecting every second");
  };
  const auto find_publisher = [&]() -> bool {
    const auto reply = c.request("SUB_PORT");
    const auto port = reply ? parse_port_reply(*reply) : std::nullopt;
    if (!port) return false;
    if (*port != c.sub_port) c.subscribe(spec_, *port);
    return true;
  };
  for (int i = 0; i < kBurstExchanges; ++i) {
    if (!sync_clock(c)) return lost("no answer to \"t\"");
  }
  if (!find_publisher()) return lost("no answer to \"SUB_PORT\"");
  {
    std::lock_guard lock(mutex_);
    stats_.connected = true;
    ++stats_.connects;
  }
  set_problem(Problem::Waiting, description() + ": connected; waiting for gaze");
  spdlog::info("{}: connected (publisher on port {})", description(), c.sub_port);
  c.last_message_ns = protocol::monotonic_ns();
  last_surface_ns_ = c.last_message_ns;  // give the surface its 2 s before calling gaze scene-only
  c.settle_until_ns = c.last_message_ns + kSettleForNs;
  c.schedule_sync(c.last_message_ns, clock_.uncertainty_ns());
  while (!stopping()) {
    zmq::pollitem_t item{c.sub.handle(), 0, ZMQ_POLLIN, 0};
    zmq::poll(&item, 1, std::chrono::milliseconds(50));
    const std::int64_t now = protocol::monotonic_ns();
    if (item.revents & ZMQ_POLLIN) {
      // Drain what is there (at most a few hundred messages), then tend the clock.
      for (int i = 0; i < 256 && handle_message(c, now); ++i) c.last_message_ns = now;
    }
    if (now >= c.next_sync_ns || clock_suspect()) {
      const std::uint64_t resets = clock_.resets();
      if (!sync_clock(c)) return lost("Pupil Remote stopped answering");
      for (int i = 1; i < kBurstExchanges && clock_.resets() != resets; ++i) {
        if (!sync_clock(c)) return lost("Pupil Remote stopped answering");
      }
      // A restarted Pupil Capture has a new clock, and its publisher may be on another port.
      if ((clock_.resets() != resets || now - c.last_message_ns > kSilenceNs) && !find_publisher()) {
        return lost("no answer to \"SUB_PORT\"");
      }
      if (clock_.resets() != resets) c.settle_until_ns = now + kSettleForNs;
      c.schedule_sync(now, clock_.uncertainty_ns());
    }
    if (now - last_surface_ns_ > kSurfaceStaleNs && now - c.last_message_ns < kSurfaceStaleNs && stats().scene_only > 0) {
      set_problem(Problem::SceneOnly, description() + ": only scene-camera gaze, no surface \"" + spec_.surface +
                  "\" (define it in Pupil Capture's Surface Tracker, fitted to the screen): screen gaze is invalid");
    } else if (now - c.last_message_ns > kSilenceNs) {
      set_problem(Problem::Silent, description() + ": connected, but no gaze for 3 s (are the eye cameras running?)");
    }
  }
}

bool PupilSource::handle_message(Connection& c, std::int64_t receive_ns) {
  std::vector<zmq::message_t> frames;
  zmq::message_t first;
  if (!c.sub.recv(first, zmq::recv_flags::dontwait)) return false;
  bool more = first.more();
  frames.push_back(std::move(first));
  while (more) {  // the rest of a multipart message is already there
    zmq::message_t part;
    if (!c.sub.recv(part, zmq::recv_flags::none)) break;
    more = part.more();
    if (frames.size() < 3) frames.push_back(std::move(part));
  }
  if (frames.size() != 2) {
    count_malformed("a message of " + std::to_string(frames.size()) + (frames.size() > 2 ? "+" : "") +
                    " frames (topic and payload expected)");
    return true;
  }
  const std::string topic(static_cast<const char*>(frames[0].data()), std::min<std::size_t>(frames[0].size(), 128));
  const std::span<const std::uint8_t> payload(static_cast<const std::uint8_t*>(frames[1].data()), frames[1].size());
  std::string error;
  if (topic == "surfaces." + spec_.surface) {
    const auto gaze = parse_surface_payload(payload, spec_.surface, error);
    if (!gaze) {
      count_malformed(topic + ": " + error);
      return true;
    }
    last_surface_ns_ = receive_ns;
    if (problem_kind_ != Problem::None) set_problem(Problem::None, "");  // screen gaze is flowing
    for (const PupilGaze& g : *gaze) publish(g, true, receive_ns);
  } else if (topic.rfind("gaze.", 0) == 0) {
    const auto g = parse_gaze_payload(payload, error);
    if (!g) {
      count_malformed(topic + ": " + error);
      return true;
    }
    if (spec_.scene_gaze) {
      if (problem_kind_ != Problem::None) set_problem(Problem::None, "");
      publish(*g, true, receive_ns);  // the point a fovea calibration maps
      return true;
    }
    // With the surface present, its gaze is the screen gaze; this datum is the same gaze in the
    // scene camera's image. Without it, the stream goes on, invalid.
    if (receive_ns - last_surface_ns_ > kSurfaceStaleNs) publish(*g, false, receive_ns);
  }
  return true;
}

// One gaze point as a sample: Pupil time mapped onto the host clock (never after it arrived), y
// flipped to fovea's top-left origin; invalid below the confidence threshold or without a screen.
// Over the rate cap it is counted and dropped; during a flood it is stamped on arrival.
void PupilSource::publish(const PupilGaze& g, bool screen, std::int64_t receive_ns) {
  std::lock_guard lock(mutex_);
  if (!(g.timestamp > last_timestamp_)) {
    ++stats_.out_of_order;
    return;
  }
  if (screen && g.timestamp - last_timestamp_ > 2.5 / nominal_rate_hz_ && last_timestamp_ > -1e300) ++stats_.gaps;
  last_timestamp_ = g.timestamp;
  const net::ArrivalGuard::Admission a = arrivals_.admit(receive_ns);
  if (!a.keep) return;  // counted by the guard; the clock is fed by "t" exchanges, not by gaze
  protocol::GazeSample s;
  if (a.flooding) {
    s.tracker_time_ns = receive_ns;
  } else {
    // A gaze can only have been taken before it arrived (a later time is stamped on arrival and
    // counted by the guard), and not long before: a mapped time beyond that means Pupil time
    // jumped (a restart, "T" from another client) before the clock heard of it. The clock is then
    // asked again at once, and until it answers every gaze is stamped on arrival (counted too).
    const std::int64_t mapped = clock_.to_host_ns(g.timestamp);
    if (mapped > receive_ns + kClockSlackNs || mapped < receive_ns - kMaxLatencyNs) clock_suspect_ = true;
    s.tracker_time_ns = arrivals_.not_after_arrival(mapped, receive_ns);
    if (clock_suspect_ && s.tracker_time_ns != receive_ns) {
      s.tracker_time_ns = receive_ns;
      ++stats_.stamped_unsynced;
    }
    delays_.add(receive_ns - s.tracker_time_ns);
    if (++delay_samples_ % 64 == 1) {
      stats_.delay_p50_ns = delays_.percentile(0.5);
      stats_.delay_p99_ns = delays_.percentile(0.99);
    }
  }
  s.confidence = static_cast<float>(g.confidence);
  const double x = g.x, y = 1.0 - g.y_up;
  const bool confident = g.confidence >= spec_.min_confidence;
  const bool on_screen_plane = x >= -1 && x <= 2 && y >= -1 && y <= 2;
  if (!screen) {
    ++stats_.scene_only;
  } else {
    ++stats_.samples;
    if (!confident) ++stats_.low_confidence;
    if (!g.on_surface) ++stats_.off_surface;
    if (confident && on_screen_plane) {
      s.x = static_cast<float>(x);
      s.y = static_cast<float>(y);
      const protocol::Degrees d = protocol::normalized_to_degrees(display_, {x, y});
      s.x_deg = static_cast<float>(d.x);
      s.y_deg = static_cast<float>(d.y);
      s.flags = protocol::kGazeValid;
      ++stats_.valid;
    }
  }
  queue_.push(s, receive_ns);
}

}  // namespace fovea::trackerd::pupil
