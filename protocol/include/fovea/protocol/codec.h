// SPDX-License-Identifier: Apache-2.0
#pragma once
// Encoder and strict decoder for protocol v1 datagrams. The decoder accepts only datagrams whose
// every field is in range; anything else is rejected with a reason and never partly trusted.
#include <array>
#include <atomic>
#include <cstdint>
#include <span>
#include <vector>

#include "fovea/protocol/messages.h"

namespace fovea::protocol {

enum class DecodeError : std::uint8_t {
  Ok = 0,
  TooShort,          // shorter than the header, or than header + payload_length
  TooLong,           // longer than header + payload_length, or than kMaxDatagramSize
  BadMagic,
  BadVersion,
  UnknownType,
  BadPayloadLength,  // payload_length differs from the fixed size of the type
  ReservedNotZero,   // reserved bytes or flag bits set
  NonFinite,         // NaN or Inf in a floating-point field
  OutOfRange,        // enum or value outside its documented range
  BadString,         // text not NUL-terminated or NUL followed by non-NUL padding
};
inline constexpr std::size_t kDecodeErrorCount = 11;
const char* to_string(DecodeError e);

// Payload size in bytes of each message type (all v1 messages are fixed-size).
std::size_t payload_size(MessageType t);

// Encodes header + payload. header.type and header.payload_length are taken from the payload.
// Throws std::invalid_argument if a field cannot be encoded (non-finite float, text too long):
// nothing invalid ever reaches the wire.
std::vector<std::uint8_t> encode(const Message& m);
// The same into a caller-provided buffer (no allocation); returns bytes written.
std::size_t encode_into(const Message& m, std::span<std::uint8_t, kMaxDatagramSize> out);

struct DecodeResult {
  DecodeError error = DecodeError::Ok;
  std::size_t offset = 0;  // byte offset of the offending field, for diagnostics
  explicit operator bool() const { return error == DecodeError::Ok; }
};

DecodeResult decode(std::span<const std::uint8_t> datagram, Message& out);

// The payload codecs alone, used by recordings to store the same bytes as the wire.
void encode_payload(const Payload& p, std::span<std::uint8_t> out);
DecodeResult decode_payload(MessageType t, std::span<const std::uint8_t> in, Payload& out);

// Counts of rejected datagrams per reason; safe to bump from several threads.
class DecodeCounters {
 public:
  void count(DecodeError e) { counts_[static_cast<std::size_t>(e)].fetch_add(1, std::memory_order_relaxed); }
  std::uint64_t get(DecodeError e) const { return counts_[static_cast<std::size_t>(e)].load(std::memory_order_relaxed); }
  std::uint64_t rejected() const;

 private:
  std::array<std::atomic<std::uint64_t>, kDecodeErrorCount> counts_{};
};

}  // namespace fovea::protocol
