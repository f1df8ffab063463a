// SPDX-License-Identifier: Apache-2.0
#include "backend/gl/gl_visibility.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <cstring>
#include <glm/gtc/type_ptr.hpp>
#include <stdexcept>

#include "backend/gl/gl_program.h"
#include "backend/gl/shaders.h"

namespace fovea::render {

namespace {

// kVisibilityResolve's struct Draw in std430.
struct DrawStd430 {
  float model[16], model_prev[16], normal_matrix[16];
  float kd_emissive[4], ks_shininess[4], emission_moved[4];
  std::uint32_t mesh[4];
};
static_assert(sizeof(DrawStd430) == 256);

void copy(const glm::mat4& m, float* out) { std::memcpy(out, glm::value_ptr(m), 16 * sizeof(float)); }

DrawStd430 pack(const GlVisibilityPass::Draw& d, std::uint32_t first_index, std::uint32_t first_vertex) {
  DrawStd430 out{};
  copy(d.model, out.model);
  copy(d.model_prev, out.model_prev);
  copy(glm::mat4(glm::transpose(glm::inverse(glm::mat3(d.model)))), out.normal_matrix);
  const Material& m = *d.material;
  const float emissive = m.type == MaterialType::Emissive ? 1.0f : 0.0f;
  const float kd[4] = {m.kd.x, m.kd.y, m.kd.z, emissive};
  const float ks[4] = {m.ks.x, m.ks.y, m.ks.z, m.shininess};
  const float em[4] = {m.emission.x, m.emission.y, m.emission.z, d.moved ? 1.0f : 0.0f};
  std::memcpy(out.kd_emissive, kd, sizeof kd);
  std::memcpy(out.ks_shininess, ks, sizeof ks);
  std::memcpy(out.emission_moved, em, sizeof em);
  out.mesh[0] = first_index;
  out.mesh[1] = first_vertex;
  out.mesh[2] = d.object_id;
  return out;
}

void check(const char* where) {
  const GLenum e = glGetError();
  if (e == GL_NO_ERROR) return;
  while (glGetError() != GL_NO_ERROR) {
  }
  throw std::runtime_error(std::string("GlVisibilityPass: OpenGL error ") + std::to_string(e) + " in " + where);
}

}  // namespace

std::string GlVisibilityPass::unavailable_reason(const GlFeatures& f) {
  if (!f.at_least(4, 3)) {  // the resolve pass is GLSL 4.30: compute shaders and storage buffers
    return "no compute shaders (OpenGL " + std::to_string(f.major) + "." + std::to_string(f.minor) + ", 4.3 needed)";
  }
  return "";
}

GlVisibilityPass::GlVisibilityPass(unsigned light_ubo) : light_ubo_(light_ubo) {
  raster_program_ = gl::link_program(gl::kDepthVertex, gl::kVisibilityFragment, "GlVisibilityPass raster program");
  loc_model_ = glGetUniformLocation(raster_program_, "u_model");
  loc_view_ = glGetUniformLocation(raster_program_, "u_view");
  loc_proj_ = glGetUniformLocation(raster_program_, "u_proj");
  loc_draw_ = glGetUniformLocation(raster_program_, "u_draw");
  const std::string resolve = std::string("#version 430 core\n") + gl::kShadingGlsl + gl::kVisibilityResolve;
  try {
    resolve_program_ = gl::link_compute_program(resolve.c_str(), "GlVisibilityPass resolve program");
    const std::string peel = std::string("#version 330 core\n") + gl::kPeelTest + gl::kPeelVisibilityFragment;
    peel_program_ = gl::link_program(gl::kPeelVisibilityVertex, peel.c_str(), "GlVisibilityPass peel program");
  } catch (...) {
    glDeleteProgram(raster_program_);
    glDeleteProgram(resolve_program_);
    throw;
  }
  const auto peel_loc = [this](const char* name) { return glGetUniformLocation(peel_program_, name); };
  peel_loc_ = {peel_loc("u_model"),     peel_loc("u_view"), peel_loc("u_proj"), peel_loc("u_draw"),
               peel_loc("u_object_id"), peel_loc("u_eye"),  peel_loc("u_peel")};
  glUseProgram(peel_program_);
  glUniform1i(peel_loc("u_peel_depth"), 0);
  glUniform1i(peel_loc("u_peel_state"), 1);
  glUseProgram(0);
  const auto loc = [this](const char* name) { return glGetUniformLocation(resolve_program_, name); };
  loc_ = {loc("u_planes"), loc("u_view"), loc("u_view_prev"), loc("u_proj"), loc("u_inv_proj"), loc("u_inv_view"),
          loc("u_eye"), loc("u_size"), loc("u_background"), loc("u_far"), loc("u_ambient"), loc("u_light_count"),
          loc("u_visibility")};
  const GLuint block = glGetUniformBlockIndex(resolve_program_, "LightSamples");
  if (block != GL_INVALID_INDEX) glUniformBlockBinding(resolve_program_, block, 0);
  glGenBuffers(1, &vertices_);
  glGenBuffers(1, &indices_);
  glGenBuffers(1, &draws_);
  check("GlVisibilityPass()");
}

GlVisibilityPass::~GlVisibilityPass() {
  glDeleteProgram(raster_program_);
  glDeleteProgram(resolve_program_);
  glDeleteProgram(peel_program_);
  glDeleteBuffers(1, &vertices_);
  glDeleteBuffers(1, &indices_);
  glDeleteBuffers(1, &draws_);
  if (fbo_ != 0) glDeleteFramebuffers(1, &fbo_);
  if (ids_ != 0) glDeleteTextures(1, &ids_);
}

void GlVisibilityPass::set_meshes(const std::vector<const Mesh*>& meshes) {
  std::vector<float> vertices;
  std::vector<std::uint32_t> indices;
  first_index_.clear();
  first_vertex_.clear();
  for (const Mesh* m : meshes) {
    first_index_.push_back(static_cast<std::uint32_t>(indices.size()));
    first_vertex_.push_back(static_cast<std::uint32_t>(vertices.size() / 6));
    for (std::size_t i = 0; i < m->positions.size(); ++i) {
      const glm::vec3 &p = m->positions[i], &n = m->normals[i];
      vertices.insert(vertices.end(), {p.x, p.y, p.z, n.x, n.y, n.z});
    }
    indices.insert(indices.end(), m->indices.begin(), m->indices.end());
  }
  GLint64 max_block = 0;
  glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &max_block);
  const auto bytes = static_cast<GLint64>(std::max(vertices.size(), indices.size()) * sizeof(float));
  if (bytes > max_block || vertices.size() / 6 > 0xFFFFFFFFu || indices.size() > 0xFFFFFFFFu) {
    throw std::runtime_error("the scene's meshes need a " + std::to_string(bytes) +
                             "-byte storage buffer; the device allows " + std::to_string(max_block));
  }
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, vertices_);
  glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(std::max<std::size_t>(1, vertices.size()) * sizeof(float)),
               vertices.empty() ? nullptr : vertices.data(), GL_STATIC_DRAW);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, indices_);
  glBufferData(GL_SHADER_STORAGE_BUFFER,
               static_cast<GLsizeiptr>(std::max<std::size_t>(1, indices.size()) * sizeof(std::uint32_t)),
               indices.empty() ? nullptr : indices.data(), GL_STATIC_DRAW);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
  check("GlVisibilityPass::set_meshes");
}

// The id target (RG32UI: 1 + draw, primitive) sharing the G-buffer's z-buffer.
// The id target grows to the largest framebuffer seen and keeps its size: the frame's targets and
// render_aside's alternate every frame (ULOD), and only the z-buffer is attached anew for each.
void GlVisibilityPass::ensure_target(unsigned z_buffer, std::uint32_t width, std::uint32_t height) {
  if (fbo_ != 0 && fbo_z_ == z_buffer && fb_width_ >= width && fb_height_ >= height) return;
  if (fbo_ == 0) glGenFramebuffers(1, &fbo_);
  if (fbo_ != 0 && ids_ != 0 && fb_width_ >= width && fb_height_ >= height) {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, z_buffer);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("GlVisibilityPass: id framebuffer incomplete");
    fbo_z_ = z_buffer;
    return;
  }
  width = std::max(width, fb_width_);
  height = std::max(height, fb_height_);
  if (ids_ != 0) glDeleteTextures(1, &ids_);
  glGenTextures(1, &ids_);
  glBindTexture(GL_TEXTURE_2D, ids_);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RG32UI, static_cast<GLsizei>(width), static_cast<GLsizei>(height), 0,
               GL_RG_INTEGER, GL_UNSIGNED_INT, nullptr);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glBindTexture(GL_TEXTURE_2D, 0);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, ids_, 0);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, z_buffer);
  const GLenum draw_buffer = GL_COLOR_ATTACHMENT0;
  glDrawBuffers(1, &draw_buffer);
  if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("GlVisibilityPass: id framebuffer incomplete");
  fbo_z_ = z_buffer;
  fb_width_ = width;
  fb_height_ = height;
}

void GlVisibilityPass::render(const View& view, const std::vector<Draw>& draws, unsigned z_buffer,
                              std::uint32_t fb_width, std::uint32_t fb_height, const unsigned targets[5],
                              const GBufferPlanes& planes) {
  ensure_target(z_buffer, fb_width, fb_height);
  raster_ids(view, draws);
  shade(view, draws, ids_, targets, planes);
  check("GlVisibilityPass::render");
}

void GlVisibilityPass::raster_peel(const View& view, const std::vector<Draw>& draws, unsigned fbo,
                                   unsigned against_depth, unsigned against_state) {
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glViewport(0, 0, static_cast<GLsizei>(view.width), static_cast<GLsizei>(view.height));
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glUseProgram(peel_program_);
  glUniformMatrix4fv(peel_loc_.view, 1, GL_FALSE, glm::value_ptr(view.view));
  glUniformMatrix4fv(peel_loc_.proj, 1, GL_FALSE, glm::value_ptr(view.proj));
  glUniform3fv(peel_loc_.eye, 1, glm::value_ptr(view.eye));
  glUniform1i(peel_loc_.peel, against_depth != 0 ? 1 : 0);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, against_depth);
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_2D, against_state);
  for (std::size_t k = 0; k < draws.size(); ++k) {
    glUniformMatrix4fv(peel_loc_.model, 1, GL_FALSE, glm::value_ptr(draws[k].model));
    glUniform1ui(peel_loc_.draw, static_cast<GLuint>(k + 1));
    glUniform1ui(peel_loc_.object_id, draws[k].object_id);
    glBindVertexArray(draws[k].vao);
    glDrawElements(GL_TRIANGLES, draws[k].index_count, GL_UNSIGNED_INT, nullptr);
  }
  glBindVertexArray(0);
  glBindTexture(GL_TEXTURE_2D, 0);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, 0);
  glUseProgram(0);
  check("GlVisibilityPass::raster_peel");
}

void GlVisibilityPass::raster_ids(const View& view, const std::vector<Draw>& draws) {
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glViewport(0, 0, static_cast<GLsizei>(view.width), static_cast<GLsizei>(view.height));
  glEnable(GL_SCISSOR_TEST);
  glScissor(0, 0, static_cast<GLsizei>(view.width), static_cast<GLsizei>(view.height));
  const GLuint background[4] = {0, 0, 0, 0};
  const GLfloat far_z = 1.0f;
  glClearBufferuiv(GL_COLOR, 0, background);
  glClearBufferfv(GL_DEPTH, 0, &far_z);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glUseProgram(raster_program_);
  glUniformMatrix4fv(loc_view_, 1, GL_FALSE, glm::value_ptr(view.view));
  glUniformMatrix4fv(loc_proj_, 1, GL_FALSE, glm::value_ptr(view.proj));
  for (std::size_t k = 0; k < draws.size(); ++k) {
    glUniformMatrix4fv(loc_model_, 1, GL_FALSE, glm::value_ptr(draws[k].model));
    glUniform1ui(loc_draw_, static_cast<GLuint>(k + 1));
    glBindVertexArray(draws[k].vao);
    glDrawElements(GL_TRIANGLES, draws[k].index_count, GL_UNSIGNED_INT, nullptr);
  }
  glBindVertexArray(0);
  glDisable(GL_SCISSOR_TEST);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

void GlVisibilityPass::shade(const View& view, const std::vector<Draw>& draws, unsigned visibility,
                             const unsigned targets[5], const GBufferPlanes& planes) {
  std::vector<DrawStd430> packed;
  packed.reserve(draws.size());
  for (const Draw& d : draws) packed.push_back(pack(d, first_index_.at(d.mesh), first_vertex_.at(d.mesh)));
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, draws_);
  glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(std::max<std::size_t>(1, packed.size()) * sizeof(DrawStd430)),
               packed.empty() ? nullptr : packed.data(), GL_STREAM_DRAW);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, draws_);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, vertices_);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, indices_);
  glBindBufferBase(GL_UNIFORM_BUFFER, 0, light_ubo_);

  glUseProgram(resolve_program_);
  const bool written[5] = {planes.color, planes.depth, planes.object_id, planes.normal, planes.motion};
  const GLenum formats[5] = {GL_RGBA32F, GL_R32F, GL_R32UI, GL_RGBA32F, GL_RG32F};
  int mask = 0;
  for (GLuint k = 0; k < 5; ++k) {
    if (written[k]) mask |= 1 << k;
    glBindImageTexture(k, targets[k], 0, GL_FALSE, 0, GL_WRITE_ONLY, formats[k]);
  }
  glUniform1i(loc_.planes, mask);
  glUniformMatrix4fv(loc_.view, 1, GL_FALSE, glm::value_ptr(view.view));
  glUniformMatrix4fv(loc_.view_prev, 1, GL_FALSE, glm::value_ptr(view.view_prev));
  glUniformMatrix4fv(loc_.proj, 1, GL_FALSE, glm::value_ptr(view.proj));
  glUniformMatrix4fv(loc_.inv_proj, 1, GL_FALSE, glm::value_ptr(glm::inverse(view.proj)));
  glUniformMatrix4fv(loc_.inv_view, 1, GL_FALSE, glm::value_ptr(glm::inverse(view.view)));
  glUniform3fv(loc_.eye, 1, glm::value_ptr(view.eye));
  glUniform2i(loc_.size, static_cast<GLint>(view.width), static_cast<GLint>(view.height));
  glUniform3fv(loc_.background, 1, glm::value_ptr(view.background));
  glUniform1f(loc_.far_m, view.far_m);
  glUniform3fv(loc_.ambient, 1, glm::value_ptr(view.ambient));
  glUniform1i(loc_.light_count, view.light_count);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, visibility);
  glUniform1i(loc_.visibility, 0);
  glDispatchCompute((view.width + 7) / 8, (view.height + 7) / 8, 1);
  // The planes are read next by texture fetches (the GPU passes), glReadPixels (the readback) or a
  // framebuffer (ULOD's second pass): every kind of access must see the image stores.
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  glBindTexture(GL_TEXTURE_2D, 0);
  for (GLuint k = 0; k < 5; ++k) glBindImageTexture(k, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, formats[k]);
  glUseProgram(0);
}

}  // namespace fovea::render
