// SPDX-License-Identifier: Apache-2.0
#include "sources/network_common.h"

#include <algorithm>
#include <charconv>
#include <chrono>

#include "fovea/protocol/bounded_file.h"

namespace fovea::trackerd::net {

namespace {
constexpr std::size_t kQueueCapacity = 4096;
}

HostPort parse_host_port(std::string text, std::uint16_t default_port,
                         const std::function<std::invalid_argument(const std::string&)>& bad) {
  HostPort out{{}, default_port};
  if (const std::size_t colon = text.rfind(':'); colon != std::string::npos) {
    const std::string p = text.substr(colon + 1);
    unsigned port = 0;
    const auto r = std::from_chars(p.data(), p.data() + p.size(), port);
    if (p.empty() || r.ec != std::errc{} || r.ptr != p.data() + p.size() || port < 1 || port > 65535) {
      throw bad("\"" + protocol::escape_for_log(p) + "\" is not a port (1..65535)");
    }
    out.port = static_cast<std::uint16_t>(port);
    text.resize(colon);
  }
  if (text.empty()) throw bad("no host");
  for (const char c : text) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '-';
    if (!ok) throw bad("the host \"" + protocol::escape_for_log(text) + "\" is not an IPv4 address or a host name");
  }
  out.host = std::move(text);
  return out;
}

void SampleQueue::push(const protocol::GazeSample& s, std::int64_t receive_ns) {
  std::lock_guard lock(mutex_);
  if (queue_.size() == kQueueCapacity) {
    queue_.pop_front();
    ++dropped_;
  }
  queue_.push_back({s, receive_ns});
  ready_.notify_all();
}

std::optional<GazeItem> SampleQueue::next() {
  std::unique_lock lock(mutex_);
  ready_.wait_for(lock, std::chrono::milliseconds(50), [&] { return !queue_.empty() || interrupted_; });
  interrupted_ = false;
  if (queue_.empty()) return std::nullopt;
  const Entry e = queue_.front();
  queue_.pop_front();
  last_receive_ns_ = e.receive_ns;
  return GazeItem{e.sample};
}

void SampleQueue::interrupt() {
  std::lock_guard lock(mutex_);
  interrupted_ = true;
  ready_.notify_all();
}

void DelayWindow::add(std::int64_t delay_ns) {
  constexpr std::size_t kWindow = 1024;
  if (ring_.size() < kWindow) {
    ring_.push_back(delay_ns);
  } else {
    ring_[next_] = delay_ns;
    next_ = (next_ + 1) % kWindow;
  }
}

std::int64_t DelayWindow::percentile(double q) const {
  if (ring_.empty()) return 0;
  std::vector<std::int64_t> v = ring_;
  const auto k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

std::uint64_t SampleQueue::dropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}

}  // namespace fovea::trackerd::net
