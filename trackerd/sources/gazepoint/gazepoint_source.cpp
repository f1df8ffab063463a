// SPDX-License-Identifier: Apache-2.0
#include "sources/gazepoint/gazepoint_source.h"

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>

#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/clock.h"

namespace fovea::trackerd::gazepoint {

namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kRetryNs = 1000 * kMs;    // between connection attempts
constexpr std::int64_t kSilenceNs = 3000 * kMs;  // connected, no records: say so

std::string errno_text(int e) { return std::strerror(e); }

// Waits for a non-blocking connect() to finish; 0 or the errno it failed with.
int finish_connect(int fd, int timeout_ms) {
  pollfd p{fd, POLLOUT, 0};
  const int n = ::poll(&p, 1, timeout_ms);
  if (n == 0) return ETIMEDOUT;
  if (n < 0) return errno;
  int err = 0;
  socklen_t len = sizeof err;
  if (::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len) != 0) return errno;
  return err;
}

bool send_all(int fd, const std::string& text) {
  std::size_t sent = 0;
  while (sent < text.size()) {
    const ssize_t n = ::send(fd, text.data() + sent, text.size() - sent, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      pollfd p{fd, POLLOUT, 0};
      if (::poll(&p, 1, 1000) <= 0) return false;
      continue;
    }
    if (n <= 0) return false;
    sent += static_cast<std::size_t>(n);
  }
  return true;
}


// One eye's point of gaze as the protocol's EyeGaze (invalid and zero when the tracker had none).
protocol::EyeGaze eye_gaze(const protocol::DisplayGeometry& display, const std::optional<Record::Point>& pog) {
  protocol::EyeGaze e;
  if (!pog) return e;
  const protocol::Degrees d = protocol::normalized_to_degrees(display, {pog->x, pog->y});
  e.flags = protocol::kEyeGazeValid;
  e.x = static_cast<float>(pog->x);
  e.y = static_cast<float>(pog->y);
  e.x_deg = static_cast<float>(d.x);
  e.y_deg = static_cast<float>(d.y);
  return e;
}

}  // namespace

GazepointSource::GazepointSource(GazepointSpec spec, protocol::DisplayGeometry display, double nominal_rate_hz)
    : ReaderSource(display, nominal_rate_hz), spec_(std::move(spec)) {
  start_reader([this] { run(); });
}

GazepointStats GazepointSource::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

std::string GazepointSource::status_detail() const {
  const GazepointStats s = stats();
  std::string out = std::to_string(s.records) + " records (" + std::to_string(s.valid) + " valid), " +
                    std::to_string(s.malformed) + " malformed, " + std::to_string(s.counter_gaps) + " missing by CNT" +
                    arrivals_.status();
  // The clock part only once a TIME anchored it: between a first record's count and its mapping,
  // STATUS would otherwise show an offset of 0.
  if (s.clock_offset_ns) {
    char clock[160];
    std::snprintf(clock, sizeof clock, ", clock offset %.3f ms, drift %s ppm, delay p50 %.2f / p99 %.2f ms",
                  static_cast<double>(*s.clock_offset_ns) / 1e6,
                  s.clock_drift_ppm ? std::to_string(static_cast<long>(std::lround(*s.clock_drift_ppm))).c_str() : "?",
                  static_cast<double>(s.delay_p50_ns) / 1e6, static_cast<double>(s.delay_p99_ns) / 1e6);
    out += clock;
  }
  if (s.connects > 1) out += ", " + std::to_string(s.connects - 1) + " reconnections";
  if (s.malformed > 0) out += "; last refused: " + protocol::escape_for_log(s.last_malformed, 80);
  return out;
}

// ---- the reader thread -----------------------------------------------------------------------

void GazepointSource::run() {
  while (!stopping()) {
    const int fd = connect_to_server();
    if (fd >= 0) {
      serve(fd);
      ::close(fd);
      {
        std::lock_guard lock(mutex_);
        stats_.connected = false;
      }
      if (stopping()) break;
      problem_.set(description() + ": the connection ended; reconnecting every second");
    }
    for (std::int64_t waited = 0; waited < kRetryNs && !stopping(); waited += 50 * kMs) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
}

int GazepointSource::connect_to_server() {
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const std::string port = std::to_string(spec_.port);
  if (const int rc = ::getaddrinfo(spec_.host.c_str(), port.c_str(), &hints, &found); rc != 0) {
    problem_.set(description() + ": cannot resolve " + spec_.host + ": " + ::gai_strerror(rc) + "; retrying every second");
    return -1;
  }
  const int fd = ::socket(found->ai_family, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  int err = fd < 0 ? errno : 0;
  if (fd >= 0 && ::connect(fd, found->ai_addr, found->ai_addrlen) != 0) {
    err = errno == EINPROGRESS ? finish_connect(fd, 1000) : errno;
  }
  ::freeaddrinfo(found);
  if (err != 0) {
    if (fd >= 0) ::close(fd);
    problem_.set(description() + ": " + errno_text(err) + " (is Gazepoint Control running, with its API on port " + port +
                "?); retrying every second");
    return -1;
  }
  const int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  return fd;
}

void GazepointSource::serve(int fd) {
  for (const std::string& command : start_commands()) {
    if (!send_all(fd, command)) {
      problem_.set(description() + ": could not send the start commands: " + errno_text(errno));
      return;
    }
  }
  // A new connection may be a restarted Gazepoint Control, with a new clock and counter.
  clock_.reset();
  paced_clock_ = {};
  last_counter_.reset();
  silence_reported_ = false;
  {
    std::lock_guard lock(mutex_);
    stats_.clock_offset_ns.reset();  // the old server's mapping says nothing of the new one's
    stats_.clock_drift_ppm.reset();
    stats_.connected = true;
    ++stats_.connects;
  }
  problem_.set("");
  spdlog::info("{}: connected; streaming", description());
  std::string buffer;
  bool discarding = false;  // inside a line that was already too long
  std::int64_t last_record_ns = protocol::monotonic_ns();
  char chunk[8192];
  while (!stopping()) {
    pollfd p{fd, POLLIN, 0};
    const int ready = ::poll(&p, 1, 100);
    const std::int64_t now = protocol::monotonic_ns();
    if (ready == 0) {
      if (now - last_record_ns > kSilenceNs && !silence_reported_) {
        problem_.set(description() + ": connected, but no gaze records for 3 s (is the tracker running?)");
        silence_reported_ = true;
      }
      continue;
    }
    const ssize_t n = ready < 0 ? -1 : ::recv(fd, chunk, sizeof chunk, 0);
    if (n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
    if (n <= 0) return;  // closed by the server, or an error: reconnect
    buffer.append(chunk, static_cast<std::size_t>(n));
    std::size_t start = 0;
    for (std::size_t nl; (nl = buffer.find('\n', start)) != std::string::npos; start = nl + 1) {
      std::string_view line(buffer.data() + start, nl - start);
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      if (discarding) {
        discarding = false;  // the end of the over-long line
        continue;
      }
      if (handle_line(line, now)) last_record_ns = now;
    }
    buffer.erase(0, start);
    if (buffer.size() > kMaxLineBytes) {
      if (!discarding) {
        std::lock_guard lock(mutex_);
        ++stats_.malformed;
        stats_.last_malformed = "a line of over " + std::to_string(kMaxLineBytes) + " bytes";
      }
      discarding = true;
      buffer.clear();
    }
  }
}

bool GazepointSource::handle_line(std::string_view line, std::int64_t receive_ns) {
  if (line.empty()) return false;
  std::string error;
  std::optional<Record> record;
  const std::optional<Element> e = parse_element(line, error);
  if (e && e->name == "REC") {
    record = parse_record(*e, error);
  } else if (e && e->name == "NACK") {
    std::lock_guard lock(mutex_);
    ++stats_.refused;
    const std::string* id = e->attribute("ID");
    spdlog::warn("{}: the server refused {}", description(), protocol::escape_for_log(id ? *id : "a command"));
    return false;
  } else if (e) {
    if (const auto size = screen_size(*e)) {
      std::lock_guard lock(mutex_);
      stats_.screen = size;
    }
    return false;  // ACKs and other messages need nothing
  }
  if (!record) {
    std::lock_guard lock(mutex_);
    ++stats_.malformed;
    stats_.last_malformed = error;
    return false;
  }
  handle_record(*record, receive_ns);
  return true;
}

void GazepointSource::handle_record(const Record& r, std::int64_t receive_ns) {
  if (silence_reported_) {
    problem_.set("");
    silence_reported_ = false;
  }
  // The arrival rules before the clock (arrival_guard.h): a flood must not teach it its time.
  const net::ArrivalGuard::Admission a = arrivals_.admit(receive_ns);
  if (a.within_pace && !a.flooding && clock_.anchored()) paced_clock_ = {clock_.offset_ns(), clock_.drift_ppm()};
  {
    std::lock_guard lock(mutex_);
    if (r.counter && last_counter_ && *r.counter > *last_counter_ + 1) stats_.counter_gaps += *r.counter - *last_counter_ - 1;
    if (r.counter) last_counter_ = r.counter;
    ++stats_.records;
    if (r.best_valid) ++stats_.valid;
    if (a.flood_began) {
      // What the flood's first records taught the clock is wrong: forget it, and show the mapping
      // as it was before them until the clock anchors afresh after the flood.
      clock_.reset();
      stats_.clock_offset_ns = paced_clock_.first;
      stats_.clock_drift_ppm = paced_clock_.second;
    }
  }
  if (!a.keep) return;
  std::int64_t mapped = receive_ns;
  if (r.time_s && !a.flooding) {
    mapped = arrivals_.not_after_arrival(clock_.map(static_cast<std::uint64_t>(std::llround(*r.time_s * 1e6)), receive_ns),
                                         receive_ns);
  }
  protocol::GazeSample s;
  s.tracker_time_ns = mapped;
  if (r.best_valid) {
    s.x = static_cast<float>(r.best_x);
    s.y = static_cast<float>(r.best_y);
    const protocol::Degrees d = protocol::normalized_to_degrees(display_, {r.best_x, r.best_y});
    s.x_deg = static_cast<float>(d.x);
    s.y_deg = static_cast<float>(d.y);
    s.confidence = 1;
    s.flags = protocol::kGazeValid;
  }
  s.left_gaze = eye_gaze(display_, r.left_pog);
  s.right_gaze = eye_gaze(display_, r.right_pog);
  if (r.left_pupil_mm) {
    s.left.flags |= protocol::kEyePupilValid;
    s.left.pupil_diameter_mm = static_cast<float>(*r.left_pupil_mm);
  }
  if (r.right_pupil_mm) {
    s.right.flags |= protocol::kEyePupilValid;
    s.right.pupil_diameter_mm = static_cast<float>(*r.right_pupil_mm);
  }
  if (!a.flooding) {
    delays_.add(receive_ns - mapped);
    std::lock_guard lock(mutex_);
    if (clock_.anchored()) {
      stats_.clock_offset_ns = clock_.offset_ns();
      stats_.clock_drift_ppm = clock_.drift_ppm();
    }
    stats_.clock_resets = clock_.resets();
    if (++delay_samples_ % 64 == 1) {
      stats_.delay_p50_ns = delays_.percentile(0.5);
      stats_.delay_p99_ns = delays_.percentile(0.99);
    }
  }
  queue_.push(s, receive_ns);
}

}  // namespace fovea::trackerd::gazepoint
