// SPDX-License-Identifier: Apache-2.0
// libFuzzer entry point for the datagram decoder: whatever the bytes, decode() must return a
// verdict without undefined behaviour, and anything it accepts must re-encode to the same bytes.
#include <cstdint>
#include <cstdlib>
#include <span>

#include "fovea/protocol/codec.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace fovea::protocol;
  Message m;
  const DecodeResult r = decode(std::span<const std::uint8_t>(data, size), m);
  if (r) {
    const auto again = encode(m);
    if (again.size() != size) std::abort();
    for (std::size_t i = 0; i < size; ++i) {
      if (again[i] != data[i]) std::abort();
    }
  }
  return 0;
}
