// SPDX-License-Identifier: Apache-2.0
#pragma once
// ULOD's blend of adjacent levels (Lee 2009 §7.3 with Giegl et al.'s unpopping LOD; lod/lod_frame.h
// ulod_blend, the CPU reference) as one OpenGL 3.3 pass where the frame lies: each pixel whose object
// is blending and whose id is the same in the image of the drawn levels and in the image of the next
// levels gets (1 - f) drawn + f next, f the object's blend factor; every other pixel keeps its colour.
// The result replaces the drawn image's colour texture, so every later pass (dof, the tone map) reads
// the blended colour as it would read the G-buffer's.
#include <cstdint>
#include <vector>

namespace fovea::render {

class GlUlodBlend {
 public:
  // Compiles the pass on the current context; throws std::runtime_error with the driver's log.
  GlUlodBlend();
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
  void run(const Image& drawn, const Image& next, const std::vector<std::uint32_t>& ids, const std::vector<float>& blend);

 private:
  void ensure(std::uint32_t width, std::uint32_t height, std::size_t objects);
  unsigned program_ = 0, vao_ = 0, fbo_ = 0, result_ = 0, table_ids_ = 0, table_blend_ = 0;
  std::uint32_t width_ = 0, height_ = 0;
  std::size_t capacity_ = 0;
};

}  // namespace fovea::render
