// SPDX-License-Identifier: Apache-2.0
#pragma once
// The depth-of-field references every real-time method is measured against (issue step 7):
// - Distributed ray tracing through the thin lens (Embree): every pixel's primary ray starts at its
//   own point of the aperture, taken from a per-pixel scrambled Sobol' (0,2)-sequence, so each
//   power-of-two prefix of samples is stratified over the lens; progressive (add samples and read
//   the mean at any time) and deterministic for a seed.
// - The accumulation-buffer equivalent (any backend, raster included): N pinhole renders from lens
//   points (the same sequence, one point for all pixels) through sheared frusta, averaged.
// Both converge to the same image: the integral of the pinhole radiance over the aperture with the
// plane at the focus distance sharp. The aperture is the real lens's uniform disc by default, or the
// Gaussian lens of Lee §4.1.3 (backend/lens_sample.h), whose blur is the Gaussian the mipmap method
// models: measuring against it separates a method's own error from its blur model's. Pixel centres are not jittered: the in-focus plane matches the
// pinhole G-buffer the real-time methods start from, so only the lens is being measured.
#include <cstdint>
#include <functional>

#include "backend/backend.h"
#include "dof/dof_image.h"

namespace fovea::render::dof {

enum class ReferenceKind { RayTraced, Accumulation };

class DofReference {
 public:
  // `backend` has the scene set; `lens` gives the aperture diameter E (lens.aperture_m); `focus_m`
  // the distance in focus. RayTraced needs a backend that takes per-pixel lens samples (Embree).
  // gaussian_sigma_per_coc > 0: the Gaussian aperture whose blur has a per-axis deviation of this
  // times the CoC diameter (0.5: Lee's sigma = C / 2); 0: the uniform disc. Allowed 0 to 4.
  DofReference(Backend& backend, const FrameTime& time, const BackendSettings& base, const Lens& lens,
               double focus_m, ReferenceKind kind, std::uint64_t seed, double gaussian_sigma_per_coc = 0);
  // Renders `n` more samples (one backend render each).
  void add_samples(std::uint32_t n);
  std::uint32_t samples() const { return samples_; }
  // The mean of the samples so far (the pinhole render before any sample).
  RgbImage image() const;
  std::uint32_t width() const { return width_; }
  std::uint32_t height() const { return height_; }
  double seconds() const { return seconds_; }

 private:
  Backend& backend_;
  FrameTime time_;
  BackendSettings base_;
  double radius_m_, focus_m_;
  ReferenceKind kind_;
  std::uint64_t seed_;
  double gaussian_sigma_per_coc_;
  std::uint32_t samples_ = 0, width_ = 0, height_ = 0;
  std::vector<double> sum_;  // 3 per pixel
  GBuffer scratch_;
  double seconds_ = 0;
};

}  // namespace fovea::render::dof
