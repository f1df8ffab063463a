// SPDX-License-Identifier: Apache-2.0
#pragma once
// Little-endian field access on byte buffers. Callers check bounds once per message (all v1
// messages are fixed-size), so these helpers only assert in debug builds.
#include <bit>
#include <cassert>
#include <cstdint>
#include <cstring>
#include <span>
#include <type_traits>

namespace fovea::protocol::wire {

template <typename T>
T load_le(std::span<const std::uint8_t> buf, std::size_t offset) {
  static_assert(std::is_trivially_copyable_v<T>);
  assert(offset + sizeof(T) <= buf.size());
  std::uint8_t bytes[sizeof(T)];
  for (std::size_t i = 0; i < sizeof(T); ++i) {
    bytes[i] = buf[offset + (std::endian::native == std::endian::little ? i : sizeof(T) - 1 - i)];
  }
  T value;
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}

template <typename T>
void store_le(std::span<std::uint8_t> buf, std::size_t offset, T value) {
  static_assert(std::is_trivially_copyable_v<T>);
  assert(offset + sizeof(T) <= buf.size());
  std::uint8_t bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  for (std::size_t i = 0; i < sizeof(T); ++i) {
    buf[offset + (std::endian::native == std::endian::little ? i : sizeof(T) - 1 - i)] = bytes[i];
  }
}

}  // namespace fovea::protocol::wire
