// SPDX-License-Identifier: Apache-2.0
// Hard cases of the GI render (renderer/gi/gi_render.h): gaze outside the screen, a gaze area
// larger than the screen, radius 0 or NaN, no lights, empty maps, nNN larger than the map.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "backend/embree/embree_backend.h"
#include "gi/gi_render.h"
#include "scene/scene_loader.h"

namespace fovea::render::gi {
namespace {

bool all_finite(const std::vector<glm::vec3>& img) {
  for (const glm::vec3& c : img)
    if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.z) || c.x < 0 || c.y < 0 || c.z < 0) return false;
  return true;
}

TEST(GiRenderStability, GazeAndAreaHardCases) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Scene scene = load_scene(std::string(FOVEA_SOURCE_DIR) + "/renderer/scenes/cornell.json");
  scene.camera.width = 64;
  scene.camera.height = 48;
  EmbreeBackend backend;
  backend.set_scene(scene);
  PhotonMaps maps;
  TraceSettings ts;
  ts.stored_photons = 2000;
  maps.global = trace_photons(backend, ts);
  maps.index();
  GiRenderSettings s;
  s.estimate.nearest = 100000;  // nNN larger than the map
  std::vector<glm::vec3> hdr;
  GiStats st;
  const auto pixels = [&](GazeArea a) {
    hdr.clear();
    render_gaze_area(backend, scene.camera, 0, maps, a, s, hdr, &st);
    EXPECT_TRUE(all_finite(hdr));
    EXPECT_EQ(hdr.size(), 64u * 48u);
    return st.pixels;
  };
  EXPECT_EQ(pixels({{-500.0f, -500.0f}, 30.0f}), 0u);     // wholly off the screen
  const std::uint64_t partial = pixels({{0.0f, 0.0f}, 20.0f});  // a quarter of the circle is on it
  EXPECT_GT(partial, 250u);
  EXPECT_LT(partial, 360u);
  EXPECT_EQ(pixels({{32.0f, 24.0f}, 1e6f}), 64u * 48u);  // larger than the screen
  EXPECT_EQ(pixels({{32.0f, 24.0f}, 0.0f}), 0u);
  EXPECT_EQ(pixels({{32.0f, 24.0f}, nan}), 0u);
  EXPECT_EQ(pixels({{nan, 24.0f}, 10.0f}), 0u);
  EXPECT_EQ(pixels({{32.0f, 24.0f}, std::numeric_limits<float>::infinity()}), 0u);

  // The composite with an off-screen or degenerate area leaves the local image as it was.
  const std::vector<glm::vec3> local(64 * 48, glm::vec3(0.25f)), gi(64 * 48, glm::vec3(1.0f));
  std::vector<glm::vec3> out;
  for (GazeArea a : {GazeArea{{-500.0f, -500.0f}, 30.0f}, GazeArea{{32, 24}, 0.0f}, GazeArea{{nan, 24}, 10.0f}}) {
    hybrid_composite(local, gi, 64, 48, a, 0.7f, out);
    EXPECT_EQ(out, local);
  }
  hybrid_composite(local, gi, 64, 48, {{32, 24}, 1e6f}, nan, out);  // NaN fovea: 0.7
  EXPECT_TRUE(all_finite(out));
  EXPECT_EQ(out[24 * 64 + 32], glm::vec3(1.0f));
  // gaze_area: NaN gaze -> the centre; diameter NaN, 0 or beyond 180 deg stays finite.
  protocol::DisplayGeometry d;
  EXPECT_FLOAT_EQ(gaze_area(d, 64, 48, {nan, 0.2f}, 20).center_px.x, 32.0f);
  for (double deg : {0.0, -5.0, 1000.0, std::numeric_limits<double>::quiet_NaN()}) {
    const GazeArea a = gaze_area(d, 64, 48, {0.5f, 0.5f}, deg);
    EXPECT_TRUE(std::isfinite(a.radius_px) && a.radius_px >= 0) << deg;
  }
}

TEST(GiRenderStability, NoLightsAndEmptyMapsRenderFiniteImages) {
  Scene scene = load_scene(std::string(FOVEA_SOURCE_DIR) + "/renderer/scenes/cornell.json");
  scene.camera.width = 32;
  scene.camera.height = 24;
  scene.lights.clear();
  EmbreeBackend backend;
  backend.set_scene(scene);
  PhotonMaps maps;
  maps.global = trace_photons(backend, TraceSettings{});
  EXPECT_EQ(maps.global.note, "no lights");
  maps.index();
  maps.precompute_irradiance(EstimateSettings{}, 4);
  std::vector<glm::vec3> hdr;
  for (IndirectEstimate e : {IndirectEstimate::Nearest, IndirectEstimate::Precomputed}) {
    GiRenderSettings s;
    s.indirect_estimate = e;
    render_gaze_area(backend, scene.camera, 0, maps, {{16, 12}, 100.0f}, s, hdr);
    EXPECT_TRUE(all_finite(hdr));
    for (const glm::vec3& c : hdr) EXPECT_EQ(c, glm::vec3(0.0f));  // no light, black background
  }
}

}  // namespace
}  // namespace fovea::render::gi
