// SPDX-License-Identifier: Apache-2.0
#include "scene/scene.h"

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>

namespace fovea::render {

bool all_finite(const Mesh& m) {
  const auto finite = [](const glm::vec3& v) { return all_finite(v); };
  const auto finite2 = [](const glm::vec2& v) { return std::isfinite(v.x) && std::isfinite(v.y); };
  const auto finite4 = [](const glm::vec4& v) { return all_finite(glm::vec3(v)) && std::isfinite(v.w); };
  return std::all_of(m.positions.begin(), m.positions.end(), finite) &&
         std::all_of(m.normals.begin(), m.normals.end(), finite) &&
         std::all_of(m.texcoords0.begin(), m.texcoords0.end(), finite2) &&
         std::all_of(m.texcoords1.begin(), m.texcoords1.end(), finite2) &&
         std::all_of(m.colors.begin(), m.colors.end(), finite4) &&
         std::all_of(m.tangents.begin(), m.tangents.end(), finite4);
}

glm::mat4 Transform::matrix() const {
  if (matrix_override) {
    // An animation adds its translation to an imported node's matrix (rotation keys do not apply).
    glm::mat4 m = *matrix_override;
    m[3] = glm::vec4(translation, 1.0f);
    return m;
  }
  glm::mat4 m = glm::translate(glm::mat4(1.0f), translation);
  m = glm::rotate(m, glm::radians(rotation_deg.z), glm::vec3(0, 0, 1));
  m = glm::rotate(m, glm::radians(rotation_deg.y), glm::vec3(0, 1, 0));
  m = glm::rotate(m, glm::radians(rotation_deg.x), glm::vec3(1, 0, 0));
  return glm::scale(m, scale);
}

Transform Animation::apply(const Transform& base, double t) const {
  if (keys.empty()) return base;
  const double first = keys.front().time_s, last = keys.back().time_s;
  if (loop && last > first) {
    t = first + std::fmod(t - first, last - first);
    if (t < first) t += last - first;
  }
  t = std::clamp(t, first, last);
  const auto next = std::upper_bound(keys.begin(), keys.end(), t,
                                     [](double v, const AnimationKey& k) { return v < k.time_s; });
  Transform out = base;
  if (next == keys.begin() || next == keys.end()) {
    const AnimationKey& k = next == keys.begin() ? keys.front() : keys.back();
    out.translation += k.translation;
    out.rotation_deg += k.rotation_deg;
    return out;
  }
  const AnimationKey& a = *(next - 1);
  const AnimationKey& b = *next;
  const auto f = static_cast<float>((t - a.time_s) / (b.time_s - a.time_s));
  out.translation += glm::mix(a.translation, b.translation, f);
  out.rotation_deg += glm::mix(a.rotation_deg, b.rotation_deg, f);
  return out;
}

const char* to_string(MaterialType t) {
  switch (t) {
    case MaterialType::Lambertian: return "lambertian";
    case MaterialType::BlinnPhong: return "blinn-phong";
    case MaterialType::Mirror: return "mirror";
    case MaterialType::Glass: return "glass";
    case MaterialType::Emissive: return "emissive";
    case MaterialType::MetallicRoughness: return "metallic-roughness";
  }
  return "?";
}

const char* to_string(AlphaMode m) {
  switch (m) {
    case AlphaMode::Opaque: return "OPAQUE";
    case AlphaMode::Mask: return "MASK";
    case AlphaMode::Blend: return "BLEND";
  }
  return "?";
}

const char* to_string(LightType t) {
  switch (t) {
    case LightType::Point: return "point";
    case LightType::Spot: return "spot";
    case LightType::Area: return "area";
  }
  return "?";
}

Lens Lens::human_eye(double focus_distance_m) {
  Lens l;
  l.focal_length_m = 0.0167;
  l.aperture_m = 0.004;
  l.image_distance_m = 0.024;
  l.focus_distance_m = focus_distance_m;
  return l;
}

glm::vec3 Camera::right() const { return glm::normalize(glm::cross(target - position, up)); }

double Camera::eye_shift_x(double depth_m) const {
  if (eye_offset_m == 0 || !(depth_m > 0) || std::isinf(depth_m)) return 0;
  const double aspect = static_cast<double>(width) / static_cast<double>(height);
  const double p00 = 1.0 / (aspect * std::tan(0.5 * glm::radians(static_cast<double>(vertical_fov_deg))));
  return -p00 * static_cast<double>(eye_offset_m) / (2.0 * depth_m);
}

glm::vec3 Camera::position_at(double t) const {
  const glm::vec3 eye = eye_offset_m != 0 ? right() * eye_offset_m : glm::vec3(0);
  return (animation ? animation->apply(Transform{position, {}, {1, 1, 1}, std::nullopt}, t).translation : position) + eye;
}

glm::mat4 Camera::view_at(double t) const {
  // The animation and the eye move position and target together: the view axes stay parallel.
  const glm::vec3 offset = position_at(t) - position;
  return glm::lookAt(position + offset, target + offset, up);
}

glm::mat4 Camera::projection() const {
  return glm::perspective(glm::radians(vertical_fov_deg), static_cast<float>(width) / static_cast<float>(height),
                          near_m, far_m);
}

bool Scene::has_specular_or_refractive() const {
  return std::any_of(objects.begin(), objects.end(),
                     [&](const Object& o) { return materials.at(o.material).is_specular_or_refractive(); });
}

bool Scene::has_textures() const {
  return std::any_of(materials.begin(), materials.end(), [](const Material& m) {
    return m.type == MaterialType::MetallicRoughness && m.pbr.has_textures();
  });
}

bool Scene::has_animation() const {
  return camera.animation.has_value() ||
         std::any_of(objects.begin(), objects.end(), [](const Object& o) { return o.animation.has_value(); });
}

bool Scene::has_lods() const {
  return std::any_of(objects.begin(), objects.end(), [](const Object& o) { return !o.lods.empty(); });
}

const Object* Scene::object_by_id(std::uint32_t id) const {
  for (const Object& o : objects) {
    if (o.id == id) return &o;
  }
  return nullptr;
}

}  // namespace fovea::render
