// SPDX-License-Identifier: Apache-2.0
// fovea-ctl's daemon client: status, watch, record (subscribed clients of the gaze stream) and the
// control commands (reload, record-start, record-stop, calibration-load).
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "ctl/commands.h"
#include "fovea/protocol/client.h"
#include "fovea/protocol/control_socket.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/recording.h"

namespace fovea::ctl {
namespace {

using namespace fovea::protocol;

struct Common {
  std::string server = "127.0.0.1:47800";
  std::string name;
  std::string stats_json;
  double duration_s = 0;
  std::string multicast;
  int connect_timeout_ms = 5000;
  std::string control_socket;  // control commands: this socket ("" : the daemon's default on this host)
};

std::string ms(std::int64_t ns) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", static_cast<double>(ns) / 1e6);
  return buf;
}

// Runs a subscribed client until the duration elapses or a signal arrives, then prints a summary.
int run_client(const Common& c, const std::string& role, std::uint32_t streams,
               const std::function<void(GazeClient&)>& setup, const std::function<void(const Subscribed&)>& on_subscribed) {
  ClientOptions co;
  try {
    co.server = parse_endpoint(c.server, kDefaultPort);
    if (!c.multicast.empty()) co.multicast_group = parse_endpoint(c.multicast, 0);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl %s: %s\n", role.c_str(), e.what());
    return 2;
  }
  co.streams = streams;
  co.name = c.name.empty() ? "fovea-ctl " + role : c.name;
  std::unique_ptr<GazeClient> client;
  try {
    client = std::make_unique<GazeClient>(co);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl %s: %s\n", role.c_str(), e.what());
    return 2;
  }
  setup(*client);
  client->start();
  if (!client->wait_subscribed(c.connect_timeout_ms)) {
    if (client->stats().last_error == ErrorCode::TooManySubscribers) {
      std::fprintf(stderr,
                   "fovea-ctl %s: %s refused the subscription: too many subscribers (in all, or from this "
                   "address); try again when some have left\n",
                   role.c_str(), co.server.to_string().c_str());
    } else {
      std::fprintf(stderr, "fovea-ctl %s: no answer from %s within %d ms; is fovea-trackerd running there?\n",
                   role.c_str(), co.server.to_string().c_str(), c.connect_timeout_ms);
    }
    return 1;
  }
  try {
    on_subscribed(*client->session());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl %s: %s\n", role.c_str(), e.what());
    return 2;
  }
  const std::int64_t end = c.duration_s > 0 ? monotonic_ns() + static_cast<std::int64_t>(c.duration_s * 1e9) : INT64_MAX;
  while (!stop_requested().load() && monotonic_ns() < end) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  client->stop();

  const ClientStats s = client->stats();
  std::fprintf(stderr,
               "fovea-ctl %s: summary received=%llu lost=%llu duplicated=%llu reordered=%llu implausible=%llu events=%llu "
               "markers=%llu latency_ms_p50=%s latency_ms_p99=%s latency_ms_max=%s clock_offset_us=%.1f subscriptions=%llu\n",
               role.c_str(), static_cast<unsigned long long>(s.samples.received),
               static_cast<unsigned long long>(s.samples.lost), static_cast<unsigned long long>(s.samples.duplicated),
               static_cast<unsigned long long>(s.samples.reordered),
               static_cast<unsigned long long>(s.samples.implausible), static_cast<unsigned long long>(s.events.received),
               static_cast<unsigned long long>(s.markers.received),
               ms(s.latency_p50_ns).c_str(), ms(s.latency_p99_ns).c_str(), ms(s.latency_max_ns).c_str(),
               static_cast<double>(s.clock_offset_ns) / 1e3, static_cast<unsigned long long>(s.subscriptions));
  if (!c.stats_json.empty()) {
    nlohmann::json j = {{"client", role},
                        {"received", s.samples.received},
                        {"lost", s.samples.lost},
                        {"duplicated", s.samples.duplicated},
                        {"reordered", s.samples.reordered},
                        {"implausible", s.samples.implausible},
                        {"events", s.events.received},
                        {"latency_p50_ns", s.latency_p50_ns},
                        {"latency_p99_ns", s.latency_p99_ns},
                        {"latency_max_ns", s.latency_max_ns},
                        {"clock_offset_ns", s.clock_offset_ns},
                        {"subscriptions", s.subscriptions},
                        {"markers", s.markers.received},
                        {"provisional", s.provisional.received}};
    std::ofstream(c.stats_json) << j.dump(2) << "\n";
  }
  return 0;
}

int cmd_status(const Common& c) {
  Endpoint server;
  try {
    server = parse_endpoint(c.server, kDefaultPort);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl status: %s\n", e.what());
    return 2;
  }
  const auto s = GazeClient::query_status(server, 1000);
  if (!s) {
    std::fprintf(stderr, "fovea-ctl status: no answer from %s within 1000 ms; is fovea-trackerd running there?\n",
                 server.to_string().c_str());
    return 1;
  }
  static const char* states[] = {"running", "ended", "retrying"};
  std::printf("server      %s\n", server.to_string().c_str());
  std::printf("source      %s (%s)\n", s->source.value.c_str(), states[static_cast<int>(s->source_state)]);
  std::printf("rate        %.1f Hz\n", s->nominal_rate_hz);
  std::printf("display     %s (%.2f px/mm)\n", to_string(s->display).c_str(), pixels_per_mm(s->display));
  std::printf("uptime      %.1f s\n", static_cast<double>(s->uptime_ns) / 1e9);
  std::printf("published   %llu samples, %llu events\n", static_cast<unsigned long long>(s->samples_published),
              static_cast<unsigned long long>(s->events_published));
  std::printf("subscribers %u\n", s->subscribers);
  std::printf("rejected    %llu datagrams\n", static_cast<unsigned long long>(s->datagrams_rejected));
  return 0;
}

int cmd_watch(const Common& c, unsigned every, bool events_only, bool provisional) {
  std::mutex out_mutex;
  std::int64_t t0 = 0;
  std::uint64_t count = 0;
  const auto rel = [&](std::int64_t t) {
    if (t0 == 0) t0 = t;
    return static_cast<double>(t - t0) / 1e9;
  };
  return run_client(
      c, "watch",
      (events_only ? kStreamEvents : kStreamSamples | kStreamEvents | kStreamEyes) | kStreamMarkers |
          (provisional ? kStreamProvisional : 0u),
      [&](GazeClient& client) {
        client.on_sample([&](const GazeSample& s, const Arrival& a) {
          std::lock_guard lock(out_mutex);
          if (count++ % every != 0) return;
          if (s.flags & kGazeValid) {
            // A binocular source's eyes (the per-eye stream): each eye's point in degrees.
            std::string eyes;
            for (const auto& [side, e] : {std::pair{"L", &s.left_gaze}, std::pair{"R", &s.right_gaze}}) {
              if (!e->valid()) continue;
              char buf[48];
              std::snprintf(buf, sizeof buf, " %s(%+6.2f°, %+6.2f°)", side, static_cast<double>(e->x_deg),
                            static_cast<double>(e->y_deg));
              eyes += buf;
            }
            std::printf("%9.3fs #%-7llu %-8s x=%.4f y=%.4f (%+6.2f°, %+6.2f°) %6.1f°/s conf %.2f%s\n",
                        rel(s.tracker_time_ns), static_cast<unsigned long long>(a.sequence), to_string(s.state),
                        static_cast<double>(s.x), static_cast<double>(s.y), static_cast<double>(s.x_deg),
                        static_cast<double>(s.y_deg), static_cast<double>(s.angular_velocity_deg_s),
                        static_cast<double>(s.confidence), eyes.c_str());
          } else {
            // Eye-camera sources without a calibration still publish the pupil: show it.
            std::string pupil;
            for (const auto& [side, e] : {std::pair{"left", &s.left}, std::pair{"right", &s.right}}) {
              if ((e->flags & kEyePupilValid) == 0) continue;
              char buf[128];
              std::snprintf(buf, sizeof buf, " %s pupil (%.1f, %.1f) px", side, static_cast<double>(e->pupil_x_px),
                            static_cast<double>(e->pupil_y_px));
              pupil += buf;
              if (e->flags & kEyeGlintValid) {
                std::snprintf(buf, sizeof buf, ", pupil-glint (%+.2f, %+.2f) px",
                              static_cast<double>(e->pupil_glint_x_px), static_cast<double>(e->pupil_glint_y_px));
                pupil += buf;
              }
            }
            std::printf("%9.3fs #%-7llu %-8s (no gaze)%s\n", rel(s.tracker_time_ns),
                        static_cast<unsigned long long>(a.sequence), to_string(s.state), pupil.c_str());
          }
          std::fflush(stdout);
        });
        client.on_event([&](const GazeEvent& e, const Arrival&) {
          std::lock_guard lock(out_mutex);
          const double t = rel(e.start_time_ns + e.duration_ns);
          const char* what = (e.flags & kEventRetracted) != 0 ? "RETRACTED" : e.provisional() ? "PROVISIONAL" : "EVENT";
          if (e.phase == EventPhase::Start) {
            std::printf("%9.3fs %s %s start at (%.3f, %.3f)\n", t, what, to_string(e.kind),
                        static_cast<double>(e.centroid_x), static_cast<double>(e.centroid_y));
          } else {
            std::printf("%9.3fs %s %s end: %.0f ms, amplitude %.2f°, peak %.0f°/s, centroid (%.3f, %.3f)\n", t,
                        what, to_string(e.kind), static_cast<double>(e.duration_ns) / 1e6,
                        static_cast<double>(e.amplitude_deg), static_cast<double>(e.peak_velocity_deg_s),
                        static_cast<double>(e.centroid_x), static_cast<double>(e.centroid_y));
          }
          std::fflush(stdout);
        });
        client.on_marker([&](const Marker& m, const Arrival&) {
          std::lock_guard lock(out_mutex);
          std::printf("%9.3fs MARKER \"%s\" (%s time)\n", rel(m.time_ns), m.label.value.c_str(),
                      (m.flags & kMarkerClientTime) != 0 ? "sender's" : "daemon's receive");
          std::fflush(stdout);
        });
      },
      [](const Subscribed&) {});
}

// Sends one marker and prints the copy the daemon published (so the marker is known to be on the
// gaze clock, in the daemon's recording if it records, and with its subscribers).
int cmd_mark(const Common& c, const std::string& label, std::optional<std::int64_t> time_ns) {
  ClientOptions co;
  try {
    GazeClient::check_marker_label(label);
    co.server = parse_endpoint(c.server, kDefaultPort);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl mark: %s\n", e.what());
    return 2;
  }
  co.streams = kStreamMarkers;
  co.name = c.name.empty() ? "fovea-ctl mark" : c.name;
  GazeClient client(co);
  client.start();
  if (!client.wait_subscribed(c.connect_timeout_ms)) {
    std::fprintf(stderr, "fovea-ctl mark: no answer from %s within %d ms; is fovea-trackerd running there?\n",
                 co.server.to_string().c_str(), c.connect_timeout_ms);
    return 1;
  }
  // A given time is mapped through the clock offset: wait for the first burst of exchanges (about
  // 200 ms), whose least-delay one bounds the error by half its round trip, or 1 s at most.
  for (int i = 0; time_ns && i < 100 && client.clock_exchanges() < GazeClient::kClockBurst; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  std::uint64_t id = 0;
  try {
    id = client.mark(label, time_ns);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl mark: %s\n", e.what());
    return 2;
  }
  const int wait_ms = GazeClient::kMarkerAttempts * 250 + 500;
  const std::optional<Marker> published = client.wait_marker(id, wait_ms);
  const ClientStats st = client.stats();
  client.stop();
  if (!published) {
    std::fprintf(stderr, "fovea-ctl mark: %s did not confirm the marker within %d ms%s%s\n",
                 co.server.to_string().c_str(), wait_ms, st.last_error ? "; it answered: " : "",
                 st.last_error ? to_string(*st.last_error) : "");
    return 1;
  }
  // The mapped time is as good as the offset: within half the round trip of its exchange.
  char how[96] = "when it arrived";
  if ((published->flags & kMarkerClientTime) != 0)
    std::snprintf(how, sizeof how, "the time given, mapped within +-%.3f ms",
                  static_cast<double>(st.clock_round_trip_ns) / 2e6);
  std::printf("marker \"%s\" at %.9f s on the daemon's clock (%s), received %.9f s\n", published->label.value.c_str(),
              static_cast<double>(published->time_ns) / 1e9, how, static_cast<double>(published->received_ns) / 1e9);
  return 0;
}

int cmd_record(const Common& c, const std::string& path, bool append) {
  std::unique_ptr<RecordingWriter> writer;
  std::mutex writer_mutex;
  std::string failure;
  std::string device = "fovea-trackerd at " + c.server;
  DisplayGeometry header_display;
  int rc = run_client(
      c, "record", kStreamSamples | kStreamEvents | kStreamMarkers | kStreamEyes,
      [&](GazeClient& client) {
        const auto write = [&](Record r) {
          // The client resubscribes on its own (a daemon restart); a daemon restarted with another
          // display must not go on into a file whose header says the old one (issue 23 item 12).
          // Callbacks run on the client's thread after it handled SUBSCRIBED, so session() is this item's.
          const std::optional<Subscribed> session = client.session();
          std::lock_guard lock(writer_mutex);
          if (!writer) return;
          if (session && !(session->display == header_display)) {
            failure = "the daemon's display changed from " + to_string(header_display) + " to " +
                      to_string(session->display) + " (reloaded or restarted with another configuration); the recording ends "
                      "here: record the new display into another file";
            writer.reset();
            stop_requested() = true;
            return;
          }
          try {
            writer->append(r);
          } catch (const std::exception& e) {
            failure = e.what();
            writer.reset();
            stop_requested() = true;
          }
        };
        client.on_sample([write](const GazeSample& s, const Arrival& a) {
          // The daemon's receive time, where it differs from the sample's (RECORDING.md).
          write(Record{a.sequence, s, a.host_receive_ns != s.tracker_time_ns ? std::optional(a.host_receive_ns) : std::nullopt});
        });
        client.on_event([write](const GazeEvent& e, const Arrival& a) { write(Record{a.sequence, e}); });
        client.on_marker([write](const Marker& m, const Arrival& a) { write(Record{a.sequence, m}); });
      },
      [&](const Subscribed& s) {
        RecordingHeader h;
        if (auto st = GazeClient::query_status(parse_endpoint(c.server, kDefaultPort), 500)) device = st->source.value;
        h.device = recording_device_name(device);
        h.display = s.display;
        header_display = s.display;
        h.nominal_rate_hz = s.nominal_rate_hz;
        h.clock = RecordingClock::Monotonic;
        h.created_unix_ns = realtime_ns();
        h.created_clock_ns = monotonic_ns();
        std::lock_guard lock(writer_mutex);
        writer = std::make_unique<RecordingWriter>(
            path, h, append ? RecordingWriter::Mode::Append : RecordingWriter::Mode::CreateNew);
      });
  std::lock_guard lock(writer_mutex);
  if (!failure.empty()) {
    std::fprintf(stderr, "fovea-ctl record: %s\n", failure.c_str());
    return 1;
  }
  if (writer) {
    std::fprintf(stderr, "fovea-ctl record: wrote %llu records to %s\n",
                 static_cast<unsigned long long>(writer->records_written()), path.c_str());
  }
  return rc;
}

// ---- control commands (reload, record-start, record-stop, calibration-load) ------------------------

// Sends one CONTROL_REQUEST and prints the daemon's answer: through the daemon's control socket
// (--control-socket, or its default on this host for a loopback --server), else over UDP, where the
// request is retransmitted unchanged after 1 s without a reply (the daemon answers a retransmission
// without executing it twice). Exit status: 0 ok, 1 refused, failed or no answer, 2 bad arguments.
int cmd_control(const Common& c, ControlCommand command, const std::string& argument) {
  const std::string role = to_string(command);
  Endpoint server;
  ControlRequest request{command, {}};
  try {
    server = parse_endpoint(c.server, kDefaultPort);
    request.argument.value = argument;
    Message m{Header{}, request};
    (void)encode(m);  // the argument must fit (at most 63 bytes)
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl %s: %s\n", role.c_str(), e.what());
    return 2;
  }
  std::string error, via;
  const std::optional<ControlReply> reply = send_control_to_daemon(server, c.control_socket, request, 4000, error, via);
  if (!reply) {
    // No socket was found (or named) for a daemon on this host, or the server is elsewhere: UDP was tried.
    std::fprintf(stderr, "fovea-ctl %s: %s; %s\n", role.c_str(), error.c_str(),
                 via.rfind("UDP", 0) == 0
                     ? "is fovea-trackerd running there? (it takes control commands only through its control "
                       "socket: run fovea-ctl on its host, as a member of its group)"
                     : "is fovea-trackerd running on this host?");
    return 1;
  }
  std::fprintf(reply->result == ControlResult::Ok ? stdout : stderr, "fovea-ctl %s: %s: %s\n", role.c_str(),
               to_string(reply->result), reply->message.value.c_str());
  return reply->result == ControlResult::Ok ? 0 : 1;
}

CLI::App* add_mark_command(CLI::App& app, std::string& label, std::optional<std::int64_t>& time_ns) {
  auto* mark = app.add_subcommand(
      "mark", "put an experiment marker (stimulus onset, trial start, ...) on the gaze clock: into the daemon's "
              "recording and to its subscribers");
  mark->add_option("LABEL", label, "1..63 bytes of UTF-8 text, no control characters")->required();
  mark->add_option("--time-ns", time_ns,
                   "when it happened, in ns of this host's CLOCK_MONOTONIC (mapped to the daemon's clock through the "
                   "least-delay one of the first 4 TIME_SYNC exchanges; the reply says within how much); default: "
                   "when the daemon receives it");
  return mark;
}

}  // namespace

std::vector<Command> add_daemon_commands(CLI::App& app) {
  struct Options {
    Common c;
    unsigned every = 1;
    bool events_only = false;
    bool provisional = false;
    std::string record_path;
    bool append = false;
    std::string control_record_path;
    std::string calibration_file;
    std::string mark_label;
    std::optional<std::int64_t> mark_time_ns;
  };
  auto o = std::make_shared<Options>();
  auto& [c, every, events_only, provisional, record_path, append, control_record_path, calibration_file, mark_label, mark_time_ns] = *o;
  app.add_option("--server", c.server, "fovea-trackerd address HOST:PORT")->capture_default_str();
  app.add_option("--control-socket", c.control_socket,
                 "control commands through this socket (default: the daemon's own on this host, found by the "
                 "--server port: /run/fovea/control-PORT.sock, $XDG_RUNTIME_DIR/fovea/..., /tmp/fovea-UID/...)");

  auto* status = app.add_subcommand("status", "print the daemon's source, rate, display and counters");

  auto* watch = app.add_subcommand("watch", "print live gaze samples and events");
  watch->add_option("--duration", c.duration_s, "stop after S seconds (default: until Ctrl-C)");
  watch->add_option("--every", every, "print every Nth sample (events are always printed)")
      ->check(CLI::Range(1u, 1000000u))
      ->capture_default_str();
  watch->add_flag("--events-only", events_only, "subscribe to events only");
  watch->add_flag("--provisional", provisional,
                  "also subscribe to provisional events (saccade start/end, fixation start as soon as the newest "
                  "samples show them, before the final labels), printed PROVISIONAL, and their retractions");
  watch->add_option("--multicast", c.multicast, "receive samples from multicast GROUP:PORT instead of unicast");
  watch->add_option("--stats-json", c.stats_json, "write the final statistics to this JSON file");

  auto* record = app.add_subcommand("record", "record the live stream to a .fgr file");
  record->add_option("FILE", record_path, "output .fgr file (refuses to overwrite)")->required();
  record->add_option("--duration", c.duration_s, "stop after S seconds (default: until Ctrl-C)");
  record->add_flag("--append", append, "append to an existing recording of the same display");
  record->add_option("--multicast", c.multicast, "receive samples from multicast GROUP:PORT instead of unicast");
  record->add_option("--stats-json", c.stats_json, "write the final statistics to this JSON file");

  auto* mark = add_mark_command(app, mark_label, mark_time_ns);

  auto* reload = app.add_subcommand(
      "reload", "make the daemon reload its configuration and calibration (as SIGHUP; subscribers stay connected)");
  auto* record_start =
      app.add_subcommand("record-start", "make the daemon record what it publishes to PATH on its machine");
  record_start->add_option("PATH", control_record_path,
                           "new .fgr file, at most 63 bytes, inside the daemon's [network] control_dir (its "
                           "working directory by default: /var/lib/fovea for the service); relative to it")
      ->required();
  auto* record_stop = app.add_subcommand("record-stop", "make the daemon stop the recording it is writing");
  auto* calibration_load = app.add_subcommand(
      "calibration-load",
      "make the daemon load a calibration file now (kept over reloads), 'none' (the source's own gaze) or "
      "'configured' (back to its configuration's [calibration] file); subscribers stay connected");
  calibration_load->add_option("FILE", calibration_file,
                               "calibration file (fovea-calibrate), read by the daemon on its machine from its "
                               "calibrations directory ([network] calibration_dir, else control_dir); its absolute "
                               "path must fit in 63 bytes")
      ->required();

  return {
      {status, [o] { return cmd_status(o->c); }},
      {watch, [o] { return cmd_watch(o->c, o->every, o->events_only, o->provisional); }},
      {record, [o] { return cmd_record(o->c, o->record_path, o->append); }},
      {mark, [o] { return cmd_mark(o->c, o->mark_label, o->mark_time_ns); }},
      {reload, [o] { return cmd_control(o->c, ControlCommand::Reload, ""); }},
      {record_start, [o] { return cmd_control(o->c, ControlCommand::StartRecording, o->control_record_path); }},
      {record_stop, [o] { return cmd_control(o->c, ControlCommand::StopRecording, ""); }},
      {calibration_load,
       [o] {
         // A file is named to the daemon by its absolute path (the daemon may run elsewhere in the tree).
         std::string arg = o->calibration_file;
         if (arg != "none" && arg != "configured") arg = std::filesystem::absolute(arg).lexically_normal().string();
         return cmd_control(o->c, ControlCommand::LoadCalibration, arg);
       }},
  };
}

}  // namespace fovea::ctl
