// SPDX-License-Identifier: Apache-2.0
// Regression client in the manner of gpsd's gpsfake: subscribes to a fovea-trackerd that replays a
// recorded input, and prints a canonical, diff-able account of what the daemon published (events
// with times relative to the first sample, and a per-state sample summary) once the daemon reports
// that its source has ended.
// Usage: fovea-regress-client HOST:PORT [--timeout S]
#include <cmath>
#include <cstdio>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"

using namespace fovea::protocol;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s HOST:PORT [--timeout S]\n", argv[0]);
    return 2;
  }
  double timeout_s = 60;
  if (argc == 4 && std::string(argv[2]) == "--timeout") timeout_s = std::stod(argv[3]);
  ClientOptions o;
  o.server = parse_endpoint(argv[1], kDefaultPort);
  o.name = "fovea-regress";
  GazeClient client(o);
  std::mutex mu;
  std::vector<GazeSample> samples;
  std::vector<GazeEvent> events;
  client.on_sample([&](const GazeSample& s, const Arrival&) {
    std::lock_guard lock(mu);
    samples.push_back(s);
  });
  client.on_event([&](const GazeEvent& e, const Arrival&) {
    std::lock_guard lock(mu);
    events.push_back(e);
  });
  client.start();
  if (!client.wait_subscribed(5000)) {
    std::fprintf(stderr, "fovea-regress-client: no answer from %s\n", argv[1]);
    return 1;
  }
  const std::int64_t deadline = monotonic_ns() + static_cast<std::int64_t>(timeout_s * 1e9);
  bool ended = false;
  while (!ended && monotonic_ns() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    const auto st = GazeClient::query_status(o.server, 500);
    ended = st && st->source_state == SourceState::Ended;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // let the last datagrams arrive
  client.stop();
  if (!ended) {
    std::fprintf(stderr, "fovea-regress-client: the daemon's source did not end within %.0f s\n", timeout_s);
    return 1;
  }
  const ClientStats stats = client.stats();
  std::lock_guard lock(mu);
  if (samples.empty()) {
    std::fprintf(stderr, "fovea-regress-client: no samples received\n");
    return 1;
  }
  const std::int64_t t0 = samples.front().tracker_time_ns;
  std::printf("# fovea regression output v1\n");
  std::printf("samples %zu lost %llu\n", samples.size(), static_cast<unsigned long long>(stats.samples.lost));
  std::map<std::string, std::size_t> by_state;
  std::size_t valid = 0;
  double sx = 0, sy = 0;
  for (const auto& s : samples) {
    ++by_state[to_string(s.state)];
    if (s.flags & kGazeValid) {
      ++valid;
      sx += static_cast<double>(s.x);
      sy += static_cast<double>(s.y);
    }
  }
  std::printf("valid %zu mean_x %.4f mean_y %.4f\n", valid, valid ? sx / static_cast<double>(valid) : 0.0,
              valid ? sy / static_cast<double>(valid) : 0.0);
  for (const auto& [state, n] : by_state) std::printf("state %s %zu\n", state.c_str(), n);
  std::printf("events %zu\n", events.size());
  for (const auto& e : events) {
    if (e.phase != EventPhase::End) continue;
    // Millisecond resolution: enough to catch a changed classification, robust to float formatting.
    std::printf("%9.3f %-8s %7.1f ms amp %6.2f deg peak %6.0f deg/s at (%.3f, %.3f)\n",
                static_cast<double>(e.start_time_ns - t0) / 1e9, to_string(e.kind),
                static_cast<double>(e.duration_ns) / 1e6, static_cast<double>(e.amplitude_deg),
                static_cast<double>(e.peak_velocity_deg_s), static_cast<double>(e.centroid_x),
                static_cast<double>(e.centroid_y));
  }
  return 0;
}
