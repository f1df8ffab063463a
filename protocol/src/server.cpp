// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/server.h"

#include "fovea/protocol/bounded_file.h"

#include <sys/random.h>

#include <algorithm>
#include <cassert>
#include <cctype>
#include <cstdio>
#include <stdexcept>

#include "fovea/protocol/clock.h"

namespace fovea::protocol {

MulticastTarget parse_multicast(const std::string& text) {
  if (text.find(':') == std::string::npos) {
    throw std::invalid_argument("multicast \"" + text + "\": expected GROUP:PORT, e.g. 239.255.47.80:47801");
  }
  MulticastTarget t;
  t.group = parse_endpoint(text, 0);
  if (!t.group.is_multicast()) {
    throw std::invalid_argument("multicast \"" + text + "\": " + Endpoint{t.group.ip, 0}.to_string() +
                                " is not a multicast group (224.0.0.0 - 239.255.255.255)");
  }
  if (t.group.port == 0) throw std::invalid_argument("multicast \"" + text + "\": port must be 1..65535");
  return t;
}

namespace {
std::string dotted_quad(std::uint32_t ip) {
  const std::string s = Endpoint{ip, 0}.to_string();
  return s.substr(0, s.rfind(':'));
}
}  // namespace

bool Ipv4Cidr::contains(std::uint32_t ip) const {
  const std::uint32_t mask = prefix == 0 ? 0u : ~std::uint32_t{0} << (32 - prefix);
  return (ip & mask) == network;
}

std::string Ipv4Cidr::to_string() const {
  return dotted_quad(network) + "/" + std::to_string(prefix);
}

Ipv4Cidr parse_cidr(const std::string& text) {
  const auto fail = [&](const std::string& why) {
    return std::invalid_argument("network \"" + text + "\": " + why +
                                 " (expected A.B.C.D/N with N in 0..32, e.g. 127.0.0.0/8 or 192.168.1.0/24)");
  };
  const std::size_t slash = text.find('/');
  const std::string addr = text.substr(0, slash);
  unsigned a = 0, b = 0, c = 0, d = 0;
  int consumed = 0;
  if (addr.empty() || std::sscanf(addr.c_str(), "%3u.%3u.%3u.%3u%n", &a, &b, &c, &d, &consumed) != 4 ||
      static_cast<std::size_t>(consumed) != addr.size() || a > 255 || b > 255 || c > 255 || d > 255 ||
      !std::all_of(addr.begin(), addr.end(),
                   [](char ch) { return ch == '.' || std::isdigit(static_cast<unsigned char>(ch)) != 0; })) {
    throw fail("not a dotted-quad IPv4 address");
  }
  Ipv4Cidr n;
  n.network = (a << 24) | (b << 16) | (c << 8) | d;
  if (slash != std::string::npos) {
    const std::string len = text.substr(slash + 1);
    if (len.empty() || len.size() > 2 || !std::all_of(len.begin(), len.end(), [](char ch) {
          return std::isdigit(static_cast<unsigned char>(ch)) != 0;
        })) {
      throw fail("prefix length is not a number");
    }
    const int p = std::stoi(len);
    if (p > 32) throw fail("prefix length " + len + " is larger than 32");
    n.prefix = static_cast<std::uint8_t>(p);
  }
  const std::uint32_t mask = n.prefix == 0 ? 0u : ~std::uint32_t{0} << (32 - n.prefix);
  if ((n.network & ~mask) != 0) {
    Ipv4Cidr fixed{n.network & mask, n.prefix};
    throw fail("host bits are set below the /" + std::to_string(n.prefix) + " prefix; did you mean " +
               fixed.to_string() + "?");
  }
  return n;
}

bool allowed(const std::vector<Ipv4Cidr>& list, std::uint32_t ip) {
  return std::any_of(list.begin(), list.end(), [&](const Ipv4Cidr& n) { return n.contains(ip); });
}

namespace {
std::uint64_t random_u64() {
  std::uint64_t v = 0;
  while (v == 0) {
    if (getrandom(&v, sizeof v, 0) != sizeof v) throw std::runtime_error("getrandom failed");
  }
  return v;
}
}  // namespace

GazeServer::GazeServer(ServerOptions options)
    : options_(std::move(options)),
      socket_(UdpSocket::bind(options_.listen)),
      cookies_(options_.cookie_lifetime_ms),
      started_ns_(monotonic_ns()) {
  socket_.set_receive_buffer(1 << 20);
  if (options_.multicast) {
    multicast_socket_ = UdpSocket::bind(Endpoint{0, 0});
    multicast_socket_.set_multicast_output(options_.multicast->ttl, options_.multicast->interface_ip, true);
  }
  thread_ = std::thread([this] { control_loop(); });
}

GazeServer::~GazeServer() { stop(); }

void GazeServer::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
}

void GazeServer::on_subscriber_change(std::function<void(const SubscriberInfo&, const char*)> cb) {
  std::lock_guard lock(mutex_);
  on_change_ = std::move(cb);
}

void GazeServer::set_display(const DisplayGeometry& g) {
  std::lock_guard lock(mutex_);
  if (options_.display == g) return;
  options_.display = g;
  for (const auto& [id, session] : sessions_) reply(session.address, 0, subscribed_reply(session));
}

void GazeServer::set_nominal_rate(double hz) {
  std::lock_guard lock(mutex_);
  options_.nominal_rate_hz = hz;
}

void GazeServer::set_limits(std::uint32_t default_lease_ms, std::size_t max_subscribers) {
  std::lock_guard lock(mutex_);
  options_.default_lease_ms = std::clamp(default_lease_ms, options_.min_lease_ms, options_.max_lease_ms);
  options_.max_subscribers = max_subscribers;
}

void GazeServer::set_control_allow(std::vector<Ipv4Cidr> allow) {
  std::lock_guard lock(mutex_);
  options_.control_allow = std::move(allow);
}

std::vector<Ipv4Cidr> GazeServer::control_allow() const {
  std::lock_guard lock(mutex_);
  return options_.control_allow;
}

void GazeServer::on_control(ControlHandler handler) {
  std::lock_guard lock(mutex_);
  on_control_ = std::move(handler);
}

void GazeServer::on_marker(MarkerHandler handler) {
  std::lock_guard lock(mutex_);
  on_marker_ = std::move(handler);
}

ServerStats GazeServer::stats() const {
  std::lock_guard lock(mutex_);
  ServerStats s = stats_;
  s.subscribers = sessions_.size();
  s.datagrams_rejected = rejected_.rejected();
  return s;
}

std::vector<SubscriberInfo> GazeServer::subscribers() const {
  std::lock_guard lock(mutex_);
  std::vector<SubscriberInfo> out;
  for (const auto& [id, s] : sessions_) out.push_back(s);
  return out;
}

std::uint64_t GazeServer::send_stream(const std::unique_lock<std::mutex>& held, std::uint32_t stream_bit,
                                      std::uint64_t& sequence, std::int64_t origin_ns, const Payload& p) {
  send_to_subscribers(held, stream_bit, sequence, origin_ns, p, true);
  return sequence++;
}

// One datagram to every session subscribed to `stream_bit` (and to the multicast group when asked),
// carrying `sequence`. The caller holds mutex_, so all subscribers see the same sequence numbers in
// the same order.
void GazeServer::send_to_subscribers(const std::unique_lock<std::mutex>& held, std::uint32_t stream_bit,
                                     std::uint64_t sequence, std::int64_t origin_ns, const Payload& p,
                                     bool to_group) {
  assert(held.owns_lock() && held.mutex() == &mutex_ && "send_to_subscribers: the caller must hold mutex_");
  (void)held;
  targets_.clear();
  for (const auto& [id, s] : sessions_) {
    if ((s.streams & stream_bit) != 0) targets_.push_back(s.address);
  }
  if (!to_group && targets_.empty()) return;  // nobody asked: nothing to encode
  const bool group = to_group && multicast_socket_.valid();
  Message m{Header{}, p};
  m.header.sequence = sequence;
  m.header.origin_time_ns = origin_ns;
  m.header.send_time_ns = monotonic_ns();
  std::array<std::uint8_t, kMaxDatagramSize> buf{};
  const std::size_t n = encode_into(m, buf);
  const std::span<const std::uint8_t> datagram(buf.data(), n);
  const std::size_t sent = socket_.send_to_many(targets_, datagram);
  stats_.datagrams_sent += sent;
  stats_.send_failures += targets_.size() - sent;
  if (group) {
    if (multicast_socket_.send_to(options_.multicast->group, datagram)) {
      ++stats_.datagrams_sent;
    } else {
      ++stats_.send_failures;
    }
  }
}

std::uint64_t GazeServer::publish(const GazeSample& sample) { return publish(sample, sample.tracker_time_ns); }

std::uint64_t GazeServer::publish(const GazeSample& sample, std::int64_t host_receive_ns) {
  std::unique_lock lock(mutex_);
  ++stats_.samples_published;
  if (sample.has_eye_gaze()) send_eyes(lock, sample, host_receive_ns);
  return send_stream(lock, kStreamSamples, next_sample_seq_, host_receive_ns, sample);
}

// A sample's per-eye gaze as GAZE_EYES, to kStreamEyes subscribers only (unicast: a v1 receiver of
// the multicast group would reject the type), just before the GAZE_SAMPLE whose sequence it carries
// (the sample stream's counter, not advanced), so that a client holds it when the sample arrives and
// delivers the two as one.
void GazeServer::send_eyes(const std::unique_lock<std::mutex>& held, const GazeSample& sample,
                           std::int64_t origin_ns) {
  send_to_subscribers(held, kStreamEyes, next_sample_seq_, origin_ns,
                      GazeEyes{sample.tracker_time_ns, sample.left_gaze, sample.right_gaze}, false);
}

std::uint64_t GazeServer::publish(const Marker& marker) {
  std::unique_lock lock(mutex_);
  Marker published = marker;
  published.session_id = 0;
  return send_marker(lock, published);
}

// Sends a marker on its stream and tells the marker handler; the caller holds mutex_.
std::uint64_t GazeServer::send_marker(const std::unique_lock<std::mutex>& held, const Marker& published) {
  const std::uint64_t sequence = send_stream(held, kStreamMarkers, next_marker_seq_, published.time_ns, published);
  ++stats_.markers_published;
  if (on_marker_) on_marker_(published, sequence);
  return sequence;
}

std::uint64_t GazeServer::publish(const GazeEvent& event) {
  std::unique_lock lock(mutex_);
  ++stats_.events_published;
  if (event.provisional()) {
    return send_stream(lock, kStreamProvisional, next_provisional_seq_, event.start_time_ns + event.duration_ns, event);
  }
  return send_stream(lock, kStreamEvents, next_event_seq_, event.start_time_ns + event.duration_ns, event);
}

void GazeServer::control_loop() {
  std::array<std::uint8_t, kMaxDatagramSize + 1> buf{};
  while (running_.load()) {
    Endpoint from;
    const std::size_t n = socket_.receive(buf, from, 20);
    const std::int64_t now = monotonic_ns();
    if (n > 0) {
      Message m;
      const std::span<const std::uint8_t> datagram(buf.data(), std::min(n, buf.size()));
      const DecodeResult r = n > kMaxDatagramSize ? DecodeResult{DecodeError::TooLong, kMaxDatagramSize}
                                                   : decode(datagram, m);
      if (r) {
        handle(m, from, now);
      } else {
        rejected_.count(r.error);
        // A peer speaking another version learns which one we speak, if its datagram is at least as
        // large as our answer (so we never amplify).
        if (r.error == DecodeError::BadVersion && n >= kHeaderSize + payload_size(MessageType::Error)) {
          std::lock_guard lock(mutex_);
          refuse(from, 0, MessageType::Hello, ErrorCode::UnsupportedVersion);
        }
      }
    }
    expire_leases(now);
  }
}

void GazeServer::reply(const Endpoint& to, std::uint64_t sequence, Payload payload, std::int64_t origin_ns) {
  Message m{Header{}, std::move(payload)};
  m.header.sequence = sequence;
  m.header.send_time_ns = monotonic_ns();
  m.header.origin_time_ns = origin_ns != 0 ? origin_ns : m.header.send_time_ns;
  std::array<std::uint8_t, kMaxDatagramSize> buf{};
  const std::size_t n = encode_into(m, buf);
  if (socket_.send_to(to, std::span<const std::uint8_t>(buf.data(), n))) {
    ++stats_.datagrams_sent;
  } else {
    ++stats_.send_failures;
  }
}

void GazeServer::refuse(const Endpoint& to, std::uint64_t sequence, MessageType request, ErrorCode code) {
  ++stats_.requests_refused;
  reply(to, sequence, Error{code, request, kVersion});
}

std::uint32_t GazeServer::clamp_lease(std::uint32_t requested) const {
  if (requested == 0) return options_.default_lease_ms;
  return std::clamp(requested, options_.min_lease_ms, options_.max_lease_ms);
}

void GazeServer::handle_control(const Message& m, const Endpoint& from) {
  const auto& req = std::get<ControlRequest>(m.payload);
  const std::uint64_t seq = m.header.sequence;
  ControlHandler handler;
  {
    std::lock_guard lock(mutex_);
    if (!allowed(options_.control_allow, from.ip)) {
      ++stats_.control_refused;
      ControlReply no{req.command, ControlResult::Refused, {}};
      no.message.value = options_.control_allow.empty() ? "UDP control is off; use the daemon's control socket"
                                                        : "not allowed from " + dotted_quad(from.ip);
      reply(from, seq, no);
      return;
    }
    // A retransmission of a request already executed gets the same answer again.
    for (const auto& r : recent_control_) {
      if (r.from == from && r.sequence == seq && r.request == req) {
        reply(from, seq, r.reply);
        return;
      }
    }
    ++stats_.control_requests;
    handler = on_control_;
  }
  // The handler runs without the lock: it may reconfigure this server (set_limits, ...).
  ControlReply answer{req.command, ControlResult::Failed, {}};
  if (!handler) {
    answer.message.value = "this server executes no control commands";
  } else {
    try {
      answer = handler(req, from);
      answer.command = req.command;
      if (answer.message.value.size() >= decltype(answer.message)::capacity) {
        answer.message.value = answer.message.value.substr(0, decltype(answer.message)::capacity - 4) + "...";
      }
    } catch (const std::exception& e) {
      answer = ControlReply{req.command, ControlResult::Failed, {}};
      answer.message.value = std::string(e.what()).substr(0, decltype(answer.message)::capacity - 1);
    }
  }
  std::lock_guard lock(mutex_);
  if (recent_control_.size() >= 16) recent_control_.erase(recent_control_.begin());
  recent_control_.push_back(RecentControl{from, seq, req, answer});
  reply(from, seq, answer);
}

// PROTOCOL.md §4.5: session ids are random and non-zero; a draw that is already in use is redrawn.
SubscriberInfo& GazeServer::new_session(const Endpoint& from) {
  std::uint64_t id = random_u64();
  while (sessions_.contains(id)) id = random_u64();
  SubscriberInfo& session = sessions_[id];
  session.session_id = id;
  session.address = from;
  return session;
}

// PROTOCOL.md §4.5: the next sequence numbers let the client tell a late start from a lost datagram.
Subscribed GazeServer::subscribed_reply(const SubscriberInfo& session) const {
  Subscribed reply_msg;
  reply_msg.session_id = session.session_id;
  reply_msg.streams = session.streams;
  reply_msg.lease_ms = session.lease_ms;
  reply_msg.nominal_rate_hz = options_.nominal_rate_hz;
  reply_msg.next_sample_sequence = next_sample_seq_;
  reply_msg.next_event_sequence = next_event_seq_;
  reply_msg.display = options_.display;
  if (options_.multicast) {
    reply_msg.multicast = {options_.multicast->group.ip, options_.multicast->group.port, options_.multicast->ttl};
  }
  return reply_msg;
}

// PROTOCOL.md §4.4: a valid cookie proves the client receives at `from` before a session is made for it.
void GazeServer::handle_subscribe(const Subscribe& sub, std::uint64_t seq, const Endpoint& from,
                                  std::int64_t received_ns) {
  switch (cookies_.check(sub.cookie, from, sub.client_nonce, received_ns)) {
    case CookieCheck::Forged: refuse(from, seq, MessageType::Subscribe, ErrorCode::BadCookie); return;
    case CookieCheck::Expired: refuse(from, seq, MessageType::Subscribe, ErrorCode::CookieExpired); return;
    case CookieCheck::Valid: break;
  }
  // One session per address: a repeated SUBSCRIBE (its SUBSCRIBED was lost) renews the same one.
  SubscriberInfo* session = nullptr;
  for (auto& [id, s] : sessions_) {
    if (s.address == from) session = &s;
  }
  const char* what = "renewed";
  if (session == nullptr) {
    const auto same_host = static_cast<std::size_t>(std::count_if(
        sessions_.begin(), sessions_.end(), [&](const auto& kv) { return kv.second.address.ip == from.ip; }));
    if (sessions_.size() >= options_.max_subscribers || same_host >= options_.max_subscribers_per_address) {
      refuse(from, seq, MessageType::Subscribe, ErrorCode::TooManySubscribers);
      return;
    }
    session = &new_session(from);
    what = "subscribed";
  }
  session->streams = sub.streams;
  session->lease_ms = clamp_lease(sub.requested_lease_ms);
  session->expires_ns = received_ns + std::int64_t{session->lease_ms} * 1'000'000;
  reply(from, seq, subscribed_reply(*session));
  if (on_change_) on_change_(*session, what);
}

// PROTOCOL.md §4.6: only the address that subscribed may renew; lease 0 keeps the current lease.
void GazeServer::handle_heartbeat(const Heartbeat& hb, std::uint64_t seq, const Endpoint& from,
                                  std::int64_t received_ns) {
  const auto it = sessions_.find(hb.session_id);
  if (it == sessions_.end()) {
    refuse(from, seq, MessageType::Heartbeat, ErrorCode::UnknownSession);
    return;
  }
  if (!(it->second.address == from)) {
    refuse(from, seq, MessageType::Heartbeat, ErrorCode::AddressMismatch);
    return;
  }
  if (hb.lease_ms != 0) it->second.lease_ms = clamp_lease(hb.lease_ms);
  it->second.expires_ns = received_ns + std::int64_t{it->second.lease_ms} * 1'000'000;
  reply(from, seq, Heartbeat{hb.session_id, it->second.lease_ms});
}

// PROTOCOL.md §4.7: never answered, and ignored unless it comes from the session's own address.
void GazeServer::handle_unsubscribe(const Unsubscribe& un, const Endpoint& from) {
  const auto it = sessions_.find(un.session_id);
  if (it != sessions_.end() && it->second.address == from) {
    const SubscriberInfo gone = it->second;
    sessions_.erase(it);
    if (on_change_) on_change_(gone, "unsubscribed");
  }
}

// PROTOCOL.md §4.17 and §9: only a session's own address may mark (anyone else gets a 40-byte ERROR,
// smaller than the 136-byte MARKER), at most marker_rate_per_s; what is published goes only to
// subscribers of the marker stream, who all proved they receive where they asked.
void GazeServer::handle_marker(const std::unique_lock<std::mutex>& held, const Marker& marker, std::uint64_t seq,
                               const Endpoint& from, std::int64_t received_ns) {
  const auto session = sessions_.find(marker.session_id);
  if (session == sessions_.end() || !(session->second.address == from)) {
    ++stats_.markers_refused;
    refuse(from, seq, MessageType::Marker,
           session == sessions_.end() ? ErrorCode::UnknownSession : ErrorCode::AddressMismatch);
    return;
  }
  MarkerState& state = marker_state_[marker.session_id];
  for (const auto& sent : state.recent) {
    if (sent.marker_id == marker.marker_id) {
      // Its copy was lost on the way back (or is late): the sender alone gets the same copy again.
      ++stats_.markers_repeated;
      if ((session->second.streams & kStreamMarkers) != 0) reply(from, sent.sequence, sent.published, sent.published.time_ns);
      return;
    }
  }
  const double rate = options_.marker_rate_per_s;
  if (state.refilled_ns == 0) state.tokens = rate;
  state.tokens = std::min(rate, state.tokens + rate * static_cast<double>(received_ns - state.refilled_ns) * 1e-9);
  state.refilled_ns = received_ns;
  const bool implausible = (marker.flags & kMarkerClientTime) != 0 &&
                           (marker.time_ns < received_ns - options_.marker_max_time_offset_ns ||
                            marker.time_ns > received_ns + options_.marker_max_time_offset_ns);
  if (state.tokens < 1.0 || implausible) {
    ++stats_.markers_refused;
    refuse(from, seq, MessageType::Marker, implausible ? ErrorCode::BadRequest : ErrorCode::RateLimited);
    return;
  }
  state.tokens -= 1.0;
  Marker published = marker;
  published.session_id = 0;  // sessions are never disclosed to other subscribers
  published.received_ns = received_ns;
  if ((marker.flags & kMarkerClientTime) == 0) published.time_ns = received_ns;
  const std::uint64_t sequence = send_marker(held, published);
  if (state.recent.size() >= 32) state.recent.pop_front();
  state.recent.push_back({marker.marker_id, sequence, published});
}

// PROTOCOL.md §4.11; read under mutex_ so the counters agree with each other.
StatusReply GazeServer::status_reply(std::int64_t received_ns) const {
  StatusReply s;
  s.source.value = escape_to_fit(options_.source_name, decltype(s.source)::capacity - 1);  // no control characters on the wire
  s.nominal_rate_hz = options_.nominal_rate_hz;
  s.uptime_ns = received_ns - started_ns_;
  s.samples_published = stats_.samples_published;
  s.events_published = stats_.events_published;
  s.datagrams_rejected = rejected_.rejected();
  s.subscribers = static_cast<std::uint32_t>(sessions_.size());
  s.source_state = source_state_.load();
  s.display = options_.display;
  return s;
}

void GazeServer::handle(const Message& m, const Endpoint& from, std::int64_t received_ns) {
  if (m.header.type == MessageType::ControlRequest) {
    handle_control(m, from);
    return;
  }
  std::unique_lock lock(mutex_);
  const std::uint64_t seq = m.header.sequence;
  switch (m.header.type) {
    case MessageType::Hello: {
      const auto& hello = std::get<Hello>(m.payload);
      reply(from, seq, Challenge{hello.client_nonce, cookies_.issue(from, hello.client_nonce, received_ns),
                                 cookies_.lifetime_ms()});
      return;
    }
    case MessageType::Subscribe: handle_subscribe(std::get<Subscribe>(m.payload), seq, from, received_ns); return;
    case MessageType::Heartbeat: handle_heartbeat(std::get<Heartbeat>(m.payload), seq, from, received_ns); return;
    case MessageType::Unsubscribe: handle_unsubscribe(std::get<Unsubscribe>(m.payload), from); return;
    case MessageType::Marker: handle_marker(lock, std::get<Marker>(m.payload), seq, from, received_ns); return;
    case MessageType::StatusRequest: reply(from, seq, status_reply(received_ns)); return;
    case MessageType::TimeSyncRequest: {
      const auto& req = std::get<TimeSyncRequest>(m.payload);
      reply(from, seq, TimeSyncReply{req.client_send_ns, received_ns, monotonic_ns()});
      return;
    }
    default:
      // Server-to-client messages arriving here are well-formed but meaningless: count, do not answer.
      ++stats_.unexpected_messages;
      return;
  }
}

void GazeServer::expire_leases(std::int64_t now_ns) {
  std::lock_guard lock(mutex_);
  for (auto it = sessions_.begin(); it != sessions_.end();) {
    if (it->second.expires_ns < now_ns) {
      const SubscriberInfo gone = it->second;
      it = sessions_.erase(it);
      ++stats_.leases_expired;
      if (on_change_) on_change_(gone, "lease expired");
    } else {
      ++it;
    }
  }
  std::erase_if(marker_state_, [&](const auto& kv) { return !sessions_.contains(kv.first); });
}

}  // namespace fovea::protocol
