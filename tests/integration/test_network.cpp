// SPDX-License-Identifier: Apache-2.0
// GazeServer and GazeClient on loopback: handshake, leases, fan-out, late joiners, restarts.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>

#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/server.h"

using namespace fovea::protocol;
using namespace std::chrono_literals;

namespace {

constexpr std::uint32_t kLoopback = 0x7F000001;

ServerOptions server_options(std::uint16_t port = 0) {
  ServerOptions o;
  o.listen = Endpoint{kLoopback, port};
  o.nominal_rate_hz = 1000;
  o.source_name = "test";
  return o;
}

GazeSample sample_at(std::int64_t t) {
  GazeSample s;
  s.tracker_time_ns = t;
  s.x = 0.5f;
  s.y = 0.5f;
  s.confidence = 1.0f;
  s.flags = kGazeValid;
  s.state = EyeMovement::Fixation;
  return s;
}

// Publishes samples at a fixed rate on its own thread, like the daemon's source loop.
class Publisher {
 public:
  Publisher(GazeServer& server, int rate_hz) : server_(server), period_(1'000'000'000 / rate_hz) {
    thread_ = std::thread([this] {
      std::int64_t next = monotonic_ns();
      while (!stop_) {
        server_.publish(sample_at(monotonic_ns()));
        next += period_;
        std::this_thread::sleep_for(std::chrono::nanoseconds(std::max<std::int64_t>(0, next - monotonic_ns())));
      }
    });
  }
  ~Publisher() {
    stop_ = true;
    thread_.join();
  }

 private:
  GazeServer& server_;
  std::int64_t period_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// A hand-driven peer speaking raw datagrams, to test what a misbehaving client gets.
class RawPeer {
 public:
  explicit RawPeer(Endpoint server, std::uint32_t local_ip = kLoopback)
      : server_(server), socket_(UdpSocket::bind(Endpoint{local_ip, 0})) {}
  void send(Payload p, std::uint64_t seq = 1) {
    Message m{Header{}, std::move(p)};
    m.header.sequence = seq;
    m.header.send_time_ns = m.header.origin_time_ns = monotonic_ns();
    socket_.send_to(server_, encode(m));
  }
  void send_raw(const std::vector<std::uint8_t>& bytes) { socket_.send_to(server_, bytes); }
  // Next message of any type within the timeout.
  std::optional<Message> receive_any(int timeout_ms) {
    const std::int64_t deadline = monotonic_ns() + std::int64_t{timeout_ms} * 1'000'000;
    std::array<std::uint8_t, kMaxDatagramSize + 1> buf{};
    while (monotonic_ns() < deadline) {
      Endpoint from;
      const std::size_t n = socket_.receive(buf, from, 10);
      Message m;
      if (n > 0 && decode(std::span<const std::uint8_t>(buf.data(), n), m)) return m;
    }
    return std::nullopt;
  }
  // Next message of the given type within the timeout; others are skipped.
  std::optional<Message> receive(MessageType type, int timeout_ms) {
    const std::int64_t deadline = monotonic_ns() + std::int64_t{timeout_ms} * 1'000'000;
    std::array<std::uint8_t, kMaxDatagramSize + 1> buf{};
    while (monotonic_ns() < deadline) {
      Endpoint from;
      const std::size_t n = socket_.receive(buf, from, 10);
      if (n == 0) continue;
      Message m;
      if (decode(std::span<const std::uint8_t>(buf.data(), n), m) && m.header.type == type) return m;
    }
    return std::nullopt;
  }
  std::size_t count(MessageType type, int for_ms) {
    std::size_t n = 0;
    const std::int64_t deadline = monotonic_ns() + std::int64_t{for_ms} * 1'000'000;
    while (monotonic_ns() < deadline) {
      if (receive(type, 5)) ++n;
    }
    return n;
  }
  std::optional<Subscribed> handshake(std::uint32_t lease_ms, std::uint32_t streams = kStreamSamples) {
    send(Hello{99, {"raw"}});
    const auto challenge = receive(MessageType::Challenge, 1000);
    if (!challenge) return std::nullopt;
    send(Subscribe{std::get<Challenge>(challenge->payload).cookie, 99, streams, lease_ms});
    const auto sub = receive(MessageType::Subscribed, 1000);
    if (!sub) return std::nullopt;
    return std::get<Subscribed>(sub->payload);
  }
  Endpoint local() const { return socket_.local_endpoint(); }

 private:
  Endpoint server_;
  UdpSocket socket_;
};

ClientOptions client_options(Endpoint server) {
  ClientOptions o;
  o.server = server;
  o.streams = kStreamSamples;
  return o;
}

}  // namespace

TEST(Handshake, SubscribeWithForgedCookieGetsErrorAndNoStream) {
  GazeServer server(server_options());
  Publisher pub(server, 500);
  RawPeer peer(server.local_endpoint());
  Cookie forged{};
  forged.fill(0x5A);
  peer.send(Subscribe{forged, 1, kStreamSamples, 0});
  const auto err = peer.receive(MessageType::Error, 1000);
  ASSERT_TRUE(err);
  EXPECT_EQ(std::get<Error>(err->payload).code, ErrorCode::BadCookie);
  EXPECT_EQ(peer.count(MessageType::GazeSample, 300), 0u);
  EXPECT_TRUE(server.subscribers().empty());
}

TEST(Handshake, CookieIsBoundToTheAddressItWasIssuedTo) {
  GazeServer server(server_options());
  RawPeer alice(server.local_endpoint()), mallory(server.local_endpoint());
  alice.send(Hello{7, {"alice"}});
  const auto challenge = alice.receive(MessageType::Challenge, 1000);
  ASSERT_TRUE(challenge);
  mallory.send(Subscribe{std::get<Challenge>(challenge->payload).cookie, 7, kStreamSamples, 0});
  const auto err = mallory.receive(MessageType::Error, 1000);
  ASSERT_TRUE(err);
  EXPECT_EQ(std::get<Error>(err->payload).code, ErrorCode::BadCookie);
  EXPECT_TRUE(server.subscribers().empty());
}

TEST(Handshake, ValidHandshakeStreamsFromTheAnnouncedSequence) {
  GazeServer server(server_options());
  Publisher pub(server, 500);
  std::this_thread::sleep_for(50ms);
  RawPeer peer(server.local_endpoint());
  const auto sub = peer.handshake(0);
  ASSERT_TRUE(sub);
  EXPECT_EQ(sub->lease_ms, 5000u);
  EXPECT_EQ(sub->display, DisplayGeometry{});
  EXPECT_GT(sub->next_sample_sequence, 0u);
  const auto first = peer.receive(MessageType::GazeSample, 1000);
  ASSERT_TRUE(first);
  EXPECT_EQ(first->header.sequence, sub->next_sample_sequence);
  ASSERT_EQ(server.subscribers().size(), 1u);
  EXPECT_EQ(server.subscribers()[0].address, peer.local());
}

TEST(Leases, SilentSubscriberIsDroppedAfterItsLease) {
  GazeServer server(server_options());
  Publisher pub(server, 500);
  RawPeer peer(server.local_endpoint());
  const auto sub = peer.handshake(300);
  ASSERT_TRUE(sub);
  EXPECT_EQ(sub->lease_ms, 300u);
  EXPECT_GT(peer.count(MessageType::GazeSample, 150), 0u);
  std::this_thread::sleep_for(400ms);
  EXPECT_TRUE(server.subscribers().empty());
  EXPECT_EQ(server.stats().leases_expired, 1u);
  peer.count(MessageType::GazeSample, 50);  // drain what was in flight
  EXPECT_EQ(peer.count(MessageType::GazeSample, 200), 0u) << "a dropped subscriber must get nothing more";
  // Its old session is gone: a heartbeat now is refused.
  peer.send(Heartbeat{sub->session_id, 0});
  const auto err = peer.receive(MessageType::Error, 1000);
  ASSERT_TRUE(err);
  EXPECT_EQ(std::get<Error>(err->payload).code, ErrorCode::UnknownSession);
}

TEST(Leases, HeartbeatsKeepTheSubscriptionAndUnsubscribeEndsIt) {
  GazeServer server(server_options());
  RawPeer peer(server.local_endpoint());
  const auto sub = peer.handshake(300);
  ASSERT_TRUE(sub);
  for (int i = 0; i < 8; ++i) {
    std::this_thread::sleep_for(100ms);
    peer.send(Heartbeat{sub->session_id, 0});
    ASSERT_TRUE(peer.receive(MessageType::Heartbeat, 500)) << "heartbeat " << i << " unanswered";
  }
  EXPECT_EQ(server.subscribers().size(), 1u);
  peer.send(Unsubscribe{sub->session_id});
  std::this_thread::sleep_for(100ms);
  EXPECT_TRUE(server.subscribers().empty());
}

TEST(Leases, HeartbeatFromAnotherAddressIsRefused) {
  GazeServer server(server_options());
  RawPeer peer(server.local_endpoint()), other(server.local_endpoint());
  const auto sub = peer.handshake(0);
  ASSERT_TRUE(sub);
  other.send(Heartbeat{sub->session_id, 0});
  const auto err = other.receive(MessageType::Error, 1000);
  ASSERT_TRUE(err);
  EXPECT_EQ(std::get<Error>(err->payload).code, ErrorCode::AddressMismatch);
}

TEST(Server, RefusesSubscribersBeyondItsLimit) {
  ServerOptions o = server_options();
  o.max_subscribers = 1;
  GazeServer server(o);
  RawPeer a(server.local_endpoint()), b(server.local_endpoint());
  ASSERT_TRUE(a.handshake(0));
  b.send(Hello{5, {"b"}});
  const auto challenge = b.receive(MessageType::Challenge, 1000);
  ASSERT_TRUE(challenge);
  b.send(Subscribe{std::get<Challenge>(challenge->payload).cookie, 5, kStreamSamples, 0});
  const auto err = b.receive(MessageType::Error, 1000);
  ASSERT_TRUE(err);
  EXPECT_EQ(std::get<Error>(err->payload).code, ErrorCode::TooManySubscribers);
}

// A reload that changes the display tells every session at once (PROTOCOL.md §4.5): before, a
// subscriber learnt it only if it happened to subscribe again (a stall of the daemon), so whether a
// running `fovea-ctl record` ended depended on timing (CI's service_daemon failed on it).
TEST(Server, AChangedDisplayIsSentToEverySessionUnaskedAndTheSessionsGoOn) {
  GazeServer server(server_options());
  RawPeer peer(server.local_endpoint());
  const auto sub = peer.handshake(0);
  ASSERT_TRUE(sub);
  GazeClient client(client_options(server.local_endpoint()));
  client.start();
  ASSERT_TRUE(client.wait_subscribed(2000));

  server.set_display(DisplayGeometry{});  // unchanged: nothing is sent
  EXPECT_FALSE(peer.receive(MessageType::Subscribed, 300));

  DisplayGeometry other;
  other.width_px = 1280;
  other.height_px = 1024;
  other.width_m = 0.376;
  server.set_display(other);
  const auto pushed = peer.receive(MessageType::Subscribed, 1000);
  ASSERT_TRUE(pushed);
  EXPECT_EQ(pushed->header.sequence, 0u);
  const auto& s = std::get<Subscribed>(pushed->payload);
  EXPECT_EQ(s.session_id, sub->session_id);
  EXPECT_EQ(s.display, other);
  EXPECT_EQ(s.lease_ms, sub->lease_ms);
  for (int i = 0; i < 100 && !(client.session()->display == other); ++i) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(client.session()->display, other);
  EXPECT_EQ(client.stats().subscriptions, 1u) << "the client kept its session";
  EXPECT_EQ(server.subscribers().size(), 2u);
  client.stop();
}

// Issue 23 item 4: 256 SUBSCRIBEs asking for 10-minute leases from one process locked every other
// client out for 10 minutes. Now one address holds at most max_subscribers_per_address sessions,
// another address still gets in, leases are capped at a minute, and the client knows why it was
// refused.
TEST(Server, OneAddressCannotTakeTheWholeTable) {
  ServerOptions o = server_options();
  o.max_subscribers_per_address = 4;
  GazeServer server(o);
  std::vector<std::unique_ptr<RawPeer>> flood;
  for (int i = 0; i < 4; ++i) {
    flood.push_back(std::make_unique<RawPeer>(server.local_endpoint()));
    const auto s = flood.back()->handshake(600'000);
    ASSERT_TRUE(s) << i;
    EXPECT_EQ(s->lease_ms, 60'000u) << "a 10-minute lease is capped at a minute";
  }
  RawPeer fifth(server.local_endpoint());
  fifth.send(Hello{5, {"fifth"}});
  const auto challenge = fifth.receive(MessageType::Challenge, 1000);
  ASSERT_TRUE(challenge);
  fifth.send(Subscribe{std::get<Challenge>(challenge->payload).cookie, 5, kStreamSamples, 0});
  const auto err = fifth.receive(MessageType::Error, 1000);
  ASSERT_TRUE(err);
  EXPECT_EQ(std::get<Error>(err->payload).code, ErrorCode::TooManySubscribers);
  RawPeer elsewhere(server.local_endpoint(), 0x7F000002);  // 127.0.0.2: another address
  EXPECT_TRUE(elsewhere.handshake(0));
  // The reference client says why (fovea-ctl watch printed "no answer ... is it running?").
  ClientOptions co = client_options(server.local_endpoint());
  GazeClient refused(co);
  refused.start();
  EXPECT_FALSE(refused.wait_subscribed(1500));
  EXPECT_EQ(refused.stats().last_error, ErrorCode::TooManySubscribers);
}

TEST(Server, AnswersOtherVersionsWithItsOwnAndIgnoresGarbage) {
  GazeServer server(server_options());
  RawPeer peer(server.local_endpoint());
  Message hello{Header{}, Hello{1, {"v2 client"}}};
  auto bytes = encode(hello);
  bytes[4] = 2;
  peer.send_raw(bytes);
  const auto err = peer.receive(MessageType::Error, 1000);
  ASSERT_TRUE(err);
  EXPECT_EQ(std::get<Error>(err->payload).code, ErrorCode::UnsupportedVersion);
  EXPECT_EQ(std::get<Error>(err->payload).supported_version, kVersion);

  peer.send_raw({1, 2, 3});
  peer.send_raw(std::vector<std::uint8_t>(600, 0xAB));
  auto sample = encode(Message{Header{}, sample_at(1)});
  peer.send_raw(sample);  // well-formed but a server never accepts samples
  EXPECT_EQ(peer.count(MessageType::Error, 200), 0u);
  EXPECT_EQ(server.stats().datagrams_rejected, 3u);
  EXPECT_EQ(server.stats().unexpected_messages, 1u);
  EXPECT_EQ(server.decode_counters().get(DecodeError::TooShort), 1u);
  EXPECT_EQ(server.decode_counters().get(DecodeError::TooLong), 1u);
}

TEST(Fanout, ThreeClientsReceiveTheIdenticalSequence) {
  GazeServer server(server_options());
  // Declared before the clients so they outlive the callbacks that write to them.
  std::vector<std::vector<std::pair<std::uint64_t, std::int64_t>>> got(3);
  std::mutex mu;
  std::vector<std::unique_ptr<GazeClient>> clients;
  for (int i = 0; i < 3; ++i) {
    clients.push_back(std::make_unique<GazeClient>(client_options(server.local_endpoint())));
    clients.back()->on_sample([&, i](const GazeSample& s, const Arrival& a) {
      std::lock_guard lock(mu);
      got[static_cast<std::size_t>(i)].emplace_back(a.sequence, s.tracker_time_ns);
    });
    clients.back()->start();
  }
  for (auto& c : clients) ASSERT_TRUE(c->wait_subscribed(2000));
  {
    Publisher pub(server, 1000);
    std::this_thread::sleep_for(500ms);
  }
  std::this_thread::sleep_for(100ms);
  std::lock_guard lock(mu);
  ASSERT_GT(got[0].size(), 300u);
  EXPECT_EQ(got[0], got[1]);
  EXPECT_EQ(got[0], got[2]);
  for (auto& c : clients) {
    const auto st = c->stats();
    EXPECT_EQ(st.samples.lost, 0u);
    EXPECT_EQ(st.samples.duplicated, 0u);
  }
}

TEST(Fanout, LateJoinerSeesConsecutiveSequenceNumbersFromItsJoin) {
  GazeServer server(server_options());
  Publisher pub(server, 1000);
  std::this_thread::sleep_for(200ms);
  std::vector<std::uint64_t> seqs;
  std::mutex mu;
  GazeClient late(client_options(server.local_endpoint()));
  late.on_sample([&](const GazeSample&, const Arrival& a) {
    std::lock_guard lock(mu);
    seqs.push_back(a.sequence);
  });
  late.start();
  ASSERT_TRUE(late.wait_subscribed(2000));
  const std::uint64_t join = late.session()->next_sample_sequence;
  EXPECT_GT(join, 100u);
  std::this_thread::sleep_for(300ms);
  std::lock_guard lock(mu);
  ASSERT_GT(seqs.size(), 100u);
  EXPECT_EQ(seqs.front(), join);
  for (std::size_t i = 1; i < seqs.size(); ++i) ASSERT_EQ(seqs[i], seqs[i - 1] + 1) << "at " << i;
}

TEST(Restart, ClientsResubscribeWithinTwoSecondsAfterTheDaemonRestarts) {
  auto server = std::make_unique<GazeServer>(server_options());
  const Endpoint where = server->local_endpoint();
  std::vector<std::unique_ptr<GazeClient>> clients;
  for (int i = 0; i < 3; ++i) {
    clients.push_back(std::make_unique<GazeClient>(client_options(where)));
    clients.back()->start();
  }
  for (auto& c : clients) ASSERT_TRUE(c->wait_subscribed(2000));
  std::optional<Publisher> pub;
  pub.emplace(*server, 500);
  std::this_thread::sleep_for(200ms);
  pub.reset();
  server.reset();  // the daemon goes away...
  std::this_thread::sleep_for(300ms);
  server = std::make_unique<GazeServer>(server_options(where.port));  // ...and comes back
  pub.emplace(*server, 500);
  const std::int64_t restarted = monotonic_ns();
  for (auto& c : clients) {
    while (c->stats().subscriptions < 2 && monotonic_ns() - restarted < 3'000'000'000) std::this_thread::sleep_for(5ms);
    const double took_s = static_cast<double>(monotonic_ns() - restarted) / 1e9;
    EXPECT_EQ(c->stats().subscriptions, 2u);
    EXPECT_LT(took_s, 2.0) << "resubscription took " << took_s << " s";
  }
  std::this_thread::sleep_for(200ms);
  EXPECT_EQ(server->subscribers().size(), 3u);
  for (auto& c : clients) {
    const auto st = c->stats();
    EXPECT_GT(st.samples.received, 150u);
    EXPECT_EQ(st.samples.duplicated, 0u);
  }
}

TEST(Client, StatusQueryAndClockSyncOnLoopback) {
  GazeServer server(server_options());
  Publisher pub(server, 1000);
  const auto status = GazeClient::query_status(server.local_endpoint(), 1000);
  ASSERT_TRUE(status);
  EXPECT_EQ(status->source.value, "test");
  EXPECT_DOUBLE_EQ(status->nominal_rate_hz, 1000.0);
  GazeClient c(client_options(server.local_endpoint()));
  c.start();
  ASSERT_TRUE(c.wait_subscribed(2000));
  std::this_thread::sleep_for(400ms);
  const auto st = c.stats();
  EXPECT_GE(st.clock_round_trip_ns, 0);
  // One clock on loopback: the offset is 0 within its exchange's bound, half the round trip (1 ms
  // when that was short; a loaded host stretches it).
  EXPECT_LE(std::abs(st.clock_offset_ns), std::max<std::int64_t>(1'000'000, st.clock_round_trip_ns / 2 + 1000))
      << "same clock on loopback: offset should be ~0";
  EXPECT_GT(st.latency_count, 100u);
  EXPECT_GE(st.latency_p50_ns, 0);
  std::vector<std::pair<GazeSample, Arrival>> polled;
  EXPECT_GT(c.poll(polled), 100u);
  EXPECT_TRUE(c.latest_sample().has_value());
}

TEST(Client, ASampleCarriesTheDaemonsReceiveTimeBesideTheTrackersTime) {
  GazeServer server(server_options());
  GazeClient c(client_options(server.local_endpoint()));
  std::mutex mutex;
  std::vector<std::pair<GazeSample, Arrival>> got;
  c.on_sample([&](const GazeSample& s, const Arrival& a) {
    std::lock_guard lock(mutex);
    got.emplace_back(s, a);
  });
  c.start();
  ASSERT_TRUE(c.wait_subscribed(2000));
  server.publish(sample_at(1'000'000'000), 1'015'000'000);  // a bridged tracker's sample, 15 ms on the way
  server.publish(sample_at(1'020'000'000));                 // a source without a clock of its own
  for (int i = 0; i < 100; ++i) {
    {
      std::lock_guard lock(mutex);
      if (got.size() == 2) break;
    }
    std::this_thread::sleep_for(10ms);
  }
  std::lock_guard lock(mutex);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].first.tracker_time_ns, 1'000'000'000);
  EXPECT_EQ(got[0].second.host_receive_ns, 1'015'000'000);
  EXPECT_EQ(got[1].second.host_receive_ns, got[1].first.tracker_time_ns);
}

TEST(Client, StatusQueryTimesOutWhenNobodyListens) {
  UdpSocket placeholder = UdpSocket::bind(Endpoint{kLoopback, 0});  // a port with no daemon behind it
  const Endpoint nobody = placeholder.local_endpoint();
  EXPECT_FALSE(GazeClient::query_status(nobody, 300));
}

namespace {

// A server publishing to a loopback multicast group and a client of it (not started). `client` is
// null, and `unavailable` says why, where this host has no multicast (the test then skips).
struct MulticastRig {
  Endpoint group;
  std::unique_ptr<GazeServer> server;
  std::unique_ptr<GazeClient> client;
  std::string unavailable;
};
MulticastRig multicast_rig(std::uint32_t group_ip, int port_salt) {
  MulticastRig r;
  r.group = Endpoint{group_ip, static_cast<std::uint16_t>(40000 + ((getpid() + port_salt) % 20000))};
  ServerOptions o = server_options();
  o.multicast = MulticastTarget{r.group, 0, kLoopback};
  r.server = std::make_unique<GazeServer>(o);
  ClientOptions co = client_options(r.server->local_endpoint());
  co.multicast_group = r.group;
  co.multicast_interface_ip = kLoopback;
  try {
    r.client = std::make_unique<GazeClient>(co);
  } catch (const std::system_error& e) {
    r.unavailable = e.what();
  }
  return r;
}

}  // namespace

TEST(Multicast, ClientReceivesSamplesFromTheGroup) {
  MulticastRig rig = multicast_rig(0xEFFF2F50, 0);
  if (!rig.client) GTEST_SKIP() << "multicast not available here: " << rig.unavailable;
  GazeServer& server = *rig.server;
  GazeClient* c = rig.client.get();
  c->start();
  ASSERT_TRUE(c->wait_subscribed(2000));
  EXPECT_EQ(c->session()->multicast.group_ipv4, 0xEFFF2F50u);
  Publisher pub(server, 500);
  std::this_thread::sleep_for(400ms);
  EXPECT_GT(c->stats().samples.received, 100u);
  EXPECT_EQ(c->stats().samples.duplicated, 0u) << "samples must not arrive twice (unicast and group)";
}

// Issue 23 item 5: on multicast only the source address is checked, so any local process can send
// the group a GAZE_SAMPLE. One with sequence 2^63 made the client drop every later sample as old,
// never resubscribe, and report lost = 2^63 - 100. Now it is counted as implausible and ignored.
TEST(Multicast, ASpoofedHugeSequenceNumberDoesNotBlackholeTheClient) {
  MulticastRig rig = multicast_rig(0xEFFF2F51, 7);
  if (!rig.client) GTEST_SKIP() << "multicast not available here: " << rig.unavailable;
  GazeServer& server = *rig.server;
  GazeClient* c = rig.client.get();
  const Endpoint group = rig.group;
  c->start();
  ASSERT_TRUE(c->wait_subscribed(2000));
  Publisher pub(server, 500);
  std::this_thread::sleep_for(200ms);
  const UdpSocket attacker = UdpSocket::bind(Endpoint{kLoopback, 0});
  attacker.set_multicast_output(0, kLoopback, true);
  Message forged{Header{}, sample_at(1)};
  forged.header.sequence = std::uint64_t{1} << 63;
  const std::vector<std::uint8_t> bytes = encode(forged);
  ASSERT_TRUE(attacker.send_to(group, bytes));
  std::this_thread::sleep_for(100ms);
  const std::uint64_t before = c->stats().samples.received;
  std::this_thread::sleep_for(400ms);
  const ClientStats st = c->stats();
  EXPECT_GT(st.samples.received, before + 100) << "samples after the forged one were dropped";
  EXPECT_EQ(st.samples.implausible, 1u);
  EXPECT_LT(st.samples.lost, 50u);
}

// A hand-driven server: completes the handshake, then answers every TIME_SYNC with `answer`.
class FakeTimeServer {
 public:
  using Answer = std::function<std::vector<TimeSyncReply>(const TimeSyncRequest&)>;
  explicit FakeTimeServer(Answer answer) : socket_(UdpSocket::bind(Endpoint{kLoopback, 0})), answer_(std::move(answer)) {
    thread_ = std::thread([this] { loop(); });
  }
  ~FakeTimeServer() {
    stop_ = true;
    thread_.join();
  }
  Endpoint endpoint() const { return socket_.local_endpoint(); }

 private:
  void reply(const Endpoint& to, std::uint64_t seq, Payload p) {
    Message m{Header{}, std::move(p)};
    m.header.sequence = seq;
    m.header.send_time_ns = m.header.origin_time_ns = monotonic_ns();
    socket_.send_to(to, encode(m));
  }
  void loop() {
    std::array<std::uint8_t, kMaxDatagramSize + 1> buf{};
    while (!stop_) {
      Endpoint from;
      const std::size_t n = socket_.receive(buf, from, 10);
      Message m;
      if (n == 0 || !decode(std::span<const std::uint8_t>(buf.data(), n), m)) continue;
      const std::uint64_t seq = m.header.sequence;
      if (const auto* h = std::get_if<Hello>(&m.payload)) reply(from, seq, Challenge{h->client_nonce, {}, 10000});
      if (std::holds_alternative<Subscribe>(m.payload)) {
        Subscribed s;
        s.session_id = 42;
        s.streams = kStreamSamples;
        s.lease_ms = 5000;
        s.nominal_rate_hz = 250;
        reply(from, seq, s);
      }
      if (const auto* t = std::get_if<TimeSyncRequest>(&m.payload)) {
        for (const TimeSyncReply& r : answer_(*t)) reply(from, seq, r);
      }
    }
  }
  UdpSocket socket_;
  Answer answer_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// Issue 23 item 12: one TIME_SYNC reply could set an absurd clock offset, and times near +-2^63
// wrapped in the arithmetic. Replies to requests never sent, times beyond +-2^60 and impossible
// round trips are dropped, and one bad exchange among honest ones cannot move the median.
TEST(Client, TimeSyncSurvivesAbsurdAndUnsolicitedReplies) {
  constexpr std::int64_t kTrueOffset = 5'000'000;  // the fake server's clock runs 5 ms ahead
  std::atomic<int> count{0};
  FakeTimeServer server([&](const TimeSyncRequest& t) {
    const std::int64_t now = monotonic_ns() + kTrueOffset;
    std::vector<TimeSyncReply> out{{t.client_send_ns, now, now}};
    switch (count++ % 4) {
      case 1: out.push_back({t.client_send_ns + 1, 0, 0}); break;  // answers a request never sent
      case 2: out.push_back({t.client_send_ns, INT64_MAX, INT64_MIN}); break;  // wraps if computed naively
      case 3: out[0] = {t.client_send_ns, now + 3'600'000'000'000, now + 3'600'000'000'000}; break;  // one hour off
      default: break;
    }
    return out;
  });
  ClientOptions co = client_options(server.endpoint());
  GazeClient c(co);
  c.start();
  ASSERT_TRUE(c.wait_subscribed(2000));
  std::this_thread::sleep_for(std::chrono::milliseconds(400));  // the first syncs come 50 ms apart
  const ClientStats st = c.stats();
  EXPECT_GE(count.load(), 4);
  EXPECT_NEAR(static_cast<double>(st.clock_offset_ns), static_cast<double>(kTrueOffset), 2e6)
      << "one bad exchange in four moved the offset";
  EXPECT_GE(st.clock_round_trip_ns, 0);
  EXPECT_GE(st.rejected, 2u);
}

TEST(Client, CompletesTheHandshakeWhenTheRoundTripExceedsTheRetryInterval) {
  // A slow "daemon" that answers each request only after 500 ms (a retry interval is 200 ms).
  UdpSocket fake = UdpSocket::bind(Endpoint{kLoopback, 0});
  GazeClient c(client_options(fake.local_endpoint()));
  c.start();
  std::array<std::uint8_t, kMaxDatagramSize + 1> buf{};
  const auto next_request = [&](MessageType type, Endpoint& from) -> std::optional<Message> {
    const std::int64_t deadline = monotonic_ns() + 3'000'000'000;
    while (monotonic_ns() < deadline) {
      const std::size_t n = fake.receive(buf, from, 20);
      Message m;
      if (n > 0 && decode(std::span<const std::uint8_t>(buf.data(), n), m) && m.header.type == type) return m;
    }
    return std::nullopt;
  };
  Endpoint client_addr;
  const auto hello = next_request(MessageType::Hello, client_addr);
  ASSERT_TRUE(hello);
  std::this_thread::sleep_for(500ms);  // the client has retransmitted HELLO twice meanwhile
  const CookieJar jar(10'000);
  const std::uint64_t nonce = std::get<Hello>(hello->payload).client_nonce;
  fake.send_to(client_addr, encode(Message{Header{}, Challenge{nonce, jar.issue(client_addr, nonce, monotonic_ns()),
                                                               10'000}}));
  const auto subscribe = next_request(MessageType::Subscribe, client_addr);
  ASSERT_TRUE(subscribe) << "the late CHALLENGE was ignored";
  EXPECT_EQ(std::get<Subscribe>(subscribe->payload).client_nonce, nonce);
  std::this_thread::sleep_for(500ms);
  Subscribed s;
  s.session_id = 42;
  s.streams = kStreamSamples;
  s.lease_ms = 5000;
  fake.send_to(client_addr, encode(Message{Header{}, s}));
  EXPECT_TRUE(c.wait_subscribed(1000));
}

TEST(Client, BacksOffWhenTheDaemonIsFull) {
  ServerOptions o = server_options();
  o.max_subscribers = 1;
  GazeServer server(o);
  GazeClient first(client_options(server.local_endpoint()));
  first.start();
  ASSERT_TRUE(first.wait_subscribed(2000));
  GazeClient second(client_options(server.local_endpoint()));
  second.start();
  std::this_thread::sleep_for(1500ms);
  // Without back-off the second client would be refused every 200 ms (7 times in 1.5 s).
  EXPECT_LE(server.stats().requests_refused, 2u);
  EXPECT_FALSE(second.subscribed());
  first.stop();  // a slot frees up: the second one gets in after its back-off
  EXPECT_TRUE(second.wait_subscribed(3000));
}

// ---- MARKER (PROTOCOL.md §4.17) ------------------------------------------------------------------

namespace {
Marker marker_from(std::uint64_t session, std::uint64_t id, const std::string& label) {
  Marker m;
  m.session_id = session;
  m.marker_id = id;
  m.label.value = label;
  return m;
}

// Collects what the server hands its marker handler (the daemon records these).
struct MarkerLog {
  std::mutex mutex;
  std::vector<std::pair<Marker, std::uint64_t>> seen;
  void attach(GazeServer& server) {
    server.on_marker([this](const Marker& m, std::uint64_t seq) {
      std::lock_guard lock(mutex);
      seen.emplace_back(m, seq);
    });
  }
  std::size_t size() {
    std::lock_guard lock(mutex);
    return seen.size();
  }
  // The server tells the handler after it sent the marker: a subscriber may have it first.
  std::size_t size_within(int timeout_ms, std::size_t want) {
    for (int i = 0; i < timeout_ms / 5 && size() < want; ++i) std::this_thread::sleep_for(5ms);
    return size();
  }
};

// A server whose markers are logged, and two raw peers: the first subscribed to markers.
struct MarkerRig {
  explicit MarkerRig(ServerOptions o = server_options()) : server(std::move(o)) { log.attach(server); }
  GazeServer server;
  MarkerLog log;
  RawPeer first{server.local_endpoint()}, second{server.local_endpoint()};
  std::optional<Subscribed> first_session = first.handshake(0, kStreamMarkers);
};
}  // namespace

TEST(Markers, ReachMarkerSubscribersOnlyWithTheSenderSessionHidden) {
  GazeServer server(server_options());
  MarkerLog log;
  log.attach(server);
  ClientOptions with = client_options(server.local_endpoint());
  with.streams = kStreamSamples | kStreamMarkers;
  GazeClient sender(with), without(client_options(server.local_endpoint()));
  std::atomic<int> seen_without{0};
  without.on_marker([&](const Marker&, const Arrival&) { ++seen_without; });
  sender.start();
  without.start();
  RawPeer watcher(server.local_endpoint());
  ASSERT_TRUE(watcher.handshake(0, kStreamMarkers));
  ASSERT_TRUE(sender.wait_subscribed(2000));
  ASSERT_TRUE(without.wait_subscribed(2000));

  const std::int64_t before = monotonic_ns();
  const std::uint64_t id = sender.mark("trial 1: stimulus on");
  const auto copy = sender.wait_marker(id, 2000);
  ASSERT_TRUE(copy) << "the sender's copy never came back";
  EXPECT_EQ(copy->session_id, 0u) << "a session id was disclosed";
  EXPECT_EQ(copy->label.value, "trial 1: stimulus on");
  EXPECT_EQ(copy->flags, 0);
  EXPECT_EQ(copy->time_ns, copy->received_ns) << "without a time of its own, the marker takes the receive time";
  EXPECT_GE(copy->received_ns, before);

  const auto at_watcher = watcher.receive(MessageType::Marker, 1000);
  ASSERT_TRUE(at_watcher);
  EXPECT_EQ(std::get<Marker>(at_watcher->payload), *copy);
  EXPECT_EQ(at_watcher->header.origin_time_ns, copy->time_ns);
  ASSERT_EQ(log.size_within(1000, 1), 1u);
  EXPECT_EQ(log.seen[0].first, *copy);
  EXPECT_EQ(log.seen[0].second, at_watcher->header.sequence);
  std::this_thread::sleep_for(200ms);
  EXPECT_EQ(seen_without.load(), 0) << "a client that did not ask for markers received one";
  const auto st = sender.stats();
  EXPECT_EQ(st.markers_sent, 1u);
  EXPECT_EQ(st.markers_confirmed, 1u);
  EXPECT_EQ(st.markers.received, 1u);
  EXPECT_EQ(server.stats().markers_published, 1u);
}

TEST(Markers, StrangersAndOtherAddressesGetASmallErrorAndPublishNothing) {
  MarkerRig rig;
  auto& [server, log, owner, stranger, sub] = rig;
  ASSERT_TRUE(sub);
  stranger.send(marker_from(0x1234, 1, "forged"));
  auto err = stranger.receive(MessageType::Error, 1000);
  ASSERT_TRUE(err);
  EXPECT_EQ(std::get<Error>(err->payload).code, ErrorCode::UnknownSession);
  EXPECT_EQ(std::get<Error>(err->payload).request_type, MessageType::Marker);
  stranger.send(marker_from(sub->session_id, 2, "forged with a real session"));
  err = stranger.receive(MessageType::Error, 1000);
  ASSERT_TRUE(err);
  EXPECT_EQ(std::get<Error>(err->payload).code, ErrorCode::AddressMismatch);
  EXPECT_LT(kHeaderSize + payload_size(MessageType::Error), kHeaderSize + payload_size(MessageType::Marker))
      << "a refusal must be smaller than the marker that caused it";
  EXPECT_EQ(owner.count(MessageType::Marker, 200), 0u);
  EXPECT_EQ(log.size(), 0u);
  EXPECT_EQ(server.stats().markers_refused, 2u);
}

TEST(Markers, ARetransmissionIsPublishedOnceAndItsCopySentAgainToTheSenderAlone) {
  MarkerRig rig;
  auto& [server, log, sender, other, sub] = rig;
  ASSERT_TRUE(sub);
  ASSERT_TRUE(other.handshake(0, kStreamMarkers));
  sender.send(marker_from(sub->session_id, 77, "key press"), 10);
  const auto first = sender.receive(MessageType::Marker, 1000);
  ASSERT_TRUE(first);
  sender.send(marker_from(sub->session_id, 77, "key press"), 11);  // its copy "was lost"
  const auto again = sender.receive(MessageType::Marker, 1000);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->header.sequence, first->header.sequence);
  EXPECT_EQ(std::get<Marker>(again->payload), std::get<Marker>(first->payload));
  EXPECT_EQ(other.count(MessageType::Marker, 300), 1u) << "others must see it once";
  EXPECT_EQ(log.size(), 1u);
  EXPECT_EQ(server.stats().markers_repeated, 1u);
}

TEST(Markers, ASessionBeyondItsRateIsRefusedWithRateLimited) {
  ServerOptions o = server_options();
  o.marker_rate_per_s = 5;
  MarkerRig rig(o);
  auto& [server, log, sender, unused, sub] = rig;
  ASSERT_TRUE(sub);
  for (std::uint64_t id = 1; id <= 10; ++id) sender.send(marker_from(sub->session_id, id, "m"), id);
  std::size_t published = 0, limited = 0;
  const std::int64_t deadline = monotonic_ns() + 500'000'000;
  while (monotonic_ns() < deadline) {
    const auto m = sender.receive_any(5);
    if (!m) continue;
    if (m->header.type == MessageType::Marker) ++published;
    if (m->header.type == MessageType::Error && std::get<Error>(m->payload).code == ErrorCode::RateLimited) ++limited;
  }
  // 10 arrive within a few ms: the bucket of 5 (plus at most one refilled token) passes.
  EXPECT_GE(published, 5u);
  EXPECT_LE(published, 6u);
  EXPECT_EQ(published + limited, 10u);
}

TEST(Markers, ASendersOwnTimeIsMappedAndAnImplausibleOneRefused) {
  GazeServer server(server_options());
  ClientOptions co = client_options(server.local_endpoint());
  co.streams = kStreamMarkers;
  GazeClient client(co);
  EXPECT_THROW(client.mark("too early"), std::logic_error);  // not subscribed yet
  client.start();
  ASSERT_TRUE(client.wait_subscribed(2000));
  for (int i = 0; i < 100 && client.clock_exchanges() < GazeClient::kClockBurst; ++i) std::this_thread::sleep_for(10ms);
  ASSERT_TRUE(client.clock_known());
  EXPECT_GE(client.clock_exchanges(), GazeClient::kClockBurst) << "the first exchanges come 50 ms apart";
  const std::int64_t flip = monotonic_ns() - 5'000'000;  // 5 ms ago on this (the same) clock
  const auto copy = client.wait_marker(client.mark("flip", flip), 2000);
  ASSERT_TRUE(copy);
  EXPECT_EQ(copy->flags, kMarkerClientTime);
  // Loopback shares one clock, so the mapping is the identity up to the offset's error, which NTP's
  // exchange bounds by half its round trip (a loaded host stretches that past 1 ms at times).
  const std::int64_t bound = std::max<std::int64_t>(1'000'000, client.stats().clock_round_trip_ns / 2 + 1000);
  EXPECT_LE(std::llabs(copy->time_ns - flip), bound) << "loopback shares one clock: the mapping is ~identity";
  EXPECT_GE(copy->received_ns - copy->time_ns, 4'000'000);

  EXPECT_THROW(client.mark(""), std::invalid_argument);
  EXPECT_THROW(client.mark("tab\there"), std::invalid_argument);
  EXPECT_THROW(client.mark(std::string(64, 'x')), std::invalid_argument);
  EXPECT_THROW(client.mark("\xff\xfe"), std::invalid_argument);

  RawPeer raw(server.local_endpoint());
  const auto sub = raw.handshake(0, kStreamMarkers);
  ASSERT_TRUE(sub);
  Marker late = marker_from(sub->session_id, 5, "an hour off");
  late.flags = kMarkerClientTime;
  late.time_ns = monotonic_ns() + 3'600'000'000'000;
  raw.send(late);
  const auto err = raw.receive(MessageType::Error, 1000);
  ASSERT_TRUE(err);
  EXPECT_EQ(std::get<Error>(err->payload).code, ErrorCode::BadRequest);
}

TEST(Markers, AMarkerSentWhileTheDaemonRestartsArrivesOnceAfterwards) {
  auto server = std::make_unique<GazeServer>(server_options());
  const Endpoint where = server->local_endpoint();
  ClientOptions co = client_options(where);
  co.streams = kStreamMarkers;
  co.heartbeat_interval_ms = 100;
  GazeClient client(co);
  client.start();
  ASSERT_TRUE(client.wait_subscribed(2000));
  server.reset();  // the daemon goes away; the client does not know yet
  const std::uint64_t id = client.mark("trial 2");
  std::this_thread::sleep_for(300ms);
  server = std::make_unique<GazeServer>(server_options(where.port));
  MarkerLog log;
  log.attach(*server);
  const auto copy = client.wait_marker(id, 3000);
  ASSERT_TRUE(copy) << "the marker was lost across the restart";
  EXPECT_EQ(copy->label.value, "trial 2");
  std::this_thread::sleep_for(600ms);  // later resends, if any, must not publish it twice
  EXPECT_EQ(log.size(), 1u);
  EXPECT_EQ(client.stats().markers_confirmed, 1u);
  EXPECT_EQ(client.stats().markers_unconfirmed, 0u);
}

// Issue 25: provisional events and their retractions go only to subscribers of the provisional
// stream, on a counter of their own, so the final event stream of everyone else stays gap-free.
TEST(ProvisionalEvents, ReachOnlyTheirSubscribersOnTheirOwnCounter) {
  GazeServer server(server_options());
  ClientOptions with = client_options(server.local_endpoint());
  with.streams = kStreamEvents | kStreamProvisional;
  ClientOptions without = client_options(server.local_endpoint());
  without.streams = kStreamEvents;
  struct Seen {
    std::mutex mu;
    std::vector<std::pair<std::uint8_t, std::uint64_t>> events;  // flags, sequence
  } seen_with, seen_without;
  GazeClient a(with), b(without);
  for (auto [client, seen] : {std::pair{&a, &seen_with}, std::pair{&b, &seen_without}}) {
    client->on_event([seen](const GazeEvent& e, const Arrival& arrival) {
      std::lock_guard lock(seen->mu);
      seen->events.emplace_back(e.flags, arrival.sequence);
    });
    client->start();
  }
  ASSERT_TRUE(a.wait_subscribed(2000));
  ASSERT_TRUE(b.wait_subscribed(2000));

  GazeEvent e;
  e.kind = EyeMovement::Saccade;
  e.start_time_ns = monotonic_ns();
  for (int i = 0; i < 10; ++i) {
    e.flags = i % 3 == 1 ? kEventProvisional : i % 3 == 2 ? kEventProvisional | kEventRetracted : 0;
    server.publish(e);
  }
  for (int i = 0; i < 200 && (a.stats().events.received + a.stats().provisional.received < 10 ||
                              b.stats().events.received < 4);
       ++i) {
    std::this_thread::sleep_for(5ms);
  }
  std::lock_guard la(seen_with.mu), lb(seen_without.mu);
  ASSERT_EQ(seen_with.events.size(), 10u);
  ASSERT_EQ(seen_without.events.size(), 4u) << "only the final events (flags 0)";
  std::uint64_t next_final = seen_with.events.front().second, next_provisional = 0;
  bool first_provisional = true;
  for (const auto& [flags, seq] : seen_with.events) {
    if (flags == 0) {
      EXPECT_EQ(seq, next_final++) << "the final stream's counter skips nothing";
    } else {
      if (first_provisional) next_provisional = seq, first_provisional = false;
      EXPECT_EQ(seq, next_provisional++) << "the provisional stream counts on its own";
    }
  }
  for (const auto& [flags, seq] : seen_without.events) EXPECT_EQ(flags, 0);
  EXPECT_EQ(a.stats().events.lost, 0u);
  EXPECT_EQ(a.stats().provisional.lost, 0u);
  EXPECT_EQ(a.stats().provisional.received, 6u);
  EXPECT_EQ(b.stats().events.lost, 0u);
  EXPECT_EQ(b.stats().provisional.received, 0u);
}

// Issue 42 (stereo with per-eye gaze): GAZE_EYES goes only to subscribers of the eye stream, just
// before its sample; their samples arrive with both eyes joined, everyone else's as before, and the
// sample stream's numbering is the same for both (GAZE_EYES takes no sequence of its own).
TEST(EyeStream, JoinsEachEyesGazeToItsSampleForItsSubscribersOnly) {
  GazeServer server(server_options());
  ClientOptions with = client_options(server.local_endpoint());
  with.streams = kStreamSamples | kStreamEyes;
  ClientOptions without = client_options(server.local_endpoint());
  without.streams = kStreamSamples;
  struct Seen {
    std::mutex mu;
    std::vector<std::pair<GazeSample, std::uint64_t>> samples;
  } seen_with, seen_without;
  GazeClient a(with), b(without);
  for (auto [client, seen] : {std::pair{&a, &seen_with}, std::pair{&b, &seen_without}}) {
    client->on_sample([seen](const GazeSample& s, const Arrival& arrival) {
      std::lock_guard lock(seen->mu);
      seen->samples.emplace_back(s, arrival.sequence);
    });
    client->start();
  }
  ASSERT_TRUE(a.wait_subscribed(2000));
  ASSERT_TRUE(b.wait_subscribed(2000));

  // Samples 0, 2, 4 are binocular; 1 and 3 come from a moment the tracker saw one eye or none.
  for (int i = 0; i < 5; ++i) {
    GazeSample s;
    s.tracker_time_ns = monotonic_ns() + i;
    s.x = 0.5f, s.y = 0.5f, s.flags = kGazeValid;
    if (i % 2 == 0) {
      s.left_gaze = EyeGaze{kEyeGazeValid, 0.48f + 0.001f * static_cast<float>(i), 0.5f, -0.7f, 0.0f};
      s.right_gaze = EyeGaze{kEyeGazeValid, 0.52f, 0.5f, 0.7f, 0.0f};
    } else if (i == 1) {
      s.right_gaze = EyeGaze{kEyeGazeValid, 0.51f, 0.49f, 0.35f, -0.35f};
    }
    server.publish(s);
  }
  for (int i = 0; i < 200 && (a.stats().samples.received < 5 || b.stats().samples.received < 5); ++i) {
    std::this_thread::sleep_for(5ms);
  }
  std::lock_guard la(seen_with.mu), lb(seen_without.mu);
  ASSERT_EQ(seen_with.samples.size(), 5u);
  ASSERT_EQ(seen_without.samples.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    const GazeSample& s = seen_with.samples[static_cast<std::size_t>(i)].first;
    EXPECT_EQ(seen_with.samples[static_cast<std::size_t>(i)].second, seen_without.samples[static_cast<std::size_t>(i)].second);
    if (i % 2 == 0) {
      ASSERT_TRUE(s.left_gaze.valid() && s.right_gaze.valid()) << i;
      EXPECT_FLOAT_EQ(s.left_gaze.x, 0.48f + 0.001f * static_cast<float>(i));
      EXPECT_FLOAT_EQ(s.right_gaze.x_deg, 0.7f);
    } else if (i == 1) {
      EXPECT_FALSE(s.left_gaze.valid());
      ASSERT_TRUE(s.right_gaze.valid());
      EXPECT_FLOAT_EQ(s.right_gaze.y_deg, -0.35f);
    } else {
      EXPECT_FALSE(s.has_eye_gaze()) << "sample 3 has no eyes: it must not get sample 2's";
    }
    EXPECT_FALSE(seen_without.samples[static_cast<std::size_t>(i)].first.has_eye_gaze());
  }
  EXPECT_EQ(a.stats().eye_samples, 4u);
  EXPECT_EQ(a.stats().samples.lost, 0u);
  EXPECT_EQ(a.stats().rejected, 0u);
  EXPECT_EQ(b.stats().eye_samples, 0u);
  EXPECT_EQ(b.stats().rejected, 0u) << "a client that did not ask is never sent GAZE_EYES";
}
