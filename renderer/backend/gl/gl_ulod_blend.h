// SPDX-License-Identifier: Apache-2.0
#pragma once
// ULOD's blend of adjacent levels (Lee 2009 §7.3 with Giegl et al.'s unpopping LOD; lod/lod_frame.h
// ulod_blend, the CPU reference) as one OpenGL 3.3 pass where the frame lies: each pixel whose object
// is blending and whose id is the same in the image of the drawn levels and in the image of the next
// levels gets (1 - f) drawn + f next, f the object's blend factor; every other pixel keeps its colour.
// The result replaces the drawn image's colour texture, so every later pass (dof, the tone map) reads
// the blended colour as it would read the G-buffer's.
//
// Two implementations (issue 42): a fragment pass that renders the blended image aside and copies it
// back (a pass cannot read and write one texture), and an OpenGL 4.3 compute pass that blends in
// place (each invocation reads and writes only its own texel, and skips every pixel that keeps its
// colour), with no copy. GlFrame takes the compute pass where compute pays (GlFeatures::compute_pays).
#include <cstdint>
#include <vector>

namespace fovea::render {

class GlUlodBlend {
 public:
  enum class Pass { Fragment, Compute };
  // Compiles the passes on the current context (the compute pass only with `compute`: OpenGL 4.3);
  // throws std::runtime_error with the driver's log.
  explicit GlUlodBlend(bool compute);
  bool has_compute() const { return compute_program_ != 0; }
  ~GlUlodBlend();
  GlUlodBlend(const GlUlodBlend&) = delete;
  GlUlodBlend& operator=(const GlUlodBlend&) = delete;

  struct Image {  // colour (RGBA32F) and ids (R32UI) in the lower-left width x height texels
    unsigned color = 0, object_id = 0;
    std::uint32_t width = 0, height = 0;
  };
  // `ids` and `blend`: the blending objects and their factors (clamped to [0, 1]; ids in any order,
  // the first of a repeated id counts). Throws std::invalid_argument when they differ in length or
  // the images in size.
  // Pass::Compute without has_compute() throws std::invalid_argument.
  void run(const Image& drawn, const Image& next, const std::vector<std::uint32_t>& ids, const std::vector<float>& blend,
           Pass pass = Pass::Fragment);

 private:
  void ensure_result(std::uint32_t width, std::uint32_t height);
  void ensure_table(std::size_t objects);
  void upload_table(const std::vector<std::uint32_t>& ids, const std::vector<float>& blend);
  void run_fragment(const Image& drawn, const Image& next);
  void run_compute(const Image& drawn, const Image& next);
  unsigned program_ = 0, compute_program_ = 0, vao_ = 0, fbo_ = 0, result_ = 0, table_ids_ = 0, table_blend_ = 0;
  int count_ = 0;  // blending objects in the table
  std::uint32_t width_ = 0, height_ = 0;
  std::size_t capacity_ = 0;
};

}  // namespace fovea::render
