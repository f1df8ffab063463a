// SPDX-License-Identifier: Apache-2.0
#pragma once
// The Embree backend's state (EmbreeBackend::Impl): the scene it was given, as Embree geometry, one
// record per object and level of detail, with the ray masks and matrix checks its files share.
// Internal to the backend: embree_scene.cpp builds and updates the geometry, embree_rays.cpp
// traces rays against it, embree_backend.cpp renders the G-buffer and answers intersect().
#include <embree3/rtcore.h>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "backend/embree/embree_backend.h"

namespace fovea::render::embree_detail {

// Ray masks (Embree is built with EMBREE_RAY_MASK). Primary rays see everything; shadow rays only
// see shadow casters. Emissive objects do not cast shadows: they are the visible face of a light
// (a Cornell box's ceiling panel sits at or just below its area light), and a shadow ray towards
// the light would otherwise stop on the panel and leave the whole room in shadow.
constexpr unsigned kMaskPrimary = 0xFFFFFFFFu;
constexpr unsigned kMaskShadowCaster = 0x1u;
constexpr unsigned kMaskEmitter = 0x2u;

inline bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

inline bool finite(const glm::mat4& m) {
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      if (!std::isfinite(m[c][r])) return false;
    }
  }
  return true;
}

// Cofactor matrix of the upper 3x3 of m: det(M) * inverse-transpose(M). It transforms normals like
// the inverse-transpose up to a positive or negative scale (the sign does not matter: normals are
// turned to face the eye afterwards and the length is normalized away), and unlike the inverse it
// exists for singular matrices (zero scale), so no division can produce Inf.
inline glm::mat3 cofactor(const glm::mat4& m) {
  const glm::vec3 c0(m[0]), c1(m[1]), c2(m[2]);
  return glm::mat3(glm::cross(c1, c2), glm::cross(c2, c0), glm::cross(c0, c1));
}

// A mesh as Embree gets it: non-finite positions replaced by the origin (Embree drops the
// resulting degenerate triangles), triangles with an index out of range dropped, normals kept only
// if there is one per position. primID indexes `indices` of this copy.
// Texture coordinates, colours and tangents are kept likewise: one per position or none.
struct PreparedMesh {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<std::uint32_t> indices;
  std::vector<glm::vec2> texcoords[2];
  std::vector<glm::vec4> colors, tangents;
  std::size_t triangle_count() const { return indices.size() / 3; }
};

// What a geometry's hit filters read (Embree geometry user data), for a material that is alpha-tested
// or single-sided (or both):
//  - alpha test: MASK (and BLEND) materials drop hits whose base-colour alpha is below the cutoff,
//    for every ray, primary and shadow alike. The alpha is read at the texture's base level in both
//    backends, so a distant leaf does not fade away with the mip chain's averaged alpha (it may alias
//    instead).
//  - back-face culling (glTF: a material that is not doubleSided): the camera's rays (the G-buffer,
//    its lens samples and peeled layers, through cull_back_faces) drop hits on the back of the
//    triangle, as the raster backend culls them; shadow rays, photons and GI paths see both sides.
//    front_sign is +1, or -1 for a flattened object whose transform mirrors (negative determinant:
//    glTF turns the winding round there, and the world-space geometry normal has turned with it).
struct HitFilter {
  const Scene* scene = nullptr;
  const PbrParameters* material = nullptr;
  const PreparedMesh* mesh = nullptr;
  bool alpha_tested = false;
  bool single_sided = false;
  float front_sign = 1.0f;
};

// Installs a geometry's filter data and, for an alpha test, its intersection and occlusion filters.
void set_hit_filter(RTCGeometry g, const HitFilter* filter);

// Makes an intersect context drop back-face hits on single-sided geometry: a context filter, where
// `scene` was built with RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION (set_scene sets it when any object
// is single-sided; elsewhere the context is left as it is).
void cull_back_faces(RTCIntersectContext& context, RTCScene scene);

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

// The levels of detail asked for (BackendSettings::lod_levels): one geometry per object enabled.
void select_lods(EmbreeBackend::Impl& im, const BackendSettings& settings, EmbreeGeometry geometry);

}  // namespace fovea::render::embree_detail

namespace fovea::render {

struct EmbreeBackend::Impl {
  RTCDevice device = nullptr;
  RTCScene top = nullptr;
  std::vector<RTCScene> mesh_scenes;  // instanced mode: one per distinct mesh (and emitter flag)
  Scene scene;
  bool has_scene = false;
  std::vector<embree_detail::ObjectRecord> records;  // one per attached object; geomID in `top` = position here
  std::vector<std::unique_ptr<embree_detail::HitFilter>> hit_filters;  // user data of filtered geometry
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
    hit_filters.clear();  // after the scenes that point at them
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

}  // namespace fovea::render
