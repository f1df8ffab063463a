// SPDX-License-Identifier: Apache-2.0
#pragma once
// Lee 2009 chapter 4's depth of field (dof/lee_mipmap.h, the CPU reference) as OpenGL 3.3 passes,
// as Lee's own implementation ran it: the mipmaps are built by fragment passes, the final pass reads
// them with the texture unit's bilinear filtering. The same settings, the same steps, the same
// choices where the paper is silent (see lee_mipmap.h):
//   1. base pass: I(0) (colour kept in [1e-18, 1e18] for eq. 4.8's logarithms), Z(0), B(0) = sigma =
//      dob_per_coc x C with the CoC model's terms (dof/lens.h CocModel::terms), per pixel;
//   2.-3. one pass per level l = 1..top: Z and B by eq. 4.1's [1 2 1] / 4 Gaussian read as three
//      bilinear taps per axis (4 texels: the CPU's Taps), the colour with eq. 4.9's anisotropic
//      weights, the DoN N(l) of eq. 4.10 from level l - 1, and the largest DoB below (a max pyramid,
//      so the top level's texel is the image's largest DoB and no readback is needed to choose M);
//   4.-5. final pass: M from that largest DoB (as top_mipmap_level), eq. 4.11's smoothing from N(M),
//      m by eq. 4.6 and eq. 4.8's geometric blend over the circular 3x3 at levels m - 1 and m.
// Levels above M are built too (each a quarter of the one below): the pass never waits for the GPU.
// The levels are regions of two atlases (see Atlas below), not GL mipmap levels.
//
// Differences from the CPU reference, by design: bilinear reads by the texture unit (NVIDIA and
// other GPUs quantise the filter weight to 8 bits; llvmpipe does not), GLSL's exp2/log2 for eq. 4.8,
// and the output clamped to the largest of the samples it blends (the CPU clamps to the image's
// largest input, a looser bound of the same quantity). tests/gl/test_gl_lee_mipmap.cpp states the
// tolerance (PSNR against the CPU reference) and bench/RESULTS.md the measured agreement.
//
// Two implementations of the same passes (issue 42): fragment passes (OpenGL 3.3: float colour
// attachments, several draw buffers) and compute passes (OpenGL 4.3) that write the atlases and the
// output as images, with no framebuffer, no rasteriser and no blending unit between. Each pass's body
// is one GLSL function of its texel shared by both, so they agree up to the device's arithmetic.
// GlFrame takes the compute passes where compute pays (GlFeatures::compute_pays).
#include <cstdint>
#include <initializer_list>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "dof/lee_mipmap.h"
#include "dof/lens.h"

namespace fovea::render {

// An image on the GPU: colour (RGBA float, linear HDR) and view-axis depth (R float, metres) in
// their lower-left width x height texels, rows bottom-up (OpenGL's order).
struct GlDofInput {
  unsigned color = 0, depth = 0;
  std::uint32_t width = 0, height = 0;
};

class GlLeeMipmap {
 public:
  enum class Pass { Fragment, Compute };
  // Compiles the passes on the current context (the compute passes only with `compute`: OpenGL 4.3);
  // throws std::runtime_error with the driver's log.
  explicit GlLeeMipmap(bool compute = false);
  bool has_compute() const { return base_program_[1] != 0; }
  ~GlLeeMipmap();
  GlLeeMipmap(const GlLeeMipmap&) = delete;
  GlLeeMipmap& operator=(const GlLeeMipmap&) = delete;

  // Submits the passes (does not wait). The result is output(): RGBA32F, width x height, bottom-up.
  // A pinhole model copies the input (non-finite and negative colour as 0, as the CPU reference).
  // Pass::Compute without has_compute() throws std::invalid_argument.
  void run(const GlDofInput& in, const dof::CocModel& coc, const dof::LeeMipmapSettings& s, Pass pass = Pass::Fragment);
  unsigned output() const { return output_; }
  int levels_built() const { return top_; }  // the top level built (M <= top is chosen on the GPU)

  // For tests and benchmarks: `in` (row 0 at the top, as dof_image.h) goes up, the passes run, the
  // result comes back into `out` (row 0 at the top). gpu_ms: the passes alone (timestamp queries),
  // without the upload and the readback.
  void run_image(const dof::DofInput& in, const dof::LeeMipmapSettings& s, dof::RgbImage& out, double* gpu_ms = nullptr,
                 Pass pass = Pass::Fragment);

 private:
  static constexpr int kMaxLevels = 16;  // levels 0..15: an image side below 65536 px
  void ensure_targets(std::uint32_t width, std::uint32_t height);
  void base_pass(const GlDofInput& in, const dof::CocModel& coc, const dof::LeeMipmapSettings& s);
  void level_pass(int level, float zf, const dof::LeeMipmapSettings& s);
  void final_pass(const GlDofInput& in, int top, const dof::LeeMipmapSettings& s);  // top 0: a copy
  void draw_into(unsigned target, std::initializer_list<unsigned> textures, glm::ivec2 origin, glm::ivec2 size);

  // [0]: the fragment passes, [1]: the compute passes (0 when not built).
  unsigned base_program_[2] = {0, 0}, level_program_[2] = {0, 0}, final_program_[2] = {0, 0}, vao_ = 0, fbo_ = 0;
  bool compute_ = false;  // the passes of the current run
  // The mipmaps of colour I (RGBA32F), ZBN (RGBA32F: Z, B, the largest B at or below, unused) and
  // the DoN (R32F; level l from level l - 1), each level in a region of an atlas (rectangle
  // textures): the even levels in atlas_[0], the odd ones in atlas_[1], so a pass reads level l - 1
  // from one texture while it writes level l into the other. Not GL mipmaps: which level a pixel
  // reads is then a coordinate, not a LOD, and no implementation's LOD rules change it (llvmpipe
  // shares one explicit LOD among a 2x2 quad, which blends the wrong levels at silhouettes).
  struct Atlas {
    unsigned color = 0, zs = 0, don = 0;
    int width = 0, height = 0;
  };
  Atlas atlas_[2];
  glm::ivec2 origin_[kMaxLevels] = {}, size_[kMaxLevels] = {};  // level l's region in atlas_[l & 1]
  unsigned output_ = 0;
  std::uint32_t width_ = 0, height_ = 0;
  int top_ = 0;
  // run_image's upload textures and query pair.
  unsigned upload_color_ = 0, upload_depth_ = 0, queries_[2] = {0, 0};
  std::vector<float> staging_;
};

}  // namespace fovea::render
