// SPDX-License-Identifier: Apache-2.0
#pragma once
// The exact filter lee-mipmap approximates (Lee 2009 ch. 4): every pixel's colour is the whole image
// blurred by a Gaussian of the pixel's own degree of blurring sigma = sigma_per_coc x C(depth), a
// spatially varying gather — isotropic (no eq. 4.9) and on the level-0 DoB (no eq. 4.11's smoothing).
//
// It splits a method's distance from the thin-lens reference into two parts that can be measured:
// lee-mipmap against this gather is the mipmap's own approximation error (pyramid, eqs. 4.5-4.8);
// this gather against the reference is its blur model's error (one layer, a Gaussian kernel, a
// gather where the lens scatters). See bench_dof's "gaussian gather" rows and DOF.md.
//
// How: the image is blurred by separable sampled Gaussians (radius ceil(4 sigma), normalised,
// clamped at the border) at sigma_k = 0.25 x 2^(k / steps_per_octave) px; a pixel whose sigma lies in
// [sigma_k, sigma_k+1] mixes the two blurs with the weight that gives the mixture's kernel exactly
// the variance sigma^2 (sigma_0 = 0 is the input itself, so C = 0 copies the input bit for bit).
// Not real time (seconds at 1024x768): a bench and test tool. Non-finite colour reads as 0.
#include "dof/dof_image.h"

namespace fovea::render::dof {

struct GaussianGatherSettings {
  double sigma_per_coc = 0.5;  // Lee §4.1.3's sigma = C / 2; 0.25 has the thin lens's variance
  int steps_per_octave = 4;    // blur levels per doubling of sigma
  double max_sigma_px = 128;   // larger sigmas are clamped here (the cost grows with sigma)
};

struct GaussianGatherStats {
  int blurs = 0;          // blur levels computed (only those some pixel needs)
  double max_sigma_px = 0;  // largest sigma in the image, after the clamp
};

// out is resized to in.pixels(). Throws std::invalid_argument for settings out of range.
void gaussian_gather(const DofInput& in, const GaussianGatherSettings& s, RgbImage& out,
                     GaussianGatherStats* stats = nullptr);

}  // namespace fovea::render::dof
