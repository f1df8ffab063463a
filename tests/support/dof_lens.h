// SPDX-License-Identifier: Apache-2.0
#pragma once
// Thin-lens CoC models for the DOF tests (renderer/dof/lens.h), built from the numbers a test cares about.
#include "dof/lens.h"

namespace fovea::render::dof::test {

// Focal length f, aperture diameter e, focus distance and image-plane pixels per metre.
inline CocModel thin_lens(double f, double e, double focus_m, double px_per_image_m) {
  CocModel m;
  m.focal_length_m = f;
  m.aperture_m = e;
  m.focus_m = focus_m;
  m.px_per_image_m = px_per_image_m;
  m.max_coc_px = 1e4;
  return m;
}

// A lens with C(d) = K |d - d_f| / d, K (eq. 5.3) = k_px pixels: F = 50 mm, E = 10 mm.
inline CocModel lens_with_k(double k_px, double focus_m = 2.0) {
  return thin_lens(0.05, 0.01, focus_m, k_px * (focus_m - 0.05) / (0.01 * 0.05));
}

}  // namespace fovea::render::dof::test
