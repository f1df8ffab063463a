// SPDX-License-Identifier: Apache-2.0
#include "gi/photon_tracer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include "backend/embree/embree_backend.h"
#include "gi/optics.h"

namespace fovea::render::gi {

namespace {

using optics::cosine_direction;
using optics::finite3;
using optics::fresnel_dielectric;
using optics::reflect;
using optics::surface_epsilon;
using optics::tangents;

constexpr float kPi = std::numbers::pi_v<float>;

float mean(const glm::vec3& v) { return (v.x + v.y + v.z) / 3.0f; }
// Russian roulette's probability for a coloured reflectance: its largest channel (Jensen 2001,
// §5.2.1), so that power * reflectance / probability never grows in any channel.
float max3(const glm::vec3& v) { return std::max({v.x, v.y, v.z}); }
glm::vec3 clamp01(const glm::vec3& v) {
  const auto c = [](float x) { return std::isfinite(x) ? std::clamp(x, 0.0f, 1.0f) : 0.0f; };
  return {c(v.x), c(v.y), c(v.z)};
}

// A direction around unit axis with pdf (e + 1) / (2 pi) cos^e(alpha): the Phong lobe.
glm::vec3 lobe_direction(const glm::vec3& axis, float exponent, float u1, float u2) {
  glm::vec3 t, b;
  tangents(axis, t, b);
  const float cos_a = std::pow(u1, 1.0f / (exponent + 1.0f));
  const float sin_a = std::sqrt(std::max(0.0f, 1.0f - cos_a * cos_a));
  const float phi = 2 * kPi * u2;
  return glm::normalize(t * (sin_a * std::cos(phi)) + b * (sin_a * std::sin(phi)) + axis * cos_a);
}

}  // namespace

Pcg32::Pcg32(std::uint64_t seed, std::uint64_t stream) : inc_((stream << 1u) | 1u) {
  next();
  state_ += seed;
  next();
}

std::uint32_t Pcg32::next() {
  const std::uint64_t old = state_;
  state_ = old * 6364136223846793005ULL + inc_;
  const auto xorshifted = static_cast<std::uint32_t>(((old >> 18u) ^ old) >> 27u);
  const auto rot = static_cast<std::uint32_t>(old >> 59u);
  return (xorshifted >> rot) | (xorshifted << ((32u - rot) & 31u));
}

float Pcg32::uniform() { return static_cast<float>(next() >> 8) * 0x1p-24f; }

std::uint32_t hash_seed(std::uint64_t a, std::uint64_t b, std::uint64_t c) {
  std::uint64_t z = a * 0x9E3779B97F4A7C15ULL ^ (b + 0x632BE59BD9B4E019ULL) * 0xC2B2AE3D27D4EB4FULL ^ (c + 1) * 0x165667B19E3779F9ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return static_cast<std::uint32_t>(z ^ (z >> 31));
}

std::vector<double> light_shares(const Scene& scene) {
  std::vector<double> share(scene.lights.size(), 0.0);
  double total = 0;
  for (std::size_t i = 0; i < scene.lights.size(); ++i) {
    const glm::vec3 p = scene.lights[i].power;
    const double m = (static_cast<double>(p.x) + static_cast<double>(p.y) + static_cast<double>(p.z)) / 3.0;
    share[i] = std::isfinite(m) && m > 0 && finite3(scene.lights[i].position) ? m : 0.0;
    total += share[i];
  }
  for (double& s : share) s = total > 0 ? s / total : 0.0;
  return share;
}

glm::vec3 emitted_power(const Light& light, const glm::vec3& direction) {
  glm::vec3 power = glm::max(light.power, glm::vec3(0.0f));
  if (light.type == LightType::Spot) {
    glm::vec3 axis = light.direction;
    if (!(glm::length(axis) > 0) || !finite3(axis)) axis = glm::vec3(0, -1, 0);
    axis = glm::normalize(axis);
    const float cutoff = std::cos(glm::radians(std::clamp(light.spot_cutoff_deg, 0.0f, 180.0f)));
    const float inner = std::cos(glm::radians(std::clamp(light.spot_cutoff_deg - light.spot_falloff_deg, 0.0f, 180.0f)));
    const float start = std::max(inner, cutoff + 1e-6f);
    const float x = std::clamp((glm::dot(direction, axis) - cutoff) / (start - cutoff), 0.0f, 1.0f);
    power *= (1 - cutoff) / 2 * (x * x * (3 - 2 * x));
  }
  return finite3(power) ? power : glm::vec3(0.0f);
}

EmittedPhoton emit_from_light(const Scene& scene, std::size_t light_index, std::uint32_t seed) {
  EmittedPhoton e;
  e.light = static_cast<std::uint8_t>(std::min<std::size_t>(light_index, 255));
  e.seed = seed;
  if (light_index >= scene.lights.size()) return e;
  const Light& light = scene.lights[light_index];
  Pcg32 rng(seed, 0x5eed);  // emission draws from its own stream of the trace's seed
  const float u1 = rng.uniform(), u2 = rng.uniform();
  glm::vec3 axis = light.direction;
  if (!(glm::length(axis) > 0) || !finite3(axis)) axis = glm::vec3(0, -1, 0);
  axis = glm::normalize(axis);
  e.origin = light.position;
  e.power = glm::max(light.power, glm::vec3(0.0f));
  switch (light.type) {
    case LightType::Point: {  // Algorithm 6.1's uniform sphere, by inversion instead of rejection
      const float z = 1 - 2 * u1, r = std::sqrt(std::max(0.0f, 1 - z * z)), phi = 2 * kPi * u2;
      e.direction = {r * std::cos(phi), r * std::sin(phi), z};
      break;
    }
    case LightType::Spot: {
      // Uniform inside the cutoff cone (solid angle 2 pi (1 - cos c)); the power is the cone's share
      // of a point light's, times the smoothstep falloff local illumination uses (shading.cpp).
      const float cutoff = std::cos(glm::radians(std::clamp(light.spot_cutoff_deg, 0.0f, 180.0f)));
      const float cos_a = 1 - u1 * (1 - cutoff), sin_a = std::sqrt(std::max(0.0f, 1 - cos_a * cos_a));
      glm::vec3 t, b;
      tangents(axis, t, b);
      const float phi = 2 * kPi * u2;
      e.direction = glm::normalize(t * (sin_a * std::cos(phi)) + b * (sin_a * std::sin(phi)) + axis * cos_a);
      e.power = emitted_power(light, e.direction);
      break;
    }
    case LightType::Area: {  // a uniform point of the rectangle, a cosine-weighted direction
      glm::vec3 t, b;
      tangents(axis, t, b);
      const float u3 = rng.uniform(), u4 = rng.uniform();
      e.origin = light.position + t * ((u3 - 0.5f) * light.area_size.x) + b * ((u4 - 0.5f) * light.area_size.y);
      e.direction = cosine_direction(axis, u1, u2);
      break;
    }
  }
  if (!finite3(e.power) || !finite3(e.direction) || !finite3(e.origin)) e.power = glm::vec3(0.0f);
  return e;
}

namespace {

// One trace's state between surface interactions: its random numbers (one stream per trace seed),
// where it goes next with what power, and what its path has been (stored photons record it).
struct PhotonPath {
  explicit PhotonPath(const EmittedPhoton& start)
      : rng(start.seed), origin(start.origin), dir(start.direction), power(start.power) {}
  Pcg32 rng;
  glm::vec3 origin, dir, power;
  std::uint32_t parent = kNoParent;  // the trace's last stored photon
  std::uint8_t diffuse_bounces = 0;
  bool via_specular = false;
};

// A hit as the photon met it: the side it arrived at and what the material offers there.
struct Arrival {
  const SurfaceHit& hit;
  const Material& m;
  bool from_front;
  glm::vec3 n_face;  // shading normal on the arrival side
  float eps;
  bool diffuse;
  glm::vec3 kd;
};

// Where a photon that survived Russian roulette leaves the surface.
struct Scatter {
  glm::vec3 dir{0.0f}, origin{0.0f};
};

// The hit seen from the photon's side: arrival normal, offset and diffuse reflectance.
Arrival arrival_side(const SurfaceHit& hit, const glm::vec3& dir) {
  const Material& m = *hit.material;
  // The side the photon arrived at (glass is entered from outside, left from inside).
  const bool from_front = glm::dot(dir, hit.geometric_normal) < 0.0f;
  const glm::vec3 n_face = from_front ? hit.normal : -hit.normal;  // shading normal on the arrival side
  const float eps = surface_epsilon(hit.position);
  const bool diffuse = m.is_diffuse_or_glossy();
  // A PBR material's textured diffuse reflectance (SurfaceHit::diffuse_albedo), else its kd.
  const glm::vec3 kd = diffuse ? clamp01(hit.diffuse_albedo()) : glm::vec3(0.0f);
  return {hit, m, from_front, n_face, eps, diffuse, kd};
}

// Store at diffuse surfaces (§6.2.3), black ones too (their irradiance is real; they reflect
// none of it): every hit in the global map; a caustic map keeps only the
// diffuse end of light -> specular+ -> diffuse paths. Returns the stored photon's index in `out`,
// kNoParent where nothing was stored; links it to the trace's previous stored photon.
std::uint32_t store_diffuse_hit(const Arrival& a, const EmittedPhoton& start, const TraceSettings& s, PhotonPath& path,
                                std::vector<Photon>& out) {
  const bool keep = (s.mode == TraceMode::Global || (path.via_specular && path.diffuse_bounces == 0)) &&
                    (!s.store_if || s.store_if(a.hit.position, a.n_face));
  if (!keep) return kNoParent;
  Photon p;
  p.position = a.hit.position;
  p.power = path.power;
  p.incoming = path.dir;
  p.normal = a.n_face;
  p.emission_origin = start.origin;
  p.emission_direction = start.direction;
  p.parent = path.parent;
  p.seed = start.seed;
  p.light = start.light;
  p.diffuse_bounces = path.diffuse_bounces;
  p.via_specular = path.via_specular;
  p.kind = start.kind;
  p.flags = start.kind == EmissionKind::Traditional ? kTraditional : 0;
  const auto stored = static_cast<std::uint32_t>(out.size());
  if (path.parent != kNoParent) out[path.parent].outgoing = path.dir;
  out.push_back(p);
  path.parent = stored;
  return stored;
}

// Eq. 6.3 at a diffuse or glossy (modified Blinn-Phong) surface: diffuse with probability max(kd)
// (guided by `guide` from the photon just stored, §8.4.7, else the cosine lobe), glossy with
// max(ks) in the Phong lobe, else absorbed.
std::optional<Scatter> scatter_diffuse_or_glossy(float u, const Arrival& a, std::uint32_t stored,
                                                 const std::vector<Photon>& out, const DiffuseGuide& guide,
                                                 PhotonPath& path) {
  const Material& m = a.m;
  const glm::vec3 ks = m.is_glossy() ? clamp01(m.ks) : glm::vec3(0.0f);
  float pd = max3(a.kd), ps = max3(ks);
  if (pd + ps > 1.0f) {  // a material reflecting more than it receives: keep the ratio, total 1
    const float t = pd + ps;
    pd /= t;
    ps /= t;
  }
  Scatter next;
  if (u < pd) {
    std::optional<glm::vec3> guided;
    if (guide && stored != kNoParent) guided = guide(out[stored], a.n_face, path.rng);
    next.dir = guided && glm::dot(*guided, a.n_face) > 0 ? *guided
                                                         : cosine_direction(a.n_face, path.rng.uniform(), path.rng.uniform());
    path.power *= a.kd / pd;
    ++path.diffuse_bounces;
  } else if (u < pd + ps) {
    next.dir =
        lobe_direction(reflect(path.dir, a.n_face), std::max(0.0f, m.shininess), path.rng.uniform(), path.rng.uniform());
    if (glm::dot(next.dir, a.n_face) <= 0) return std::nullopt;  // the lobe dipped below the surface: absorbed
    path.power *= ks / ps;
  } else {
    return std::nullopt;  // absorbed
  }
  next.origin = a.hit.position + a.n_face * a.eps;
  return next;
}

// Eq. 6.3 at a mirror: reflected with probability max(reflectance), else absorbed.
std::optional<Scatter> scatter_mirror(float u, const Arrival& a, PhotonPath& path) {
  const glm::vec3 r = clamp01(a.m.reflectance);
  const float pr = max3(r);
  if (!(u < pr)) return std::nullopt;
  Scatter next;
  next.dir = reflect(path.dir, a.n_face);
  next.origin = a.hit.position + a.n_face * a.eps;
  path.power *= r / pr;
  path.via_specular = true;
  return next;
}

// Eq. 6.3 at glass: on with probability max(tint), else absorbed; reflected or refracted by Fresnel.
std::optional<Scatter> scatter_glass(float u, const Arrival& a, PhotonPath& path) {
  const Material& m = a.m;
  const glm::vec3 tint = clamp01(m.reflectance);
  const float pt = max3(tint);
  if (!(u < pt)) return std::nullopt;
  const float ior = std::isfinite(m.ior) && m.ior > 0 ? m.ior : 1.5f;
  const float eta = a.from_front ? 1.0f / ior : ior;
  glm::vec3 refracted(0.0f);
  const float f = fresnel_dielectric(path.dir, a.n_face, eta, refracted);
  Scatter next;
  if (path.rng.uniform() < f) {
    next.dir = reflect(path.dir, a.n_face);
    next.origin = a.hit.position + a.n_face * a.eps;
  } else {
    next.dir = refracted;
    next.origin = a.hit.position - a.n_face * a.eps;
  }
  path.power *= tint / pt;
  path.via_specular = true;
  return next;
}

// Russian roulette (eq. 6.3): reflect, transmit or absorb with the material's probabilities;
// the surviving photon's power is scaled by reflectance / probability per channel. Nothing: absorbed.
std::optional<Scatter> russian_roulette(const Arrival& a, std::uint32_t stored, const std::vector<Photon>& out,
                                        const DiffuseGuide& guide, PhotonPath& path) {
  const float u = path.rng.uniform();
  if (a.diffuse) return scatter_diffuse_or_glossy(u, a, stored, out, guide, path);
  if (a.m.type == MaterialType::Mirror) return scatter_mirror(u, a, path);
  if (a.m.type == MaterialType::Glass) return scatter_glass(u, a, path);
  return std::nullopt;  // emissive (photon rays skip emitters; kept for safety)
}

}  // namespace

std::uint32_t trace_photon(const EmbreeBackend& backend, const EmittedPhoton& start, const TraceSettings& s,
                           std::vector<Photon>& out, const DiffuseGuide& guide) {
  if (!(mean(start.power) > 0) || s.max_depth == 0) return 0;
  PhotonPath path(start);
  std::uint32_t rays = 0;
  SurfaceHit hit;
  for (std::uint32_t depth = 0; depth < s.max_depth; ++depth) {
    ++rays;
    const float t_far = std::numeric_limits<float>::infinity();
    if (!backend.intersect(path.origin, path.dir, 0.0f, t_far, RayVisibility::ShadowCasters, hit)) break;
    const Arrival a = arrival_side(hit, path.dir);
    std::uint32_t stored = kNoParent;
    if (a.diffuse) {
      stored = store_diffuse_hit(a, start, s, path, out);
      if (s.mode == TraceMode::Caustic) break;  // a caustic map ends the trace at its first diffuse surface
    }
    if (s.mode == TraceMode::Caustic && !(a.m.type == MaterialType::Mirror || a.m.type == MaterialType::Glass)) break;
    const std::optional<Scatter> next = russian_roulette(a, stored, out, guide, path);
    if (!next || !finite3(path.power) || !finite3(next->dir) || !(mean(path.power) > 0)) break;
    path.origin = next->origin;
    path.dir = next->dir;
  }
  return rays;
}

std::uint64_t trace_emitted(const EmbreeBackend& backend, const TraceSettings& s, const std::vector<EmittedPhoton>& emissions,
                            std::vector<Photon>& out, const DiffuseGuide& guide) {
  constexpr std::size_t kChunk = 256;
  const std::size_t chunks = (emissions.size() + kChunk - 1) / kChunk;
  std::vector<std::vector<Photon>> stored(chunks);
  std::vector<std::uint64_t> chunk_rays(chunks, 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t c = r.begin(); c < r.end(); ++c) {
      const std::size_t end = std::min(emissions.size(), (c + 1) * kChunk);
      // Parents in stored[c] are its own indices; shifted below when the chunk is appended.
      for (std::size_t j = c * kChunk; j < end; ++j) chunk_rays[c] += trace_photon(backend, emissions[j], s, stored[c], guide);
    }
  });
  std::uint64_t rays = 0;
  for (std::size_t c = 0; c < chunks; ++c) {
    const auto offset = static_cast<std::uint32_t>(out.size());
    for (Photon& p : stored[c]) {
      if (p.parent != kNoParent) p.parent += offset;
      out.push_back(p);
    }
    rays += chunk_rays[c];
  }
  return rays;
}

PhotonTraceResult trace_photons(const EmbreeBackend& backend, const TraceSettings& s) {
  const auto t0 = std::chrono::steady_clock::now();
  PhotonTraceResult result;
  const Scene& scene = backend.scene();
  result.emitted_per_light.assign(scene.lights.size(), 0);
  const std::vector<double> share = light_shares(scene);
  const bool any_light = std::any_of(share.begin(), share.end(), [](double v) { return v > 0; });
  const auto finish = [&] {
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return std::move(result);
  };
  if (!any_light) {
    result.note = scene.lights.empty() ? "no lights" : "no light has positive, finite power";
    return finish();
  }
  if (s.stored_photons == 0 || s.max_depth == 0) {
    result.note = s.stored_photons == 0 ? "0 photons asked for" : "trace depth 0";
    return finish();
  }
  const std::uint64_t round = s.round > 0 ? s.round : std::clamp<std::uint64_t>(s.stored_photons / 4, 256, 8192);
  const std::uint64_t cap = std::uint64_t{s.stored_photons} * std::max<std::uint32_t>(1, s.max_emitted_per_stored);
  // Photons per light per round, by power share (at least one for every light with power).
  std::vector<std::uint64_t> per_round(scene.lights.size(), 0);
  for (std::size_t l = 0; l < share.size(); ++l)
    if (share[l] > 0) per_round[l] = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(share[l] * static_cast<double>(round))));
  std::uint64_t per_round_total = 0;
  for (std::uint64_t v : per_round) per_round_total += v;

  std::uint64_t rays = 0;
  std::vector<EmittedPhoton> emissions;
  while (result.photons.size() < s.stored_photons && result.emitted < cap) {
    // This round's emissions: (light, index within the light) in a fixed order.
    emissions.clear();
    for (std::size_t l = 0; l < per_round.size(); ++l)
      for (std::uint64_t k = 0; k < per_round[l]; ++k)
        emissions.push_back(emit_from_light(scene, l, hash_seed(s.seed, l, result.emitted_per_light[l] + k)));
    rays += trace_emitted(backend, s, emissions, result.photons);
    for (std::size_t l = 0; l < per_round.size(); ++l) result.emitted_per_light[l] += per_round[l];
    result.emitted += per_round_total;
  }
  // Eq. 6.1: each light's power is shared by the photons it emitted.
  for (Photon& p : result.photons) {
    const std::uint64_t n = p.light < result.emitted_per_light.size() ? result.emitted_per_light[p.light] : 0;
    p.power = n > 0 ? p.power / static_cast<float>(n) : glm::vec3(0.0f);
  }
  result.rays = rays;
  if (result.photons.size() < s.stored_photons) {
    result.note = "stored " + std::to_string(result.photons.size()) + " of " + std::to_string(s.stored_photons) +
                  " photons after emitting " + std::to_string(result.emitted) +
                  (result.photons.empty() ? " (no photon reached a diffuse surface)" : " (the emission cap)");
  }
  return finish();
}

}  // namespace fovea::render::gi
