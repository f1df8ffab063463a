#pragma once
// Small helpers for GLSL programs: compile, link, and turn a failure into an exception carrying
// the driver's info log. Header-only; needs a current context.
#include <epoxy/gl.h>

#include <stdexcept>
#include <string>

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

}  // namespace fovea::render::gl
