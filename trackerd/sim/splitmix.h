// SPDX-License-Identifier: Apache-2.0
#pragma once
// The synthetic eye's random numbers: the same on every platform.
#include <cstdint>

namespace fovea::trackerd::eye::synthetic {

// splitmix64: a small, fast, well-mixed generator. Used for the instance's look (seeded from the
// options' seed) and for the per-frame noise (seeded by one draw from the instance's mt19937_64),
// so results do not depend on the standard library's distribution implementations.
struct SplitMix {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }  // [0, 1)
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  int integer(int lo, int hi) {  // [lo, hi]
    return lo + static_cast<int>(next() % static_cast<std::uint64_t>(hi - lo + 1));
  }
};

}  // namespace fovea::trackerd::eye::synthetic
