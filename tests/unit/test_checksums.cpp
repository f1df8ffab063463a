// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <string>

#include "fovea/protocol/clock.h"
#include "fovea/protocol/cookie.h"
#include "fovea/protocol/crc32c.h"

using namespace fovea::protocol;

namespace {
std::span<const std::uint8_t> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}
}  // namespace

TEST(Crc32c, KnownAnswers) {
  // RFC 3720 appendix B.4 and the common "123456789" check value.
  EXPECT_EQ(crc32c(bytes_of("123456789")), 0xE3069283u);
  const std::vector<std::uint8_t> zeros(32, 0x00), ones(32, 0xFF);
  EXPECT_EQ(crc32c(zeros), 0x8A9136AAu);
  EXPECT_EQ(crc32c(ones), 0x62A8AB43u);
  std::vector<std::uint8_t> inc(32);
  for (std::size_t i = 0; i < 32; ++i) inc[i] = static_cast<std::uint8_t>(i);
  EXPECT_EQ(crc32c(inc), 0x46DD794Eu);
  EXPECT_EQ(crc32c({}), 0u);
}

TEST(Crc32c, IncrementalEqualsOneShot) {
  const std::string text = "The quick brown fox jumps over the lazy dog, twice over for good measure.";
  for (std::size_t cut = 0; cut <= text.size(); ++cut) {
    const auto all = bytes_of(text);
    EXPECT_EQ(crc32c(all.subspan(cut), crc32c(all.first(cut))), crc32c(all)) << cut;
  }
}

TEST(SipHash, ReferenceVector) {
  // Aumasson & Bernstein, SipHash paper appendix A: key 00..0f, message 00..0e.
  std::array<std::uint8_t, 16> key{};
  for (std::size_t i = 0; i < 16; ++i) key[i] = static_cast<std::uint8_t>(i);
  std::vector<std::uint8_t> msg(15);
  for (std::size_t i = 0; i < 15; ++i) msg[i] = static_cast<std::uint8_t>(i);
  EXPECT_EQ(siphash24(key, msg), 0xa129ca6149be45e5ULL);
  EXPECT_EQ(siphash24(key, {}), 0x726fdb47dd0e0e31ULL);
}

TEST(Cookie, ValidOnlyForItsAddressNonceAndLifetime) {
  std::array<std::uint8_t, 16> key{};
  key[3] = 42;
  const CookieJar jar(key, 10'000);
  const Endpoint peer{0x7F000001, 40000};
  const std::int64_t t0 = 5'000'000'000;
  const Cookie c = jar.issue(peer, 77, t0);
  EXPECT_EQ(jar.check(c, peer, 77, t0 + 1'000'000'000), CookieCheck::Valid);
  EXPECT_EQ(jar.check(c, Endpoint{0x7F000001, 40001}, 77, t0), CookieCheck::Forged);
  EXPECT_EQ(jar.check(c, Endpoint{0x7F000002, 40000}, 77, t0), CookieCheck::Forged);
  EXPECT_EQ(jar.check(c, peer, 78, t0), CookieCheck::Forged);
  EXPECT_EQ(jar.check(c, peer, 77, t0 + 10'001'000'000), CookieCheck::Expired);
  Cookie tampered = c;
  tampered[0] ^= 1;  // claims another issue time
  EXPECT_EQ(jar.check(tampered, peer, 77, t0), CookieCheck::Forged);
  const CookieJar other_daemon(10'000);  // a restarted daemon has a new random key
  EXPECT_EQ(other_daemon.check(c, peer, 77, t0), CookieCheck::Forged);
}
