// SPDX-License-Identifier: Apache-2.0
// Loopback latency of the gaze stream: a real fovea-trackerd process publishing synthetic gaze,
// and N GazeClient subscribers in this process. For each N it reports, over all clients:
//   age      - the sample's capture (due) time on the daemon to the client callback
//              (includes the daemon's timer wake-up, encoding, fan-out, kernel, client thread);
//   transit  - the daemon's send timestamp to client receipt (network path only);
// as p50/p99/max, plus lost/duplicated samples and the daemon's CPU use (from /proc).
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "proc_cpu.h"
#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"

using namespace fovea::protocol;

namespace {

using fovea::bench::cpu_seconds;

double pct(std::vector<std::int64_t>& v, double q) {
  if (v.empty()) return 0;
  const auto k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return static_cast<double>(v[k]) / 1e6;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_latency: loopback latency of fovea-trackerd to N subscribers"};
  std::string trackerd = FOVEA_TRACKERD_PATH;
  double rate = 1000, seconds = 5, warmup = 1;
  std::vector<int> counts{1, 8, 32};
  int port = 47990;
  app.add_option("--trackerd", trackerd, "fovea-trackerd binary")->capture_default_str();
  app.add_option("--rate", rate, "sample rate (Hz)")->capture_default_str();
  app.add_option("--seconds", seconds, "measured seconds per subscriber count")->capture_default_str();
  app.add_option("--warmup", warmup, "seconds before measuring")->capture_default_str();
  app.add_option("--subscribers", counts, "subscriber counts to measure")->capture_default_str();
  app.add_option("--port", port, "UDP port for the daemon")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  const std::string rate_text = std::to_string(rate);
  const std::string port_text = std::to_string(port);
  const pid_t daemon = fork();
  if (daemon == 0) {
    execl(trackerd.c_str(), trackerd.c_str(), "--source", "synthetic", "--rate", rate_text.c_str(), "--port",
          port_text.c_str(), "--log-level", "warn", static_cast<char*>(nullptr));
    std::perror("exec fovea-trackerd");
    _exit(127);
  }
  const Endpoint server{0x7F000001, static_cast<std::uint16_t>(port)};
  bool up = false;
  for (int i = 0; i < 50 && !up; ++i) up = GazeClient::query_status(server, 100).has_value();
  if (!up) {
    std::fprintf(stderr, "bench_latency: fovea-trackerd (%s) did not come up on port %d\n", trackerd.c_str(), port);
    kill(daemon, SIGKILL);
    return 1;
  }

  std::printf("# %s --rate %.0f --seconds %.0f, daemon pid %d, %u cores\n", trackerd.c_str(), rate, seconds, daemon,
              std::thread::hardware_concurrency());
  std::printf("%-5s %9s %6s %5s | %8s %8s %8s | %9s %9s %9s | %8s\n", "subs", "received", "lost", "dup", "age p50",
              "age p99", "age max", "trans p50", "trans p99", "trans max", "daemon%");
  int worst = 0;
  for (const int n : counts) {
    std::mutex mu;
    std::vector<std::int64_t> ages, transits;
    bool measuring = false;
    std::vector<std::unique_ptr<GazeClient>> clients;
    for (int i = 0; i < n; ++i) {
      ClientOptions o;
      o.server = server;
      o.streams = kStreamSamples;
      o.name = "bench " + std::to_string(i);
      auto c = std::make_unique<GazeClient>(o);
      c->on_sample([&](const GazeSample& s, const Arrival& a) {
        const std::int64_t now = monotonic_ns();
        std::lock_guard lock(mu);
        if (!measuring) return;
        ages.push_back(now - s.tracker_time_ns);
        transits.push_back(a.latency_ns);
      });
      c->start();
      clients.push_back(std::move(c));
    }
    for (auto& c : clients) {
      if (!c->wait_subscribed(3000)) {
        std::fprintf(stderr, "bench_latency: a client did not subscribe\n");
        kill(daemon, SIGKILL);
        return 1;
      }
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(warmup));
    std::vector<ClientStats> before;
    for (auto& c : clients) before.push_back(c->stats());
    const double cpu0 = cpu_seconds(daemon);
    const std::int64_t t0 = monotonic_ns();
    {
      std::lock_guard lock(mu);
      measuring = true;
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    {
      std::lock_guard lock(mu);
      measuring = false;
    }
    const double wall = static_cast<double>(monotonic_ns() - t0) / 1e9;
    const double cpu = (cpu_seconds(daemon) - cpu0) / wall * 100;
    std::uint64_t received = 0, lost = 0, dup = 0;
    for (std::size_t i = 0; i < clients.size(); ++i) {
      const ClientStats s = clients[i]->stats();
      received += s.samples.received - before[i].samples.received;
      lost += s.samples.lost - before[i].samples.lost;
      dup += s.samples.duplicated - before[i].samples.duplicated;
    }
    clients.clear();
    std::lock_guard lock(mu);
    const double age_p99 = pct(ages, 0.99);
    std::printf("%-5d %9llu %6llu %5llu | %8.3f %8.3f %8.3f | %9.3f %9.3f %9.3f | %7.1f%%\n", n,
                static_cast<unsigned long long>(received), static_cast<unsigned long long>(lost),
                static_cast<unsigned long long>(dup), pct(ages, 0.5), age_p99, pct(ages, 1.0), pct(transits, 0.5),
                pct(transits, 0.99), pct(transits, 1.0), cpu);
    std::fflush(stdout);
    if (lost > 0 || age_p99 >= 1.0) worst = 1;
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
  }
  std::printf("# latencies in ms; target: no loss and p99 < 1 ms at 1000 Hz x 32 subscribers -> %s\n",
              worst == 0 ? "met" : "NOT met");
  kill(daemon, SIGTERM);
  int st = 0;
  waitpid(daemon, &st, 0);
  return 0;
}
