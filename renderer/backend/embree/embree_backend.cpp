// SPDX-License-Identifier: Apache-2.0
#include "backend/embree/embree_backend.h"

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "scene/shading.h"

namespace fovea::render {

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

constexpr unsigned kInvalidId = std::numeric_limits<unsigned>::max();
constexpr std::uint32_t kTile = 16;  // pixels per tile side: one TBB task, one Embree stream

// Ray masks (Embree is built with EMBREE_RAY_MASK). Primary rays see everything; shadow rays only
// see shadow casters. Emissive objects do not cast shadows: they are the visible face of a light
// (a Cornell box's ceiling panel sits at or just below its area light), and a shadow ray towards
// the light would otherwise stop on the panel and leave the whole room in shadow.
constexpr unsigned kMaskPrimary = 0xFFFFFFFFu;
constexpr unsigned kMaskShadowCaster = 0x1u;
constexpr unsigned kMaskEmitter = 0x2u;

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

bool finite(const glm::mat4& m) {
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      if (!std::isfinite(m[c][r])) return false;
    }
  }
  return true;
}

// v / |v|, or false when v has no usable direction (zero, denormal-tiny, Inf or NaN).
bool normalize_checked(glm::vec3& v) {
  const float len2 = glm::dot(v, v);
  if (!(len2 > 1e-30f) || !std::isfinite(len2)) return false;
  v *= 1.0f / std::sqrt(len2);
  return finite(v);
}

// Cofactor matrix of the upper 3x3 of m: det(M) * inverse-transpose(M). It transforms normals like
// the inverse-transpose up to a positive or negative scale (the sign does not matter: normals are
// turned to face the eye afterwards and the length is normalized away), and unlike the inverse it
// exists for singular matrices (zero scale), so no division can produce Inf.
glm::mat3 cofactor(const glm::mat4& m) {
  const glm::vec3 c0(m[0]), c1(m[1]), c2(m[2]);
  return glm::mat3(glm::cross(c1, c2), glm::cross(c2, c0), glm::cross(c0, c1));
}

// A mesh as Embree gets it: non-finite positions replaced by the origin (Embree drops the
// resulting degenerate triangles), triangles with an index out of range dropped, normals kept only
// if there is one per position. primID indexes `indices` of this copy.
struct PreparedMesh {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<std::uint32_t> indices;
  std::size_t triangle_count() const { return indices.size() / 3; }
};

std::shared_ptr<const PreparedMesh> prepare(const Mesh& mesh) {
  auto out = std::make_shared<PreparedMesh>();
  out->positions.reserve(mesh.positions.size());
  for (const glm::vec3& p : mesh.positions) out->positions.push_back(finite(p) ? p : glm::vec3(0.0f));
  if (mesh.normals.size() == mesh.positions.size()) {
    out->normals.reserve(mesh.normals.size());
    for (const glm::vec3& n : mesh.normals) out->normals.push_back(finite(n) ? n : glm::vec3(0.0f));
  }
  const std::size_t n = mesh.positions.size();
  out->indices.reserve(mesh.indices.size());
  for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    const std::uint32_t a = mesh.indices[t], b = mesh.indices[t + 1], c = mesh.indices[t + 2];
    if (a >= n || b >= n || c >= n) continue;
    out->indices.insert(out->indices.end(), {a, b, c});
  }
  return out;
}

struct ObjectRecord {
  std::size_t object = 0;  // index into Impl::scene.objects
  const Material* material = nullptr;
  std::shared_ptr<const PreparedMesh> mesh;
  RTCGeometry geometry = nullptr;  // owned by the top-level scene; nullptr when not attached
  bool animated = false;
  bool enabled = true;             // instanced: disabled while the transform is singular
  glm::mat4 committed{1.0f};       // model matrix the BVH currently holds
  glm::mat3 normal_committed{1.0f};  // its cofactor (transforms normals)
  std::uint32_t lod = 0;           // 0: the object's full mesh; k: its lods[k - 1]
  bool lod_active = true;          // this level is the one drawn (only one per object is)
};

// Per-frame, per-object matrices.
struct ObjectFrame {
  glm::mat4 model_now{1.0f};
  glm::mat3 normal_now{1.0f};         // cofactor of model_now
  glm::mat4 clip_now{1.0f};           // projection * view(now) * model(now): object -> clip now
  glm::mat4 clip_prev{1.0f};          // the same at the previous frame's time
  bool moves = false;                 // clip_now != clip_prev: motion can be non-zero
};

// m * (p, 1), written out so it inlines (glm's operator* does not always at -O2; it was a quarter
// of the frame time in a profile of the geometry-only G-buffer).
inline glm::vec3 transform_point(const glm::mat4& m, const glm::vec3& p) {
  return glm::vec3(m[0]) * p.x + glm::vec3(m[1]) * p.y + glm::vec3(m[2]) * p.z + glm::vec3(m[3]);
}
inline glm::vec4 transform_point4(const glm::mat4& m, const glm::vec3& p) {
  return m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3];
}
inline glm::vec3 transform_vector(const glm::mat3& m, const glm::vec3& v) { return m[0] * v.x + m[1] * v.y + m[2] * v.z; }

// Everything a tile needs, computed once per frame.
struct Frame {
  std::uint32_t width = 0, height = 0;
  glm::vec3 eye{0.0f}, right{1, 0, 0}, up{0, 1, 0}, back{0, 0, 1};
  float tan_x = 1, tan_y = 1;  // half-extent of the image plane at view depth 1
  float near_m = 0, far_m = 0;
  bool motion = false;
  glm::mat4 view_proj_now{1.0f}, view_proj_prev{1.0f};
  std::vector<ObjectFrame> objects;

  // Ray direction through the centre of pixel (x, y), scaled so its component along the view
  // axis is exactly 1: ray parameter t is then linear view-space depth, and [near, far] in t is
  // the same clip range as the OpenGL backend's near and far planes.
  glm::vec3 direction(std::uint32_t x, std::uint32_t y) const {
    const float ndc_x = 2.0f * (static_cast<float>(x) + 0.5f) / static_cast<float>(width) - 1.0f;
    const float ndc_y = 1.0f - 2.0f * (static_cast<float>(y) + 0.5f) / static_cast<float>(height);
    return right * (ndc_x * tan_x) + up * (ndc_y * tan_y) - back;
  }

  // Thin lens (BackendSettings::lens): the ray of pixel (x, y) leaves from its lens point and passes
  // through the pixel's point on the plane in focus; divided by the focus distance its view-axis
  // component stays 1, so t is still view-axis depth (from the lens plane).
  LensSample lens;
  bool lens_on = false;
  float lens_radius = 0, focus = 1;
  void ray(std::uint32_t x, std::uint32_t y, glm::vec3& origin, glm::vec3& dir) const {
    dir = direction(x, y);
    origin = eye;
    if (!lens_on) return;
    const glm::vec2 p = lens_sampling::pixel_lens_point(lens, x, y) * lens_radius;
    const glm::vec3 offset = right * p.x + up * p.y;
    const glm::vec3 focal = eye + dir * focus;
    origin = eye + offset;
    dir = (focal - origin) / focus;
  }
};

// Image position in pixels (x right, y down, pixel centres at +0.5) of an object-space point under
// an object -> clip matrix, or false if the point is at or behind the camera plane.
inline bool to_pixels(const glm::mat4& object_to_clip, const glm::vec3& p, const Frame& f, glm::vec2& px) {
  const glm::vec4 clip = transform_point4(object_to_clip, p);
  if (!(clip.w > 1e-6f)) return false;
  const float ndc_x = clip.x / clip.w, ndc_y = clip.y / clip.w;
  px = {(ndc_x + 1.0f) * 0.5f * static_cast<float>(f.width), (1.0f - ndc_y) * 0.5f * static_cast<float>(f.height)};
  return std::isfinite(px.x) && std::isfinite(px.y);
}

struct Hit {
  float t = 0, u = 0, v = 0;
  unsigned geom = kInvalidId, prim = kInvalidId, inst = kInvalidId;
};

// Shadow rays: rtcOccluded1 from the shaded point (pushed off the surface along the normal) to
// the light sample.
struct ShadowContext {
  RTCScene scene = nullptr;
  glm::vec3 offset{0.0f};  // normal * epsilon
  float epsilon = 0;
  std::uint64_t rays = 0;
};

// True if a shadow caster lies on origin + t d for t in (0, t_far).
bool segment_occluded(RTCScene scene, const glm::vec3& origin, const glm::vec3& d, float t_far) {
  RTCIntersectContext ic;
  rtcInitIntersectContext(&ic);
  RTCRay ray{};
  ray.org_x = origin.x;
  ray.org_y = origin.y;
  ray.org_z = origin.z;
  ray.dir_x = d.x;
  ray.dir_y = d.y;
  ray.dir_z = d.z;
  ray.tnear = 0.0f;
  ray.tfar = t_far;
  ray.mask = kMaskShadowCaster;
  rtcOccluded1(scene, &ic, &ray);
  return !(ray.tfar >= 0.0f);  // Embree sets tfar = -inf when occluded
}

bool shadow_visible(void* context, const glm::vec3& from, const glm::vec3& to) {
  auto* c = static_cast<ShadowContext*>(context);
  ++c->rays;
  const glm::vec3 origin = from + c->offset;
  const glm::vec3 d = to - origin;
  const float len = glm::length(d);
  if (!(len > c->epsilon) || !std::isfinite(len)) return true;  // light on the surface: nothing between
  return !segment_occluded(c->scene, origin, d, 1.0f - c->epsilon / len);  // stop just short of the light sample
}

template <class Ray>
void fill_ray(Ray& r, const Frame& f, std::uint32_t x, std::uint32_t y) {
  glm::vec3 o, d;
  f.ray(x, y, o, d);
  r.org_x = o.x;
  r.org_y = o.y;
  r.org_z = o.z;
  r.dir_x = d.x;
  r.dir_y = d.y;
  r.dir_z = d.z;
  r.tnear = f.near_m;
  r.tfar = f.far_m;
  r.mask = kMaskPrimary;
  r.time = 0.0f;
  r.flags = 0;
}

// Packet traits: rtcIntersectN and the pixel block each packet covers.
template <int N>
struct Packet;
template <>
struct Packet<4> {
  using RayHit = RTCRayHit4;
  static constexpr std::uint32_t bw = 2, bh = 2;
  static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) { rtcIntersect4(valid, s, c, r); }
};
template <>
struct Packet<8> {
  using RayHit = RTCRayHit8;
  static constexpr std::uint32_t bw = 4, bh = 2;
  static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) { rtcIntersect8(valid, s, c, r); }
};
template <>
struct Packet<16> {
  using RayHit = RTCRayHit16;
  static constexpr std::uint32_t bw = 4, bh = 4;
  static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) { rtcIntersect16(valid, s, c, r); }
};

using TileHits = std::array<Hit, kTile * kTile>;
constexpr std::size_t tile_slot(std::uint32_t dx, std::uint32_t dy) { return std::size_t{dy} * kTile + dx; }

void trace_single(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                  std::uint32_t y1, TileHits& hits) {
  RTCIntersectContext ic;
  rtcInitIntersectContext(&ic);
  ic.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  for (std::uint32_t y = y0; y < y1; ++y) {
    for (std::uint32_t x = x0; x < x1; ++x) {
      RTCRayHit rh{};
      fill_ray(rh.ray, f, x, y);
      rh.hit.geomID = kInvalidId;
      rh.hit.instID[0] = kInvalidId;
      rtcIntersect1(scene, &ic, &rh);
      hits[tile_slot(x - x0, y - y0)] = {rh.ray.tfar, rh.hit.u, rh.hit.v, rh.hit.geomID, rh.hit.primID, rh.hit.instID[0]};
    }
  }
}

template <int N>
void trace_packets(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                   std::uint32_t y1, TileHits& hits) {
  using P = Packet<N>;
  RTCIntersectContext ic;
  rtcInitIntersectContext(&ic);
  ic.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  for (std::uint32_t by = y0; by < y1; by += P::bh) {
    for (std::uint32_t bx = x0; bx < x1; bx += P::bw) {
      typename P::RayHit rh{};
      alignas(64) std::array<int, static_cast<std::size_t>(N)> valid{};
      for (int i = 0; i < N; ++i) {
        const std::uint32_t x = bx + static_cast<std::uint32_t>(i) % P::bw;
        const std::uint32_t y = by + static_cast<std::uint32_t>(i) / P::bw;
        const auto lane = static_cast<std::size_t>(i);
        valid[lane] = (x < x1 && y < y1) ? -1 : 0;
        glm::vec3 o = f.eye, d(0, 0, -1);
        if (valid[lane] != 0) f.ray(x, y, o, d);
        rh.ray.org_x[lane] = o.x;
        rh.ray.org_y[lane] = o.y;
        rh.ray.org_z[lane] = o.z;
        rh.ray.dir_x[lane] = d.x;
        rh.ray.dir_y[lane] = d.y;
        rh.ray.dir_z[lane] = d.z;
        rh.ray.tnear[lane] = f.near_m;
        rh.ray.tfar[lane] = f.far_m;
        rh.ray.mask[lane] = kMaskPrimary;
        rh.hit.geomID[lane] = kInvalidId;
        rh.hit.instID[0][lane] = kInvalidId;
      }
      P::intersect(valid.data(), scene, &ic, &rh);
      for (int i = 0; i < N; ++i) {
        const auto lane = static_cast<std::size_t>(i);
        if (valid[lane] == 0) continue;
        const std::uint32_t x = bx + static_cast<std::uint32_t>(i) % P::bw;
        const std::uint32_t y = by + static_cast<std::uint32_t>(i) / P::bw;
        hits[tile_slot(x - x0, y - y0)] = {rh.ray.tfar[lane], rh.hit.u[lane],      rh.hit.v[lane],
                                           rh.hit.geomID[lane], rh.hit.primID[lane], rh.hit.instID[0][lane]};
      }
    }
  }
}

void trace_stream(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                  std::uint32_t y1, TileHits& hits) {
  RTCIntersectContext ic;
  rtcInitIntersectContext(&ic);
  ic.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  std::array<RTCRayHit, kTile * kTile> rh{};
  unsigned count = 0;
  for (std::uint32_t y = y0; y < y1; ++y) {
    for (std::uint32_t x = x0; x < x1; ++x) {
      RTCRayHit& r = rh[count++];
      fill_ray(r.ray, f, x, y);
      r.hit.geomID = kInvalidId;
      r.hit.instID[0] = kInvalidId;
    }
  }
  rtcIntersect1M(scene, &ic, rh.data(), count, sizeof(RTCRayHit));
  count = 0;
  for (std::uint32_t y = y0; y < y1; ++y) {
    for (std::uint32_t x = x0; x < x1; ++x) {
      const RTCRayHit& r = rh[count++];
      hits[tile_slot(x - x0, y - y0)] = {r.ray.tfar, r.hit.u, r.hit.v, r.hit.geomID, r.hit.primID, r.hit.instID[0]};
    }
  }
}

// Depth peeling by object: the first hit of the peel-th object behind the visible one, continuing
// the ray past each further hit of an object already met (its back faces, its other parts).
void trace_peeled(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                  std::uint32_t y1, bool instanced, std::uint32_t peel, TileHits& hits) {
  RTCIntersectContext ic;
  rtcInitIntersectContext(&ic);
  for (std::uint32_t y = y0; y < y1; ++y) {
    for (std::uint32_t x = x0; x < x1; ++x) {
      Hit out;  // miss unless another object is found
      RTCRayHit rh{};
      fill_ray(rh.ray, f, x, y);
      rh.hit.geomID = kInvalidId;
      rh.hit.instID[0] = kInvalidId;
      rtcIntersect1(scene, &ic, &rh);
      if (rh.hit.geomID != kInvalidId) {
        unsigned current = instanced ? rh.hit.instID[0] : rh.hit.geomID;
        std::uint32_t met = 0;  // objects met behind the visible one
        for (int step = 0; step < 256; ++step) {
          const float t = rh.ray.tfar;
          fill_ray(rh.ray, f, x, y);
          rh.ray.tnear = t + std::max(1e-4f, 1e-5f * t);
          rh.hit.geomID = kInvalidId;
          rh.hit.instID[0] = kInvalidId;
          if (!(rh.ray.tnear < rh.ray.tfar)) break;
          rtcIntersect1(scene, &ic, &rh);
          if (rh.hit.geomID == kInvalidId) break;
          const unsigned id = instanced ? rh.hit.instID[0] : rh.hit.geomID;
          if (id != current) {
            current = id;
            if (++met == peel) {
              out = {rh.ray.tfar, rh.hit.u, rh.hit.v, rh.hit.geomID, rh.hit.primID, rh.hit.instID[0]};
              break;
            }
          }
        }
      }
      hits[tile_slot(x - x0, y - y0)] = out;
    }
  }
}

const Material& default_material() {
  static const Material m;
  return m;
}

}  // namespace

struct EmbreeBackend::Impl {
  RTCDevice device = nullptr;
  RTCScene top = nullptr;
  std::vector<RTCScene> mesh_scenes;  // instanced mode: one per distinct mesh (and emitter flag)
  Scene scene;
  bool has_scene = false;
  std::vector<ObjectRecord> records;   // one per attached object; geomID in `top` = position here
  std::atomic<std::uint64_t> shadow_rays{0};
  EmbreeFrameStats stats;

  std::mutex error_mutex;
  std::string last_error;

  ~Impl() {
    release_scene();
    if (device != nullptr) rtcReleaseDevice(device);
  }

  void release_scene() {
    records.clear();
    if (top != nullptr) rtcReleaseScene(top);
    top = nullptr;
    for (RTCScene s : mesh_scenes) rtcReleaseScene(s);
    mesh_scenes.clear();
    has_scene = false;
  }

  // Throws if Embree reported an error since the last check.
  void check(const std::string& what) {
    const RTCError e = rtcGetDeviceError(device);
    if (e == RTC_ERROR_NONE) return;
    std::string message;
    {
      const std::lock_guard lock(error_mutex);
      message = last_error;
    }
    throw std::runtime_error("embree backend: " + what + ": " + (message.empty() ? "error " + std::to_string(e) : message));
  }

  static void on_error(void* user, RTCError, const char* message) {
    auto* self = static_cast<Impl*>(user);
    const std::lock_guard lock(self->error_mutex);
    self->last_error = message != nullptr ? message : "";
  }
};

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

// Writes M * p for every position into an Embree vertex buffer (non-finite results become the
// origin: a collapsed object is a set of degenerate triangles Embree never reports).
void write_world_vertices(float* dst, const PreparedMesh& mesh, const glm::mat4& m) {
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    glm::vec3 p = glm::vec3(m * glm::vec4(mesh.positions[i], 1.0f));
    if (!finite(p)) p = glm::vec3(0.0f);
    dst[3 * i] = p.x;
    dst[3 * i + 1] = p.y;
    dst[3 * i + 2] = p.z;
  }
}

RTCGeometry new_triangle_geometry(RTCDevice device, const PreparedMesh& mesh) {
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                               3 * sizeof(float), mesh.positions.size()));
  auto* indices = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                      3 * sizeof(std::uint32_t), mesh.triangle_count()));
  if (vertices != nullptr) {
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
      vertices[3 * i] = mesh.positions[i].x;
      vertices[3 * i + 1] = mesh.positions[i].y;
      vertices[3 * i + 2] = mesh.positions[i].z;
    }
  }
  if (indices != nullptr) std::copy(mesh.indices.begin(), mesh.indices.end(), indices);
  return g;
}

bool invertible(const glm::mat4& m) {
  const float det = glm::determinant(glm::mat3(m));
  return finite(m) && std::isfinite(det) && std::abs(det) > 1e-30f;
}

}  // namespace

// Geometry: flattened vs instanced (both kept; EmbreeOptions::geometry selects).
//  - Flattened: world-space vertices, one geometry per object. A static scene gets a single SAH
//    BVH over all triangles; a scene with animation is DYNAMIC (Embree then keeps one BVH per
//    geometry under a top-level BVH, so only the moved objects are rebuilt, at LOW quality).
//    Rays never pay a transform.
//  - Instanced: one object-space BVH per distinct mesh, objects are instances. A frame only
//    updates instance matrices and rebuilds the (tiny) top level, but every ray that enters an
//    instance is transformed into object space.
// With tens of objects and few animated, rebuilding the animated meshes' BVHs each frame costs
// little next to tracing a 1024x768 frame, and flattened traversal is faster: measured side by
// side (bench_embree "compare", geometry only, packet16) flattened vs instanced was 28.9 vs 28.1
// Mrays/s on the Cornell room, 19.5 vs 18.2 on 64 objects with 4 animated, 18.4 vs 15.5 on
// cornell.json, 18.8 vs 17.3 on attention.json. So flattened is the default (EmbreeOptions);
// instancing stays selectable for scenes with many animated or repeated heavy meshes.
void EmbreeBackend::set_scene(const Scene& scene) {
  Impl& im = *impl_;
  im.release_scene();
  im.scene = scene;
  const Scene& s = im.scene;
  const bool instanced = options_.geometry == EmbreeGeometry::Instanced;
  const bool any_animated = std::any_of(s.objects.begin(), s.objects.end(),
                                        [](const Object& o) { return o.animation.has_value(); });

  im.top = rtcNewScene(im.device);
  if (any_animated) {
    rtcSetSceneFlags(im.top, RTC_SCENE_FLAG_DYNAMIC);
    rtcSetSceneBuildQuality(im.top, RTC_BUILD_QUALITY_LOW);
  }

  std::map<const Mesh*, std::shared_ptr<const PreparedMesh>> prepared;
  std::map<const PreparedMesh*, RTCScene> mesh_scene;
  for (std::size_t i = 0; i < s.objects.size(); ++i) {
    const Object& o = s.objects[i];
    if (!o.mesh) continue;
    // Level 0 (the full mesh) and every LOD level get their own geometry; only one per object is
    // enabled at a time (BackendSettings::lod_levels), so switching costs a commit, not a rebuild.
    for (std::uint32_t lod = 0; lod <= o.lods.size(); ++lod) {
      const std::shared_ptr<const Mesh>& source = lod == 0 ? o.mesh : o.lods[lod - 1].mesh;
      if (!source) continue;
      auto& pm = prepared[source.get()];
      if (!pm) pm = prepare(*source);
      if (pm->triangle_count() == 0 || pm->positions.empty()) continue;

      ObjectRecord r;
      r.object = i;
      r.material = o.material < s.materials.size() ? &s.materials[o.material] : &default_material();
      r.mesh = pm;
      r.animated = o.animation.has_value();
      r.lod = lod;
      r.lod_active = lod == 0;
      r.committed = o.transform_at(0).matrix();
      r.normal_committed = cofactor(r.committed);
      const bool emitter = r.material->type == MaterialType::Emissive;

      RTCGeometry g = nullptr;
      if (instanced) {
        RTCScene& ms = mesh_scene[pm.get()];
        if (ms == nullptr) {
          ms = rtcNewScene(im.device);
          im.mesh_scenes.push_back(ms);
          RTCGeometry tri = new_triangle_geometry(im.device, *pm);
          rtcCommitGeometry(tri);
          rtcAttachGeometry(ms, tri);
          rtcReleaseGeometry(tri);
          rtcCommitScene(ms);
          im.check("mesh of object '" + o.name + "'");
        }
        g = rtcNewGeometry(im.device, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(g, ms);
        rtcSetGeometryTimeStepCount(g, 1);
        r.enabled = invertible(r.committed);
        const glm::mat4 m = r.enabled ? r.committed : glm::mat4(1.0f);
        rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT4X4_COLUMN_MAJOR, &m[0][0]);
        if (!r.enabled) rtcDisableGeometry(g);
      } else {
        g = new_triangle_geometry(im.device, *pm);
        auto* vertices = static_cast<float*>(rtcGetGeometryBufferData(g, RTC_BUFFER_TYPE_VERTEX, 0));
        if (vertices != nullptr) write_world_vertices(vertices, *pm, r.committed);
        if (r.animated) rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_LOW);
      }
      if (emitter) rtcSetGeometryMask(g, kMaskEmitter);
      if (!r.lod_active) rtcDisableGeometry(g);
      rtcCommitGeometry(g);
      rtcAttachGeometryByID(im.top, g, static_cast<unsigned>(im.records.size()));
      rtcReleaseGeometry(g);  // the scene holds it; r.geometry stays valid while `top` lives
      r.geometry = g;
      im.check("object '" + o.name + "'");
      im.records.push_back(std::move(r));
    }
  }
  rtcCommitScene(im.top);
  im.check("scene '" + s.name + "'");
  im.has_scene = true;
}

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
  f.near_m = std::max(0.0f, cam.near_m);
  f.far_m = cam.far_m;
  f.lens = settings.lens;
  f.lens_on = settings.lens.active();
  f.lens_radius = static_cast<float>(settings.lens.aperture_radius_m);
  f.focus = static_cast<float>(settings.lens.focus_m);
  return finite(view) && finite(cam_to_world) && std::isfinite(tan_half) && tan_half > 0 && std::isfinite(f.tan_x) &&
         std::isfinite(f.far_m) && f.far_m > f.near_m;
}

// The levels of detail asked for (BackendSettings::lod_levels): one geometry per object enabled.
void select_lods(EmbreeBackend::Impl& im, const BackendSettings& settings, EmbreeGeometry geometry) {
  const Scene& s = im.scene;
  bool lod_changed = false;
  for (ObjectRecord& r : im.records) {
    const Object& o = s.objects[r.object];
    const std::uint32_t want = r.object < settings.lod_levels.size()
                                   ? std::min<std::uint32_t>(settings.lod_levels[r.object], static_cast<std::uint32_t>(o.lods.size()))
                                   : 0u;
    const bool active = r.lod == want;
    if (active == r.lod_active) continue;
    r.lod_active = active;
    lod_changed = true;
    if (active && (geometry != EmbreeGeometry::Instanced || r.enabled)) rtcEnableGeometry(r.geometry);
    if (!active) rtcDisableGeometry(r.geometry);
    rtcCommitGeometry(r.geometry);
  }
  if (lod_changed) {
    rtcCommitScene(im.top);
    im.check("switching levels of detail");
  }
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
  if (glm::dot(n, dir) > 0.0f) n = -n;  // face the eye

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
    color = shade_local(s, *r.material, p, n, origin, pass.visibility, &shadow);
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
  // Move animated objects to now_s (see the geometry note above set_scene).
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

void EmbreeBackend::set_lod_levels(const std::vector<std::uint8_t>& levels) {
  if (!impl_->has_scene) return;
  BackendSettings settings;
  settings.lod_levels = levels;
  select_lods(*impl_, settings, options_.geometry);
}

void EmbreeBackend::set_time(double now_s) {
  Impl& im = *impl_;
  if (!im.has_scene) return;
  const Scene& s = im.scene;
  const bool instanced = options_.geometry == EmbreeGeometry::Instanced;
  bool changed = false;
  for (ObjectRecord& r : im.records) {
    if (!r.animated) continue;
    const glm::mat4 m = s.objects[r.object].transform_at(now_s).matrix();
    if (m == r.committed) continue;
    r.committed = m;
    r.normal_committed = cofactor(m);
    changed = true;
    if (instanced) {
      const bool ok = invertible(m);
      if (ok) rtcSetGeometryTransform(r.geometry, 0, RTC_FORMAT_FLOAT4X4_COLUMN_MAJOR, &m[0][0]);
      if (ok && !r.enabled && r.lod_active) rtcEnableGeometry(r.geometry);
      if (!ok && r.enabled && r.lod_active) rtcDisableGeometry(r.geometry);
      r.enabled = ok;
    } else {
      auto* vertices = static_cast<float*>(rtcGetGeometryBufferData(r.geometry, RTC_BUFFER_TYPE_VERTEX, 0));
      if (vertices != nullptr) write_world_vertices(vertices, *r.mesh, m);
      rtcUpdateGeometryBuffer(r.geometry, RTC_BUFFER_TYPE_VERTEX, 0);
    }
    rtcCommitGeometry(r.geometry);
  }
  if (changed) {
    rtcCommitScene(im.top);
    im.check("updating animated objects");
  }
}

const Scene& EmbreeBackend::scene() const { return impl_->scene; }

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
  return true;
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
