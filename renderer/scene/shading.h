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

// PBR materials (MaterialType::MetallicRoughness) use the glTF 2.0 specification's appendix B BRDF
// instead, with the same lights, irradiance and ambient (shade_pbr below).

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

// A surface point as a backend interpolates it at a hit, for materials with textures.
struct SurfacePoint {
  glm::vec3 position{0.0f};  // world space
  glm::vec3 normal{0, 0, 1};  // unit interpolated normal of the front side (as the mesh gives it)
  bool back_face = false;     // the eye sees the back side: the shading normal is turned round
  // World-space tangent; the bitangent is cross(normal, tangent) * w. xyz 0 when the mesh has none.
  glm::vec4 tangent{0.0f};
  glm::vec2 uv[2] = {glm::vec2(0.0f), glm::vec2(0.0f)};
  glm::vec4 color{1.0f};     // vertex colour (COLOR_0), 1 when the mesh has none
  // Level of detail per texture-coordinate set without the texture's own size: the ray cone's
  // log2(width / |n.d|) + 0.5 log2(uv area / world area) (Akenine-Möller et al. 2019, eq. 34);
  // sampling adds texel_area_lod of the texture.
  float lod[2] = {0, 0};
};

// What a PBR material is at a point: its factors times its textures.
struct SurfaceSample {
  glm::vec3 base_color{1.0f};
  float alpha = 1;
  float metallic = 1, roughness = 1, occlusion = 1;
  glm::vec3 emission{0.0f};
  glm::vec3 normal{0, 0, 1};  // after the normal map, unit, on the eye's side
};

// The texture a binding names, sampled at the point's coordinates and level; 1 where the binding
// names no texture the scene has.
glm::vec4 sample_binding(const Scene& scene, const TextureBinding& binding, const SurfacePoint& point);

// Base colour alpha at the point (the factor, the texture's alpha and COLOR_0's alpha): what MASK tests.
float pbr_alpha(const Scene& scene, const PbrParameters& m, const SurfacePoint& point);

// The material's parameters at the point: base colour (factor x texture x COLOR_0), metallic and
// roughness (factor x texture B, G), occlusion (1 + strength (R - 1)), emission, and the normal
// bent by the normal map in the front side's frame (n = normalize(T x + B y + N z), x and y scaled
// by normal_scale, B = w cross(N, T)), then turned round on a back face: the back of a bump is a
// dent (as Khronos' sample viewer flips T, B and N). Values clamped to their ranges; never NaN.
SurfaceSample evaluate_pbr(const Scene& scene, const PbrParameters& m, const SurfacePoint& point);

// The appendix B BRDF at the sample, towards light l from view direction v (unit, both on the
// normal's side): Lambert diffuse c_diff / pi weighted by (1 - F), GGX D with the height-correlated
// Smith V, F Schlick's with f0 = mix(0.04, base, metallic); alpha = roughness^2, at least 1e-3 so
// that a perfectly smooth surface stays finite under a point light.
glm::vec3 pbr_brdf(const SurfaceSample& s, const glm::vec3& l, const glm::vec3& v);

// shade_local for a PBR sample: sum over light samples of brdf * irradiance, plus the ambient times
// (c_diff + f0) times occlusion, plus the emission.
glm::vec3 shade_pbr(const Scene& scene, const SurfaceSample& sample, const glm::vec3& position, const glm::vec3& eye,
                    VisibilityFn visible = nullptr, void* visibility_context = nullptr);

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
