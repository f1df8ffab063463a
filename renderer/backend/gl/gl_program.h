// SPDX-License-Identifier: Apache-2.0
#pragma once
// Small helpers for GLSL programs and the GPU passes: compile, link, and turn a failure into an
// exception carrying the driver's info log; the full-screen triangle every image pass draws; GL
// errors as exceptions; images with row 0 at the top up to and back from textures. Header-only;
// needs a current context.
#include <epoxy/gl.h>

#include <cstring>
#include <initializer_list>
#include <stdexcept>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

namespace fovea::render::gl {

inline GLuint compile_shader(GLenum stage, const char* source, const char* what) {
  const GLuint shader = glCreateShader(stage);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE) {
    GLint length = 0;
    glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
    std::string log(static_cast<std::size_t>(length > 0 ? length : 1), '\0');
    glGetShaderInfoLog(shader, length, nullptr, log.data());
    glDeleteShader(shader);
    throw std::runtime_error(std::string(what) + ": shader compilation failed: " + log.c_str());
  }
  return shader;
}

// Returns `program` when it linked; else deletes it and throws with the driver's info log.
inline GLuint checked_link(GLuint program, const char* what) {
  GLint ok = GL_FALSE;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE) {
    GLint length = 0;
    glGetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
    std::string log(static_cast<std::size_t>(length > 0 ? length : 1), '\0');
    glGetProgramInfoLog(program, length, nullptr, log.data());
    glDeleteProgram(program);
    throw std::runtime_error(std::string(what) + ": program link failed: " + log.c_str());
  }
  return program;
}

// Compiles and links a vertex + fragment program; the shaders are deleted after linking.
inline GLuint link_program(const char* vertex_source, const char* fragment_source, const char* what) {
  const GLuint vs = compile_shader(GL_VERTEX_SHADER, vertex_source, what);
  GLuint fs = 0;
  try {
    fs = compile_shader(GL_FRAGMENT_SHADER, fragment_source, what);
  } catch (...) {
    glDeleteShader(vs);
    throw;
  }
  const GLuint program = glCreateProgram();
  glAttachShader(program, vs);
  glAttachShader(program, fs);
  glLinkProgram(program);
  glDetachShader(program, vs);
  glDetachShader(program, fs);
  glDeleteShader(vs);
  glDeleteShader(fs);
  return checked_link(program, what);
}

// Compiles and links a compute program (GL 4.3); the shader is deleted after linking.
inline GLuint link_compute_program(const char* source, const char* what) {
  const GLuint cs = compile_shader(GL_COMPUTE_SHADER, source, what);
  const GLuint program = glCreateProgram();
  glAttachShader(program, cs);
  glLinkProgram(program);
  glDetachShader(program, cs);
  glDeleteShader(cs);
  return checked_link(program, what);
}

// The effect passes with a fragment and a compute implementation (issue 42) share their GLSL after
// one of these version lines; the compute one declares 8x8 work groups.
inline constexpr const char* kFragmentVersion = "#version 330 core\n";
inline constexpr const char* kComputeVersion8x8 = "#version 430 core\nlayout(local_size_x = 8, local_size_y = 8) in;\n";

// After a compute pass: what it wrote is read next through a sampler, an image, a framebuffer, a
// copy or a readback.
inline constexpr GLbitfield kComputeWrittenBarrier = GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT |
                                                     GL_FRAMEBUFFER_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT |
                                                     GL_PIXEL_BUFFER_BARRIER_BIT;

// One triangle over the viewport (draw 3 vertices, no buffers); the fragment shaders address texels
// with gl_FragCoord.
inline constexpr const char* kFullscreenVertex = R"(#version 330 core
void main() {
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
)";

// Binds `fbo` with `textures` (at most 4, of texture target `target`) as its colour attachments
// 0, 1, ..., the other attachments of 0..3 detached, and draws into all of them.
inline void attach_targets(unsigned fbo, std::span<const unsigned> textures, GLenum target = GL_TEXTURE_2D) {
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  GLenum buffers[4] = {GL_NONE, GL_NONE, GL_NONE, GL_NONE};
  GLsizei n = 0;
  for (unsigned t : textures) {
    if (n == 4) throw std::logic_error("gl::attach_targets: more than 4 targets");
    buffers[n] = static_cast<GLenum>(GL_COLOR_ATTACHMENT0 + n);
    glFramebufferTexture2D(GL_FRAMEBUFFER, buffers[n], target, t, 0);
    ++n;
  }
  for (GLsizei k = n; k < 4; ++k)
    glFramebufferTexture2D(GL_FRAMEBUFFER, static_cast<GLenum>(GL_COLOR_ATTACHMENT0 + k), GL_TEXTURE_2D, 0, 0);
  glDrawBuffers(n, buffers);
}
inline void attach_targets(unsigned fbo, std::initializer_list<unsigned> textures, GLenum target = GL_TEXTURE_2D) {
  attach_targets(fbo, std::span<const unsigned>(textures.begin(), textures.size()), target);
}

// Throws std::runtime_error("<who>: OpenGL error N in <where>") when GL reports an error (and clears
// the rest of the queue).
inline void check_error(const char* who, const char* where) {
  const GLenum e = glGetError();
  if (e == GL_NO_ERROR) return;
  while (glGetError() != GL_NO_ERROR) {
  }
  throw std::runtime_error(std::string(who) + ": OpenGL error " + std::to_string(e) + " in " + where);
}

// A 2D texture on texture unit `unit`, as `program`'s sampler `name` (the program in use).
inline void bind_sampler(int unit, unsigned texture, unsigned program, const char* name, GLenum target = GL_TEXTURE_2D) {
  glActiveTexture(static_cast<GLenum>(GL_TEXTURE0 + unit));
  glBindTexture(target, texture);
  glUniform1i(glGetUniformLocation(program, name), unit);
}

// A w x h 2D texture of `internal` format (its data `format` and `type`: what an upload would pass),
// uninitialised, nearest filtering, clamped at the edges.
inline unsigned make_texture(GLenum internal, GLenum format, GLenum type, std::uint32_t w, std::uint32_t h) {
  unsigned t = 0;
  glGenTextures(1, &t);
  glBindTexture(GL_TEXTURE_2D, t);
  glTexImage2D(GL_TEXTURE_2D, 0, static_cast<GLint>(internal), static_cast<GLsizei>(w), static_cast<GLsizei>(h), 0, format,
               type, nullptr);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  return t;
}

// Deletes `texture` (if any) and zeroes the name.
inline void delete_texture(unsigned& texture) {
  if (texture != 0) glDeleteTextures(1, &texture);
  texture = 0;
}

// `data` (w x h pixels of `per_pixel` floats, row 0 at the top; null: nothing) into `texture` (made
// on first use, nearest filtering), rows flipped to OpenGL's bottom-up order. Returns the texture, 0
// for no data.
inline unsigned upload_top_first(unsigned& texture, GLenum format, GLenum channels, const float* data, std::uint32_t w,
                                 std::uint32_t h, std::size_t per_pixel, std::vector<float>& staging) {
  if (data == nullptr) return 0u;
  if (texture == 0) glGenTextures(1, &texture);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, texture);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  const std::size_t row = std::size_t{w} * per_pixel;
  staging.resize(row * h);
  for (std::uint32_t y = 0; y < h; ++y) std::memcpy(&staging[std::size_t{h - 1 - y} * row], data + y * row, row * sizeof(float));
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glTexImage2D(GL_TEXTURE_2D, 0, static_cast<GLint>(format), static_cast<GLsizei>(w), static_cast<GLsizei>(h), 0,
               channels, GL_FLOAT, staging.data());
  return texture;
}

// The lower-left w x h of an RGBA float texture, through `fbo`, as RGB with row 0 at the top.
inline void read_rgb_top_first(unsigned fbo, unsigned texture, std::uint32_t w, std::uint32_t h,
                               std::vector<glm::vec3>& out, std::vector<float>& staging) {
  staging.resize(std::size_t{w} * h * 4);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, texture, 0);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadPixels(0, 0, static_cast<GLsizei>(w), static_cast<GLsizei>(h), GL_RGBA, GL_FLOAT, staging.data());
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  out.resize(std::size_t{w} * h);
  for (std::uint32_t y = 0; y < h; ++y)
    for (std::uint32_t x = 0; x < w; ++x) {
      const float* src = &staging[(std::size_t{h - 1 - y} * w + x) * 4];
      out[std::size_t{y} * w + x] = {src[0], src[1], src[2]};
    }
}

// Milliseconds between two GL_TIMESTAMP queries (waits for their results).
inline double elapsed_ms(const unsigned (&queries)[2]) {
  GLuint64 t0 = 0, t1 = 0;
  glGetQueryObjectui64v(queries[0], GL_QUERY_RESULT, &t0);
  glGetQueryObjectui64v(queries[1], GL_QUERY_RESULT, &t1);
  return t1 >= t0 ? static_cast<double>(t1 - t0) * 1e-6 : 0.0;
}

}  // namespace fovea::render::gl
