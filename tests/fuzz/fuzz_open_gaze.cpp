// SPDX-License-Identifier: Apache-2.0
// libFuzzer entry point for a line from a Gazepoint server (sources/gazepoint/open_gaze.h): whatever
// the bytes, parsing returns an element or a reason, never undefined behaviour; a record it accepts
// holds finite numbers within the bounds parse_record promises.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "sources/gazepoint/open_gaze.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace fovea::trackerd::gazepoint;
  const std::string_view line(reinterpret_cast<const char*>(data), size);
  std::string error;
  const auto e = parse_element(line, error);
  if (!e) {
    if (error.empty()) std::abort();  // a refusal always says why
    return 0;
  }
  (void)screen_size(*e);
  const auto r = parse_record(*e, error);
  if (!r) return 0;
  if (!std::isfinite(r->best_x) || !std::isfinite(r->best_y)) std::abort();
  if (r->best_x < -1 || r->best_x > 2 || r->best_y < -1 || r->best_y > 2) std::abort();
  if (r->time_s && !(*r->time_s >= 0 && *r->time_s <= 1e9)) std::abort();
  if (r->left_pupil_mm && !(*r->left_pupil_mm > 0 && *r->left_pupil_mm <= 20)) std::abort();
  return 0;
}
