// SPDX-License-Identifier: Apache-2.0
#pragma once
// The G-buffer resampled to the attention pass's n x n map (Lee 2009 §3.1.1): colour and depth by a
// box filter or the nearest source pixel, colour to HLS (lightness and the hue vector), depth to
// eq. 3.1's B_d, the item buffer and the per-object depth nearest. Level 0 of the L, hue and depth
// planes is what the feature pyramids (feature_pyramid.h) are built on. Internal to the attention
// pass (attention.cpp); gbuffer_resample.cpp has the filters and their choices.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "attention/attention.h"
#include "attention/feature_pyramid.h"

namespace fovea::render::attention::detail {

// The G-buffer as the resampling reads it: which planes it has, and the depth range of eq. 3.1.
struct Source {
  const GBuffer& g;
  std::size_t W, H;
  bool has_image, has_color, has_depth, has_ids;
  double z_range;    // z_far - z_near of eq. 3.1 (1 for a degenerate camera)
  float fnear, ffar;  // what depths are clamped to
};

// Reads `g`'s size and planes and the camera's clip range (eq. 3.1).
Source read_source(const GBuffer& g, const Camera& camera);

// Per map column (x) and row (y): the source columns / rows [c0, c1) of its box, and the one source
// column / row under its centre (n).
struct ResampleGrid {
  explicit ResampleGrid(std::size_t un) : cx0(un), cx1(un), cy0(un), cy1(un), nx(un), ny(un) {}
  std::vector<int> cx0, cx1, cy0, cy1, nx, ny;
};

// The boxes and centres of an n x n map over `src` (Resample::Nearest: every box is its centre).
ResampleGrid resample_grid(const Source& src, int n, Resample resample);

// Level 0 of the L, hue and depth planes, the map's ids and per-pixel depth, from `src`.
void resample_gbuffer(const Source& src, const ResampleGrid& grid, int n, Resample resample, Pyramid (&planes)[kPlanes],
                      std::vector<std::uint32_t>& ids, std::vector<float>& map_depth);

}  // namespace fovea::render::attention::detail
