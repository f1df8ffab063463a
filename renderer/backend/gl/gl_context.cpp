// SPDX-License-Identifier: Apache-2.0
#include "backend/gl/gl_context.h"

#include <epoxy/egl.h>
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
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
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
uniform vec2 u_extent;     // the image's part of the texture (1, 1: all of it)
uniform bool u_top_first;  // the texture's row 0 is the image's top (uploaded images): flip
out vec2 v_uv;
void main() {
  // One triangle covering the viewport.
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  v_uv = vec2(p.x, u_top_first ? 1.0 - p.y : p.y) * u_extent;
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
)";

// Context versions asked for, newest first: the GPU passes want 4.3 (compute), the G-buffer 3.3.
constexpr int kVersions[][2] = {{4, 6}, {4, 5}, {4, 3}, {3, 3}};

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
            name.find("libEGL_mesa") != std::string::npos ||
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

// The context current on this thread, as far as GlContext knows: GLFW's own bookkeeping does not
// see EGL switches (nor EGL GLFW's), so make_current compares against this.
thread_local const void* t_current_context = nullptr;

bool has_token(const char* list, std::string_view token) {
  if (list == nullptr) return false;
  std::string_view rest(list);
  while (!rest.empty()) {
    const std::size_t end = rest.find(' ');
    if (rest.substr(0, end) == token) return true;
    if (end == std::string_view::npos) break;
    rest.remove_prefix(end + 1);
  }
  return false;
}

std::string egl_error_text() {
  char hex[16];
  std::snprintf(hex, sizeof hex, "0x%04X", static_cast<unsigned>(eglGetError()));
  return std::string("EGL error ") + hex;
}

// One EGL display per process, opened on first use and never terminated: eglTerminate would end
// every context on it (several backends share it), and re-initialising the driver costs seconds.
struct EglDisplay {
  EGLDisplay display = EGL_NO_DISPLAY;
  std::string description;  // "EGL 1.5, surfaceless platform"
  bool surfaceless = false;  // EGL_KHR_surfaceless_context: contexts need no surface
};

std::optional<EglDisplay> try_initialise(EGLDisplay d, const std::string& platform, std::ostringstream& why) {
  EGLint major = 0, minor = 0;
  if (d == EGL_NO_DISPLAY) {
    why << platform << ": no display (" << egl_error_text() << "); ";
    return std::nullopt;
  }
  if (eglInitialize(d, &major, &minor) != EGL_TRUE) {
    why << platform << ": eglInitialize failed (" << egl_error_text() << "); ";
    return std::nullopt;
  }
  const char* extensions = eglQueryString(d, EGL_EXTENSIONS);
  if (!has_token(eglQueryString(d, EGL_CLIENT_APIS), "OpenGL") || !has_token(extensions, "EGL_KHR_create_context")) {
    const char* apis = eglQueryString(d, EGL_CLIENT_APIS);
    why << platform << ": no desktop OpenGL (client APIs: " << (apis != nullptr ? apis : "none") << "); ";
    eglTerminate(d);
    return std::nullopt;
  }
  EglDisplay out;
  out.display = d;
  out.description = "EGL " + std::to_string(major) + "." + std::to_string(minor) + ", " + platform;
  out.surfaceless = has_token(extensions, "EGL_KHR_surfaceless_context");
  return out;
}

// The devices EGL_EXT_platform_device lists; `software` picks Mesa's software device (llvmpipe)
// instead of the GPUs.
std::optional<EglDisplay> try_devices(bool software, std::ostringstream& why) {
  EGLint count = 0;
  if (eglQueryDevicesEXT(0, nullptr, &count) != EGL_TRUE || count <= 0) {
    if (!software) why << "device platform: no devices (" << egl_error_text() << "); ";
    return std::nullopt;
  }
  std::vector<EGLDeviceEXT> devices(static_cast<std::size_t>(count));
  if (eglQueryDevicesEXT(count, devices.data(), &count) != EGL_TRUE) return std::nullopt;
  for (EGLint i = 0; i < count; ++i) {
    const auto device = devices[static_cast<std::size_t>(i)];
    const bool is_software = has_token(eglQueryDeviceStringEXT(device, EGL_EXTENSIONS), "EGL_MESA_device_software");
    if (is_software != software) continue;
    const std::string name = software ? "software device" : "device " + std::to_string(i);
    if (auto d = try_initialise(eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, device, nullptr), name, why)) return d;
  }
  return std::nullopt;
}

EglDisplay open_egl_display() {
  std::ostringstream why;
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  const bool devices = has_token(client, "EGL_EXT_platform_device") && has_token(client, "EGL_EXT_device_enumeration");
  const bool surfaceless = has_token(client, "EGL_MESA_platform_surfaceless");
  if (devices) {
    if (auto d = try_devices(false, why)) return *d;
  } else {
    why << "device platform: not offered; ";
  }
  if (surfaceless) {
    if (auto d = try_initialise(eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr),
                                "surfaceless platform", why)) {
      return *d;
    }
  } else {
    why << "surfaceless platform: not offered; ";
  }
  if (devices) {
    if (auto d = try_devices(true, why)) return *d;
  }
  // The default display may be X11 or Wayland; it needs that server, but costs nothing to try last.
  if (auto d = try_initialise(eglGetDisplay(EGL_DEFAULT_DISPLAY), "default display", why)) return *d;
  std::string text = why.str();
  if (text.size() >= 2) text.resize(text.size() - 2);
  throw std::runtime_error("no EGL display for headless OpenGL (" + text +
                           "); install libegl1 and libegl-mesa0 (Mesa) or a GPU driver with EGL");
}

const EglDisplay& egl_display() {
  static std::mutex mutex;
  static std::optional<EglDisplay> display;
  const std::lock_guard lock(mutex);
  if (!display) display = open_egl_display();
  return *display;
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
  if (options.visible || options.platform == GlPlatform::Glfw) {
    create_glfw_window(options);
  } else {
    create_egl_context();
  }
  t_current_context = this;
  const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  renderer_ = renderer != nullptr ? renderer : "unknown";
  read_features();
  {
    const std::lock_guard lock(g_glfw_mutex);
    pin_gl_driver_libraries();
  }
}

void GlContext::create_glfw_window(const GlContextOptions& options) {
  acquire_glfw();
  GLFWwindow* share = options.share != nullptr ? options.share->window() : nullptr;
  if (options.share != nullptr && share == nullptr) {
    release_glfw();
    throw std::logic_error("GlContext: a GLFW context can share only with another GLFW context");
  }
  for (const auto& version : kVersions) {
    glfwDefaultWindowHints();
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, version[0]);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, version[1]);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_VISIBLE, options.visible ? GLFW_TRUE : GLFW_FALSE);
    glfwWindowHint(GLFW_RESIZABLE, options.visible ? GLFW_TRUE : GLFW_FALSE);
    window_ = glfwCreateWindow(options.width, options.height, options.title.c_str(), nullptr, share);
    if (window_ != nullptr) break;
  }
  if (window_ == nullptr) {
    const std::string error = glfw_error_text();
    release_glfw();
    throw std::runtime_error("cannot create an OpenGL 3.3 core context: " + error);
  }
  glfwMakeContextCurrent(window_);
  glfwSwapInterval(options.visible && options.vsync ? 1 : 0);
  const char* display = std::getenv("DISPLAY");
  platform_ = std::string("GLFW (X display ") + (display != nullptr ? display : "?") + ")";
}

void GlContext::create_egl_context() {
  const EglDisplay& d = egl_display();
  // Desktop OpenGL, not GLES; the API is per thread, so bind it before every create/make-current.
  if (eglBindAPI(EGL_OPENGL_API) != EGL_TRUE) {
    throw std::runtime_error("cannot create an OpenGL 3.3 core context through EGL: eglBindAPI(OpenGL) failed (" +
                             egl_error_text() + ", " + d.description + ")");
  }
  const EGLint config_attributes[] = {EGL_SURFACE_TYPE, d.surfaceless ? 0 : EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE,
                                      EGL_OPENGL_BIT, EGL_NONE};
  EGLConfig config = nullptr;
  EGLint configs = 0;
  if (eglChooseConfig(d.display, config_attributes, &config, 1, &configs) != EGL_TRUE || configs < 1) {
    throw std::runtime_error("cannot create an OpenGL 3.3 core context through EGL: no OpenGL config (" +
                             egl_error_text() + ", " + d.description + ")");
  }
  EGLContext context = EGL_NO_CONTEXT;
  for (const auto& version : kVersions) {
    const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION_KHR, version[0], EGL_CONTEXT_MINOR_VERSION_KHR,
                                         version[1], EGL_CONTEXT_OPENGL_PROFILE_MASK_KHR,
                                         EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT_KHR, EGL_CONTEXT_FLAGS_KHR,
                                         EGL_CONTEXT_OPENGL_FORWARD_COMPATIBLE_BIT_KHR, EGL_NONE};
    context = eglCreateContext(d.display, config, EGL_NO_CONTEXT, context_attributes);
    if (context != EGL_NO_CONTEXT) break;
  }
  if (context == EGL_NO_CONTEXT) {
    throw std::runtime_error("cannot create an OpenGL 3.3 core context through EGL (" + egl_error_text() + ", " +
                             d.description + ")");
  }
  EGLSurface surface = EGL_NO_SURFACE;
  if (!d.surfaceless) {  // a 1x1 pbuffer to be current on; rendering goes to framebuffer objects
    const EGLint pbuffer_attributes[] = {EGL_WIDTH, 1, EGL_HEIGHT, 1, EGL_NONE};
    surface = eglCreatePbufferSurface(d.display, config, pbuffer_attributes);
    if (surface == EGL_NO_SURFACE) {
      const std::string error = egl_error_text();
      eglDestroyContext(d.display, context);
      throw std::runtime_error("cannot create an EGL pbuffer for the OpenGL context (" + error + ", " +
                               d.description + ")");
    }
  }
  if (eglMakeCurrent(d.display, surface, surface, context) != EGL_TRUE) {
    const std::string error = egl_error_text();
    if (surface != EGL_NO_SURFACE) eglDestroySurface(d.display, surface);
    eglDestroyContext(d.display, context);
    throw std::runtime_error("cannot make the EGL OpenGL context current (" + error + ", " + d.description + ")");
  }
  egl_context_ = context;
  egl_surface_ = surface;
  platform_ = d.description;
}

GlContext::~GlContext() {
  make_current();
  if (present_program_ != 0) glDeleteProgram(present_program_);
  if (present_vao_ != 0) glDeleteVertexArrays(1, &present_vao_);
  if (present_texture_ != 0) glDeleteTextures(1, &present_texture_);
  t_current_context = nullptr;
  if (window_ != nullptr) {
    glfwMakeContextCurrent(nullptr);
    glfwDestroyWindow(window_);
    release_glfw();
    return;
  }
  const EglDisplay& d = egl_display();
  eglMakeCurrent(d.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (egl_surface_ != EGL_NO_SURFACE) eglDestroySurface(d.display, egl_surface_);
  eglDestroyContext(d.display, egl_context_);
}

void GlContext::make_current() {
  if (t_current_context == this) return;
  if (window_ != nullptr) {
    glfwMakeContextCurrent(window_);
  } else {
    const EglDisplay& d = egl_display();
    eglBindAPI(EGL_OPENGL_API);
    if (eglMakeCurrent(d.display, egl_surface_, egl_surface_, egl_context_) != EGL_TRUE) {
      throw std::runtime_error("cannot make the EGL OpenGL context current (" + egl_error_text() + ")");
    }
  }
  t_current_context = this;
}

void GlContext::swap_buffers() {
  if (window_ != nullptr) glfwSwapBuffers(window_);
}

bool GlContext::should_close() const { return window_ != nullptr && glfwWindowShouldClose(window_) == GLFW_TRUE; }

void GlContext::poll_events() {
  const std::lock_guard lock(g_glfw_mutex);
  if (g_glfw_users > 0) glfwPollEvents();
}

glm::ivec2 GlContext::framebuffer_size() const {
  int w = 0, h = 0;
  if (window_ != nullptr) glfwGetFramebufferSize(window_, &w, &h);
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

void GlContext::present(std::span<const std::uint8_t> rgba, std::uint32_t width, std::uint32_t height,
                        Region region) {
  if (width == 0 || height == 0 || rgba.size() != std::size_t{width} * height * 4) {
    throw std::invalid_argument("GlContext::present: " + std::to_string(rgba.size()) + " bytes for a " +
                                std::to_string(width) + "x" + std::to_string(height) +
                                " RGBA image (expected width*height*4, both positive)");
  }
  begin_present("GlContext::present");  // creates present_texture_ on first use
  glBindTexture(GL_TEXTURE_2D, present_texture_);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, static_cast<GLsizei>(width), static_cast<GLsizei>(height), 0, GL_RGBA,
               GL_UNSIGNED_BYTE, rgba.data());
  draw_present_quad(width, height, 1.0f, 1.0f, true, region);
}

void GlContext::present_texture(unsigned texture, std::uint32_t width, std::uint32_t height,
                                std::uint32_t texture_width, std::uint32_t texture_height, Region region) {
  if (width == 0 || height == 0 || width > texture_width || height > texture_height) {
    throw std::invalid_argument("GlContext::present_texture: a " + std::to_string(width) + "x" +
                                std::to_string(height) + " image in a " + std::to_string(texture_width) + "x" +
                                std::to_string(texture_height) + " texture");
  }
  begin_present("GlContext::present_texture");
  glBindTexture(GL_TEXTURE_2D, texture);
  draw_present_quad(width, height, static_cast<float>(width) / static_cast<float>(texture_width),
                    static_cast<float>(height) / static_cast<float>(texture_height), false, region);
}

// What both presents need first: a window, this context current, the present resources, unit 0.
void GlContext::begin_present(const char* who) {
  if (window_ == nullptr) {
    throw std::logic_error(std::string(who) + ": an EGL context has no window to present to (" + platform_ + ")");
  }
  make_current();
  if (present_program_ == 0) create_present_resources();
  glActiveTexture(GL_TEXTURE0);
}

// The bound texture to the default framebuffer's region, letterboxed (the largest viewport of the
// image's aspect ratio that fits, centred in the region).
void GlContext::draw_present_quad(std::uint32_t width, std::uint32_t height, float u_max, float v_max,
                                  bool top_row_first, Region region) {
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  const glm::ivec2 fb = framebuffer_size();
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_BLEND);
  if (region != Region::RightHalf) {
    glViewport(0, 0, fb.x, fb.y);
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT);
  }
  const int area_x = region == Region::RightHalf ? fb.x / 2 : 0;
  const int area_w = region == Region::Whole ? fb.x : fb.x / 2;
  const double scale = std::min(static_cast<double>(area_w) / width, static_cast<double>(fb.y) / height);
  const int vw = std::max(1, static_cast<int>(std::lround(width * scale)));
  const int vh = std::max(1, static_cast<int>(std::lround(height * scale)));
  glViewport(area_x + (area_w - vw) / 2, (fb.y - vh) / 2, vw, vh);
  glUseProgram(present_program_);
  glUniform1i(glGetUniformLocation(present_program_, "u_image"), 0);
  glUniform2f(glGetUniformLocation(present_program_, "u_extent"), u_max, v_max);
  glUniform1i(glGetUniformLocation(present_program_, "u_top_first"), top_row_first ? 1 : 0);
  glBindVertexArray(present_vao_);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);
  glUseProgram(0);
}

void GlContext::read_features() {
  glGetIntegerv(GL_MAJOR_VERSION, &features_.major);
  glGetIntegerv(GL_MINOR_VERSION, &features_.minor);
  features_.timer_query = features_.at_least(3, 3) || epoxy_has_gl_extension("GL_ARB_timer_query");
  features_.sync = features_.at_least(3, 2) || epoxy_has_gl_extension("GL_ARB_sync");
  features_.compute = features_.at_least(4, 3) || epoxy_has_gl_extension("GL_ARB_compute_shader");
  if (features_.at_least(4, 3)) {
    GLint64 max_block = 0;
    glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &max_block);
    features_.max_storage_block = max_block;
  }
  const auto* name = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const std::string renderer = name != nullptr ? name : "";
  for (const char* software : {"llvmpipe", "softpipe", "SwiftShader", "Software Rasterizer"})
    features_.software = features_.software || renderer.find(software) != std::string::npos;
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
