// SPDX-License-Identifier: Apache-2.0
// The gaze protocol codec: round trips, golden vectors, and a strict decoder.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <random>
#include <set>
#include <sstream>

#include "canonical_messages.h"
#include "fovea/protocol/codec.h"
#include "fovea/protocol/wire.h"

using namespace fovea::protocol;

namespace {

std::vector<std::uint8_t> read_hex_file(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in) << "missing golden file " << path;
  std::vector<std::uint8_t> bytes;
  std::string token;
  while (in >> token) bytes.push_back(static_cast<std::uint8_t>(std::stoul(token, nullptr, 16)));
  return bytes;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string to_hex_lines(const std::vector<std::uint8_t>& bytes) {
  std::string hex;
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    char buf[4];
    std::snprintf(buf, sizeof buf, "%02x", bytes[i]);
    hex += buf;
    hex += (i % 16 == 15 || i + 1 == bytes.size()) ? "\n" : " ";
  }
  return hex;
}

}  // namespace

TEST(Codec, EveryMessageTypeRoundTrips) {
  const auto messages = fovea::test::canonical_messages();
  ASSERT_GE(messages.size(), kMaxMessageType);
  for (std::size_t i = 0; i < kMaxMessageType; ++i) {
    EXPECT_EQ(static_cast<std::size_t>(messages[i].second.header.type), i + 1) << "one canonical example per type, in order";
  }
  for (const auto& [name, m] : messages) {
    const auto bytes = encode(m);
    EXPECT_EQ(bytes.size(), kHeaderSize + payload_size(m.header.type)) << name;
    Message back;
    const DecodeResult r = decode(bytes, back);
    ASSERT_TRUE(r) << name << ": " << to_string(r.error) << " at " << r.offset;
    back.header.payload_length = 0;
    Message expected = m;
    expected.header.payload_length = 0;
    EXPECT_EQ(back, expected) << name;
  }
}

TEST(Codec, GoldenVectorsAreStable) {
  // Any change to the wire format changes these bytes; regenerate them only with a version bump.
  for (const auto& [name, m] : fovea::test::canonical_messages()) {
    const auto golden = read_hex_file(std::string(FOVEA_TEST_DATA) + "/golden/" + name + ".hex");
    EXPECT_EQ(encode(m), golden) << name << " no longer encodes to tests/data/golden/" << name << ".hex";
    Message back;
    ASSERT_TRUE(decode(golden, back)) << name;
    EXPECT_EQ(back.payload, m.payload) << name;
  }
}

TEST(Codec, ProtocolDocumentCarriesEveryGoldenVector) {
  const std::string doc = read_text(std::string(FOVEA_SOURCE_DIR) + "/protocol/PROTOCOL.md");
  for (const auto& [name, m] : fovea::test::canonical_messages()) {
    EXPECT_NE(doc.find(to_hex_lines(encode(m))), std::string::npos)
        << "protocol/PROTOCOL.md lacks the worked example of " << name << " (regenerate with fovea-protocol-examples)";
  }
}

TEST(Codec, SizesNeverAmplify) {
  // Unauthenticated replies are never larger than the request that triggers them.
  const auto total = [](MessageType t) { return kHeaderSize + payload_size(t); };
  EXPECT_GE(total(MessageType::Hello), total(MessageType::Challenge));
  EXPECT_GE(total(MessageType::StatusRequest), total(MessageType::StatusReply));
  EXPECT_GE(total(MessageType::TimeSyncRequest), total(MessageType::TimeSyncReply));
  EXPECT_GE(total(MessageType::Heartbeat), total(MessageType::Heartbeat));
  for (std::uint8_t t = 1; t <= kMaxMessageType; ++t) {
    EXPECT_LE(total(MessageType::Error), total(static_cast<MessageType>(t)) + 8)
        << "ERROR must stay small: it answers requests of any size";
    EXPECT_LE(total(static_cast<MessageType>(t)), kMaxDatagramSize);
  }
}

TEST(Decoder, RejectsEveryTruncationOfEveryMessage) {
  DecodeCounters counters;
  std::size_t cases = 0;
  for (const auto& [name, m] : fovea::test::canonical_messages()) {
    const auto bytes = encode(m);
    for (std::size_t len = 0; len < bytes.size(); ++len) {
      Message out;
      const DecodeResult r = decode(std::span<const std::uint8_t>(bytes.data(), len), out);
      ASSERT_FALSE(r) << name << " cut to " << len << " bytes was accepted";
      EXPECT_EQ(r.error, DecodeError::TooShort) << name << " cut to " << len;
      counters.count(r.error);
      ++cases;
    }
  }
  EXPECT_EQ(counters.get(DecodeError::TooShort), cases);
  EXPECT_EQ(counters.rejected(), cases);
}

TEST(Decoder, RejectsTrailingBytesOversizeMagicVersionTypeAndLength) {
  for (const auto& [name, m] : fovea::test::canonical_messages()) {
    const auto good = encode(m);
    Message out;
    auto longer = good;
    longer.push_back(0);
    EXPECT_EQ(decode(longer, out).error, DecodeError::TooLong) << name;

    auto bad_magic = good;
    bad_magic[1] ^= 0x20;
    EXPECT_EQ(decode(bad_magic, out).error, DecodeError::BadMagic) << name;

    auto bad_version = good;
    bad_version[4] = 2;
    EXPECT_EQ(decode(bad_version, out).error, DecodeError::BadVersion) << name;
    bad_version[4] = 0;
    EXPECT_EQ(decode(bad_version, out).error, DecodeError::BadVersion) << name;

    auto bad_type = good;
    bad_type[5] = 0;
    EXPECT_EQ(decode(bad_type, out).error, DecodeError::UnknownType) << name;
    bad_type[5] = kMaxMessageType + 1;
    EXPECT_EQ(decode(bad_type, out).error, DecodeError::UnknownType) << name;

    // A payload length that disagrees with the type, whether or not the datagram size matches it.
    auto bad_length = good;
    wire::store_le<std::uint16_t>(bad_length, 6, static_cast<std::uint16_t>(payload_size(m.header.type) + 4));
    EXPECT_EQ(decode(bad_length, out).error, DecodeError::BadPayloadLength) << name;
    bad_length.resize(bad_length.size() + 4, 0);
    EXPECT_EQ(decode(bad_length, out).error, DecodeError::BadPayloadLength) << name;
  }
  std::vector<std::uint8_t> huge(kMaxDatagramSize + 1, 0);
  Message out;
  EXPECT_EQ(decode(huge, out).error, DecodeError::TooLong);
}

TEST(Decoder, RejectsNonFiniteFloatsInEveryFloatField) {
  const auto messages = fovea::test::canonical_messages();
  const auto& sample = messages[6].second;
  ASSERT_EQ(sample.header.type, MessageType::GazeSample);
  const auto good = encode(sample);
  // GAZE_SAMPLE float fields: 8..31 and the two eyes at 36..75 (see PROTOCOL.md).
  std::vector<std::size_t> float_offsets;
  for (std::size_t off = 8; off < 32; off += 4) float_offsets.push_back(kHeaderSize + off);
  for (std::size_t off = 36; off < 76; off += 4) float_offsets.push_back(kHeaderSize + off);
  for (const float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                          -std::numeric_limits<float>::infinity()}) {
    for (const std::size_t off : float_offsets) {
      auto bytes = good;
      wire::store_le<float>(bytes, off, bad);
      Message out;
      const DecodeResult r = decode(bytes, out);
      EXPECT_EQ(r.error, DecodeError::NonFinite) << "offset " << off;
      EXPECT_EQ(r.offset, off);
    }
  }
}

TEST(Decoder, RejectsOutOfRangeFieldsAndReservedBits) {
  const auto messages = fovea::test::canonical_messages();
  const auto mutate = [&](std::size_t index, auto&& f) {
    auto bytes = encode(messages[index].second);
    f(bytes);
    Message out;
    return decode(bytes, out).error;
  };
  constexpr std::size_t H = kHeaderSize;
  // GAZE_SAMPLE (index 6)
  EXPECT_EQ(mutate(6, [](auto& b) { wire::store_le<float>(b, H + 28, 1.5f); }), DecodeError::OutOfRange);
  EXPECT_EQ(mutate(6, [](auto& b) { wire::store_le<float>(b, H + 28, -0.1f); }), DecodeError::OutOfRange);
  EXPECT_EQ(mutate(6, [](auto& b) { wire::store_le<float>(b, H + 24, -1.0f); }), DecodeError::OutOfRange);
  EXPECT_EQ(mutate(6, [](auto& b) { b[H + 32] = kMaxEyeMovement + 1; }), DecodeError::OutOfRange);
  EXPECT_EQ(mutate(6, [](auto& b) { b[H + 33] = 0x80; }), DecodeError::ReservedNotZero);
  EXPECT_EQ(mutate(6, [](auto& b) { b[H + 34] = 0x04; }), DecodeError::ReservedNotZero);
  EXPECT_EQ(mutate(6, [](auto& b) { wire::store_le<float>(b, H + 44, -3.0f); }), DecodeError::OutOfRange);
  // GAZE_EVENT (index 7)
  EXPECT_EQ(mutate(7, [](auto& b) { b[H + 0] = 0; }), DecodeError::OutOfRange);
  EXPECT_EQ(mutate(7, [](auto& b) { b[H + 1] = 3; }), DecodeError::OutOfRange);
  EXPECT_EQ(mutate(7, [](auto& b) { b[H + 5] = 1; }), DecodeError::ReservedNotZero);
  EXPECT_EQ(mutate(7, [](auto& b) { wire::store_le<std::int64_t>(b, H + 16, -1); }), DecodeError::OutOfRange);
  // GAZE_EVENT flags (byte 2): unknown bits, and a retraction that is not of a provisional event
  EXPECT_EQ(mutate(7, [](auto& b) { b[H + 2] = 0x04; }), DecodeError::ReservedNotZero);
  EXPECT_EQ(mutate(7, [](auto& b) { b[H + 2] = kEventRetracted; }), DecodeError::OutOfRange);
  EXPECT_EQ(mutate(7, [](auto& b) { b[H + 2] = kEventProvisional; }), DecodeError::Ok);
  EXPECT_EQ(mutate(7, [](auto& b) { b[H + 2] = kEventProvisional | kEventRetracted; }), DecodeError::Ok);
  EXPECT_EQ(mutate(7, [](auto& b) { b[H + 3] = 1; }), DecodeError::ReservedNotZero);
  // HELLO (index 0): name without terminator, garbage after terminator, reserved tail
  EXPECT_EQ(mutate(0, [](auto& b) { std::fill(b.begin() + H + 8, b.begin() + H + 40, 'a'); }), DecodeError::BadString);
  EXPECT_EQ(mutate(0, [](auto& b) { b[H + 38] = 'x'; }), DecodeError::BadString);
  EXPECT_EQ(mutate(0, [](auto& b) { b[H + 47] = 1; }), DecodeError::ReservedNotZero);
  // SUBSCRIBE (index 2): no streams, unknown stream bits
  EXPECT_EQ(mutate(2, [](auto& b) { wire::store_le<std::uint32_t>(b, H + 24, 0); }), DecodeError::OutOfRange);
  EXPECT_EQ(mutate(2, [](auto& b) { wire::store_le<std::uint32_t>(b, H + 24, 32); }), DecodeError::OutOfRange);
  EXPECT_EQ(mutate(2, [](auto& b) { wire::store_le<std::uint32_t>(b, H + 24, kStreamEyes); }), DecodeError::Ok);
  EXPECT_EQ(mutate(2, [](auto& b) { wire::store_le<std::uint32_t>(b, H + 24, kStreamProvisional); }), DecodeError::Ok);
  // SUBSCRIBED (index 3): zero-sized display, negative distance
  EXPECT_EQ(mutate(3, [](auto& b) { wire::store_le<std::uint32_t>(b, H + 40, 0); }), DecodeError::OutOfRange);
  EXPECT_EQ(mutate(3, [](auto& b) { wire::store_le<double>(b, H + 64, -0.5); }), DecodeError::OutOfRange);
  // STATUS_REQUEST (index 8): padding must be zero
  EXPECT_EQ(mutate(8, [](auto& b) { b[H + 100] = 1; }), DecodeError::ReservedNotZero);
  // ERROR (index 12): unknown code, unknown request type
  EXPECT_EQ(mutate(12, [](auto& b) { wire::store_le<std::uint16_t>(b, H, 99); }), DecodeError::OutOfRange);
  EXPECT_EQ(mutate(12, [](auto& b) { b[H + 2] = 0; }), DecodeError::OutOfRange);
}

TEST(Decoder, MarkerLabelsArePrintableUtf8AndItsFieldsConsistent) {
  const auto messages = fovea::test::canonical_messages();
  const std::size_t index = 15;
  ASSERT_EQ(messages[index].first, "marker");
  const auto mutate = [&](auto&& f) {
    auto bytes = encode(messages[index].second);
    f(bytes);
    Message out;
    return decode(bytes, out);
  };
  constexpr std::size_t H = kHeaderSize, L = H + 40;  // the label
  const auto label = [&](const std::string& text) {
    return mutate([&](auto& b) {
      std::fill(b.begin() + L, b.begin() + L + 64, 0);
      std::copy(text.begin(), text.end(), b.begin() + L);
    });
  };
  EXPECT_TRUE(label("Reiz an: \xc3\xa4\xe2\x82\xac \\ \"quoted\", comma"));  // UTF-8, backslash, quotes
  EXPECT_EQ(label("").error, DecodeError::BadString);
  const DecodeResult newline = label("trial 1\nforged log line");
  EXPECT_EQ(newline.error, DecodeError::BadString);
  EXPECT_EQ(newline.offset, L + 7) << "the offset names the offending byte";
  EXPECT_EQ(label("esc \x1b[2J").error, DecodeError::BadString);
  EXPECT_EQ(label("del \x7f").error, DecodeError::BadString);
  EXPECT_EQ(label("c1 \xc2\x9b").error, DecodeError::BadString);
  EXPECT_EQ(label("latin-1 \xe4").error, DecodeError::BadString);
  EXPECT_EQ(label("overlong \xc0\xaf").error, DecodeError::BadString);
  EXPECT_EQ(label("surrogate \xed\xa0\x80").error, DecodeError::BadString);
  EXPECT_EQ(label("cut \xe2\x82").error, DecodeError::BadString);
  EXPECT_EQ(mutate([&](auto& b) { b[L + 30] = 'x'; }).error, DecodeError::BadString);  // after the NUL
  EXPECT_EQ(mutate([&](auto& b) { wire::store_le<std::uint64_t>(b, H + 8, 0); }).error, DecodeError::OutOfRange);
  EXPECT_EQ(mutate([&](auto& b) { b[H + 32] = 2; }).error, DecodeError::ReservedNotZero);
  EXPECT_EQ(mutate([&](auto& b) { b[H + 35] = 1; }).error, DecodeError::ReservedNotZero);
  // Without the sender's-time flag, time_ns must be the receive time: nothing half-meant.
  EXPECT_EQ(mutate([&](auto& b) { b[H + 32] = 0; }).error, DecodeError::OutOfRange);
  EXPECT_TRUE(mutate([&](auto& b) {
    b[H + 32] = 0;
    wire::store_le<std::int64_t>(b, H + 16, 1'002'000'000);
  }));
}

// GAZE_EYES (PROTOCOL.md §4.18): flag bits, reserved bytes, zeros for an invalid eye, one eye at least.
TEST(Decoder, GazeEyesCarriesAtLeastOneValidEyeAndZerosForAnInvalidOne) {
  const auto messages = fovea::test::canonical_messages();
  const std::size_t index = 16;
  ASSERT_EQ(messages[index].first, "gaze_eyes");
  const auto mutate = [&](auto&& f) {
    auto bytes = encode(messages[index].second);
    f(bytes);
    Message out;
    const DecodeResult r = decode(bytes, out);
    return std::pair{r, out};
  };
  constexpr std::size_t H = kHeaderSize;
  const auto result = [](const DecodeResult& r) { return std::pair{r.error, r.offset}; };
  EXPECT_EQ(result(mutate([](auto& b) { b[H + 9] = 0x02; }).first), std::pair(DecodeError::ReservedNotZero, H + 9));
  EXPECT_EQ(mutate([](auto& b) { b[H + 15] = 1; }).first.error, DecodeError::ReservedNotZero);
  EXPECT_EQ(result(mutate([](auto& b) { wire::store_le<float>(b, H + 40, std::numeric_limits<float>::infinity()); }).first),
            std::pair(DecodeError::NonFinite, H + 40));
  // The left eye marked invalid but its numbers left in: refused, at the eye's first field.
  EXPECT_EQ(result(mutate([](auto& b) { b[H + 8] = 0; }).first), std::pair(DecodeError::OutOfRange, H + 16));
  // Only the right eye: fine. Neither: refused.
  const auto [right_only, eyes] = mutate([](auto& b) {
    b[H + 8] = 0;
    std::fill(b.begin() + H + 16, b.begin() + H + 32, 0);
  });
  ASSERT_TRUE(right_only);
  const auto& e = std::get<GazeEyes>(eyes.payload);
  EXPECT_FALSE(e.left.valid());
  EXPECT_TRUE(e.right.valid());
  EXPECT_FLOAT_EQ(e.right.x, 0.53125f);
  EXPECT_EQ(result(mutate([](auto& b) {
              b[H + 8] = b[H + 9] = 0;
              std::fill(b.begin() + H + 16, b.begin() + H + 48, 0);
            }).first),
            std::pair(DecodeError::OutOfRange, H + 8));
}

TEST(Decoder, SurvivesAHundredThousandRandomDatagrams) {
  std::mt19937_64 rng(20261122);
  DecodeCounters counters;
  std::size_t accepted = 0;
  const auto messages = fovea::test::canonical_messages();
  for (int i = 0; i < 100'000; ++i) {
    std::vector<std::uint8_t> d;
    const int kind = static_cast<int>(rng() % 3);
    if (kind == 0) {
      d.resize(rng() % (kMaxDatagramSize + 64));  // pure noise
      for (auto& b : d) b = static_cast<std::uint8_t>(rng());
    } else {
      // A valid header with noise after it, or a valid message with a few bytes changed: these
      // reach the payload checks, which pure noise rarely does.
      d = encode(messages[rng() % messages.size()].second);
      const int flips = 1 + static_cast<int>(rng() % 4);
      for (int f = 0; f < flips; ++f) {
        const std::size_t at = kind == 1 ? kHeaderSize + rng() % (d.size() - kHeaderSize) : rng() % d.size();
        d[at] = static_cast<std::uint8_t>(rng());
      }
    }
    Message out;
    const DecodeResult r = decode(d, out);
    if (r) {
      ++accepted;
      EXPECT_EQ(encode(out), d) << "an accepted datagram must be exactly what its fields encode to";
    } else {
      counters.count(r.error);
    }
  }
  EXPECT_EQ(counters.rejected() + accepted, 100'000u);
  EXPECT_GT(counters.get(DecodeError::BadMagic), 0u);
  EXPECT_GT(counters.get(DecodeError::NonFinite) + counters.get(DecodeError::OutOfRange) +
                counters.get(DecodeError::ReservedNotZero),
            0u);
}

TEST(Encoder, RefusesWhatTheDecoderWouldReject) {
  GazeSample s;
  s.x = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(encode(Message{Header{}, s}), std::invalid_argument);
  s.x = 0.5f;
  s.confidence = 2.0f;
  EXPECT_THROW(encode(Message{Header{}, s}), std::invalid_argument);
  Hello h;
  h.client_name.value = std::string(40, 'n');
  EXPECT_THROW(encode(Message{Header{}, h}), std::invalid_argument);
  StatusReply st;
  st.display.width_m = std::numeric_limits<double>::infinity();
  EXPECT_THROW(encode(Message{Header{}, st}), std::invalid_argument);
}

TEST(Decoder, ErrorNamesAreDistinct) {
  std::set<std::string> names;
  for (std::size_t i = 0; i < kDecodeErrorCount; ++i) names.insert(to_string(static_cast<DecodeError>(i)));
  EXPECT_EQ(names.size(), kDecodeErrorCount);
}
