// SPDX-License-Identifier: Apache-2.0
#include "web_server.h"

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include <chrono>
#include <deque>
#include <map>
#include <stdexcept>
#include <thread>

namespace fovea::monitor {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = net::ip::tcp;

namespace {

// Beast 1.74 speaks boost::string_view.
std::string_view sv(beast::string_view s) { return {s.data(), s.size()}; }
beast::string_view bsv(std::string_view s) { return {s.data(), s.size()}; }

struct Counters {
  std::atomic<std::uint64_t> requests{0}, websockets_opened{0}, refused_host{0}, refused_origin{0}, refused_token{0},
      refused_full{0}, not_found{0}, bad_requests{0}, slow_closed{0}, frames_replaced{0}, messages_sent{0};
  std::atomic<std::size_t> connections{0}, sessions{0};
};

// Counts a connection for as long as it lives (HTTP, then the WebSocket it may become).
class ConnectionSlot {
 public:
  explicit ConnectionSlot(Counters& c) : c_(&c) { ++c_->connections; }
  ~ConnectionSlot() {
    if (c_ != nullptr) --c_->connections;
  }
  ConnectionSlot(ConnectionSlot&& o) noexcept : c_(o.c_) { o.c_ = nullptr; }
  ConnectionSlot(const ConnectionSlot&) = delete;
  ConnectionSlot& operator=(const ConnectionSlot&) = delete;
  ConnectionSlot& operator=(ConnectionSlot&&) = delete;

 private:
  Counters* c_;
};

template <class Body>
void secure_headers(http::response<Body>& res) {
  res.set(http::field::server, "fovea-monitor");
  res.set("Content-Security-Policy", bsv(kContentSecurityPolicy));
  res.set("X-Content-Type-Options", "nosniff");
  res.set("X-Frame-Options", "DENY");
  res.set("Referrer-Policy", "no-referrer");
  res.set("Cross-Origin-Resource-Policy", "same-origin");
  res.set(http::field::cache_control, "no-store");
}

http::response<http::string_body> plain(http::status status, unsigned version, std::string text) {
  http::response<http::string_body> res{status, version};
  secure_headers(res);
  res.set(http::field::content_type, "text/plain; charset=utf-8");
  res.body() = std::move(text) + "\n";
  res.keep_alive(false);
  res.prepare_payload();
  return res;
}

}  // namespace

class WsSession;

class WebServer::Impl {
 public:
  Impl(WebServerOptions o, std::vector<Asset> a, OpenHandler open, MessageHandler message)
      : options(std::move(o)), assets(std::move(a)), on_open(std::move(open)), on_message(std::move(message)),
        acceptor(ioc), retry(ioc) {
    boost::system::error_code ec;
    const auto address = net::ip::make_address(options.listen_ip, ec);
    if (ec) throw std::runtime_error("--listen " + options.listen_ip + ": not an IP address");
    const tcp::endpoint at(address, options.port);
    acceptor.open(at.protocol(), ec);
    if (!ec) acceptor.set_option(net::socket_base::reuse_address(true), ec);
    if (!ec) acceptor.bind(at, ec);
    if (!ec) acceptor.listen(net::socket_base::max_listen_connections, ec);
    if (ec) {
      throw std::runtime_error("cannot listen on " + options.listen_ip + ":" + std::to_string(options.port) + ": " +
                               ec.message() + " (is another fovea-monitor running? choose another --listen port)");
    }
    accept();
    thread = std::thread([this] { ioc.run(); });
  }
  ~Impl() { stop(); }
  void stop() {
    ioc.stop();
    if (thread.joinable()) thread.join();
  }

  void accept();
  void deliver(const Outgoing& message);

  WebServerOptions options;
  std::vector<Asset> assets;
  OpenHandler on_open;
  MessageHandler on_message;
  // Before the io_context, so that sessions its pending handlers still hold, destroyed with it,
  // find these alive.
  Counters counters;
  std::map<SessionId, std::weak_ptr<WsSession>> sessions;  // the server thread's only
  SessionId next_session = 1;
  net::io_context ioc{1};
  tcp::acceptor acceptor;
  net::steady_timer retry;  // after an accept error (out of file descriptors): pause, then accept again
  std::thread thread;
};

// ---- a WebSocket --------------------------------------------------------------------------------

class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  WsSession(WebServer::Impl& server, tcp::socket socket, ConnectionSlot slot)
      : server_(server), ws_(std::move(socket)), slot_(std::move(slot)), id_(server.next_session++) {}
  ~WsSession() {
    if (!registered_) return;
    server_.sessions.erase(id_);
    --server_.counters.sessions;
  }

  void run(http::request<http::string_body> request) {
    websocket::stream_base::timeout t{};
    t.handshake_timeout = std::chrono::milliseconds(server_.options.request_timeout_ms);
    t.idle_timeout = std::chrono::seconds(30);  // a page that answers no ping for 30 s is gone
    t.keep_alive_pings = true;
    ws_.set_option(t);
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::server, "fovea-monitor"); }));
    ws_.read_message_max(server_.options.max_message_bytes);
    ws_.async_accept(request, [self = shared_from_this()](beast::error_code ec) { self->on_accept(ec); });
  }

  void send(const Outgoing& message) {
    if (closed_) return;
    if (message.kind == Outgoing::Kind::EyeFrame) {
      // The newest eye frame replaces one still waiting (not the one being written).
      for (std::size_t i = writing_ ? 1 : 0; i < queue_.size(); ++i) {
        if (queue_[i].kind == Outgoing::Kind::EyeFrame) {
          queued_bytes_ -= queue_[i].data->size();
          queue_[i] = message;
          queued_bytes_ += message.data->size();
          ++server_.counters.frames_replaced;
          return;
        }
      }
    }
    queue_.push_back(message);
    queued_bytes_ += message.data->size();
    if (queued_bytes_ > server_.options.max_queue_bytes) {
      ++server_.counters.slow_closed;
      close();
      return;
    }
    if (!writing_) write_next();
  }

 private:
  void on_accept(beast::error_code ec) {
    if (ec) return;
    ++server_.counters.websockets_opened;
    // Counted once it can receive: a broadcast after this reaches it.
    server_.sessions[id_] = weak_from_this();
    ++server_.counters.sessions;
    registered_ = true;
    if (server_.on_open) {
      for (const Outgoing& m : server_.on_open()) send(m);
    }
    read();
  }

  void read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {
        self->closed_ = true;  // too large (read_message_max), closed, or timed out
        return;
      }
      if (self->ws_.got_text() && self->server_.on_message) {
        self->server_.on_message(self->id_, beast::buffers_to_string(self->buffer_.data()));
      }
      self->buffer_.consume(self->buffer_.size());
      self->read();
    });
  }

  void write_next() {
    if (queue_.empty() || closed_) {
      writing_ = false;
      return;
    }
    writing_ = true;
    ws_.binary(queue_.front().kind == Outgoing::Kind::EyeFrame);
    ws_.async_write(net::buffer(*queue_.front().data), [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {
        self->closed_ = true;
        return;
      }
      ++self->server_.counters.messages_sent;
      self->queued_bytes_ -= self->queue_.front().data->size();
      self->queue_.pop_front();
      self->write_next();
    });
  }

  void close() {
    closed_ = true;
    beast::error_code ignored;
    beast::get_lowest_layer(ws_).socket().shutdown(tcp::socket::shutdown_both, ignored);
    beast::get_lowest_layer(ws_).socket().close(ignored);
  }

  WebServer::Impl& server_;
  websocket::stream<beast::tcp_stream> ws_;
  ConnectionSlot slot_;
  WebServer::SessionId id_;
  beast::flat_buffer buffer_;
  std::deque<Outgoing> queue_;
  std::size_t queued_bytes_ = 0;
  bool writing_ = false;
  bool closed_ = false;
  bool registered_ = false;
};

// ---- an HTTP connection -------------------------------------------------------------------------

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(WebServer::Impl& server, tcp::socket socket, ConnectionSlot slot)
      : server_(server), stream_(std::move(socket)), slot_(std::move(slot)) {}

  void read() {
    parser_.emplace();
    parser_->header_limit(8192);
    parser_->body_limit(server_.options.max_message_bytes);
    stream_.expires_after(std::chrono::milliseconds(server_.options.request_timeout_ms));
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }

 private:
  void on_read(beast::error_code ec) {
    if (ec == http::error::end_of_stream) return shut();
    if (ec) {
      // Too large, malformed or too slow: answered where HTTP still can be, then closed.
      ++server_.counters.bad_requests;
      if (ec != beast::error::timeout && ec != net::error::operation_aborted && ec != net::error::connection_reset) {
        return respond(plain(http::status::bad_request, 11, "bad request: " + ec.message()));
      }
      return shut();
    }
    ++server_.counters.requests;
    http::request<http::string_body> req = parser_->release();
    const std::string host(sv(req[http::field::host]));
    if (!host_allowed(host, server_.options.hosts)) {
      ++server_.counters.refused_host;
      return respond(plain(http::status::misdirected_request, req.version(),
                           "this fovea-monitor is not reached by that name (Host); open the URL it printed"));
    }
    const std::string_view path = path_of(sv(req.target()));
    if (websocket::is_upgrade(req)) return upgrade(std::move(req), host);
    if (req.method() != http::verb::get && req.method() != http::verb::head) {
      return respond(plain(http::status::method_not_allowed, req.version(), "only GET"));
    }
    for (const Asset& a : server_.assets) {
      if (a.path != path) continue;
      http::response<http::string_body> res{http::status::ok, req.version()};
      secure_headers(res);
      res.set(http::field::content_type, bsv(a.content_type));
      if (req.method() == http::verb::get) res.body() = std::string(a.body);
      res.keep_alive(req.keep_alive());
      res.prepare_payload();
      if (req.method() == http::verb::head) res.content_length(a.body.size());
      return respond(std::move(res));
    }
    ++server_.counters.not_found;
    return respond(plain(http::status::not_found, req.version(), "not found"));
  }

  void upgrade(http::request<http::string_body> req, const std::string& host) {
    const auto origin_field = req.find(http::field::origin);
    const std::optional<std::string_view> origin =
        origin_field == req.end() ? std::nullopt : std::optional<std::string_view>(sv(origin_field->value()));
    if (path_of(sv(req.target())) != "/ws") {
      ++server_.counters.not_found;
      return respond(plain(http::status::not_found, req.version(), "the WebSocket is at /ws"));
    }
    if (!origin_allowed(origin, host)) {
      ++server_.counters.refused_origin;
      return respond(plain(http::status::forbidden, req.version(), "a WebSocket from another origin is refused"));
    }
    if (!token_matches(token_of(sv(req.target())), server_.options.token)) {
      ++server_.counters.refused_token;
      return respond(plain(http::status::forbidden, req.version(), "the token is missing or wrong: open the URL fovea-monitor printed"));
    }
    if (server_.counters.sessions.load() >= server_.options.max_sessions) {
      ++server_.counters.refused_full;
      return respond(plain(http::status::service_unavailable, req.version(), "too many pages open"));
    }
    stream_.expires_never();  // the WebSocket keeps time its own way (pings)
    std::make_shared<WsSession>(server_, stream_.release_socket(), std::move(slot_))->run(std::move(req));
  }

  void respond(http::response<http::string_body> res) {
    auto shared = std::make_shared<http::response<http::string_body>>(std::move(res));
    http::async_write(stream_, *shared, [self = shared_from_this(), shared](beast::error_code ec, std::size_t) {
      if (ec || !shared->keep_alive()) return self->shut();
      self->read();
    });
  }

  void shut() {
    beast::error_code ignored;
    stream_.socket().shutdown(tcp::socket::shutdown_both, ignored);
  }

  WebServer::Impl& server_;
  beast::tcp_stream stream_;
  ConnectionSlot slot_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
};

// ---- the server ---------------------------------------------------------------------------------

void WebServer::Impl::accept() {
  acceptor.async_accept(ioc, [this](beast::error_code ec, tcp::socket socket) {
    if (ec == net::error::operation_aborted) return;
    if (ec) {
      // Out of file descriptors (a flood): the pending connections wait in the backlog meanwhile.
      retry.expires_after(std::chrono::milliseconds(100));
      retry.async_wait([this](beast::error_code) { accept(); });
      return;
    }
    if (counters.connections.load() >= options.max_connections) {
      ++counters.refused_full;
      beast::error_code ignored;
      socket.close(ignored);
    } else {
      std::make_shared<HttpSession>(*this, std::move(socket), ConnectionSlot(counters))->read();
    }
    accept();
  });
}

void WebServer::Impl::deliver(const Outgoing& message) {
  std::vector<std::shared_ptr<WsSession>> open;  // send() may end a session, which erases its entry
  open.reserve(sessions.size());
  for (const auto& [id, weak] : sessions) {
    if (auto s = weak.lock()) open.push_back(std::move(s));
  }
  for (const auto& s : open) s->send(message);
}

WebServer::WebServer(WebServerOptions options, std::vector<Asset> assets, OpenHandler on_open, MessageHandler on_message)
    : impl_(std::make_unique<Impl>(std::move(options), std::move(assets), std::move(on_open), std::move(on_message))) {}

WebServer::~WebServer() = default;

std::uint16_t WebServer::port() const { return impl_->acceptor.local_endpoint().port(); }

void WebServer::stop() { impl_->stop(); }

void WebServer::broadcast(Outgoing message) {
  net::post(impl_->ioc, [impl = impl_.get(), m = std::move(message)] { impl->deliver(m); });
}

void WebServer::send_to(SessionId session, Outgoing message) {
  net::post(impl_->ioc, [impl = impl_.get(), session, m = std::move(message)] {
    const auto it = impl->sessions.find(session);
    if (it == impl->sessions.end()) return;
    if (auto s = it->second.lock()) s->send(m);
  });
}

WebStats WebServer::stats() const {
  const Counters& c = impl_->counters;
  return {c.requests.load(),      c.websockets_opened.load(), c.refused_host.load(), c.refused_origin.load(),
          c.refused_token.load(), c.refused_full.load(),      c.not_found.load(),    c.bad_requests.load(),
          c.slow_closed.load(),   c.frames_replaced.load(),   c.messages_sent.load(), c.connections.load(),
          c.sessions.load()};
}

}  // namespace fovea::monitor
