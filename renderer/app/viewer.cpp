// SPDX-License-Identifier: Apache-2.0
// The interactive viewer: a GLFW window showing the tone-mapped frame, camera navigation, effect
// toggles, and gaze, latency and loss in the title bar.
#include <GLFW/glfw3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <glm/gtc/matrix_transform.hpp>

#include "app/render_options.h"
#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_context.h"
#include "pipeline/frame_pipeline.h"

namespace fovea::render {

namespace {

const char* kHelp =
    "fovea-render viewer keys:\n"
    "  W/S forward/back, A/D left/right, Q/E down/up, arrows turn; hold Shift to move faster\n"
    "  G gaze overlay, M mouse gaze on/off (with --gaze mouse), O cycle map (none, depth, id, normal, motion)\n"
    "  1 dof, 2 lod, 3 gi, 4 attention, 5 shadows (toggle the setting), F focus overlay (the focused object),\n"
    "  P cycle attention maps (none, saliency, spatial, temporal, attention), C CoC map (dof), K cycle DOF method\n"
    "  (lee-mipmap, lee-splat, schedl-layered, accum, reference), I cycle the GI strategy (traditional,\n"
    "  gaze-directed, importon), U GI estimate (nearest, precomputed), L cycle the LOD policy (screen-size,\n"
    "  distance, brown, ulod, gaze, none), X print the frame plan, Esc quit\n";

void toggle(Settings& s, const std::string& key) {
  s.set(key, s.flag(key) ? "false" : "true");
  std::printf("%s=%s\n", key.c_str(), s.text(key).c_str());
}

// Moves the camera (position and target together) in its own frame.
bool navigate(GLFWwindow* w, Camera& cam, double dt) {
  const auto down = [&](int key) { return glfwGetKey(w, key) == GLFW_PRESS; };
  const float speed = static_cast<float>((down(GLFW_KEY_LEFT_SHIFT) ? 4.0 : 1.0) * dt);
  const glm::vec3 forward = glm::normalize(cam.target - cam.position);
  const glm::vec3 right = glm::normalize(glm::cross(forward, cam.up));
  glm::vec3 move(0.0f);
  if (down(GLFW_KEY_W)) move += forward;
  if (down(GLFW_KEY_S)) move -= forward;
  if (down(GLFW_KEY_D)) move += right;
  if (down(GLFW_KEY_A)) move -= right;
  if (down(GLFW_KEY_E)) move += cam.up;
  if (down(GLFW_KEY_Q)) move -= cam.up;
  float yaw = 0, pitch = 0;
  if (down(GLFW_KEY_LEFT)) yaw += 1;
  if (down(GLFW_KEY_RIGHT)) yaw -= 1;
  if (down(GLFW_KEY_UP)) pitch += 1;
  if (down(GLFW_KEY_DOWN)) pitch -= 1;
  if (move == glm::vec3(0.0f) && yaw == 0 && pitch == 0) return false;
  cam.position += move * speed * 2.0f;
  cam.target += move * speed * 2.0f;
  const float dist = glm::length(cam.target - cam.position);
  glm::mat4 r = glm::rotate(glm::mat4(1.0f), yaw * static_cast<float>(dt), cam.up);
  r = glm::rotate(r, pitch * static_cast<float>(dt), right);
  const glm::vec3 dir = glm::normalize(glm::vec3(r * glm::vec4(forward, 0.0f)));
  cam.target = cam.position + dir * dist;
  return true;
}

struct KeyState {
  Settings* settings = nullptr;
  FramePipeline* pipeline = nullptr;
};

void on_key(GLFWwindow* w, int key, int, int action, int) {
  if (action != GLFW_PRESS) return;
  auto* ks = static_cast<KeyState*>(glfwGetWindowUserPointer(w));
  Settings& s = *ks->settings;
  switch (key) {
    case GLFW_KEY_ESCAPE: glfwSetWindowShouldClose(w, GLFW_TRUE); break;
    case GLFW_KEY_G: toggle(s, "overlay.gaze"); break;
    case GLFW_KEY_1: toggle(s, "dof.enabled"); break;
    case GLFW_KEY_2: toggle(s, "lod.enabled"); break;
    case GLFW_KEY_3: toggle(s, "gi.enabled"); break;
    case GLFW_KEY_4: s.set("overlay.map", s.is("overlay.map", "attention") ? "none" : "attention"); break;
    case GLFW_KEY_5: toggle(s, "shadows"); break;
    case GLFW_KEY_O: {
      static const char* maps[] = {"none", "depth", "id", "normal", "motion"};
      std::size_t i = 0;
      while (i < 5 && !s.is("overlay.map", maps[i])) ++i;
      s.set("overlay.map", maps[(i + 1) % 5]);
      std::printf("overlay.map=%s\n", s.text("overlay.map").c_str());
      break;
    }
    case GLFW_KEY_F: toggle(s, "overlay.focus"); break;
    case GLFW_KEY_P: {
      // none, then the attention maps in their order; from any other map, the first attention map.
      std::vector<std::string> cycle{"none"};
      cycle.insert(cycle.end(), attention::kMaps.begin(), attention::kMaps.end());
      const auto at = std::find(cycle.begin(), cycle.end(), s.text("overlay.map"));
      const std::size_t i = at == cycle.end() ? 0 : static_cast<std::size_t>(at - cycle.begin());
      s.set("overlay.map", cycle[(i + 1) % cycle.size()]);
      std::printf("overlay.map=%s\n", s.text("overlay.map").c_str());
      break;
    }
    case GLFW_KEY_C: {
      s.set("overlay.map", s.is("overlay.map", "coc") ? "none" : "coc");
      std::printf("overlay.map=%s\n", s.text("overlay.map").c_str());
      break;
    }
    case GLFW_KEY_K: {
      static const char* methods[] = {"lee-mipmap", "lee-splat", "schedl-layered", "accum", "reference"};
      std::size_t i = 0;
      while (i < 5 && !s.is("dof.method", methods[i])) ++i;
      s.set("dof.method", methods[(i + 1) % 5]);
      std::printf("dof.method=%s\n", s.text("dof.method").c_str());
      break;
    }
    case GLFW_KEY_I: {
      static const char* strategies[] = {"traditional", "gaze-directed", "importon"};
      std::size_t i = 0;
      while (i < 3 && !s.is("gi.strategy", strategies[i])) ++i;
      s.set("gi.strategy", strategies[(i + 1) % 3]);
      std::printf("gi.strategy=%s\n", s.text("gi.strategy").c_str());
      break;
    }
    case GLFW_KEY_L: {
      static const char* policies[] = {"screen-size", "distance", "brown", "ulod", "gaze", "none"};
      std::size_t i = 0;
      while (i < 6 && !s.is("lod.policy", policies[i])) ++i;
      s.set("lod.policy", policies[(i + 1) % 6]);
      std::printf("lod.policy=%s\n", s.text("lod.policy").c_str());
      break;
    }
    case GLFW_KEY_U:
      s.set("gi.estimate", s.is("gi.estimate", "precomputed") ? "auto" : "precomputed");
      std::printf("gi.estimate=%s\n", s.text("gi.estimate").c_str());
      break;
    case GLFW_KEY_X: std::printf("%s", ks->pipeline->plan().explain().c_str()); break;
    default: break;
  }
  std::fflush(stdout);
}

// Puts the frame on the window (a stereo frame's eye on its half): from the GPU where it lies
// (Frame::on_gpu), else the CPU image uploaded.
void draw(GlContext& window, const FramePipeline::Frame& f, FramePipeline& pipeline, std::vector<std::uint8_t>& rgba,
          GlContext::Region region) {
  window.make_current();
  if (f.on_gpu) {
    const GpuFrame::Texture d = pipeline.gpu_frame()->display_texture();
    if (d.id != 0) window.present_texture(d.id, d.width, d.height, d.texture_width, d.texture_height, region);
  } else if (f.image != nullptr) {
    rgba.resize(std::size_t{f.image->width} * f.image->height * 4);
    for (std::size_t p = 0; p < std::size_t{f.image->width} * f.image->height; ++p) {
      rgba[4 * p + 0] = f.image->rgb[3 * p + 0];
      rgba[4 * p + 1] = f.image->rgb[3 * p + 1];
      rgba[4 * p + 2] = f.image->rgb[3 * p + 2];
      rgba[4 * p + 3] = 255;
    }
    window.present(rgba, f.image->width, f.image->height, region);
  }
}

// Draws the frame (one view: the whole window; stereo: the right eye beside the left drawn before)
// and swaps. Records the gaze's age when the swap returned ("gaze-age.swap").
void show(GlContext& window, const FramePipeline::Frame& f, FramePipeline& pipeline, std::vector<std::uint8_t>& rgba,
          PassTimer& timer) {
  {
    auto t = timer.scope("display");
    draw(window, f, pipeline, rgba,
         f.eye == FramePipeline::Eye::Right ? GlContext::Region::RightHalf : GlContext::Region::Whole);
    window.swap_buffers();
  }
  const double swapped =
      std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  timer.record("gaze-age.swap", f.gaze_age_at_completion_ms + (swapped - f.completed_wall_s) * 1000.0);
}

// The title bar: frame time (and the GPU's own time when the frame is kept there), gaze, its age when
// latched and when shown, loss, and the governor's choice.
void set_title(GlContext& window, const FramePipeline& pipeline, const GazeInput& gaze, const FramePipeline::Frame& f,
               const PassTimer& timer, const Governor* governor) {
  // The GPU's own time for the frame's passes (timestamp queries), beside the CPU's frame time.
  double gpu_ms = 0;
  for (const char* pass : {"gpu.gbuffer", "gpu.upload", "gpu.tonemap", "gpu.overlay"}) gpu_ms += timer.frame_ms(pass);
  char gpu[48] = "";
  if (f.on_gpu) std::snprintf(gpu, sizeof gpu, " (frame on the GPU: %.2f ms there)", gpu_ms);
  char title[320];
  std::snprintf(title, sizeof title, "fovea-render %s | %.1f ms/frame%s | gaze %s (%.3f, %.3f) %s | age %.1f ms, "
                "%.1f ms when shown | lost %llu",
                pipeline.backend().name().c_str(), timer.last_ms("frame") + timer.last_ms("right.frame"), gpu,
                gaze.description().c_str(), f.gaze.x, f.gaze.y,
                f.gaze.valid ? protocol::to_string(f.gaze.movement) : "no gaze", f.gaze.age_ms,
                timer.last_ms("gaze-age.swap"), static_cast<unsigned long long>(f.gaze.lost));
  std::string full = title;
  if (governor) full += " | " + governor->state().summary();
  glfwSetWindowTitle(window.window(), full.c_str());
}

// Renders the frame's views: one, or a stereo frame's left eye (drawn on its half at once) and then
// its right eye. Returns the last view's frame, for show() to draw and swap.
FramePipeline::Frame render_views(GlContext& window, FramePipeline& pipeline, std::vector<std::uint8_t>& rgba,
                                  PassTimer& timer, std::uint64_t i, double now, double previous, bool stereo) {
  if (!stereo) return pipeline.render(i, now, previous, now, timer, true);
  const FramePipeline::Frame left = pipeline.render(i, now, previous, now, timer, true, FramePipeline::Eye::Left);
  {
    auto t = timer.scope("display");
    draw(window, left, pipeline, rgba, GlContext::Region::LeftHalf);
  }
  return pipeline.render(i, now, previous, now, timer, true, FramePipeline::Eye::Right);
}

}  // namespace

int run_viewer(const RenderOptions& o) {
  LoadReport load;
  Scene scene = load_render_scene(o, &load);
  GlContextOptions co;
  co.visible = true;
  co.title = "fovea-render: " + scene.name;
  const bool stereo = scene.camera.stereo;
  co.width = static_cast<int>(scene.camera.width) * (stereo ? 2 : 1);  // stereo: left | right
  co.height = static_cast<int>(scene.camera.height);
  GlContext window(co);
  std::unique_ptr<GazeInput> gaze = make_gaze_input(o.gaze);
  // The raster backend's context uses the window's platform (GLFW): the viewer never mixes EGL and
  // GLX contexts in one process. It shares the window's textures, so a frame kept on the GPU is
  // shown from where it lies.
  const auto backend_start = std::chrono::steady_clock::now();
  FramePipeline pipeline(std::move(scene), o.settings,
                         o.backend == BackendKind::OpenGL ? make_gl_backend(GlPlatform::Glfw, &window)
                                                          : make_backend(o.backend),
                         *gaze);
  load.add_since("backend", backend_start, backend_load_note(o.backend));
  if (o.verbose) std::fprintf(stderr, "fovea-render: %s\n", load.summary().c_str());
  KeyState keys{&pipeline.settings(), &pipeline};
  glfwSetWindowUserPointer(window.window(), &keys);
  glfwSetKeyCallback(window.window(), on_key);
  std::printf("%s", kHelp);
  std::printf("%s", pipeline.plan().explain().c_str());
  if (stereo) std::printf("%s\n", pipeline.stereo_summary().c_str());
  std::fflush(stdout);

  PassTimer timer;
  std::unique_ptr<Governor> governor = make_governor(o);
  const auto start = std::chrono::steady_clock::now();
  double previous = 0;
  std::vector<std::uint8_t> rgba;
  for (std::uint64_t i = 0; o.frames == 0 || i < o.frames; ++i) {
    GlContext::poll_events();
    if (window.should_close()) break;
    const double now = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (navigate(window.window(), pipeline.mutable_scene().camera, i == 0 ? 0.0 : now - previous)) {
      pipeline.camera_changed();
    }
    double cx = 0, cy = 0;
    glfwGetCursorPos(window.window(), &cx, &cy);
    int ww = 1, wh = 1;
    glfwGetWindowSize(window.window(), &ww, &wh);
    gaze->set_cursor(cx / std::max(1, ww), cy / std::max(1, wh));
    if (governor)  // all the frame's pixels: both eyes' in stereo
      governor->apply(pipeline.plan(), pipeline.backend().name(), pipeline.device(),
                      pipeline.scene().camera.width * (stereo ? 2u : 1u), pipeline.scene().camera.height,
                      pipeline.settings());
    const FramePipeline::Frame f = render_views(window, pipeline, rgba, timer, i, now, i == 0 ? now : previous, stereo);
    if (governor) governor->observe(timer);
    previous = now;
    show(window, f, pipeline, rgba, timer);
    if (i % 10 == 0) {
      set_title(window, pipeline, *gaze, f, timer, governor.get());
      if (governor && i % 100 == 0) std::printf("governor: %s\n", governor->state().summary().c_str());
    }
  }
  std::printf("%s", timer.summary_table().c_str());
  if (governor) std::printf("governor: %s\n", governor->state().summary().c_str());
  return 0;
}

}  // namespace fovea::render
