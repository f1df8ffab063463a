// SPDX-License-Identifier: Apache-2.0
#include "pipeline/finite_check.h"

#include <cmath>
#include <cstdio>

namespace fovea::render {
namespace {

std::string describe(const std::string& pass, const std::string& buffer, std::size_t index, std::uint32_t width, double value) {
  char where[64];
  if (width > 0)
    std::snprintf(where, sizeof where, "pixel (%zu, %zu)", index % width, index / width);
  else
    std::snprintf(where, sizeof where, "element %zu", index);
  return "pass '" + pass + "' wrote a non-finite value (" + (std::isnan(value) ? "NaN" : value > 0 ? "+Inf" : "-Inf") +
         ") to " + buffer + " at " + where + " (the module boundary check, debug.finite_checks)";
}

template <typename T, int N>
void scan(const char* pass, const char* buffer, std::span<const T> values, std::uint32_t width) {
  for (std::size_t i = 0; i < values.size(); ++i) {
    if constexpr (N == 1) {
      if (!std::isfinite(values[i])) throw NonFiniteError(pass, buffer, i, width, static_cast<double>(values[i]));
    } else {
      for (int c = 0; c < N; ++c)
        if (!std::isfinite(values[i][c])) throw NonFiniteError(pass, buffer, i, width, static_cast<double>(values[i][c]));
    }
  }
}

}  // namespace

NonFiniteError::NonFiniteError(std::string pass, std::string buffer, std::size_t index, std::uint32_t width, double value)
    : std::runtime_error(describe(pass, buffer, index, width, value)), pass_(std::move(pass)), buffer_(std::move(buffer)), index_(index) {}

void require_finite(const char* pass, const char* buffer, std::span<const float> values, std::uint32_t width) {
  scan<float, 1>(pass, buffer, values, width);
}
void require_finite(const char* pass, const char* buffer, std::span<const glm::vec2> values, std::uint32_t width) {
  scan<glm::vec2, 2>(pass, buffer, values, width);
}
void require_finite(const char* pass, const char* buffer, std::span<const glm::vec3> values, std::uint32_t width) {
  scan<glm::vec3, 3>(pass, buffer, values, width);
}
void require_finite(const char* pass, const char* buffer, std::span<const double> values, std::uint32_t width) {
  scan<double, 1>(pass, buffer, values, width);
}

}  // namespace fovea::render
