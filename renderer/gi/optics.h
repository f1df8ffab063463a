// SPDX-License-Identifier: Apache-2.0
#pragma once
// Small optics shared by the photon tracer and the GI render: reflection, Fresnel refraction,
// ray-origin offsets, tangent frames and direction sampling.
#include <algorithm>
#include <cmath>
#include <glm/glm.hpp>
#include <numbers>

namespace fovea::render::gi::optics {

inline bool finite3(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

inline glm::vec3 reflect(const glm::vec3& d, const glm::vec3& n) { return d - 2.0f * glm::dot(d, n) * n; }

// Unpolarised Fresnel reflectance of a dielectric for unit direction d arriving at unit normal n
// (dot(d, n) < 0), eta = n_incident / n_transmitted. Returns 1 for total internal reflection and
// writes the refracted direction otherwise (Snell's law).
inline float fresnel_dielectric(const glm::vec3& d, const glm::vec3& n, float eta, glm::vec3& refracted) {
  const float cos_i = -glm::dot(d, n);
  const float sin2_t = eta * eta * std::max(0.0f, 1.0f - cos_i * cos_i);
  if (sin2_t >= 1.0f) return 1.0f;
  const float cos_t = std::sqrt(1.0f - sin2_t);
  refracted = glm::normalize(eta * d + (eta * cos_i - cos_t) * n);
  const float rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  const float rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  return std::clamp(0.5f * (rs * rs + rp * rp), 0.0f, 1.0f);
}

// Offset of a new ray's origin off a surface: relative to the coordinates' size (float spacing grows
// with magnitude), as the G-buffer's shadow rays do.
inline float surface_epsilon(const glm::vec3& p) {
  return 1e-4f * std::max({1.0f, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
}

// Two unit tangents of a plane with unit normal n (the same construction as scene/shading.cpp's
// area-light samples, so photons leave the same rectangle local illumination samples).
inline void tangents(const glm::vec3& n, glm::vec3& t, glm::vec3& b) {
  const glm::vec3 helper = std::abs(n.y) < 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
  t = glm::normalize(glm::cross(helper, n));
  b = glm::cross(n, t);
}

// A direction around unit n with pdf cos(theta) / pi (Malley: a uniform disc point lifted).
inline glm::vec3 cosine_direction(const glm::vec3& n, float u1, float u2) {
  glm::vec3 t, b;
  tangents(n, t, b);
  const float r = std::sqrt(u1), phi = 2 * std::numbers::pi_v<float> * u2;
  const float x = r * std::cos(phi), y = r * std::sin(phi), z = std::sqrt(std::max(0.0f, 1.0f - u1));
  return glm::normalize(t * x + b * y + n * z);
}

}  // namespace fovea::render::gi::optics
