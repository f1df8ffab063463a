// fovea-ctl: the command-line client of fovea-trackerd (status, watch, record), recording tools and
// eye-image tools (detect-pupil, synth-eye).
#include <CLI/CLI.hpp>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <nlohmann/json.hpp>
#include <thread>
#include <unistd.h>

#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/csv.h"
#include "fovea/protocol/recording.h"
#include "classify/classifier.h"
#include "sim/calibration_viewer.h"
#include "eye/eye_detector.h"
#include "sim/synthetic_eye.h"
#include "sim/synthetic_eye_frames.h"

#include <opencv2/imgcodecs.hpp>
#include <spdlog/spdlog.h>

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

// ---- control commands (reload, record-start, record-stop, calibration-load) ------------------------

// Sends one CONTROL_REQUEST and prints the daemon's answer. The request is retransmitted unchanged
// (same sequence) after 1 s without a reply; the daemon answers a retransmission without executing
// it twice. Exit status: 0 ok, 1 refused, failed or no answer, 2 bad arguments.
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
  const std::optional<ControlReply> reply = GazeClient::send_control(server, request, 4000);
  if (!reply) {
    std::fprintf(stderr,
                 "fovea-ctl %s: no answer from %s within 4000 ms; is fovea-trackerd (with control support) "
                 "running there?\n",
                 role.c_str(), server.to_string().c_str());
    return 1;
  }
  std::fprintf(reply->result == ControlResult::Ok ? stdout : stderr, "fovea-ctl %s: %s: %s\n", role.c_str(),
               to_string(reply->result), reply->message.value.c_str());
  return reply->result == ControlResult::Ok ? 0 : 1;
}

// --- classify: offline eye-movement classification of a CSV of gaze points (trackerd/CLASSIFY.md) ---

// Parses a decimal number field of the classify input; `nan_ok` accepts "nan" (any case) as NaN.
double classify_field(const std::string& text, const char* name, bool nan_ok, const std::string& where) {
  std::string t = text;
  while (!t.empty() && (t.back() == ' ' || t.back() == '\t')) t.pop_back();
  std::size_t b = 0;
  while (b < t.size() && (t[b] == ' ' || t[b] == '\t')) ++b;
  t = t.substr(b);
  std::string lower;
  for (char ch : t) lower += (ch >= 'A' && ch <= 'Z') ? static_cast<char>(ch - 'A' + 'a') : ch;
  if (nan_ok && (lower == "nan" || lower == "-nan" || lower == "+nan")) return std::nan("");
  double v = 0;
  std::size_t used = 0;
  try {
    v = std::stod(t, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (t.empty() || used != t.size() || !std::isfinite(v)) {
    throw std::runtime_error(where + ": " + name + " \"" + text + "\" is not a finite number" +
                             (nan_ok ? " or nan" : ""));
  }
  return v;
}

int cmd_classify(const std::string& in_path, const std::string& out_path, double rate_hz, std::uint32_t w_px,
                 std::uint32_t h_px, double w_mm, double h_mm, double dist_mm, const std::string& method, bool force) {
  namespace cl = fovea::trackerd::classify;
  const std::string tmp = out_path + ".partial-" + std::to_string(getpid());
  try {
    if (!force && std::filesystem::exists(out_path)) {
      throw std::runtime_error(out_path + " already exists (use --force to replace it)");
    }
    if (!std::isfinite(rate_hz) || rate_hz <= 0 || rate_hz > 100000) {
      throw std::runtime_error("RATE_HZ " + std::to_string(rate_hz) + " is out of range (0, 100000]");
    }
    DisplayGeometry g;
    g.width_px = w_px;
    g.height_px = h_px;
    g.width_m = w_mm / 1000.0;
    g.height_m = h_mm / 1000.0;
    g.viewing_distance_m = dist_mm / 1000.0;
    if (const std::string err = validate(g); !err.empty()) throw std::runtime_error("screen geometry: " + err);

    std::ifstream in(in_path);
    if (!in) throw std::runtime_error("cannot open " + in_path);
    std::vector<cl::Sample> samples;
    std::vector<std::string> times;  // t_ms exactly as written, echoed to OUT
    std::string line;
    std::size_t line_no = 0;
    double last_t = 0;
    while (std::getline(in, line)) {
      ++line_no;
      if (!line.empty() && line.back() == '\r') line.pop_back();
      const std::string where = in_path + ":" + std::to_string(line_no);
      if (line_no == 1) {
        if (line.size() >= 3 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);  // UTF-8 BOM
        if (line != "t_ms,x_px,y_px") {
          throw std::runtime_error(where + ": header is \"" + line + "\", expected \"t_ms,x_px,y_px\"");
        }
        continue;
      }
      if (line.empty()) throw std::runtime_error(where + ": empty line (expected t_ms,x_px,y_px)");
      std::vector<std::string> f;
      std::size_t start = 0;
      for (std::size_t comma; (comma = line.find(',', start)) != std::string::npos; start = comma + 1) {
        f.push_back(line.substr(start, comma - start));
      }
      f.push_back(line.substr(start));
      if (f.size() != 3) {
        throw std::runtime_error(where + ": " + std::to_string(f.size()) + " fields, expected 3 (t_ms,x_px,y_px)");
      }
      const double t_ms = classify_field(f[0], "t_ms", false, where);
      const double x_px = classify_field(f[1], "x_px", true, where);
      const double y_px = classify_field(f[2], "y_px", true, where);
      if (!samples.empty() && !(t_ms > last_t)) {
        throw std::runtime_error(where + ": t_ms " + f[0] + " is not after the previous row's " + times.back() +
                                 " (times must strictly increase)");
      }
      last_t = t_ms;
      cl::Sample s;
      s.t_s = t_ms / 1000.0;
      s.valid = std::isfinite(x_px) && std::isfinite(y_px);
      if (s.valid) {
        // Pixels (origin top-left) to normalized, then to degrees from the centre: atan(offset / d).
        const Degrees d = normalized_to_degrees(
            g, Normalized{x_px / static_cast<double>(w_px), y_px / static_cast<double>(h_px)});
        s.x_deg = d.x;
        s.y_deg = d.y;
      }
      samples.push_back(s);
      times.push_back(f[0]);
    }
    if (in.bad()) throw std::runtime_error("error reading " + in_path);
    if (line_no == 0) throw std::runtime_error(in_path + ": empty file (expected the header t_ms,x_px,y_px)");

    cl::ClassifierOptions options;
    options.nominal_rate_hz = rate_hz;
    options.display = g;
    const std::vector<cl::Label> labels = cl::classify_all(method, options, samples);

    std::map<std::string, std::size_t> counts;
    {
      std::ofstream out(tmp);
      if (!out) throw std::runtime_error("cannot create " + tmp);
      out << "t_ms,label\n";
      for (std::size_t i = 0; i < samples.size(); ++i) {
        out << times[i] << ',' << cl::to_string(labels[i]) << '\n';
        ++counts[cl::to_string(labels[i])];
      }
      out.close();
      if (!out) throw std::runtime_error("cannot write " + tmp);
    }
    std::filesystem::rename(tmp, out_path);  // atomic: OUT is either absent/old or complete
    std::fprintf(stderr, "fovea-ctl classify: %zu samples, method %s (online latency %.0f ms):", samples.size(),
                 method.c_str(), cl::make_classifier(method, options)->latency_s() * 1000);
    for (const auto& [k, n] : counts) std::fprintf(stderr, " %zu %s", n, k.c_str());
    std::fprintf(stderr, "\nfovea-ctl classify: wrote %s\n", out_path.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    std::fprintf(stderr, "fovea-ctl classify: %s\n", e.what());
    return 1;
  }
}

// --- eye images: detect-pupil and synth-eye (trackerd/eye/) ---

namespace eye = fovea::trackerd::eye;

// A CSV field: quoted when it holds a comma, a quote or a line break (RFC 4180).
std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string out = "\"";
  for (const char ch : text) {
    if (ch == '"') out += '"';
    out += ch;
  }
  return out + "\"";
}

std::string fixed3(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.3f", std::isfinite(v) ? v : 0.0);
  return buf;
}

std::string glint_list(const std::vector<cv::Point2d>& points) {
  std::string out;
  for (const auto& p : points) out += (out.empty() ? "" : ";") + fixed3(p.x) + ":" + fixed3(p.y);
  return out;
}

// Writes `text` to `path` through a temporary file beside it (never a half-written file), refusing
// to replace an existing one unless `force`.
void write_new_file(const std::string& path, const std::string& text, bool force) {
  if (!force && std::filesystem::exists(path)) {
    throw std::runtime_error(path + " already exists (use --force to replace it)");
  }
  const std::string tmp = path + ".partial-" + std::to_string(getpid());
  {
    std::ofstream out(tmp);
    out << text;
    out.close();
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw std::runtime_error("cannot write " + path);
    }
  }
  std::filesystem::rename(tmp, path);
}

int cmd_detect_pupil(const std::vector<std::string>& images, const std::string& out_path, bool force,
                     const std::string& leds, int downscale, bool track) {
  eye::DetectorSettings settings;
  try {
    if (!leds.empty()) settings.leds = eye::LedLayout::parse(leds);
    settings.coarse_downscale = downscale;
    settings.roi_tracking = track;
    settings.validate();
    if (!out_path.empty() && !force && std::filesystem::exists(out_path)) {
      throw std::runtime_error(out_path + " already exists (use --force to replace it)");
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl detect-pupil: %s\n", e.what());
    return 2;
  }
  eye::EyeDetector detector(settings);
  const std::string header = "file,pupil_x,pupil_y,major,minor,angle_deg,confidence,glint_count,glints\n";
  std::string csv = header;
  std::fputs(header.c_str(), stdout);
  int status = 0;
  for (const std::string& file : images) {
    std::error_code ec;
    const auto st = std::filesystem::status(file, ec);
    cv::Mat image;
    std::string why;
    if (!std::filesystem::exists(st)) {
      why = "no such file";
    } else if (std::filesystem::is_directory(st)) {
      why = "is a directory";
    } else {
      try {
        image = cv::imread(file, cv::IMREAD_UNCHANGED);
      } catch (const cv::Exception&) {
        image.release();
      }
      if (image.empty()) why = "cannot be read as an image (unreadable, or a format OpenCV cannot decode)";
    }
    if (!why.empty()) {
      std::fprintf(stderr, "fovea-ctl detect-pupil: %s: %s\n", file.c_str(), why.c_str());
      status = 1;
      continue;
    }
    if (!track) detector.reset();
    const eye::EyeMeasurement m = detector.detect(image);
    std::string row = csv_field(file) + ",";
    if (m.pupil_found) {
      row += fixed3(m.pupil.centre.x) + "," + fixed3(m.pupil.centre.y) + "," + fixed3(m.pupil.major) + "," +
             fixed3(m.pupil.minor) + "," + fixed3(m.pupil.angle_deg) + ",";
    } else {
      row += ",,,,,";
    }
    std::vector<cv::Point2d> glints;
    for (const auto& g : m.glints) glints.push_back(g.centre);
    row += fixed3(m.confidence) + "," + std::to_string(glints.size()) + "," + glint_list(glints) + "\n";
    std::fputs(row.c_str(), stdout);
    csv += row;
  }
  std::fflush(stdout);
  if (!out_path.empty()) {
    try {
      write_new_file(out_path, csv, force);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "fovea-ctl detect-pupil: %s\n", e.what());
      return 1;
    }
  }
  return status;
}

int cmd_synth_eye(const std::string& dir, int count, const std::string& size, bool hard, std::uint64_t seed,
                  const std::string& leds) {
  try {
    unsigned w = 0, h = 0;
    char tail = 0;
    if (std::sscanf(size.c_str(), "%ux%u%c", &w, &h, &tail) != 2 || w < 32 || h < 32 || w > 4096 || h > 4096) {
      throw std::runtime_error("--size \"" + size + "\": expected WxH, each 32..4096 (e.g. 320x240)");
    }
    if (count < 1 || count > 100000) {
      throw std::runtime_error("--count " + std::to_string(count) + " is outside 1..100000");
    }
    std::error_code ec;
    if (std::filesystem::exists(dir, ec)) {
      if (!std::filesystem::is_directory(dir, ec)) throw std::runtime_error(dir + " exists and is not a directory");
      if (!std::filesystem::is_empty(dir, ec)) {
        throw std::runtime_error(dir + " is not empty (synth-eye writes only into a new or empty directory)");
      }
    } else if (!std::filesystem::create_directories(dir, ec)) {
      throw std::runtime_error("cannot create " + dir + ": " + ec.message());
    }
    eye::SyntheticEyeOptions o;
    o.width = static_cast<int>(w);
    o.height = static_cast<int>(h);
    o.seed = seed;
    o.leds = eye::LedLayout::parse(leds);
    if (hard) o = eye::with_hard_conditions(o);
    eye::SyntheticEye generator(o);
    std::mt19937_64 rng(seed ^ 0x5eed5eedULL);  // the gazes; the generator draws its noise from its own
    std::uniform_real_distribution<double> angle(-20.0, 20.0);
    std::string csv =
        "file,pupil_x,pupil_y,major,minor,angle_deg,closed,glint_count,glints,pupil_glint_x,pupil_glint_y\n";
    for (int i = 0; i < count; ++i) {
      const double yaw = angle(rng), pitch = angle(rng);
      eye::EyeTruth t;
      const cv::Mat image = generator.render(yaw, pitch, 1.0, &t);
      char name[32];
      std::snprintf(name, sizeof name, "eye_%04d.png", i);
      const std::string path = (std::filesystem::path(dir) / name).string();
      if (!cv::imwrite(path, image)) throw std::runtime_error("cannot write " + path);
      csv += std::string(name) + ",";
      if (t.closed) {
        csv += ",,,,,1,";
      } else {
        csv += fixed3(t.pupil.centre.x) + "," + fixed3(t.pupil.centre.y) + "," + fixed3(t.pupil.major) + "," +
               fixed3(t.pupil.minor) + "," + fixed3(t.pupil.angle_deg) + ",0,";
      }
      csv += std::to_string(t.glints.size()) + "," + glint_list(t.glints) + ",";
      csv += t.closed ? std::string(",") : fixed3(t.pupil_glint.x) + "," + fixed3(t.pupil_glint.y);
      csv += "\n";
    }
    write_new_file((std::filesystem::path(dir) / "truth.csv").string(), csv, false);
    std::fprintf(stderr, "fovea-ctl synth-eye: wrote %d image(s) %ux%u%s and truth.csv to %s\n", count, w, h,
                 hard ? " (hard conditions)" : "", dir.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl synth-eye: %s\n", e.what());
    return 1;
  }
}

// --- synth-calibration: a recorded calibration session of the synthetic viewer ---

int cmd_synth_calibration(const std::string& out, int points, int validation_points, std::uint64_t seed, bool hard,
                          const std::string& head_offset, const std::string& display_text, const std::string& size) {
  try {
    unsigned w = 0, h = 0;
    char tail = 0;
    if (std::sscanf(size.c_str(), "%ux%u%c", &w, &h, &tail) != 2 || w < 32 || h < 32 || w > 4096 || h > 4096) {
      throw std::runtime_error("--eye-size \"" + size + "\": expected WxH, each 32..4096 (e.g. 320x240)");
    }
    eye::CalibrationSessionOptions o;
    try {
      o.head_offset_mm = eye::parse_head_offset(head_offset);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(std::string("--head-offset: ") + e.what());
    }
    if (!display_text.empty()) {
      try {
        o.display = parse_display_geometry(display_text);
      } catch (const std::invalid_argument& e) {
        throw std::runtime_error(std::string("--display: ") + e.what());
      }
    }
    o.schedule.points = points;
    o.schedule.validation_points = validation_points;
    o.schedule.seed = seed;
    try {
      o.schedule.check();
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(std::string("--points/--validation-points: ") + e.what());
    }
    o.eye.width = static_cast<int>(w);
    o.eye.height = static_cast<int>(h);
    o.eye.seed = seed;
    if (hard) o.eye = eye::with_hard_conditions(o.eye);
    // SESSION.fgr and SESSION.targets.csv: both new, or neither is written.
    const std::string base = ends_with(out, ".fgr") ? out.substr(0, out.size() - 4) : out;
    const std::string fgr = base + ".fgr", targets = base + ".targets.csv";
    std::error_code ec;
    for (const std::string& p : {fgr, targets}) {
      if (std::filesystem::exists(p, ec) || std::filesystem::is_symlink(p, ec)) {
        throw std::runtime_error(p + " already exists (synth-calibration never overwrites; it writes " + fgr +
                                 " and " + targets + " together)");
      }
    }
    spdlog::set_level(spdlog::level::warn);  // the pipeline's start-up lines: not this tool's one-line summary
    o.start_time_ns = monotonic_ns();  // frame 0 on this machine's monotonic clock, as the daemon records
    const std::int64_t created_unix = realtime_ns();
    const eye::CalibrationSession session = eye::simulate_calibration_session(o);

    RecordingHeader header;
    header.device = ("synthetic-eye calibration seed " + std::to_string(seed)).substr(0, 63);
    header.display = o.display;
    header.nominal_rate_hz = o.rate_hz;
    header.clock = RecordingClock::Monotonic;
    header.created_unix_ns = created_unix;
    header.created_clock_ns = o.start_time_ns;
    try {
      RecordingWriter writer(fgr, header, RecordingWriter::Mode::CreateNew);
      std::uint64_t sequence = 0;
      for (const auto& item : session.published) {
        std::visit([&](const auto& v) { writer.append(Record{sequence++, v}); }, item);
      }
      writer.sync();
    } catch (...) {
      std::filesystem::remove(fgr, ec);
      throw;
    }
    try {
      fovea::calib::write_target_windows(targets, session.targets);
    } catch (...) {
      std::filesystem::remove(fgr, ec);
      throw;
    }
    std::size_t calibrate = 0;
    for (const auto& t : session.targets) calibrate += t.phase == fovea::calib::TargetPhase::Calibrate ? 1 : 0;
    std::printf("synth-calibration: %s (%zu samples, %zu events, %.1f s at %.0f Hz, eye %ux%u%s, seed %llu, head "
                "offset %g,%g,%g mm) and %s (%zu calibration + %zu validation targets)\n",
                fgr.c_str(), session.samples.size(), session.events.size(), session.session_s, o.rate_hz, w, h,
                hard ? " hard" : "", static_cast<unsigned long long>(seed), o.head_offset_mm.x, o.head_offset_mm.y,
                o.head_offset_mm.z, targets.c_str(), calibrate, session.targets.size() - calibrate);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl synth-calibration: %s\n", e.what());
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

  auto* reload = app.add_subcommand(
      "reload", "make the daemon reload its configuration and calibration (as SIGHUP; subscribers stay connected)");
  std::string control_record_path;
  auto* record_start =
      app.add_subcommand("record-start", "make the daemon record what it publishes to PATH on its machine");
  record_start->add_option("PATH", control_record_path,
                           "new .fgr file, at most 63 bytes; relative to the daemon's working directory "
                           "(/var/lib/fovea for the service)")
      ->required();
  auto* record_stop = app.add_subcommand("record-stop", "make the daemon stop the recording it is writing");
  std::string calibration_file;
  auto* calibration_load = app.add_subcommand(
      "calibration-load",
      "make the daemon load a calibration file now (kept over reloads), 'none' (the source's own gaze) or "
      "'configured' (back to its configuration's [calibration] file); subscribers stay connected");
  calibration_load->add_option("FILE", calibration_file,
                               "calibration file (fovea-calibrate), read by the daemon on its machine; its absolute "
                               "path must fit in 63 bytes")
      ->required();

  // classify: offline eye-movement classification (trackerd/CLASSIFY.md)
  std::string cls_in, cls_out, cls_method = fovea::trackerd::classify::classifiers().front().name;
  double cls_rate = 0, cls_w_mm = 0, cls_h_mm = 0, cls_dist_mm = 0;
  std::uint32_t cls_w_px = 0, cls_h_px = 0;
  bool cls_force = false;
  auto* classify = app.add_subcommand("classify", "label every gaze sample of a CSV (t_ms,x_px,y_px) as fixation, "
                                                  "saccade, pso, pursuit, blink, lost or unknown");
  classify->add_option("IN", cls_in, "input CSV with header t_ms,x_px,y_px (nan marks a lost sample)")
      ->required()
      ->check(CLI::ExistingFile);
  classify->add_option("OUT", cls_out, "output CSV t_ms,label, one row per input row (refuses to overwrite)")
      ->required();
  classify->add_option("RATE_HZ", cls_rate, "nominal sample rate, Hz")->required();
  classify->add_option("SCREEN_W_PX", cls_w_px, "screen width, pixels")->required();
  classify->add_option("SCREEN_H_PX", cls_h_px, "screen height, pixels")->required();
  classify->add_option("SCREEN_W_MM", cls_w_mm, "screen width, millimetres")->required();
  classify->add_option("SCREEN_H_MM", cls_h_mm, "screen height, millimetres")->required();
  classify->add_option("DIST_MM", cls_dist_mm, "eye-to-screen distance, millimetres")->required();
  {
    std::vector<std::string> names;
    std::string help = "classification method:";
    for (const auto& m : fovea::trackerd::classify::classifiers()) {
      names.push_back(m.name);
      help += "\n  " + m.name + (names.size() == 1 ? " (default)" : "") + ": " + m.summary;
    }
    classify->add_option("--method", cls_method, help)->check(CLI::IsMember(names))->capture_default_str();
  }
  classify->add_flag("--force", cls_force, "replace OUT if it exists");

  // detect-pupil / synth-eye: the eye pipeline's detector on image files, and test images for it
  std::vector<std::string> dp_images;
  std::string dp_out, dp_leds;
  int dp_downscale = eye::DetectorSettings{}.coarse_downscale;
  bool dp_track = false, dp_force = false;
  auto* detect_pupil = app.add_subcommand(
      "detect-pupil", "find the pupil and corneal glints in eye images (PNG, JPEG, ... 8 or 16 bit); one CSV row "
                      "per image: file,pupil_x,pupil_y,major,minor,angle_deg,confidence,glint_count,glints (pixels from "
                      "the top-left corner; confidence = probability that the centre is within 1 px; method: "
                      "trackerd/eye/EYE.md)");
  detect_pupil->add_option("IMAGE", dp_images, "eye images")->required();
  detect_pupil->add_option("--out", dp_out, "also write the CSV to this file (refuses to overwrite)");
  detect_pupil->add_flag("--force", dp_force, "with --out: replace the file if it exists");
  detect_pupil->add_option("--leds", dp_leds,
                           "LED layout to pair glints with: a preset 0..5 or \"x,y;x,y;...\" in mm (default: "
                           "unknown, glints unpaired)");
  detect_pupil->add_option("--downscale", dp_downscale, "coarse pupil search on an image 1, 2 or 4 times smaller")
      ->check(CLI::IsMember({1, 2, 4}))
      ->capture_default_str();
  detect_pupil->add_flag("--track", dp_track,
                         "treat the images as consecutive video frames: search near the last pupil first "
                         "(default: every image on its own)");

  std::string se_dir, se_size = "320x240", se_leds = "2";
  int se_count = 20;
  bool se_hard = false;
  std::uint64_t se_seed = 1;
  auto* synth_eye = app.add_subcommand(
      "synth-eye", "write synthetic infrared eye images (eye_0000.png, ...) with their exact truth (truth.csv) "
                   "for gazes drawn uniformly within +-20 degrees");
  synth_eye->add_option("--out", se_dir, "new or empty directory to write into")->required();
  synth_eye->add_option("--count", se_count, "number of images")->capture_default_str();
  synth_eye->add_option("--size", se_size, "image size WxH")->capture_default_str();
  synth_eye->add_flag("--hard", se_hard,
                      "hard conditions: sensor noise 10, 2 px motion blur, upper lid over 30% of the pupil, "
                      "spectacle reflections, uneven illumination");
  synth_eye->add_option("--seed", se_seed, "random seed (same seed, same images)")->capture_default_str();
  synth_eye->add_option("--leds", se_leds, "LED layout: a preset 0..5 or \"x,y;x,y;...\" in mm")
      ->capture_default_str();

  std::string sc_out, sc_offset = "0,0,0", sc_display, sc_size = "320x240";
  int sc_points = 9, sc_validation = 4;
  std::uint64_t sc_seed = 1;
  bool sc_hard = false;
  auto* synth_calibration = app.add_subcommand(
      "synth-calibration",
      "write a recorded calibration session of the synthetic viewer, for fovea-calibrate run --headless --from: "
      "the synthetic eye follows the calibration targets (reaction, main-sequence saccades with undershoot and "
      "correction, fixation jitter, blinks) and goes through the daemon's eye pipeline and classifier, as "
      "fovea-trackerd --source synthetic-eye --eye-script calibration:POINTS[:SEED] publishes; writes SESSION.fgr "
      "and the targets shown, on the recording's clock, as SESSION.targets.csv");
  synth_calibration->add_option("--out", sc_out, "SESSION.fgr to write (with SESSION.targets.csv beside it; refuses "
                                                 "to overwrite either)")
      ->required();
  synth_calibration->add_option("--points", sc_points, "calibration targets: 5, 9, 16 or 64")
      ->check(CLI::IsMember({5, 9, 16, 64}))
      ->capture_default_str();
  synth_calibration->add_option("--validation-points", sc_validation, "validation targets after them: 0, 4 or 9")
      ->check(CLI::IsMember({0, 4, 9}))
      ->capture_default_str();
  synth_calibration->add_option("--seed", sc_seed, "the viewer, its eye's look and the target order")
      ->capture_default_str();
  synth_calibration->add_flag("--eye-hard", sc_hard,
                              "hard imaging conditions: sensor noise 10, 2 px motion blur, upper lid over 30% of "
                              "the pupil, spectacle reflections, uneven illumination");
  synth_calibration->add_option("--head-offset", sc_offset,
                                "X,Y,Z mm: the eye displaced from the position the tracker's factory calibration "
                                "assumes (x right, y down, z towards the screen; camera fixed to the screen)")
      ->capture_default_str();
  synth_calibration->add_option("--display", sc_display,
                                "display geometry WxH@WMMxHMMmm,DISTmm (default " + to_string(DisplayGeometry{}) + ")");
  synth_calibration->add_option("--eye-size", sc_size, "eye image size WxH")->capture_default_str();

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
  if (classify->parsed()) {
    return cmd_classify(cls_in, cls_out, cls_rate, cls_w_px, cls_h_px, cls_w_mm, cls_h_mm, cls_dist_mm, cls_method,
                        cls_force);
  }
  if (detect_pupil->parsed()) return cmd_detect_pupil(dp_images, dp_out, dp_force, dp_leds, dp_downscale, dp_track);
  if (synth_eye->parsed()) return cmd_synth_eye(se_dir, se_count, se_size, se_hard, se_seed, se_leds);
  if (synth_calibration->parsed()) {
    return cmd_synth_calibration(sc_out, sc_points, sc_validation, sc_seed, sc_hard, sc_offset, sc_display, sc_size);
  }
  if (reload->parsed()) return cmd_control(c, ControlCommand::Reload, "");
  if (record_start->parsed()) return cmd_control(c, ControlCommand::StartRecording, control_record_path);
  if (calibration_load->parsed()) {
    // A file is named to the daemon by its absolute path (the daemon may run elsewhere in the tree).
    std::string arg = calibration_file;
    if (arg != "none" && arg != "configured") arg = std::filesystem::absolute(arg).lexically_normal().string();
    return cmd_control(c, ControlCommand::LoadCalibration, arg);
  }
  if (record_stop->parsed()) return cmd_control(c, ControlCommand::StopRecording, "");
  return 2;
}
