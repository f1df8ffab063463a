// SPDX-License-Identifier: Apache-2.0
#pragma once
// Lee 2009 chapter 5's depth of field by point splatting (dof/lee_splat.h, the CPU reference) as
// OpenGL 3.3 passes: the same settings and the same choices where the paper is silent.
//   1. classify (per pixel): the source colour (NaN as 0, eq. 5.5's LDR highlights when asked),
//      B_v by eq. 5.3 (CocModel::terms), and the hidden pixel's three tests of §5.1.2 (eq. 5.1's
//      Laplacian over the 12 Poisson samples) with its colour and B_h;
//   2. normalise (per point): eq. 5.2's k_n(C) as 1 / the footprint's IDF sum, over the exact
//      discrete footprint (disc, Gaussian sigma = C/4, or hexagon) as the CPU sums it;
//   3. splat: one instanced quad per point (the visible pixel, and its hidden pixel where it passed)
//      over its footprint; each fragment inside it adds the point's premultiplied colour and weight
//      to one of the destination pixel's three layers (eq. 5.3: in front / same depth / behind,
//      against that pixel's B_v and delta C_v) by additive blending into three float targets;
//   4. compose: eq. 5.4 back to front with each composite divided by its alpha.
// Pass::Compute (OpenGL 4.3, issue 42) does step 3 as a tiled gather in compute passes instead of
// rasterised quads and blending (the same sums, added in pixel order: see kSplatCompute); GlFrame
// takes it where compute pays (frame.effect_passes).
// §5.3's reduced point array (LeeSplatSettings::reduce > 1) stays on the CPU; run() refuses it.
//
// Differences from the CPU reference, by design: float arithmetic where the CPU uses double (the
// footprint rim, the Gaussian IDF) and the order in which splats are added (the GPU adds in point
// order, the CPU per radius class and row). tests/gl/test_gl_lee_splat.cpp states the tolerance.
//
// Needs a current OpenGL 3.3 context (instanced draws, float blending, several draw buffers).
#include <cstdint>
#include <initializer_list>
#include <vector>

#include "backend/gl/gl_lee_mipmap.h"  // GlDofInput
#include "dof/lee_splat.h"

namespace fovea::render {

class GlLeeSplat {
 public:
  enum class Pass { Fragment, Compute };
  // Compiles the passes on the current context (the compute splat only with `compute`: OpenGL 4.3);
  // throws std::runtime_error with the driver's log.
  explicit GlLeeSplat(bool compute = false);
  bool has_compute() const { return splat_compute_program_ != 0; }
  ~GlLeeSplat();
  GlLeeSplat(const GlLeeSplat&) = delete;
  GlLeeSplat& operator=(const GlLeeSplat&) = delete;

  // Submits the passes (does not wait). `hidden`: the hidden image H (colour and depth of the first
  // peeled layer, the same size as `in`), or null; used when s.use_hidden. The result is output():
  // RGBA32F, in's size, bottom-up. Throws std::invalid_argument for s.reduce > 1 (§5.3 runs on the
  // CPU only), a hidden image of another size, or Pass::Compute without has_compute().
  void run(const GlDofInput& in, const GlDofInput* hidden, const dof::CocModel& coc, const dof::LeeSplatSettings& s,
           Pass pass = Pass::Fragment);
  unsigned output() const { return output_; }

  // For tests and benchmarks: `in` (row 0 at the top, as dof_image.h, with its hidden image if any)
  // goes up, the passes run, the result comes back into `out`. gpu_ms: the passes alone.
  void run_image(const dof::DofInput& in, const dof::LeeSplatSettings& s, dof::RgbImage& out, double* gpu_ms = nullptr,
                 Pass pass = Pass::Fragment);

 private:
  void ensure_targets(std::uint32_t width, std::uint32_t height);
  void classify(const GlDofInput& in, const GlDofInput* hidden, const dof::CocModel& coc, const dof::LeeSplatSettings& s);
  void normalise(const dof::CocModel& coc, const dof::LeeSplatSettings& s);
  void splat(const dof::CocModel& coc, const dof::LeeSplatSettings& s);
  void splat_compute(const dof::CocModel& coc, const dof::LeeSplatSettings& s);
  void use_splat_program(unsigned program, const dof::CocModel& coc, const dof::LeeSplatSettings& s);
  void compose(bool copy, unsigned input_color);  // copy: a pinhole, the input as it is
  void draw_into(std::initializer_list<unsigned> targets);

  unsigned classify_program_ = 0, norm_program_ = 0, splat_program_ = 0, compose_program_ = 0, vao_ = 0, fbo_ = 0;
  unsigned reach_program_ = 0, splat_compute_program_ = 0, reach_ = 0;  // 0: built without compute
  // Per pixel: source (rgb, B_v), hidden (rgb, B_h), hidden passed (r: 1 or 0); per point: k_n
  // (r: the visible point's, g: the hidden point's); the three layers (premultiplied rgb, alpha).
  unsigned source_ = 0, hidden_ = 0, hidden_ok_ = 0, norm_ = 0, layers_[3] = {0, 0, 0}, output_ = 0;
  std::uint32_t width_ = 0, height_ = 0;
  // run_image's uploads and query pair.
  unsigned upload_color_ = 0, upload_depth_ = 0, upload_hidden_color_ = 0, upload_hidden_depth_ = 0;
  unsigned queries_[2] = {0, 0};
  std::vector<float> staging_;
};

}  // namespace fovea::render
