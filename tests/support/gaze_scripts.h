// SPDX-License-Identifier: Apache-2.0
#pragma once
// Scripted gaze for classifier tests: an eye whose position is a function of time, evenly sampled
// with gaussian noise, and the minimum-jerk saccade it makes.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "classify/classifier.h"

namespace fovea::test {

using trackerd::classify::Sample;

// A scripted eye: position(t) in degrees; noise per axis; evenly sampled.
struct Script {
  double rate = 500;
  double noise = 0.01;
  std::uint64_t seed = 3;
};

template <class F>
inline std::vector<Sample> sample(const Script& s, double seconds, F position) {
  std::mt19937_64 rng(s.seed);
  std::normal_distribution<double> g(0, 1);
  std::vector<Sample> out;
  const auto n = static_cast<std::size_t>(seconds * s.rate);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / s.rate;
    Sample x;
    x.t_s = t;
    const auto [px, py] = position(t);
    x.x_deg = px + s.noise * g(rng);
    x.y_deg = py + s.noise * g(rng);
    out.push_back(x);
  }
  return out;
}

// Minimum-jerk saccade of `amp` degrees starting at t0, main-sequence duration (2.2 ms/deg + 21 ms).
inline std::pair<double, double> saccade_at(double t, double t0, double amp) {
  const double d = (2.2 * amp + 21) / 1000;
  const double u = std::clamp((t - t0) / d, 0.0, 1.0);
  return {amp * (10 * std::pow(u, 3) - 15 * std::pow(u, 4) + 6 * std::pow(u, 5)), 0.0};
}

// Its speed, deg/s.
inline double saccade_speed(double t, double t0, double amp) {
  const double d = (2.2 * amp + 21) / 1000;
  const double u = (t - t0) / d;
  if (u <= 0 || u >= 1) return 0;
  return amp / d * 30 * u * u * (1 - u) * (1 - u);
}

}  // namespace fovea::test
