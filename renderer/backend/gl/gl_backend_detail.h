// SPDX-License-Identifier: Apache-2.0
#pragma once
// What GlBackend's files share: the G-buffer's attachments, the std140 layout of the light
// samples, and GL errors as exceptions. Internal to the backend: gl_backend.cpp (programs,
// framebuffers, drawing), gl_backend_scene.cpp (the scene uploaded), gl_backend_textures.cpp (its
// textures and PBR materials), gl_backend_readback.cpp (the G-buffer read back to the CPU).
#include <epoxy/gl.h>

#include <cmath>
#include <cstddef>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace fovea::render::gl_backend_detail {

enum Attachment : std::size_t { kColor = 0, kDepth = 1, kId = 2, kNormal = 3, kMotion = 4 };
constexpr std::size_t kNoMesh = static_cast<std::size_t>(-1);  // DrawItem of an object without a mesh
// The G-buffer program's material textures take units 8..12 (one per PBR slot; 6 and 7 are the
// peel pass's).
constexpr int kMaterialTextureUnit = 8;
constexpr GLenum kDrawBuffers[5] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2,
                                    GL_COLOR_ATTACHMENT3, GL_COLOR_ATTACHMENT4};

// std140 layout of one LightSample in the LightSamples uniform block (shaders.h).
struct LightSampleStd140 {
  float position_kind[4];
  float power_cutoff[4];
  float direction_start[4];
};
static_assert(sizeof(LightSampleStd140) == 48);

inline std::string hex(unsigned v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%04X", v);
  return buf;
}

inline void check_gl(const char* where) {
  const GLenum error = glGetError();
  if (error == GL_NO_ERROR) return;
  while (glGetError() != GL_NO_ERROR) {
  }
  throw std::runtime_error(std::string("GlBackend: OpenGL error ") + hex(error) + " in " + where);
}

inline float finite_or(float v, float fallback) { return std::isfinite(v) ? v : fallback; }

}  // namespace fovea::render::gl_backend_detail
