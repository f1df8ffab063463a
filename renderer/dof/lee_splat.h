// SPDX-License-Identifier: Apache-2.0
#pragma once
// Real-time depth of field by point splatting on per-pixel layers (Lee 2009, chapter 5), on the CPU.
//
// Every source pixel of the visible image V (and every accepted pixel of the hidden image H, §5.1.2)
// is splatted over a footprint of its CoC diameter C with intensity normalised per discrete footprint
// (eq. 5.2). At each destination pixel q the incoming splats are sorted into three layers relative
// to the visible pixel at q (in front / same depth / behind, eq. 5.3), and the layers are blended
// back to front with normalisation (eq. 5.4). Aperture shapes come from the intensity distribution
// function (IDF) of the footprint; HDR input gives defocused highlights directly, and LDR input can
// have them extrapolated (eq. 5.5). §5.3's reduced-resolution point array is an option.
//
// CPU splatting: the image is cut into horizontal bands of destination rows; each band (one TBB
// task) walks, in a fixed order, every point whose footprint reaches it and accumulates into its
// own rows only. Each destination pixel therefore sums its splats in the same order whatever the
// thread count: the output is deterministic, with no atomics and no per-thread image copies.
#include <cstddef>

#include "dof/dof_image.h"

namespace fovea::render::dof {

enum class Aperture { Disc, Gaussian, Hexagon };

struct LeeSplatSettings {
  double delta = 0.4;                  // δ of eq. 5.3 (the paper: 0.3 to 0.5)
  Aperture aperture = Aperture::Disc;  // the IDF: uniform disc, Gaussian (σ = C/4), uniform hexagon
  bool use_hidden = true;              // splat the hidden layer H when DofInput has one (§5.1.2)
  // §5.1.2's three depth tests for hidden pixels, on the depth scale normalised by the focus distance
  // (depth / d_f; the paper's "normalized scale").
  double hidden_epsilon = 0.05;         // test 1: Z' >= Z_v + ε
  double laplacian_threshold = 0.01;    // test 3: L(p) of eq. 5.1 >= this, else completely hidden
  bool ldr_highlights = false;          // eq. 5.5: extrapolate bright LDR pixels before splatting
  double highlight_threshold = 0.8;     // λ_0 of eq. 5.5
  double highlight_falloff = 3;         // β of eq. 5.5
  double highlight_gain = 2;            // γ of eq. 5.5
  int reduce = 1;  // §5.3: splat blurred, depth-smooth r x r blocks as one point (1 = full resolution)
};

struct LeeSplatStats {
  std::size_t splats = 0;       // points splatted (visible + hidden + reduced blocks)
  std::size_t hidden_used = 0;  // hidden pixels that passed the three tests of §5.1.2
  double seconds = 0;
};

// out is resized to in.pixels(). Never NaN or Inf; a pinhole (every C < 1 px) returns the input
// exactly (non-finite colour as 0).
void lee_splat(const DofInput& in, const LeeSplatSettings& s, RgbImage& out, LeeSplatStats* stats = nullptr);

}  // namespace fovea::render::dof
