// fovea-ctl: the command-line client of fovea-trackerd (status, watch, record) and recording tools.
#include <CLI/CLI.hpp>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>
#include <unistd.h>

#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/csv.h"
#include "fovea/protocol/recording.h"

namespace {

using namespace fovea::protocol;

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop.store(true); }

struct Common {
  std::string server = "127.0.0.1:47800";
  std::string name;
  std::string stats_json;
  double duration_s = 0;
  std::string multicast;
  int connect_timeout_ms = 5000;
};

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

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
    std::fprintf(stderr, "fovea-ctl %s: no answer from %s within %d ms; is fovea-trackerd running there?\n",
                 role.c_str(), co.server.to_string().c_str(), c.connect_timeout_ms);
    return 1;
  }
  try {
    on_subscribed(*client->session());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl %s: %s\n", role.c_str(), e.what());
    return 2;
  }
  const std::int64_t end = c.duration_s > 0 ? monotonic_ns() + static_cast<std::int64_t>(c.duration_s * 1e9) : INT64_MAX;
  while (!g_stop.load() && monotonic_ns() < end) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  client->stop();

  const ClientStats s = client->stats();
  std::fprintf(stderr,
               "fovea-ctl %s: summary received=%llu lost=%llu duplicated=%llu reordered=%llu events=%llu "
               "latency_ms_p50=%s latency_ms_p99=%s latency_ms_max=%s clock_offset_us=%.1f subscriptions=%llu\n",
               role.c_str(), static_cast<unsigned long long>(s.samples.received),
               static_cast<unsigned long long>(s.samples.lost), static_cast<unsigned long long>(s.samples.duplicated),
               static_cast<unsigned long long>(s.samples.reordered), static_cast<unsigned long long>(s.events.received),
               ms(s.latency_p50_ns).c_str(), ms(s.latency_p99_ns).c_str(), ms(s.latency_max_ns).c_str(),
               static_cast<double>(s.clock_offset_ns) / 1e3, static_cast<unsigned long long>(s.subscriptions));
  if (!c.stats_json.empty()) {
    nlohmann::json j = {{"client", role},
                        {"received", s.samples.received},
                        {"lost", s.samples.lost},
                        {"duplicated", s.samples.duplicated},
                        {"reordered", s.samples.reordered},
                        {"events", s.events.received},
                        {"latency_p50_ns", s.latency_p50_ns},
                        {"latency_p99_ns", s.latency_p99_ns},
                        {"latency_max_ns", s.latency_max_ns},
                        {"clock_offset_ns", s.clock_offset_ns},
                        {"subscriptions", s.subscriptions}};
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

int cmd_watch(const Common& c, unsigned every, bool events_only) {
  std::mutex out_mutex;
  std::int64_t t0 = 0;
  std::uint64_t count = 0;
  const auto rel = [&](std::int64_t t) {
    if (t0 == 0) t0 = t;
    return static_cast<double>(t - t0) / 1e9;
  };
  return run_client(
      c, "watch", events_only ? kStreamEvents : kStreamSamples | kStreamEvents,
      [&](GazeClient& client) {
        client.on_sample([&](const GazeSample& s, const Arrival& a) {
          std::lock_guard lock(out_mutex);
          if (count++ % every != 0) return;
          if (s.flags & kGazeValid) {
            std::printf("%9.3fs #%-7llu %-8s x=%.4f y=%.4f (%+6.2f°, %+6.2f°) %6.1f°/s conf %.2f\n",
                        rel(s.tracker_time_ns), static_cast<unsigned long long>(a.sequence), to_string(s.state),
                        static_cast<double>(s.x), static_cast<double>(s.y), static_cast<double>(s.x_deg),
                        static_cast<double>(s.y_deg), static_cast<double>(s.angular_velocity_deg_s),
                        static_cast<double>(s.confidence));
          } else {
            std::printf("%9.3fs #%-7llu %-8s (no gaze)\n", rel(s.tracker_time_ns),
                        static_cast<unsigned long long>(a.sequence), to_string(s.state));
          }
          std::fflush(stdout);
        });
        client.on_event([&](const GazeEvent& e, const Arrival&) {
          std::lock_guard lock(out_mutex);
          const double t = rel(e.start_time_ns + e.duration_ns);
          if (e.phase == EventPhase::Start) {
            std::printf("%9.3fs EVENT %s start at (%.3f, %.3f)\n", t, to_string(e.kind),
                        static_cast<double>(e.centroid_x), static_cast<double>(e.centroid_y));
          } else {
            std::printf("%9.3fs EVENT %s end: %.0f ms, amplitude %.2f°, peak %.0f°/s, centroid (%.3f, %.3f)\n", t,
                        to_string(e.kind), static_cast<double>(e.duration_ns) / 1e6,
                        static_cast<double>(e.amplitude_deg), static_cast<double>(e.peak_velocity_deg_s),
                        static_cast<double>(e.centroid_x), static_cast<double>(e.centroid_y));
          }
          std::fflush(stdout);
        });
      },
      [](const Subscribed&) {});
}

int cmd_record(const Common& c, const std::string& path, bool append) {
  std::unique_ptr<RecordingWriter> writer;
  std::mutex writer_mutex;
  std::string failure;
  std::string device = "fovea-trackerd at " + c.server;
  int rc = run_client(
      c, "record", kStreamSamples | kStreamEvents,
      [&](GazeClient& client) {
        const auto write = [&](Record r) {
          std::lock_guard lock(writer_mutex);
          if (!writer) return;
          try {
            writer->append(r);
          } catch (const std::exception& e) {
            failure = e.what();
            writer.reset();
            g_stop = true;
          }
        };
        client.on_sample([write](const GazeSample& s, const Arrival& a) { write(Record{a.sequence, s}); });
        client.on_event([write](const GazeEvent& e, const Arrival& a) { write(Record{a.sequence, e}); });
      },
      [&](const Subscribed& s) {
        RecordingHeader h;
        if (auto st = GazeClient::query_status(parse_endpoint(c.server, kDefaultPort), 500)) device = st->source.value;
        h.device = device.substr(0, 63);
        h.display = s.display;
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

Recording load_any(const std::string& path) {
  if (ends_with(path, ".csv")) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error("cannot open " + path);
    return read_csv(in, path);
  }
  return read_recording(path);
}

int cmd_convert(const std::string& in_path, const std::string& out_path, bool force) {
  // A name of our own next to OUT, so rename() is atomic and nobody else's file is touched.
  const std::string tmp = out_path + ".partial-" + std::to_string(getpid());
  try {
    if (!force && std::filesystem::exists(out_path)) {
      throw std::runtime_error(out_path + " already exists (use --force to replace it)");
    }
    const Recording rec = load_any(in_path);
    std::fprintf(stderr, "fovea-ctl convert: %s: %s\n", in_path.c_str(), rec.report.describe().c_str());
    if (ends_with(out_path, ".csv")) {
      std::ofstream out(tmp);
      const std::size_t events = write_csv(out, rec);
      out.close();
      if (!out) throw std::runtime_error("cannot write " + tmp);
      if (events > 0) std::fprintf(stderr, "fovea-ctl convert: %zu events left out (CSV holds samples only)\n", events);
    } else if (ends_with(out_path, ".fgr")) {
      RecordingWriter w(tmp, rec.header);
      for (const Record& r : rec.records) w.append(r);
      w.sync();
    } else {
      throw std::runtime_error("output " + out_path + ": unknown format (use .fgr or .csv)");
    }
    // Replace atomically so an interrupted conversion never leaves a half-written output.
    std::filesystem::rename(tmp, out_path);
    std::fprintf(stderr, "fovea-ctl convert: wrote %s\n", out_path.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    std::fprintf(stderr, "fovea-ctl convert: %s\n", e.what());
    return 1;
  }
}

int cmd_info(const std::string& path) {
  try {
    const Recording rec = load_any(path);
    std::size_t samples = 0, valid = 0;
    std::map<std::string, std::size_t> ends;
    std::int64_t first = INT64_MAX, last = INT64_MIN;
    for (const Record& r : rec.records) {
      if (const auto* s = std::get_if<GazeSample>(&r.item)) {
        first = std::min(first, s->tracker_time_ns);  // the span of samples: events may end later
        last = std::max(last, s->tracker_time_ns);
        ++samples;
        if (s->flags & kGazeValid) ++valid;
      } else if (const auto& e = std::get<GazeEvent>(r.item); e.phase == EventPhase::End) {
        ++ends[to_string(e.kind)];
      }
    }
    std::printf("file        %s\n", path.c_str());
    std::printf("device      %s\n", rec.header.device.c_str());
    std::printf("display     %s\n", to_string(rec.header.display).c_str());
    std::printf("rate        %.1f Hz (nominal)\n", rec.header.nominal_rate_hz);
    const double span = samples > 1 ? static_cast<double>(last - first) / 1e9 : 0;
    std::printf("span        %.3f s\n", span);
    std::printf("samples     %zu (%zu with valid gaze)", samples, valid);
    if (span > 0) std::printf(", %.1f Hz measured", static_cast<double>(samples - 1) / span);
    std::printf("\n");
    std::printf("events     ");
    for (const auto& [k, n] : ends) std::printf(" %zu %s", n, k.c_str());
    std::printf("\nintegrity   %s\n", rec.report.describe().c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl info: %s\n", e.what());
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"fovea-ctl: talk to fovea-trackerd and work with gaze recordings (.fgr, .csv)"};
  app.set_version_flag("--version", "fovea-ctl 0.1.0");
  app.require_subcommand(1);
  app.fallthrough();  // --server may also follow the subcommand
  Common c;
  app.add_option("--server", c.server, "fovea-trackerd address HOST:PORT")->capture_default_str();

  auto* status = app.add_subcommand("status", "print the daemon's source, rate, display and counters");

  unsigned every = 1;
  bool events_only = false;
  auto* watch = app.add_subcommand("watch", "print live gaze samples and events");
  watch->add_option("--duration", c.duration_s, "stop after S seconds (default: until Ctrl-C)");
  watch->add_option("--every", every, "print every Nth sample (events are always printed)")
      ->check(CLI::Range(1u, 1000000u))
      ->capture_default_str();
  watch->add_flag("--events-only", events_only, "subscribe to events only");
  watch->add_option("--multicast", c.multicast, "receive samples from multicast GROUP:PORT instead of unicast");
  watch->add_option("--stats-json", c.stats_json, "write the final statistics to this JSON file");

  std::string record_path;
  bool append = false;
  auto* record = app.add_subcommand("record", "record the live stream to a .fgr file");
  record->add_option("FILE", record_path, "output .fgr file (refuses to overwrite)")->required();
  record->add_option("--duration", c.duration_s, "stop after S seconds (default: until Ctrl-C)");
  record->add_flag("--append", append, "append to an existing recording of the same display");
  record->add_option("--multicast", c.multicast, "receive samples from multicast GROUP:PORT instead of unicast");
  record->add_option("--stats-json", c.stats_json, "write the final statistics to this JSON file");

  std::string in_path, out_path;
  bool force = false;
  auto* convert = app.add_subcommand("convert", "convert between .fgr and .csv (also repairs damaged .fgr files)");
  convert->add_option("IN", in_path, "input .fgr or .csv")->required()->check(CLI::ExistingFile);
  convert->add_option("OUT", out_path, "output .fgr or .csv")->required();
  convert->add_flag("--force", force, "replace OUT if it exists");

  std::string info_path;
  auto* info = app.add_subcommand("info", "describe a recording: display, rate, span, events, integrity");
  info->add_option("FILE", info_path, ".fgr or .csv file")->required()->check(CLI::ExistingFile);

  CLI11_PARSE(app, argc, argv);

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);

  if (status->parsed()) return cmd_status(c);
  if (watch->parsed()) return cmd_watch(c, every, events_only);
  if (record->parsed()) return cmd_record(c, record_path, append);
  if (convert->parsed()) return cmd_convert(in_path, out_path, force);
  if (info->parsed()) return cmd_info(info_path);
  return 2;
}
