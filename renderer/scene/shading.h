// SPDX-License-Identifier: Apache-2.0
#pragma once
// Local illumination with the modified Blinn-Phong BRDF, shared by the Embree backend (C++) and the
// OpenGL backend (the GLSL in backend/gl/shaders.h implements the same formulas; a test compares
// them). Jensen & Pedersen 2009, §5.2-5.3:
//   f_r = k_s (n.h)^n + k_d                      (eq. 5.22, h the half vector, eq. 5.21)
//   E   = Phi_s / (4 pi d^2) cos(theta)          (eq. 5.33, point light, r << d)
//   L_o = sum_j f_r E_j                          (eq. 5.23, 5.32)
// plus an ambient term k_d * ambient. Spot lights scale E by a smooth cone falloff; area lights
// are n x n point lights sharing the power, each radiating into the front half-space with a cosine
// (a Lambertian emitter: the 4 pi of a point light becomes pi).
#include <glm/glm.hpp>
#include <span>

#include "scene/scene.h"

namespace fovea::render {

// Visibility callback for shadows: true if the segment from `from` to `to` is unoccluded. nullptr
// means every light is visible (no shadows).
using VisibilityFn = bool (*)(void* context, const glm::vec3& from, const glm::vec3& to);

// Radiance leaving `position` towards `eye`. `normal` is the unit shading normal (facing the eye).
// Emissive materials return their emission; mirror and glass return the local-illumination view
// of them (specular highlight of their reflectance; their reflections/refractions belong to the
// GI pass). Never returns NaN or Inf.
glm::vec3 shade_local(const Scene& scene, const Material& material, const glm::vec3& position,
                      const glm::vec3& normal, const glm::vec3& eye, VisibilityFn visible = nullptr,
                      void* visibility_context = nullptr);

// The point-light samples a light stands for in local illumination (1 for point/spot, n*n for area).
struct LightSample {
  glm::vec3 position;
  glm::vec3 power;       // share of the light's power
  glm::vec3 direction;   // emitter normal (area) or spot axis
  int kind;              // 0 point (isotropic), 1 spot, 2 area (cosine emitter)
  float cos_cutoff, cos_falloff_start;
};
void light_samples(const Light& light, std::vector<LightSample>& out);

}  // namespace fovea::render
