// SPDX-License-Identifier: Apache-2.0
#include "scene/shading.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace fovea::render {

namespace {
constexpr float kPi = std::numbers::pi_v<float>;

glm::vec3 finite_or_zero(const glm::vec3& v) {
  return {std::isfinite(v.x) ? v.x : 0.0f, std::isfinite(v.y) ? v.y : 0.0f, std::isfinite(v.z) ? v.z : 0.0f};
}

// Two unit tangents of an area light's plane.
void tangents(const glm::vec3& n, glm::vec3& t, glm::vec3& b) {
  const glm::vec3 helper = std::abs(n.y) < 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
  t = glm::normalize(glm::cross(helper, n));
  b = glm::cross(n, t);
}
}  // namespace

void light_samples(const Light& light, std::vector<LightSample>& out) {
  out.clear();
  const glm::vec3 dir = glm::length(light.direction) > 0 ? glm::normalize(light.direction) : glm::vec3(0, -1, 0);
  switch (light.type) {
    case LightType::Point:
      out.push_back({light.position, light.power, dir, 0, -1.0f, -1.0f});
      return;
    case LightType::Spot: {
      const float cutoff = std::cos(glm::radians(light.spot_cutoff_deg));
      const float inner = std::cos(glm::radians(std::max(0.0f, light.spot_cutoff_deg - light.spot_falloff_deg)));
      out.push_back({light.position, light.power, dir, 1, cutoff, std::max(inner, cutoff + 1e-6f)});
      return;
    }
    case LightType::Area: {
      const int n = std::max(1, light.area_samples);
      glm::vec3 t, b;
      tangents(dir, t, b);
      const glm::vec3 share = light.power / static_cast<float>(n * n);
      for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
          const float u = (static_cast<float>(i) + 0.5f) / static_cast<float>(n) - 0.5f;
          const float v = (static_cast<float>(j) + 0.5f) / static_cast<float>(n) - 0.5f;
          out.push_back({light.position + t * (u * light.area_size.x) + b * (v * light.area_size.y), share, dir, 2,
                         -1.0f, -1.0f});
        }
      }
      return;
    }
  }
}

glm::vec3 shade_local(const Scene& scene, const Material& m, const glm::vec3& x, const glm::vec3& n,
                      const glm::vec3& eye, VisibilityFn visible, void* context) {
  if (m.type == MaterialType::Emissive) return finite_or_zero(m.emission + m.kd * scene.ambient);
  const glm::vec3 to_eye = eye - x;
  const float eye_dist = glm::length(to_eye);
  const glm::vec3 v = eye_dist > 0 ? to_eye / eye_dist : n;
  glm::vec3 radiance = m.kd * scene.ambient;
  thread_local std::vector<LightSample> samples;
  for (const Light& light : scene.lights) {
    light_samples(light, samples);
    for (const LightSample& s : samples) {
      const glm::vec3 to_light = s.position - x;
      const float d2 = glm::dot(to_light, to_light);
      if (!(d2 > 1e-12f)) continue;
      const float d = std::sqrt(d2);
      const glm::vec3 l = to_light / d;
      const float cos_theta = glm::dot(n, l);
      if (cos_theta <= 0) continue;
      float emit = 1.0f / (4 * kPi);  // isotropic point light: E = Phi / (4 pi d^2) cos(theta), eq. 5.33
      if (s.kind == 1) {
        const float c = glm::dot(-l, s.direction);
        const float t = std::clamp((c - s.cos_cutoff) / (s.cos_falloff_start - s.cos_cutoff), 0.0f, 1.0f);
        emit *= t * t * (3 - 2 * t);  // smoothstep across the soft edge
      } else if (s.kind == 2) {
        emit = std::max(0.0f, glm::dot(-l, s.direction)) / kPi;  // Lambertian emitter
      }
      if (emit <= 0) continue;
      if (visible != nullptr && !visible(context, x, s.position)) continue;
      const glm::vec3 irradiance = s.power * (emit * cos_theta / d2);
      const glm::vec3 h = glm::normalize(l + v);  // eq. 5.21
      const float n_dot_h = std::max(0.0f, glm::dot(n, h));
      const glm::vec3 brdf = m.ks * std::pow(n_dot_h, m.shininess) + m.kd;  // eq. 5.22
      radiance += brdf * irradiance;
    }
  }
  return finite_or_zero(radiance);
}

}  // namespace fovea::render
