// SPDX-License-Identifier: Apache-2.0
#pragma once
// The G-buffer by a visibility buffer (Burns & Hunt 2013): the raster pass writes only which
// triangle covers each pixel (and z), and one compute pass (GL 4.3) rebuilds every plane asked for
// from it, shading each pixel once on every core of the GPU. On GPUs whose raster pipeline is a small
// part of the chip (NVIDIA's H100/H200 run graphics on a few of their SMs) the forward G-buffer pass
// is bound by fragment shading and per-pixel writes; this moves both off it (bench/RESULTS.md).
// The planes agree with the forward pass's (tests/gl/test_gl_backend.cpp): same triangle per pixel,
// same shading formula (shaders.h kShadingGlsl), barycentrics from the pixel ray instead of the
// rasteriser's interpolation (float rounding apart, the same numbers).
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "backend/gbuffer.h"
#include "backend/gl/gl_context.h"
#include "scene/scene.h"

namespace fovea::render {

class GlVisibilityPass {
 public:
  // Why this context cannot run it ("" when it can): compute shaders and storage buffers (GL 4.3).
  static std::string unavailable_reason(const GlFeatures& features);
  // Needs the context current; throws std::runtime_error when a shader does not build.
  GlVisibilityPass(unsigned light_ubo);
  ~GlVisibilityPass();
  GlVisibilityPass(const GlVisibilityPass&) = delete;
  GlVisibilityPass& operator=(const GlVisibilityPass&) = delete;

  // The scene's meshes, in the order the draws name them (GlBackend's meshes_), copied into one
  // vertex and one index buffer the compute pass reads. Throws std::runtime_error past the device's
  // storage-buffer size (the caller falls back to the forward pass).
  void set_meshes(const std::vector<const Mesh*>& meshes);

  struct Draw {  // one object of this frame
    std::size_t mesh;  // index into set_meshes' list
    unsigned vao;      // its vertex array (GlBackend's)
    std::int32_t index_count;
    glm::mat4 model, model_prev;
    std::uint32_t object_id;
    const Material* material;
    bool moved;  // model or view differ between the frame's two times (motion exactly 0 otherwise)
  };
  struct View {
    glm::mat4 view, view_prev, proj;
    glm::vec3 eye;
    std::uint32_t width, height;  // the image, in the framebuffer's lower-left corner
    glm::vec3 background;
    float far_m;
    glm::vec3 ambient;
    int light_count;
  };
  // Rasterises the draws' triangle ids with `z_buffer` (a GL_DEPTH_COMPONENT32F renderbuffer of
  // fb_width x fb_height) as depth, then writes `planes` of `targets` (the G-buffer's five textures:
  // colour, depth, id, normal, motion) over the image.
  void render(const View& view, const std::vector<Draw>& draws, unsigned z_buffer, std::uint32_t fb_width,
              std::uint32_t fb_height, const unsigned targets[5], const GBufferPlanes& planes);

  // Depth peeling through the visibility buffer (GlPeeling::run_visibility): rasterises the draws
  // into `fbo` (bound, cleared and sized by the caller: view depth at attachment 1, object id at 2,
  // (1 + draw, primitive) at 5, a z-buffer), discarding fragments against the last layer's depth and
  // state textures as the forward G-buffer's peel does; against_depth 0: the unpeeled layer.
  void raster_peel(const View& view, const std::vector<Draw>& draws, unsigned fbo, unsigned against_depth,
                   unsigned against_state);
  // Writes `planes` of `targets` from a visibility texture (RG32UI: 1 + draw, primitive; 0: nothing
  // there, the background) that raster_peel or render made with the same draws.
  void shade(const View& view, const std::vector<Draw>& draws, unsigned visibility, const unsigned targets[5],
             const GBufferPlanes& planes);

 private:
  void ensure_target(unsigned z_buffer, std::uint32_t width, std::uint32_t height);
  void raster_ids(const View& view, const std::vector<Draw>& draws);

  unsigned raster_program_ = 0, resolve_program_ = 0, peel_program_ = 0;
  int loc_model_ = -1, loc_view_ = -1, loc_proj_ = -1, loc_draw_ = -1;
  struct PeelUniforms {
    int model = -1, view = -1, proj = -1, draw = -1, object_id = -1, eye = -1, peel = -1;
  } peel_loc_;
  struct ResolveUniforms {
    int planes = -1, view = -1, view_prev = -1, proj = -1, inv_proj = -1, inv_view = -1, eye = -1, size = -1,
        background = -1, far_m = -1, ambient = -1, light_count = -1, visibility = -1;
  } loc_;
  unsigned light_ubo_ = 0;
  unsigned fbo_ = 0, ids_ = 0, fbo_z_ = 0;
  std::uint32_t fb_width_ = 0, fb_height_ = 0;
  unsigned vertices_ = 0, indices_ = 0, draws_ = 0;
  std::vector<std::uint32_t> first_index_, first_vertex_;  // per mesh, in the scene-wide buffers
};

}  // namespace fovea::render
