// SPDX-License-Identifier: Apache-2.0
// The LSL outlet's cost (issue 27, "Measure"), side by side in one run: for 1, 8 and 32 consumers
// (liblsl inlets, one thread each, on this machine), the latency from a sample's timestamp to its
// receipt by an inlet, p50/p99,
//   bare   an outlet in this process with fovea's 11 float channels at the rate, each sample
//          stamped with lsl_local_clock() as it is pushed: LSL's own cost
//   fovea  fovea-trackerd --source synthetic --lsl: the sample's device time (when the synthetic
//          viewer's sample was due; the daemon publishes it then) to receipt: the daemon's pipeline
//          (calibration, classifier, GazeServer, outlet) plus LSL
// and, the other direction, from an LSL outlet's push (its timestamp, lsl_local_clock()) to receipt
// by 1, 8 and 32 fovea clients (GazeClient) of fovea-trackerd --source lsl:NAME, against the same
// outlet read by as many bare inlets; and the daemon's CPU (utime + stime from /proc over the
// window) with the outlet on and off (no LSL consumer, no fovea subscriber), as % of one core. Discovery stays on this machine: LSLAPICFG
// is set to tests/data/lsl_api.cfg unless already set.
//
//   bench_lsl [--rate 1000] [--seconds 5] [--consumers 1 8 32]
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <lsl_cpp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"
#include "lsl/lsl_outlet.h"
#include "proc_cpu.h"

namespace {

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

// Each consumer pulls until `stop`; the latency of every sample, ms.
std::vector<double> consume(const lsl::stream_info& info, std::size_t consumers, double seconds) {
  std::vector<std::vector<double>> per(consumers);
  std::vector<std::unique_ptr<lsl::stream_inlet>> inlets;
  for (std::size_t i = 0; i < consumers; ++i) {
    inlets.push_back(std::make_unique<lsl::stream_inlet>(info, 360, 1));
    inlets.back()->open_stream(10.0);
  }
  std::atomic<bool> stop{false};
  std::vector<std::thread> threads;
  for (std::size_t i = 0; i < consumers; ++i) {
    threads.emplace_back([&, i] {
      std::vector<float> v;
      while (!stop.load()) {
        const double ts = inlets[i]->pull_sample(v, 0.1);
        if (ts != 0.0) per[i].push_back((lsl::local_clock() - ts) * 1e3);
      }
    });
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  stop = true;
  for (auto& t : threads) t.join();
  std::vector<double> all;
  for (auto& p : per) {
    // The first 10 % of each consumer's window: the connection's start-up, not the steady state.
    all.insert(all.end(), p.begin() + static_cast<std::ptrdiff_t>(p.size() / 10), p.end());
  }
  return all;
}

pid_t start_daemon(const std::string& trackerd, double rate, int port, bool lsl, const std::string& source = "synthetic") {
  const std::string rate_text = std::to_string(rate), port_text = std::to_string(port);
  const pid_t pid = fork();
  if (pid == 0) {
    std::vector<const char*> args{trackerd.c_str(), "--source", source.c_str(), "--rate", rate_text.c_str(), "--port",
                                  port_text.c_str(), "--log-level", "warn"};
    if (lsl) args.push_back("--lsl");
    args.push_back(nullptr);
    execv(trackerd.c_str(), const_cast<char* const*>(args.data()));
    std::perror("exec fovea-trackerd");
    _exit(127);
  }
  return pid;
}

void stop_daemon(pid_t pid) {
  kill(pid, SIGTERM);
  waitpid(pid, nullptr, 0);
}

using fovea::bench::cpu_seconds;

double daemon_cpu_percent(const std::string& trackerd, double rate, int port, bool lsl, double seconds) {
  const pid_t pid = start_daemon(trackerd, rate, port, lsl);
  std::this_thread::sleep_for(std::chrono::seconds(1));  // past start-up
  const double c0 = cpu_seconds(pid);
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const double c1 = cpu_seconds(pid);
  stop_daemon(pid);
  return 100.0 * (c1 - c0) / seconds;
}

// An outlet of `info` in this process pushing at its rate, each sample stamped as pushed, while
// `read` measures.
template <class Read>
std::vector<double> with_pushing_outlet(lsl::stream_info info, Read read) {
  const double rate = info.nominal_srate();
  lsl::stream_outlet outlet(info);
  std::atomic<bool> stop{false};
  std::thread pusher([&] {
    const std::vector<float> v(static_cast<std::size_t>(info.channel_count()), 0.5f);
    auto due = std::chrono::steady_clock::now();
    const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(1.0 / rate));
    while (!stop.load()) {
      due += period;
      std::this_thread::sleep_until(due);
      outlet.push_sample(v, lsl::local_clock());
    }
  });
  std::vector<double> ms = read(info);
  stop = true;
  pusher.join();
  return ms;
}

// LSL outlet -> fovea-trackerd --source lsl:NAME -> `clients` GazeClients: receipt (CLOCK_MONOTONIC)
// minus the sample's time (the outlet's timestamp, mapped by the daemon onto the same clock), ms.
std::vector<double> inbound_fovea(const std::string& trackerd, double rate, int port, std::size_t clients, double seconds) {
  const std::string name = "bench-in-" + std::to_string(getpid()) + "-" + std::to_string(clients);
  lsl::stream_info info(name, "Gaze", 2, rate, lsl::cf_float32, name);
  lsl::xml_element chns = info.desc().append_child("channels");
  chns.append_child("channel").append_child_value("label", "x").append_child_value("type", "ScreenX").append_child_value("unit", "normalized");
  chns.append_child("channel").append_child_value("label", "y").append_child_value("type", "ScreenY").append_child_value("unit", "normalized");
  return with_pushing_outlet(info, [&](const lsl::stream_info&) {
    const pid_t pid = start_daemon(trackerd, rate, port, false, "lsl:" + name);
    std::mutex mu;
    std::vector<double> ms;
    bool measuring = false;
    std::vector<std::unique_ptr<fovea::protocol::GazeClient>> cs;
    for (std::size_t i = 0; i < clients; ++i) {
      fovea::protocol::ClientOptions o;
      o.server = fovea::protocol::Endpoint{0x7F000001, static_cast<std::uint16_t>(port)};
      o.streams = fovea::protocol::kStreamSamples;
      o.name = "bench_lsl";
      auto c = std::make_unique<fovea::protocol::GazeClient>(o);
      c->on_sample([&](const fovea::protocol::GazeSample& s, const fovea::protocol::Arrival&) {
        const double d = static_cast<double>(fovea::protocol::monotonic_ns() - s.tracker_time_ns) * 1e-6;
        std::lock_guard lock(mu);
        if (measuring) ms.push_back(d);
      });
      c->start();
      cs.push_back(std::move(c));
    }
    std::this_thread::sleep_for(std::chrono::seconds(3));  // resolution, subscriptions
    { std::lock_guard lock(mu); measuring = true; }
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    { std::lock_guard lock(mu); measuring = false; }
    cs.clear();
    stop_daemon(pid);
    return ms;
  });
}

// A bare outlet of `channels` floats read by `consumers` bare inlets: LSL's own latency.
std::vector<double> bare(double rate, std::size_t channels, std::size_t consumers, double seconds) {
  const std::string name = "bench-bare-" + std::to_string(getpid()) + "-" + std::to_string(channels) + "-" + std::to_string(consumers);
  return with_pushing_outlet(lsl::stream_info(name, "Gaze", static_cast<std::int32_t>(channels), rate, lsl::cf_float32, name),
                             [&](const lsl::stream_info& info) {
    const auto found = lsl::resolve_stream("source_id", info.source_id(), 1, 10.0);
    return found.empty() ? std::vector<double>{} : consume(found.front(), consumers, seconds);
  });
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_lsl: the LSL outlet's added latency and CPU against bare liblsl, side by side"};
  double rate = 1000, seconds = 5;
  std::vector<std::size_t> consumers{1, 8, 32};
  std::string trackerd = FOVEA_TRACKERD_PATH;
  app.add_option("--rate", rate, "sample rate, Hz")->capture_default_str();
  app.add_option("--seconds", seconds, "seconds per measurement")->capture_default_str();
  app.add_option("--consumers", consumers, "numbers of LSL consumers")->capture_default_str();
  app.add_option("--trackerd", trackerd, "fovea-trackerd to run")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (std::getenv("LSLAPICFG") == nullptr) setenv("LSLAPICFG", FOVEA_LSL_API_CFG, 1);

  std::printf("# bench_lsl --rate %g --seconds %g, %s, %u cores, LSLAPICFG=%s\n", rate, seconds,
              fovea::trackerd::lsl_library_info().c_str(), std::thread::hardware_concurrency(), std::getenv("LSLAPICFG"));
  std::printf("\n| consumers | bare LSL p50 / p99 ms | fovea-trackerd --lsl p50 / p99 ms | added p50 ms | samples (bare, fovea) |\n"
              "|---:|---:|---:|---:|---:|\n");
  const int port = 47000 + static_cast<int>(getpid() % 900);
  for (const std::size_t n : consumers) {
    const std::vector<double> b = bare(rate, fovea::trackerd::kLslGazeChannels.size(), n, seconds);
    const pid_t pid = start_daemon(trackerd, rate, port, true);
    const auto found = lsl::resolve_stream("source_id", "fovea-trackerd-" + std::to_string(port) + "-gaze", 1, 10.0);
    const std::vector<double> f = found.empty() ? std::vector<double>{} : consume(found.front(), n, seconds);
    stop_daemon(pid);
    std::printf("| %zu | %.3f / %.3f | %.3f / %.3f | %+.3f | %zu, %zu |\n", n, quantile(b, 0.5), quantile(b, 0.99),
                quantile(f, 0.5), quantile(f, 0.99), quantile(f, 0.5) - quantile(b, 0.5), b.size(), f.size());
    std::fflush(stdout);
  }
  std::printf("\nThe other direction: an LSL outlet at %g Hz, stamped as pushed, read by bare inlets and by fovea "
              "clients of fovea-trackerd --source lsl:NAME.\n\n"
              "| consumers | bare LSL p50 / p99 ms | LSL -> fovea-trackerd -> fovea clients p50 / p99 ms | added p50 ms | samples (bare, fovea) |\n"
              "|---:|---:|---:|---:|---:|\n", rate);
  for (const std::size_t n : consumers) {
    const std::vector<double> b = bare(rate, 2, n, seconds);
    const std::vector<double> f = inbound_fovea(trackerd, rate, port, n, seconds);
    std::printf("| %zu | %.3f / %.3f | %.3f / %.3f | %+.3f | %zu, %zu |\n", n, quantile(b, 0.5), quantile(b, 0.99),
                quantile(f, 0.5), quantile(f, 0.99), quantile(f, 0.5) - quantile(b, 0.5), b.size(), f.size());
    std::fflush(stdout);
  }
  const double off = daemon_cpu_percent(trackerd, rate, port, false, seconds);
  const double on = daemon_cpu_percent(trackerd, rate, port, true, seconds);
  const double off2 = daemon_cpu_percent(trackerd, rate, port, false, seconds);
  std::printf("\nfovea-trackerd CPU at %g Hz (%% of one core, %g s each): outlet off %.1f, on %.1f, off again %.1f: "
              "the outlet costs %+.1f\n", rate, seconds, off, on, off2, on - (off + off2) / 2);
  return 0;
}
