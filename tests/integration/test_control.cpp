// SPDX-License-Identifier: Apache-2.0
// CONTROL_REQUEST / CONTROL_REPLY at the GazeServer: the allow-list decides, refusals are counted
// and never executed, retransmissions are not executed twice, replies never amplify, and a handler
// may reconfigure the server (live limits and allow-list) without dropping a session.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/server.h"

using namespace fovea::protocol;

namespace {

constexpr std::uint32_t kLoopback = 0x7F000001;

ServerOptions options(std::vector<Ipv4Cidr> allow) {
  ServerOptions o;
  o.listen = Endpoint{kLoopback, 0};
  o.nominal_rate_hz = 100;
  o.source_name = "test";
  o.control_allow = std::move(allow);
  return o;
}

// Sends one CONTROL_REQUEST from its own socket and waits for the matching CONTROL_REPLY.
class ControlPeer {
 public:
  explicit ControlPeer(Endpoint server) : server_(server), socket_(UdpSocket::bind(Endpoint{kLoopback, 0})) {}

  std::optional<ControlReply> request(ControlCommand c, const std::string& arg, std::uint64_t seq,
                                      int timeout_ms = 2000) {
    Message m{Header{}, ControlRequest{c, {arg}}};
    m.header.sequence = seq;
    m.header.send_time_ns = m.header.origin_time_ns = monotonic_ns();
    last_request_size_ = encode(m).size();
    socket_.send_to(server_, encode(m));
    const std::int64_t deadline = monotonic_ns() + std::int64_t{timeout_ms} * 1'000'000;
    std::array<std::uint8_t, kMaxDatagramSize + 1> buf{};
    while (monotonic_ns() < deadline) {
      Endpoint from;
      const std::size_t n = socket_.receive(buf, from, 20);
      if (n == 0 || n > kMaxDatagramSize) continue;
      last_reply_size_ = n;
      Message r;
      if (decode(std::span<const std::uint8_t>(buf.data(), n), r) && r.header.type == MessageType::ControlReply &&
          r.header.sequence == seq) {
        return std::get<ControlReply>(r.payload);
      }
    }
    return std::nullopt;
  }
  std::size_t last_request_size_ = 0, last_reply_size_ = 0;

 private:
  Endpoint server_;
  UdpSocket socket_;
};

}  // namespace

TEST(Control, AllowedAddressIsExecuted) {
  GazeServer server(options({parse_cidr("127.0.0.0/8")}));
  std::atomic<int> calls{0};
  server.on_control([&](const ControlRequest& r, const Endpoint& from) {
    ++calls;
    EXPECT_EQ(from.ip, kLoopback);
    ControlReply out{r.command, ControlResult::Ok, {}};
    out.message.value = "recording to " + r.argument.value;
    return out;
  });
  ControlPeer peer(server.local_endpoint());
  const auto reply = peer.request(ControlCommand::StartRecording, "/tmp/x.fgr", 41);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->result, ControlResult::Ok);
  EXPECT_EQ(reply->command, ControlCommand::StartRecording);
  EXPECT_EQ(reply->message.value, "recording to /tmp/x.fgr");
  EXPECT_EQ(calls.load(), 1);
  EXPECT_EQ(server.stats().control_requests, 1u);
  EXPECT_EQ(server.stats().control_refused, 0u);
  EXPECT_LE(peer.last_reply_size_, peer.last_request_size_) << "a control reply must not amplify";
}

TEST(Control, OutsideTheAllowListIsRefusedCountedAndNeverExecuted) {
  GazeServer server(options({parse_cidr("10.0.0.0/8"), parse_cidr("192.168.0.0/16")}));
  std::atomic<int> calls{0};
  server.on_control([&](const ControlRequest& r, const Endpoint&) {
    ++calls;
    return ControlReply{r.command, ControlResult::Ok, {}};
  });
  ControlPeer peer(server.local_endpoint());
  for (std::uint64_t seq = 1; seq <= 3; ++seq) {
    const auto reply = peer.request(ControlCommand::Reload, "", seq);
    ASSERT_TRUE(reply) << "a refused request is still answered (same size, so no amplification)";
    EXPECT_EQ(reply->result, ControlResult::Refused);
    EXPECT_EQ(reply->message.value, "not allowed from 127.0.0.1");
  }
  EXPECT_EQ(calls.load(), 0);
  EXPECT_EQ(server.stats().control_refused, 3u);
  EXPECT_EQ(server.stats().control_requests, 0u);
  EXPECT_EQ(peer.last_reply_size_, peer.last_request_size_);
}

TEST(Control, EmptyAllowListRefusesEveryone) {
  GazeServer server(options({}));
  server.on_control([](const ControlRequest& r, const Endpoint&) {
    return ControlReply{r.command, ControlResult::Ok, {}};
  });
  ControlPeer peer(server.local_endpoint());
  const auto reply = peer.request(ControlCommand::StopRecording, "", 5);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->result, ControlResult::Refused);
  EXPECT_EQ(reply->message.value, "UDP control is off; use the daemon's control socket");
  EXPECT_TRUE(ServerOptions{}.control_allow.empty());  // the default is nobody
}

TEST(Control, NoHandlerFails) {
  GazeServer server(options({parse_cidr("127.0.0.1/32")}));
  ControlPeer peer(server.local_endpoint());
  const auto reply = peer.request(ControlCommand::Reload, "", 9);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->result, ControlResult::Failed);
}

TEST(Control, RetransmissionIsAnsweredNotExecutedAgain) {
  GazeServer server(options({parse_cidr("127.0.0.0/8")}));
  std::atomic<int> calls{0};
  server.on_control([&](const ControlRequest& r, const Endpoint&) {
    ControlReply out{r.command, ControlResult::Ok, {}};
    out.message.value = "call " + std::to_string(++calls);
    return out;
  });
  ControlPeer peer(server.local_endpoint());
  const auto first = peer.request(ControlCommand::Reload, "", 77);
  const auto again = peer.request(ControlCommand::Reload, "", 77);
  const auto next = peer.request(ControlCommand::Reload, "", 78);
  ASSERT_TRUE(first && again && next);
  EXPECT_EQ(first->message.value, "call 1");
  EXPECT_EQ(again->message.value, "call 1");
  EXPECT_EQ(next->message.value, "call 2");
  EXPECT_EQ(calls.load(), 2);
}

TEST(Control, HandlerExceptionBecomesFailed) {
  GazeServer server(options({parse_cidr("127.0.0.0/8")}));
  server.on_control(
      [](const ControlRequest&, const Endpoint&) -> ControlReply { throw std::runtime_error("disk full"); });
  ControlPeer peer(server.local_endpoint());
  const auto reply = peer.request(ControlCommand::StartRecording, "a.fgr", 3);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->result, ControlResult::Failed);
  EXPECT_EQ(reply->message.value, "disk full");
}

TEST(Control, HandlerMayReconfigureTheServerLiveWithoutDroppingSessions) {
  GazeServer server(options({parse_cidr("127.0.0.0/8")}));
  server.on_control([&](const ControlRequest& r, const Endpoint&) {
    // What the daemon does on a reload: new limits and a new allow-list, from the control thread.
    server.set_limits(1000, 1);
    server.set_control_allow({parse_cidr("10.0.0.0/8")});
    server.set_display(parse_display_geometry("800x600@300x200mm,500mm"));
    return ControlReply{r.command, ControlResult::Ok, {}};
  });
  ClientOptions co;
  co.server = server.local_endpoint();
  co.requested_lease_ms = 0;  // take the server's default
  GazeClient client(co);
  client.start();
  ASSERT_TRUE(client.wait_subscribed(2000));
  const std::uint64_t session = client.session()->session_id;

  ControlPeer peer(server.local_endpoint());
  const auto reply = peer.request(ControlCommand::Reload, "", 1);
  ASSERT_TRUE(reply);
  EXPECT_EQ(reply->result, ControlResult::Ok);
  // The new allow-list applies to the next request.
  const auto refused = peer.request(ControlCommand::Reload, "", 2);
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->result, ControlResult::Refused);
  ASSERT_EQ(server.control_allow().size(), 1u);

  // The existing session survives (max_subscribers 1 = this one), keeps streaming and keeps its
  // lease; a second subscriber is refused by the new limit.
  for (int i = 0; i < 20; ++i) {
    server.publish(GazeSample{monotonic_ns(), 0.5f, 0.5f, 0, 0, 0, 1.0f, EyeMovement::Fixation, kGazeValid, {}, {}, {}, {}});
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(700));  // a heartbeat or two
  ASSERT_EQ(server.subscribers().size(), 1u);
  EXPECT_EQ(server.subscribers()[0].session_id, session);
  EXPECT_EQ(server.subscribers()[0].lease_ms, 5000u);
  EXPECT_EQ(client.stats().subscriptions, 1u);
  EXPECT_GE(client.stats().samples.received, 15u);
  EXPECT_EQ(client.stats().samples.lost, 0u);
  const auto status = GazeClient::query_status(server.local_endpoint(), 1000);
  ASSERT_TRUE(status);
  EXPECT_EQ(status->display.width_px, 800u);

  ClientOptions co2 = co;
  GazeClient second(co2);
  second.start();
  EXPECT_FALSE(second.wait_subscribed(600));
  second.stop();
  client.stop();
}
