// SPDX-License-Identifier: Apache-2.0
#pragma once
// The first pass of photon mapping (Jensen & Pedersen 2009, §6.2; Jensen 2001): photons emitted
// from the scene's point, spot and area lights, traced through it with Embree, scattered by Russian
// roulette (eq. 6.3) off diffuse, glossy (modified Blinn-Phong), mirror and glass surfaces, and
// stored where they hit a diffuse surface.
//
// Radiometry. A material's kd is its diffuse reflectance (albedo, the probability of a diffuse
// reflection in eq. 6.3, as the paper's test scenes use it: "a diffuse reflection coefficient of
// 1.0 and an albedo of 1.0"); ks the glossy reflectance; mirror and glass reflect or transmit with
// probability max(reflectance) (glass splitting by Fresnel). Photon powers are in watts; a
// photon's power changes by reflectance / probability (per channel, never growing: the probability
// is the largest channel), so the expected flux is exact. Reflectances are clamped to [0, 1].
// Emission matches local illumination (scene/shading.h): a point light radiates Phi / (4 pi) per
// steradian, a spot light that times the same smoothstep cone falloff, an area light is a
// Lambertian emitter of total power Phi.
//
// Determinism: every trace draws its random numbers from its own seed (frame-coherent random
// numbers, §8.4.6: seed = hash(settings.seed, light, emission index)), and the photons are kept in
// emission order, so the result does not depend on the number of threads.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "gi/photon_map.h"
#include "scene/scene.h"

namespace fovea::render {
class EmbreeBackend;
}

namespace fovea::render::gi {

// A small PCG32 (O'Neill 2014): one per trace, seeded by the trace's seed.
class Pcg32 {
 public:
  explicit Pcg32(std::uint64_t seed, std::uint64_t stream = 0x853c49e6748fea9bULL);
  std::uint32_t next();
  float uniform();  // [0, 1)

 private:
  std::uint64_t state_ = 0, inc_ = 1;
};

// Mixes (a, b, c) into a 32-bit seed (splitmix64 finaliser).
std::uint32_t hash_seed(std::uint64_t a, std::uint64_t b, std::uint64_t c);

enum class TraceMode {
  Global,    // store at every diffuse hit (the global photon map; direct, caustic and indirect photons)
  Caustic,   // follow only light -> specular+ -> diffuse paths and store at their diffuse end
};

struct TraceSettings {
  TraceMode mode = TraceMode::Global;
  std::uint32_t stored_photons = 40000;  // emit rounds until this many are stored (maxPhotons, Table 8.3)
  std::uint32_t max_depth = 3;           // surface interactions per trace (pmTraceDepth, Table 8.3); 0: none
  std::uint64_t seed = 1;
  // Photons emitted per round (over all lights); 0: a quarter of stored_photons, within [256, 8192], so
  // a small map does not overshoot its count by a whole large round.
  std::uint32_t round = 0;
  // Stop after this many emitted photons per stored photon asked for, whatever was stored (a light
  // enclosed by geometry that absorbs everything, or one that shines into the void).
  std::uint32_t max_emitted_per_stored = 64;
  // Store a photon only where this says yes (position, surface normal on the arrival side); empty:
  // everywhere. The importon strategy (§7.2) stores only near important surfaces this way.
  std::function<bool(const glm::vec3&, const glm::vec3&)> store_if;
};

// Where a diffusely reflected photon goes next: return a unit direction on the side `normal`
// faces, or nothing for the cosine-weighted default. The gaze-directed tracer plugs in here
// (§8.4.7's photon scattering).
using DiffuseGuide = std::function<std::optional<glm::vec3>(const Photon& stored, const glm::vec3& normal, Pcg32& rng)>;

// One trace's start: where, which way, with what power (W per channel), from which light.
struct EmittedPhoton {
  glm::vec3 origin{0.0f};
  glm::vec3 direction{0, -1, 0};
  glm::vec3 power{0.0f};
  std::uint8_t light = 0;
  std::uint32_t seed = 0;
  EmissionKind kind = EmissionKind::Traditional;
};

struct PhotonTraceResult {
  std::vector<Photon> photons;                // stored photons in emission order; parents are indices here
  std::vector<std::uint64_t> emitted_per_light;  // photon powers are already divided by these
  std::uint64_t emitted = 0;
  std::uint64_t rays = 0;  // photon rays traced
  double seconds = 0;
  std::string note;        // empty, or why fewer photons than asked were stored ("no lights", ...)
};

// Samples the emission of `light_index` for trace seed `seed` (uniform sphere, cone or Lambertian
// rectangle). The power is the light's full power (times the spot's cone share and falloff): the
// caller divides by the number emitted from that light.
EmittedPhoton emit_from_light(const Scene& scene, std::size_t light_index, std::uint32_t seed);

// The power a photon leaving `light` in unit `direction` carries before division by the number
// emitted: Phi, for a spot light times its cone's share of the sphere and the smoothstep falloff.
glm::vec3 emitted_power(const Light& light, const glm::vec3& direction);

// Traces one photon, appending the photons it stores to `out` (parents as indices into `out`).
// Returns the number of rays cast.
std::uint32_t trace_photon(const EmbreeBackend& backend, const EmittedPhoton& start, const TraceSettings& s,
                           std::vector<Photon>& out, const DiffuseGuide& guide = {});

// Traces a list of emissions in parallel; the stored photons are appended to `out` in emission
// order (parents shifted to indices of `out`), whatever the number of threads. `guide` (optional)
// steers diffuse reflections. Returns the rays cast. Powers are left as emitted.
std::uint64_t trace_emitted(const EmbreeBackend& backend, const TraceSettings& s, const std::vector<EmittedPhoton>& emissions,
                            std::vector<Photon>& out, const DiffuseGuide& guide = {});

// Emits and traces photons in rounds until settings.stored_photons are stored (or the emission cap
// is reached), in parallel, deterministic for a given seed.
PhotonTraceResult trace_photons(const EmbreeBackend& backend, const TraceSettings& s);

// The shares of a scene's lights in the emission: proportional to mean power (0 for lights with
// no positive, finite power).
std::vector<double> light_shares(const Scene& scene);

}  // namespace fovea::render::gi
