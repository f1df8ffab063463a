// SPDX-License-Identifier: Apache-2.0
// What the tracker bridges cost and how well they keep time (issue 24): a fake tracker (Gazepoint
// Control, Pupil Capture: tests/fakes/) with a known clock (offset and drift), a real
// fovea-trackerd reading it, and a GazeClient subscriber in this process. Every sample received is
// matched to the record the fake wrote in its ground truth (by its point, then nearest in time):
//   latency  - the fake's send time to the client's receipt (the bridge: parse, map, queue, the
//              daemon's publishing, the network), p50 / p99 / max;
//   time err - the sample's time (the tracker clock mapped onto the host) minus when the fake took
//              the gaze: what the clock mapping gets wrong, p50 / p99 of |err| and the mean (bias);
//   drift    - the fake's clock drift against the daemon's estimate (from its final log).
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"

using namespace fovea::protocol;
namespace fs = std::filesystem;

namespace {

struct Bridge {
  std::string name;
  std::string fake;                 // tests/fakes/...
  std::vector<std::string> fake_args;
  std::string spec_prefix;          // "gazepoint:127.0.0.1:" / "pupil:127.0.0.1:"
  int time_col, x_col, y_col;       // truth columns: the time the gaze was taken/sent, its point
  bool y_up;                        // Pupil: y points up
  int valid_col;                    // -1: validity from confidence (Pupil, column 6 >= 0.6)
  double expected_drift_ppm;  // host - tracker: a tracker clock running fast makes it negative
};

struct Received {
  float x, y;
  bool valid;
  std::int64_t time_ns, receive_ns;
};

pid_t spawn(const std::vector<std::string>& argv, const std::string& log) {
  std::fflush(stdout);  // else the child flushes our buffered table into its log and ours
  const pid_t pid = fork();
  if (pid == 0) {
    std::FILE* f = std::freopen(log.c_str(), "w", stdout);
    if (f != nullptr) dup2(fileno(stdout), 2);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    std::perror("exec");
    _exit(127);
  }
  return pid;
}

void stop(pid_t pid) {
  kill(pid, SIGTERM);
  int status = 0;
  waitpid(pid, &status, 0);
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string wait_for_port(const std::string& ready) {
  for (int i = 0; i < 100; ++i) {
    const std::string text = read_text(ready);
    if (!text.empty() && text.back() == '\n') return text.substr(0, text.size() - 1);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return {};
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

// The truth's rows by the point they carry (as a float on the wire holds it), their times sorted.
using Truth = std::map<std::pair<float, float>, std::vector<std::int64_t>>;

Truth read_truth(const std::string& path, const Bridge& b) {
  Truth truth;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || !std::isdigit(static_cast<unsigned char>(line[0]))) continue;
    std::vector<std::string> f;
    std::stringstream s(line);
    for (std::string cell; std::getline(s, cell, ',');) f.push_back(cell);
    const bool valid = b.valid_col >= 0 ? f[static_cast<std::size_t>(b.valid_col)] == "1" : std::stod(f[6]) >= 0.6;
    if (!valid) continue;
    const double x = std::stod(f[static_cast<std::size_t>(b.x_col)]);
    const double y = std::stod(f[static_cast<std::size_t>(b.y_col)]);
    truth[{static_cast<float>(x), static_cast<float>(b.y_up ? 1.0 - y : y)}].push_back(
        std::stoll(f[static_cast<std::size_t>(b.time_col)]));
  }
  for (auto& [k, v] : truth) std::sort(v.begin(), v.end());
  return truth;
}

void run_bridge(const Bridge& b, const std::string& trackerd, const std::string& source_dir, double seconds) {
  const fs::path dir = fs::temp_directory_path() / ("fovea-bench-bridges-" + std::to_string(getpid()) + "-" + b.name);
  fs::create_directories(dir);
  std::vector<std::string> fake = {"/usr/bin/python3", "-B", source_dir + "/tests/fakes/" + b.fake, "--port", "0",
                                   "--ready-file", (dir / "port").string(), "--truth", (dir / "truth.csv").string()};
  fake.insert(fake.end(), b.fake_args.begin(), b.fake_args.end());
  const pid_t fake_pid = spawn(fake, (dir / "fake.log").string());
  const std::string port = wait_for_port((dir / "port").string());
  if (port.empty()) {
    std::printf("%-10s the fake did not start (%s)\n", b.name.c_str(), (dir / "fake.log").c_str());
    stop(fake_pid);
    return;
  }
  const std::uint16_t daemon_port = static_cast<std::uint16_t>(48000 + getpid() % 900);
  const pid_t daemon = spawn({trackerd, "--source", b.spec_prefix + port, "--port", std::to_string(daemon_port),
                              "--control-socket", "none", "--log-level", "info"},
                             (dir / "daemon.log").string());
  ClientOptions o;
  o.server = Endpoint{0x7F000001, daemon_port};
  GazeClient client(o);
  std::mutex m;
  std::vector<Received> got;
  client.on_sample([&](const GazeSample& s, const Arrival& a) {
    std::lock_guard lock(m);
    got.push_back({s.x, s.y, (s.flags & kGazeValid) != 0, s.tracker_time_ns, a.receive_ns});
  });
  client.start();
  client.wait_subscribed(5000);
  std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<long>(seconds * 1000)));
  client.stop();
  stop(fake_pid);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  stop(daemon);

  const Truth truth = read_truth((dir / "truth.csv").string(), b);
  std::vector<double> latency_ms, error_ms, abs_error_ms;
  std::size_t unmatched = 0, valid = 0;
  for (const Received& r : got) {
    if (!r.valid) continue;
    ++valid;
    const auto it = truth.find({r.x, r.y});
    if (it == truth.end()) {
      ++unmatched;
      continue;
    }
    const auto& times = it->second;
    const auto at = std::lower_bound(times.begin(), times.end(), r.time_ns);
    std::int64_t best = at == times.end() ? times.back() : *at;
    if (at != times.begin() && (at == times.end() || r.time_ns - *(at - 1) < *at - r.time_ns)) best = *(at - 1);
    latency_ms.push_back(static_cast<double>(r.receive_ns - best) / 1e6);
    error_ms.push_back(static_cast<double>(r.time_ns - best) / 1e6);
    abs_error_ms.push_back(std::abs(error_ms.back()));
  }
  double mean = 0;
  for (double e : error_ms) mean += e / static_cast<double>(std::max<std::size_t>(1, error_ms.size()));
  const std::string log = read_text((dir / "daemon.log").string());
  std::smatch drift;
  const bool has_drift = std::regex_search(log, drift, std::regex("drift (-?[0-9?]+) ppm"));
  std::printf("%-10s %7zu %6zu %5zu | %7.3f %7.3f %7.3f | %7.3f %7.3f %+7.3f | %+6.0f %6s\n", b.name.c_str(),
              got.size(), valid, unmatched, percentile(latency_ms, 0.5), percentile(latency_ms, 0.99),
              latency_ms.empty() ? std::nan("") : *std::max_element(latency_ms.begin(), latency_ms.end()),
              percentile(abs_error_ms, 0.5), percentile(abs_error_ms, 0.99), mean, b.expected_drift_ppm,
              has_drift ? drift[1].str().c_str() : "?");
  std::error_code ec;
  fs::remove_all(dir, ec);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Latency and clock-mapping error of the tracker bridges against fake trackers on loopback");
  double seconds = 20;
  std::string trackerd = FOVEA_TRACKERD_PATH;
  std::string source_dir = FOVEA_SOURCE_DIR;
  app.add_option("--seconds", seconds, "how long each bridge streams")->capture_default_str();
  app.add_option("--trackerd", trackerd, "the fovea-trackerd binary")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  // Gazepoint: TIME is written with 5 decimals (10 us); the fake stamps a record just before it
  // writes it. Pupil: gaze taken on schedule and sent 15 ms later, "t" answers delayed 0..3 ms.
  const std::vector<Bridge> bridges = {
      {"gazepoint", "fake_gazepoint.py", {"--rate", "150", "--drift-ppm", "50"}, "gazepoint:127.0.0.1:", 1, 3, 4, false,
       5, -50},
      {"gp-burst4", "fake_gazepoint.py", {"--rate", "150", "--drift-ppm", "50", "--burst", "4"}, "gazepoint:127.0.0.1:", 1,
       3, 4, false, 5, -50},
      {"pupil", "fake_pupil_capture.py", {"--rate", "200", "--drift-ppm", "30"}, "pupil:127.0.0.1:", 1, 3, 4, true, -1,
       -30},
      {"pupil-late", "fake_pupil_capture.py",
       {"--rate", "200", "--drift-ppm", "30", "--latency-ms", "15", "--t-jitter-ms", "3"}, "pupil:127.0.0.1:", 1, 3, 4,
       true, -1, -30},
  };
  std::printf("# %s, %.0f s per bridge, one subscriber, loopback; times in ms\n", trackerd.c_str(), seconds);
  std::printf("%-10s %7s %6s %5s | %7s %7s %7s | %7s %7s %7s | %6s %6s\n", "bridge", "samples", "valid", "unmat",
              "lat p50", "lat p99", "lat max", "err p50", "err p99", "bias", "drift", "found");
  for (const Bridge& b : bridges) run_bridge(b, trackerd, source_dir, seconds);
  std::printf("# latency: the fake's send (gazepoint) or capture (pupil) time to the client's receipt; err: the\n"
              "# sample's mapped time minus the truth's; drift: of the offset host - tracker in ppm, as the fake\n"
              "# sets it (its clock runs 50 / 30 ppm fast) and as the daemon's final log found it\n");
  return 0;
}
