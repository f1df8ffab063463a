// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/client.h"

#include <poll.h>
#include <sys/random.h>

#include <algorithm>
#include <array>
#include <stdexcept>

#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/clock.h"

namespace fovea::protocol {

namespace {
constexpr std::size_t kLatencyWindow = 65536;
constexpr std::size_t kLatencyRecordLimit = 2'000'000;
constexpr std::size_t kTimeSyncKeep = 8;
constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kRefusedBackoffNs = 2000 * kMs;

std::uint64_t random_nonce() {
  std::uint64_t v = 0;
  if (getrandom(&v, sizeof v, 0) != sizeof v) throw std::runtime_error("getrandom failed");
  return v;
}

std::int64_t percentile(std::vector<std::int64_t> v, double q) {
  if (v.empty()) return 0;
  const auto k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}
}  // namespace

namespace {
// With multicast, samples come from the group; the unicast subscription carries events only (a
// subscription needs at least one stream, so it asks for events even when they will be ignored).
std::uint32_t unicast_streams(const ClientOptions& o) {
  if (!o.multicast_group) return o.streams;
  return kStreamEvents;
}
}  // namespace

GazeClient::GazeClient(ClientOptions options)
    : options_(std::move(options)), socket_(UdpSocket::bind(Endpoint{0, 0})) {
  socket_.set_receive_buffer(1 << 20);
  if (options_.multicast_group) {
    multicast_socket_ = UdpSocket::bind(Endpoint{0, options_.multicast_group->port}, true);
    multicast_socket_.join_multicast(options_.multicast_group->ip, options_.multicast_interface_ip);
    multicast_socket_.set_receive_buffer(1 << 20);
  }
  latency_ring_.reserve(kLatencyWindow);
}

GazeClient::~GazeClient() { stop(); }

void GazeClient::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { loop(); });
}

void GazeClient::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
  std::optional<Subscribed> s = session();
  if (s) send(Unsubscribe{s->session_id});
  subscribed_ = false;
}

bool GazeClient::wait_subscribed(int timeout_ms) {
  std::unique_lock lock(mutex_);
  return subscribed_cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [this] { return subscribed_.load(); });
}

std::optional<Subscribed> GazeClient::session() const {
  std::lock_guard lock(mutex_);
  return session_;
}

std::optional<GazeSample> GazeClient::latest_sample() const {
  std::lock_guard lock(mutex_);
  return latest_;
}

std::size_t GazeClient::poll(std::vector<std::pair<GazeSample, Arrival>>& out, std::size_t max) {
  std::lock_guard lock(mutex_);
  std::size_t n = 0;
  while (n < max && !queue_.empty()) {
    out.push_back(queue_.front());
    queue_.pop_front();
    ++n;
  }
  return n;
}

ClientStats GazeClient::stats() const {
  std::lock_guard lock(mutex_);
  ClientStats s = stats_;
  s.samples = sample_seq_.counts();
  s.events = event_seq_.counts();
  s.markers = marker_seq_.counts();
  s.provisional = provisional_seq_.counts();
  s.rejected += rejected_.rejected();
  s.latency_count = latency_ring_.size();
  s.latency_p50_ns = percentile(latency_ring_, 0.50);
  s.latency_p99_ns = percentile(latency_ring_, 0.99);
  s.latency_max_ns = latency_ring_.empty() ? 0 : *std::max_element(latency_ring_.begin(), latency_ring_.end());
  return s;
}

std::vector<std::int64_t> GazeClient::latencies() const {
  std::lock_guard lock(mutex_);
  return latency_all_;
}

void GazeClient::send(Payload p) {
  Message m{Header{}, std::move(p)};
  m.header.sequence = request_seq_++;
  m.header.send_time_ns = monotonic_ns();
  m.header.origin_time_ns = m.header.send_time_ns;
  std::array<std::uint8_t, kMaxDatagramSize> buf{};
  const std::size_t n = encode_into(m, buf);
  socket_.send_to(options_.server, std::span<const std::uint8_t>(buf.data(), n));
  last_sent_ns_ = m.header.send_time_ns;
}

void GazeClient::begin_handshake(std::int64_t now, bool fresh) {
  state_ = State::Hello;
  subscribed_ = false;
  // Retransmissions keep the nonce, so a CHALLENGE that arrives after the next retry (a round trip
  // longer than the retry interval) still matches.
  if (fresh || nonce_ == 0) nonce_ = random_nonce();
  Hello h;
  h.client_nonce = nonce_;
  h.client_name.value = options_.name.substr(0, decltype(h.client_name)::capacity - 1);
  send(h);
  last_heard_ns_ = now;
}

void GazeClient::loop() {
  std::array<std::uint8_t, kMaxDatagramSize + 1> buf{};
  begin_handshake(monotonic_ns(), true);
  std::uint32_t subscribe_attempts = 0;
  while (running_.load()) {
    pollfd fds[2] = {{socket_.fd(), POLLIN, 0}, {multicast_socket_.fd(), POLLIN, 0}};
    ::poll(fds, multicast_socket_.valid() ? 2 : 1, 10);
    for (int i = 0; i < 2; ++i) {
      const UdpSocket& sock = i == 0 ? socket_ : multicast_socket_;
      if (!sock.valid() || (fds[i].revents & POLLIN) == 0) continue;
      for (int burst = 0; burst < 256; ++burst) {
        Endpoint from;
        const std::size_t n = sock.receive(buf, from, 0);
        if (n == 0) break;
        const std::int64_t now = monotonic_ns();
        Message m;
        const DecodeResult r = n > kMaxDatagramSize
                                   ? DecodeResult{DecodeError::TooLong, kMaxDatagramSize}
                                   : decode(std::span<const std::uint8_t>(buf.data(), n), m);
        if (!r) {
          rejected_.count(r.error);
          continue;
        }
        const bool from_server = i == 0 && from == options_.server;
        // Group traffic must still come from the daemon's host (any port: it sends from its own socket).
        const bool from_group = i == 1 && m.header.type == MessageType::GazeSample && from.ip == options_.server.ip;
        if (!from_server && !from_group) {
          std::lock_guard lock(mutex_);
          ++stats_.rejected;  // not our server: never trusted
          continue;
        }
        handle(m, now);
      }
    }

    const std::int64_t now = monotonic_ns();
    const std::int64_t retry = std::int64_t{options_.retry_interval_ms} * kMs;
    switch (state_) {
      case State::Hello:
        if (now - last_sent_ns_ >= retry && now >= retry_after_ns_) begin_handshake(now, false);
        break;
      case State::Subscribe:
        if (now - last_sent_ns_ >= retry) {
          if (++subscribe_attempts > 10) {
            begin_handshake(now, true);
          } else {
            send(Subscribe{cookie_, nonce_, unicast_streams(options_), options_.requested_lease_ms});
          }
        }
        break;
      case State::Subscribed: {
        const std::int64_t hb = std::int64_t{options_.heartbeat_interval_ms} * kMs;
        if (now - last_heard_ns_ > std::max<std::int64_t>(3 * hb, 1000 * kMs)) {
          // The daemon went quiet (stopped, restarted, or the network failed): start over.
          begin_handshake(now, true);
          break;
        }
        const std::optional<Subscribed> s = session();
        if (now - last_sent_ns_ >= hb && s) send(Heartbeat{s->session_id, options_.requested_lease_ms});
        resend_markers(now);
        if (now >= next_time_sync_ns_) {
          TimeSyncRequest t;
          t.client_send_ns = monotonic_ns();
          {
            std::lock_guard lock(mutex_);
            sync_sent_.push_back(t.client_send_ns);
            if (sync_sent_.size() > kTimeSyncKeep) sync_sent_.pop_front();
          }
          send(t);
          next_time_sync_ns_ = now + (time_syncs_done_ < kClockBurst ? 50 * kMs : 2000 * kMs);
        }
        break;
      }
    }
    if (state_ != State::Subscribe) subscribe_attempts = 0;
  }
}

void GazeClient::handle(const Message& m, std::int64_t now) {
  switch (m.header.type) {
    case MessageType::Challenge: {
      const auto& c = std::get<Challenge>(m.payload);
      if (state_ != State::Hello || c.client_nonce != nonce_) return;
      cookie_ = c.cookie;
      state_ = State::Subscribe;
      send(Subscribe{cookie_, nonce_, unicast_streams(options_), options_.requested_lease_ms});
      return;
    }
    case MessageType::Subscribed: {
      const auto& s = std::get<Subscribed>(m.payload);
      last_heard_ns_ = now;
      {
        std::lock_guard lock(mutex_);
        const bool new_session = !session_ || session_->session_id != s.session_id;
        if (new_session) {
          sample_seq_.reset(s.next_sample_sequence);
          event_seq_.reset(s.next_event_sequence);
          marker_seq_.reset_from_first_arrival();
          provisional_seq_.reset_from_first_arrival();
          ++stats_.subscriptions;
          sync_samples_.clear();
          time_syncs_done_ = 0;
          next_time_sync_ns_ = now;
        }
        session_ = s;
      }
      state_ = State::Subscribed;
      subscribed_ = true;
      subscribed_cv_.notify_all();
      return;
    }
    case MessageType::Heartbeat:
      last_heard_ns_ = now;
      return;
    case MessageType::TimeSyncReply: {
      on_time_sync(std::get<TimeSyncReply>(m.payload), now);
      return;
    }
    case MessageType::Error: {
      const auto& e = std::get<Error>(m.payload);
      {
        std::lock_guard lock(mutex_);
        ++stats_.errors_received;
        stats_.last_error = e.code;
      }
      // Our session or cookie is no longer known (daemon restarted, lease lapsed): subscribe again.
      if (e.code == ErrorCode::UnknownSession || e.code == ErrorCode::BadCookie || e.code == ErrorCode::CookieExpired ||
          e.code == ErrorCode::AddressMismatch) {
        begin_handshake(now, true);
      } else if (e.code == ErrorCode::TooManySubscribers || e.code == ErrorCode::UnsupportedVersion) {
        // Asking again at once will not help; try again in a while (the daemon may free a slot).
        state_ = State::Hello;
        retry_after_ns_ = now + kRefusedBackoffNs;
      }
      return;
    }
    case MessageType::GazeSample:
    case MessageType::GazeEvent:
      handle_gaze(m, now);
      return;
    case MessageType::Marker:
      handle_marker(m, now);
      return;
    case MessageType::GazeEyes:
      handle_eyes(m);
      return;
    default: {
      std::lock_guard lock(mutex_);
      ++stats_.rejected;
      return;
    }
  }
}

// NTP's exchange (offset = ((t2 - t1) + (t3 - t4)) / 2, delay = (t4 - t1) - (t3 - t2)), hardened
// (issue 23 item 12: one reply could set an absurd offset, and times near +-2^63 wrapped): only a
// reply to a request this client sent counts; a server time outside +-2^60 ns (36 years) is dropped
// so that no difference below can overflow, and so is a round trip outside [0, 10 s]; the offset
// is that of the least-delay exchange (NTP's clock filter) among those that agree with the median
// of the last few, so a minority of bad exchanges cannot move it.
void GazeClient::on_time_sync(const TimeSyncReply& t, std::int64_t now) {
  constexpr std::int64_t kMaxTime = std::int64_t{1} << 60;
  std::lock_guard lock(mutex_);
  const auto sent = std::find(sync_sent_.begin(), sync_sent_.end(), t.client_send_ns);
  if (sent == sync_sent_.end()) {
    ++stats_.rejected;  // not an answer to a request of ours
    return;
  }
  sync_sent_.erase(sent);
  if (t.server_receive_ns < -kMaxTime || t.server_receive_ns > kMaxTime || t.server_send_ns < -kMaxTime ||
      t.server_send_ns > kMaxTime) {
    ++stats_.rejected;
    return;
  }
  // |t1|, |t4| < 2^62 (this host's monotonic clock), |t2|, |t3| <= 2^60: every sum below fits.
  const std::int64_t t1 = t.client_send_ns, t2 = t.server_receive_ns, t3 = t.server_send_ns, t4 = now;
  const std::int64_t delay = (t4 - t1) - (t3 - t2);
  if (delay < 0 || delay > 10'000'000'000) {
    ++stats_.rejected;
    return;
  }
  ++time_syncs_done_;
  sync_samples_.push_back({(t2 - t1) / 2 + (t3 - t4) / 2, delay});
  if (sync_samples_.size() > kTimeSyncKeep) sync_samples_.pop_front();
  // The majority's offset (the median of all kept exchanges), then NTP's choice among the exchanges
  // that agree with it within their own round trip (1 ms at least): the one of least delay.
  std::vector<std::int64_t> offsets;
  for (const SyncSample& s : sync_samples_) offsets.push_back(s.offset);
  std::nth_element(offsets.begin(), offsets.begin() + static_cast<std::ptrdiff_t>(offsets.size() / 2), offsets.end());
  const std::int64_t median = offsets[offsets.size() / 2];
  const SyncSample* best = nullptr;
  for (const SyncSample& s : sync_samples_) {
    const std::int64_t tolerance = std::max<std::int64_t>(s.delay, 1'000'000);
    if (s.offset - median > tolerance || median - s.offset > tolerance) continue;
    if (best == nullptr || s.delay < best->delay) best = &s;
  }
  stats_.clock_offset_ns = best != nullptr ? best->offset : median;
  stats_.clock_round_trip_ns = best != nullptr ? best->delay : sync_samples_.back().delay;
}

void GazeClient::handle_gaze(const Message& m, std::int64_t now) {
  if (state_ != State::Subscribed) return;
  Arrival a;
  a.sequence = m.header.sequence;
  a.receive_ns = now;
  a.host_receive_ns = m.header.origin_time_ns;
  const bool is_sample = m.header.type == MessageType::GazeSample;
  // Provisional events and their retractions come on a stream (and counter) of their own.
  const bool provisional = !is_sample && std::get<GazeEvent>(m.payload).provisional();
  const std::uint32_t stream = is_sample ? kStreamSamples : provisional ? kStreamProvisional : kStreamEvents;
  if ((options_.streams & stream) == 0) return;
  GazeSample delivered;
  {
    std::lock_guard lock(mutex_);
    SequenceTracker& tracker = is_sample ? sample_seq_ : provisional ? provisional_seq_ : event_seq_;
    const auto verdict = tracker.on_arrival(m.header.sequence);
    if (verdict == SequenceTracker::Verdict::Duplicate || verdict == SequenceTracker::Verdict::TooOld ||
        verdict == SequenceTracker::Verdict::Implausible) {
      return;  // not heard: a stream the client cannot follow must end in a resubscription (issue 23 item 5)
    }
    last_heard_ns_ = now;
    // Map the server's send time to our clock; meaningful once a TIME_SYNC exchange has completed.
    a.latency_ns = now - (m.header.send_time_ns - stats_.clock_offset_ns);
    if (is_sample) {
      GazeSample s = std::get<GazeSample>(m.payload);
      attach_eyes(s, m.header.sequence);
      delivered = s;
      latest_ = s;
      if (queue_.size() >= options_.queue_capacity) {
        queue_.pop_front();
        ++stats_.queue_dropped;
      }
      queue_.emplace_back(s, a);
      if (stats_.clock_round_trip_ns >= 0) {
        if (latency_ring_.size() < kLatencyWindow) {
          latency_ring_.push_back(a.latency_ns);
        } else {
          latency_ring_[latency_next_] = a.latency_ns;
        }
        latency_next_ = (latency_next_ + 1) % kLatencyWindow;
        if (latency_all_.size() < kLatencyRecordLimit) latency_all_.push_back(a.latency_ns);
      }
    }
  }
  if (is_sample) {
    if (on_sample_) on_sample_(delivered, a);
  } else if (on_event_) {
    on_event_(std::get<GazeEvent>(m.payload), a);
  }
}

// GAZE_EYES comes just before its GAZE_SAMPLE (same sequence); it is kept until then. Asked for
// only with kStreamEyes: from a server that was not asked, it is not trusted.
void GazeClient::handle_eyes(const Message& m) {
  std::lock_guard lock(mutex_);
  if (state_ != State::Subscribed || (options_.streams & kStreamEyes) == 0) {
    ++stats_.rejected;
    return;
  }
  pending_eyes_ = std::make_pair(m.header.sequence, std::get<GazeEyes>(m.payload));
}

// The held GAZE_EYES into the sample it belongs to: same sequence and capture time. One lost or
// reordered leaves the sample as the server's cyclopean gaze alone, never another sample's eyes.
void GazeClient::attach_eyes(GazeSample& s, std::uint64_t sequence) {
  if (!pending_eyes_) return;
  const auto& [held_sequence, eyes] = *pending_eyes_;
  if (held_sequence == sequence && eyes.tracker_time_ns == s.tracker_time_ns) {
    s.left_gaze = eyes.left;
    s.right_gaze = eyes.right;
    ++stats_.eye_samples;
  }
  if (held_sequence <= sequence) pending_eyes_.reset();
}

namespace {
constexpr std::int64_t kMarkerResendNs = 250 * kMs;
constexpr std::size_t kMarkerPendingLimit = 4096;
}  // namespace

void GazeClient::check_marker_label(const std::string& label) {
  std::size_t bad = 0;
  if (label.empty() || label.size() >= decltype(Marker::label)::capacity) {
    throw std::invalid_argument("marker label must be 1.." + std::to_string(decltype(Marker::label)::capacity - 1) +
                                " bytes; \"" + escape_for_log(label, 80) + "\" is " + std::to_string(label.size()));
  }
  if (!printable_utf8(label, &bad)) {
    throw std::invalid_argument("marker label \"" + escape_for_log(label, 80) + "\": byte " + std::to_string(bad) +
                                " is a control character or not UTF-8");
  }
}

std::uint64_t GazeClient::mark(const std::string& label, std::optional<std::int64_t> client_time_ns) {
  check_marker_label(label);
  std::unique_lock lock(mutex_);
  if (!session_ || !subscribed_.load()) throw std::logic_error("mark: not subscribed to a daemon");
  PendingMarker p;
  p.marker.marker_id = random_nonce();
  p.marker.label.value = label;
  p.marker.session_id = session_->session_id;
  if (client_time_ns) {
    if (stats_.clock_round_trip_ns < 0) throw std::logic_error("mark: the daemon's clock offset is not known yet");
    p.marker.flags = kMarkerClientTime;
    p.marker.time_ns = *client_time_ns + stats_.clock_offset_ns;  // offset = server - client
  }
  p.sent_ns = monotonic_ns();
  p.attempts = 1;
  ++stats_.markers_sent;
  const Marker to_send = p.marker;
  if ((options_.streams & kStreamMarkers) != 0 && pending_markers_.size() < kMarkerPendingLimit) {
    pending_markers_.push_back(p);
  }
  lock.unlock();
  send(to_send);
  return to_send.marker_id;
}

// Loop thread: markers whose copy has not come back go out again (with the current session: a
// daemon restart in between gave us a new one), until kMarkerAttempts sends.
void GazeClient::resend_markers(std::int64_t now) {
  std::vector<Marker> again;
  {
    std::lock_guard lock(mutex_);
    if (!session_) return;
    for (auto it = pending_markers_.begin(); it != pending_markers_.end();) {
      if (now - it->sent_ns < kMarkerResendNs) {
        ++it;
      } else if (it->attempts >= kMarkerAttempts) {
        ++stats_.markers_unconfirmed;
        it = pending_markers_.erase(it);
      } else {
        ++it->attempts;
        it->sent_ns = now;
        it->marker.session_id = session_->session_id;
        again.push_back(it->marker);
        ++it;
      }
    }
  }
  for (const Marker& m : again) send(m);
}

void GazeClient::handle_marker(const Message& m, std::int64_t now) {
  if (state_ != State::Subscribed || (options_.streams & kStreamMarkers) == 0) return;
  const auto& marker = std::get<Marker>(m.payload);
  Arrival a;
  a.sequence = m.header.sequence;
  a.receive_ns = now;
  {
    std::lock_guard lock(mutex_);
    const auto verdict = marker_seq_.on_arrival(m.header.sequence);
    const auto mine = std::find_if(pending_markers_.begin(), pending_markers_.end(),
                                   [&](const PendingMarker& p) { return p.marker.marker_id == marker.marker_id; });
    if (mine != pending_markers_.end()) {
      pending_markers_.erase(mine);
      ++stats_.markers_confirmed;
      if (confirmed_markers_.size() >= 64) confirmed_markers_.pop_front();
      confirmed_markers_.push_back(marker);
      marker_cv_.notify_all();
    }
    if (verdict == SequenceTracker::Verdict::Duplicate || verdict == SequenceTracker::Verdict::TooOld ||
        verdict == SequenceTracker::Verdict::Implausible) {
      return;
    }
    last_heard_ns_ = now;
    a.latency_ns = now - (m.header.send_time_ns - stats_.clock_offset_ns);
  }
  if (on_marker_) on_marker_(marker, a);
}

std::optional<Marker> GazeClient::wait_marker(std::uint64_t marker_id, int timeout_ms) {
  std::unique_lock lock(mutex_);
  std::optional<Marker> found;
  marker_cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] {
    for (const Marker& m : confirmed_markers_) {
      if (m.marker_id == marker_id) found = m;
    }
    return found.has_value();
  });
  return found;
}

bool GazeClient::clock_known() const {
  std::lock_guard lock(mutex_);
  return stats_.clock_round_trip_ns >= 0;
}

std::uint32_t GazeClient::clock_exchanges() const {
  std::lock_guard lock(mutex_);
  return time_syncs_done_;
}

namespace {

// One request/reply exchange without a session: sends `request` (with a random sequence),
// retransmits it unchanged every `resend_ms`, and returns the first decodable reply of type
// `reply_type` from `server` that carries the request's sequence.
std::optional<Message> exchange(const Endpoint& server, Payload request, MessageType reply_type, int timeout_ms,
                                int resend_ms) {
  UdpSocket sock = UdpSocket::bind(Endpoint{0, 0});
  Message req{Header{}, std::move(request)};
  req.header.sequence = random_nonce();
  req.header.send_time_ns = req.header.origin_time_ns = monotonic_ns();
  const std::vector<std::uint8_t> bytes = encode(req);
  const std::int64_t deadline = monotonic_ns() + std::int64_t{timeout_ms} * kMs;
  std::int64_t next_send = 0;
  std::array<std::uint8_t, kMaxDatagramSize + 1> buf{};
  while (true) {
    const std::int64_t now = monotonic_ns();
    if (now >= deadline) return std::nullopt;
    if (now >= next_send) {
      sock.send_to(server, bytes);
      next_send = now + std::int64_t{resend_ms} * kMs;
    }
    Endpoint from;
    const std::size_t n = sock.receive(buf, from, 20);
    if (n == 0 || n > kMaxDatagramSize || !(from == server)) continue;
    Message m;
    if (!decode(std::span<const std::uint8_t>(buf.data(), n), m)) continue;
    if (m.header.type == reply_type && m.header.sequence == req.header.sequence) return m;
  }
}

}  // namespace

std::optional<StatusReply> GazeClient::query_status(const Endpoint& server, int timeout_ms) {
  const auto m = exchange(server, StatusRequest{}, MessageType::StatusReply, timeout_ms, 250);
  if (!m) return std::nullopt;
  return std::get<StatusReply>(m->payload);
}

std::optional<ControlReply> GazeClient::send_control(const Endpoint& server, const ControlRequest& request,
                                                     int timeout_ms) {
  // Retransmitted after 1 s: the daemon answers a retransmission without executing it twice.
  const auto m = exchange(server, request, MessageType::ControlReply, timeout_ms, 1000);
  if (!m) return std::nullopt;
  return std::get<ControlReply>(m->payload);
}

}  // namespace fovea::protocol
