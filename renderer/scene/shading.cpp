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

namespace {

// `radiance` plus the sum over the scene's light samples of brdf(l) * E (eq. 5.23, 5.32), E the irradiance at x from
// the sample (eq. 5.33, spot smoothstep, area cosine emitter); samples behind the normal or
// occluded add nothing.
template <class Brdf>
glm::vec3 sum_lights(glm::vec3 radiance, const Scene& scene, const glm::vec3& x, const glm::vec3& n,
                     VisibilityFn visible, void* context, const Brdf& brdf) {
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
      radiance += brdf(l) * (s.power * (emit * cos_theta / d2));
    }
  }
  return radiance;
}

glm::vec3 view_direction(const glm::vec3& x, const glm::vec3& eye, const glm::vec3& n) {
  const glm::vec3 to_eye = eye - x;
  const float eye_dist = glm::length(to_eye);
  return eye_dist > 0 ? to_eye / eye_dist : n;
}

constexpr float kMinAlpha = 1e-3f;  // GGX alpha floor (pbr_brdf)

}  // namespace

glm::vec3 shade_local(const Scene& scene, const Material& m, const glm::vec3& x, const glm::vec3& n,
                      const glm::vec3& eye, VisibilityFn visible, void* context) {
  if (m.type == MaterialType::MetallicRoughness) {
    SurfacePoint point;
    point.position = x;
    point.normal = n;
    return shade_pbr(scene, evaluate_pbr(scene, m.pbr, point), x, eye, visible, context);
  }
  if (m.type == MaterialType::Emissive) return finite_or_zero(m.emission + m.kd * scene.ambient);
  const glm::vec3 v = view_direction(x, eye, n);
  return finite_or_zero(sum_lights(m.kd * scene.ambient, scene, x, n, visible, context, [&](const glm::vec3& l) {
    const glm::vec3 h = glm::normalize(l + v);  // eq. 5.21
    const float n_dot_h = std::max(0.0f, glm::dot(n, h));
    return m.ks * std::pow(n_dot_h, m.shininess) + m.kd;  // eq. 5.22
  }));
}

glm::vec4 sample_binding(const Scene& scene, const TextureBinding& b, const SurfacePoint& point) {
  if (b.texture >= scene.textures.size() || !scene.textures[b.texture]) return glm::vec4(1.0f);
  const TextureImage& image = *scene.textures[b.texture];
  const std::uint32_t set = std::min<std::uint32_t>(b.tex_coord, 1);
  return sample_texture(image, b.sampler, point.uv[set], point.lod[set] + texel_area_lod(image));
}

float pbr_alpha(const Scene& scene, const PbrParameters& m, const SurfacePoint& point) {
  float alpha = m.base_color.a * point.color.a;
  if (m.base_color_texture) alpha *= sample_binding(scene, *m.base_color_texture, point).a;
  return std::isfinite(alpha) ? std::clamp(alpha, 0.0f, 1.0f) : 1.0f;
}

SurfaceSample evaluate_pbr(const Scene& scene, const PbrParameters& m, const SurfacePoint& point) {
  SurfaceSample s;
  glm::vec4 base = m.base_color * point.color;
  if (m.base_color_texture) base *= sample_binding(scene, *m.base_color_texture, point);
  s.base_color = glm::clamp(finite_or_zero(glm::vec3(base)), 0.0f, 1.0f);
  s.alpha = std::isfinite(base.a) ? std::clamp(base.a, 0.0f, 1.0f) : 1.0f;
  float metallic = m.metallic, roughness = m.roughness;
  if (m.metallic_roughness_texture) {
    const glm::vec4 t = sample_binding(scene, *m.metallic_roughness_texture, point);
    metallic *= t.b;
    roughness *= t.g;
  }
  s.metallic = std::isfinite(metallic) ? std::clamp(metallic, 0.0f, 1.0f) : 1.0f;
  s.roughness = std::isfinite(roughness) ? std::clamp(roughness, 0.0f, 1.0f) : 1.0f;
  if (m.occlusion_texture) {
    const float r = sample_binding(scene, *m.occlusion_texture, point).r;
    s.occlusion = std::clamp(1.0f + m.occlusion_strength * (r - 1.0f), 0.0f, 1.0f);
    if (!std::isfinite(s.occlusion)) s.occlusion = 1;
  }
  glm::vec3 emission = m.emissive;
  if (m.emissive_texture) emission *= glm::vec3(sample_binding(scene, *m.emissive_texture, point));
  s.emission = glm::max(finite_or_zero(emission), glm::vec3(0.0f));
  s.normal = point.normal;
  const glm::vec3 t_raw(point.tangent);
  if (m.normal_texture && glm::dot(t_raw, t_raw) > 0) {
    const glm::vec3 n = point.normal;
    const glm::vec3 t_ortho = t_raw - n * glm::dot(n, t_raw);  // Gram-Schmidt against the normal
    const float t_len = glm::length(t_ortho);
    if (t_len > 1e-12f && std::isfinite(t_len)) {
      const glm::vec3 t = t_ortho / t_len;
      const glm::vec3 b = glm::cross(n, t) * (point.tangent.w < 0 ? -1.0f : 1.0f);
      glm::vec3 tn = glm::vec3(sample_binding(scene, *m.normal_texture, point)) * 2.0f - 1.0f;
      tn.x *= m.normal_scale;
      tn.y *= m.normal_scale;
      glm::vec3 bent = t * tn.x + b * tn.y + n * tn.z;
      const float len = glm::length(bent);
      // A map pointing below the surface (or a zero texel) keeps the interpolated normal.
      if (len > 1e-12f && std::isfinite(len) && glm::dot(bent, n) > 0) s.normal = bent / len;
    }
  }
  if (point.back_face) s.normal = -s.normal;
  return s;
}

glm::vec3 pbr_brdf(const SurfaceSample& s, const glm::vec3& l, const glm::vec3& v) {
  const glm::vec3 n = s.normal;
  const float n_dot_l = std::max(0.0f, glm::dot(n, l));
  const float n_dot_v = std::max(1e-4f, std::abs(glm::dot(n, v)));
  if (n_dot_l <= 0) return glm::vec3(0.0f);
  glm::vec3 h = l + v;
  const float h_len = glm::length(h);
  h = h_len > 1e-12f ? h / h_len : n;
  const float n_dot_h = std::max(0.0f, glm::dot(n, h));
  const float v_dot_h = std::clamp(std::abs(glm::dot(v, h)), 0.0f, 1.0f);
  const float alpha = std::max(s.roughness * s.roughness, kMinAlpha), a2 = alpha * alpha;
  const glm::vec3 c_diff = glm::mix(s.base_color, glm::vec3(0.0f), s.metallic);
  const glm::vec3 f0 = glm::mix(glm::vec3(0.04f), s.base_color, s.metallic);
  const float fw = std::pow(1.0f - v_dot_h, 5.0f);
  const glm::vec3 fresnel = f0 + (glm::vec3(1.0f) - f0) * fw;
  const float denom_d = n_dot_h * n_dot_h * (a2 - 1.0f) + 1.0f;
  const float d = a2 / (kPi * denom_d * denom_d);
  const float vis = 1.0f / ((n_dot_l + std::sqrt(a2 + (1.0f - a2) * n_dot_l * n_dot_l)) *
                            (n_dot_v + std::sqrt(a2 + (1.0f - a2) * n_dot_v * n_dot_v)));
  return (glm::vec3(1.0f) - fresnel) * c_diff / kPi + fresnel * (d * vis);
}

glm::vec3 shade_pbr(const Scene& scene, const SurfaceSample& sample, const glm::vec3& x, const glm::vec3& eye,
                    VisibilityFn visible, void* context) {
  const glm::vec3 n = sample.normal;
  const glm::vec3 v = view_direction(x, eye, n);
  const glm::vec3 c_diff = glm::mix(sample.base_color, glm::vec3(0.0f), sample.metallic);
  const glm::vec3 f0 = glm::mix(glm::vec3(0.04f), sample.base_color, sample.metallic);
  const glm::vec3 unlit = sample.emission + scene.ambient * (c_diff + f0) * sample.occlusion;
  return finite_or_zero(sum_lights(unlit, scene, x, n, visible, context,
                                   [&](const glm::vec3& l) { return pbr_brdf(sample, l, v); }));
}

}  // namespace fovea::render
