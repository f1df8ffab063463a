// SPDX-License-Identifier: Apache-2.0
// What the photon map's stand-in for glTF's BRDF costs in accuracy (renderer/gi/GI.md): photons on a
// MetallicRoughness surface scatter with the Blinn-Phong that material_from_gltf derives from its
// factors (diffuse albedo kd = base (1 - metallic), glossy albedo ks = mix(0.04, base, metallic) in a
// Phong lobe of n = 2/alpha^2 - 2), while the G-buffer and the eye paths' direct light use appendix
// B (scene/shading.h pbr_brdf). This integrates both over the hemisphere for one incidence angle at
// a time, the directional albedo E(mu) = int f(l, v) cos(theta_l) dl, and prints them side by side
// with their relative difference: the energy the substitute adds or loses per bounce.
// Usage: bench_pbr_substitute   (a table; midpoint quadrature of 2048 x 2048 directions per row)
#include <cmath>
#include <cstdio>
#include <numbers>

#include "scene/shading.h"

using namespace fovea::render;

namespace {

// E(mu) of appendix B for grey base colour `base`, at view direction with cos = mu.
double albedo_pbr(float base, float metallic, float roughness, float mu, int n_theta, int n_phi) {
  SurfaceSample s;
  s.base_color = glm::vec3(base);
  s.metallic = metallic;
  s.roughness = roughness;
  s.normal = glm::vec3(0, 0, 1);
  const glm::vec3 v(std::sqrt(1 - mu * mu), 0, mu);
  double sum = 0;
  // Midpoints in theta and phi, d omega = sin(theta) d theta d phi: fine enough for the narrowest lobe
  // here (roughness 0.1: alpha 0.01, about 0.02 rad wide).
  const double d_theta = 0.5 * std::numbers::pi / n_theta, d_phi = 2 * std::numbers::pi / n_phi;
  for (int i = 0; i < n_theta; ++i) {
    const double theta = (i + 0.5) * d_theta, c = std::cos(theta), sin_t = std::sin(theta);
    for (int j = 0; j < n_phi; ++j) {
      const double phi = (j + 0.5) * d_phi;
      const glm::vec3 l(static_cast<float>(sin_t * std::cos(phi)), static_cast<float>(sin_t * std::sin(phi)),
                        static_cast<float>(c));
      sum += static_cast<double>(pbr_brdf(s, l, v).g) * c * sin_t * d_theta * d_phi;
    }
  }
  return sum;
}

}  // namespace

int main() {
  std::printf("# directional albedo E(mu) = int f cos: glTF appendix B against the photon map's Blinn-Phong "
              "(kd + ks; both lobes conserve their albedo when sampled)\n");
  std::printf("%-6s %-9s %-10s %-5s %10s %10s %10s\n", "base", "metallic", "roughness", "mu", "appendixB", "substitute",
              "rel.diff");
  for (const float base : {0.2f, 0.8f}) {
    for (const float metallic : {0.0f, 1.0f}) {
      for (const float roughness : {0.1f, 0.3f, 0.6f, 1.0f}) {
        for (const float mu : {1.0f, 0.5f, 0.15f}) {
          const double e = albedo_pbr(base, metallic, roughness, mu, 2048, 2048);
          const double kd = static_cast<double>(base * (1 - metallic)), ks = static_cast<double>(0.04f * (1 - metallic) + base * metallic);
          const double sub = kd + ks;
          std::printf("%-6.1f %-9.0f %-10.1f %-5.2f %10.4f %10.4f %+9.1f%%\n", static_cast<double>(base),
                      static_cast<double>(metallic), static_cast<double>(roughness), static_cast<double>(mu), e, sub,
                      100 * (sub - e) / e);
        }
      }
    }
  }
  return 0;
}
