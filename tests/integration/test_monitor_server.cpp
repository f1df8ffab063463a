// SPDX-License-Identifier: Apache-2.0
// fovea-monitor's server under hostile and slow clients (monitor/web_server.h): a page that is
// connected keeps getting every message while 1,000 connections pile up, while another page stops
// reading (it is closed once it falls behind) and while clients send a giant WebSocket message or
// header (they are closed); eye frames waiting for a slow page are replaced, not queued; beyond
// the connection limit a connection is closed at once, and a slot frees when its holder goes.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>

#include <array>
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "web_server.h"

using namespace fovea::monitor;
namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using tcp = net::ip::tcp;

namespace {

const std::string kToken = "0123456789abcdef0123456789abcdef";

struct Server {
  explicit Server(WebServerOptions o = {}) {
    o.listen_ip = "127.0.0.1";
    o.port = 0;
    o.token = kToken;
    web = std::make_unique<WebServer>(o, std::vector<Asset>{{"/", "text/html", "<p>hi</p>"}},
                                      [] { return std::vector<Outgoing>{}; }, [](WebServer::SessionId, std::string) {});
  }
  std::unique_ptr<WebServer> web;
};

bool wait_for(const std::function<bool()>& done, int ms = 5000) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return done();
}

// A page: a WebSocket with the right Origin and token.
struct Page {
  net::io_context ioc;
  websocket::stream<tcp::socket> ws{ioc};
  explicit Page(std::uint16_t port) {
    ws.next_layer().connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), port));
    ws.set_option(websocket::stream_base::decorator([port](websocket::request_type& r) {
      r.set(beast::http::field::origin, "http://127.0.0.1:" + std::to_string(port));
    }));
    ws.handshake("127.0.0.1:" + std::to_string(port), "/ws?token=" + kToken);
  }
  std::string read() {
    beast::flat_buffer b;
    ws.read(b);
    return beast::buffers_to_string(b.data());
  }
};

Outgoing text(const std::string& s) { return {std::make_shared<const std::string>(s), Outgoing::Kind::Text}; }

}  // namespace

TEST(MonitorServer, APageKeepsItsDataWhileAThousandConnectionsPileUp) {
  rlimit lim{};
  getrlimit(RLIMIT_NOFILE, &lim);
  lim.rlim_cur = std::min<rlim_t>(lim.rlim_max, 4096);
  setrlimit(RLIMIT_NOFILE, &lim);
  const std::size_t hostile = lim.rlim_cur >= 2200 ? 1000 : (lim.rlim_cur - 200) / 2;

  WebServerOptions o;
  o.max_connections = 64;
  o.request_timeout_ms = 1500;
  Server s(o);
  Page page(s.web->port());
  ASSERT_TRUE(wait_for([&] { return s.web->stats().sessions == 1; }));

  net::io_context ioc;
  std::vector<std::unique_ptr<tcp::socket>> flood;
  for (std::size_t i = 0; i < hostile; ++i) {
    auto sock = std::make_unique<tcp::socket>(ioc);
    sock->connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), s.web->port()));
    const std::string partial = "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n";  // never finished (slowloris)
    net::write(*sock, net::buffer(partial));
    flood.push_back(std::move(sock));
  }
  // The page is served all the while, in order and at once.
  for (int k = 0; k < 50; ++k) {
    s.web->broadcast(text("m" + std::to_string(k)));
    EXPECT_EQ(page.read(), "m" + std::to_string(k)) << "at " << k;
  }
  EXPECT_TRUE(wait_for([&] { return s.web->stats().refused_full >= hostile - o.max_connections; }))
      << s.web->stats().refused_full << " refused of " << hostile;
  EXPECT_LE(s.web->stats().connections, o.max_connections);
  // The slowloris connections time out; then a new page gets in.
  EXPECT_TRUE(wait_for([&] { return s.web->stats().connections <= 1; }, 5000)) << s.web->stats().connections;
  Page late(s.web->port());
  ASSERT_TRUE(wait_for([&] { return s.web->stats().sessions == 2; }));
  s.web->broadcast(text("after"));
  EXPECT_EQ(late.read(), "after");
  EXPECT_EQ(page.read(), "after");
}

TEST(MonitorServer, APageThatStopsReadingIsClosedAndTheOthersMissNothing) {
  WebServerOptions o;
  o.max_queue_bytes = 256 * 1024;
  Server s(o);
  Page reader(s.web->port());
  Page stuck(s.web->port());  // never reads
  ASSERT_TRUE(wait_for([&] { return s.web->stats().sessions == 2; }));
  const std::string chunk(8192, 'x');
  std::atomic<int> received{0};
  std::thread consume([&] {
    for (int k = 0; k < 2000; ++k) {
      EXPECT_EQ(reader.read().size(), chunk.size());
      ++received;
    }
  });
  // 16 MB, paced as a live stream is: never more than 8 messages ahead of the page that reads.
  for (int k = 0; k < 2000; ++k) {
    wait_for([&] { return received.load() >= k - 8; });
    s.web->broadcast(text(chunk));
  }
  consume.join();
  EXPECT_TRUE(wait_for([&] { return s.web->stats().slow_closed == 1; })) << s.web->stats().slow_closed;
  EXPECT_TRUE(wait_for([&] { return s.web->stats().sessions == 1; }));
}

TEST(MonitorServer, EyeFramesWaitingForASlowPageAreReplacedNotQueued) {
  WebServerOptions o;
  o.max_queue_bytes = 16u << 20;
  Server s(o);
  Page page(s.web->port());
  ASSERT_TRUE(wait_for([&] { return s.web->stats().sessions == 1; }));
  // A large text first, which the page does not read yet, keeps the frames waiting behind it.
  s.web->broadcast(text(std::string(4 << 20, 't')));
  for (int k = 0; k < 100; ++k) {
    s.web->broadcast({std::make_shared<const std::string>("frame" + std::to_string(k)), Outgoing::Kind::EyeFrame});
  }
  EXPECT_TRUE(wait_for([&] { return s.web->stats().frames_replaced >= 90; })) << s.web->stats().frames_replaced;
  EXPECT_EQ(page.read().size(), std::size_t{4} << 20);
  const std::string frame = page.read();
  EXPECT_TRUE(frame == "frame99" || frame == "frame0") << frame;  // the newest (or the one already on its way)
}

TEST(MonitorServer, GiantMessagesAndHeadersCloseTheirSenderOnly) {
  Server s;
  Page page(s.web->port());
  {
    Page giant(s.web->port());
    ASSERT_TRUE(wait_for([&] { return s.web->stats().sessions == 2; }));
    beast::error_code ec;
    giant.ws.write(net::buffer(std::string(1 << 20, 'g')), ec);  // 1 MB, over the 4 KB a page may send
    beast::flat_buffer b;
    giant.ws.read(b, ec);
    EXPECT_TRUE(ec) << "the server closes it";
  }
  EXPECT_TRUE(wait_for([&] { return s.web->stats().sessions == 1; }));
  net::io_context ioc;
  tcp::socket sock(ioc);
  sock.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), s.web->port()));
  const std::string header = "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: " + std::string(100000, 'h') + "\r\n\r\n";
  beast::error_code ec;
  net::write(sock, net::buffer(header), ec);
  std::string reply(64, '\0');
  const std::size_t n = sock.read_some(net::buffer(reply), ec);
  EXPECT_EQ(reply.substr(0, std::min<std::size_t>(n, 12)), "HTTP/1.1 400");
  s.web->broadcast(text("still here"));
  EXPECT_EQ(page.read(), "still here");
}

TEST(MonitorServer, ResponsesCarryTheSecurityHeaders) {
  Server s;
  net::io_context ioc;
  tcp::socket sock(ioc);
  sock.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), s.web->port()));
  net::write(sock, net::buffer(std::string("GET / HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n")));
  std::string all;
  beast::error_code ec;
  std::array<char, 4096> buf{};
  for (std::size_t n; (n = sock.read_some(net::buffer(buf), ec)) > 0 && !ec;) all.append(buf.data(), n);
  EXPECT_NE(all.find("HTTP/1.1 200"), std::string::npos) << all;
  EXPECT_NE(all.find("Content-Security-Policy: default-src 'none'; script-src 'self'"), std::string::npos);
  EXPECT_NE(all.find("X-Content-Type-Options: nosniff"), std::string::npos);
  EXPECT_NE(all.find("Referrer-Policy: no-referrer"), std::string::npos);
  EXPECT_NE(all.find("<p>hi</p>"), std::string::npos);
}
