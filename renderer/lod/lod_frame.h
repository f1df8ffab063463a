// SPDX-License-Identifier: Apache-2.0
#pragma once
// What the lod-select pass and bench_lod share: the per-object views the policies read, built from
// the scene and camera at a frame time, and ULOD's image-space blend of two adjacent levels.
#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

#include "backend/gbuffer.h"
#include "lod/lod_policy.h"
#include "scene/scene.h"

namespace fovea::render::lod {

// Bounding spheres per mesh, computed once per mesh (a scene of 256 instances of a 220k-vertex mesh
// would otherwise read 56 M vertices every frame).
class BoundsCache {
 public:
  struct Sphere {
    glm::vec3 centre{0.0f};
    float radius = 0;
  };
  const Sphere& of(const Mesh& mesh);

 private:
  std::unordered_map<const Mesh*, std::pair<std::size_t, Sphere>> spheres_;  // keyed by mesh, checked by vertex count
};

struct ViewInputs {
  double now_s = 0, previous_s = 0;
  double gaze_x = 0.5, gaze_y = 0.5;  // normalised gaze point (eccentricity)
  const GBuffer* last_frame = nullptr;  // luminance contrast per object (Brown); null: 0
  std::function<double(std::uint32_t)> attention;  // S_o of an object id; empty: 0
};

// The views of the scene's objects that have a chain (an object without one is drawn at full detail
// and not listed); object_index[k] is views[k]'s index in scene.objects.
std::vector<ObjectView> object_views(const Scene& scene, const ViewInputs& in, BoundsCache& bounds,
                                     std::vector<std::size_t>& object_index);

// ULOD (Lee 2009 §7.3 with Giegl et al.'s unpopping LOD): the levels of the second pass (each object
// at its selection's blend_to, objects without a chain at 0), and whether any object is between
// levels (no second pass needed otherwise).
bool ulod_next_levels(const Scene& scene, const std::vector<Selection>& selection, std::vector<std::uint8_t>& levels);
// The pixels the blend reads: those where `base` shows an object between levels (the second pass
// need not be right elsewhere: BackendSettings::pixel_mask).
void ulod_pixel_mask(const GBuffer& base, const std::vector<Selection>& selection, std::vector<std::uint8_t>& mask);
// Blends `next` into `base`'s colour by each object's blend weight where the same object covers the
// pixel in both (where the coarser level does not cover it, the finer one stays: no holes).
void ulod_blend(GBuffer& base, const GBuffer& next, const std::vector<Selection>& selection);

// The proxy G-buffer's size for the attention pass (Lee 2009 §7.2): twice the saliency map's side in
// height (the map's box resample then averages about 2x2 pixels), the camera's aspect, never more
// than the camera's resolution.
void proxy_size(std::uint32_t camera_width, std::uint32_t camera_height, int map_size, std::uint32_t& width,
                std::uint32_t& height);

}  // namespace fovea::render::lod
