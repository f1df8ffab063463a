#include "fovea/protocol/cookie.h"

#include <sys/random.h>

#include <cerrno>
#include <system_error>

#include "fovea/protocol/wire.h"

namespace fovea::protocol {

namespace {
constexpr std::uint64_t rotl(std::uint64_t x, int b) { return (x << b) | (x >> (64 - b)); }

void sipround(std::uint64_t& v0, std::uint64_t& v1, std::uint64_t& v2, std::uint64_t& v3) {
  v0 += v1; v1 = rotl(v1, 13); v1 ^= v0; v0 = rotl(v0, 32);
  v2 += v3; v3 = rotl(v3, 16); v3 ^= v2;
  v0 += v3; v3 = rotl(v3, 21); v3 ^= v0;
  v2 += v1; v1 = rotl(v1, 17); v1 ^= v2; v2 = rotl(v2, 32);
}
}  // namespace

std::uint64_t siphash24(const std::array<std::uint8_t, 16>& key, std::span<const std::uint8_t> data) {
  const std::uint64_t k0 = wire::load_le<std::uint64_t>(key, 0);
  const std::uint64_t k1 = wire::load_le<std::uint64_t>(key, 8);
  std::uint64_t v0 = 0x736f6d6570736575ULL ^ k0, v1 = 0x646f72616e646f6dULL ^ k1;
  std::uint64_t v2 = 0x6c7967656e657261ULL ^ k0, v3 = 0x7465646279746573ULL ^ k1;
  const std::size_t n = data.size();
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const std::uint64_t m = wire::load_le<std::uint64_t>(data, i);
    v3 ^= m;
    sipround(v0, v1, v2, v3);
    sipround(v0, v1, v2, v3);
    v0 ^= m;
  }
  std::uint64_t b = static_cast<std::uint64_t>(n) << 56;
  for (std::size_t j = 0; i + j < n; ++j) b |= static_cast<std::uint64_t>(data[i + j]) << (8 * j);
  v3 ^= b;
  sipround(v0, v1, v2, v3);
  sipround(v0, v1, v2, v3);
  v0 ^= b;
  v2 ^= 0xff;
  for (int r = 0; r < 4; ++r) sipround(v0, v1, v2, v3);
  return v0 ^ v1 ^ v2 ^ v3;
}

CookieJar::CookieJar(std::uint32_t lifetime_ms) : lifetime_ms_(lifetime_ms) {
  if (getrandom(key_.data(), key_.size(), 0) != static_cast<ssize_t>(key_.size())) {
    throw std::system_error(errno, std::generic_category(), "getrandom for the cookie key");
  }
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
  if (wire::load_le<std::uint64_t>(c, 8) != mac(peer, client_nonce, issued_ms)) return CookieCheck::Forged;
  const auto now_ms = static_cast<std::uint64_t>(now_ns / 1'000'000);
  if (issued_ms > now_ms || now_ms - issued_ms > lifetime_ms_) return CookieCheck::Expired;
  return CookieCheck::Valid;
}

}  // namespace fovea::protocol
