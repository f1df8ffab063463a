// SPDX-License-Identifier: Apache-2.0
#include "dof/reference.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

namespace fovea::render::dof {

DofReference::DofReference(Backend& backend, const FrameTime& time, const BackendSettings& base, const Lens& lens,
                           double focus_m, ReferenceKind kind, std::uint64_t seed, double gaussian_sigma_per_coc)
    : backend_(backend),
      time_(time),
      base_(base),
      radius_m_(lens.is_pinhole() || !std::isfinite(lens.aperture_m) ? 0.0 : 0.5 * lens.aperture_m),
      focus_m_(focus_m),
      kind_(kind),
      seed_(seed),
      gaussian_sigma_per_coc_(gaussian_sigma_per_coc) {
  if (!(focus_m > 0) || !std::isfinite(focus_m)) {
    throw std::invalid_argument("DOF reference: focus distance " + std::to_string(focus_m) +
                                " m: allowed a finite distance > 0");
  }
  if (!(gaussian_sigma_per_coc >= 0) || !(gaussian_sigma_per_coc <= 4)) {
    throw std::invalid_argument("DOF reference: Gaussian aperture sigma per CoC diameter " +
                                std::to_string(gaussian_sigma_per_coc) + ": allowed 0 (the uniform disc) to 4");
  }
}

void DofReference::add_samples(std::uint32_t n) {
  const auto start = std::chrono::steady_clock::now();
  for (std::uint32_t k = 0; k < n; ++k) {
    BackendSettings s = base_;
    s.lens.aperture_radius_m = radius_m_;
    s.lens.focus_m = focus_m_;
    s.lens.seed = seed_;
    s.lens.index = samples_;
    s.lens.gaussian_sigma_per_coc = gaussian_sigma_per_coc_;
    if (kind_ == ReferenceKind::RayTraced) {
      s.lens.per_pixel = true;
    } else {
      s.lens.per_pixel = false;
      s.lens.disc = lens_sampling::lens_point(samples_, lens_sampling::mix(seed_), gaussian_sigma_per_coc_);
    }
    backend_.render(time_, s, scratch_);
    if (samples_ == 0) {
      width_ = scratch_.width;
      height_ = scratch_.height;
      sum_.assign(scratch_.size() * 3, 0.0);
    }
    if (scratch_.width != width_ || scratch_.height != height_) {
      throw std::runtime_error("DOF reference: the backend changed the image size between samples");
    }
    for (std::size_t i = 0; i < scratch_.size(); ++i) {
      const glm::vec3 c = scratch_.color[i];
      for (glm::length_t ch = 0; ch < 3; ++ch) {
        const float v = c[ch];
        sum_[3 * i + static_cast<std::size_t>(ch)] += std::isfinite(v) ? static_cast<double>(v) : 0.0;
      }
    }
    ++samples_;
  }
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

RgbImage DofReference::image() const {
  RgbImage out(sum_.size() / 3);
  if (samples_ == 0) return out;
  const double inv = 1.0 / samples_;
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = glm::vec3(static_cast<float>(sum_[3 * i] * inv), static_cast<float>(sum_[3 * i + 1] * inv),
                       static_cast<float>(sum_[3 * i + 2] * inv));
  }
  return out;
}

}  // namespace fovea::render::dof
