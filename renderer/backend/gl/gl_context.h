// SPDX-License-Identifier: Apache-2.0
#pragma once
// An OpenGL core context, the newest the driver gives of 4.6, 4.5, 4.3 and 3.3 (3.3 is what the
// G-buffer needs; the GPU passes need more: GlFeatures). Two platforms:
//  - EGL, without any window system (the default for invisible contexts: GlBackend, --headless, the
//    tests and the benchmarks). The display is the first that works of: a GPU through
//    EGL_EXT_platform_device (NVIDIA's headless path), Mesa's surfaceless platform
//    (EGL_MESA_platform_surfaceless; llvmpipe on a machine without a GPU), Mesa's software device,
//    the default display. DISPLAY is not needed. Rendering goes to framebuffer objects: there is no
//    default framebuffer.
//  - GLFW, an X window (visible for the interactive viewer; invisible where a context must share
//    the viewer's window system). Needs DISPLAY.
//
// GLFW is initialised when the first GLFW context is created and terminated when the last one is
// destroyed, so several contexts (and backends) can coexist in one process. The EGL display is
// opened once per process and kept. Contexts must be used from the main thread only (a GLFW rule;
// make_current tracks the current context per thread).
#include <cstdint>
#include <glm/glm.hpp>
#include <span>
#include <string>
#include <vector>

struct GLFWwindow;

namespace fovea::render {

enum class GlPlatform {
  Egl,   // no window system (see above)
  Glfw,  // an X window through GLFW
};

struct GlContextOptions {
  bool visible = false;        // true: an interactive window (always GLFW)
  GlPlatform platform = GlPlatform::Egl;  // for invisible contexts
  std::string title = "fovea";
  int width = 640, height = 480;  // window size in screen coordinates
  bool vsync = true;           // visible windows only: swap interval 1 (else 0)
  // GLFW only: share textures and buffers with this context (the viewer's window shows the frame
  // the backend's invisible context rendered, without a copy through the CPU).
  const class GlContext* share = nullptr;
};

// What the context can do, read once when it is created.
struct GlFeatures {
  int major = 0, minor = 0;  // GL_MAJOR_VERSION / GL_MINOR_VERSION of the context
  bool timer_query = false;  // GL_TIMESTAMP queries (core in 3.3; ARB_timer_query)
  bool sync = false;         // fences (core in 3.2; ARB_sync)
  bool compute = false;      // compute shaders (core in 4.3; ARB_compute_shader)
  // A software rasteriser (Mesa's llvmpipe/softpipe, SwiftShader): fragment and compute shaders run
  // on the same CPU cores, so moving shading to compute buys nothing (bench/RESULTS.md).
  bool software = false;
  // GL_MAX_SHADER_STORAGE_BLOCK_SIZE, bytes (GL 4.3; 0 without storage buffers): the largest buffer
  // one compute pass may read, asked once here rather than by every frame's plan.
  std::int64_t max_storage_block = 0;
  // Compute passes pay here: compute shaders (GL 4.3) on a GPU, not a software rasteriser. The
  // visibility buffer and the compute tone map follow this one rule (bench/RESULTS.md).
  bool compute_pays() const { return at_least(4, 3) && !software; }
  bool at_least(int want_major, int want_minor) const {
    return major > want_major || (major == want_major && minor >= want_minor);
  }
  std::string version() const { return std::to_string(major) + "." + std::to_string(minor); }
};

class GlContext {
 public:
  // Throws std::runtime_error when the context cannot be created: GLFW without an X display ("no X
  // display: run under xvfb-run or set DISPLAY"), no EGL display or no OpenGL 3.3 core context
  // through EGL (naming each platform tried and why it failed), GLFW's error text otherwise.
  explicit GlContext(const GlContextOptions& options = {});
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;
  GlContext(GlContext&&) = delete;
  GlContext& operator=(GlContext&&) = delete;

  // Makes this context current on the calling thread (cheap when it already is).
  void make_current();
  GLFWwindow* window() const { return window_; }  // nullptr for EGL contexts
  bool windowed() const { return window_ != nullptr; }
  // How the context was made, e.g. "EGL 1.5, surfaceless platform" or "GLFW (X display :1)".
  const std::string& platform_description() const { return platform_; }

  // Viewer helpers: they need a window (GLFW); on an EGL context present() throws
  // std::logic_error, swap_buffers() does nothing and framebuffer_size() is {0, 0}.
  void swap_buffers();
  bool should_close() const;
  static void poll_events();
  glm::ivec2 framebuffer_size() const;  // pixels (may differ from the window size on HiDPI)

  // Where on the window present() draws: all of it, or one half (a stereo frame's eyes, side by
  // side). Whole and LeftHalf clear the window first; RightHalf draws beside what is there.
  enum class Region { Whole, LeftHalf, RightHalf };
  // Draws an image to the default framebuffer, scaled to fill it (aspect ratio kept, letterboxed),
  // with a fullscreen textured quad. `rgba` is 8-bit sRGB RGBA, width*height*4 bytes, row 0 at the
  // top. Does not swap buffers. Throws std::invalid_argument on a size mismatch.
  void present(std::span<const std::uint8_t> rgba, std::uint32_t width, std::uint32_t height,
               Region region = Region::Whole);
  // Convenience: linear RGB in [0, 1] (values outside are clamped, NaN becomes 0) encoded to sRGB8.
  // Tone mapping belongs to the tonemap pass; this does none.
  void present(const std::vector<glm::vec3>& linear_rgb, std::uint32_t width, std::uint32_t height);

  // Draws `texture` (RGBA8, rows bottom-up as OpenGL renders them, width x height texels used from
  // its lower-left corner) to the default framebuffer like present(). The texture must be visible in
  // this context (made here or in a context given as GlContextOptions::share). Does not swap buffers.
  void present_texture(unsigned texture, std::uint32_t width, std::uint32_t height, std::uint32_t texture_width,
                       std::uint32_t texture_height, Region region = Region::Whole);

  // The renderer string of the context (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)").
  std::string renderer() const { return renderer_; }
  const GlFeatures& features() const { return features_; }

 private:
  void create_present_resources();
  void create_glfw_window(const GlContextOptions& options);
  void create_egl_context();

  GLFWwindow* window_ = nullptr;
  void* egl_context_ = nullptr;  // EGLContext (EGL_NO_CONTEXT when GLFW)
  void* egl_surface_ = nullptr;  // EGLSurface: a 1x1 pbuffer where the display lacks surfaceless contexts
  std::string renderer_, platform_;
  GlFeatures features_;
  void read_features();
  void begin_present(const char* who);
  void draw_present_quad(std::uint32_t width, std::uint32_t height, float u_max, float v_max, bool top_row_first,
                         Region region);
  // present() resources, created on first use.
  unsigned present_program_ = 0, present_vao_ = 0, present_texture_ = 0;
  std::vector<std::uint8_t> srgb_scratch_;
};

}  // namespace fovea::render
