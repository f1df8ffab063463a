// SPDX-License-Identifier: Apache-2.0
#pragma once
// Stateless subscription cookies (in the spirit of TCP SYN cookies and DTLS HelloVerifyRequest):
// the server proves a subscriber receives at the address it claims without keeping state for
// addresses that never complete the handshake.
#include <array>
#include <cstdint>
#include <span>

#include "fovea/protocol/messages.h"
#include "fovea/protocol/udp.h"

namespace fovea::protocol {

// SipHash-2-4 (Aumasson & Bernstein 2012), a keyed PRF over short inputs: libsodium's
// crypto_shorthash, as the reference's 64-bit little-endian value.
std::uint64_t siphash24(const std::array<std::uint8_t, 16>& key, std::span<const std::uint8_t> data);

enum class CookieCheck { Valid, Forged, Expired };

class CookieJar {
 public:
  // A random key from libsodium's generator; a restarted daemon therefore rejects the old daemon's cookies.
  explicit CookieJar(std::uint32_t lifetime_ms);
  CookieJar(const std::array<std::uint8_t, 16>& key, std::uint32_t lifetime_ms) : key_(key), lifetime_ms_(lifetime_ms) {}

  // Cookie layout: issue time (u64 ms, server monotonic clock) | SipHash(key, ip, port, nonce, time).
  Cookie issue(const Endpoint& peer, std::uint64_t client_nonce, std::int64_t now_ns) const;
  CookieCheck check(const Cookie& c, const Endpoint& peer, std::uint64_t client_nonce, std::int64_t now_ns) const;
  std::uint32_t lifetime_ms() const { return lifetime_ms_; }

 private:
  std::uint64_t mac(const Endpoint& peer, std::uint64_t nonce, std::uint64_t issued_ms) const;
  std::array<std::uint8_t, 16> key_{};
  std::uint32_t lifetime_ms_;
};

}  // namespace fovea::protocol
