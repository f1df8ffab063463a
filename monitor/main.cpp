// SPDX-License-Identifier: Apache-2.0
// fovea-monitor: a live page in the browser with what the tracker sees (the eye image with the
// pupil, glints and search region), the gaze on the screen, the classifier's labels over time and
// the daemon's health. A client of fovea-trackerd like any other (MONITOR.md).
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <optional>
#include <cstdio>
#include <thread>

#include "assets.h"
#include "fovea/protocol/udp.h"
#include "live_feed.h"
#include "request_checks.h"
#include "web_server.h"

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop.store(true); }

struct Args {
  std::string server = "127.0.0.1:47800";
  std::string listen = "127.0.0.1:47880";
  bool allow_remote = false;
  std::vector<std::string> allow_hosts;
  std::string control_socket, viewer_socket;
  double duration_s = 0;
  std::string stats_json;
};

// "IP:PORT" for --listen (IPv4; the port may be 0 for any free one).
bool split_listen(const std::string& text, std::string& ip, std::uint16_t& port) {
  const std::size_t colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0) return false;
  ip = text.substr(0, colon);
  try {
    const unsigned long p = std::stoul(text.substr(colon + 1));
    if (p > 65535) return false;
    port = static_cast<std::uint16_t>(p);
  } catch (const std::exception&) {
    return false;
  }
  return true;
}

bool loopback_ip(const std::string& ip) { return ip.rfind("127.", 0) == 0; }

void write_stats(const std::string& path, const fovea::monitor::WebStats& w, const fovea::monitor::FeedStats& f) {
  if (path.empty()) return;
  FILE* out = std::fopen(path.c_str(), "w");
  if (out == nullptr) return;
  std::fprintf(out,
               "{\"samples\": %llu, \"events\": %llu, \"batches\": %llu, \"eye_frames\": %llu, \"jpeg_ms_total\": %.3f, "
               "\"requests\": %llu, \"websockets_opened\": %llu, \"refused_host\": %llu, \"refused_origin\": %llu, "
               "\"refused_token\": %llu, \"refused_full\": %llu, \"slow_closed\": %llu, \"frames_replaced\": %llu, "
               "\"messages_sent\": %llu}\n",
               static_cast<unsigned long long>(f.samples), static_cast<unsigned long long>(f.events),
               static_cast<unsigned long long>(f.batches), static_cast<unsigned long long>(f.eye_frames),
               static_cast<double>(f.jpeg_ns_total) * 1e-6, static_cast<unsigned long long>(w.requests),
               static_cast<unsigned long long>(w.websockets_opened), static_cast<unsigned long long>(w.refused_host),
               static_cast<unsigned long long>(w.refused_origin), static_cast<unsigned long long>(w.refused_token),
               static_cast<unsigned long long>(w.refused_full), static_cast<unsigned long long>(w.slow_closed),
               static_cast<unsigned long long>(w.frames_replaced), static_cast<unsigned long long>(w.messages_sent));
  std::fclose(out);
}

void add_options(CLI::App& app, Args& a) {
  app.set_version_flag("--version", "fovea-monitor " FOVEA_VERSION);
  app.add_option("--server", a.server, "the daemon's gaze port, HOST:PORT")->capture_default_str();
  app.add_option("--listen", a.listen,
                 "where to serve the page, IP:PORT (loopback; another address needs --allow-remote)")
      ->capture_default_str();
  app.add_flag("--allow-remote", a.allow_remote,
               "allow --listen on a non-loopback address: anyone who can reach it and has the URL's token sees the "
               "eye images (prefer an SSH tunnel)");
  app.add_option("--allow-host", a.allow_hosts,
                 "also accept requests for this host name (Host header), e.g. the name a reverse proxy uses");
  app.add_option("--control-socket", a.control_socket,
                 "the daemon's control socket (default: where fovea-trackerd puts it for the --server port)");
  app.add_option("--viewer-socket", a.viewer_socket, "the daemon's viewer socket (default: beside the control socket)");
  app.add_option("--duration", a.duration_s, "stop after this many seconds (0: until SIGINT/SIGTERM)");
  app.add_option("--stats-json", a.stats_json, "write the monitor's counters here when it stops (benchmarks)");
}

// The options checked and turned into the feed's and the server's; an exit status when they are wrong.
std::optional<int> configure(const Args& a, fovea::monitor::FeedOptions& fo, fovea::monitor::WebServerOptions& wo) {
  std::string ip;
  std::uint16_t port = 0;
  if (!split_listen(a.listen, ip, port)) {
    std::fprintf(stderr, "fovea-monitor: --listen \"%s\": IP:PORT is needed (e.g. 127.0.0.1:47880)\n", a.listen.c_str());
    return 2;
  }
  if (!loopback_ip(ip)) {
    if (!a.allow_remote) {
      std::fprintf(stderr,
                   "fovea-monitor: --listen %s is not a loopback address: the page shows the user's eye. Use an SSH "
                   "tunnel (ssh -L 47880:127.0.0.1:47880 HOST), or give --allow-remote to serve other machines\n",
                   a.listen.c_str());
      return 2;
    }
    spdlog::warn("serving on {}, beyond this machine: anyone who can reach it and has the token sees the eye images, "
                 "unencrypted (an SSH tunnel is safer)",
                 a.listen);
  }
  try {
    fo.server = fovea::protocol::parse_endpoint(a.server, fovea::protocol::kDefaultPort);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-monitor: --server: %s\n", e.what());
    return 2;
  }
  try {
    wo.hosts = fovea::monitor::allowed_hosts(ip, a.allow_hosts);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-monitor: %s\n", e.what());
    return 2;
  }
  fo.control_socket = a.control_socket;
  fo.viewer_socket = a.viewer_socket;
  wo.listen_ip = ip;
  wo.port = port;
  wo.token = fovea::monitor::new_token();
  return std::nullopt;
}

// Serves until a signal (or --duration); 1 when the server cannot start.
int serve(const Args& a, const fovea::monitor::FeedOptions& fo, const fovea::monitor::WebServerOptions& wo) {
  using namespace fovea;
  try {
    // The page's handlers run on the server's thread: they see the feed only while it exists.
    std::atomic<monitor::LiveFeed*> feed_ptr{nullptr};
    monitor::WebServer web(
        wo, monitor::page_assets(),
        [&] {
          monitor::LiveFeed* f = feed_ptr.load();
          return f != nullptr ? f->opening_messages() : std::vector<monitor::Outgoing>{};
        },
        [&](monitor::WebServer::SessionId id, std::string text) {
          if (monitor::LiveFeed* f = feed_ptr.load()) f->on_page_message(id, std::move(text));
        });
    monitor::LiveFeed feed(fo, web);
    feed_ptr = &feed;
    const std::string shown_ip = wo.listen_ip == "0.0.0.0" ? "127.0.0.1" : wo.listen_ip;
    std::printf("fovea-monitor: open http://%s:%u/?token=%s\n", shown_ip.c_str(), web.port(), wo.token.c_str());
    std::printf("  gaze from %s; viewer feed %s; control %s\n", fo.server.to_string().c_str(),
                feed.viewer_socket().empty() ? "(no daemon control socket found on this host)" : feed.viewer_socket().c_str(),
                feed.controls() ? "allowed (markers, recording)" : "not allowed: read-only");
    std::fflush(stdout);
    const auto start = std::chrono::steady_clock::now();
    while (!g_stop.load()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (a.duration_s > 0 && std::chrono::steady_clock::now() - start >= std::chrono::duration<double>(a.duration_s)) break;
    }
    write_stats(a.stats_json, web.stats(), feed.stats());
    web.stop();  // no handler runs any more: the feed can go
    feed_ptr.store(nullptr);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-monitor: %s\n", e.what());
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  CLI::App app{
      "fovea-monitor: a live page in the browser showing what fovea-trackerd sees: the eye image with the detected "
      "pupil, glints and search region, the gaze on the screen with its trail and labels, position and velocity over "
      "time, and the daemon's health. It subscribes to the daemon like any client, reads eye images from the "
      "daemon's viewer socket (same host, the daemon's group), and serves the page on loopback. Open the URL it "
      "prints (it holds this run's token). From another machine: ssh -L 47880:127.0.0.1:47880 HOST, then open the "
      "printed URL on your machine (MONITOR.md)."};
  add_options(app, a);
  CLI11_PARSE(app, argc, argv);
  fovea::monitor::FeedOptions fo;
  fovea::monitor::WebServerOptions wo;
  if (const auto failed = configure(a, fo, wo)) return *failed;

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);
  return serve(a, fo, wo);
}
