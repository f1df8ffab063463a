// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/cookie.h"

#include <sodium.h>

#include <cstring>
#include <stdexcept>

#include "fovea/protocol/wire.h"

namespace fovea::protocol {

namespace {
void init_sodium() {
  if (sodium_init() < 0) throw std::runtime_error("libsodium could not initialise (no entropy source?)");
}
}  // namespace

// libsodium's crypto_shorthash is SipHash-2-4 with a 16-byte key; its 8 bytes are the little-endian
// 64-bit value of the reference implementation.
std::uint64_t siphash24(const std::array<std::uint8_t, 16>& key, std::span<const std::uint8_t> data) {
  static_assert(crypto_shorthash_KEYBYTES == 16 && crypto_shorthash_BYTES == 8);
  std::array<std::uint8_t, crypto_shorthash_BYTES> out{};
  crypto_shorthash(out.data(), data.data(), data.size(), key.data());
  return wire::load_le<std::uint64_t>(out, 0);
}

CookieJar::CookieJar(std::uint32_t lifetime_ms) : lifetime_ms_(lifetime_ms) {
  init_sodium();
  crypto_shorthash_keygen(key_.data());
}

std::uint64_t CookieJar::mac(const Endpoint& peer, std::uint64_t nonce, std::uint64_t issued_ms) const {
  std::array<std::uint8_t, 22> msg{};
  wire::store_le<std::uint32_t>(msg, 0, peer.ip);
  wire::store_le<std::uint16_t>(msg, 4, peer.port);
  wire::store_le<std::uint64_t>(msg, 6, nonce);
  wire::store_le<std::uint64_t>(msg, 14, issued_ms);
  return siphash24(key_, msg);
}

Cookie CookieJar::issue(const Endpoint& peer, std::uint64_t client_nonce, std::int64_t now_ns) const {
  const auto issued_ms = static_cast<std::uint64_t>(now_ns / 1'000'000);
  Cookie c{};
  wire::store_le<std::uint64_t>(c, 0, issued_ms);
  wire::store_le<std::uint64_t>(c, 8, mac(peer, client_nonce, issued_ms));
  return c;
}

CookieCheck CookieJar::check(const Cookie& c, const Endpoint& peer, std::uint64_t client_nonce,
                             std::int64_t now_ns) const {
  const auto issued_ms = wire::load_le<std::uint64_t>(c, 0);
  std::array<std::uint8_t, 8> expected{};
  wire::store_le<std::uint64_t>(expected, 0, mac(peer, client_nonce, issued_ms));
  // In constant time: how many leading bytes of a forgery match must not show in the reply's timing.
  if (sodium_memcmp(expected.data(), c.data() + 8, expected.size()) != 0) return CookieCheck::Forged;
  const auto now_ms = static_cast<std::uint64_t>(now_ns / 1'000'000);
  if (issued_ms > now_ms || now_ms - issued_ms > lifetime_ms_) return CookieCheck::Expired;
  return CookieCheck::Valid;
}

}  // namespace fovea::protocol
