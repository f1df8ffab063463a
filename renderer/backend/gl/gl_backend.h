// SPDX-License-Identifier: Apache-2.0
#pragma once
// OpenGL 3.3 raster G-buffer backend. Renders the scene into a framebuffer object at the camera's
// resolution with one pass and multiple render targets:
//   0 RGBA32F  HDR local illumination (the shared BRDF of scene/shading.h, ported to GLSL in shaders.h)
//   1 R32F     linear view-space depth in metres (written by the shader, not a linearised z-buffer)
//   2 R32UI    object id
//   3 RGBA32F  world normal facing the camera
//   4 RG32F    screen-space motion in pixels (now minus previous, y down)
// plus a 32-bit float depth renderbuffer for the z test. The five planes are textures: render() reads
// back the planes BackendSettings::readback asks for (glReadPixels, rows flipped so row 0 is the
// top); render_on_gpu() leaves them on the GPU for the frame's GPU passes (gl_frame.h), which sample
// them through textures(). Runs in an invisible EGL context (no window system), or beside a viewer's
// GLFW window sharing its textures.
//
// Levels of detail are drawn as asked (BackendSettings::lod_levels); depth peeling by object
// (BackendSettings::peel, gl_peel.h) into targets of its own, read back by render(). Not supported:
// shadows (BackendSettings::shadows is ignored; the Embree backend casts shadow rays) and a lens point
// per pixel (refused with the reason).
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec2.hpp>

#include "backend/backend.h"
#include "backend/gl/gl_context.h"
#include "backend/gl/gl_peel.h"
#include "backend/gl/gl_visibility.h"
#include "backend/gpu_frame.h"
#include "scene/shading.h"

namespace fovea::render {

// The G-buffer's planes as textures, the image in their lower-left width x height texels (rows
// bottom-up, as OpenGL renders them).
struct GlGBufferTextures {
  unsigned color = 0, depth = 0, object_id = 0, normal = 0, motion = 0;
  std::uint32_t width = 0, height = 0;                  // the image
  std::uint32_t texture_width = 0, texture_height = 0;  // the textures
};

class GlBackend final : public Backend {
 public:
  // Creates its own invisible OpenGL 3.3 core context on `platform` (EGL: no window system needed;
  // GLFW: beside a viewer's window). Throws std::runtime_error with the reason (no EGL display, no X
  // display for GLFW, no GL 3.3 core context, shader compilation failure).
  // `share` (GLFW only): a window whose context sees this backend's textures (the viewer shows the
  // GPU-resident frame from there).
  explicit GlBackend(GlPlatform platform = GlPlatform::Egl, const GlContext* share = nullptr);
  ~GlBackend() override;
  GlBackend(const GlBackend&) = delete;
  GlBackend& operator=(const GlBackend&) = delete;

  std::string name() const override { return "gl"; }
  // A raster G-buffer: no shadow rays, one lens point per frame (an off-axis frustum), peeling.
  BackendCapabilities capabilities() const override;
  // Uploads every mesh once (shared meshes once) and the expanded light samples. Throws
  // std::invalid_argument for an object the raster backend cannot draw (normals not one per
  // position, index out of range, material index out of range; an object without a mesh is
  // skipped, as by the Embree backend) and
  // std::runtime_error when the lights expand to more than gl::kMaxLightSamples samples.
  void set_scene(const Scene& scene) override;
  void set_camera(const Camera& camera) override {
    if (scene_) scene_->camera = camera;
  }
  // settings.shadows is ignored: the raster backend has no shadows in this step. Renders the
  // background only (default camera) if no scene was set, like the Embree backend.
  void render(const FrameTime& time, const BackendSettings& settings, GBuffer& out) override;
  // Every layer in one peeling loop (layer n costs what layers 1..n do), each read back.
  void render_peeled_layers(const FrameTime& time, const BackendSettings& settings, std::vector<GBuffer>& out) override;

  // Renders without reading back: for benchmarks of the GPU side alone (ends with glFinish).
  void render_without_readback(const FrameTime& time);

  // Renders into the G-buffer textures and reads nothing back (the GPU-resident frame); the same
  // checks as render(). Writes only `planes` (the others keep what they held). Does not wait for the GPU.
  void render_on_gpu(const FrameTime& time, const BackendSettings& settings, const GBufferPlanes& planes);
  // Reads `planes` of the last render into `out`, which must already have the render's size.
  void read_back(const GBufferPlanes& planes, GBuffer& out);
  // Depth and ids of the last render's pixels [x0, x1) x [y0, y1) (row 0 at the top), row-major, as
  // read_back converts them (a non-finite depth reads as the far plane).
  void read_back_rect(std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1, std::vector<float>& depth,
                      std::vector<std::uint32_t>& ids);
  // The G-buffer textures of the last render (0 before the first).
  GlGBufferTextures textures() const;
  // Peels layers 1..`layers` behind the visible one (settings: time's lens, LOD levels; its peel is
  // ignored) into targets of their own, left on the GPU; the frame's G-buffer textures are untouched.
  const GlPeeling& peel_on_gpu(const FrameTime& time, const BackendSettings& settings, std::uint32_t layers);
  // Renders the scene (settings' lens, LOD levels, size, and G-buffer pass: the visibility buffer
  // where settings.visibility_buffer and the frame could take it, else forward shading) into targets
  // of its own, left on the GPU: the frame's G-buffer textures are untouched (ULOD's next levels,
  // blended where the frame lies). Only `planes` are written. Valid until the next call of that size
  // or the second of other sizes (two sizes are kept).
  GlGBufferTextures render_aside(const FrameTime& time, const BackendSettings& settings,
                                 const GBufferPlanes& planes = GBufferPlanes::all());
  // Makes the G-buffer's five plane textures (colour RGBA32F, depth R32F, id R32UI, normal RGBA32F,
  // motion RG32F) at width x height and attaches them to the bound framebuffer's colour attachments 0-4.
  static void attach_gbuffer_textures(unsigned (&textures)[5], std::uint32_t width, std::uint32_t height);
  // A new framebuffer `fbo` of the planes (attach_gbuffer_textures) and a 32-bit float z-buffer `z`,
  // width x height, bound; returns its glCheckFramebufferStatus.
  static unsigned make_gbuffer_target(unsigned& fbo, unsigned (&textures)[5], unsigned& z, std::uint32_t width,
                                      std::uint32_t height);

  // The GPU-resident frame (gl_frame.h) on this backend's context, made on first use.
  GpuFrame* gpu_frame() override;

  GlContext& context() { return context_; }
  const GlContext& context() const { return context_; }

 private:
  struct GpuMesh {
    unsigned vao = 0, vbo = 0, ibo = 0;
    unsigned extra_vbo = 0;  // texture coordinates, colours, tangents; 0 when the mesh has none
    std::int32_t index_count = 0;
  };
  struct DrawItem {
    std::size_t mesh;               // index into meshes_ (kNoMesh: nothing to draw)
    std::vector<std::size_t> lods;  // the object's LOD levels 1.. in meshes_
  };

  // width/height 0: the camera's resolution.
  void draw(const FrameTime& time, const LensSample& lens = {}, const std::vector<std::uint8_t>& lod_levels = {},
            std::uint32_t width = 0, std::uint32_t height = 0, const GBufferPlanes& planes = GBufferPlanes::all(),
            bool depth_prepass = false, bool visibility_buffer = false);
  // The forward G-buffer pass into `fbo` (the frame's, or render_aside's).
  void draw_forward(unsigned fbo, const FrameTime& time, const LensSample& lens, const std::vector<std::uint8_t>& lod_levels,
                    std::uint32_t width, std::uint32_t height, const GBufferPlanes& planes, bool depth_prepass);

  // The camera's view (now and at the previous frame), projection and eye for one render.
  struct FrameView {
    glm::mat4 view, view_prev, proj;
    glm::vec3 eye;
  };
  static FrameView frame_view(const Camera& cam, const FrameTime& time, const LensSample& lens);
  static void move_eye_to_lens_point(const Camera& cam, const LensSample& lens, FrameView& frame);
  void set_frame_uniforms(const FrameView& frame, const glm::vec3& ambient, std::uint32_t width, std::uint32_t height);
  // Which objects draw_objects draws: all, or the opaque ones and the alpha-tested ones apart (a
  // depth pre-pass holds only the opaque: an alpha-tested surface's depth depends on its texture).
  enum class DrawSubset { All, Opaque, AlphaTested };
  void draw_objects(const Scene& scene, const FrameTime& time, const std::vector<std::uint8_t>& lod_levels, DrawSubset subset,
                    bool camera_moved);
  void set_object_uniforms(const Object& o, const Material& m, const FrameTime& time, bool camera_moved);
  // The visibility-buffer pass, built on first use; false (and one stderr line, once) where the
  // context or the scene cannot have it.
  bool ensure_visibility();
  // Into the frame's targets (textures_, z_buffer_) or render_aside's.
  struct Targets {
    const unsigned* textures;  // the five planes
    unsigned z;
    std::uint32_t width, height;  // the framebuffer's
  };
  void draw_visibility(const Scene& scene, const FrameTime& time, const std::vector<std::uint8_t>& lod_levels,
                       const FrameView& frame, bool camera_moved, std::uint32_t width, std::uint32_t height,
                       const GBufferPlanes& planes, const Targets& targets);
  // The objects of this frame (their chosen levels) as the visibility pass's draws, and its view.
  struct VisibilityFrame {
    GlVisibilityPass::View view;
    std::vector<GlVisibilityPass::Draw> draws;
  };
  VisibilityFrame visibility_frame(const Scene& scene, const FrameTime& time,
                                   const std::vector<std::uint8_t>& lod_levels, const FrameView& frame,
                                   bool camera_moved, std::uint32_t width, std::uint32_t height) const;
  // BackendSettings::depth_prepass: the z-buffer of every object, nothing else.
  void draw_depth(const Scene& scene, const FrameTime& time, const std::vector<std::uint8_t>& lod_levels,
                  const FrameView& frame);
  // Object i's mesh at the level asked for (clamped to what it has); null when there is nothing to draw.
  const GpuMesh* mesh_for(std::size_t i, const std::vector<std::uint8_t>& lod_levels) const;
  // Uploads one mesh as an interleaved position/normal vertex buffer and an index buffer.
  static GpuMesh upload_interleaved_mesh(const Mesh& mesh, std::vector<float>& interleaved);
  // Fills meshes_ and draws_ (one per object, LOD levels included).
  void upload_draw_items(const Scene& scene);
  // PBR (gl_backend_textures.cpp): the scene's textures with their mip chains, the sampler objects
  // of its bindings, and a material's uniforms and texture units for one draw.
  void upload_textures(const Scene& scene);
  void release_textures();
  unsigned sampler_for(const TextureSampler& s);
  void set_material_textures(const Material& m);
  void ensure_framebuffer(std::uint32_t width, std::uint32_t height);
  static void check_settings(const BackendSettings& settings);
  void release_framebuffer();
  void release_meshes();
  // BackendSettings::peel > 0: the peeled layer into `out` (its own targets: the G-buffer textures
  // keep the frame's render).
  void render_peeled(const FrameTime& time, const BackendSettings& settings, GBuffer& out);
  void read_back_from(unsigned fbo, const GBufferPlanes& planes, GBuffer& out);

  GlContext context_;
  unsigned program_ = 0;
  unsigned depth_program_ = 0;  // the depth pre-pass
  std::unique_ptr<GlVisibilityPass> visibility_;
  std::string visibility_refusal_;          // why it cannot run here ("" : not refused)
  std::vector<const Mesh*> mesh_sources_;   // meshes_' meshes (the visibility pass copies them)
  bool visibility_meshes_stale_ = true;
  int loc_depth_model_ = -1, loc_depth_view_ = -1, loc_depth_proj_ = -1;
  unsigned light_ubo_ = 0;
  // Uniform locations.
  int loc_model_ = -1, loc_model_prev_ = -1, loc_normal_matrix_ = -1, loc_view_ = -1, loc_view_prev_ = -1,
      loc_proj_ = -1, loc_light_count_ = -1, loc_eye_ = -1, loc_ambient_ = -1, loc_viewport_ = -1,
      loc_object_id_ = -1, loc_emissive_ = -1, loc_kd_ = -1, loc_ks_ = -1, loc_emission_ = -1, loc_shininess_ = -1, loc_moved_ = -1;

  unsigned fbo_ = 0;
  unsigned textures_[5] = {};  // colour, depth, id, normal, motion
  unsigned z_buffer_ = 0;
  std::uint32_t fb_width_ = 0, fb_height_ = 0;
  std::uint32_t image_width_ = 0, image_height_ = 0;  // of the last render

  std::optional<Scene> scene_;
  std::vector<GpuMesh> meshes_;
  std::vector<DrawItem> draws_;  // one per scene object, same order
  int light_sample_count_ = 0;

  std::vector<float> scratch_;
  std::vector<std::uint32_t> scratch_id_;
  std::unique_ptr<GpuFrame> gpu_frame_;
  std::unique_ptr<GlPeeling> peeling_;  // made on the first peeled render
  int loc_peel_ = -1;
  struct PbrLocations {
    int pbr = -1, base_color = -1, metallic_roughness = -1, emissive = -1, normal_scale = -1, occlusion_strength = -1,
        alpha_test = -1, alpha_cutoff = -1, tex_present = -1, tex_set1 = -1;
  } loc_pbr_;
  std::vector<unsigned> scene_textures_;  // one per Scene::textures entry
  std::vector<std::pair<TextureSampler, unsigned>> samplers_;
  bool pbr_scene_ = false;  // a MetallicRoughness material: the visibility buffer cannot shade it
  struct Aside {  // render_aside's targets
    unsigned fbo = 0, z = 0, textures[5] = {0, 0, 0, 0, 0};
    std::uint32_t width = 0, height = 0;
  };
  // Two sizes kept: a ULOD frame renders the attention proxy (the map's size) and the next levels (the
  // frame's) aside every frame, and reallocating targets twice a frame cost 2 ms on the H200.
  std::array<Aside, 2> asides_;
  std::size_t aside_last_ = 0;  // the slot the last render_aside drew into
  Aside& aside_for(std::uint32_t width, std::uint32_t height);
  void release_aside();
  // The start of a render into targets of the backend's own: checks `settings`, a default scene if
  // none was set, the context current; returns the image's size (the camera's unless set).
  glm::uvec2 begin_render(const BackendSettings& settings);
};

std::unique_ptr<Backend> make_gl_backend(GlPlatform platform = GlPlatform::Egl, const GlContext* share = nullptr);

}  // namespace fovea::render
