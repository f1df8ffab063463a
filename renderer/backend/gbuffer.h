// SPDX-License-Identifier: Apache-2.0
#pragma once
// The G-buffer every backend produces and every pass reads. Row-major, row 0 at the top of the
// image, pixel (x, y) covers [x, x+1) x [y, y+1) and is sampled at its centre.
#include <cstdint>
#include <glm/glm.hpp>
#include <string>
#include <vector>

namespace fovea::render {

// Which planes of a G-buffer a pass reads: what the raster backend reads back from the GPU
// (BackendSettings::readback) and what the frame's passes declare.
struct GBufferPlanes {
  bool color = false, depth = false, object_id = false, normal = false, motion = false;
  static constexpr GBufferPlanes all() { return {true, true, true, true, true}; }
  static constexpr GBufferPlanes none() { return {}; }
  bool any() const { return color || depth || object_id || normal || motion; }
  GBufferPlanes operator|(const GBufferPlanes& o) const {
    return {color || o.color, depth || o.depth, object_id || o.object_id, normal || o.normal, motion || o.motion};
  }
  bool operator==(const GBufferPlanes&) const = default;
};

// "colour, depth, id", or "nothing": for people (--explain).
inline std::string to_string(const GBufferPlanes& p) {
  std::string out;
  const auto add = [&](bool on, const char* name) {
    if (on) out += (out.empty() ? "" : ", ") + std::string(name);
  };
  add(p.color, "colour");
  add(p.depth, "depth");
  add(p.object_id, "id");
  add(p.normal, "normal");
  add(p.motion, "motion");
  return out.empty() ? "nothing" : out;
}

struct GBuffer {
  std::uint32_t width = 0, height = 0;
  std::vector<glm::vec3> color;          // HDR local illumination, linear RGB radiance
  std::vector<float> depth;              // linear view-space depth (metres along the view axis); far plane where nothing is hit
  std::vector<std::uint32_t> object_id;  // Object::id, 0 where nothing is hit
  std::vector<glm::vec3> normal;         // world-space unit normal facing the camera; 0 where nothing is hit
  std::vector<glm::vec2> motion;         // screen-space motion in pixels: position now minus position at the previous frame

  void resize(std::uint32_t w, std::uint32_t h);
  std::size_t index(std::uint32_t x, std::uint32_t y) const { return std::size_t{y} * width + x; }
  std::size_t size() const { return std::size_t{width} * height; }
};

inline void GBuffer::resize(std::uint32_t w, std::uint32_t h) {
  width = w;
  height = h;
  const std::size_t n = size();
  color.assign(n, glm::vec3(0.0f));
  depth.assign(n, 0.0f);
  object_id.assign(n, 0);
  normal.assign(n, glm::vec3(0.0f));
  motion.assign(n, glm::vec2(0.0f));
}

}  // namespace fovea::render
