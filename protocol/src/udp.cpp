// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/udp.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <stdexcept>
#include <system_error>
#include <vector>

namespace fovea::protocol {

sockaddr_in Endpoint::to_sockaddr() const {
  sockaddr_in sa{};
  sa.sin_family = AF_INET;
  sa.sin_addr.s_addr = htonl(ip);
  sa.sin_port = htons(port);
  return sa;
}

Endpoint Endpoint::from_sockaddr(const sockaddr_in& sa) { return {ntohl(sa.sin_addr.s_addr), ntohs(sa.sin_port)}; }

std::string Endpoint::to_string() const {
  return std::to_string(ip >> 24) + "." + std::to_string((ip >> 16) & 0xFF) + "." + std::to_string((ip >> 8) & 0xFF) +
         "." + std::to_string(ip & 0xFF) + ":" + std::to_string(port);
}

Endpoint parse_endpoint(const std::string& text, std::uint16_t default_port) {
  std::string host = text;
  std::uint16_t port = default_port;
  if (const auto colon = text.rfind(':'); colon != std::string::npos) {
    host = text.substr(0, colon);
    const std::string port_text = text.substr(colon + 1);
    unsigned value = 0;
    const auto [ptr, ec] = std::from_chars(port_text.data(), port_text.data() + port_text.size(), value);
    if (ec != std::errc{} || ptr != port_text.data() + port_text.size() || value > 65535) {
      throw std::invalid_argument("address \"" + text + "\": port \"" + port_text + "\" is not a number in 0..65535");
    }
    port = static_cast<std::uint16_t>(value);
  }
  if (host.empty()) host = "0.0.0.0";
  in_addr addr{};
  if (inet_pton(AF_INET, host.c_str(), &addr) == 1) return {ntohl(addr.s_addr), port};
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* res = nullptr;
  if (const int rc = getaddrinfo(host.c_str(), nullptr, &hints, &res); rc != 0 || res == nullptr) {
    throw std::invalid_argument("address \"" + text + "\": cannot resolve host \"" + host + "\" to IPv4 (" +
                                gai_strerror(rc) + ")");
  }
  const auto* sa = reinterpret_cast<const sockaddr_in*>(res->ai_addr);
  const Endpoint ep{ntohl(sa->sin_addr.s_addr), port};
  freeaddrinfo(res);
  return ep;
}

UdpSocket UdpSocket::bind(Endpoint local, bool reuse_address) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::system_error(errno, std::generic_category(), "socket(AF_INET, SOCK_DGRAM)");
  UdpSocket s(fd);
  if (reuse_address) {
    const int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  }
  const sockaddr_in sa = local.to_sockaddr();
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&sa), sizeof sa) != 0) {
    throw std::system_error(errno, std::generic_category(), "cannot bind UDP " + local.to_string());
  }
  return s;
}

UdpSocket& UdpSocket::operator=(UdpSocket&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = o.fd_;
    o.fd_ = -1;
  }
  return *this;
}

UdpSocket::~UdpSocket() {
  if (fd_ >= 0) ::close(fd_);
}

Endpoint UdpSocket::local_endpoint() const {
  sockaddr_in sa{};
  socklen_t len = sizeof sa;
  getsockname(fd_, reinterpret_cast<sockaddr*>(&sa), &len);
  return Endpoint::from_sockaddr(sa);
}

bool UdpSocket::send_to(const Endpoint& to, std::span<const std::uint8_t> data) const {
  const sockaddr_in sa = to.to_sockaddr();
  const ssize_t n = ::sendto(fd_, data.data(), data.size(), MSG_DONTWAIT | MSG_NOSIGNAL,
                             reinterpret_cast<const sockaddr*>(&sa), sizeof sa);
  return n == static_cast<ssize_t>(data.size());
}

std::size_t UdpSocket::send_to_many(std::span<const Endpoint> to, std::span<const std::uint8_t> data) const {
  constexpr std::size_t kBatch = 64;
  sockaddr_in addrs[kBatch];
  mmsghdr msgs[kBatch];
  iovec iov{const_cast<std::uint8_t*>(data.data()), data.size()};
  std::size_t sent = 0;
  for (std::size_t base = 0; base < to.size(); base += kBatch) {
    const std::size_t n = std::min(kBatch, to.size() - base);
    for (std::size_t i = 0; i < n; ++i) {
      addrs[i] = to[base + i].to_sockaddr();
      msgs[i] = {};
      msgs[i].msg_hdr.msg_name = &addrs[i];
      msgs[i].msg_hdr.msg_namelen = sizeof(sockaddr_in);
      msgs[i].msg_hdr.msg_iov = &iov;
      msgs[i].msg_hdr.msg_iovlen = 1;
    }
    std::size_t done = 0;
    while (done < n) {
      const int r = ::sendmmsg(fd_, msgs + done, static_cast<unsigned>(n - done), MSG_DONTWAIT | MSG_NOSIGNAL);
      if (r <= 0) {
        // A full buffer or an unreachable peer must not stop the others: skip this one.
        if (r < 0 && errno == EINTR) continue;
        ++done;
        continue;
      }
      done += static_cast<std::size_t>(r);
      sent += static_cast<std::size_t>(r);
    }
  }
  return sent;
}

std::size_t UdpSocket::receive(std::span<std::uint8_t> buffer, Endpoint& from, int timeout_ms) const {
  pollfd p{fd_, POLLIN, 0};
  const int ready = ::poll(&p, 1, timeout_ms);
  if (ready <= 0) return 0;
  sockaddr_in sa{};
  socklen_t len = sizeof sa;
  // MSG_TRUNC makes recvfrom report the real datagram size, so oversized input is detected.
  const ssize_t n = ::recvfrom(fd_, buffer.data(), buffer.size(), MSG_DONTWAIT | MSG_TRUNC,
                               reinterpret_cast<sockaddr*>(&sa), &len);
  if (n <= 0) return 0;
  from = Endpoint::from_sockaddr(sa);
  return static_cast<std::size_t>(n);
}

void UdpSocket::join_multicast(std::uint32_t group_ip, std::uint32_t interface_ip) const {
  ip_mreq mreq{};
  mreq.imr_multiaddr.s_addr = htonl(group_ip);
  mreq.imr_interface.s_addr = htonl(interface_ip);
  if (setsockopt(fd_, IPPROTO_IP, IP_ADD_MEMBERSHIP, &mreq, sizeof mreq) != 0) {
    throw std::system_error(errno, std::generic_category(),
                            "cannot join multicast group " + Endpoint{group_ip, 0}.to_string());
  }
}

void UdpSocket::set_multicast_output(std::uint8_t ttl, std::uint32_t interface_ip, bool loopback) const {
  const int t = ttl;
  const unsigned char loop = loopback ? 1 : 0;
  setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_TTL, &t, sizeof t);
  setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof loop);
  if (interface_ip != 0) {
    in_addr ifaddr{};
    ifaddr.s_addr = htonl(interface_ip);
    if (setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_IF, &ifaddr, sizeof ifaddr) != 0) {
      throw std::system_error(errno, std::generic_category(),
                              "cannot send multicast through interface " + Endpoint{interface_ip, 0}.to_string());
    }
  }
}

void UdpSocket::set_receive_buffer(int bytes) const { setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &bytes, sizeof bytes); }

}  // namespace fovea::protocol
