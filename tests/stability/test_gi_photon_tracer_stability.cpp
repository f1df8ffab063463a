// SPDX-License-Identifier: Apache-2.0
// Hard cases of the photon tracer (renderer/gi/photon_tracer.h): no lights, a light inside
// geometry, zero photons stored, albedo 1, non-finite light data. It terminates, says why, and
// every stored photon is finite.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "backend/embree/embree_backend.h"
#include "gi/photon_tracer.h"
#include "scene/geometry.h"

namespace fovea::render::gi {
namespace {

Scene box_scene(glm::vec3 kd, glm::vec3 light_at, bool with_light = true) {
  Scene s;
  Material m;
  m.kd = kd;
  s.materials.push_back(m);
  Object o;
  o.name = "box";
  o.id = 1;
  o.mesh = std::make_shared<Mesh>(make_box({1, 1, 1}));
  s.objects.push_back(o);
  if (with_light) {
    Light l;
    l.position = light_at;
    l.power = glm::vec3(10.0f);
    s.lights.push_back(l);
  }
  return s;
}

void expect_finite(const PhotonTraceResult& r) {
  for (const Photon& p : r.photons) {
    ASSERT_TRUE(std::isfinite(p.position.x) && std::isfinite(p.power.x) && std::isfinite(p.power.y) &&
                std::isfinite(p.power.z) && std::isfinite(p.incoming.x));
    ASSERT_GE(p.power.x, 0.0f);
  }
}

TEST(GiPhotonTracerStability, HardCasesTerminateAndSayWhy) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  EmbreeBackend backend;
  TraceSettings ts;
  ts.stored_photons = 1000;

  // No lights.
  backend.set_scene(box_scene(glm::vec3(0.5f), {}, false));
  PhotonTraceResult r = trace_photons(backend, ts);
  EXPECT_TRUE(r.photons.empty());
  EXPECT_EQ(r.note, "no lights");

  // A light inside a black box: every photon is stored where it first hits and absorbed there.
  backend.set_scene(box_scene(glm::vec3(0.0f), {0, 0, 0}));
  r = trace_photons(backend, ts);
  EXPECT_GE(r.photons.size(), ts.stored_photons);
  for (const Photon& p : r.photons) EXPECT_EQ(p.diffuse_bounces, 0);

  // A light with nothing to hit: no photon is stored; the emission cap ends it and says so.
  Scene void_scene = box_scene(glm::vec3(0.5f), {0, 0, 0});
  void_scene.objects.clear();
  backend.set_scene(void_scene);
  r = trace_photons(backend, ts);
  EXPECT_TRUE(r.photons.empty());
  EXPECT_NE(r.note.find("no photon reached a diffuse surface"), std::string::npos) << r.note;
  const std::uint64_t cap = std::uint64_t{ts.stored_photons} * ts.max_emitted_per_stored;
  EXPECT_GE(r.emitted, cap);  // whole rounds: the cap is checked between them
  EXPECT_LT(r.emitted, cap + 8192);

  // A light outside the (closed) box, shining at its outside; and the light inside a white box
  // (albedo 1): traces end at max_depth, photons finite.
  backend.set_scene(box_scene(glm::vec3(1.0f), {0, 0, 0}));
  ts.max_depth = 50;
  r = trace_photons(backend, ts);
  EXPECT_GE(r.photons.size(), ts.stored_photons);
  expect_finite(r);
  // Albedo above 1 (a non-physical kd) is clamped to 1: no photon gains power.
  backend.set_scene(box_scene(glm::vec3(2.5f, nan, -1.0f), {0, 0, 0}));
  r = trace_photons(backend, ts);
  expect_finite(r);
  for (const Photon& p : r.photons) EXPECT_LE(p.power.x, 10.0f / static_cast<float>(r.emitted_per_light[0]) * 1.0001f);

  // Zero photons asked for; trace depth 0.
  ts.stored_photons = 0;
  r = trace_photons(backend, ts);
  EXPECT_TRUE(r.photons.empty());
  EXPECT_FALSE(r.note.empty());
  ts.stored_photons = 100;
  ts.max_depth = 0;
  r = trace_photons(backend, ts);
  EXPECT_TRUE(r.photons.empty());
  EXPECT_FALSE(r.note.empty());

  // Lights with NaN or infinite power or position are not emitted from.
  Scene bad = box_scene(glm::vec3(0.5f), {0, 0, 0});
  bad.lights[0].power = glm::vec3(nan);
  Light l2 = bad.lights[0];
  l2.power = glm::vec3(inf);
  Light l3 = bad.lights[0];
  l3.power = glm::vec3(1.0f);
  l3.position = glm::vec3(nan);
  bad.lights.push_back(l2);
  bad.lights.push_back(l3);
  backend.set_scene(bad);
  ts.max_depth = 3;
  r = trace_photons(backend, ts);
  EXPECT_TRUE(r.photons.empty());
  EXPECT_FALSE(r.note.empty());
}

}  // namespace
}  // namespace fovea::render::gi
