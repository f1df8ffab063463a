// SPDX-License-Identifier: Apache-2.0
#include "backend/gl/gl_frame.h"

#include "passes/overlay.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "backend/gl/gl_attention.h"
#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_lee_splat.h"
#include "backend/gl/gl_ulod_blend.h"
#include "backend/gl/gl_lee_mipmap.h"
#include "backend/gl/gl_photon_gather.h"
#include "backend/gl/gl_schedl_layered.h"
#include "backend/gl/gl_program.h"

namespace fovea::render {

namespace {

// One triangle over the viewport; the fragment shaders address texels with gl_FragCoord.

// passes/tonemap.cpp on the GPU: exposure, the operator, the sRGB transfer function (the exact
// formula, as tonemap.exact=true), rounded to 8 bits here so the RGBA8 store is exact. One body for
// the fragment pass (kTonemapFragment) and the compute pass (kTonemapCompute, GL 4.3), after their
// #version line.
constexpr const char* kTonemapCommon = R"(
uniform sampler2D u_hdr;
uniform bool u_top_first;   // the uploaded HDR image has row 0 at the top
uniform int u_height;
uniform float u_exposure;
uniform int u_op;           // 0 reinhard, 1 clamp, 2 exponential
// The GI inset (GpuFrame::upload_inset), blended over the HDR input first: gi/gi_render.cpp's
// hybrid_composite, Algorithm 8.4 steps 7-8.
uniform bool u_inset;
uniform sampler2D u_inset_gi;  // its box, row 0 at the top
uniform ivec2 u_inset_origin, u_inset_size;
uniform vec2 u_inset_centre;
uniform float u_inset_radius, u_inset_fovea;
float map_operator(float v) {
  v = (isnan(v) || isinf(v)) ? 0.0 : max(v, 0.0);
  if (u_op == 0) return v / (1.0 + v);
  if (u_op == 2) return 1.0 - exp(-v);  // Jensen & Pedersen 2009, eq. 8.7
  return min(v, 1.0);
}
float srgb(float v) {
  v = clamp(v, 0.0, 1.0);
  return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}
vec3 composite(vec3 local, ivec2 image_px) {
  vec2 q = vec2(image_px) + 0.5 - u_inset_centre;
  float d = sqrt(q.x * q.x + q.y * q.y);
  if (d >= u_inset_radius) return local;  // step 7: local illumination
  ivec2 t = image_px - u_inset_origin;
  if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, u_inset_size))) return local;
  float alpha = d >= u_inset_fovea && u_inset_radius > u_inset_fovea
                    ? (d - u_inset_fovea) / (u_inset_radius - u_inset_fovea) : 0.0;  // step 8
  return alpha * local + (1.0 - alpha) * texelFetch(u_inset_gi, t, 0).rgb;
}
// The display pixel p (row 0 at the bottom) as stored.
vec4 display_pixel(ivec2 p) {
  ivec2 image_px = ivec2(p.x, u_height - 1 - p.y);
  if (u_top_first) p.y = u_height - 1 - p.y;
  vec3 hdr = texelFetch(u_hdr, p, 0).rgb;
  if (u_inset) hdr = composite(hdr, image_px);
  vec3 c = hdr * u_exposure;
  vec3 s = vec3(srgb(map_operator(c.r)), srgb(map_operator(c.g)), srgb(map_operator(c.b)));
  return vec4(floor(s * 255.0 + 0.5) / 255.0, 1.0);
}
)";

constexpr const char* kTonemapFragment = R"(
out vec4 o_color;
void main() { o_color = display_pixel(ivec2(gl_FragCoord.xy)); }
)";

// Every core of the GPU instead of its graphics ones (bench/RESULTS.md); the RGBA8 image store of
// k/255 is exact, as the fragment pass's.
constexpr const char* kTonemapCompute = R"(
layout(local_size_x = 8, local_size_y = 8) in;
layout(rgba8, binding = 0) uniform writeonly image2D u_display;
uniform int u_width;
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= u_width || p.y >= u_height) return;
  imageStore(u_display, p, display_pixel(p));
}
)";

// passes/overlay.cpp's draw_focus and draw_gaze on the GPU, in their order (the gaze-area ring over
// the gaze ring over the focus outline); pixels with nothing to draw are discarded. Coordinates are
// the image's (row 0 at the top, pixel centres at +0.5).
constexpr const char* kOverlayFragment = R"(#version 330 core
uniform usampler2D u_id;
uniform sampler2D u_depth;
uniform ivec2 u_size;
uniform bool u_gaze;
uniform vec2 u_gaze_px;
uniform vec3 u_gaze_colour;
uniform float u_ring_radius, u_area_radius;  // u_area_radius 0: none
uniform int u_focus;                          // 0 none, 1 outline u_object, 2 iso-depth line
uniform uint u_object;
uniform float u_focal_depth;
uniform float u_iso_tolerance;  // passes/overlay.h kIsoDepthTolerance
uniform vec3 u_focus_colour;
out vec4 o_color;

ivec2 texel_of(ivec2 p) { return ivec2(p.x, u_size.y - 1 - p.y); }
bool inside(ivec2 p) { return p.x >= 0 && p.y >= 0 && p.x < u_size.x && p.y < u_size.y; }
bool is_object(ivec2 p) { return inside(p) && texelFetch(u_id, texel_of(p), 0).r == u_object; }
int side(ivec2 p) {
  if (!inside(p)) return 0;
  float d = texelFetch(u_depth, texel_of(p), 0).r;
  if (texelFetch(u_id, texel_of(p), 0).r == 0u || isnan(d) || isinf(d)) return 0;
  if (abs(d - u_focal_depth) <= u_iso_tolerance * u_focal_depth) return 2;  // on the contour
  return d < u_focal_depth ? -1 : 1;
}
bool across(int here, int there) { return (there == -1 || there == 1) && there != here; }
bool ring(vec2 q, float radius, float thickness) {
  float r_out = radius + thickness / 2.0, r_in = max(0.0, radius - thickness / 2.0);
  float d = length(q - u_gaze_px);
  return d <= r_out && d >= r_in;
}
void main() {
  ivec2 p = ivec2(int(gl_FragCoord.x), u_size.y - 1 - int(gl_FragCoord.y));
  vec2 q = vec2(p) + 0.5;
  bool drawn = false;
  vec3 c = vec3(0.0);
  if (u_focus == 1 && is_object(p)) {
    bool edge = false;
    for (int d = 1; d <= 2 && !edge; ++d)
      edge = !is_object(p + ivec2(-d, 0)) || !is_object(p + ivec2(d, 0)) || !is_object(p + ivec2(0, -d)) ||
             !is_object(p + ivec2(0, d));
    if (edge) { c = u_focus_colour; drawn = true; }
  } else if (u_focus == 2) {
    int here = side(p);
    if (here != 0) {
      int right = side(p + ivec2(1, 0)), below = side(p + ivec2(0, 1));
      if (here == 2 || across(here, right) || across(here, below)) { c = u_focus_colour; drawn = true; }
    }
  }
  if (u_gaze && ring(q, u_ring_radius, 2.0)) { c = u_gaze_colour; drawn = true; }
  if (u_gaze && u_area_radius > 0.0 && ring(q, u_area_radius, 1.0)) { c = u_gaze_colour * 0.8; drawn = true; }
  if (!drawn) discard;
  o_color = vec4(floor(clamp(c, 0.0, 1.0) * 255.0 + 0.5) / 255.0, 1.0);
}
)";

// The inset's box (image pixels, y down, [x0, x1) x [y0, y1)): the circle's bounding box and one more
// pixel, clipped to the image; false when there is no area or nothing of it on the image
// (hybrid_composite's guards).
bool inset_box(glm::vec2 centre_px, float radius_px, std::uint32_t width, std::uint32_t height, glm::ivec2& origin,
               glm::ivec2& size) {
  if (!(radius_px > 0) || !std::isfinite(radius_px) || !std::isfinite(centre_px.x) || !std::isfinite(centre_px.y)) return false;
  const auto clamp_to = [](double v, std::uint32_t hi) {
    return static_cast<int>(std::clamp(v, 0.0, static_cast<double>(hi)));
  };
  const int x0 = clamp_to(static_cast<double>(std::floor(centre_px.x - radius_px)), width);
  const int x1 = clamp_to(static_cast<double>(std::ceil(centre_px.x + radius_px) + 1.0f), width);
  const int y0 = clamp_to(static_cast<double>(std::floor(centre_px.y - radius_px)), height);
  const int y1 = clamp_to(static_cast<double>(std::ceil(centre_px.y + radius_px) + 1.0f), height);
  if (x1 <= x0 || y1 <= y0) return false;
  origin = {x0, y0};
  size = {x1 - x0, y1 - y0};
  return true;
}

float fovea_px(float fovea_fraction, float radius_px) {
  return std::clamp(std::isfinite(fovea_fraction) ? fovea_fraction : 0.7f, 0.0f, 1.0f) * radius_px;
}

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

void check(const char* where) { gl::check_error("GlFrame", where); }

// The features the GPU passes need of the context, or "" when it has them all.
std::string missing_features(const GlFeatures& f) {
  if (!f.at_least(3, 3)) return "OpenGL " + f.version() + " < 3.3";
  if (!f.timer_query) return "no timer queries (GL_ARB_timer_query)";
  if (!f.sync) return "no fences (GL_ARB_sync)";
  return "";
}

}  // namespace

GlFrame::GlFrame(GlBackend& backend) : backend_(backend) {
  GlContext& context = backend_.context();
  context.make_current();
  unavailable_ = missing_features(context.features());
  if (!unavailable_.empty()) return;
  const std::string tonemap = std::string("#version 330 core\n") + kTonemapCommon + kTonemapFragment;
  tonemap_program_ = gl::link_program(gl::kFullscreenVertex, tonemap.c_str(), "GlFrame tone map");
  const GlFeatures& features = backend_.context().features();
  if (features.at_least(4, 3)) {
    const std::string compute = std::string("#version 430 core\n") + kTonemapCommon + kTonemapCompute;
    try {
      tonemap_compute_ = gl::link_compute_program(compute.c_str(), "GlFrame tone map (compute)");
    } catch (const std::runtime_error& e) {  // the fragment pass does the same; say so once
      std::fprintf(stderr, "fovea-render: the compute tone map is off (%s): the fragment pass is used\n", e.what());
    }
  }
  compute_faster_ = tonemap_compute_ != 0 && features.compute_pays();
  overlay_program_ = gl::link_program(gl::kFullscreenVertex, kOverlayFragment, "GlFrame overlay");
  glGenVertexArrays(1, &vao_);
  check("GlFrame()");
}

GlFrame::~GlFrame() {
  backend_.context().make_current();
  if (!query_pool_.empty()) glDeleteQueries(static_cast<GLsizei>(query_pool_.size()), query_pool_.data());
  for (const Timed& t : timed_) {
    glDeleteQueries(1, &t.start);
    if (t.end != 0) glDeleteQueries(1, &t.end);
  }
  if (display_fbo_ != 0) glDeleteFramebuffers(1, &display_fbo_);
  if (display_texture_ != 0) glDeleteTextures(1, &display_texture_);
  if (hdr_texture_ != 0) glDeleteTextures(1, &hdr_texture_);
  if (inset_.texture != 0) glDeleteTextures(1, &inset_.texture);
  if (vao_ != 0) glDeleteVertexArrays(1, &vao_);
  if (tonemap_program_ != 0) glDeleteProgram(tonemap_program_);
  if (tonemap_compute_ != 0) glDeleteProgram(tonemap_compute_);
  if (overlay_program_ != 0) glDeleteProgram(overlay_program_);
}

std::string GlFrame::description() const {
  const GlContext& c = backend_.context();
  return "OpenGL " + c.features().version() + " (" + c.renderer() + ")";
}

unsigned GlFrame::pooled_query() {
  unsigned query = 0;
  if (query_pool_.empty()) {
    glGenQueries(1, &query);
  } else {
    query = query_pool_.back();
    query_pool_.pop_back();
  }
  return query;
}

// GPU timestamps at the pass's start and end (glQueryCounter), not GL_TIME_ELAPSED: Mesa's llvmpipe
// answers an elapsed-time query begun before the frame's first framebuffer exists with garbage.
void GlFrame::begin_timed(const char* pass) {
  const unsigned start = pooled_query();
  glQueryCounter(start, GL_TIMESTAMP);
  timed_.push_back({pass, start, 0});
}

void GlFrame::end_timed() {
  const unsigned end = pooled_query();
  glQueryCounter(end, GL_TIMESTAMP);
  timed_.back().end = end;
}

void GlFrame::render_gbuffer(const FrameTime& time, const BackendSettings& settings, const GBufferPlanes& planes,
                             GBuffer& out) {
  backend_.context().make_current();
  hdr_source_ = HdrSource::GBuffer;
  inset_.active = false;
  begin_timed("gpu.gbuffer");
  try {
    backend_.render_on_gpu(time, settings, planes | GBufferPlanes{.color = true});
  } catch (...) {
    end_timed();
    throw;
  }
  end_timed();
  // Submit now: the GPU renders the G-buffer while the CPU runs its passes (GI traces, DOF) instead
  // of when the next command happens to flush.
  glFlush();
  const GlGBufferTextures t = backend_.textures();
  if (out.width != t.width || out.height != t.height) out.resize(t.width, t.height);
}

void GlFrame::read_back(const GBufferPlanes& planes, GBuffer& out) {
  if (planes.any()) backend_.read_back(planes, out);
}

void GlFrame::upload_hdr(const std::vector<glm::vec3>& hdr, std::uint32_t width, std::uint32_t height) {
  if (hdr.size() != std::size_t{width} * height) {
    throw std::invalid_argument("GlFrame::upload_hdr: " + std::to_string(hdr.size()) + " pixels for " +
                                std::to_string(width) + "x" + std::to_string(height));
  }
  backend_.context().make_current();
  if (hdr_texture_ == 0) {
    glGenTextures(1, &hdr_texture_);
    glBindTexture(GL_TEXTURE_2D, hdr_texture_);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  }
  glBindTexture(GL_TEXTURE_2D, hdr_texture_);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  begin_timed("gpu.upload");
  if (width != hdr_w_ || height != hdr_h_) {
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, static_cast<GLsizei>(width), static_cast<GLsizei>(height), 0, GL_RGB,
                 GL_FLOAT, hdr.data());
    hdr_w_ = width;
    hdr_h_ = height;
  } else {
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, static_cast<GLsizei>(width), static_cast<GLsizei>(height), GL_RGB,
                    GL_FLOAT, hdr.data());
  }
  end_timed();
  hdr_source_ = HdrSource::Upload;
  check("GlFrame::upload_hdr");
}

// The one place the effect passes are built: ahead of their first use when the plan says (each pass
// function asks for its own on first use too), with their compute passes where the context has GL 4.3.
void GlFrame::prepare(const Prepare& passes) {
  const bool compute = backend_.context().features().at_least(4, 3);
  if (!(passes.attention && !attention_) && !(passes.ulod_blend && !ulod_) && !(passes.lee_mipmap && !lee_mipmap_) &&
      !(passes.schedl_layered && !schedl_) && !(passes.lee_splat && !lee_splat_))
    return;
  backend_.context().make_current();
  if (passes.attention && !attention_) attention_ = std::make_unique<GlAttention>(compute);
  if (passes.ulod_blend && !ulod_) ulod_ = std::make_unique<GlUlodBlend>(compute);
  if (passes.lee_mipmap && !lee_mipmap_) lee_mipmap_ = std::make_unique<GlLeeMipmap>(compute);
  if (passes.schedl_layered && !schedl_) schedl_ = std::make_unique<GlSchedlLayered>(compute);
  if (passes.lee_splat && !lee_splat_) lee_splat_ = std::make_unique<GlLeeSplat>(compute);
  check("GlFrame::prepare");
}

// The attention passes, and which implementation runs: compute where it pays (frame.effect_passes),
// the fragment passes elsewhere.
bool GlFrame::attention_compute() {
  prepare({.attention = true});
  return attention_->has_compute() && effect_compute();
}

void GlFrame::attention_pixels(const attention::AttentionSettings& settings, double near_m, double far_m,
                               const std::vector<std::uint32_t>& ids, const std::vector<float>& motion,
                               std::vector<attention::ObjectPixels>& out) {
  backend_.context().make_current();
  const GlGBufferTextures t = backend_.textures();
  if (t.color == 0) throw std::logic_error("GlFrame::attention_pixels before the G-buffer was rendered");
  const GlAttention::Pass pass = attention_compute() ? GlAttention::Pass::Compute : GlAttention::Pass::Fragment;
  begin_timed("gpu.attention");
  attention_->run(GlAttentionInput{t.color, t.depth, t.object_id, t.width, t.height}, near_m, far_m, settings,
                  GlAttentionObjects{ids, motion}, out, pass);
  end_timed();
  check("GlFrame::attention_pixels");
}

void GlFrame::ulod_blend(const FrameTime& time, const BackendSettings& next, const std::vector<std::uint32_t>& ids,
                         const std::vector<float>& blend) {
  backend_.context().make_current();
  const GlGBufferTextures t = backend_.textures();
  if (t.color == 0) throw std::logic_error("GlFrame::ulod_blend before the G-buffer was rendered");
  prepare({.ulod_blend = true});
  BackendSettings aside = next;
  aside.width = t.width;
  aside.height = t.height;
  // Timed apart: the next levels' G-buffer (a second scene render, gpu.ulod_render) and the blend
  // itself (gpu.ulod, issue 42's "ULOD blend" target).
  begin_timed("gpu.ulod_render");
  const GlGBufferTextures n = backend_.render_aside(time, aside, GBufferPlanes{.color = true, .object_id = true});
  end_timed();
  // In place where compute pays (no copy of the colour image), or as set; the fragment pass elsewhere.
  const auto pass = ulod_->has_compute() && effect_compute() ? GlUlodBlend::Pass::Compute : GlUlodBlend::Pass::Fragment;
  begin_timed("gpu.ulod");
  ulod_->run({t.color, t.object_id, t.width, t.height}, {n.color, n.object_id, n.width, n.height}, ids, blend, pass);
  end_timed();
  check("GlFrame::ulod_blend");
}

void GlFrame::read_rect(std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1,
                        std::vector<float>& depth, std::vector<std::uint32_t>& ids) {
  backend_.read_back_rect(x0, y0, x1, y1, depth, ids);
}

void GlFrame::attention_pixels_on(const FrameTime& time, const BackendSettings& proxy,
                                  const attention::AttentionSettings& settings, double near_m, double far_m,
                                  const std::vector<std::uint32_t>& ids, const std::vector<float>& motion,
                                  std::vector<attention::ObjectPixels>& out) {
  backend_.context().make_current();
  const GlAttention::Pass pass = attention_compute() ? GlAttention::Pass::Compute : GlAttention::Pass::Fragment;
  begin_timed("gpu.attention");
  const GlGBufferTextures t = backend_.render_aside(time, proxy);
  attention_->run(GlAttentionInput{t.color, t.depth, t.object_id, t.width, t.height}, near_m, far_m, settings,
                  GlAttentionObjects{ids, motion}, out, pass);
  end_timed();
  check("GlFrame::attention_pixels_on");
}

void GlFrame::read_saliency(std::vector<float>& saliency) {
  backend_.context().make_current();
  if (!attention_) throw std::logic_error("GlFrame::read_saliency before attention_pixels");
  attention_->read_saliency(saliency);
}

void GlFrame::dof_lee_mipmap(const dof::CocModel& coc, const dof::LeeMipmapSettings& settings) {
  backend_.context().make_current();
  const GlGBufferTextures t = backend_.textures();
  if (t.color == 0) throw std::logic_error("GlFrame::dof_lee_mipmap before the G-buffer was rendered");
  prepare({.lee_mipmap = true});
  // Compute passes where they pay (no rasteriser and no framebuffer switch per level), or as set.
  const auto pass = lee_mipmap_->has_compute() && effect_compute() ? GlLeeMipmap::Pass::Compute
                                                                   : GlLeeMipmap::Pass::Fragment;
  begin_timed("gpu.dof");
  lee_mipmap_->run(GlDofInput{t.color, t.depth, t.width, t.height}, coc, settings, pass);
  end_timed();
  hdr_source_ = HdrSource::Dof;
  dof_output_ = lee_mipmap_->output();
  check("GlFrame::dof_lee_mipmap");
}

dof::SchedlStats GlFrame::dof_schedl_layered(const FrameTime& time, const BackendSettings& peel_settings,
                                             const dof::CocModel& coc, std::uint32_t layers) {
  backend_.context().make_current();
  const GlGBufferTextures t = backend_.textures();
  if (t.color == 0) throw std::logic_error("GlFrame::dof_schedl_layered before the G-buffer was rendered");
  prepare({.schedl_layered = true});
  std::vector<GlDofInput> peeled;
  if (layers > 1) {
    begin_timed("gpu.peel");
    const GlPeeling& p = backend_.peel_on_gpu(time, peel_settings, layers - 1);
    end_timed();
    for (std::uint32_t n = 1; n < layers; ++n) peeled.push_back({p.result_color(n), p.result_depth(n), t.width, t.height});
  }
  begin_timed("gpu.dof");
  const auto pass = schedl_->has_compute() && effect_compute() ? GlSchedlLayered::Pass::Compute
                                                               : GlSchedlLayered::Pass::Fragment;
  const dof::SchedlStats stats = schedl_->run(GlDofInput{t.color, t.depth, t.width, t.height}, peeled, coc, {}, pass);
  end_timed();
  hdr_source_ = HdrSource::Dof;
  dof_output_ = schedl_->output();
  check("GlFrame::dof_schedl_layered");
  return stats;
}

void GlFrame::dof_lee_splat(const FrameTime& time, const BackendSettings& peel_settings, const dof::CocModel& coc,
                            const dof::LeeSplatSettings& settings) {
  backend_.context().make_current();
  const GlGBufferTextures t = backend_.textures();
  if (t.color == 0) throw std::logic_error("GlFrame::dof_lee_splat before the G-buffer was rendered");
  prepare({.lee_splat = true});
  // The tiled gather where compute pays (no rasteriser, no blending), or as set; the quads elsewhere.
  const auto pass = lee_splat_->has_compute() && effect_compute() ? GlLeeSplat::Pass::Compute
                                                                  : GlLeeSplat::Pass::Fragment;
  GlDofInput hidden{};
  if (settings.use_hidden) {  // Lee §5.1.2's hidden image: the first layer behind the visible one
    begin_timed("gpu.peel");
    const GlPeeling& p = backend_.peel_on_gpu(time, peel_settings, 1);
    end_timed();
    hidden = {p.result_color(1), p.result_depth(1), t.width, t.height};
  }
  begin_timed("gpu.dof");
  lee_splat_->run(GlDofInput{t.color, t.depth, t.width, t.height}, settings.use_hidden ? &hidden : nullptr, coc, settings,
                  pass);
  end_timed();
  hdr_source_ = HdrSource::Dof;
  dof_output_ = lee_splat_->output();
  check("GlFrame::dof_lee_splat");
}

unsigned GlFrame::hdr_input() const {
  switch (hdr_source_) {
    case HdrSource::Upload: return hdr_texture_;
    case HdrSource::Dof: return dof_output_;
    case HdrSource::GBuffer: break;
  }
  return backend_.textures().color;
}

void GlFrame::read_hdr(std::vector<glm::vec3>& hdr) {
  backend_.context().make_current();
  const GlGBufferTextures t = backend_.textures();
  hdr.assign(std::size_t{t.width} * t.height, glm::vec3(0.0f));
  if (t.color == 0 || hdr.empty()) return;
  // The whole texture (the G-buffer's may be larger than the image), then its lower-left image.
  GLint tw = 0, th = 0;
  glBindTexture(GL_TEXTURE_2D, hdr_input());
  glGetTexLevelParameteriv(GL_TEXTURE_2D, 0, GL_TEXTURE_WIDTH, &tw);
  glGetTexLevelParameteriv(GL_TEXTURE_2D, 0, GL_TEXTURE_HEIGHT, &th);
  std::vector<float> texels(static_cast<std::size_t>(tw) * static_cast<std::size_t>(th) * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_FLOAT, texels.data());
  const bool top_first = hdr_source_ == HdrSource::Upload;
  for (std::uint32_t y = 0; y < t.height; ++y) {
    const std::uint32_t row = top_first ? y : t.height - 1 - y;
    for (std::uint32_t x = 0; x < t.width; ++x) {
      const float* p = &texels[(std::size_t{row} * static_cast<std::size_t>(tw) + x) * 4];
      hdr[std::size_t{y} * t.width + x] = {p[0], p[1], p[2]};
    }
  }
  check("GlFrame::read_hdr");
}

void GlFrame::upload_inset(const std::vector<glm::vec3>& gi, std::uint32_t width, std::uint32_t height,
                           glm::vec2 centre_px, float radius_px, float fovea_fraction) {
  if (gi.size() != std::size_t{width} * height) {
    throw std::invalid_argument("GlFrame::upload_inset: " + std::to_string(gi.size()) + " pixels for " +
                                std::to_string(width) + "x" + std::to_string(height));
  }
  inset_.active = false;
  glm::ivec2 origin, size;
  if (!inset_box(centre_px, radius_px, width, height, origin, size)) return;
  const int x0 = origin.x, y0 = origin.y, x1 = origin.x + size.x, y1 = origin.y + size.y;
  backend_.context().make_current();
  if (inset_.texture == 0) {
    glGenTextures(1, &inset_.texture);
    glBindTexture(GL_TEXTURE_2D, inset_.texture);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  }
  glBindTexture(GL_TEXTURE_2D, inset_.texture);
  begin_timed("gpu.upload");
  // The box alone, straight from the full image: rows of `width` pixels, starting at (x0, y0).
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glPixelStorei(GL_UNPACK_ROW_LENGTH, static_cast<GLint>(width));
  glPixelStorei(GL_UNPACK_SKIP_PIXELS, x0);
  glPixelStorei(GL_UNPACK_SKIP_ROWS, y0);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, x1 - x0, y1 - y0, 0, GL_RGB, GL_FLOAT, gi.data());
  glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
  glPixelStorei(GL_UNPACK_SKIP_PIXELS, 0);
  glPixelStorei(GL_UNPACK_SKIP_ROWS, 0);
  end_timed();
  check("GlFrame::upload_inset");
  inset_ = Inset{true, inset_.texture, inset_.texture, origin, size, centre_px, radius_px, fovea_px(fovea_fraction, radius_px)};
}

std::string GlFrame::gi_gather_unavailable(std::size_t photons) const {
  return GlPhotonGather::unavailable_reason(backend_.context().features(), photons);
}

void GlFrame::gi_gather(const GpuGiGather& gather) {
  backend_.context().make_current();
  const GlGBufferTextures t = backend_.textures();
  if (t.color == 0) throw std::logic_error("GlFrame::gi_gather before the G-buffer was rendered");
  if (gather.traced != nullptr && gather.traced->size() != std::size_t{t.width} * t.height) {
    throw std::invalid_argument("GlFrame::gi_gather: " + std::to_string(gather.traced->size()) + " traced pixels for " +
                                std::to_string(t.width) + "x" + std::to_string(t.height));
  }
  inset_.active = false;
  glm::ivec2 origin, size;
  if (!inset_box(gather.centre_px, gather.radius_px, t.width, t.height, origin, size)) return;
  if (!gather_) {
    const std::string why = gi_gather_unavailable(0);
    if (!why.empty()) throw std::logic_error("GlFrame::gi_gather: " + why);
    gather_ = std::make_unique<GlPhotonGather>(backend_.context().features());
  }
  begin_timed("gpu.gi");
  gather_->run({t.color, t.depth, t.object_id, t.normal, t.width, t.height}, gather, origin, size);
  end_timed();
  check("GlFrame::gi_gather");
  inset_ = Inset{true, inset_.texture, gather_->output(), origin, size, gather.centre_px, gather.radius_px,
                 fovea_px(gather.fovea_fraction, gather.radius_px)};
}

void GlFrame::read_gi_labels(std::vector<std::uint8_t>& used, std::vector<double>& traditional,
                             std::vector<double>& gaze) {
  backend_.context().make_current();
  used.clear();
  traditional.clear();
  gaze.clear();
  if (gather_) gather_->read_labels(used, traditional, gaze);
}

void GlFrame::read_gi(std::vector<glm::vec3>& gi) {
  backend_.context().make_current();
  const GlGBufferTextures t = backend_.textures();
  gi.assign(std::size_t{t.width} * t.height, glm::vec3(0.0f));
  if (!gather_ || !inset_.active || inset_.shown != gather_->output()) return;
  std::vector<glm::vec3> box;
  gather_->read(box);
  for (int y = 0; y < inset_.size.y; ++y)
    for (int x = 0; x < inset_.size.x; ++x)
      gi[std::size_t(inset_.origin.y + y) * t.width + std::size_t(inset_.origin.x + x)] =
          box[std::size_t(y) * std::size_t(inset_.size.x) + std::size_t(x)];
}

void GlFrame::ensure_display(std::uint32_t tw, std::uint32_t th) {
  if (display_texture_ != 0 && tw == display_tw_ && th == display_th_) return;
  if (display_fbo_ == 0) glGenFramebuffers(1, &display_fbo_);
  if (display_texture_ != 0) glDeleteTextures(1, &display_texture_);
  glGenTextures(1, &display_texture_);
  glBindTexture(GL_TEXTURE_2D, display_texture_);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, static_cast<GLsizei>(tw), static_cast<GLsizei>(th), 0, GL_RGBA,
               GL_UNSIGNED_BYTE, nullptr);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glBindFramebuffer(GL_FRAMEBUFFER, display_fbo_);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, display_texture_, 0);
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    throw std::runtime_error("GlFrame: display framebuffer incomplete (status " + std::to_string(status) + ")");
  }
  display_tw_ = tw;
  display_th_ = th;
}

bool GlFrame::effect_compute(GpuPass asked) const {
  if (!backend_.context().features().at_least(4, 3)) return false;
  return asked == GpuPass::Compute || (asked == GpuPass::Auto && compute_faster_);
}

std::string GlFrame::effect_passes(GpuPass asked) const {
  if (effect_compute(asked)) return "compute";
  if (asked == GpuPass::Fragment) return "fragment";
  if (!backend_.context().features().at_least(4, 3)) {
    return "fragment: compute passes need OpenGL 4.3, this context is " + backend_.context().features().version();
  }
  return "fragment: frame.effect_passes=auto on a software rasteriser";
}

// Binds the display image's framebuffer over the image's part of it, with `program`.
void GlFrame::begin_fullscreen_pass(unsigned program) {
  const GlGBufferTextures t = backend_.textures();
  ensure_display(t.texture_width, t.texture_height);
  glBindFramebuffer(GL_FRAMEBUFFER, display_fbo_);
  glViewport(0, 0, static_cast<GLsizei>(t.width), static_cast<GLsizei>(t.height));
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_BLEND);
  glUseProgram(program);
  glBindVertexArray(vao_);
}

void GlFrame::tonemap(const GpuTonemap& params) {
  backend_.context().make_current();
  const GlGBufferTextures t = backend_.textures();
  if (t.color == 0) throw std::logic_error("GlFrame::tonemap before the G-buffer was rendered");
  const bool uploaded = hdr_source_ == HdrSource::Upload;
  if (uploaded && (hdr_w_ != t.width || hdr_h_ != t.height)) {
    throw std::invalid_argument("GlFrame::tonemap: the uploaded HDR image is " + std::to_string(hdr_w_) + "x" +
                                std::to_string(hdr_h_) + ", the G-buffer " + std::to_string(t.width) + "x" +
                                std::to_string(t.height));
  }
  const bool compute = params.pass == GpuTonemap::Pass::Compute ? tonemap_compute_ != 0
                       : params.pass == GpuTonemap::Pass::Auto  ? tonemap_compute_ != 0 && effect_compute()
                                                                : false;
  if (params.pass == GpuTonemap::Pass::Compute && !compute) {
    throw std::invalid_argument("GlFrame::tonemap: a compute pass needs OpenGL 4.3, this context is " +
                                backend_.context().features().version());
  }
  const unsigned program = compute ? tonemap_compute_ : tonemap_program_;
  begin_timed("gpu.tonemap");
  begin_fullscreen_pass(program);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, hdr_input());
  const auto loc = [program](const char* name) { return glGetUniformLocation(program, name); };
  glUniform1i(loc("u_hdr"), 0);
  glUniform1i(loc("u_top_first"), uploaded ? 1 : 0);
  glUniform1i(loc("u_height"), static_cast<GLint>(t.height));
  glUniform1f(loc("u_exposure"), params.exposure);
  glUniform1i(loc("u_op"), static_cast<GLint>(params.op));
  glUniform1i(loc("u_inset"), inset_.active ? 1 : 0);
  if (inset_.active) {
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, inset_.shown);
    glUniform1i(loc("u_inset_gi"), 1);
    glActiveTexture(GL_TEXTURE0);
    glUniform2i(loc("u_inset_origin"), inset_.origin.x, inset_.origin.y);
    glUniform2i(loc("u_inset_size"), inset_.size.x, inset_.size.y);
    glUniform2f(loc("u_inset_centre"), inset_.centre.x, inset_.centre.y);
    glUniform1f(loc("u_inset_radius"), inset_.radius);
    glUniform1f(loc("u_inset_fovea"), inset_.fovea);
  }
  if (compute) {
    glUniform1i(loc("u_width"), static_cast<GLint>(t.width));
    glBindImageTexture(0, display_texture_, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA8);
    glDispatchCompute((t.width + 7) / 8, (t.height + 7) / 8, 1);
    // The overlay draws into the display image next, the viewer samples it, read_display reads it.
    glMemoryBarrier(GL_FRAMEBUFFER_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT | GL_PIXEL_BUFFER_BARRIER_BIT |
                    GL_TEXTURE_UPDATE_BARRIER_BIT);
    glBindImageTexture(0, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA8);
  } else {
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }
  end_timed();
  check("GlFrame::tonemap");
}

void GlFrame::overlay(const GpuOverlay& o) {
  if (!o.any()) return;
  backend_.context().make_current();
  const GlGBufferTextures t = backend_.textures();
  begin_timed("gpu.overlay");
  begin_fullscreen_pass(overlay_program_);
  const unsigned p = overlay_program_;
  const auto loc = [p](const char* name) { return glGetUniformLocation(p, name); };
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, t.object_id);
  glUniform1i(loc("u_id"), 0);
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_2D, t.depth);
  glUniform1i(loc("u_depth"), 1);
  glActiveTexture(GL_TEXTURE0);
  glUniform2i(loc("u_size"), static_cast<GLint>(t.width), static_cast<GLint>(t.height));
  glUniform1i(loc("u_gaze"), o.gaze ? 1 : 0);
  glUniform2f(loc("u_gaze_px"), static_cast<float>(o.gaze_x * t.width), static_cast<float>(o.gaze_y * t.height));
  const glm::vec3 gaze_colour = o.gaze_valid ? glm::vec3(1.0f, 0.15f, 0.1f) : glm::vec3(0.6f);
  glUniform3f(loc("u_gaze_colour"), gaze_colour.r, gaze_colour.g, gaze_colour.b);
  glUniform1f(loc("u_ring_radius"), static_cast<float>(o.ring_diameter_px / 2));
  glUniform1f(loc("u_area_radius"), static_cast<float>(o.area_diameter_px / 2));
  glUniform1i(loc("u_focus"), static_cast<GLint>(o.focus));
  glUniform1ui(loc("u_object"), o.focus_object);
  glUniform1f(loc("u_focal_depth"), static_cast<float>(o.focal_depth_m));
  glUniform1f(loc("u_iso_tolerance"), static_cast<float>(kIsoDepthTolerance));
  const glm::vec3 focus_colour = o.focus_in_transition ? glm::vec3(0.2f, 0.85f, 1.0f) : glm::vec3(1.0f, 0.85f, 0.1f);
  glUniform3f(loc("u_focus_colour"), focus_colour.r, focus_colour.g, focus_colour.b);
  if (o.focus == GpuOverlay::Focus::None) {
    // Only the rings: shade their bounding box, not the whole image (as draw_gaze's loops do).
    const double r = std::max(o.ring_diameter_px / 2 + 1.0, o.area_diameter_px / 2 + 0.5) + 1.0;
    const double cx = o.gaze_x * t.width, cy = o.gaze_y * t.height;
    // A non-finite gaze point (never sent by the decoder, but not this pass's to assume) draws nothing.
    const auto clampi = [](double v, std::uint32_t hi) {
      return std::isfinite(v) ? static_cast<GLint>(std::clamp(v, 0.0, static_cast<double>(hi))) : 0;
    };
    const GLint x0 = clampi(std::floor(cx - r), t.width), x1 = clampi(std::ceil(cx + r), t.width);
    const GLint y0 = clampi(std::floor(t.height - (cy + r)), t.height), y1 = clampi(std::ceil(t.height - (cy - r)), t.height);
    glEnable(GL_SCISSOR_TEST);
    glScissor(x0, y0, x1 - x0, y1 - y0);
  }
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glDisable(GL_SCISSOR_TEST);
  end_timed();
  check("GlFrame::overlay");
}

GpuCompletion GlFrame::finish() {
  backend_.context().make_current();
  glBindVertexArray(0);
  glUseProgram(0);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  GLsync fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  GpuCompletion done;
  GLenum waited = GL_TIMEOUT_EXPIRED;
  while (waited == GL_TIMEOUT_EXPIRED) waited = glClientWaitSync(fence, GL_SYNC_FLUSH_COMMANDS_BIT, 100'000'000);
  done.wall_s = steady_seconds();
  glDeleteSync(fence);
  if (waited == GL_WAIT_FAILED) throw std::runtime_error("GlFrame::finish: glClientWaitSync failed");
  for (const Timed& t : timed_) {
    GLuint64 start = 0, end = 0;
    glGetQueryObjectui64v(t.start, GL_QUERY_RESULT, &start);
    glGetQueryObjectui64v(t.end, GL_QUERY_RESULT, &end);
    done.pass_ms.emplace_back(t.pass, end >= start ? static_cast<double>(end - start) * 1e-6 : 0.0);
    query_pool_.push_back(t.start);
    query_pool_.push_back(t.end);
  }
  timed_.clear();
  check("GlFrame::finish");
  return done;
}

void GlFrame::read_display(std::vector<std::uint8_t>& rgb, std::uint32_t& width, std::uint32_t& height) {
  backend_.context().make_current();
  const GlGBufferTextures t = backend_.textures();
  width = t.width;
  height = t.height;
  rgb.resize(std::size_t{width} * height * 3);
  if (display_fbo_ == 0 || width == 0 || height == 0) return;
  rgba_scratch_.resize(std::size_t{width} * height * 4);
  glBindFramebuffer(GL_FRAMEBUFFER, display_fbo_);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, static_cast<GLsizei>(width), static_cast<GLsizei>(height), GL_RGBA, GL_UNSIGNED_BYTE,
               rgba_scratch_.data());
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  for (std::uint32_t y = 0; y < height; ++y) {
    const std::uint8_t* src = &rgba_scratch_[std::size_t{height - 1 - y} * width * 4];
    std::uint8_t* dst = &rgb[std::size_t{y} * width * 3];
    for (std::uint32_t x = 0; x < width; ++x) std::memcpy(dst + 3 * x, src + 4 * x, 3);
  }
  check("GlFrame::read_display");
}

GpuFrame::Texture GlFrame::display_texture() const {
  const GlGBufferTextures t = backend_.textures();
  return {display_texture_, t.width, t.height, display_tw_, display_th_};
}

}  // namespace fovea::render
