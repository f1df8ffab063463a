// SPDX-License-Identifier: Apache-2.0
#include "dof/gaussian_gather.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace fovea::render::dof {

namespace {

constexpr double kSigmaMin = 0.25;

glm::vec3 finite_or_zero(glm::vec3 c) {
  return {std::isfinite(c.x) ? c.x : 0.0f, std::isfinite(c.y) ? c.y : 0.0f, std::isfinite(c.z) ? c.z : 0.0f};
}

std::vector<float> gaussian_taps(double sigma) {
  const int r = std::max(1, static_cast<int>(std::ceil(4.0 * sigma)));
  std::vector<float> w(static_cast<std::size_t>(2 * r + 1));
  double sum = 0;
  for (int i = -r; i <= r; ++i) sum += std::exp(-0.5 * i * i / (sigma * sigma));
  for (int i = -r; i <= r; ++i) {
    w[static_cast<std::size_t>(i + r)] = static_cast<float>(std::exp(-0.5 * i * i / (sigma * sigma)) / sum);
  }
  return w;
}

// One separable pass along x (step 1) or y (step = width), clamped at the border.
void blur_pass(const std::vector<glm::vec3>& src, std::vector<glm::vec3>& dst, int w, int h, bool along_x,
               const std::vector<float>& taps) {
  const int r = static_cast<int>(taps.size() / 2);
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < w; ++x) {
        glm::dvec3 acc(0.0);
        for (int i = -r; i <= r; ++i) {
          const int sx = along_x ? std::clamp(x + i, 0, w - 1) : x;
          const int sy = along_x ? y : std::clamp(y + i, 0, h - 1);
          acc += static_cast<double>(taps[static_cast<std::size_t>(i + r)]) *
                 glm::dvec3(src[static_cast<std::size_t>(sy) * static_cast<std::size_t>(w) + static_cast<std::size_t>(sx)]);
        }
        dst[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)] = glm::vec3(acc);
      }
    }
  });
}

double level_sigma(int k, int steps) {
  return k == 0 ? 0.0 : kSigmaMin * std::exp2(static_cast<double>(k - 1) / steps);
}

// The level k with sigma_k <= sigma < sigma_k+1.
int level_below(double sigma, int steps) {
  if (sigma < kSigmaMin) return 0;
  return 1 + static_cast<int>(std::floor(std::log2(sigma / kSigmaMin) * steps + 1e-9));
}

}  // namespace

void gaussian_gather(const DofInput& in, const GaussianGatherSettings& s, RgbImage& out, GaussianGatherStats* stats) {
  if (!(s.sigma_per_coc > 0) || !(s.sigma_per_coc <= 4)) {
    throw std::invalid_argument("gaussian gather: sigma per CoC diameter " + std::to_string(s.sigma_per_coc) +
                                ": allowed (0, 4]");
  }
  if (s.steps_per_octave < 1 || s.steps_per_octave > 64) {
    throw std::invalid_argument("gaussian gather: " + std::to_string(s.steps_per_octave) +
                                " steps per octave: allowed 1 to 64");
  }
  if (!(s.max_sigma_px >= kSigmaMin) || !(s.max_sigma_px <= 4096)) {
    throw std::invalid_argument("gaussian gather: largest sigma " + std::to_string(s.max_sigma_px) +
                                " px: allowed 0.25 to 4096");
  }
  const std::size_t np = in.pixels();
  const int w = static_cast<int>(in.width), h = static_cast<int>(in.height);
  out.resize(np);
  std::vector<glm::vec3> input(np);
  for (std::size_t i = 0; i < np; ++i) input[i] = finite_or_zero(in.color[i]);

  std::vector<float> sigma(np);
  in.coc.scaled_coc_px(in.depth, np, s.sigma_per_coc, sigma.data());
  double max_sigma = 0;
  for (float& v : sigma) {
    v = std::min(v, static_cast<float>(s.max_sigma_px));
    max_sigma = std::max(max_sigma, static_cast<double>(v));
  }
  if (stats) *stats = {.blurs = 0, .max_sigma_px = max_sigma};

  // Level k's blur is needed by the pixels of bins k - 1 and k (bin k: sigma_k <= sigma < sigma_k+1).
  const int steps = s.steps_per_octave;
  const int top = level_below(max_sigma, steps) + 1;
  std::vector<char> bin_used(static_cast<std::size_t>(top) + 1, 0);
  for (const float v : sigma) bin_used[static_cast<std::size_t>(level_below(static_cast<double>(v), steps))] = 1;

  std::vector<glm::vec3> lower = input, upper(np), tmp(np);
  for (int k = 1; k <= top; ++k) {
    const bool needed = bin_used[static_cast<std::size_t>(k - 1)] || bin_used[static_cast<std::size_t>(k)];
    if (needed) {
      const std::vector<float> taps = gaussian_taps(level_sigma(k, steps));
      blur_pass(input, tmp, w, h, true, taps);
      blur_pass(tmp, upper, w, h, false, taps);
      if (stats) ++stats->blurs;
    }
    if (bin_used[static_cast<std::size_t>(k - 1)]) {
      // The mixture (1 - t) G(s_lo) + t G(s_hi) has variance s^2 when t = (s^2 - s_lo^2) / (s_hi^2 - s_lo^2).
      const double lo = level_sigma(k - 1, steps), hi = level_sigma(k, steps);
      for (std::size_t i = 0; i < np; ++i) {
        const double v = static_cast<double>(sigma[i]);
        if (level_below(v, steps) != k - 1) continue;
        const auto t = static_cast<float>((v * v - lo * lo) / (hi * hi - lo * lo));
        out[i] = t == 0.0f ? lower[i] : (1.0f - t) * lower[i] + t * upper[i];
      }
    }
    if (needed) std::swap(lower, upper);
  }
}

}  // namespace fovea::render::dof
