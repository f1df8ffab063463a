// SPDX-License-Identifier: Apache-2.0
#pragma once
// Depth of field by anisotropically filtered nonlinear mipmap interpolation: Lee 2009, chapter 4
// (S. Lee, G. J. Kim, S. Choi, "Real-Time Depth-of-Field Rendering Using Anisotropically Filtered
// Mipmap Interpolation", IEEE TVCG 2009), as a CPU image operation.
//
// The five steps of Fig. 4.10 (§4.4):
//   1. I(0) = the pinhole colour, ZBN(0) = depth Z, DoB B = sigma = C / 2 (§4.1.3).
//   2. Isotropic 3x3 Gaussian mipmaps of Z and B (eq. 4.1), and the DoN rho at the top level M
//      (eq. 4.10: the largest DoB among the nearer foreground neighbours).
//   3. The colour mipmap I with the anisotropic Gaussian H of eq. 4.9 (no intensity flows from a
//      sharper neighbour into a blurred background texel).
//   4. Foreground smoothing (eq. 4.11): rho(M) magnified to the pixel gives a level n, and the DoB
//      is read from B at level n instead of level 0.
//   5. m from the DoB (eq. 4.6), and the colour by nonlinear (geometric) interpolation of the 3x3
//      circular neighbourhood at the one-lower level (eq. 4.8, Fig. 4.4b).
//
// Choices where the paper is silent are documented next to the code (lee_mipmap_detail.h,
// lee_mipmap_levels.cpp, lee_mipmap_final_pass.cpp): the 3x3 Gaussian is the binomial [1 2 1] / 4
// read with GL bilinear taps; k_sigma is refitted for this pipeline (see LeeMipmapSettings::k_sigma);
// in eq. 4.8 the I(l) factor is read at offsets of its own texels (I(l - 1)'s at its own, as the
// paper writes), so the result is continuous in m; for m < 1 (no level -1) the pixel is blended with
// its level-0 3x3 neighbourhood.
//
// Cost: one LeeMipmap reuses its buffers from frame to frame. The per-pixel work is 18 bilinear
// colour reads and, with eq. 4.8's geometric blend, 27 log/exp pairs (vectorised), plus 9 DoN reads
// on rows near a foreground object; the mipmaps cost ~1/3 of level 0 in all. It does not depend on
// the CoC size, only on the image size. On a CPU the 18 reads are gathers (the level varies per
// pixel) and dominate: ~270 instructions per pixel, ~20 ms of CPU time at 1024x768; the blend's
// 27 log/exp pairs another ~9 ms; see bench/RESULTS.md.
#include <cstdint>
#include <memory>
#include <vector>

#include "dof/dof_image.h"

namespace fovea::render::dof {

struct LeeMipmapSettings {
  bool anisotropic = true;  // eq. 4.9 while building the colour mipmap (false: eq. 4.1 alone)
  // eq. 4.9's offset delta, in level-0 pixels of DoB (sigma = C / 2): neighbours whose DoB is at
  // most this much below the centre's still blur it. The paper gives no value ("a slight offset");
  // 0.5 px of sigma is a CoC diameter 1 px smaller, the smallest difference a pixel grid resolves.
  double delta = 0.5;
  bool smooth_foreground = true;  // eqs. 4.10-4.11 (false: m from the level-0 DoB)
  bool circular = true;           // Fig. 4.4b sample positions (false: the square 3x3 of Fig. 4.4a)
  // eq. 4.8's geometric blend I(l-1)^(1-beta) I(l)^beta; false: the linear blend of the GPU's
  // mipmap biasing (§4.4 step 5, "the difference ... is marginal"), which is cheaper on a CPU.
  bool geometric = true;
  // eq. 4.6's k_sigma. The paper's 2/3 comes from eq. 4.5, its RMSE fit (Fig. 4.3) of the blur its
  // GPU mipmap gives per level, sigma = 1.5 2^(m-1). The same fit for this pipeline (binomial 3x3
  // Gaussian, bilinear GL sampling, eq. 4.8 at level m - 1) is sigma = 0.9 2^(m-1): with 2/3 the
  // blur would be about half the sigma = C / 2 of §4.1.3. 2/3 reproduces the paper's constant.
  double k_sigma = 1.1;
  // The degree of blurring per CoC diameter: sigma = dob_per_coc x C. Lee §4.1.3 chooses 1/2 (a
  // lens with a Gaussian intensity distribution); a thin lens's uniform disc of diameter C has a
  // standard deviation of C / 4 per axis, so 1/4 matches the variance of the ray-traced reference.
  double dob_per_coc = 0.5;
  int max_level = 0;  // 0: as many levels as the largest DoB needs (capped at the image's top level)
  bool operator==(const LeeMipmapSettings&) const = default;
};

struct LeeMipmapStats {
  int levels = 0;         // top mipmap level M built (0: none, the output is the input)
  double max_dob_px = 0;  // largest level-0 DoB sigma = C / 2 in the image
  double seconds = 0;     // wall time of the call
  double mipmap_seconds = 0;  // of which steps 1-3 and the DoN (the rest: steps 4-5, the final pass)
};

// Holds the mipmaps between calls so that a frame loop allocates nothing after its first frame.
// Not thread-safe: one instance per concurrent caller (each call is parallel inside, with TBB).
class LeeMipmap {
 public:
  LeeMipmap();
  ~LeeMipmap();
  LeeMipmap(const LeeMipmap&) = delete;
  LeeMipmap& operator=(const LeeMipmap&) = delete;

  // out is resized to in.pixels(). Non-finite colour reads as 0, negative colour as 0 (the geometric
  // blend is defined for non-negative values only); output is finite and within [0, max input].
  // A pinhole model (or C = 0 everywhere) copies the input bit for bit (non-finite values as 0).
  void run(const DofInput& in, const LeeMipmapSettings& s, RgbImage& out, LeeMipmapStats* stats = nullptr);

  // Debug: the continuous mipmap level m (eq. 4.6, after eq. 4.11's smoothing) of every pixel of
  // the last run (row-major, width * height); empty before the first run or after a pinhole run.
  const std::vector<float>& level_map() const;
  // Debug: the DoB sigma (pixels) used for each pixel of the last run (after eq. 4.11's smoothing).
  const std::vector<float>& dob_map() const;
  // Record level_map / dob_map during run (off by default: it costs a little).
  void set_record_debug(bool on) { record_debug_ = on; }

 private:
  struct Scratch;
  std::unique_ptr<Scratch> scratch_;
  bool record_debug_ = false;
};

// Convenience: a fresh LeeMipmap per call (allocates every call).
void lee_mipmap(const DofInput& in, const LeeMipmapSettings& s, RgbImage& out, LeeMipmapStats* stats = nullptr);

}  // namespace fovea::render::dof
