#pragma once
// An OpenGL 3.3 core context owned together with its GLFW window. Used invisible by GlBackend
// (headless rendering into framebuffer objects; the window is only there to own the context) and
// visible by the interactive viewer, which also gets swap_buffers, should_close, the framebuffer
// size and present() to show an image.
//
// GLFW is initialised when the first GlContext is created and terminated when the last one is
// destroyed, so several contexts (and backends) can coexist in one process. GLFW and every
// GlContext must be used from the main thread only (a GLFW rule).
#include <cstdint>
#include <glm/glm.hpp>
#include <span>
#include <string>
#include <vector>

struct GLFWwindow;

namespace fovea::render {

struct GlContextOptions {
  bool visible = false;        // false: headless (GLFW_VISIBLE false); true: an interactive window
  std::string title = "fovea";
  int width = 640, height = 480;  // window size in screen coordinates
  bool vsync = true;           // visible windows only: swap interval 1 (else 0)
};

class GlContext {
 public:
  // Throws std::runtime_error when there is no display ("no X display: run under xvfb-run or set
  // DISPLAY") or when the window/context cannot be created (with GLFW's error text).
  explicit GlContext(const GlContextOptions& options = {});
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;
  GlContext(GlContext&&) = delete;
  GlContext& operator=(GlContext&&) = delete;

  // Makes this context current on the calling thread (cheap when it already is).
  void make_current();
  GLFWwindow* window() const { return window_; }

  // Viewer helpers.
  void swap_buffers();
  bool should_close() const;
  static void poll_events();
  glm::ivec2 framebuffer_size() const;  // pixels (may differ from the window size on HiDPI)

  // Draws an image to the default framebuffer, scaled to fill it (aspect ratio kept, letterboxed),
  // with a fullscreen textured quad. `rgba` is 8-bit sRGB RGBA, width*height*4 bytes, row 0 at the
  // top. Does not swap buffers. Throws std::invalid_argument on a size mismatch.
  void present(std::span<const std::uint8_t> rgba, std::uint32_t width, std::uint32_t height);
  // Convenience: linear RGB in [0, 1] (values outside are clamped, NaN becomes 0) encoded to sRGB8.
  // Tone mapping belongs to the tonemap pass; this does none.
  void present(const std::vector<glm::vec3>& linear_rgb, std::uint32_t width, std::uint32_t height);

  // The renderer string of the context (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)").
  std::string renderer() const { return renderer_; }

 private:
  void create_present_resources();

  GLFWwindow* window_ = nullptr;
  std::string renderer_;
  // present() resources, created on first use.
  unsigned present_program_ = 0, present_vao_ = 0, present_texture_ = 0;
  std::vector<std::uint8_t> srgb_scratch_;
};

}  // namespace fovea::render
