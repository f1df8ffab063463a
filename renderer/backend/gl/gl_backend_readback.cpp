// SPDX-License-Identifier: Apache-2.0
// GlBackend's G-buffer read back to the CPU (gl_backend.h): the planes asked for, flipped to row 0
// at the top with non-finite values replaced, and a rectangle of depth and ids for the passes that
// need only what lies under the gaze.
#include <epoxy/gl.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_backend_detail.h"

namespace fovea::render {

using namespace gl_backend_detail;

void GlBackend::read_back(const GBufferPlanes& planes, GBuffer& out) { read_back_from(fbo_, planes, out); }

void GlBackend::read_back_from(unsigned fbo, const GBufferPlanes& planes, GBuffer& out) {
  const std::uint32_t w = out.width, h = out.height;
  if (w == 0 || h == 0) return;
  context_.make_current();
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  const auto gw = static_cast<GLsizei>(w), gh = static_cast<GLsizei>(h);
  const float far_m = scene_->camera.far_m;
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  const std::size_t n = out.size();

  // Reads attachment `index` into scratch with `channels` floats per pixel.
  const auto read_float = [&](std::size_t index, GLenum format, std::size_t channels) {
    scratch_.resize(n * channels);
    glReadBuffer(kDrawBuffers[index]);
    glReadPixels(0, 0, gw, gh, format, GL_FLOAT, scratch_.data());
  };
  // GL rows start at the bottom; the G-buffer's row 0 is the top.
  const auto src = [&](std::uint32_t x, std::uint32_t y) { return std::size_t{h - 1 - y} * w + x; };
  // An RGBA32F attachment's RGB into a vec3 plane, non-finite values as 0.
  const auto read_vec3 = [&](std::size_t index, std::vector<glm::vec3>& plane) {
    read_float(index, GL_RGBA, 4);
    for (std::uint32_t y = 0; y < h; ++y) {
      for (std::uint32_t x = 0; x < w; ++x) {
        const float* p = &scratch_[4 * src(x, y)];
        plane[out.index(x, y)] = {finite_or(p[0], 0), finite_or(p[1], 0), finite_or(p[2], 0)};
      }
    }
  };

  if (planes.color) read_vec3(kColor, out.color);
  if (planes.depth) {
    read_float(kDepth, GL_RED, 1);
    for (std::uint32_t y = 0; y < h; ++y) {
      for (std::uint32_t x = 0; x < w; ++x) out.depth[out.index(x, y)] = finite_or(scratch_[src(x, y)], far_m);
    }
  } else {
    std::fill(out.depth.begin(), out.depth.end(), far_m);
  }
  if (planes.normal) read_vec3(kNormal, out.normal);
  if (planes.motion) {
    read_float(kMotion, GL_RG, 2);
    for (std::uint32_t y = 0; y < h; ++y) {
      for (std::uint32_t x = 0; x < w; ++x) {
        const float* p = &scratch_[2 * src(x, y)];
        out.motion[out.index(x, y)] = {finite_or(p[0], 0), finite_or(p[1], 0)};
      }
    }
  }
  if (planes.object_id) {
    scratch_id_.resize(n);
    glReadBuffer(kDrawBuffers[kId]);
    glReadPixels(0, 0, gw, gh, GL_RED_INTEGER, GL_UNSIGNED_INT, scratch_id_.data());
    for (std::uint32_t y = 0; y < h; ++y) {
      std::memcpy(&out.object_id[out.index(0, y)], &scratch_id_[src(0, y)], std::size_t{w} * sizeof(std::uint32_t));
    }
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  check_gl("GlBackend::render (read back)");
}

void GlBackend::read_back_rect(std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1,
                               std::vector<float>& depth, std::vector<std::uint32_t>& ids) {
  if (x1 > image_width_ || y1 > image_height_ || x0 > x1 || y0 > y1) {
    throw std::invalid_argument("GlBackend::read_back_rect: [" + std::to_string(x0) + ", " + std::to_string(x1) + ") x [" +
                                std::to_string(y0) + ", " + std::to_string(y1) + ") is not inside the " +
                                std::to_string(image_width_) + "x" + std::to_string(image_height_) + " image");
  }
  const std::uint32_t w = x1 - x0, h = y1 - y0;
  depth.resize(std::size_t{w} * h);
  ids.resize(std::size_t{w} * h);
  if (w == 0 || h == 0) return;
  context_.make_current();
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  // GL rows start at the bottom: the rectangle's top row y0 is GL row image_height_ - 1 - y0.
  const auto gx = static_cast<GLint>(x0), gy = static_cast<GLint>(image_height_ - y1);
  const auto gw = static_cast<GLsizei>(w), gh = static_cast<GLsizei>(h);
  scratch_.resize(std::size_t{w} * h);
  scratch_id_.resize(std::size_t{w} * h);
  glReadBuffer(kDrawBuffers[kDepth]);
  glReadPixels(gx, gy, gw, gh, GL_RED, GL_FLOAT, scratch_.data());
  glReadBuffer(kDrawBuffers[kId]);
  glReadPixels(gx, gy, gw, gh, GL_RED_INTEGER, GL_UNSIGNED_INT, scratch_id_.data());
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  const float far_m = scene_ ? scene_->camera.far_m : 100.0f;
  for (std::uint32_t y = 0; y < h; ++y) {
    const std::size_t from = std::size_t{h - 1 - y} * w, to = std::size_t{y} * w;
    for (std::uint32_t x = 0; x < w; ++x) depth[to + x] = finite_or(scratch_[from + x], far_m);
    std::memcpy(&ids[to], &scratch_id_[from], std::size_t{w} * sizeof(std::uint32_t));
  }
  check_gl("GlBackend::read_back_rect");
}

}  // namespace fovea::render
