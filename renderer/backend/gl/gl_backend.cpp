// SPDX-License-Identifier: Apache-2.0
// The OpenGL G-buffer backend (gl_backend.h): its programs, the G-buffer's framebuffers, and the
// frame drawn into them (forward with an optional depth pre-pass, the visibility buffer, or depth
// peeling). The scene's upload is in gl_backend_scene.cpp, the read-back in gl_backend_readback.cpp.
#include "backend/gl/gl_backend.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <stdexcept>
#include <string>

#include "backend/gl/gl_backend_detail.h"
#include "backend/gl/gl_frame.h"
#include "backend/gl/gl_program.h"
#include "backend/gl/shaders.h"

namespace fovea::render {

using namespace gl_backend_detail;

namespace {

// The texture units of the G-buffer program's depth-peeling samplers (gl_peel.h).
constexpr int kPeelDepthUnit = 6, kPeelStateUnit = 7;

// Targets the image's lower-left corner of the G-buffer with the z test on and no culling or blending,
// writing only the planes asked for: a plane nobody reads is neither cleared nor written (the raster
// pass is bound by what it writes per pixel on GPUs with few graphics units, bench/RESULTS.md).
void begin_gbuffer_pass(GLuint fbo, std::uint32_t width, std::uint32_t height, const GBufferPlanes& planes) {
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  const bool written[5] = {planes.color, planes.depth, planes.object_id, planes.normal, planes.motion};
  GLenum buffers[5];
  for (std::size_t i = 0; i < 5; ++i) buffers[i] = written[i] ? kDrawBuffers[i] : GL_NONE;
  glDrawBuffers(5, buffers);
  glViewport(0, 0, static_cast<GLsizei>(width), static_cast<GLsizei>(height));
  glEnable(GL_SCISSOR_TEST);  // clears only the image's corner of the framebuffer
  glScissor(0, 0, static_cast<GLsizei>(width), static_cast<GLsizei>(height));
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);  // surfaces are seen from both sides (draw_objects culls single-sided glTF materials)
  glDisable(GL_BLEND);
}

// What a pixel no object covers reads back as: the background, depth at the far plane, id 0.
void clear_gbuffer(const Scene& scene) {
  const GLfloat background[4] = {finite_or(scene.background.r, 0), finite_or(scene.background.g, 0),
                                 finite_or(scene.background.b, 0), 1.0f};
  const GLfloat far_depth[4] = {scene.camera.far_m, 0, 0, 0};
  const GLfloat zero[4] = {0, 0, 0, 0};
  const GLuint zero_id[4] = {0, 0, 0, 0};
  const GLfloat one = 1.0f;
  glClearBufferfv(GL_COLOR, 0, background);
  glClearBufferfv(GL_COLOR, 1, far_depth);
  glClearBufferuiv(GL_COLOR, 2, zero_id);
  glClearBufferfv(GL_COLOR, 3, zero);
  glClearBufferfv(GL_COLOR, 4, zero);
  glClearBufferfv(GL_DEPTH, 0, &one);
}

}  // namespace

GlBackend::GlBackend(GlPlatform platform, const GlContext* share)
    : context_(GlContextOptions{.visible = false, .platform = platform, .title = "fovea-gl-backend", .width = 16,
                                .height = 16, .vsync = false, .share = share}) {
  context_.make_current();
  const std::string fragment = std::string("#version 330 core\n") + gl::kShadingGlsl + gl::kPeelTest + gl::kGBufferFragment;
  program_ = gl::link_program(gl::kGBufferVertex, fragment.c_str(), "GlBackend G-buffer program");
  const auto loc = [this](const char* name) { return glGetUniformLocation(program_, name); };
  loc_model_ = loc("u_model");
  loc_model_prev_ = loc("u_model_prev");
  loc_normal_matrix_ = loc("u_normal_matrix");
  loc_view_ = loc("u_view");
  loc_view_prev_ = loc("u_view_prev");
  loc_proj_ = loc("u_proj");
  loc_light_count_ = loc("u_light_count");
  loc_eye_ = loc("u_eye");
  loc_ambient_ = loc("u_ambient");
  loc_viewport_ = loc("u_viewport");
  loc_object_id_ = loc("u_object_id");
  loc_emissive_ = loc("u_emissive");
  loc_kd_ = loc("u_kd");
  loc_ks_ = loc("u_ks");
  loc_emission_ = loc("u_emission");
  loc_shininess_ = loc("u_shininess");
  loc_moved_ = loc("u_moved");
  loc_peel_ = loc("u_peel");
  loc_pbr_ = {loc("u_pbr"),          loc("u_base_color"),  loc("u_metallic_roughness"), loc("u_emissive_factor"),
              loc("u_normal_scale"), loc("u_occlusion_strength"), loc("u_alpha_test"),   loc("u_alpha_cutoff"),
              loc("u_tex_present"),  loc("u_tex_set1")};
  // Units of their own: the program's samplers of different types must never share one.
  glUseProgram(program_);
  glUniform1i(loc("u_peel_depth"), kPeelDepthUnit);
  glUniform1i(loc("u_peel_state"), kPeelStateUnit);
  const char* slots[5] = {"u_tex_base", "u_tex_mr", "u_tex_normal", "u_tex_occlusion", "u_tex_emissive"};
  for (int k = 0; k < 5; ++k) glUniform1i(loc(slots[k]), kMaterialTextureUnit + k);
  glUseProgram(0);
  depth_program_ = gl::link_program(gl::kDepthVertex, gl::kDepthFragment, "GlBackend depth pre-pass program");
  loc_depth_model_ = glGetUniformLocation(depth_program_, "u_model");
  loc_depth_view_ = glGetUniformLocation(depth_program_, "u_view");
  loc_depth_proj_ = glGetUniformLocation(depth_program_, "u_proj");

  const GLuint block = glGetUniformBlockIndex(program_, "LightSamples");
  if (block == GL_INVALID_INDEX) throw std::runtime_error("GlBackend: uniform block LightSamples not found");
  glUniformBlockBinding(program_, block, 0);
  GLint max_block = 0;
  glGetIntegerv(GL_MAX_UNIFORM_BLOCK_SIZE, &max_block);
  constexpr auto kBlockBytes = static_cast<GLsizeiptr>(sizeof(LightSampleStd140) * gl::kMaxLightSamples);
  if (max_block < kBlockBytes) {
    throw std::runtime_error("GlBackend: GL_MAX_UNIFORM_BLOCK_SIZE " + std::to_string(max_block) + " < " +
                             std::to_string(kBlockBytes) + " bytes needed for the light samples");
  }
  glGenBuffers(1, &light_ubo_);
  glBindBuffer(GL_UNIFORM_BUFFER, light_ubo_);
  glBufferData(GL_UNIFORM_BUFFER, kBlockBytes, nullptr, GL_STATIC_DRAW);
  glBindBuffer(GL_UNIFORM_BUFFER, 0);
  check_gl("GlBackend()");
}

GlBackend::~GlBackend() {
  gpu_frame_.reset();  // its GL objects go while the context lives
  context_.make_current();
  peeling_.reset();
  visibility_.reset();
  release_meshes();
  release_textures();
  release_framebuffer();
  release_aside();
  if (light_ubo_ != 0) glDeleteBuffers(1, &light_ubo_);
  if (program_ != 0) glDeleteProgram(program_);
  if (depth_program_ != 0) glDeleteProgram(depth_program_);
}

void GlBackend::release_framebuffer() {
  if (fbo_ != 0) glDeleteFramebuffers(1, &fbo_);
  glDeleteTextures(5, textures_);
  if (z_buffer_ != 0) glDeleteRenderbuffers(1, &z_buffer_);
  fbo_ = 0;
  z_buffer_ = 0;
  std::fill(std::begin(textures_), std::end(textures_), 0u);
  fb_width_ = fb_height_ = 0;
}

void GlBackend::release_aside() {
  for (Aside& a : asides_) {
    if (a.fbo != 0) glDeleteFramebuffers(1, &a.fbo);
    glDeleteTextures(5, a.textures);
    if (a.z != 0) glDeleteRenderbuffers(1, &a.z);
    a = Aside{};
  }
}

// The slot of that size, else the one not drawn into last, made that size.
GlBackend::Aside& GlBackend::aside_for(std::uint32_t width, std::uint32_t height) {
  for (std::size_t k = 0; k < asides_.size(); ++k) {
    if (asides_[k].fbo != 0 && asides_[k].width == width && asides_[k].height == height) {
      aside_last_ = k;
      return asides_[k];
    }
  }
  const std::size_t k = asides_[0].fbo == 0 ? 0 : asides_[1].fbo == 0 ? 1 : 1 - aside_last_;
  Aside& a = asides_[k];
  if (a.fbo != 0) glDeleteFramebuffers(1, &a.fbo);
  glDeleteTextures(5, a.textures);
  if (a.z != 0) glDeleteRenderbuffers(1, &a.z);
  a = Aside{};
  const GLenum status = make_gbuffer_target(a.fbo, a.textures, a.z, width, height);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    release_aside();
    throw std::runtime_error("GlBackend::render_aside: framebuffer incomplete (status " + hex(status) + ")");
  }
  a.width = width;
  a.height = height;
  aside_last_ = k;
  return a;
}

glm::uvec2 GlBackend::begin_render(const BackendSettings& settings) {
  check_settings(settings);
  if (!scene_) set_scene(Scene{});  // as the Embree backend: background only, default camera
  context_.make_current();
  const Camera& cam = scene_->camera;
  return {settings.width > 0 ? settings.width : cam.width, settings.height > 0 ? settings.height : cam.height};
}

GlGBufferTextures GlBackend::render_aside(const FrameTime& time, const BackendSettings& settings,
                                         const GBufferPlanes& planes) {
  const glm::uvec2 size = begin_render(settings);
  const std::uint32_t width = size.x, height = size.y;
  const Aside& aside = aside_for(width, height);
  // As the frame's G-buffer pass draws (the same pass, the same pre-pass), so that both images pick
  // the same surface where two touch; on GPUs the visibility buffer's compute shading is the faster.
  if (settings.visibility_buffer && !pbr_scene_ && ensure_visibility()) {
    const FrameView frame = frame_view(scene_->camera, time, settings.lens);
    draw_visibility(*scene_, time, settings.lod_levels, frame, frame.view != frame.view_prev, width, height, planes,
                    {aside.textures, aside.z, width, height});
  } else {
    draw_forward(aside.fbo, time, settings.lens, settings.lod_levels, width, height, planes, settings.depth_prepass);
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  check_gl("GlBackend::render_aside");
  return {aside.textures[kColor], aside.textures[kDepth], aside.textures[kId], aside.textures[kNormal],
          aside.textures[kMotion], width, height, width, height};
}

void GlBackend::ensure_framebuffer(std::uint32_t width, std::uint32_t height) {
  if (fbo_ != 0 && width == fb_width_ && height == fb_height_) return;
  GLint max_size = 0, max_texture = 0;
  glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_size);
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_texture);  // the planes are textures, the z-buffer a renderbuffer
  GLint max_viewport[2] = {0, 0};
  glGetIntegerv(GL_MAX_VIEWPORT_DIMS, max_viewport);
  const auto limit = static_cast<std::uint32_t>(std::min({max_size, max_texture, max_viewport[0], max_viewport[1]}));
  if (width > limit || height > limit) {
    throw std::invalid_argument("GlBackend: camera resolution " + std::to_string(width) + "x" +
                                std::to_string(height) + " exceeds the OpenGL limit of " + std::to_string(limit) +
                                " pixels per side");
  }
  release_framebuffer();
  const GLenum status = make_gbuffer_target(fbo_, textures_, z_buffer_, width, height);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    release_framebuffer();
    throw std::runtime_error("GlBackend: G-buffer framebuffer incomplete (status " + hex(status) + ")");
  }
  fb_width_ = width;
  fb_height_ = height;
  check_gl("GlBackend::ensure_framebuffer");
}

unsigned GlBackend::make_gbuffer_target(unsigned& fbo, unsigned (&textures)[5], unsigned& z, std::uint32_t width,
                                        std::uint32_t height) {
  glGenFramebuffers(1, &fbo);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  // Textures, not renderbuffers: the GPU passes (GlFrame's) sample them where they lie.
  attach_gbuffer_textures(textures, width, height);
  glGenRenderbuffers(1, &z);
  glBindRenderbuffer(GL_RENDERBUFFER, z);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, static_cast<GLsizei>(width), static_cast<GLsizei>(height));
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, z);
  glBindRenderbuffer(GL_RENDERBUFFER, 0);
  glDrawBuffers(5, kDrawBuffers);
  return glCheckFramebufferStatus(GL_FRAMEBUFFER);
}

void GlBackend::attach_gbuffer_textures(unsigned (&textures)[5], std::uint32_t width, std::uint32_t height) {
  glGenTextures(5, textures);
  // glTexImage2D, not glTexStorage2D: the G-buffer keeps to OpenGL 3.3.
  const GLenum formats[5][3] = {{GL_RGBA32F, GL_RGBA, GL_FLOAT},
                                {GL_R32F, GL_RED, GL_FLOAT},
                                {GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT},
                                {GL_RGBA32F, GL_RGBA, GL_FLOAT},
                                {GL_RG32F, GL_RG, GL_FLOAT}};
  for (std::size_t i = 0; i < 5; ++i) {
    glBindTexture(GL_TEXTURE_2D, textures[i]);
    glTexImage2D(GL_TEXTURE_2D, 0, static_cast<GLint>(formats[i][0]), static_cast<GLsizei>(width),
                 static_cast<GLsizei>(height), 0, formats[i][1], formats[i][2], nullptr);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glFramebufferTexture2D(GL_FRAMEBUFFER, kDrawBuffers[i], GL_TEXTURE_2D, textures[i], 0);
  }
  glBindTexture(GL_TEXTURE_2D, 0);
}

void GlBackend::draw(const FrameTime& time, const LensSample& lens, const std::vector<std::uint8_t>& lod_levels,
                     std::uint32_t width, std::uint32_t height, const GBufferPlanes& planes, bool depth_prepass,
                     bool visibility_buffer) {
  if (!scene_) set_scene(Scene{});  // as the Embree backend: background only, default camera
  const Scene& scene = *scene_;
  const Camera& cam = scene.camera;
  context_.make_current();
  // A smaller image (BackendSettings::width/height) goes to the framebuffer's lower-left corner, so
  // alternating sizes do not reallocate it.
  if (width == 0) width = cam.width;
  if (height == 0) height = cam.height;
  ensure_framebuffer(std::max(std::max(cam.width, width), fb_width_), std::max(std::max(cam.height, height), fb_height_));
  if (visibility_buffer && pbr_scene_) {
    // The compute resolve shades the scene's own materials, not glTF's textures and BRDF.
    static bool said = false;
    if (!said) {
      std::fprintf(stderr, "fovea-render: visibility buffer off for this scene: its metallic-roughness (glTF) "
                           "materials are shaded in the raster pass\n");
      said = true;
    }
    visibility_buffer = false;
  }
  if (visibility_buffer && ensure_visibility()) {
    const FrameView frame = frame_view(cam, time, lens);
    draw_visibility(scene, time, lod_levels, frame, frame.view != frame.view_prev, width, height, planes,
                    {textures_, z_buffer_, fb_width_, fb_height_});
    check_gl("GlBackend::render (visibility buffer)");
    return;
  }
  draw_forward(fbo_, time, lens, lod_levels, width, height, planes, depth_prepass);
  check_gl("GlBackend::render (draw)");
}

void GlBackend::draw_forward(unsigned fbo, const FrameTime& time, const LensSample& lens,
                             const std::vector<std::uint8_t>& lod_levels, std::uint32_t width, std::uint32_t height,
                             const GBufferPlanes& planes, bool depth_prepass) {
  const Scene& scene = *scene_;
  begin_gbuffer_pass(fbo, width, height, planes);
  clear_gbuffer(scene);  // a draw buffer of GL_NONE ignores its clear
  const FrameView frame = frame_view(scene.camera, time, lens);
  const bool camera_moved = frame.view != frame.view_prev;
  if (depth_prepass) {
    draw_depth(scene, time, lod_levels, frame);
    glDepthFunc(GL_EQUAL);  // shade only the surface the pre-pass kept, once per pixel
    glDepthMask(GL_FALSE);
  }
  set_frame_uniforms(frame, scene.ambient, width, height);
  draw_objects(scene, time, lod_levels, depth_prepass ? DrawSubset::Opaque : DrawSubset::All, camera_moved);
  if (depth_prepass) {  // alpha-tested objects were left out of the pre-pass: depth-tested as usual
    glDepthFunc(GL_LESS);
    glDepthMask(GL_TRUE);
    draw_objects(scene, time, lod_levels, DrawSubset::AlphaTested, camera_moved);
  }
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glBindVertexArray(0);
  glUseProgram(0);
  glDisable(GL_SCISSOR_TEST);
}

BackendCapabilities GlBackend::capabilities() const {
  const bool visibility = GlVisibilityPass::unavailable_reason(context_.features()).empty();
  return {.shadow_rays = false, .per_pixel_lens = false, .peeling = true, .visibility_buffer = visibility,
          .visibility_buffer_faster = visibility && context_.features().compute_pays(),
          .software_rasteriser = context_.features().software};
}

bool GlBackend::ensure_visibility() {
  if (!visibility_refusal_.empty()) return false;
  try {
    const std::string missing = GlVisibilityPass::unavailable_reason(context_.features());
    if (!missing.empty()) throw std::runtime_error(missing);
    if (!visibility_) visibility_ = std::make_unique<GlVisibilityPass>(light_ubo_);
    if (visibility_meshes_stale_) {
      visibility_->set_meshes(mesh_sources_);
      visibility_meshes_stale_ = false;
    }
    return true;
  } catch (const std::runtime_error& e) {
    visibility_.reset();
    visibility_refusal_ = e.what();
    std::fprintf(stderr, "fovea-render: visibility buffer off (%s): the G-buffer is shaded in the raster pass\n",
                 visibility_refusal_.c_str());
    return false;
  }
}

void GlBackend::draw_visibility(const Scene& scene, const FrameTime& time, const std::vector<std::uint8_t>& lod_levels,
                                const FrameView& frame, bool camera_moved, std::uint32_t width, std::uint32_t height,
                                const GBufferPlanes& planes, const Targets& targets) {
  const VisibilityFrame f = visibility_frame(scene, time, lod_levels, frame, camera_moved, width, height);
  visibility_->render(f.view, f.draws, targets.z, targets.width, targets.height, targets.textures, planes);
}

GlBackend::VisibilityFrame GlBackend::visibility_frame(const Scene& scene, const FrameTime& time,
                                                       const std::vector<std::uint8_t>& lod_levels,
                                                       const FrameView& frame, bool camera_moved, std::uint32_t width,
                                                       std::uint32_t height) const {
  std::vector<GlVisibilityPass::Draw> draws;
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const GpuMesh* gpu = mesh_for(i, lod_levels);
    if (gpu == nullptr) continue;
    const Object& o = scene.objects[i];
    const glm::mat4 model = o.transform_at(time.now_s).matrix();
    const glm::mat4 model_prev = o.transform_at(time.previous_s).matrix();
    draws.push_back({static_cast<std::size_t>(gpu - meshes_.data()), gpu->vao, gpu->index_count, model, model_prev,
                     o.id, &scene.materials[o.material], camera_moved || model != model_prev});
  }
  const GlVisibilityPass::View view{frame.view,
                                    frame.view_prev,
                                    frame.proj,
                                    frame.eye,
                                    width,
                                    height,
                                    {finite_or(scene.background.r, 0), finite_or(scene.background.g, 0),
                                     finite_or(scene.background.b, 0)},
                                    scene.camera.far_m,
                                    scene.ambient,
                                    light_sample_count_};
  return {view, std::move(draws)};
}

GlBackend::FrameView GlBackend::frame_view(const Camera& cam, const FrameTime& time, const LensSample& lens) {
  FrameView frame{cam.view_at(time.now_s), cam.view_at(time.previous_s), cam.projection(), cam.position_at(time.now_s)};
  if (lens.active()) move_eye_to_lens_point(cam, lens, frame);
  return frame;
}

// One view of an accumulation buffer: the eye moved to lens point p (camera right/up) and the
// frustum sheared so the plane in focus projects where the pinhole projects it: at the near
// plane n the window shifts by -p n / focus (view-space z, hence linear depth, is unchanged).
void GlBackend::move_eye_to_lens_point(const Camera& cam, const LensSample& lens, FrameView& frame) {
  const glm::vec2 p = lens.disc * static_cast<float>(lens.aperture_radius_m);
  const float n = cam.near_m, focus = static_cast<float>(lens.focus_m);
  const float ty = n * std::tan(glm::radians(cam.vertical_fov_deg) * 0.5f);
  const float tx = ty * static_cast<float>(cam.width) / static_cast<float>(cam.height);
  const float sx = p.x * n / focus, sy = p.y * n / focus;
  frame.proj = glm::frustum(-tx - sx, tx - sx, -ty - sy, ty - sy, n, cam.far_m);
  const glm::mat4 shift = glm::translate(glm::mat4(1.0f), glm::vec3(-p.x, -p.y, 0.0f));
  const glm::mat4 cam_to_world = glm::inverse(frame.view);
  frame.eye = glm::vec3(cam_to_world * glm::vec4(p.x, p.y, 0.0f, 1.0f));
  frame.view = shift * frame.view;
  frame.view_prev = shift * frame.view_prev;
}

// Binds the program and sets the uniforms shared by every object of the frame.
void GlBackend::set_frame_uniforms(const FrameView& frame, const glm::vec3& ambient, std::uint32_t width,
                                   std::uint32_t height) {
  glUseProgram(program_);
  glBindBufferBase(GL_UNIFORM_BUFFER, 0, light_ubo_);
  glUniformMatrix4fv(loc_view_, 1, GL_FALSE, glm::value_ptr(frame.view));
  glUniformMatrix4fv(loc_view_prev_, 1, GL_FALSE, glm::value_ptr(frame.view_prev));
  glUniformMatrix4fv(loc_proj_, 1, GL_FALSE, glm::value_ptr(frame.proj));
  glUniform1i(loc_light_count_, light_sample_count_);
  glUniform3fv(loc_eye_, 1, glm::value_ptr(frame.eye));
  glUniform3fv(loc_ambient_, 1, glm::value_ptr(ambient));
  glUniform2f(loc_viewport_, static_cast<float>(width), static_cast<float>(height));
  // What a mesh without PBR attributes reads (generic attribute values are context state).
  glVertexAttrib4f(2, 0, 0, 0, 1);
  glVertexAttrib4f(3, 0, 0, 0, 1);
  glVertexAttrib4f(4, 1, 1, 1, 1);
  glVertexAttrib4f(5, 0, 0, 0, 1);
}

namespace {

bool alpha_tested(const Material& m) { return m.type == MaterialType::MetallicRoughness && m.pbr.alpha_tested(); }

}  // namespace

const GlBackend::GpuMesh* GlBackend::mesh_for(std::size_t i, const std::vector<std::uint8_t>& lod_levels) const {
  if (draws_[i].mesh == kNoMesh) return nullptr;
  // The level of detail asked for (BackendSettings::lod_levels), clamped to what the object has.
  const std::size_t level = i < lod_levels.size() ? std::min<std::size_t>(lod_levels[i], draws_[i].lods.size()) : 0;
  const GpuMesh& gpu = meshes_[level == 0 ? draws_[i].mesh : draws_[i].lods[level - 1]];
  return gpu.index_count == 0 ? nullptr : &gpu;
}

namespace {

// Back-face culling for a single-sided glTF material (every other material is seen from both sides,
// as by the ray caster). A transform with a negative determinant turns the winding round (glTF
// 2.0 §3.7.4): its front faces run clockwise on screen.
void set_culling(const Material& m, const glm::mat4& model) {
  if (m.type != MaterialType::MetallicRoughness || m.pbr.double_sided) {
    glDisable(GL_CULL_FACE);
    return;
  }
  glEnable(GL_CULL_FACE);
  glCullFace(GL_BACK);
  glFrontFace(glm::determinant(glm::mat3(model)) < 0 ? GL_CW : GL_CCW);
}

}  // namespace

void GlBackend::draw_objects(const Scene& scene, const FrameTime& time, const std::vector<std::uint8_t>& lod_levels,
                             DrawSubset subset, bool camera_moved) {
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const GpuMesh* gpu = mesh_for(i, lod_levels);
    if (gpu == nullptr) continue;
    const Object& o = scene.objects[i];
    const Material& m = scene.materials[o.material];
    if (subset != DrawSubset::All && alpha_tested(m) != (subset == DrawSubset::AlphaTested)) continue;
    set_object_uniforms(o, m, time, camera_moved);
    set_material_textures(m);
    set_culling(m, o.transform_at(time.now_s).matrix());
    glBindVertexArray(gpu->vao);
    glDrawElements(GL_TRIANGLES, gpu->index_count, GL_UNSIGNED_INT, nullptr);
  }
  glDisable(GL_CULL_FACE);
}

void GlBackend::draw_depth(const Scene& scene, const FrameTime& time, const std::vector<std::uint8_t>& lod_levels,
                           const FrameView& frame) {
  glUseProgram(depth_program_);
  glUniformMatrix4fv(loc_depth_view_, 1, GL_FALSE, glm::value_ptr(frame.view));
  glUniformMatrix4fv(loc_depth_proj_, 1, GL_FALSE, glm::value_ptr(frame.proj));
  glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const GpuMesh* gpu = mesh_for(i, lod_levels);
    if (gpu == nullptr || alpha_tested(scene.materials[scene.objects[i].material])) continue;
    const glm::mat4 model = scene.objects[i].transform_at(time.now_s).matrix();
    glUniformMatrix4fv(loc_depth_model_, 1, GL_FALSE, glm::value_ptr(model));
    set_culling(scene.materials[scene.objects[i].material], model);
    glBindVertexArray(gpu->vao);
    glDrawElements(GL_TRIANGLES, gpu->index_count, GL_UNSIGNED_INT, nullptr);
  }
  glDisable(GL_CULL_FACE);
  glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
}

// The object's transform now and at the previous frame (for motion), and its material.
void GlBackend::set_object_uniforms(const Object& o, const Material& m, const FrameTime& time, bool camera_moved) {
  const glm::mat4 model = o.transform_at(time.now_s).matrix();
  const glm::mat4 model_prev = o.transform_at(time.previous_s).matrix();
  const glm::mat3 normal_matrix = glm::transpose(glm::inverse(glm::mat3(model)));
  glUniformMatrix4fv(loc_model_, 1, GL_FALSE, glm::value_ptr(model));
  glUniformMatrix4fv(loc_model_prev_, 1, GL_FALSE, glm::value_ptr(model_prev));
  glUniformMatrix3fv(loc_normal_matrix_, 1, GL_FALSE, glm::value_ptr(normal_matrix));
  // Exactly zero motion for what did not move (the shader's two projections would differ by
  // rounding, ~1e-5 px).
  glUniform1i(loc_moved_, camera_moved || model != model_prev ? 1 : 0);
  glUniform1ui(loc_object_id_, o.id);
  glUniform1i(loc_emissive_, m.type == MaterialType::Emissive ? 1 : 0);
  glUniform3fv(loc_kd_, 1, glm::value_ptr(m.kd));
  glUniform3fv(loc_ks_, 1, glm::value_ptr(m.ks));
  glUniform3fv(loc_emission_, 1, glm::value_ptr(m.emission));
  glUniform1f(loc_shininess_, m.shininess);
}

void GlBackend::render_without_readback(const FrameTime& time) {
  draw(time);
  glFinish();
}

// The settings the raster backend cannot honour, refused with the reason.
void GlBackend::check_settings(const BackendSettings& settings) {
  // settings.shadows is not supported by the raster backend in this step (no shadow maps yet):
  // shading is unshadowed local illumination regardless. The Embree backend honours it.
  if (settings.lens.active() && settings.lens.per_pixel) {
    throw std::invalid_argument(
        "OpenGL backend: a lens sample per pixel needs the ray tracer (--backend embree); the raster backend takes "
        "one lens point per render (an accumulation-buffer view)");
  }
}

void GlBackend::render_on_gpu(const FrameTime& time, const BackendSettings& settings, const GBufferPlanes& planes) {
  check_settings(settings);
  if (settings.peel > 0) {
    throw std::invalid_argument("GlBackend::render_on_gpu: a peeled layer is rendered into targets of its own and "
                                "read back (render()), not left as the frame's G-buffer");
  }
  draw(time, settings.lens, settings.lod_levels, settings.width, settings.height, planes, settings.depth_prepass,
       settings.visibility_buffer);
  image_width_ = settings.width > 0 ? settings.width : scene_->camera.width;
  image_height_ = settings.height > 0 ? settings.height : scene_->camera.height;
}

void GlBackend::render(const FrameTime& time, const BackendSettings& settings, GBuffer& out) {
  if (settings.peel > 0) {
    render_peeled(time, settings, out);
    return;
  }
  if (settings.keep_frame) {
    const GlGBufferTextures t = render_aside(time, settings);
    out.resize(t.width, t.height);
    read_back_from(asides_[aside_last_].fbo, settings.readback, out);
    return;
  }
  render_on_gpu(time, settings, GBufferPlanes::all());
  out.resize(image_width_, image_height_);
  read_back(settings.readback, out);
}

void GlBackend::render_peeled(const FrameTime& time, const BackendSettings& settings, GBuffer& out) {
  const GlPeeling& peeled = peel_on_gpu(time, settings, settings.peel);
  const Camera& cam = scene_->camera;
  out.resize(settings.width > 0 ? settings.width : cam.width, settings.height > 0 ? settings.height : cam.height);
  read_back_from(peeled.result_fbo(settings.peel), settings.readback, out);
  check_gl("GlBackend::render (peeled)");
}

void GlBackend::render_peeled_layers(const FrameTime& time, const BackendSettings& settings, std::vector<GBuffer>& out) {
  if (out.empty()) return;
  const auto layers = static_cast<std::uint32_t>(out.size());
  const GlPeeling& peeled = peel_on_gpu(time, settings, layers);
  const Camera& cam = scene_->camera;
  for (std::uint32_t n = 1; n <= layers; ++n) {
    GBuffer& g = out[n - 1];
    g.resize(settings.width > 0 ? settings.width : cam.width, settings.height > 0 ? settings.height : cam.height);
    read_back_from(peeled.result_fbo(n), settings.readback, g);
  }
  check_gl("GlBackend::render_peeled_layers");
}

const GlPeeling& GlBackend::peel_on_gpu(const FrameTime& time, const BackendSettings& settings, std::uint32_t layers) {
  const glm::uvec2 size = begin_render(settings);
  const std::uint32_t width = size.x, height = size.y;
  const Scene& scene = *scene_;
  const Camera& cam = scene.camera;
  if (!peeling_) peeling_ = std::make_unique<GlPeeling>();
  const FrameView frame = frame_view(cam, time, settings.lens);
  if (settings.peel_visibility && !pbr_scene_ && ensure_visibility()) {  // ids per draw; each layer shaded once
    const VisibilityFrame f =
        visibility_frame(scene, time, settings.lod_levels, frame, frame.view != frame.view_prev, width, height);
    const auto draw_layer = [&](unsigned fbo, const GlPeeling::Against* against) {
      visibility_->raster_peel(f.view, f.draws, fbo, against != nullptr ? against->depth : 0,
                               against != nullptr ? against->state : 0);
    };
    const auto shade = [&](unsigned visibility, const unsigned planes[5]) {
      visibility_->shade(f.view, f.draws, visibility, planes, GBufferPlanes::all());
    };
    peeling_->run_visibility(width, height, layers, draw_layer, shade);
    check_gl("GlBackend::peel_on_gpu (visibility buffer)");
    return *peeling_;
  }
  const auto clear = [&](unsigned fbo) {
    begin_gbuffer_pass(fbo, width, height, GBufferPlanes::all());
    clear_gbuffer(scene);
  };
  const auto draw_layer = [&](unsigned fbo, const GlPeeling::Against* against) {
    clear(fbo);
    set_frame_uniforms(frame, scene.ambient, width, height);
    glUniform1i(loc_peel_, against != nullptr ? 1 : 0);
    if (against != nullptr) {
      glActiveTexture(GL_TEXTURE0 + kPeelDepthUnit);
      glBindTexture(GL_TEXTURE_2D, against->depth);
      glActiveTexture(GL_TEXTURE0 + kPeelStateUnit);
      glBindTexture(GL_TEXTURE_2D, against->state);
      glActiveTexture(GL_TEXTURE0);
    }
    draw_objects(scene, time, settings.lod_levels, DrawSubset::All, frame.view != frame.view_prev);
    glUniform1i(loc_peel_, 0);
    glDisable(GL_SCISSOR_TEST);
  };
  peeling_->run(width, height, layers, draw_layer, clear);
  check_gl("GlBackend::peel_on_gpu");
  return *peeling_;
}

GlGBufferTextures GlBackend::textures() const {
  return {textures_[kColor], textures_[kDepth], textures_[kId], textures_[kNormal], textures_[kMotion],
          image_width_,      image_height_,     fb_width_,      fb_height_};
}

GpuFrame* GlBackend::gpu_frame() {
  if (!gpu_frame_) gpu_frame_ = std::make_unique<GlFrame>(*this);
  return gpu_frame_.get();
}

std::unique_ptr<Backend> make_gl_backend(GlPlatform platform, const GlContext* share) {
  return std::make_unique<GlBackend>(platform, share);
}

}  // namespace fovea::render
