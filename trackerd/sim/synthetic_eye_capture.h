// SPDX-License-Identifier: Apache-2.0
#pragma once
// What the eye camera does to the shaded image (synthetic_eye_capture.cpp), in render()'s order:
// uneven illumination, optics (defocus, motion blur), and the sensor (noise, rounding, clipping).
#include <cstdint>

#include <opencv2/core.hpp>

#include "sim/synthetic_eye.h"

namespace fovea::trackerd::eye::synthetic {

// g: strength 0..1; gradient_dir: the unit direction in which the image brightens.
void apply_uneven_illumination(cv::Mat1f& img, double g, cv::Point2d gradient_dir);
// Defocus and motion blur as set in the options.
void apply_optics(cv::Mat1f& img, const SyntheticEyeOptions& o);
// The 8-bit frame: noise of sigma noise_sigma grey levels from a generator seeded by noise_seed.
cv::Mat sensor_readout(const cv::Mat1f& img, double noise_sigma, std::uint64_t noise_seed);

}  // namespace fovea::trackerd::eye::synthetic
