// SPDX-License-Identifier: Apache-2.0
#pragma once
// The synthetic eye's look (SyntheticEye::Look, drawn in synthetic_eye_look.cpp): iris texture,
// skin, lid shape, lashes, spectacle reflections and the direction of uneven illumination.
#include <cstddef>
#include <vector>

#include <opencv2/core.hpp>

#include "sim/splitmix.h"
#include "sim/synthetic_eye.h"

namespace fovea::trackerd::eye {

// The instance's look: everything about the eye's appearance that a real person and a real
// headset keep from frame to frame, drawn once from the seed.
struct SyntheticEye::Look {
  static constexpr int kTheta = 512, kRho = 32;  // iris texture: angle x normalised radius

  double skin = 160, sclera = 200, pupil = 22, lash = 50;
  double iris_inner = 100;    // iris level next to the pupil (flat there, so the edge is unbiased)
  std::vector<float> iris;    // kRho rows of kTheta grey levels
  // Skin: a few low-frequency waves, separable per wave: cos(kx x + phi + ky y).
  struct Wave {
    double kx, ky, phase, amp;
  };
  std::vector<Wave> waves;
  std::vector<float> wave_cx, wave_sx;  // [wave][x]
  std::vector<float> wave_cy, wave_sy;  // [wave][y]
  double lid_skew_upper = 0, lid_skew_lower = 0;
  struct Lash {
    double s, length_mm, tilt, curl, width_mm, opacity;
  };
  std::vector<Lash> lashes;
  struct Reflection {
    cv::Point2d centre;  // pixels
    double a, b, angle, strength;
  };
  std::vector<Reflection> reflections;
  cv::Point2d gradient_dir{1, 0};

  explicit Look(const SyntheticEyeOptions& o);

 private:
  // Look()'s stages, in the order it calls them (the order of the random draws); members because
  // each fills some of the fields above.
  float& iris_at(int ir, int it);
  void draw_iris_texture(synthetic::SplitMix& rng);
  void darken_iris(double contrast);
  static std::vector<double> iris_low_frequency(synthetic::SplitMix& rng);
  void add_collarette_and_limbal_ring(const std::vector<double>& low, const std::vector<double>& col_phase);
  void add_iris_fibres(synthetic::SplitMix& rng);
  void add_iris_crypts(synthetic::SplitMix& rng);
  void draw_skin_waves(synthetic::SplitMix& rng, const SyntheticEyeOptions& o);
  void tabulate_skin_waves(std::size_t w, std::size_t h);
  void draw_lashes(synthetic::SplitMix& rng);
  void draw_spectacle_reflections(synthetic::SplitMix& rng, const SyntheticEyeOptions& o);
};

}  // namespace fovea::trackerd::eye
