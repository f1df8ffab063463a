// SPDX-License-Identifier: Apache-2.0
#pragma once
// A thin-lens sample for the depth-of-field references (renderer/dof/reference.h): primary rays
// leave from a point of the lens aperture and pass through the pixel's point on the plane in focus,
// so that plane stays sharp and everything else blurs by the thin-lens CoC (Lee 2009 eq. 4.3). With
// one lens point for every pixel a render is one view of an accumulation buffer (Haeberli & Akeley);
// with a different point per pixel it is one sample of distributed ray tracing (Cook et al. 1984).
// The aperture is a uniform disc (a real lens's iris: the blur of a point is a disc of the CoC's
// diameter C) or, for Lee 2009 §4.1.3's lens "with a Gaussian intensity distribution", a Gaussian
// transmission profile: the blur of a point is then a Gaussian whose per-axis standard deviation is
// gaussian_sigma_per_coc x C (Lee's sigma = C / 2 is 0.5; the disc's own per-axis deviation is C / 4).
#include <cmath>
#include <cstdint>

#include <glm/vec2.hpp>

namespace fovea::render {

struct LensSample {
  double aperture_radius_m = 0;  // E / 2; 0: pinhole (the default: G-buffers are pinhole renders)
  double focus_m = 2;            // view-axis distance of the plane in focus
  // Per pixel: sample `index` of a per-pixel scrambled Sobol' (0,2)-sequence (any power-of-two
  // prefix is stratified over the aperture), scrambled from `seed` and the pixel. Otherwise every
  // pixel uses `disc`, a point of the unit disc.
  bool per_pixel = false;
  std::uint32_t index = 0;
  std::uint64_t seed = 0;
  glm::vec2 disc{0.0f, 0.0f};
  // > 0: the Gaussian aperture above (its per-axis deviation is this times the diameter E = 2 x
  // aperture_radius_m, unbounded); 0: the uniform disc of radius aperture_radius_m.
  double gaussian_sigma_per_coc = 0;
  bool active() const { return aperture_radius_m > 0 && std::isfinite(aperture_radius_m) && focus_m > 0 && std::isfinite(focus_m); }
};

namespace lens_sampling {

inline std::uint32_t reverse_bits(std::uint32_t v) {
  v = ((v >> 1) & 0x55555555u) | ((v & 0x55555555u) << 1);
  v = ((v >> 2) & 0x33333333u) | ((v & 0x33333333u) << 2);
  v = ((v >> 4) & 0x0F0F0F0Fu) | ((v & 0x0F0F0F0Fu) << 4);
  v = ((v >> 8) & 0x00FF00FFu) | ((v & 0x00FF00FFu) << 8);
  return (v >> 16) | (v << 16);
}
// The second dimension of Sobol' (direction numbers v_k = v_{k-1} ^ v_{k-1} >> 1).
inline std::uint32_t sobol_dim2(std::uint32_t i) {
  std::uint32_t r = 0;
  for (std::uint32_t v = 1u << 31; i != 0; i >>= 1, v ^= v >> 1) {
    if (i & 1u) r ^= v;
  }
  return r;
}
inline std::uint64_t mix(std::uint64_t z) {  // splitmix64's finaliser
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}
// Shirley & Chiu's concentric map from [0,1)^2 to the unit disc (keeps strata compact).
inline glm::vec2 concentric_disc(double u, double v) {
  const double a = 2 * u - 1, b = 2 * v - 1;
  if (a == 0 && b == 0) return {0.0f, 0.0f};
  constexpr double kQuarterPi = 0.78539816339744830962;
  double r = 0, phi = 0;
  if (std::fabs(a) > std::fabs(b)) {
    r = a;
    phi = kQuarterPi * (b / a);
  } else {
    r = b;
    phi = 2 * kQuarterPi - kQuarterPi * (a / b);
  }
  return {static_cast<float>(r * std::cos(phi)), static_cast<float>(r * std::sin(phi))};
}
// Box-Muller from [0,1)^2 to the standard normal in 2-D, radius from u and angle from v, so the
// (0,2)-sequence's strata map to annular sectors; 1 - u > 0 keeps the radius finite (at most 6.7).
inline glm::vec2 normal_point(double u, double v) {
  constexpr double kTwoPi = 6.28318530717958647692;
  const double r = std::sqrt(-2.0 * std::log(1.0 - u)), phi = kTwoPi * v;
  return {static_cast<float>(r * std::cos(phi)), static_cast<float>(r * std::sin(phi))};
}
// Point `index` of the (0,2)-sequence XOR-scrambled by `scramble` (scrambling keeps the net property),
// on the unit disc (gaussian_sigma_per_coc = 0) or drawn from the Gaussian aperture of
// LensSample::gaussian_sigma_per_coc, in units of the aperture radius (per-axis deviation 2 sigma).
inline glm::vec2 lens_point(std::uint32_t index, std::uint64_t scramble, double gaussian_sigma_per_coc = 0) {
  const auto sx = static_cast<std::uint32_t>(scramble), sy = static_cast<std::uint32_t>(scramble >> 32);
  const double u = static_cast<double>(reverse_bits(index) ^ sx) * 0x1p-32;
  const double v = static_cast<double>(sobol_dim2(index) ^ sy) * 0x1p-32;
  if (gaussian_sigma_per_coc > 0) return normal_point(u, v) * static_cast<float>(2.0 * gaussian_sigma_per_coc);
  return concentric_disc(u, v);
}
// The lens point (in units of the aperture radius) of pixel (x, y) under `s`.
inline glm::vec2 pixel_lens_point(const LensSample& s, std::uint32_t x, std::uint32_t y) {
  if (!s.per_pixel) return s.disc;
  return lens_point(s.index, mix(s.seed ^ mix((std::uint64_t{y} << 32) | x)), s.gaussian_sigma_per_coc);
}

}  // namespace lens_sampling
}  // namespace fovea::render
