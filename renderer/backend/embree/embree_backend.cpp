// SPDX-License-Identifier: Apache-2.0
// The Embree G-buffer backend (embree_backend.h): its device, render() as a tile pass (camera
// frame, per-object matrices, each tile's primary rays resolved into texels, shaded with
// scene/shading.h) and the world-space rays of intersect() and occluded(). The geometry is built
// in embree_scene.cpp, the rays traced in embree_rays.cpp.
#include "backend/embree/embree_backend.h"

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "backend/embree/embree_rays.h"
#include "backend/embree/embree_scene.h"
#include "scene/shading.h"

namespace fovea::render {

using namespace embree_detail;

const char* to_string(EmbreeTraversal t) {
  switch (t) {
    case EmbreeTraversal::Single: return "single";
    case EmbreeTraversal::Packet4: return "packet4";
    case EmbreeTraversal::Packet8: return "packet8";
    case EmbreeTraversal::Packet16: return "packet16";
    case EmbreeTraversal::Stream: return "stream";
  }
  return "?";
}

const char* to_string(EmbreeGeometry g) {
  switch (g) {
    case EmbreeGeometry::Flattened: return "flattened";
    case EmbreeGeometry::Instanced: return "instanced";
  }
  return "?";
}

namespace {

// v / |v|, or false when v has no usable direction (zero, denormal-tiny, Inf or NaN).
bool normalize_checked(glm::vec3& v) {
  const float len2 = glm::dot(v, v);
  if (!(len2 > 1e-30f) || !std::isfinite(len2)) return false;
  v *= 1.0f / std::sqrt(len2);
  return finite(v);
}

// m * (p, 1), written out so it inlines (glm's operator* does not always at -O2; it was a quarter
// of the frame time in a profile of the geometry-only G-buffer).
inline glm::vec3 transform_point(const glm::mat4& m, const glm::vec3& p) {
  return glm::vec3(m[0]) * p.x + glm::vec3(m[1]) * p.y + glm::vec3(m[2]) * p.z + glm::vec3(m[3]);
}
inline glm::vec4 transform_point4(const glm::mat4& m, const glm::vec3& p) {
  return m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3];
}
inline glm::vec3 transform_vector(const glm::mat3& m, const glm::vec3& v) { return m[0] * v.x + m[1] * v.y + m[2] * v.z; }

// Image position in pixels (x right, y down, pixel centres at +0.5) of an object-space point under
// an object -> clip matrix, or false if the point is at or behind the camera plane.
inline bool to_pixels(const glm::mat4& object_to_clip, const glm::vec3& p, const Frame& f, glm::vec2& px) {
  const glm::vec4 clip = transform_point4(object_to_clip, p);
  if (!(clip.w > 1e-6f)) return false;
  const float ndc_x = clip.x / clip.w, ndc_y = clip.y / clip.w;
  px = {(ndc_x + 1.0f) * 0.5f * static_cast<float>(f.width), (1.0f - ndc_y) * 0.5f * static_cast<float>(f.height)};
  return std::isfinite(px.x) && std::isfinite(px.y);
}

}  // namespace

EmbreeBackend::EmbreeBackend(EmbreeOptions options) : options_(options), impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice(nullptr);
  if (impl_->device == nullptr) {
    throw std::runtime_error("embree backend: rtcNewDevice failed (error " + std::to_string(rtcGetDeviceError(nullptr)) + ")");
  }
  rtcSetDeviceErrorFunction(impl_->device, &Impl::on_error, impl_.get());
}

EmbreeBackend::~EmbreeBackend() = default;

EmbreeFrameStats EmbreeBackend::last_frame_stats() const { return impl_->stats; }

namespace {

// The G-buffer's size: BackendSettings' override, else the camera's.
struct ImageSize {
  std::uint32_t width = 0, height = 0;
};

// Sizes `out` for the frame.
ImageSize fit_gbuffer(const Camera& cam, const BackendSettings& settings, GBuffer& out) {
  const std::uint32_t width = settings.width > 0 ? settings.width : cam.width;
  const std::uint32_t height = settings.height > 0 ? settings.height : cam.height;
  // render() writes every texel, so a buffer of the right size is reused without clearing.
  const std::size_t texels = std::size_t{width} * height;
  if (out.width != width || out.height != height || out.color.size() != texels || out.depth.size() != texels ||
      out.object_id.size() != texels || out.normal.size() != texels || out.motion.size() != texels) {
    out.resize(width, height);
  }
  return {width, height};
}

// A texel no object covers: the background at the far plane, no object, normal or motion.
struct BackgroundTexel {
  GBuffer& out;
  const Camera& cam;
  glm::vec3 background;
  void operator()(std::size_t i) const {
    out.color[i] = background;
    out.depth[i] = std::isfinite(cam.far_m) ? cam.far_m : std::numeric_limits<float>::max();
    out.object_id[i] = 0;
    out.normal[i] = glm::vec3(0.0f);
    out.motion[i] = glm::vec2(0.0f);
  }
};

// Camera frame: eye and axes from the inverse view matrix, image-plane half-extents at view depth 1,
// clip range and thin lens. False for a degenerate camera (up parallel to the view axis, bad FOV),
// which renders background.
bool camera_frame(const Camera& cam, const glm::mat4& view, const BackendSettings& settings, ImageSize size,
                  Frame& f) {
  f.width = size.width;
  f.height = size.height;
  const glm::mat4 cam_to_world = glm::inverse(view);
  const float tan_half = std::tan(glm::radians(cam.vertical_fov_deg) * 0.5f);
  const float aspect = static_cast<float>(cam.width) / static_cast<float>(cam.height);
  f.eye = glm::vec3(cam_to_world[3]);
  f.right = glm::vec3(cam_to_world[0]);
  f.up = glm::vec3(cam_to_world[1]);
  f.back = glm::vec3(cam_to_world[2]);
  f.tan_x = tan_half * aspect;
  f.tan_y = tan_half;
  f.cone_spread = std::atan(2.0f * tan_half / static_cast<float>(std::max(1u, size.height)));
  f.near_m = std::max(0.0f, cam.near_m);
  f.far_m = cam.far_m;
  f.lens = settings.lens;
  f.lens_on = settings.lens.active();
  f.lens_radius = static_cast<float>(settings.lens.aperture_radius_m);
  f.focus = static_cast<float>(settings.lens.focus_m);
  return finite(view) && finite(cam_to_world) && std::isfinite(tan_half) && tan_half > 0 && std::isfinite(f.tan_x) &&
         std::isfinite(f.far_m) && f.far_m > f.near_m;
}

// Per-object matrices of the frame (ObjectFrame): the committed model matrix and its cofactor, and
// for motion vectors object -> clip now and at the previous frame's time.
void object_frames(const EmbreeBackend::Impl& im, const Camera& cam, const glm::mat4& view, const FrameTime& time,
                   Frame& f) {
  const Scene& s = im.scene;
  f.motion = time.previous_s != time.now_s;
  const glm::mat4 proj = cam.projection();
  f.view_proj_now = proj * view;
  f.view_proj_prev = proj * cam.view_at(time.previous_s);
  if (!finite(f.view_proj_now) || !finite(f.view_proj_prev)) f.motion = false;
  f.objects.resize(im.records.size());
  for (std::size_t k = 0; k < im.records.size(); ++k) {
    const Object& o = s.objects[im.records[k].object];
    ObjectFrame& of = f.objects[k];
    of.model_now = im.records[k].committed;
    of.normal_now = cofactor(of.model_now);
    if (f.motion) {
      of.clip_now = f.view_proj_now * of.model_now;
      of.clip_prev = f.view_proj_prev * o.transform_at(time.previous_s).matrix();
      // Static object under a static camera: motion is exactly 0, skip the reprojection.
      of.moves = of.clip_now != of.clip_prev && finite(of.clip_prev) && finite(of.clip_now);
    }
  }
}

// What the tile pass reads, fixed for the frame; only `out`, im.shadow_rays and the per-task
// ShadowContext are written.
struct TilePass {
  EmbreeBackend::Impl& im;
  const Frame& f;
  GBuffer& out;
  const BackgroundTexel& fill_background;
  const std::vector<std::uint8_t>& pixel_mask;
  bool masked = false;  // pixel_mask covers the image: tiles without a marked pixel get background
  RTCScene top = nullptr;
  EmbreeTraversal traversal = EmbreeTraversal::Single;
  std::uint32_t peel = 0;
  bool instanced = false;
  bool shade = true;
  VisibilityFn visibility = nullptr;
};

// True if the tile [x0, x1) x [y0, y1) has a pixel marked in BackendSettings::pixel_mask.
inline bool tile_marked(const TilePass& pass, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1) {
  for (std::uint32_t y = y0; y < y1; ++y)
    for (std::uint32_t x = x0; x < x1; ++x)
      if (pass.pixel_mask[pass.out.index(x, y)] != 0) return true;
  return false;
}

// The tile's primary hits with the chosen traversal, or the peeled layer when peel > 0.
inline void trace_tile(const TilePass& pass, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1,
                       TileHits& hits) {
  const RTCScene top = pass.top;
  const Frame& f = pass.f;
  if (pass.peel > 0) {
    trace_peeled(top, f, x0, y0, x1, y1, pass.instanced, pass.peel, hits);
  } else {
    switch (pass.traversal) {
    case EmbreeTraversal::Single: trace_single(top, f, x0, y0, x1, y1, hits); break;
    case EmbreeTraversal::Packet4: trace_packets<4>(top, f, x0, y0, x1, y1, hits); break;
    case EmbreeTraversal::Packet8: trace_packets<8>(top, f, x0, y0, x1, y1, hits); break;
    case EmbreeTraversal::Packet16: trace_packets<16>(top, f, x0, y0, x1, y1, hits); break;
    case EmbreeTraversal::Stream: trace_stream(top, f, x0, y0, x1, y1, hits); break;
    }
  }
}

// A hit's triangle and barycentrics (u, v weigh vertices 1 and 2, w = 1 - u - v vertex 0).
struct HitVertices {
  const PreparedMesh& m;
  std::uint32_t i0, i1, i2;
  float u, v, w;
  template <class T>
  T at(const std::vector<T>& a) const { return w * a[i0] + u * a[i1] + v * a[i2]; }
};

// The hit as a PBR material reads it: texture coordinates, colour, the front side's normal and
// tangent frame, and each coordinate set's level of detail from the primary ray's cone
// (Akenine-Möller et al. 2019, §3.4): spread angle (primary rays: atan(2 tan(fov/2) / height) per
// pixel; 0 samples the base level), width
// W = spread t at distance t, level log2(W / |n.d|) + 0.5 log2(uv area / world area) (eq. 34, the
// texture's own 0.5 log2(w h) added when sampling). t is the ray's length, not view depth.
SurfacePoint surface_point(float spread, const ObjectFrame& of, const HitVertices& hv, const glm::vec3& p,
                           const glm::vec3& front_normal, bool back_face, const glm::vec3& dir, float t) {
  const PreparedMesh& m = hv.m;
  SurfacePoint sp;
  sp.position = p;
  sp.normal = front_normal;
  sp.back_face = back_face;
  if (!m.colors.empty()) sp.color = hv.at(m.colors);
  const glm::vec3 p0 = m.positions[hv.i0], p1 = m.positions[hv.i1], p2 = m.positions[hv.i2];
  const float world_area = glm::length(transform_vector(of.normal_now, glm::cross(p1 - p0, p2 - p0)));
  const float dir_len = glm::length(dir);
  const float cos_view = std::max(1e-4f, std::abs(glm::dot(front_normal, dir)) / std::max(dir_len, 1e-30f));
  const float cone = std::log2(std::max(spread * t * dir_len, 1e-30f) / cos_view);
  for (std::uint32_t set = 0; set < 2; ++set) {
    const auto& tc = m.texcoords[set];
    if (tc.empty()) continue;
    sp.uv[set] = hv.at(tc);
    const glm::vec2 e1 = tc[hv.i1] - tc[hv.i0], e2 = tc[hv.i2] - tc[hv.i0];
    const float uv_area = std::abs(e1.x * e2.y - e2.x * e1.y);
    sp.lod[set] = uv_area > 0 && world_area > 0 ? cone + 0.5f * std::log2(uv_area / world_area) : -100.0f;
    if (!std::isfinite(sp.lod[set])) sp.lod[set] = 0;
  }
  if (!m.tangents.empty()) {
    // Tangent and bitangent lie in the surface: they transform with the model matrix, and the
    // handedness is read back against the world normal (a mirroring transform flips it).
    const glm::vec4 t4 = hv.at(m.tangents);
    const glm::vec3 n_obj = m.normals.empty() ? glm::cross(p1 - p0, p2 - p0) : hv.at(m.normals);
    const glm::vec3 b_obj = glm::cross(n_obj, glm::vec3(t4)) * (t4.w < 0 ? -1.0f : 1.0f);
    const glm::mat3 model(of.model_now);
    const glm::vec3 tw = transform_vector(model, glm::vec3(t4)), bw = transform_vector(model, b_obj);
    sp.tangent = glm::vec4(tw, glm::dot(glm::cross(front_normal, tw), bw) < 0 ? -1.0f : 1.0f);
  }
  return sp;
}

// Turns one traced hit into G-buffer texels.
inline void resolve_hit(const TilePass& pass, const Hit& h, std::uint32_t x, std::uint32_t y, ShadowContext& shadow) {
  const EmbreeBackend::Impl& im = pass.im;
  const Scene& s = im.scene;
  const Frame& f = pass.f;
  GBuffer& out = pass.out;
  const std::size_t i = out.index(x, y);
  const unsigned id = pass.instanced ? h.inst : h.geom;
  if (h.geom == kInvalidId || id >= im.records.size() || !std::isfinite(h.t)) {
    pass.fill_background(i);
    return;
  }
  const ObjectRecord& r = im.records[id];
  const PreparedMesh& m = *r.mesh;
  if (h.prim >= m.triangle_count()) {
    pass.fill_background(i);
    return;
  }
  const ObjectFrame& of = f.objects[id];
  const std::uint32_t i0 = m.indices[3 * std::size_t{h.prim}], i1 = m.indices[3 * std::size_t{h.prim} + 1],
                      i2 = m.indices[3 * std::size_t{h.prim} + 2];
  const float u = h.u, v = h.v, w = 1.0f - u - v;
  glm::vec3 origin, dir;
  f.ray(x, y, origin, dir);

  // The hit in object space, from the barycentrics: exact on the triangle, and the same point
  // the motion vector follows back in time.
  const glm::vec3 p_obj = w * m.positions[i0] + u * m.positions[i1] + v * m.positions[i2];
  glm::vec3 p = transform_point(of.model_now, p_obj);
  if (!finite(p)) p = origin + h.t * dir;

  // Shading normal: interpolated vertex normals, else the face normal, else towards the eye.
  glm::vec3 n_obj = m.normals.empty() ? glm::vec3(0.0f) : w * m.normals[i0] + u * m.normals[i1] + v * m.normals[i2];
  if (!normalize_checked(n_obj)) {
    n_obj = glm::cross(m.positions[i1] - m.positions[i0], m.positions[i2] - m.positions[i0]);
    if (!normalize_checked(n_obj)) n_obj = glm::vec3(0.0f);
  }
  glm::vec3 n = transform_vector(of.normal_now, n_obj);
  if (!normalize_checked(n)) {
    n = -dir;
    if (!normalize_checked(n)) n = f.back;
  }
  const bool back_face = glm::dot(n, dir) > 0.0f;
  if (back_face) n = -n;  // face the eye

  out.depth[i] = h.t;  // view-axis depth: the ray direction has unit length along the view axis
  out.object_id[i] = s.objects[r.object].id;
  out.normal[i] = n;
  glm::vec3 color(0.0f);
  if (pass.shade) {
    // Push shadow-ray origins off the surface by a distance relative to the coordinates' size
    // (float spacing grows with magnitude).
    const float scale = std::max({1.0f, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
    shadow.epsilon = 1e-4f * scale;
    shadow.offset = n * shadow.epsilon;
    if (r.material->type == MaterialType::MetallicRoughness) {
      const HitVertices hv{m, i0, i1, i2, u, v, w};
      const SurfacePoint point = surface_point(f.cone_spread, of, hv, p, back_face ? -n : n, back_face, dir, h.t);
      color = shade_pbr(s, evaluate_pbr(s, r.material->pbr, point), p, origin, pass.visibility, &shadow);
    } else {
      color = shade_local(s, *r.material, p, n, origin, pass.visibility, &shadow);
    }
  }
  out.color[i] = finite(color) ? color : glm::vec3(0.0f);

  glm::vec2 motion(0.0f);
  if (of.moves) {
    glm::vec2 now_px, prev_px;
    if (to_pixels(of.clip_now, p_obj, f, now_px) && to_pixels(of.clip_prev, p_obj, f, prev_px)) {
      motion = now_px - prev_px;
      if (!std::isfinite(motion.x) || !std::isfinite(motion.y)) motion = glm::vec2(0.0f);
    }
  }
  out.motion[i] = motion;
}

// The image in kTile x kTile tiles, one TBB task each: trace a tile's primary rays, then resolve its
// hits into texels. Counts the shadow rays into im.shadow_rays.
void render_tiles(const TilePass& pass) {
  const Frame& f = pass.f;
  GBuffer& out = pass.out;
  const std::uint32_t tiles_x = (f.width + kTile - 1) / kTile, tiles_y = (f.height + kTile - 1) / kTile;
  const std::size_t tile_count = std::size_t{tiles_x} * tiles_y;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, tile_count), [&](const tbb::blocked_range<std::size_t>& range) {
    TileHits hits;
    ShadowContext shadow;
    shadow.scene = pass.top;
    for (std::size_t t = range.begin(); t != range.end(); ++t) {
      const auto tx = static_cast<std::uint32_t>(t % tiles_x), ty = static_cast<std::uint32_t>(t / tiles_x);
      const std::uint32_t x0 = tx * kTile, y0 = ty * kTile;
      const std::uint32_t x1 = std::min(x0 + kTile, f.width), y1 = std::min(y0 + kTile, f.height);
      if (pass.masked && !tile_marked(pass, x0, y0, x1, y1)) {
        for (std::uint32_t y = y0; y < y1; ++y)
          for (std::uint32_t x = x0; x < x1; ++x) pass.fill_background(out.index(x, y));
        continue;
      }
      trace_tile(pass, x0, y0, x1, y1, hits);
      for (std::uint32_t y = y0; y < y1; ++y) {
        for (std::uint32_t x = x0; x < x1; ++x) resolve_hit(pass, hits[tile_slot(x - x0, y - y0)], x, y, shadow);
      }
    }
    pass.im.shadow_rays.fetch_add(shadow.rays, std::memory_order_relaxed);
  });
}

}  // namespace

void EmbreeBackend::render(const FrameTime& time, const BackendSettings& settings, GBuffer& out) {
  Impl& im = *impl_;
  const Camera& cam = im.scene.camera;
  const ImageSize size = fit_gbuffer(cam, settings, out);
  im.stats = {};
  im.shadow_rays = 0;
  if (out.size() == 0) return;

  const Scene& s = im.scene;
  const BackgroundTexel fill_background{out, cam, finite(s.background) ? s.background : glm::vec3(0.0f)};

  Frame f;
  const glm::mat4 view = cam.view_at(time.now_s);
  const bool camera_ok = camera_frame(cam, view, settings, size, f);
  if (!im.has_scene || !camera_ok) {
    for (std::size_t i = 0; i < out.size(); ++i) fill_background(i);
    im.stats.primary_rays = 0;
    return;
  }

  select_lods(im, settings, options_.geometry);
  // Move animated objects to now_s (see the geometry note above set_scene, embree_scene.cpp).
  set_time(time.now_s);
  object_frames(im, cam, view, time, f);

  const TilePass pass{.im = im,
                      .f = f,
                      .out = out,
                      .fill_background = fill_background,
                      .pixel_mask = settings.pixel_mask,
                      .masked = settings.pixel_mask.size() == out.size(),
                      .top = im.top,
                      .traversal = options_.traversal,
                      .peel = settings.peel,
                      .instanced = options_.geometry == EmbreeGeometry::Instanced,
                      .shade = options_.shading,
                      .visibility = settings.shadows ? &shadow_visible : nullptr};
  render_tiles(pass);
  im.stats.primary_rays = out.size();
  im.stats.shadow_rays = im.shadow_rays.load();
}

const Scene& EmbreeBackend::scene() const { return impl_->scene; }

void EmbreeBackend::set_camera(const Camera& camera) {
  if (impl_->has_scene) impl_->scene.camera = camera;
}

bool EmbreeBackend::intersect(const glm::vec3& origin, const glm::vec3& direction, float t_min, float t_max,
                              RayVisibility visibility, SurfaceHit& hit) const {
  const Impl& im = *impl_;
  if (!im.has_scene || !finite(origin) || !finite(direction) || !(glm::dot(direction, direction) > 0.0f) ||
      !(t_max > t_min)) {
    return false;
  }
  RTCIntersectContext ic;
  rtcInitIntersectContext(&ic);
  RTCRayHit rh{};
  rh.ray.org_x = origin.x;
  rh.ray.org_y = origin.y;
  rh.ray.org_z = origin.z;
  rh.ray.dir_x = direction.x;
  rh.ray.dir_y = direction.y;
  rh.ray.dir_z = direction.z;
  rh.ray.tnear = std::max(0.0f, t_min);
  rh.ray.tfar = t_max;
  rh.ray.mask = visibility == RayVisibility::All ? kMaskPrimary : kMaskShadowCaster;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(im.top, &ic, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID || !std::isfinite(rh.ray.tfar)) return false;
  const bool instanced = options_.geometry == EmbreeGeometry::Instanced;
  const unsigned id = instanced ? rh.hit.instID[0] : rh.hit.geomID;
  if (id >= im.records.size()) return false;
  const ObjectRecord& r = im.records[id];
  const PreparedMesh& m = *r.mesh;
  if (rh.hit.primID >= m.triangle_count()) return false;
  const std::size_t base = 3 * std::size_t{rh.hit.primID};
  const std::uint32_t i0 = m.indices[base], i1 = m.indices[base + 1], i2 = m.indices[base + 2];
  const float u = rh.hit.u, v = rh.hit.v, w = 1.0f - u - v;
  hit.t = rh.ray.tfar;
  hit.position = transform_point(r.committed, w * m.positions[i0] + u * m.positions[i1] + v * m.positions[i2]);
  if (!finite(hit.position)) hit.position = origin + hit.t * direction;
  glm::vec3 ng = transform_vector(r.normal_committed,
                                  glm::cross(m.positions[i1] - m.positions[i0], m.positions[i2] - m.positions[i0]));
  if (!normalize_checked(ng)) {
    ng = -direction;
    if (!normalize_checked(ng)) ng = glm::vec3(0, 1, 0);
  }
  // A mirroring transform (negative determinant) turns the cofactor's normal inwards.
  if (glm::determinant(glm::mat3(r.committed)) < 0.0f) ng = -ng;
  glm::vec3 ns = m.normals.empty() ? glm::vec3(0.0f) : w * m.normals[i0] + u * m.normals[i1] + v * m.normals[i2];
  ns = transform_vector(r.normal_committed, ns);
  if (glm::determinant(glm::mat3(r.committed)) < 0.0f) ns = -ns;
  if (!normalize_checked(ns)) ns = ng;
  if (glm::dot(ns, ng) < 0.0f) ns = -ns;
  hit.geometric_normal = ng;
  hit.normal = ns;
  hit.object_id = im.scene.objects[r.object].id;
  hit.material = r.material;
  hit.pbr.reset();
  if (r.material->type == MaterialType::MetallicRoughness) {
    // The front side is the shading normal's as the mesh gives it; the ray arrives at one side.
    const bool back_face = glm::dot(ns, direction) > 0.0f;
    ObjectFrame of;
    of.model_now = r.committed;
    of.normal_now = r.normal_committed;
    const HitVertices hv{m, i0, i1, i2, u, v, w};
    hit.pbr = evaluate_pbr(im.scene, r.material->pbr,
                           surface_point(0.0f, of, hv, hit.position, ns, back_face, direction, hit.t));
    // Back on the geometric normal's side, as `normal` is (callers turn it to the side they need).
    if (back_face) hit.pbr->normal = -hit.pbr->normal;
  }
  return true;
}

glm::vec3 SurfaceHit::diffuse_albedo() const {
  if (pbr) return glm::mix(pbr->base_color, glm::vec3(0.0f), pbr->metallic);
  return material != nullptr ? material->kd : glm::vec3(0.0f);
}

bool EmbreeBackend::occluded(const glm::vec3& from, const glm::vec3& to) const {
  const Impl& im = *impl_;
  if (!im.has_scene) return false;
  const glm::vec3 d = to - from;
  if (!finite(from) || !finite(d)) return false;
  return segment_occluded(im.top, from, d, 1.0f);
}

std::unique_ptr<Backend> make_embree_backend() { return std::make_unique<EmbreeBackend>(); }
std::unique_ptr<Backend> make_embree_backend(EmbreeOptions options) { return std::make_unique<EmbreeBackend>(options); }

}  // namespace fovea::render
