// SPDX-License-Identifier: Apache-2.0
#include "backend/gl/gl_ulod_blend.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

#include "backend/gl/gl_program.h"

namespace fovea::render {

namespace {

// The blending objects sorted by id, with their factors. Both passes' factor of object `id` from the sorted table (a binary search); false: not blending.
constexpr const char* kLookup = R"(
uniform usampler2D u_ids;
uniform sampler2D u_factors;
uniform int u_count;
bool blend_factor(uint id, out float f) {
  int lo = 0, hi = u_count;
  while (lo < hi) {
    int mid = (lo + hi) >> 1;
    if (texelFetch(u_ids, ivec2(mid, 0), 0).r < id) lo = mid + 1; else hi = mid;
  }
  f = 0.0;
  if (lo >= u_count || texelFetch(u_ids, ivec2(lo, 0), 0).r != id) return false;
  f = texelFetch(u_factors, ivec2(lo, 0), 0).r;
  return true;
}
)";

// The fragment pass: declarations, kLookup, main.
constexpr const char* kBlend = R"(#version 330 core
uniform sampler2D u_drawn, u_next;
uniform usampler2D u_drawn_ids, u_next_ids;
out vec4 o;
)";
constexpr const char* kBlendMain = R"(
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 drawn = texelFetch(u_drawn, p, 0);
  o = drawn;
  uint id = texelFetch(u_drawn_ids, p, 0).r;
  if (id == 0u || texelFetch(u_next_ids, p, 0).r != id) return;
  float f;
  if (!blend_factor(id, f)) return;
  o = vec4((1.0 - f) * drawn.rgb + f * texelFetch(u_next, p, 0).rgb, drawn.a);
}
)";

// The same blend in place: the drawn colour as a read-write image, only blending pixels touched.
constexpr const char* kBlendCompute = R"(#version 430 core
layout(local_size_x = 8, local_size_y = 8) in;
layout(rgba32f, binding = 0) uniform image2D u_drawn;
uniform sampler2D u_next;
uniform usampler2D u_drawn_ids, u_next_ids;
uniform ivec2 u_size;
)";
constexpr const char* kBlendComputeMain = R"(
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= u_size.x || p.y >= u_size.y) return;
  uint id = texelFetch(u_drawn_ids, p, 0).r;
  if (id == 0u || texelFetch(u_next_ids, p, 0).r != id) return;
  float f;
  if (!blend_factor(id, f)) return;
  vec4 drawn = imageLoad(u_drawn, p);
  imageStore(u_drawn, p, vec4((1.0 - f) * drawn.rgb + f * texelFetch(u_next, p, 0).rgb, drawn.a));
}
)";

using gl::delete_texture;

}  // namespace

GlUlodBlend::GlUlodBlend(bool compute) {
  const std::string fragment = std::string(kBlend) + kLookup + kBlendMain;
  program_ = gl::link_program(gl::kFullscreenVertex, fragment.c_str(), "GlUlodBlend");
  if (compute) {
    const std::string source = std::string(kBlendCompute) + kLookup + kBlendComputeMain;
    compute_program_ = gl::link_compute_program(source.c_str(), "GlUlodBlend (compute)");
  }
  glGenVertexArrays(1, &vao_);
  glGenFramebuffers(1, &fbo_);
  gl::check_error("GlUlodBlend", "construction");
}

GlUlodBlend::~GlUlodBlend() {
  glDeleteProgram(program_);
  if (compute_program_ != 0) glDeleteProgram(compute_program_);
  glDeleteVertexArrays(1, &vao_);
  glDeleteFramebuffers(1, &fbo_);
  for (unsigned* t : {&result_, &table_ids_, &table_blend_}) delete_texture(*t);
}

// The fragment pass's result image, sized to the frame.
void GlUlodBlend::ensure_result(std::uint32_t width, std::uint32_t height) {
  if (width != width_ || height != height_ || result_ == 0) {
    delete_texture(result_);
    result_ = gl::make_texture(GL_RGBA32F, GL_RGBA, GL_FLOAT, width, height);
    width_ = width;
    height_ = height;
  }
}

// The table of blending objects, grown to hold `objects`.
void GlUlodBlend::ensure_table(std::size_t objects) {
  if (objects > capacity_ || table_ids_ == 0) {
    GLint max_size = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
    if (objects > static_cast<std::size_t>(max_size)) {
      throw std::runtime_error("GlUlodBlend: " + std::to_string(objects) + " blending objects exceed the device's " +
                               std::to_string(max_size) + "-texel table");
    }
    capacity_ = std::max<std::size_t>(objects, 64);
    delete_texture(table_ids_);
    delete_texture(table_blend_);
    table_ids_ = gl::make_texture(GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, static_cast<std::uint32_t>(capacity_), 1);
    table_blend_ = gl::make_texture(GL_R32F, GL_RED, GL_FLOAT, static_cast<std::uint32_t>(capacity_), 1);
  }
}

void GlUlodBlend::run(const Image& drawn, const Image& next, const std::vector<std::uint32_t>& ids,
                      const std::vector<float>& blend, Pass pass) {
  if (ids.size() != blend.size()) {
    throw std::invalid_argument("GlUlodBlend: " + std::to_string(blend.size()) + " blend factors for " +
                                std::to_string(ids.size()) + " objects");
  }
  if (drawn.width != next.width || drawn.height != next.height) {
    throw std::invalid_argument("GlUlodBlend: the next levels' image is " + std::to_string(next.width) + "x" +
                                std::to_string(next.height) + ", the drawn one " + std::to_string(drawn.width) + "x" +
                                std::to_string(drawn.height));
  }
  if (pass == Pass::Compute && !has_compute()) {
    throw std::invalid_argument("GlUlodBlend: the compute pass needs OpenGL 4.3 (built without it)");
  }
  if (drawn.width == 0 || drawn.height == 0 || ids.empty()) return;
  if (pass == Pass::Fragment) ensure_result(drawn.width, drawn.height);
  upload_table(ids, blend);
  if (pass == Pass::Compute) run_compute(drawn, next);
  else run_fragment(drawn, next);
}

// The table: ids ascending (the first of a repeated id), factors clamped to [0, 1] (NaN: 0).
void GlUlodBlend::upload_table(const std::vector<std::uint32_t>& ids, const std::vector<float>& blend) {
  std::vector<std::size_t> order(ids.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return ids[a] < ids[b]; });
  std::vector<std::uint32_t> sorted;
  std::vector<float> factors;
  for (std::size_t i : order) {
    if (ids[i] == 0 || (!sorted.empty() && sorted.back() == ids[i])) continue;
    sorted.push_back(ids[i]);
    factors.push_back(std::isfinite(blend[i]) ? std::clamp(blend[i], 0.0f, 1.0f) : 0.0f);
  }
  ensure_table(sorted.size());
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  count_ = static_cast<int>(sorted.size());
  glBindTexture(GL_TEXTURE_2D, table_ids_);
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, count_, 1, GL_RED_INTEGER, GL_UNSIGNED_INT, sorted.data());
  glBindTexture(GL_TEXTURE_2D, table_blend_);
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, count_, 1, GL_RED, GL_FLOAT, factors.data());
}

void GlUlodBlend::run_fragment(const Image& drawn, const Image& next) {
  const auto w = static_cast<GLsizei>(drawn.width), h = static_cast<GLsizei>(drawn.height);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, result_, 0);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  glViewport(0, 0, w, h);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_BLEND);
  glDisable(GL_SCISSOR_TEST);
  glUseProgram(program_);
  glBindVertexArray(vao_);
  gl::bind_sampler(0, drawn.color, program_, "u_drawn");
  gl::bind_sampler(1, next.color, program_, "u_next");
  gl::bind_sampler(2, drawn.object_id, program_, "u_drawn_ids");
  gl::bind_sampler(3, next.object_id, program_, "u_next_ids");
  gl::bind_sampler(4, table_ids_, program_, "u_ids");
  gl::bind_sampler(5, table_blend_, program_, "u_factors");
  glUniform1i(glGetUniformLocation(program_, "u_count"), count_);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  // The result replaces the drawn colour (a pass cannot read and write one texture).
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, drawn.color);
  glCopyTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, 0, 0, w, h);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glBindVertexArray(0);
  glUseProgram(0);
  gl::check_error("GlUlodBlend", "run (fragment)");
}

void GlUlodBlend::run_compute(const Image& drawn, const Image& next) {
  glUseProgram(compute_program_);
  glBindImageTexture(0, drawn.color, 0, GL_FALSE, 0, GL_READ_WRITE, GL_RGBA32F);
  gl::bind_sampler(1, next.color, compute_program_, "u_next");
  gl::bind_sampler(2, drawn.object_id, compute_program_, "u_drawn_ids");
  gl::bind_sampler(3, next.object_id, compute_program_, "u_next_ids");
  gl::bind_sampler(4, table_ids_, compute_program_, "u_ids");
  gl::bind_sampler(5, table_blend_, compute_program_, "u_factors");
  glUniform1i(glGetUniformLocation(compute_program_, "u_count"), count_);
  glUniform2i(glGetUniformLocation(compute_program_, "u_size"), static_cast<GLint>(drawn.width),
              static_cast<GLint>(drawn.height));
  glDispatchCompute((drawn.width + 7) / 8, (drawn.height + 7) / 8, 1);
  // Every later pass samples, attaches, reads back or copies the blended colour.
  glMemoryBarrier(gl::kComputeWrittenBarrier);
  glBindImageTexture(0, 0, 0, GL_FALSE, 0, GL_READ_WRITE, GL_RGBA32F);
  glUseProgram(0);
  gl::check_error("GlUlodBlend", "run (compute)");
}

}  // namespace fovea::render
