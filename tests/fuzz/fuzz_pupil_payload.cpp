// SPDX-License-Identifier: Apache-2.0
// libFuzzer entry point for a payload from a Pupil Capture publisher (sources/pupil/pupil_messages.h):
// whatever the bytes, as a surface event or a gaze datum, parsing returns gaze or a reason, never
// undefined behaviour, and what it returns holds finite numbers within the promised bounds.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <string>

#include "sources/pupil/pupil_messages.h"

namespace {
void check(const fovea::trackerd::pupil::PupilGaze& g) {
  if (!std::isfinite(g.x) || !std::isfinite(g.y_up) || std::abs(g.x) > 1e3 || std::abs(g.y_up) > 1e3) std::abort();
  if (!(g.confidence >= 0 && g.confidence <= 1)) std::abort();
  if (!std::isfinite(g.timestamp)) std::abort();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace fovea::trackerd::pupil;
  const std::span<const std::uint8_t> payload(data, size);
  std::string error;
  if (const auto surface = parse_surface_payload(payload, "screen", error)) {
    for (const PupilGaze& g : *surface) check(g);
  } else if (error.empty()) {
    std::abort();
  }
  error.clear();
  if (const auto g = parse_gaze_payload(payload, error)) {
    check(*g);
  } else if (error.empty()) {
    std::abort();
  }
  return 0;
}
