// SPDX-License-Identifier: Apache-2.0
// Stereo frames (FramePipeline::Eye, Camera::eye_offset_m): each eye is the scene's camera moved
// along its right axis; the right eye reuses the left eye's attention, levels, focus and photon maps;
// each eye's gaze point is the cyclopean one at the fixation depth.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include <glm/gtc/matrix_transform.hpp>

#include "backend/embree/embree_backend.h"
#include "gaze/gaze_input.h"
#include "pipeline/frame_pipeline.h"
#include "scene/geometry.h"

namespace fovea::render {
namespace {

using Eye = FramePipeline::Eye;

// A unit box 5 m in front of a 256x192 camera, facing it (only its front face is seen from either
// eye), with a thin lens so focus, DOF and attention run.
Scene box_scene(float ipd_m) {
  Scene s;
  s.camera.position = {0, 0, 5};
  s.camera.target = {0, 0, 0};
  s.camera.width = 256;
  s.camera.height = 192;
  s.camera.stereo = true;
  s.camera.ipd_m = ipd_m;
  s.camera.lens.aperture_m = 0.01;
  s.camera.lens.focal_length_m = 0.05;
  s.camera.lens.focus_distance_m = 4.5;
  s.materials.push_back(Material{});
  Object o;
  o.id = 1;
  o.mesh = std::make_shared<Mesh>(make_box({1, 1, 1}));
  o.task_importance = 1;
  s.objects.push_back(o);
  Light l;
  l.position = {0, 2, 5};
  l.power = glm::vec3(50);
  s.lights.push_back(l);
  return s;
}

// The mean x (pixels) of the pixels showing object `id`.
double centroid_x(const GBuffer& g, std::uint32_t id) {
  double sum = 0, n = 0;
  for (std::uint32_t y = 0; y < g.height; ++y)
    for (std::uint32_t x = 0; x < g.width; ++x)
      if (g.object_id[g.index(x, y)] == id) {
        sum += x;
        n += 1;
      }
  return n > 0 ? sum / n : std::nan("");
}

TEST(StereoCamera, AnEyeIsTheCameraMovedAlongItsRightAxis) {
  Camera c;
  c.position = {1, 2, 3};
  c.target = {1, 2, -1};
  c.eye_offset_m = 0.05f;
  EXPECT_NEAR(glm::length(c.right() - glm::vec3(1, 0, 0)), 0, 1e-6);
  EXPECT_NEAR(glm::length(c.position_at(0) - glm::vec3(1.05f, 2, 3)), 0, 1e-6);
  Camera moved = c;
  moved.eye_offset_m = 0;
  moved.position += glm::vec3(0.05f, 0, 0);
  moved.target += glm::vec3(0.05f, 0, 0);  // parallel view axes: the target moves with the eye
  const glm::mat4 a = c.view_at(0), b = moved.view_at(0);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) EXPECT_NEAR(a[i][j], b[i][j], 1e-6) << i << "," << j;
}

// A point of the cyclopean image at depth D projected by each eye lands where eye_shift_x says.
TEST(StereoCamera, TheEyeShiftIsWhereTheEyeSeesTheCyclopeanPointAtItsDepth) {
  Camera c;
  c.width = 320;
  c.height = 200;
  c.vertical_fov_deg = 70;
  const glm::mat4 proj = c.projection();
  for (const double depth : {0.3, 1.0, 2.5, 40.0}) {
    for (const float offset : {-0.0315f, 0.0315f, 0.2f}) {
      // The cyclopean point at normalised (0.3, 0.6) and view depth D, in world space.
      const glm::vec2 ndc(2 * 0.3f - 1, 1 - 2 * 0.6f);
      const glm::vec4 view_point(ndc.x * static_cast<float>(depth) / proj[0][0],
                                 ndc.y * static_cast<float>(depth) / proj[1][1], -static_cast<float>(depth), 1);
      const glm::vec4 world = glm::inverse(c.view_at(0)) * view_point;
      Camera eye = c;
      eye.eye_offset_m = offset;
      const glm::vec4 clip = proj * eye.view_at(0) * world;
      const double x = 0.5 * static_cast<double>(clip.x / clip.w + 1), y = 0.5 * static_cast<double>(1 - clip.y / clip.w);
      EXPECT_NEAR(x, 0.3 + eye.eye_shift_x(depth), 1e-5) << "depth " << depth << " offset " << offset;
      EXPECT_NEAR(y, 0.6, 1e-5);
    }
  }
  Camera eye = c;
  eye.eye_offset_m = 0.03f;
  EXPECT_EQ(eye.eye_shift_x(std::numeric_limits<double>::infinity()), 0.0);  // parallel eyes
  EXPECT_EQ(eye.eye_shift_x(std::nan("")), 0.0);
  EXPECT_EQ(eye.eye_shift_x(0), 0.0);
  EXPECT_EQ(c.eye_shift_x(2), 0.0);  // the cyclopean camera
}

struct StereoRun {
  std::unique_ptr<GazeInput> gaze = make_gaze_input("mouse");
  std::unique_ptr<FramePipeline> pipeline;
  PassTimer timer;
  StereoRun(Scene s, const std::vector<std::string>& settings, const std::string& gaze_spec = "mouse") {
    gaze = make_gaze_input(gaze_spec);
    Settings set;
    for (const std::string& a : settings) set.set_assignment(a);
    gaze->set_cursor(0.5, 0.5);
    pipeline = std::make_unique<FramePipeline>(std::move(s), set, std::make_unique<EmbreeBackend>(), *gaze);
  }
};

// The two images differ by the disparity of the box's front face: W P00 ipd / (2 D) pixels.
TEST(StereoFrame, TheEyesSeeTheBoxWithItsDisparity) {
  const float ipd = 0.2f;
  StereoRun run(box_scene(ipd), {"dof.enabled=false"});
  const double left = centroid_x(*run.pipeline->render(0, 0, 0, 0, run.timer, false, Eye::Left).gbuffer, 1);
  const double right = centroid_x(*run.pipeline->render(0, 0, 0, 0, run.timer, false, Eye::Right).gbuffer, 1);
  Camera eye = run.pipeline->scene().camera;
  eye.eye_offset_m = -0.5f * ipd;
  const double expected = 2 * eye.eye_shift_x(4.5) * 256;  // left minus right, pixels
  EXPECT_GT(expected, 8);
  EXPECT_NEAR(left - right, expected, 0.6);
}

// The right eye is the scene's camera moved by +ipd/2: its G-buffer is a one-view render of that camera.
TEST(StereoFrame, TheRightEyeIsAOneViewRenderOfTheMovedCamera) {
  StereoRun run(box_scene(0.063f), {"dof.enabled=false"});
  run.pipeline->render(0, 0, 0, 0, run.timer, false, Eye::Left);
  const GBuffer right = *run.pipeline->render(0, 0, 0, 0, run.timer, false, Eye::Right).gbuffer;
  Scene moved = box_scene(0.063f);
  moved.camera.stereo = false;
  const glm::vec3 offset = moved.camera.right() * 0.0315f;
  moved.camera.position += offset;
  moved.camera.target += offset;
  StereoRun mono(std::move(moved), {"dof.enabled=false"});
  const GBuffer one = *mono.pipeline->render(0, 0, 0, 0, mono.timer).gbuffer;
  ASSERT_EQ(right.size(), one.size());
  std::size_t differ = 0;
  for (std::size_t i = 0; i < one.size(); ++i)
    differ += right.object_id[i] != one.object_id[i] || glm::length(right.color[i] - one.color[i]) > 1e-4f;
  EXPECT_LE(differ, one.size() / 1000) << "pixels differing from the moved camera's one-view render";
  // And a one-view frame after the stereo frame is the scene's own camera again.
  const GBuffer mono_after = *run.pipeline->render(1, 0, 0, 0, run.timer).gbuffer;
  EXPECT_NEAR(centroid_x(mono_after, 1), 127.5, 0.6);
}

TEST(StereoFrame, TheRightEyeReusesTheLeftEyesSharedWork) {
  StereoRun run(box_scene(0.063f), {"dof.enabled=true", "gi.enabled=true", "gi.photons=2000", "lod.enabled=true"});
  const FramePipeline::Frame left = run.pipeline->render(0, 0, 0, 0, run.timer, false, Eye::Left);
  const FramePipeline::Frame right = run.pipeline->render(0, 0, 0, 0, run.timer, false, Eye::Right);
  const auto sums = run.timer.summary();
  for (const char* pass : {"attention", "focus", "gi.photons", "gi.index", "gbuffer", "dof", "gi.render", "tonemap"})
    EXPECT_EQ(sums.count(pass), 1u) << pass << " in the left eye";
  for (const char* pass : {"right.attention", "right.focus", "right.gi.photons", "right.gi.index", "right.lod-select"})
    EXPECT_EQ(sums.count(pass), 0u) << pass << " ran again for the right eye";
  for (const char* pass : {"right.gbuffer", "right.dof", "right.gi.render", "right.tonemap", "right.frame"})
    EXPECT_EQ(sums.count(pass), 1u) << pass << " in the right eye";
  ASSERT_NE(left.attention, nullptr);
  EXPECT_EQ(right.attention, left.attention);
  ASSERT_NE(left.focus, nullptr);
  EXPECT_EQ(right.focus, left.focus);
  ASSERT_NE(left.gi, nullptr);
  ASSERT_NE(right.gi, nullptr);
  EXPECT_EQ(right.gi->photons, left.gi->photons);  // the same map, gathered from the other eye
  EXPECT_EQ(left.eye, Eye::Left);
  EXPECT_EQ(right.eye, Eye::Right);
}

// Frame 0 knows no fixation depth (parallel eyes); later frames converge at the focus pass's depth,
// the left eye's gaze point moving right and the right eye's left by the same amount.
TEST(StereoFrame, EachEyesGazeIsTheCyclopeanGazeAtTheFixationDepth) {
  StereoRun run(box_scene(0.063f), {"dof.enabled=true"});
  for (std::uint64_t i = 0; i < 3; ++i) {
    const double t = static_cast<double>(i) / 30;
    const FramePipeline::Frame l = run.pipeline->render(i, t, t, t, run.timer, false, Eye::Left);
    const FramePipeline::Frame r = run.pipeline->render(i, t, t, t, run.timer, false, Eye::Right);
    EXPECT_EQ(l.fixation_m, r.fixation_m);
    if (i == 0) {
      EXPECT_TRUE(std::isinf(l.fixation_m));
      EXPECT_EQ(l.gaze.x, 0.5);
      EXPECT_EQ(r.gaze.x, 0.5);
      continue;
    }
    EXPECT_NEAR(l.fixation_m, 4.5, 0.3) << "the box's front face";
    Camera left_eye = run.pipeline->scene().camera;
    left_eye.eye_offset_m = -0.0315f;
    EXPECT_GT(l.eye_gaze_shift_x, 0);
    EXPECT_NEAR(l.eye_gaze_shift_x, left_eye.eye_shift_x(l.fixation_m), 1e-12);
    EXPECT_NEAR(r.eye_gaze_shift_x, -l.eye_gaze_shift_x, 1e-12);
    EXPECT_NEAR(l.gaze.x, 0.5 + l.eye_gaze_shift_x, 1e-12);
    EXPECT_NEAR(r.gaze.x, 0.5 + r.eye_gaze_shift_x, 1e-12);
    EXPECT_EQ(l.gaze.y, 0.5);
  }
}

// A binocular tracker's gaze: each eye's measured point, one eye lost in the last frame.
class BinocularGaze final : public GazeInput {
 public:
  std::string description() const override { return "binocular test gaze"; }
  GazeState at(double t) override {
    GazeState g;
    g.valid = true;
    g.x = 0.5, g.y = 0.4;
    g.left_eye = GazeState::Point{0.53, 0.41};
    if (t < 0.05) g.right_eye = GazeState::Point{0.47, 0.39};
    return g;
  }
};

// Issue 42: "per-eye gaze where the source has both eyes, cyclopean otherwise". Each eye is shown
// its own measured point, not the cyclopean point moved by the vergence; an eye the tracker lost
// falls back to the vergence.
TEST(StereoFrame, EachEyeSeesItsOwnMeasuredGazeWhereTheTrackerHasBothEyes) {
  BinocularGaze gaze;
  Settings set;
  set.set_assignment("dof.enabled=true");
  FramePipeline pipeline(box_scene(0.063f), set, std::make_unique<EmbreeBackend>(), gaze);
  PassTimer timer;
  for (std::uint64_t i = 0; i < 3; ++i) {
    const double t = static_cast<double>(i) / 30;
    const FramePipeline::Frame l = pipeline.render(i, t, t, t, timer, false, Eye::Left);
    const FramePipeline::Frame r = pipeline.render(i, t, t, t, timer, false, Eye::Right);
    EXPECT_TRUE(l.eye_gaze_measured);
    EXPECT_DOUBLE_EQ(l.gaze.x, 0.53);
    EXPECT_DOUBLE_EQ(l.gaze.y, 0.41);
    EXPECT_NEAR(l.eye_gaze_shift_x, 0.03, 1e-12);
    if (i < 2) {
      EXPECT_TRUE(r.eye_gaze_measured);
      EXPECT_DOUBLE_EQ(r.gaze.x, 0.47);
      EXPECT_DOUBLE_EQ(r.gaze.y, 0.39);
    } else {
      EXPECT_FALSE(r.eye_gaze_measured) << "the right eye lost: from the vergence";
      Camera right_eye = pipeline.scene().camera;
      right_eye.eye_offset_m = 0.0315f;
      EXPECT_NEAR(r.gaze.x, 0.5 + right_eye.eye_shift_x(r.fixation_m), 1e-12);
      EXPECT_DOUBLE_EQ(r.gaze.y, 0.4);
    }
  }
  // A one-view frame shows the combined point.
  const FramePipeline::Frame mono = pipeline.render(3, 0.1, 0.1, 0.1, timer);
  EXPECT_FALSE(mono.eye_gaze_measured);
  EXPECT_DOUBLE_EQ(mono.gaze.x, 0.5);
}

// Without gaze the GI area follows the most attended object, which the attention frame (the left
// eye's) places in the left eye's image: the right eye's area is where the right eye sees it.
TEST(StereoFrame, TheGiAreaFollowsTheAttendedObjectInEachEye) {
  StereoRun run(box_scene(0.2f), {"dof.enabled=false", "gi.enabled=true", "gi.photons=1000", "gi.gaze_area_deg=5"},
                "none");
  const FramePipeline::Frame left = run.pipeline->render(0, 0, 0, 0, run.timer, false, Eye::Left);
  ASSERT_NE(left.gi, nullptr);
  ASSERT_STREQ(left.gi->follows, "attention");
  const double left_x = left.gi->area.center_px.x, left_box = centroid_x(*left.gbuffer, 1);
  const FramePipeline::Frame right = run.pipeline->render(0, 0, 0, 0, run.timer, false, Eye::Right);
  const double right_x = right.gi->area.center_px.x, right_box = centroid_x(*right.gbuffer, 1);
  EXPECT_GT(left_box - right_box, 8);  // the disparity the area must follow
  EXPECT_NEAR(left_x - 0.5, left_box, 1.0);   // pixel centres: the centroid of pixel x is x + 0.5
  EXPECT_NEAR(right_x - 0.5, right_box, 1.0);
}

TEST(StereoFrame, ARightEyeWithoutItsLeftEyeIsRefused) {
  StereoRun run(box_scene(0.063f), {});
  try {
    run.pipeline->render(0, 0, 0, 0, run.timer, false, Eye::Right);
    FAIL() << "a right eye without a left eye rendered";
  } catch (const std::logic_error& e) {
    EXPECT_NE(std::string(e.what()).find("right eye of frame 0 without its left eye"), std::string::npos) << e.what();
  }
  run.pipeline->render(0, 0, 0, 0, run.timer, false, Eye::Left);
  EXPECT_THROW(run.pipeline->render(1, 0, 0, 0, run.timer, false, Eye::Right), std::logic_error);
  run.pipeline->render(2, 0, 0, 0, run.timer);  // a one-view frame has no right eye either
  EXPECT_THROW(run.pipeline->render(2, 0, 0, 0, run.timer, false, Eye::Right), std::logic_error);
}

TEST(StereoTimer, APrefixNamesTheRightEyesPasses) {
  PassTimer t;
  t.begin_frame(0, 0);
  t.record("gbuffer", 2);
  t.set_prefix("right.");
  t.record("gbuffer", 3);
  EXPECT_EQ(t.frame_ms("gbuffer"), 3);  // lookups take the prefix too
  t.set_prefix("");
  EXPECT_EQ(t.frame_ms("gbuffer"), 2);
  EXPECT_EQ(t.frame_ms("right.gbuffer"), 3);
  EXPECT_NE(t.summary_table().find("right.gbuffer"), std::string::npos);
}

}  // namespace
}  // namespace fovea::render
