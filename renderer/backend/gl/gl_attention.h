// SPDX-License-Identifier: Apache-2.0
#pragma once
// Lee 2009 chapter 3's pixel stage (attention/attention.h, the CPU reference) as OpenGL passes,
// as Lee's own implementation ran it (Fig. 3.3: the feature maps, their pyramids and eq. 3.4's
// centre-surround differences as fragment shaders), followed by the per-object reduction of eq. 3.7
// on the GPU. Only the per-object values are read back (16 x 4 + 1 numbers per scene object); the
// CPU's object stage (AttentionTracker::update_objects: the top-down contexts of eqs. 3.8-3.10 and the
// Kalman filter) takes them from there. The same settings and the same choices as the CPU's:
//   1. resample: the G-buffer to the n x n map, box or nearest (the same integer pixel ranges), HLS
//      and eq. 3.1 per map pixel; the item buffer nearest, as each pixel's object slot; the nearest
//      depth for the per-object median;
//   2. count: each object's pixels in the map (a scatter of one point per map pixel, additive
//      blending, the classic GPU histogram), so the size plane (eq. 3.2) needs no readback;
//   3. paint: the size and motion planes (eqs. 3.2, 3.3; B_m per object from the CPU, uploaded);
//   4. pyramids: levels 1..6 by 2x2 boxes, the CPU's sizes (ceil(n / 2), the edge texel repeated);
//   5. contrast: eq. 3.4 per feature, coarse levels magnified bilinearly by the CPU's arithmetic
//      (four texel fetches, not the texture unit, whose filter weights are 8-bit on most GPUs);
//   6. eqs. 3.5-3.6: each contrast map's maximum by a reduction, the weighted sum, its range by a
//      second reduction, S_p normalised to [0, 1];
//   7. per object: pixels, the sum of S_p and of the pixel centres (a scatter into 16 bands of map
//      rows each, added in double on the CPU), and the exact median depth by a radix select on the
//      depth's bits (four scatter-and-select rounds of 8 bits, no readback between them).
// Differences from the CPU reference, by design: sums in float on the GPU (the CPU adds in double),
// GLSL's cos/sin for the hue vector (the CPU's table is within 3e-6 of them). tests/gl/
// test_gl_attention.cpp states the tolerances; bench/RESULTS.md has the measured agreement.
//
// Needs a current OpenGL 3.3 context (integer textures, float blending, several draw buffers); the
// compute passes OpenGL 4.3.
#include <cstdint>
#include <vector>

#include "attention/attention.h"
#include "backend/gbuffer.h"

namespace fovea::render {

// The G-buffer where it lies: colour (RGBA float, linear HDR), view depth (R float, metres) and
// object ids (R32UI) in their lower-left width x height texels, rows bottom-up (OpenGL's order). A
// plane the frame does not have is 0 (colour: black; depth: the far plane; ids: no objects).
struct GlAttentionInput {
  unsigned color = 0, depth = 0, object_id = 0;
  std::uint32_t width = 0, height = 0;
};

// The scene's objects as the pixel stage sees them: their ids and each one's B_m (eq. 3.3) this
// frame (AttentionTracker::object_motion), in any order; ids not listed are background.
struct GlAttentionObjects {
  std::vector<std::uint32_t> ids;
  std::vector<float> motion;
};

class GlAttention {
 public:
  // Every full-screen pass (resample, paint, pyramid, contrast, reductions, weigh, normalise, the
  // radix select's) is one GLSL function of its output texel, run by a fragment shader (OpenGL 3.3)
  // or a compute shader (OpenGL 4.3, writing images): the same values either way. The scatters
  // (steps 2 and 7) stay point draws with additive blending in both: their sums are floats, and core
  // OpenGL has no float atomics.
  enum class Pass { Fragment, Compute };
  // Compiles the passes on the current context (the compute ones too with `compute`, which needs
  // OpenGL 4.3); throws std::runtime_error with the driver's log.
  explicit GlAttention(bool compute = false);
  bool has_compute() const { return resample_program_[1] != 0; }
  ~GlAttention();
  GlAttention(const GlAttention&) = delete;
  GlAttention& operator=(const GlAttention&) = delete;

  // The pixel stage on `in` with the camera's depth range [near_m, far_m] (eq. 3.1) and `s`'s
  // map_size, resample and groups: `out` gets one entry per listed object with pixels in the map.
  // Waits for the GPU (the per-object values are read back). Throws std::invalid_argument for
  // settings that fail AttentionSettings::check(), motion values not one per id, or Pass::Compute
  // without has_compute().
  void run(const GlAttentionInput& in, double near_m, double far_m, const attention::AttentionSettings& s,
           const GlAttentionObjects& objects, std::vector<attention::ObjectPixels>& out, Pass pass = Pass::Fragment);
  int map_size() const { return n_; }
  // S_p of the last run, map_size^2, row 0 at the top (tests, overlays, the finite check).
  void read_saliency(std::vector<float>& out);
  // The contrast maps C_l, C_h, C_d, C_s, C_m of the last run (as AttentionFrame::contrast).
  void read_contrast(std::vector<float> (&out)[5]);

  // For tests and benchmarks: `g` (row 0 at the top) goes up, the passes run. gpu_ms: the passes
  // alone (timestamp queries), without the upload; the readback of the per-object values included.
  void run_gbuffer(const GBuffer& g, double near_m, double far_m, const attention::AttentionSettings& s,
                   const GlAttentionObjects& objects, std::vector<attention::ObjectPixels>& out,
                   double* gpu_ms = nullptr, Pass pass = Pass::Fragment);

 private:
  static constexpr int kLevels = 7;  // as the CPU's pyramid: levels 0..6
  struct Level {
    unsigned image = 0, object = 0;  // RGBA32F (L, hue a, hue b, B_d) and RG32F (B_s, B_m)
    int w = 0, h = 0;
  };
  void ensure_map(int n);
  void ensure_objects(std::size_t count);
  void upload_objects(const GlAttentionObjects& objects);
  void resample(const GlAttentionInput& in, double near_m, double far_m, const attention::AttentionSettings& s);
  void scatter(int mode, unsigned target, int target_w, int target_h, int shift);
  void paint_and_pyramids();
  void contrast(const attention::FeatureGroups& groups);
  unsigned reduce_max(unsigned in0, unsigned in1);  // returns the 1x1 texture pair's first; second in reduced1_
  void saliency(const attention::FeatureGroups& groups);
  void median_depths();
  void read_objects(std::vector<attention::ObjectPixels>& out);
  struct Target {
    unsigned texture;
    unsigned format;  // GLenum internal format, for the compute pass's image binding
  };
  unsigned use(const unsigned (&programs)[2]) const;  // this run's implementation of the pass, made current
  void draw(std::initializer_list<Target> targets, int w, int h);

  // Per full-screen pass: [0] its fragment program, [1] its compute program (0 when not built).
  unsigned resample_program_[2] = {0, 0}, paint_program_[2] = {0, 0}, down_program_[2] = {0, 0},
           contrast_program_[2] = {0, 0}, reduce_program_[2] = {0, 0}, weigh_program_[2] = {0, 0},
           normalise_program_[2] = {0, 0}, select_init_program_[2] = {0, 0}, select_program_[2] = {0, 0};
  unsigned scatter_program_ = 0;
  bool compute_ = false;  // this run's passes are the compute ones
  unsigned vao_ = 0, fbo_ = 0;
  int n_ = 0;
  Level levels_[kLevels];
  unsigned slots_ = 0, map_depth_ = 0;       // R32UI slot + 1 per map pixel; R32F nearest depth
  unsigned contrast_[2] = {0, 0};            // RGBA32F (C_l, C_h, C_d, C_s) and (C_m, 0, 0, 0)
  unsigned weighted_ = 0, saliency_ = 0;     // RGBA32F (sum w C, -sum w C); R32F S_p
  std::vector<unsigned> reduce_chain_[2];    // RGBA32F, each stage an eighth of the one before
  std::vector<int> reduce_w_, reduce_h_;
  unsigned reduced_[2] = {0, 0};             // the chains' 1x1 ends of the last reduce_max
  // Per scene object (a slot, in ascending id order), laid out kSlotRow per texture row.
  std::size_t objects_ = 0, object_capacity_ = 0;
  unsigned object_ids_ = 0, object_motion_ = 0, counts_ = 0, sums_ = 0, histogram_ = 0, select_[2] = {0, 0};
  int select_current_ = 0;
  std::vector<std::uint32_t> sorted_ids_;
  std::vector<float> sorted_motion_;
  bool all_groups_off_ = false;
  // run_gbuffer's upload textures and query pair.
  unsigned upload_color_ = 0, upload_depth_ = 0, upload_ids_ = 0, queries_[2] = {0, 0};
  std::vector<float> staging_;
};

}  // namespace fovea::render
