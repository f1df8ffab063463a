// SPDX-License-Identifier: Apache-2.0
#pragma once
// fovea-monitor's HTTP and WebSocket server (Boost.Beast on one Asio thread; MONITOR.md says why
// Beast). It serves the page's few embedded files and pushes live data to every WebSocket at /ws.
//
// What it refuses, before anything else (request_checks.h): a Host it is not reached by, a
// WebSocket from another origin or without the run's token. What it bounds, so that hostile or
// slow clients never stall the others or the data path: connections (beyond max_connections one is
// closed as soon as it is accepted), the time to send a request, header and body sizes, the size
// of a message a page may send, and each WebSocket's queue: an eye frame waiting to go is
// replaced by a newer one, and a page that falls max_queue_bytes behind is closed.
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "request_checks.h"

namespace fovea::monitor {

struct Asset {
  std::string_view path;          // "/", "/monitor.js", ...
  std::string_view content_type;
  std::string_view body;
};

struct WebServerOptions {
  std::string listen_ip = "127.0.0.1";
  std::uint16_t port = 47880;     // 0: any free port (tests)
  AllowedHosts hosts;
  std::string token;              // required on /ws
  std::size_t max_connections = 64;  // TCP connections, HTTP and WebSocket together
  std::size_t max_sessions = 16;     // WebSockets
  std::size_t max_queue_bytes = 2u << 20;  // per WebSocket: text waiting beyond this closes it
  std::size_t max_message_bytes = 4096;   // what a page may send in one message
  int request_timeout_ms = 5000;  // to send a whole request (and the WebSocket handshake)
};

// What goes to pages. Shared: one copy for every session.
struct Outgoing {
  enum class Kind { Text, EyeFrame };  // EyeFrame: binary, and a newer one replaces one not yet sent
  std::shared_ptr<const std::string> data;
  Kind kind = Kind::Text;
};

struct WebStats {
  std::uint64_t requests = 0, websockets_opened = 0;
  std::uint64_t refused_host = 0, refused_origin = 0, refused_token = 0, refused_full = 0;
  std::uint64_t not_found = 0, bad_requests = 0;
  std::uint64_t slow_closed = 0;      // WebSockets closed for falling behind
  std::uint64_t frames_replaced = 0;  // eye frames a page never got, a newer one having come
  std::uint64_t messages_sent = 0;
  std::size_t connections = 0, sessions = 0;
};

class WebServer {
 public:
  using SessionId = std::uint64_t;
  // What a new WebSocket is sent first (the latest state), on the server's thread.
  using OpenHandler = std::function<std::vector<Outgoing>()>;
  // A text message from a page; runs on the server's thread and must not block (hand work off).
  using MessageHandler = std::function<void(SessionId, std::string)>;

  // Binds at once (throws std::runtime_error naming the address when it cannot) and serves on its
  // own thread until destroyed.
  WebServer(WebServerOptions options, std::vector<Asset> assets, OpenHandler on_open, MessageHandler on_message);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  std::uint16_t port() const;
  // Stops serving and joins the server's thread (the destructor does too); messages handed over
  // afterwards are dropped.
  void stop();
  // Thread-safe: to every open WebSocket, or to one.
  void broadcast(Outgoing message);
  void send_to(SessionId session, Outgoing message);
  WebStats stats() const;

  class Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// The headers every response carries: a strict Content-Security-Policy (this origin's scripts and
// styles only, no inline code, no eval), no sniffing, no framing, no referrer (the URL has the
// token), no caching.
inline constexpr std::string_view kContentSecurityPolicy =
    "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob:; connect-src 'self'; "
    "base-uri 'none'; form-action 'none'; frame-ancestors 'none'";

}  // namespace fovea::monitor
