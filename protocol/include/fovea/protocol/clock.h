// SPDX-License-Identifier: Apache-2.0
#pragma once
// Time in fovea is int64 nanoseconds of CLOCK_MONOTONIC on the producing machine.
#include <cstdint>
#include <ctime>

namespace fovea::protocol {

inline std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

inline std::int64_t realtime_ns() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace fovea::protocol
