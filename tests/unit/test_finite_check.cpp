// SPDX-License-Identifier: Apache-2.0
// The module-boundary check (renderer/pipeline/finite_check.h): NaN/Inf in a pass's output stops the
// frame with an error naming the pass, the buffer and the pixel; clean frames pass through.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "backend/embree/embree_backend.h"
#include "gaze/gaze_input.h"
#include "pipeline/finite_check.h"
#include "pipeline/frame_pipeline.h"

namespace fovea::render {
namespace {

TEST(FiniteCheck, NamesThePassBufferAndPixel) {
  std::vector<glm::vec3> image(12, glm::vec3(0.5f));
  EXPECT_NO_THROW(require_finite("dof", "colour", image, 4));
  image[6].g = std::numeric_limits<float>::quiet_NaN();
  try {
    require_finite("dof", "colour", image, 4);
    FAIL() << "no error";
  } catch (const NonFiniteError& e) {
    EXPECT_EQ(e.pass(), "dof");
    EXPECT_EQ(e.index(), 6u);
    const std::string what = e.what();
    EXPECT_NE(what.find("pass 'dof'"), std::string::npos) << what;
    EXPECT_NE(what.find("pixel (2, 1)"), std::string::npos) << what;
    EXPECT_NE(what.find("NaN"), std::string::npos) << what;
  }
  std::vector<double> list{1.0, -std::numeric_limits<double>::infinity()};
  try {
    require_finite("attention", "S_o", list);
    FAIL() << "no error";
  } catch (const NonFiniteError& e) {
    EXPECT_NE(std::string(e.what()).find("element 1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("-Inf"), std::string::npos) << e.what();
  }
}

Scene one_quad_scene(float kd) {  // a lit quad filling the view
  Scene s;
  s.camera.width = 32;
  s.camera.height = 24;
  s.camera.position = {0, 0, 3};
  s.camera.target = {0, 0, 0};
  Material m;
  m.kd = glm::vec3(kd);
  s.materials.push_back(m);
  Object o;
  o.id = 1;
  o.name = "quad";
  auto mesh = std::make_shared<Mesh>();
  mesh->positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  mesh->normals.assign(4, glm::vec3(0, 0, 1));
  mesh->indices = {0, 1, 2, 0, 2, 3};
  o.mesh = mesh;
  s.objects.push_back(o);
  Light l;
  l.position = {0, 0, 3};
  l.power = glm::vec3(50);
  s.lights.push_back(l);
  return s;
}

// Embree's output is finite even for a NaN material (it sanitises); a backend that is not, wrapped
// around it, shows what the check does when any pass breaks the promise.
class NanAtOnePixel : public Backend {
 public:
  std::string name() const override { return "nan-at-one-pixel"; }
  BackendCapabilities capabilities() const override { return inner_.capabilities(); }
  void set_scene(const Scene& scene) override { inner_.set_scene(scene); }
  void set_camera(const Camera& camera) override { inner_.set_camera(camera); }
  void render(const FrameTime& time, const BackendSettings& settings, GBuffer& out) override {
    inner_.render(time, settings, out);
    out.depth[out.index(5, 3)] = std::numeric_limits<float>::infinity();
  }

 private:
  EmbreeBackend inner_;
};

TEST(FiniteCheck, ThePipelineStopsAtThePassThatWritesNonFinite) {
  auto gaze = make_gaze_input("none");
  Settings settings;
  settings.set("debug.finite_checks", "true");
  {
    FramePipeline clean(one_quad_scene(0.5f), settings, std::make_unique<EmbreeBackend>(), *gaze);
    PassTimer timer;
    EXPECT_NO_THROW(clean.render(0, 0, 0, 0, timer));
  }
  FramePipeline bad(one_quad_scene(0.5f), settings, std::make_unique<NanAtOnePixel>(), *gaze);
  PassTimer timer;
  try {
    bad.render(0, 0, 0, 0, timer);
    FAIL() << "the Inf depth crossed the boundary";
  } catch (const NonFiniteError& e) {
    EXPECT_EQ(e.pass(), "gbuffer");
    EXPECT_EQ(e.buffer(), "depth");
    EXPECT_NE(std::string(e.what()).find("pixel (5, 3)"), std::string::npos) << e.what();
  }
  settings.set("debug.finite_checks", "false");  // off: the frame goes through (the release default)
  FramePipeline unchecked(one_quad_scene(0.5f), settings, std::make_unique<NanAtOnePixel>(), *gaze);
  EXPECT_NO_THROW(unchecked.render(0, 0, 0, 0, timer));
}

}  // namespace
}  // namespace fovea::render
