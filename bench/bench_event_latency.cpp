// SPDX-License-Identifier: Apache-2.0
// Event latency through the real daemon (issue 25 goal 4): a fovea-trackerd process serves its
// synthetic viewer (seeded, so this program regenerates the ground truth: which movement each
// sample is) with the default classifier, and one GazeClient on loopback subscribes to samples,
// final events and provisional events. For each true saccade and each fixation that follows one it
// reports how long after the true onset (the onset sample's capture time on the daemon's clock) the
// client had the provisional and the final event saying so (CLOCK_MONOTONIC on one machine: no
// clock mapping), p50/p99, the true events with none, and the share of provisional events the
// final labels retracted.
//
//   bench_event_latency [--rates 60 250 500 1000] [--seconds 30] [--seed 1]
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "classify/evaluate.h"
#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"
#include "sim/synthetic_labelled.h"

using namespace fovea;
using namespace fovea::protocol;
using fovea::trackerd::classify::Label;

namespace {

struct Received {
  std::vector<GazeSample> samples;  // by sequence (the source's sample index)
  std::vector<std::pair<GazeEvent, std::int64_t>> events;  // with the client's receive time
};

// The first event of `kind`/Start with these flags whose start lies in [from, to]: its receive time.
std::optional<std::int64_t> first_event(const Received& r, EyeMovement kind, bool provisional, std::int64_t from,
                                        std::int64_t to) {
  for (const auto& [e, at] : r.events) {
    if (e.kind != kind || e.phase != EventPhase::Start || e.provisional() != provisional ||
        (e.flags & kEventRetracted) != 0)
      continue;
    if (e.start_time_ns >= from && e.start_time_ns <= to) return at;
  }
  return std::nullopt;
}

struct Latencies {
  std::vector<double> ms;
  std::size_t missed = 0;
  void add(std::optional<std::int64_t> at, std::int64_t onset) {
    if (at) ms.push_back(static_cast<double>(*at - onset) / 1e6);
    else ++missed;
  }
  std::string cell() const {
    char b[64];
    std::snprintf(b, sizeof b, "%.1f / %.1f | %zu of %zu", trackerd::classify::quantile(ms, 0.5),
                  trackerd::classify::quantile(ms, 0.99), missed, missed + ms.size());
    return b;
  }
};

pid_t start_daemon(const std::string& trackerd, double rate, unsigned seed, int port) {
  const std::string rate_text = std::to_string(rate), seed_text = std::to_string(seed), port_text = std::to_string(port);
  const pid_t pid = fork();
  if (pid == 0) {
    execl(trackerd.c_str(), trackerd.c_str(), "--source", "synthetic", "--rate", rate_text.c_str(), "--seed",
          seed_text.c_str(), "--port", port_text.c_str(), "--wait-subscribers", "1", "--log-level", "warn",
          static_cast<char*>(nullptr));
    std::perror("exec fovea-trackerd");
    _exit(127);
  }
  return pid;
}

Received record(const Endpoint& server, double seconds) {
  Received r;
  std::mutex mu;
  ClientOptions o;
  o.server = server;
  o.streams = kStreamSamples | kStreamEvents | kStreamProvisional;
  o.name = "bench_event_latency";
  o.queue_capacity = 1;
  GazeClient client(o);
  client.on_sample([&](const GazeSample& s, const Arrival& a) {
    std::lock_guard lock(mu);
    if (a.sequence >= r.samples.size()) r.samples.resize(a.sequence + 1);
    r.samples[a.sequence] = s;
  });
  client.on_event([&](const GazeEvent& e, const Arrival&) {
    const std::int64_t now = monotonic_ns();
    std::lock_guard lock(mu);
    r.events.emplace_back(e, now);
  });
  client.start();
  if (!client.wait_subscribed(3000)) throw std::runtime_error("the client did not subscribe");
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  client.stop();
  std::lock_guard lock(mu);
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_event_latency: true eye-movement onset -> provisional and final GAZE_EVENT at a loopback client"};
  std::string trackerd = FOVEA_TRACKERD_PATH;
  std::vector<double> rates{60, 250, 500, 1000};
  double seconds = 30;
  unsigned seed = 1;
  int port = 47993;
  app.add_option("--trackerd", trackerd, "fovea-trackerd binary")->capture_default_str();
  app.add_option("--rates", rates, "sample rates (Hz)")->capture_default_str();
  app.add_option("--seconds", seconds, "seconds of gaze per rate")->capture_default_str();
  app.add_option("--seed", seed, "the synthetic viewer's seed")->capture_default_str();
  app.add_option("--port", port, "UDP port for the daemon")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  std::printf("# bench_event_latency --seconds %.0f --seed %u (%s, default classifier), %u cores\n\n", seconds, seed,
              trackerd.c_str(), std::thread::hardware_concurrency());
  std::printf("| rate Hz | saccade onset, provisional p50 / p99 ms | missed | final p50 / p99 ms | missed | fixation onset, "
              "provisional p50 / p99 ms | missed | final p50 / p99 ms | missed | provisional retracted |\n");
  std::printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  const Endpoint server{0x7F000001, static_cast<std::uint16_t>(port)};
  for (const double rate : rates) {
    const pid_t daemon = start_daemon(trackerd, rate, seed, port);
    Received r;
    try {
      r = record(server, seconds);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "bench_event_latency: %s (is %s runnable?)\n", e.what(), trackerd.c_str());
      kill(daemon, SIGKILL);
      return 1;
    }
    kill(daemon, SIGTERM);
    waitpid(daemon, nullptr, 0);
    // The ground truth: the same seeded viewer; its positions must be what the daemon sent.
    const auto truth = trackerd::classify::synthetic_labelled(rate, static_cast<double>(r.samples.size()) / rate + 1, seed);
    std::size_t checked = 0;
    for (std::size_t i = 0; i < r.samples.size() && i < truth.samples.size(); ++i) {
      const GazeSample& s = r.samples[i];
      if (s.tracker_time_ns == 0 || (s.flags & kGazeValid) == 0) continue;
      // The same noise and segments; only the tremor (0.003 deg, a function of absolute time) differs.
      if (std::abs(static_cast<double>(s.x_deg) - truth.samples[i].x_deg) > 0.01) {
        std::fprintf(stderr, "bench_event_latency: sample %zu differs from the regenerated viewer (%f vs %f deg)\n", i,
                     static_cast<double>(s.x_deg), truth.samples[i].x_deg);
        return 1;
      }
      ++checked;
    }
    Latencies sac_p, sac_f, fix_p, fix_f;
    const auto time_of = [&](std::size_t i) { return r.samples[i].tracker_time_ns; };
    const std::size_t n = std::min(r.samples.size(), truth.truth.size());
    for (std::size_t a = 1; a < n; ++a) {
      if (truth.truth[a] != Label::Saccade || truth.truth[a - 1] == Label::Saccade || time_of(a) == 0) continue;
      std::size_t b = a;
      while (b < n && truth.truth[b] == Label::Saccade) ++b;
      if (b >= n || time_of(b - 1) == 0) break;  // the run reaches the end of the recording
      const std::int64_t onset = time_of(a), end = time_of(b - 1), kBefore = 20'000'000, kAfter = 50'000'000;
      sac_p.add(first_event(r, EyeMovement::Saccade, true, onset - kBefore, end), onset);
      sac_f.add(first_event(r, EyeMovement::Saccade, false, onset - kBefore, end), onset);
      if (truth.truth[b] != Label::Fixation || time_of(b) == 0) continue;
      const std::int64_t landing = time_of(b);
      fix_p.add(first_event(r, EyeMovement::Fixation, true, landing - kBefore, landing + kAfter), landing);
      fix_f.add(first_event(r, EyeMovement::Fixation, false, landing - kBefore, landing + kAfter), landing);
    }
    std::size_t provisional = 0, retracted = 0;
    for (const auto& [e, at] : r.events) {
      if ((e.flags & kEventRetracted) != 0) ++retracted;
      else if (e.provisional()) ++provisional;
    }
    std::printf("| %.0f | %s | %s | %s | %s | %zu of %zu (%.1f %%) |\n", rate, sac_p.cell().c_str(), sac_f.cell().c_str(),
                fix_p.cell().c_str(), fix_f.cell().c_str(), retracted, provisional,
                100.0 * static_cast<double>(retracted) / static_cast<double>(std::max<std::size_t>(1, provisional)));
    std::fflush(stdout);
    if (checked < 10) std::fprintf(stderr, "bench_event_latency: only %zu samples checked against the truth\n", checked);
  }
  return 0;
}
