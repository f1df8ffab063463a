// fovea-trackerd: the eye-tracking daemon.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>

#include "daemon.h"

namespace {
std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop.store(true); }
}  // namespace

int main(int argc, char** argv) {
  using namespace fovea;
  CLI::App app{
      "fovea-trackerd: reads an eye tracker (or a synthetic or recorded gaze stream) and streams gaze samples and\n"
      "events over UDP to subscribed clients (protocol: protocol/PROTOCOL.md). Stops cleanly on SIGINT/SIGTERM."};
  app.set_version_flag("--version", "fovea-trackerd 0.1.0");

  trackerd::DaemonOptions o;
  std::string listen = "127.0.0.1";
  std::uint16_t port = protocol::kDefaultPort;
  std::string multicast, display, log_level = "info";
  int multicast_ttl = 1;
  app.add_option("--source", o.source_spec,
                 "where gaze comes from: 'synthetic' (seeded model viewer) or 'replay:FILE' (a .fgr recording)")
      ->capture_default_str();
  app.add_option("--port", port, "UDP port to serve on")->capture_default_str();
  app.add_option("--listen", listen, "local IPv4 address to bind (0.0.0.0 to serve other machines)")
      ->capture_default_str();
  app.add_option("--multicast", multicast, "also publish samples and events to GROUP:PORT (e.g. 239.255.47.80:47801)");
  app.add_option("--multicast-ttl", multicast_ttl, "multicast TTL (1: this LAN segment)")
      ->check(CLI::Range(0, 255))
      ->capture_default_str();
  app.add_option("--record", o.record_path, "record everything published to this .fgr file (refuses to overwrite)");
  app.add_flag("--append", o.record_append, "with --record: append to an existing recording of the same display");
  app.add_option("--rate", o.synthetic_rate_hz, "synthetic source: sample rate in Hz")->capture_default_str();
  app.add_option("--seed", o.seed, "synthetic source: random seed (same seed, same gaze)")->capture_default_str();
  app.add_option("--speed", o.replay_speed, "replay source: speed factor (2 = twice as fast)")->capture_default_str();
  app.add_flag("--loop", o.replay_loop, "replay source: start again at the end");
  app.add_option("--display", display,
                 "display geometry WxH@WMMxHMMmm,DISTmm (default: the recording's, or 1920x1080@531.3x298.9mm,650mm)");
  app.add_option("--lease-ms", o.server.default_lease_ms, "lease granted to subscribers that do not ask for one")
      ->check(CLI::Range(200u, 600000u))
      ->capture_default_str();
  app.add_option("--max-subscribers", o.server.max_subscribers, "refuse subscriptions beyond this many")
      ->capture_default_str();
  app.add_option("--duration", o.duration_s, "stop after this many seconds (0: run until signalled)")
      ->capture_default_str();
  app.add_flag("--exit-at-end", o.exit_when_source_ends, "exit when the source ends (default: keep serving status)");
  app.add_option("--log-level", log_level, "log verbosity")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  auto logger = spdlog::stderr_color_mt("fovea-trackerd");
  logger->set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%-5l%$ fovea-trackerd: %v");
  spdlog::set_default_logger(logger);
  spdlog::set_level(spdlog::level::from_str(log_level));

  try {
    o.server.listen = protocol::parse_endpoint(listen, port);
    o.server.listen.port = port;
    if (!multicast.empty()) {
      o.server.multicast = protocol::parse_multicast(multicast);
      o.server.multicast->ttl = static_cast<std::uint8_t>(multicast_ttl);
    }
    if (!display.empty()) o.display = protocol::parse_display_geometry(display);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  const int status = trackerd::run_daemon(o, g_stop);
  if (g_stop.load()) spdlog::info("signal received, shut down cleanly");
  return status;
}
