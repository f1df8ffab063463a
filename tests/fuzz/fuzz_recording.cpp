// SPDX-License-Identifier: Apache-2.0
// libFuzzer entry point for the recording reader: any byte string either is rejected as "not a
// recording" or yields intact records that re-encode to bytes present in the input.
#include <cstdint>
#include <cstdlib>
#include <span>
#include <stdexcept>

#include "fovea/protocol/recording.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace fovea::protocol;
  try {
    const Recording rec = parse_recording(std::span<const std::uint8_t>(data, size));
    if (rec.report.records != rec.records.size()) std::abort();
    if (rec.report.bytes_skipped > size) std::abort();
    for (const Record& r : rec.records) {
      if (encode_record(r).size() > size) std::abort();
    }
  } catch (const std::runtime_error&) {
    // Not a recording: a clean refusal is the correct outcome.
  }
  return 0;
}
