// SPDX-License-Identifier: Apache-2.0
#pragma once
// The attention pass's feature pyramids and their centre-surround differences (Lee 2009 §3.1.1,
// eq. 3.4): each feature plane's pyramid by 2x2 box downsampling, its coarse levels magnified onto
// level 0 bilinearly as a GPU's texture unit would, and C_f per map pixel. Internal to the
// attention pass (attention.cpp, gbuffer_resample.cpp); feature_pyramid.cpp has the kernels.
#include <cstddef>
#include <vector>

namespace fovea::render::attention::detail {

constexpr int kLevels = 7;  // pyramid levels 0 (finest) to 6 (coarsest), Lee 2009 §3.1.1

// One level of a one-channel feature pyramid.
struct Level {
  int w = 0, h = 0;
  std::vector<float> v;  // w * h
};
using Pyramid = Level[kLevels];

// The planar feature maps (level 0 of each pyramid): L, the hue vector's two components, and the
// DSM texture of Fig. 3.3 (depth, size, motion) as three planes.
enum Plane { kPL = 0, kPHa, kPHb, kPDepth, kPSize, kPMotion, kPlanes };

// Bilinear magnification of a coarse level onto the n samples of level 0 along one axis, as a GPU's
// texture unit does with GL_LINEAR and GL_CLAMP_TO_EDGE: level-0 sample k sits at (k + 0.5) / n,
// texel j of an m-texel level at (j + 0.5) / m.
struct Axis {
  std::vector<int> i0, i1;
  std::vector<float> f;
};

// The coarse levels 1..6 of a pyramid magnified horizontally to n columns (h_L rows each), and the
// vertical lerp of each output row: level-0 row y of level L is a[y] + f[y] (b[y] - a[y]).
struct Magnified {
  std::vector<float> rows[kLevels];
  Axis vertical[kLevels];
  // Rows of levels 1..6 of `pyr` magnified to n columns, and their vertical taps.
  void build(const Pyramid& pyr, int n);
  struct Row {
    const float* a[kLevels];
    const float* b[kLevels];
    float f[kLevels];
  };
  // The rows and vertical lerp factors of level-0 row y (un = n).
  Row row(std::size_t y, std::size_t un) const;
};

// Levels 1..6 of `pyr` from its level 0 (downsample).
void build_pyramid(Pyramid& pyr);

// Eq. 3.4 for one feature plane: `out` is C, n x n; `mg` is scratch.
void centre_surround(const Pyramid& pyr, int n, Magnified& mg, std::vector<float>& out);

// Eq. 3.4 for the hue vector, whose components are the pyramids `pu` and `pw`.
void centre_surround_vector(const Pyramid& pu, const Pyramid& pw, int n, Magnified& mu, Magnified& mw,
                            std::vector<float>& out);

}  // namespace fovea::render::attention::detail
