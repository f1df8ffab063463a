// SPDX-License-Identifier: Apache-2.0
#pragma once
// The Embree G-buffer backend: one primary ray through each pixel centre, local illumination with
// the shared BRDF (scene/shading.h) and, when asked, Embree occlusion rays for shadows.
//
// Geometry and traversal are selectable so bench/bench_embree.cpp can measure the alternatives side
// by side; the defaults are the measured winners (numbers at EmbreeOptions below).
#include <cstdint>
#include <glm/glm.hpp>
#include <memory>
#include <optional>

#include "backend/backend.h"
#include "scene/shading.h"

namespace fovea::render {

// How primary rays are handed to Embree. All give the same G-buffer.
enum class EmbreeTraversal {
  Single,    // rtcIntersect1 per pixel
  Packet4,   // rtcIntersect4 on 2x2 pixel blocks
  Packet8,   // rtcIntersect8 on 4x2 pixel blocks
  Packet16,  // rtcIntersect16 on 4x4 pixel blocks
  Stream,    // rtcIntersect1M on a whole 16x16 tile, coherent flag
};
const char* to_string(EmbreeTraversal t);

// How objects become Embree geometry. Both give the same G-buffer.
enum class EmbreeGeometry {
  // One world-space triangle mesh per object in one scene. Animated objects get their vertices
  // re-transformed and their BVH rebuilt each frame (dynamic scene: two-level BVH).
  Flattened,
  // One object-space scene per mesh, one instance per object; animation only moves instances.
  Instanced,
};
const char* to_string(EmbreeGeometry g);

struct EmbreeOptions {
  // Defaults measured with bench_embree's interleaved "compare" runs (1024x768, this 2-core AVX-512
  // machine, RelWithDebInfo), primary Mrays/s of the whole G-buffer (trace + resolve), geometry only:
  //                      single  packet4  packet8  packet16  stream   (flattened)
  //   cornell-procedural  16.9    22.6     27.0     28.9      28.9
  //   many-objects (64)   11.5    14.5     18.3     19.5      19.0
  //   cornell.json        10.4    15.2     16.5     18.4      17.3
  //   attention.json      10.5    14.6     17.6     18.8      18.0
  // Packets of 16 (4x4 pixels, native width with AVX-512) win or tie everywhere; the 1M stream is
  // within 5%. With shading and shadow rays the per-pixel shading dominates and all packet/stream
  // modes land within noise of each other, 1.1-1.4x over single rays. Instanced geometry was
  // 4-15% slower than flattened in every geometry-only run (instance transform per ray), with the
  // per-frame update of the 4 animated objects included in the flattened figures.
  EmbreeTraversal traversal = EmbreeTraversal::Packet16;
  EmbreeGeometry geometry = EmbreeGeometry::Flattened;
  // false: skip shade_local (colour stays 0 where an object is hit). For benchmarks of the
  // geometric part of the G-buffer only.
  bool shading = true;
};

// Rays cast by the last render(), for throughput figures.
struct EmbreeFrameStats {
  std::uint64_t primary_rays = 0;
  std::uint64_t shadow_rays = 0;
};

// A surface point hit by a world-space ray (EmbreeBackend::intersect), for passes that trace their
// own rays (photon mapping, the GI render).
struct SurfaceHit {
  float t = 0;                          // ray parameter: distance in units of |direction|
  glm::vec3 position{0.0f};             // world space, from the barycentrics (exact on the triangle)
  glm::vec3 normal{0, 1, 0};            // shading normal (interpolated), unit, on the geometric normal's side
  glm::vec3 geometric_normal{0, 1, 0};  // unit face normal, outward by the triangle's winding
  std::uint32_t object_id = 0;          // Object::id
  const Material* material = nullptr;   // in the backend's copy of the scene; never null on a hit
  // A MetallicRoughness material at the hit: its textures sampled at the base level (no ray cone
  // for rays the caller made), its normal bent by the normal map on the side the ray arrived at.
  std::optional<SurfaceSample> pbr;
  // The diffuse reflectance the photon map uses: kd, or the PBR sample's base x (1 - metallic).
  glm::vec3 diffuse_albedo() const;
};

// What a world-space ray can hit: everything, or only shadow casters (emissive objects are the
// visible face of a light and neither cast shadows nor stop photons).
enum class RayVisibility { All, ShadowCasters };

class EmbreeBackend final : public Backend {
 public:
  // Throws std::runtime_error if Embree cannot create a device.
  explicit EmbreeBackend(EmbreeOptions options = {});
  ~EmbreeBackend() override;
  EmbreeBackend(const EmbreeBackend&) = delete;
  EmbreeBackend& operator=(const EmbreeBackend&) = delete;

  std::string name() const override { return "embree"; }
  BackendCapabilities capabilities() const override {
    return {.shadow_rays = true, .per_pixel_lens = true, .peeling = true};
  }
  // Copies the scene (meshes are shared, not copied) and builds the acceleration structures.
  // Throws std::runtime_error naming the object if Embree rejects its geometry.
  void set_scene(const Scene& scene) override;
  void set_camera(const Camera& camera) override;
  // Updates animated objects to time.now_s, then fills `out`. Renders the background only if no
  // scene was set.
  void render(const FrameTime& time, const BackendSettings& settings, GBuffer& out) override;

  // World-space rays against the geometry as of the last render() (or set_scene()'s time 0).
  // Thread-safe between renders. The nearest hit with t in [t_min, t_max], or false (also for a
  // non-finite or zero direction, or no scene).
  bool intersect(const glm::vec3& origin, const glm::vec3& direction, float t_min, float t_max,
                 RayVisibility visibility, SurfaceHit& hit) const;
  // True if a shadow caster lies on the open segment (from, to).
  bool occluded(const glm::vec3& from, const glm::vec3& to) const;
  // Moves animated objects to scene time now_s (render() does this itself) for intersect().
  void set_time(double now_s);
  // The levels of detail intersect() and occluded() see until the next render() (what
  // BackendSettings::lod_levels means): a pass tracing the frame's geometry after another render.
  void set_lod_levels(const std::vector<std::uint8_t>& levels);
  // The backend's copy of the scene (materials of hits point into it).
  const Scene& scene() const;

  const EmbreeOptions& options() const { return options_; }
  EmbreeFrameStats last_frame_stats() const;

  struct Impl;

 private:
  EmbreeOptions options_;
  std::unique_ptr<Impl> impl_;
};

std::unique_ptr<Backend> make_embree_backend();
std::unique_ptr<Backend> make_embree_backend(EmbreeOptions options);

}  // namespace fovea::render
