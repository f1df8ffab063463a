// SPDX-License-Identifier: Apache-2.0
// Gaze-directed photon maps (renderer/gi/gaze_photons.h): Algorithm 8.5's emission map, more
// photons in the gaze area than traditional photon mapping, power scaling that keeps the gaze
// area's brightness, frame-coherent seeds, importons.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "backend/embree/embree_backend.h"
#include "gi/gaze_photons.h"
#include "gi_frames.h"
#include "scene/scene_loader.h"

namespace fovea::render::gi {
namespace {

using test::cornell;
using test::Frame;
using test::gaze_frame;
using test::indirect_only;
using test::mean_in;

TEST(GiGazePhotons, EmissionMapBackTracksLabelledPhotonsToTheirEmission) {
  // Three traces: 0 -> 1 -> 2 (2 in the gaze area), 3 alone (direct, in the area), 4 -> 5 (5 not).
  Scene scene;
  Light l;
  l.power = glm::vec3(1.0f);
  scene.lights.push_back(l);
  std::vector<Photon> p(6);
  for (std::size_t i = 0; i < p.size(); ++i) {
    p[i].incoming = glm::normalize(glm::vec3(static_cast<float>(i), -1.0f, 0.0f));
    p[i].seed = static_cast<std::uint32_t>(100 + i);
    p[i].emission_direction = glm::normalize(glm::vec3(0.0f, -1.0f, static_cast<float>(i)));
  }
  p[1].parent = 0;
  p[2].parent = 1;
  p[5].parent = 4;
  p[0].flags = kTraditional;
  p[1].flags = kTraditional;
  p[2].flags = kInGazeRegion | kTraditional;
  p[3].flags = kInGazeRegion;
  GazeFrameStats st;
  const std::vector<EmissionDirection> map = build_emission_map(p, scene, st);
  ASSERT_EQ(map.size(), 1u);  // the direct photon 3 has no path to record
  EXPECT_EQ(map[0].seed, 100u);
  EXPECT_TRUE(map[0].from_traditional);
  EXPECT_EQ(map[0].direction, p[0].emission_direction);  // the root's emission, not a later direction
  EXPECT_TRUE(p[1].flags & kOnPathToGaze);
  EXPECT_TRUE(p[1].flags & kChildInGaze);
  EXPECT_TRUE(p[0].flags & kOnPathToGaze);
  EXPECT_FALSE(p[0].flags & kChildInGaze);
  EXPECT_FALSE(p[4].flags & kOnPathToGaze);
  EXPECT_EQ(p[1].outgoing, p[2].incoming);
  EXPECT_EQ(p[0].outgoing, p[1].incoming);
  EXPECT_EQ(st.gaze_photons, 2u);
  EXPECT_EQ(st.new_gaze_photons, 1u);
}

// Tables 9.9-9.10's measure: photons that shade a 10 deg gaze area, gaze-directed against
// traditional with the same number stored (the thesis: +283 % on its diffuse scene).
TEST(GiGazePhotons, MorePhotonsShadeTheGazeAreaThanWithTraditionalMapping) {
  const Scene scene = cornell();
  EmbreeBackend backend;
  backend.set_scene(scene);
  const GazeArea area = gaze_area(scene.display, 160, 120, {0.5f, 0.6f}, 10.0);
  GazeDirectedSettings gs;
  gs.max_photons = 20000;
  GazePhotonMapper mapper;
  const Frame first = gaze_frame(backend, scene, mapper, gs, area, indirect_only());  // traditional
  Frame last;
  for (int k = 0; k < 5; ++k) last = gaze_frame(backend, scene, mapper, gs, area, indirect_only());
  EXPECT_GT(last.gaze.emission_map, 0u);
  EXPECT_GT(static_cast<double>(last.render.photons_used), 1.5 * static_cast<double>(first.render.photons_used))
      << first.render.photons_used << " -> " << last.render.photons_used;
}

// The gaze area keeps the brightness of traditional photon mapping (a many-photon traditional map
// as the reference) for several emission ratios, once s is measured.
TEST(GiGazePhotons, PowerScalingKeepsTheGazeAreaAsBrightAsTraditionalMapping) {
  const Scene scene = cornell();
  EmbreeBackend backend;
  backend.set_scene(scene);
  const GazeArea area = gaze_area(scene.display, 160, 120, {0.5f, 0.6f}, 20.0);
  const GiRenderSettings rs = indirect_only();
  PhotonMaps reference;
  TraceSettings ts;
  ts.stored_photons = 300000;
  reference.global = trace_photons(backend, ts);
  reference.index();
  std::vector<glm::vec3> hdr;
  render_gaze_area(backend, scene.camera, 0, reference, area, rs, hdr);
  const double want = mean_in(hdr, area, 160);
  for (double ratio : {0.25, 0.5, 0.75}) {
    GazeDirectedSettings gs;
    gs.max_photons = 30000;
    gs.emission_ratio = ratio;
    GazePhotonMapper mapper;
    double sum = 0;
    int n = 0;
    for (int k = 0; k < 8; ++k) {
      const Frame f = gaze_frame(backend, scene, mapper, gs, area, rs);
      if (k >= 4) {  // s measured from frame 2 on; average a few frames against noise
        EXPECT_TRUE(f.gaze.scale_measured) << f.gaze.note;
        sum += f.mean;
        ++n;
      }
    }
    EXPECT_NEAR(sum / n, want, 0.04 * want) << "emissionRatio " << ratio;
  }
}

// Frame-coherent random numbers: with the gaze and the scene still, the old gaze photons of a frame
// retrace last frame's paths, so consecutive maps share most of their photons exactly.
TEST(GiGazePhotons, OldGazePhotonsRetraceTheirPaths) {
  const Scene scene = cornell();
  EmbreeBackend backend;
  backend.set_scene(scene);
  const GazeArea area = gaze_area(scene.display, 160, 120, {0.5f, 0.6f}, 20.0);
  GazeDirectedSettings gs;
  gs.max_photons = 10000;
  GazePhotonMapper mapper;
  Frame previous;
  for (int k = 0; k < 3; ++k) previous = gaze_frame(backend, scene, mapper, gs, area, indirect_only());
  const Frame next = gaze_frame(backend, scene, mapper, gs, area, indirect_only());
  EXPECT_GT(next.gaze.old_gaze + next.gaze.new_gaze, 0u);
  // The first stored photon of each trace, by seed.
  const auto roots = [](const std::vector<Photon>& photons) {
    std::map<std::uint32_t, glm::vec3> r;
    for (const Photon& p : photons)
      if (p.parent == kNoParent) r.emplace(p.seed, p.position);
    return r;
  };
  const auto before = roots(previous.photons);
  std::size_t matched = 0, same = 0;
  for (const Photon& p : next.photons) {
    if (p.parent != kNoParent || p.kind == EmissionKind::Traditional) continue;
    const auto it = before.find(p.seed);
    if (it == before.end()) continue;  // a fill photon (a new seed)
    ++matched;
    same += it->second == p.position ? 1u : 0u;
  }
  EXPECT_GT(matched, 100u);
  EXPECT_EQ(same, matched);  // same seed and direction: the very same first hit
}

TEST(GiGazePhotons, ImportonsStorePhotonsOnlyWhereTheGazeAreaCanUseThem) {
  const Scene scene = cornell();
  EmbreeBackend backend;
  backend.set_scene(scene);
  const GazeArea area = gaze_area(scene.display, 160, 120, {0.5f, 0.6f}, 10.0);
  ImportonMap importance;
  ImportonSettings is;
  is.importons = 2000;
  is.reach = 0.3f;
  importance.build(backend, scene.camera, 0, area, is);
  EXPECT_GT(importance.size(), 1500u);
  TraceSettings ts;
  ts.stored_photons = 10000;
  ts.max_emitted_per_stored = 1000;
  const PhotonTraceResult r = trace_photons_with_importons(backend, ts, importance);
  ASSERT_GE(r.photons.size(), 10000u) << r.note;
  for (const Photon& p : r.photons) ASSERT_TRUE(importance.important(p.position, p.normal));
  EXPECT_GT(r.emitted, 2 * r.photons.size());  // most of the room is out of reach
  // Traditional mapping with the same stored count puts far fewer photons where the area can see.
  TraceSettings plain;
  plain.stored_photons = 10000;
  const PhotonTraceResult t = trace_photons(backend, plain);
  std::size_t reachable = 0;
  for (const Photon& p : t.photons) reachable += importance.important(p.position, p.normal) ? 1u : 0u;
  EXPECT_LT(2 * reachable, r.photons.size());
}

}  // namespace
}  // namespace fovea::render::gi
