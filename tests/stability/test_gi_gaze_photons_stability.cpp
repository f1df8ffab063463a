// SPDX-License-Identifier: Apache-2.0
// Hard cases of gaze-directed photon mapping (renderer/gi/gaze_photons.h): emissionRatio 0 and 1,
// where photon power scaling breaks down (no traditional or no gaze-emitted photon in the area), a
// gaze area off the screen, zero photons. Everything stays finite and says what it did.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "backend/embree/embree_backend.h"
#include "gi/gaze_photons.h"
#include "gi_frames.h"

namespace fovea::render::gi {
namespace {

using test::cornell;
using test::Frame;
using test::gaze_frame;
using test::indirect_only;

// Where s cannot be measured it is held and said so: emissionRatio 1 leaves no traditional photon.
TEST(GiGazePhotonsStability, PowerScalingIsHeldWhereItBreaksDown) {
  const Scene scene = cornell();
  EmbreeBackend backend;
  backend.set_scene(scene);
  const GazeArea area = gaze_area(scene.display, 160, 120, {0.5f, 0.6f}, 20.0);
  GazeDirectedSettings gs;
  gs.max_photons = 10000;
  gs.emission_ratio = 1.0;
  GazePhotonMapper mapper;
  Frame f;
  for (int k = 0; k < 4; ++k) f = gaze_frame(backend, scene, mapper, gs, area, indirect_only());
  EXPECT_FALSE(f.gaze.scale_measured);
  EXPECT_NE(f.gaze.note.find("held"), std::string::npos);
  EXPECT_EQ(f.gaze.traditional, 0u);
  EXPECT_TRUE(std::isfinite(f.gaze.scale) && f.gaze.scale > 0);
  EXPECT_TRUE(std::isfinite(f.mean));
  // emissionRatio 0: traditional photon mapping with an emission map nobody uses.
  gs.emission_ratio = 0.0;
  GazePhotonMapper plain;
  for (int k = 0; k < 3; ++k) f = gaze_frame(backend, scene, plain, gs, area, indirect_only());
  EXPECT_EQ(f.gaze.old_gaze + f.gaze.new_gaze + f.gaze.fill, 0u);
}

// A gaze area wholly off the screen labels nothing: the next frame has no emission map and says so.
TEST(GiGazePhotonsStability, AnAreaOffTheScreenFallsBackToTraditionalEmission) {
  const Scene scene = cornell();
  EmbreeBackend backend;
  backend.set_scene(scene);
  const GazeArea off{{-1000.0f, -1000.0f}, 20.0f};
  GazeDirectedSettings gs;
  gs.max_photons = 5000;
  GazePhotonMapper mapper;
  Frame f;
  for (int k = 0; k < 3; ++k) f = gaze_frame(backend, scene, mapper, gs, off, indirect_only());
  EXPECT_EQ(f.render.pixels, 0u);
  EXPECT_EQ(f.gaze.emission_map, 0u);
  EXPECT_EQ(f.gaze.old_gaze + f.gaze.new_gaze + f.gaze.fill, 0u);
  EXPECT_GT(f.gaze.traditional, 0u);
  for (const Photon& p : f.photons) ASSERT_TRUE(std::isfinite(p.power.x) && p.power.x >= 0);
  // Zero photons asked for: an empty map, no crash, the next frame still works.
  gs.max_photons = 0;
  GazePhotonMapper empty;
  f = gaze_frame(backend, scene, empty, gs, off, indirect_only());
  EXPECT_TRUE(f.photons.empty());
  // NaN settings: emissionRatio NaN reads as 0.5, noise NaN as no noise.
  gs.max_photons = 3000;
  gs.emission_ratio = std::numeric_limits<double>::quiet_NaN();
  gs.noise_scale = std::numeric_limits<float>::quiet_NaN();
  const GazeArea centre = gaze_area(scene.display, 160, 120, {0.5f, 0.6f}, 20.0);
  GazePhotonMapper odd;
  for (int k = 0; k < 3; ++k) f = gaze_frame(backend, scene, odd, gs, centre, indirect_only());
  EXPECT_TRUE(std::isfinite(f.mean));
  for (const Photon& p : f.photons) ASSERT_TRUE(std::isfinite(p.power.x) && std::isfinite(p.incoming.x));
}

}  // namespace
}  // namespace fovea::render::gi
