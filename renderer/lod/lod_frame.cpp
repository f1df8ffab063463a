// SPDX-License-Identifier: Apache-2.0
#include "lod/lod_frame.h"

#include <algorithm>
#include <cmath>

#include <fovea/protocol/display_geometry.h>

namespace fovea::render::lod {

const BoundsCache::Sphere& BoundsCache::of(const Mesh& mesh) {
  auto& entry = spheres_[&mesh];
  if (entry.first == mesh.positions.size() && entry.first != 0) return entry.second;
  // The box centre and the farthest vertex from it.
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (const glm::vec3& p : mesh.positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  Sphere s;
  s.centre = mesh.positions.empty() ? glm::vec3(0.0f) : 0.5f * (lo + hi);
  float r2 = 0;
  for (const glm::vec3& p : mesh.positions) r2 = std::max(r2, glm::dot(p - s.centre, p - s.centre));
  s.radius = std::sqrt(r2);
  entry = {mesh.positions.size(), s};
  return entry.second;
}

std::vector<ObjectView> object_views(const Scene& scene, const ViewInputs& in, BoundsCache& bounds,
                                     std::vector<std::size_t>& object_index) {
  const Camera& cam = scene.camera;
  const glm::mat4 view = cam.view_at(in.now_s), view_prev = cam.view_at(in.previous_s), proj = cam.projection();
  const glm::vec3 eye = cam.position_at(in.now_s);
  const double px_per_radian =
      static_cast<double>(cam.height) / (2.0 * std::tan(glm::radians(static_cast<double>(cam.vertical_fov_deg)) / 2.0));
  const protocol::Degrees gaze_deg = protocol::normalized_to_degrees(scene.display, {in.gaze_x, in.gaze_y});
  // Per-object luminance contrast from the last frame's G-buffer (Brown's luminance feature).
  std::vector<float> lum_min(scene.objects.size(), 1e30f), lum_max(scene.objects.size(), 0.0f);
  std::unordered_map<std::uint32_t, std::size_t> index_of;
  for (std::size_t i = 0; i < scene.objects.size(); ++i) index_of[scene.objects[i].id] = i;
  if (in.last_frame != nullptr) {
    const GBuffer& g = *in.last_frame;
    for (std::size_t p = 0; p < g.object_id.size() && p < g.color.size(); ++p) {
      const auto it = index_of.find(g.object_id[p]);
      if (it == index_of.end()) continue;
      const glm::vec3 c = g.color[p];
      const float y = 0.2126f * c.r + 0.7152f * c.g + 0.0722f * c.b;
      lum_min[it->second] = std::min(lum_min[it->second], y);
      lum_max[it->second] = std::max(lum_max[it->second], y);
    }
  }
  const auto project = [&](const glm::mat4& v, const glm::vec3& p, glm::dvec2& out) {
    const glm::vec4 clip = proj * v * glm::vec4(p, 1.0f);
    if (!(clip.w > 1e-6f)) return false;
    out = {0.5 * (static_cast<double>(clip.x / clip.w) + 1.0), 0.5 * (1.0 - static_cast<double>(clip.y / clip.w))};
    return true;
  };
  std::vector<ObjectView> views;
  object_index.clear();
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const Object& o = scene.objects[i];
    if (!o.mesh || o.mesh->positions.empty() || o.lods.empty()) continue;  // no chain: full detail, not listed
    const BoundsCache::Sphere& sphere = bounds.of(*o.mesh);
    const Transform now_t = o.transform_at(in.now_s), prev_t = o.transform_at(in.previous_s);
    const glm::vec3 centre = glm::vec3(now_t.matrix() * glm::vec4(sphere.centre, 1.0f));
    const glm::vec3 centre_prev = glm::vec3(prev_t.matrix() * glm::vec4(sphere.centre, 1.0f));
    const float scale = std::max({std::abs(now_t.scale.x), std::abs(now_t.scale.y), std::abs(now_t.scale.z)});
    ObjectView v;
    v.id = o.id;
    v.levels = 1 + static_cast<int>(o.lods.size());
    v.level_error_m.push_back(0.0f);
    v.level_triangles.push_back(o.mesh->triangle_count());
    for (const LodLevel& l : o.lods) {
      v.level_error_m.push_back(l.max_error_m * scale);  // object-space metres to world
      v.level_triangles.push_back(l.mesh ? l.mesh->triangle_count() : 0);
    }
    v.base = o.lods[0].mesh == nullptr || o.lods[0].mesh->triangle_count() == 0
                 ? 4.0
                 : static_cast<double>(o.mesh->triangle_count()) / static_cast<double>(o.lods[0].mesh->triangle_count());
    v.distance_m = static_cast<double>(glm::length(centre - eye));
    v.radius_m = static_cast<double>(sphere.radius * scale);
    v.px_per_radian = px_per_radian;
    v.projected_radius_px = v.distance_m > 0 ? v.radius_m / v.distance_m * px_per_radian : 1e9;
    v.screen_area_px = static_cast<double>(cam.width) * static_cast<double>(cam.height);
    glm::dvec2 sp(0.5), sp_prev(0.5);
    const bool visible = project(view, centre, sp);
    if (visible && project(view_prev, centre_prev, sp_prev)) {
      v.velocity_px_per_frame = glm::length((sp - sp_prev) * glm::dvec2(cam.width, cam.height));
    }
    v.screen_x = sp.x;
    v.screen_y = sp.y;
    v.eccentricity_deg = visible ? protocol::angle_between_deg(gaze_deg, protocol::normalized_to_degrees(scene.display, {sp.x, sp.y}))
                                 : 180.0;
    const glm::vec3 dr = glm::abs(now_t.rotation_deg - prev_t.rotation_deg);
    v.rotation_deg_per_frame = static_cast<double>(std::max({dr.x, dr.y, dr.z}));
    v.luminance_contrast = lum_max[i] > 0 && lum_min[i] < 1e29f
                               ? static_cast<double>((lum_max[i] - lum_min[i]) / (lum_max[i] + lum_min[i]))
                               : 0.0;
    v.attention = in.attention ? in.attention(o.id) : 0.0;
    views.push_back(v);
    object_index.push_back(i);
  }
  return views;
}

bool ulod_next_levels(const Scene& scene, const std::vector<Selection>& selection, std::vector<std::uint8_t>& levels) {
  levels.assign(scene.objects.size(), 0);
  std::unordered_map<std::uint32_t, std::size_t> index_of;
  for (std::size_t i = 0; i < scene.objects.size(); ++i) index_of[scene.objects[i].id] = i;
  bool any = false;
  for (const Selection& sel : selection) {
    const auto it = index_of.find(sel.id);
    if (it == index_of.end()) continue;
    levels[it->second] = static_cast<std::uint8_t>(std::clamp(sel.blend_to, 0, 254));
    if (sel.blend > 0 && sel.blend_to != sel.drawn) any = true;
  }
  return any;
}

void ulod_pixel_mask(const GBuffer& base, const std::vector<Selection>& selection, std::vector<std::uint8_t>& mask) {
  std::unordered_map<std::uint32_t, bool> blends;
  for (const Selection& sel : selection)
    if (sel.blend > 0 && sel.blend_to != sel.drawn) blends[sel.id] = true;
  mask.assign(base.size(), 0);
  for (std::size_t p = 0; p < base.size() && p < base.object_id.size(); ++p)
    if (blends.contains(base.object_id[p])) mask[p] = 1;
}

void proxy_size(std::uint32_t camera_width, std::uint32_t camera_height, int map_size, std::uint32_t& width,
                std::uint32_t& height) {
  height = std::min<std::uint32_t>(camera_height, static_cast<std::uint32_t>(std::max(1, 2 * map_size)));
  const double aspect = camera_height > 0 ? static_cast<double>(camera_width) / camera_height : 1.0;
  width = std::clamp<std::uint32_t>(static_cast<std::uint32_t>(std::lround(height * aspect)), 1u, std::max(1u, camera_width));
  if (camera_width == 0 || camera_height == 0) width = height = 0;
}

void ulod_blend(GBuffer& base, const GBuffer& next, const std::vector<Selection>& selection) {
  std::unordered_map<std::uint32_t, float> blend_of;
  for (const Selection& sel : selection)
    if (sel.blend > 0 && sel.blend_to != sel.drawn) blend_of[sel.id] = static_cast<float>(std::clamp(sel.blend, 0.0, 1.0));
  if (blend_of.empty() || base.size() != next.size()) return;
  for (std::size_t p = 0; p < base.size(); ++p) {
    const auto it = blend_of.find(base.object_id[p]);
    if (it == blend_of.end() || next.object_id[p] != base.object_id[p]) continue;
    base.color[p] = (1.0f - it->second) * base.color[p] + it->second * next.color[p];
  }
}

}  // namespace fovea::render::lod
