// SPDX-License-Identifier: Apache-2.0
// The photon tracer (renderer/gi/photon_tracer.h): the white furnace, energy conservation,
// determinism, emission matching local illumination, caustic paths.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <memory>
#include <numbers>

#include "backend/embree/embree_backend.h"
#include "gi/photon_map.h"
#include "gi/photon_tracer.h"
#include "scene/geometry.h"
#include "scene/shading.h"

namespace fovea::render::gi {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

Object object(std::uint32_t id, Mesh mesh, std::uint32_t material, glm::vec3 at = glm::vec3(0.0f)) {
  Object o;
  o.name = "object" + std::to_string(id);
  o.id = id;
  o.mesh = std::make_shared<Mesh>(std::move(mesh));
  o.material = material;
  o.transform.translation = at;
  return o;
}

// A closed diffuse sphere of radius r and albedo rho with a point light of power phi at its centre.
Scene furnace(float rho, float r, float phi) {
  Scene s;
  Material m;
  m.name = "wall";
  m.kd = glm::vec3(rho);
  s.materials.push_back(m);
  s.objects.push_back(object(1, make_sphere(r, 96, 192), 0));
  Light l;
  l.position = glm::vec3(0.0f);
  l.power = glm::vec3(phi);
  s.lights.push_back(l);
  return s;
}

// White furnace: every bounce inside a sphere spreads uniformly (a sphere's form factor to an area
// is that area's share), so the irradiance everywhere on the wall is E_d / (1 - rho) with the
// direct E_d = Phi / (4 pi r^2) (the wall's radiance rho E / pi = L_e / (1 - rho), L_e = rho E_d / pi).
TEST(GiPhotonTracer, WhiteFurnaceConvergesToDirectOverOneMinusAlbedo) {
  for (float rho : {0.0f, 0.5f, 0.8f}) {
    const float r = 1.0f, phi = 100.0f;
    EmbreeBackend backend;
    backend.set_scene(furnace(rho, r, phi));
    TraceSettings ts;
    ts.stored_photons = 200000;
    ts.max_depth = 200;  // roulette ends the traces long before; no truncation bias
    const PhotonTraceResult res = trace_photons(backend, ts);
    ASSERT_GE(res.photons.size(), ts.stored_photons) << res.note;
    PhotonMap map;
    map.build_all(res.photons);
    EstimateSettings es;
    es.nearest = 2000;
    es.max_radius = 0.5f;
    es.filter = EstimateFilter::Disc;
    Neighbours scratch;
    const float e_direct = phi / (4 * kPi * r * r);
    const float expected = e_direct / (1 - rho);
    double sum = 0;
    int n = 0;
    for (glm::vec3 d : {glm::vec3(1, 0, 0), glm::vec3(0, 1, 0), glm::vec3(0, 0, -1), glm::vec3(-0.6f, 0.0f, 0.8f),
                        glm::vec3(0.0f, -0.8f, 0.6f)}) {
      const glm::vec3 x = d * (r * 0.999f);
      const float e = map.flux_density(x, -d, es, scratch).x;  // the wall faces the centre
      EXPECT_NEAR(e, expected, 0.06f * expected) << "rho " << rho << " at " << d.x << "," << d.y << "," << d.z;
      sum += static_cast<double>(e);
      ++n;
    }
    EXPECT_NEAR(sum / n, static_cast<double>(expected), 0.03 * static_cast<double>(expected)) << "rho " << rho;
  }
}

// Energy: every emitted photon hits the closed sphere once directly, so the direct photons carry
// exactly the light's power; the whole map carries Phi / (1 - rho) in expectation.
TEST(GiPhotonTracer, DirectPhotonsCarryTheLightsPowerAndTheMapPhiOverOneMinusRho) {
  const float rho = 0.6f;
  const double phi = 50.0;
  EmbreeBackend backend;
  backend.set_scene(furnace(rho, 2.0f, static_cast<float>(phi)));
  TraceSettings ts;
  ts.stored_photons = 100000;
  ts.max_depth = 200;
  const PhotonTraceResult res = trace_photons(backend, ts);
  double direct = 0, all = 0;
  for (const Photon& p : res.photons) {
    all += static_cast<double>(p.power.x);
    if (p.diffuse_bounces == 0) direct += static_cast<double>(p.power.x);
  }
  EXPECT_NEAR(direct, phi, 1e-3 * phi);
  const double expected_all = phi / (1.0 - static_cast<double>(rho));
  EXPECT_NEAR(all, expected_all, 0.02 * expected_all);
  // Parent links: a photon's parent was stored before it, one diffuse bounce earlier, and its
  // outgoing direction is the child's incoming one.
  for (std::size_t i = 0; i < res.photons.size(); ++i) {
    const Photon& p = res.photons[i];
    if (p.parent == kNoParent) {
      EXPECT_EQ(p.diffuse_bounces, 0);
      continue;
    }
    ASSERT_LT(p.parent, i);
    const Photon& q = res.photons[p.parent];
    EXPECT_EQ(q.diffuse_bounces + 1, p.diffuse_bounces);
    EXPECT_EQ(q.seed, p.seed);
    EXPECT_FLOAT_EQ(glm::dot(q.outgoing, p.incoming), 1.0f);
  }
}

TEST(GiPhotonTracer, SameSeedSamePhotonsWhateverTheThreadCount) {
  EmbreeBackend backend;
  backend.set_scene(furnace(0.5f, 1.0f, 10.0f));
  TraceSettings ts;
  ts.stored_photons = 20000;
  const PhotonTraceResult a = trace_photons(backend, ts);
  PhotonTraceResult b;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    b = trace_photons(backend, ts);
  }
  ASSERT_EQ(a.photons.size(), b.photons.size());
  for (std::size_t i = 0; i < a.photons.size(); ++i) {
    ASSERT_EQ(a.photons[i].position, b.photons[i].position) << i;
    ASSERT_EQ(a.photons[i].power, b.photons[i].power) << i;
  }
  ts.seed = 2;
  const PhotonTraceResult c = trace_photons(backend, ts);
  EXPECT_NE(a.photons.front().position, c.photons.front().position);
}

// Emission matches local illumination: the direct photons' flux density on a floor under a spot
// and an area light equals the irradiance local illumination uses (scene/shading.cpp).
TEST(GiPhotonTracer, DirectFluxDensityMatchesLocalIlluminationForEachLightType) {
  for (LightType type : {LightType::Point, LightType::Spot, LightType::Area}) {
    Scene s;
    Material m;
    m.kd = glm::vec3(0.5f);
    s.materials.push_back(m);
    s.objects.push_back(object(1, make_plane({8.0f, 8.0f}), 0));
    Light l;
    l.type = type;
    l.position = {0, 1.0f, 0};
    l.power = glm::vec3(40.0f);
    l.direction = {0, -1, 0};
    l.spot_cutoff_deg = 50;
    l.spot_falloff_deg = 10;
    l.area_size = {0.4f, 0.4f};
    l.area_samples = 16;
    s.lights.push_back(l);
    EmbreeBackend backend;
    backend.set_scene(s);
    TraceSettings ts;
    ts.stored_photons = 200000;
    ts.max_depth = 1;
    const PhotonTraceResult res = trace_photons(backend, ts);
    PhotonMap map;
    map.build_all(res.photons);
    EstimateSettings es;
    es.nearest = 1500;
    es.max_radius = 0.2f;
    es.filter = EstimateFilter::Disc;
    Neighbours scratch;
    for (glm::vec3 x : {glm::vec3(0, 0, 0), glm::vec3(0.3f, 0, 0.2f)}) {
      // Local illumination's irradiance: the BRDF-free part of shade_local (kd = 1, ks = 0, no ambient).
      Scene probe = s;
      probe.ambient = glm::vec3(0.0f);
      Material white;
      white.kd = glm::vec3(1.0f);
      const float e_local = shade_local(probe, white, x, {0, 1, 0}, {0, 5, 0}).x;
      const float e = map.flux_density(x, {0, 1, 0}, es, scratch).x;
      EXPECT_NEAR(e, e_local, 0.07f * e_local) << "light type " << static_cast<int>(type) << " at x " << x.x;
    }
  }
}

// A mirror above a floor: the caustic tracer stores only light -> mirror -> floor photons, at the
// floor, each marked as having come by a specular bounce.
TEST(GiPhotonTracer, CausticModeStoresOnlySpecularToDiffusePaths) {
  Scene s;
  Material floor;
  floor.kd = glm::vec3(0.5f);
  Material mirror;
  mirror.type = MaterialType::Mirror;
  mirror.reflectance = glm::vec3(0.9f);
  s.materials = {floor, mirror};
  s.objects.push_back(object(1, make_plane({8.0f, 8.0f}), 0));
  s.objects.push_back(object(2, make_sphere(0.3f, 32, 64), 1, {0, 0.5f, 0}));
  Light l;
  l.position = {0, 2.0f, 0};
  l.power = glm::vec3(10.0f);
  s.lights.push_back(l);
  EmbreeBackend backend;
  backend.set_scene(s);
  TraceSettings ts;
  ts.mode = TraceMode::Caustic;
  ts.stored_photons = 2000;
  ts.max_depth = 4;
  ts.max_emitted_per_stored = 1000;  // the sphere subtends a small solid angle: most photons miss it
  const PhotonTraceResult res = trace_photons(backend, ts);
  ASSERT_GE(res.photons.size(), ts.stored_photons) << res.note;
  for (const Photon& p : res.photons) {
    EXPECT_TRUE(p.via_specular);
    EXPECT_EQ(p.diffuse_bounces, 0);
    EXPECT_NEAR(p.position.y, 0.0f, 1e-3f);
  }
  EXPECT_GT(res.emitted, res.photons.size());  // most emitted photons were not caustic paths
}

}  // namespace
}  // namespace fovea::render::gi
