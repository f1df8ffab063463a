// SPDX-License-Identifier: Apache-2.0
// The instance's look, drawn once from the seed: the iris texture (fibres, crypts, collarette,
// limbal ring), skin waves, lid skew, lashes and spectacle reflections, in the order of the draws.
#include "sim/synthetic_eye_look.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "sim/synthetic_eye_geometry.h"

namespace fovea::trackerd::eye {

using namespace synthetic;  // sim/synthetic_eye_geometry.h, sim/splitmix.h

SyntheticEye::Look::Look(const SyntheticEyeOptions& o) {
  SplitMix rng{o.seed ^ 0x5EED0F0E7E5ull};
  skin = rng.uniform(152, 168);
  sclera = rng.uniform(192, 206);
  pupil = rng.uniform(17, 27);
  lash = rng.uniform(44, 56);
  draw_iris_texture(rng);
  if (o.pupil_iris_contrast > 0) darken_iris(o.pupil_iris_contrast);
  draw_skin_waves(rng, o);
  lid_skew_upper = rng.uniform(-0.18, 0.18);
  lid_skew_lower = rng.uniform(-0.15, 0.15);
  draw_lashes(rng);
  for (Lash& l : lashes) l.length_mm *= o.eyelash_length;  // after the draws: the same lashes, longer
  draw_spectacle_reflections(rng, o);
  const double ga = rng.uniform(0, 2 * kPi);
  gradient_dir = {std::cos(ga), std::sin(ga)};
}

// The iris texel at (radius row ir, angle column it), the angle wrapping around.
float& SyntheticEye::Look::iris_at(int ir, int it) {
  return iris[static_cast<std::size_t>(ir * kTheta + ((it % kTheta) + kTheta) % kTheta)];
}

// Iris texture in (angle, normalised radius 0 = pupil edge .. 1 = limbus): radial fibres,
// crypts, a collarette ring and a darker limbal ring, as the iris looks in near infrared.
void SyntheticEye::Look::draw_iris_texture(SplitMix& rng) {
  const double base = rng.uniform(98, 112);
  iris.assign(static_cast<std::size_t>(kTheta * kRho), static_cast<float>(base));
  const std::vector<double> low = iris_low_frequency(rng);
  std::vector<double> col_phase(4);
  for (double& p : col_phase) p = rng.uniform(0, 2 * kPi);
  add_collarette_and_limbal_ring(low, col_phase);
  add_iris_fibres(rng);
  add_iris_crypts(rng);
  for (float& v : iris) v = std::clamp(v, 82.0f, 130.0f);
  double inner = 0;
  for (int it = 0; it < kTheta; ++it)
    inner += static_cast<double>(iris_at(0, it)) + static_cast<double>(iris_at(1, it));
  iris_inner = inner / (2.0 * kTheta);
}

// A dark iris: the texture pulled towards the pupil's level so that the iris next to the pupil is
// `contrast` grey levels above it, its variation shrinking in proportion (a dark-brown iris under
// infrared light is dark and nearly featureless). No random draws: the rest of the look is the same.
void SyntheticEye::Look::darken_iris(double contrast) {
  const double scale = contrast / std::max(iris_inner - pupil, 1.0);
  for (float& v : iris) v = static_cast<float>(pupil + (static_cast<double>(v) - pupil) * scale);
  iris_inner = pupil + contrast;
}

// Angular variation shared by every radius: six harmonics with amplitude falling as 1/sqrt(k).
std::vector<double> SyntheticEye::Look::iris_low_frequency(SplitMix& rng) {
  std::vector<double> low(kTheta, 0.0);
  for (int k = 1; k <= 6; ++k) {
    const double amp = rng.uniform(0.5, 2.5) / std::sqrt(k), ph = rng.uniform(0, 2 * kPi);
    for (int it = 0; it < kTheta; ++it)
      low[static_cast<std::size_t>(it)] += amp * std::cos(k * 2 * kPi * it / kTheta + ph);
  }
  return low;
}

// The low-frequency pattern, a wavy bright collarette near a third of the radius and the darker
// limbal ring towards the outer edge.
void SyntheticEye::Look::add_collarette_and_limbal_ring(const std::vector<double>& low,
                                                        const std::vector<double>& col_phase) {
  for (int ir = 0; ir < kRho; ++ir) {
    const double rho = ir / (kRho - 1.0);
    for (int it = 0; it < kTheta; ++it) {
      const double th = 2 * kPi * it / kTheta;
      const double collarette_r =
          0.33 + 0.04 * std::sin(3 * th + col_phase[0]) + 0.02 * std::sin(7 * th + col_phase[1]);
      double v = low[static_cast<std::size_t>(it)];
      v += 6.0 * std::exp(-std::pow((rho - collarette_r) / 0.06, 2));
      v -= 16.0 * smoothstep(0.72, 1.0, rho);
      iris_at(ir, it) += static_cast<float>(v);
    }
  }
}

// Radial fibres, bright or dark, each a Gaussian in angle that swirls slightly from its inner to
// its outer end and fades in and out along the radius.
void SyntheticEye::Look::add_iris_fibres(SplitMix& rng) {
  const int fibres = 220;
  for (int j = 0; j < fibres; ++j) {
    const double th0 = rng.uniform(0, kTheta);
    const double width = rng.uniform(1.0, 4.0);  // bins
    const double amp = rng.uniform() < 0.55 ? rng.uniform(3, 10) : -rng.uniform(3, 9);
    const double r0 = rng.uniform(0.0, 0.55), r1 = std::min(1.0, r0 + rng.uniform(0.25, 0.7));
    const double swirl = rng.uniform(-6, 6);  // bins of angular drift from inner to outer end
    for (int ir = 0; ir < kRho; ++ir) {
      const double rho = ir / (kRho - 1.0);
      const double wr = smoothstep(r0, r0 + 0.08, rho) * (1 - smoothstep(r1 - 0.08, r1, rho));
      if (wr <= 0) continue;
      const double centre = th0 + swirl * rho;
      const int lo = static_cast<int>(std::floor(centre - 3 * width));
      const int hi = static_cast<int>(std::ceil(centre + 3 * width));
      for (int it = lo; it <= hi; ++it) {
        const double z = (it - centre) / width;
        iris_at(ir, it) += static_cast<float>(amp * wr * std::exp(-z * z));
      }
    }
  }
}

void SyntheticEye::Look::add_iris_crypts(SplitMix& rng) {
  for (int j = 0; j < 12; ++j) {  // crypts: dark lacunae
    const double th0 = rng.uniform(0, kTheta), r0 = rng.uniform(0.15, 0.7);
    const double wt = rng.uniform(4, 12), wr = rng.uniform(0.04, 0.1), amp = rng.uniform(8, 16);
    for (int ir = 0; ir < kRho; ++ir) {
      const double dr = (ir / (kRho - 1.0) - r0) / wr;
      if (std::abs(dr) > 3) continue;
      for (int it = static_cast<int>(th0 - 3 * wt); it <= static_cast<int>(th0 + 3 * wt); ++it) {
        const double dt = (it - th0) / wt;
        iris_at(ir, it) -= static_cast<float>(amp * std::exp(-dr * dr - dt * dt));
      }
    }
  }
}

// Skin waves, wavelengths relative to the image so the look does not depend on resolution.
void SyntheticEye::Look::draw_skin_waves(SplitMix& rng, const SyntheticEyeOptions& o) {
  const double size = std::max(o.width, o.height);
  const std::size_t w = static_cast<std::size_t>(o.width), h = static_cast<std::size_t>(o.height);
  for (int k = 0; k < 4; ++k) {
    const double lambda = rng.uniform(0.35, 1.4) * size, dir = rng.uniform(0, 2 * kPi);
    waves.push_back({2 * kPi / lambda * std::cos(dir), 2 * kPi / lambda * std::sin(dir), rng.uniform(0, 2 * kPi),
                     rng.uniform(1.5, 4.0)});
  }
  tabulate_skin_waves(w, h);
}

// Per-column and per-row factors of each wave, so that render() gets amp cos(kx x + phi + ky y) as
// cx cy - sx sy at pixel centres without evaluating a cosine per pixel.
void SyntheticEye::Look::tabulate_skin_waves(std::size_t w, std::size_t h) {
  wave_cx.resize(waves.size() * w);
  wave_sx.resize(waves.size() * w);
  wave_cy.resize(waves.size() * h);
  wave_sy.resize(waves.size() * h);
  for (std::size_t k = 0; k < waves.size(); ++k) {
    for (std::size_t x = 0; x < w; ++x) {
      const double arg = waves[k].kx * (static_cast<double>(x) + 0.5) + waves[k].phase;
      wave_cx[k * w + x] = static_cast<float>(waves[k].amp * std::cos(arg));
      wave_sx[k * w + x] = static_cast<float>(waves[k].amp * std::sin(arg));
    }
    for (std::size_t y = 0; y < h; ++y) {
      const double arg = waves[k].ky * (static_cast<double>(y) + 0.5);
      wave_cy[k * h + y] = static_cast<float>(std::cos(arg));
      wave_sy[k * h + y] = static_cast<float>(std::sin(arg));
    }
  }
}

// Upper lashes: hang from the upper lid margin over the eye, fanning out towards the corners.
void SyntheticEye::Look::draw_lashes(SplitMix& rng) {
  const int n_lashes = 70;
  for (int j = 0; j < n_lashes; ++j) {
    Lash l;
    l.s = rng.uniform(-0.92, 0.92);
    const double edge = 1 - l.s * l.s;
    l.length_mm = (rng.uniform() < 0.15 ? rng.uniform(4.5, 7.0) : rng.uniform(1.5, 4.5)) * (0.45 + 0.55 * edge);
    l.tilt = 0.9 * l.s + rng.uniform(-0.35, 0.35);  // radians from image "down" towards +t
    l.curl = (l.s >= 0 ? 1 : -1) * rng.uniform(0.1, 0.7);
    l.width_mm = rng.uniform(0.06, 0.11);
    l.opacity = rng.uniform(0.55, 0.95);
    lashes.push_back(l);
  }
}

// Spectacle reflections: 1-3 large soft ellipses or streaks, fixed to the headset (and camera).
void SyntheticEye::Look::draw_spectacle_reflections(SplitMix& rng, const SyntheticEyeOptions& o) {
  const int n_refl = rng.integer(1, 3);
  const double wd = o.width, ht = o.height, small = std::min(wd, ht);
  for (int j = 0; j < n_refl; ++j) {
    Reflection r;
    r.centre = {wd * rng.uniform(0.25, 0.75), ht * rng.uniform(0.25, 0.75)};
    const bool streak = rng.uniform() < 0.5;
    r.a = small * rng.uniform(0.12, 0.35);
    r.b = r.a * (streak ? rng.uniform(0.12, 0.3) : rng.uniform(0.45, 0.9));
    r.angle = rng.uniform(0, kPi);
    r.strength = rng.uniform(0.3, 0.65);
    reflections.push_back(r);
  }
}

}  // namespace fovea::trackerd::eye
