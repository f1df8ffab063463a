#include "backend/gl/gl_context.h"

#include <epoxy/gl.h>
// GLFW after epoxy: epoxy provides the GL declarations, GLFW must not include the system GL header.
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <dlfcn.h>
#include <link.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "backend/gl/gl_program.h"

namespace fovea::render {

namespace {

std::mutex g_glfw_mutex;
int g_glfw_users = 0;

std::string glfw_error_text() {
  const char* description = nullptr;
  const int code = glfwGetError(&description);
  if (code == GLFW_NO_ERROR) return "no error reported by GLFW";
  char hex[16];
  std::snprintf(hex, sizeof hex, "0x%X", static_cast<unsigned>(code));
  return std::string(description != nullptr ? description : "unknown GLFW error") + " (GLFW error " + hex + ")";
}

// Reference-counted glfwInit/glfwTerminate: several contexts and backends can live in one process.
void acquire_glfw() {
  const std::lock_guard lock(g_glfw_mutex);
  if (g_glfw_users == 0) {
    const char* display = std::getenv("DISPLAY");
    if (display == nullptr || *display == '\0') {
      throw std::runtime_error("no X display: run under xvfb-run or set DISPLAY (DISPLAY is not set)");
    }
    // An X server resets when its last client disconnects (Xvfb without -noreset, e.g. under
    // xvfb-run after the previous context's glfwTerminate); a connection attempted during the
    // reset is refused. Retry briefly before calling the display missing.
    bool ok = glfwInit() == GLFW_TRUE;
    for (int attempt = 0; !ok && attempt < 5; ++attempt) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50 << attempt));
      ok = glfwInit() == GLFW_TRUE;
    }
    if (!ok) {
      throw std::runtime_error("no X display: run under xvfb-run or set DISPLAY (glfw: " + glfw_error_text() +
                               ", DISPLAY=" + display + ")");
    }
  }
  ++g_glfw_users;
}

void release_glfw() {
  const std::lock_guard lock(g_glfw_mutex);
  if (--g_glfw_users == 0) glfwTerminate();
}

constexpr const char* kPresentVertex = R"(#version 330 core
out vec2 v_uv;
void main() {
  // One triangle covering the viewport; uv.y flipped because the image's row 0 is its top.
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  v_uv = vec2(p.x, 1.0 - p.y);
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
)";

constexpr const char* kPresentFragment = R"(#version 330 core
in vec2 v_uv;
uniform sampler2D u_image;
out vec4 o_color;
void main() { o_color = vec4(texture(u_image, v_uv).rgb, 1.0); }
)";

// Keeps the GL driver libraries (libglvnd's vendor library, Mesa's DRI driver and what they
// loaded, e.g. LLVM) mapped after glfwTerminate. Without this, the last context's glfwTerminate
// closes the X display, libglvnd dlcloses libGLX_mesa and with it swrast_dri.so, and:
//  - the next context pays for loading and initialising the driver (and LLVM) again;
//  - the driver's own small process-lifetime allocations (~1 KB) lose their only references and
//    LeakSanitizer reports them as leaks from "<unknown module>" that no suppression can match.
// Pinned, those allocations stay reachable from the driver's globals. Called once, with a context
// current (so the driver is loaded).
void pin_gl_driver_libraries() {
  static bool pinned = false;
  if (pinned) return;
  pinned = true;
  std::vector<std::string> names;
  dl_iterate_phdr(
      [](dl_phdr_info* info, std::size_t, void* data) {
        const std::string name = info->dlpi_name != nullptr ? info->dlpi_name : "";
        if (name.find("_dri.so") != std::string::npos || name.find("libGLX_mesa") != std::string::npos ||
            name.find("libgallium") != std::string::npos || name.find("libLLVM") != std::string::npos) {
          static_cast<std::vector<std::string>*>(data)->push_back(name);
        }
        return 0;
      },
      &names);
  for (const std::string& name : names) {
    // RTLD_NOLOAD: only take a reference to what is already loaded; never load anything new.
    static_cast<void>(dlopen(name.c_str(), RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE));
  }
}

std::uint8_t encode_srgb8(float linear) {
  if (!(linear > 0.0f)) return 0;  // also NaN
  if (linear >= 1.0f) return 255;
  const float s = linear <= 0.0031308f ? 12.92f * linear : 1.055f * std::pow(linear, 1.0f / 2.4f) - 0.055f;
  return static_cast<std::uint8_t>(std::lround(s * 255.0f));
}

}  // namespace

GlContext::GlContext(const GlContextOptions& options) {
  if (options.width <= 0 || options.height <= 0) {
    throw std::invalid_argument("GlContext: window size " + std::to_string(options.width) + "x" +
                                std::to_string(options.height) + " must be positive");
  }
  acquire_glfw();
  glfwDefaultWindowHints();
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_VISIBLE, options.visible ? GLFW_TRUE : GLFW_FALSE);
  glfwWindowHint(GLFW_RESIZABLE, options.visible ? GLFW_TRUE : GLFW_FALSE);
  window_ = glfwCreateWindow(options.width, options.height, options.title.c_str(), nullptr, nullptr);
  if (window_ == nullptr) {
    const std::string error = glfw_error_text();
    release_glfw();
    throw std::runtime_error("cannot create an OpenGL 3.3 core context: " + error);
  }
  glfwMakeContextCurrent(window_);
  glfwSwapInterval(options.visible && options.vsync ? 1 : 0);
  const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  renderer_ = renderer != nullptr ? renderer : "unknown";
  {
    const std::lock_guard lock(g_glfw_mutex);
    pin_gl_driver_libraries();
  }
}

GlContext::~GlContext() {
  make_current();
  if (present_program_ != 0) glDeleteProgram(present_program_);
  if (present_vao_ != 0) glDeleteVertexArrays(1, &present_vao_);
  if (present_texture_ != 0) glDeleteTextures(1, &present_texture_);
  glfwMakeContextCurrent(nullptr);
  glfwDestroyWindow(window_);
  release_glfw();
}

void GlContext::make_current() {
  if (glfwGetCurrentContext() != window_) glfwMakeContextCurrent(window_);
}

void GlContext::swap_buffers() { glfwSwapBuffers(window_); }

bool GlContext::should_close() const { return glfwWindowShouldClose(window_) == GLFW_TRUE; }

void GlContext::poll_events() { glfwPollEvents(); }

glm::ivec2 GlContext::framebuffer_size() const {
  int w = 0, h = 0;
  glfwGetFramebufferSize(window_, &w, &h);
  return {w, h};
}

void GlContext::create_present_resources() {
  present_program_ = gl::link_program(kPresentVertex, kPresentFragment, "GlContext::present");
  glGenVertexArrays(1, &present_vao_);
  glGenTextures(1, &present_texture_);
  glBindTexture(GL_TEXTURE_2D, present_texture_);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
}

void GlContext::present(std::span<const std::uint8_t> rgba, std::uint32_t width, std::uint32_t height) {
  if (width == 0 || height == 0 || rgba.size() != std::size_t{width} * height * 4) {
    throw std::invalid_argument("GlContext::present: " + std::to_string(rgba.size()) + " bytes for a " +
                                std::to_string(width) + "x" + std::to_string(height) +
                                " RGBA image (expected width*height*4, both positive)");
  }
  make_current();
  if (present_program_ == 0) create_present_resources();
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  const glm::ivec2 fb = framebuffer_size();
  glDisable(GL_DEPTH_TEST);
  glViewport(0, 0, fb.x, fb.y);
  glClearColor(0, 0, 0, 1);
  glClear(GL_COLOR_BUFFER_BIT);
  // Letterbox: the largest viewport of the image's aspect ratio that fits, centred.
  const double scale = std::min(static_cast<double>(fb.x) / width, static_cast<double>(fb.y) / height);
  const int vw = std::max(1, static_cast<int>(std::lround(width * scale)));
  const int vh = std::max(1, static_cast<int>(std::lround(height * scale)));
  glViewport((fb.x - vw) / 2, (fb.y - vh) / 2, vw, vh);

  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, present_texture_);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, static_cast<GLsizei>(width), static_cast<GLsizei>(height), 0, GL_RGBA,
               GL_UNSIGNED_BYTE, rgba.data());
  glUseProgram(present_program_);
  glUniform1i(glGetUniformLocation(present_program_, "u_image"), 0);
  glBindVertexArray(present_vao_);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);
  glUseProgram(0);
}

void GlContext::present(const std::vector<glm::vec3>& linear_rgb, std::uint32_t width, std::uint32_t height) {
  if (linear_rgb.size() != std::size_t{width} * height) {
    throw std::invalid_argument("GlContext::present: " + std::to_string(linear_rgb.size()) + " pixels for a " +
                                std::to_string(width) + "x" + std::to_string(height) + " image");
  }
  srgb_scratch_.resize(linear_rgb.size() * 4);
  for (std::size_t i = 0; i < linear_rgb.size(); ++i) {
    srgb_scratch_[4 * i + 0] = encode_srgb8(linear_rgb[i].r);
    srgb_scratch_[4 * i + 1] = encode_srgb8(linear_rgb[i].g);
    srgb_scratch_[4 * i + 2] = encode_srgb8(linear_rgb[i].b);
    srgb_scratch_[4 * i + 3] = 255;
  }
  present(srgb_scratch_, width, height);
}

}  // namespace fovea::render
