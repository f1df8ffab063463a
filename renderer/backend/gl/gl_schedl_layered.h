// SPDX-License-Identifier: Apache-2.0
#pragma once
// Schedl & Wimmer's layered depth of field (dof/schedl_layered.h, the CPU reference) as OpenGL 3.3
// passes on the visible image and its depth-peeled layers (gl_peel.h), with the same steps:
//   1. a reduction of every input layer's finite depths (min, max) and the visible colour's largest
//      channel, read back (4 floats): the CPU chooses the layers' anchors from them with the CPU
//      pass's own code (schedl_anchors, eqs. 5-9), so both cut the same K layers;
//   2. per layer k a matting pass (eqs. 2-4: the visible layer with w_k, the peeled ones with w'_k,
//      premultiplied, front to back), fused with the cascade's "over" (eqs. 12-13);
//   3. the cascade's blurs H^_k (sigma^_k = |k - kf|, eq. 14) as three box blurs of matched variance
//      per axis (schedl_box_radii), edges clamped;
//   4. the composite (eq. 13) normalised by its alpha (§3.3.1), clamped to the largest input channel;
//      where nothing covers a pixel, the input.
// Differences from the CPU: each box blur sums its 2r + 1 taps, read in bilinear pairs (the CPU keeps
// a running sum), and
// anchors and depths are compared in float; tests/gl/test_gl_schedl_layered.cpp states the tolerance.
// The input layers are packed (colour and depth in one texture each) so that eight of them and an
// accumulator fit OpenGL 3.3's 16 texture units.
//
// Pass::Compute (OpenGL 4.3, issue 42) runs every step as compute passes: steps 1, 2 and 4 are the
// fragment passes' GLSL (one function of the output texel, called by either kind of shader), step 3
// separable running sums: O(1) per pixel however wide the box (the fragment pass reads r + 1 bilinear
// pairs), compensated. GlFrame takes them where compute pays (frame.effect_passes).
#include <cstdint>
#include <utility>
#include <vector>

#include "backend/gl/gl_lee_mipmap.h"
#include "dof/schedl_layered.h"

namespace fovea::render {

class GlSchedlLayered {
 public:
  static constexpr int kMaxInputLayers = 8;  // dof.layers' range: the visible one and 7 peeled

  enum class Pass { Fragment, Compute };
  // Compiles the passes on the current context (the compute box blur only with `compute`: OpenGL
  // 4.3); throws std::runtime_error with the driver's log.
  explicit GlSchedlLayered(bool compute = false);
  bool has_compute() const { return box_compute_ != 0; }
  ~GlSchedlLayered();
  GlSchedlLayered(const GlSchedlLayered&) = delete;
  GlSchedlLayered& operator=(const GlSchedlLayered&) = delete;

  // `visible` and `peeled` (the layers behind it, front to back, at most kMaxInputLayers - 1): the
  // result is output(), RGBA32F, bottom-up. Waits for the reduction (a few floats) before the layers.
  // Pass::Compute without has_compute() throws std::invalid_argument.
  dof::SchedlStats run(const GlDofInput& visible, const std::vector<GlDofInput>& peeled, const dof::CocModel& coc,
                       const dof::SchedlSettings& s, Pass pass = Pass::Fragment);
  unsigned output() const { return output_; }

  // For tests and benchmarks: the images (row 0 at the top) go up, the passes run, the result comes
  // back. gpu_ms: the passes alone (timestamp queries), the reduction's wait included.
  dof::SchedlStats run_image(const dof::DofInput& in, const std::vector<dof::PeeledLayer>& peeled,
                             const dof::SchedlSettings& s, dof::RgbImage& out, double* gpu_ms = nullptr,
                             Pass pass = Pass::Fragment);

 private:
  struct Range {
    float zmin, zmax, max_in;
  };
  void ensure(std::uint32_t width, std::uint32_t height);
  void release();
  // Each input layer's sanitised colour and depth into packed_ (one texture per layer).
  void pack(const GlDofInput& visible, const std::vector<GlDofInput>& peeled);
  void bind_layers(unsigned program) const;  // packed_ to units 0..7, and u_inputs
  Range reduce();
  // Matting of layer k (eq. 2) into `to`, with what `acc` holds: mode 0 L_k alone, 1 acc over L_k
  // (the front cascade), 2 L_k over acc (the back cascade).
  void matte(const dof::SchedlAnchors& an, int k, int mode, unsigned acc, unsigned to);
  void gaussian(unsigned image, double sigma);  // in place, through scratch_
  void gaussian_compute(unsigned image, double sigma);
  // The composite into output_ (front, back: 0 where there is no such cascade; copy: the input).
  void composite(unsigned front, unsigned back, bool copy, float max_in);
  void draw_into(unsigned program, unsigned texture, std::uint32_t w, std::uint32_t h);

  // The passes as shade() functions: [0] fragment passes, [1] compute passes (0 when not built).
  struct Passes {
    unsigned pack = 0, reduce_first = 0, reduce_next = 0, matte = 0, composite = 0;
  };
  Passes passes_[2];
  const Passes& passes() const { return passes_[compute_ ? 1 : 0]; }
  unsigned box_program_ = 0;
  unsigned box_compute_ = 0;  // 0: not built
  bool compute_ = false;      // this run's box blur
  unsigned vao_ = 0, fbo_ = 0, queries_[2] = {0, 0};
  // Full-size RGBA32F images: the packed inputs, the cascades' accumulators (two each, ping-pong),
  // L_kf, blur scratch, the output.
  unsigned packed_[kMaxInputLayers] = {};
  unsigned front_[2] = {0, 0}, back_[2] = {0, 0}, layer_ = 0, scratch_ = 0, output_ = 0;
  std::vector<unsigned> reduction_;  // the reduction's levels, halving to 1x1
  std::vector<std::pair<std::uint32_t, std::uint32_t>> reduction_sizes_;
  std::uint32_t width_ = 0, height_ = 0;
  int inputs_ = 1;  // this run's input layers
  // run_image's uploads: colour and depth per input layer.
  std::vector<unsigned> upload_color_, upload_depth_;
  std::vector<float> staging_;
};

}  // namespace fovea::render
