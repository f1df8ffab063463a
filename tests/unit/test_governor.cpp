// SPDX-License-Identifier: Apache-2.0
// The time-budget governor (renderer/governor/governor.h): it takes the most accurate combination
// that fits the budget, corrects the fronts by measured pass times, says when it cannot meet a
// budget, and refuses malformed fronts with the field named.
#include <gtest/gtest.h>

#include "governor/governor.h"

namespace fovea::render {
namespace {

FramePlan plan_running(std::initializer_list<PassId> ids) {
  FramePlan p;
  for (int i = 0; i < kPassCount; ++i) p.passes.push_back(PlannedPass{static_cast<PassId>(i), false, false, "", {}, false, {}, ""});
  for (PassId id : ids) p.passes[static_cast<std::size_t>(id)].runs = p.passes[static_cast<std::size_t>(id)].needed = true;
  return p;
}

const char* kFronts = R"({"fronts": [
 {"effect": "dof", "passes": ["dof"], "metric": "PSNR dB", "reference": "ray traced", "higher_better": true,
  "scales_with_pixels": true, "pixels": 10000,
  "options": [{"label": "cheap", "settings": {"dof.method": "lee-mipmap"}, "ms": 10, "accuracy": 28},
              {"label": "mid", "settings": {"dof.method": "schedl-layered"}, "ms": 30, "accuracy": 33},
              {"label": "best", "settings": {"dof.method": "accum"}, "ms": 100, "accuracy": 42}]},
 {"effect": "gi", "passes": ["gi"], "metric": "relative RMSE", "reference": "2M photons", "higher_better": false,
  "scales_with_pixels": false, "pixels": 0,
  "options": [{"label": "5k", "settings": {"gi.photons": "5000"}, "ms": 5, "accuracy": 0.2},
              {"label": "40k", "settings": {"gi.photons": "40000"}, "ms": 40, "accuracy": 0.08}]}
]})";

void frame(PassTimer& t, std::uint64_t i, double frame_ms, double dof_ms, double gi_ms) {
  t.begin_frame(i, 0);
  t.record("dof", dof_ms);
  t.record("gi", gi_ms);
  t.record("frame", frame_ms);
}

TEST(Governor, TakesTheMostAccurateCombinationWithinTheBudget) {
  Governor g(60, parse_fronts(kFronts, "test"));
  Settings s;
  g.apply(plan_running({PassId::Dof, PassId::Gi}), "embree", "cpu", 100, 100, s);
  // 60 ms: mid + 5k (35 ms, utility 0.36 + 0) loses to cheap + 40k (50 ms, 0 + 1); mid + 40k is 70.
  EXPECT_EQ(s.text("dof.method"), "lee-mipmap");
  EXPECT_EQ(s.text("gi.photons"), "40000");
  EXPECT_FALSE(g.state().cannot_meet);
  EXPECT_NEAR(g.state().predicted_ms, 50, 1e-9);
  Governor roomy(200, parse_fronts(kFronts, "test"));
  roomy.apply(plan_running({PassId::Dof, PassId::Gi}), "embree", "cpu", 100, 100, s);
  EXPECT_EQ(s.text("dof.method"), "accum");
  // Image-space times scale with the pixel count: at 4x the pixels the best DOF no longer fits.
  Governor bigger(200, parse_fronts(kFronts, "test"));
  bigger.apply(plan_running({PassId::Dof, PassId::Gi}), "embree", "cpu", 200, 200, s);
  EXPECT_EQ(s.text("dof.method"), "schedl-layered");
}

// A front measured on a device (Front::device) is used only where the frame runs on that device; the
// general front elsewhere. Here the GPU's lee-mipmap fits a budget the CPU's does not.
TEST(Governor, DeviceFrontsApplyOnlyOnTheirDevice) {
  const char* fronts = R"({"fronts": [
   {"effect": "dof", "backend": "gl", "device": "NVIDIA", "passes": ["dof", "gpu.dof"], "metric": "PSNR dB",
    "reference": "ray traced", "higher_better": true, "scales_with_pixels": true, "pixels": 10000,
    "options": [{"label": "gpu", "settings": {"dof.method": "lee-mipmap", "dof.device": "gpu"}, "ms": 1, "accuracy": 28},
                {"label": "gpu sigma=C/4", "settings": {"dof.method": "lee-mipmap", "dof.device": "gpu",
                 "dof.sigma_per_coc": "0.25"}, "ms": 1.1, "accuracy": 31}]},
   {"effect": "dof", "passes": ["dof"], "metric": "PSNR dB", "reference": "ray traced", "higher_better": true,
    "scales_with_pixels": true, "pixels": 10000,
    "options": [{"label": "cpu", "settings": {"dof.method": "lee-mipmap"}, "ms": 50, "accuracy": 28}]}
  ]})";
  const FramePlan plan = plan_running({PassId::Dof});
  Governor on_gpu(10, parse_fronts(fronts, "test"));
  Settings s;
  on_gpu.apply(plan, "gl", "OpenGL 4.6 (NVIDIA H200/PCIe/SSE2)", 100, 100, s);
  EXPECT_EQ(on_gpu.state().choices.at(0).label, "gpu sigma=C/4");
  EXPECT_EQ(s.text("dof.device"), "gpu");
  EXPECT_FALSE(on_gpu.state().cannot_meet);
  for (const auto& [backend, device] : {std::pair{"gl", "OpenGL 4.5 (llvmpipe (LLVM 15.0.6, 256 bits))"},
                                        std::pair{"gl", "cpu"}, std::pair{"embree", "cpu"}}) {
    Governor elsewhere(10, parse_fronts(fronts, "test"));
    Settings t;
    elsewhere.apply(plan, backend, device, 100, 100, t);
    EXPECT_EQ(elsewhere.state().choices.at(0).label, "cpu") << backend << " on " << device;
    EXPECT_TRUE(elsewhere.state().cannot_meet);
  }
}

TEST(Governor, OnlyEffectsThePlanRunsAreGoverned) {
  Governor g(60, parse_fronts(kFronts, "test"));
  Settings s;
  g.apply(plan_running({PassId::Gi}), "embree", "cpu", 100, 100, s);
  ASSERT_EQ(g.state().choices.size(), 1u);
  EXPECT_EQ(g.state().choices[0].effect, "gi");
  EXPECT_EQ(s.text("dof.method"), Settings().text("dof.method"));
}

TEST(Governor, AdaptsWhenMeasuredTimesDrift) {
  Governor g(60, parse_fronts(kFronts, "test"));
  g.replan_frames = 1;
  Settings s;
  PassTimer t;
  const FramePlan plan = plan_running({PassId::Dof, PassId::Gi});
  g.apply(plan, "embree", "cpu", 100, 100, s);
  ASSERT_EQ(s.text("gi.photons"), "40000");
  // GI takes twice what the front says on this machine, and the rest of the frame 5 ms.
  for (int i = 0; i < 20; ++i) {
    const bool big = s.text("gi.photons") == "40000";
    const double dof = s.is("dof.method", "lee-mipmap") ? 10 : 30;
    const double gi = big ? 80 : 10;
    frame(t, static_cast<std::uint64_t>(i), dof + gi + 5, dof, gi);
    g.observe(t);
    g.apply(plan, "embree", "cpu", 100, 100, s);
  }
  EXPECT_EQ(s.text("gi.photons"), "5000");
  EXPECT_EQ(s.text("dof.method"), "schedl-layered");  // 30 + 10 + 5 fits; 100 + 10 + 5 does not
  EXPECT_NEAR(g.state().other_ms, 5, 0.5);
  EXPECT_LE(g.state().predicted_ms, 60);
}

// A stereo frame: image-space fronts scale by both views' pixels, and observe() counts each pass in
// both eyes (the right eye's as "right.<pass>") and the frame as both renders.
TEST(Governor, AStereoFrameCountsBothEyes) {
  Governor mono(60, parse_fronts(kFronts, "test")), stereo(60, parse_fronts(kFronts, "test"));
  Settings a, b;
  const FramePlan plan = plan_running({PassId::Dof, PassId::Gi});
  mono.apply(plan, "embree", "cpu", 100, 100, a);
  stereo.apply(plan, "embree", "cpu", 200, 100, b);
  EXPECT_NEAR(stereo.state().choices.at(0).predicted_ms, 2 * mono.state().choices.at(0).predicted_ms, 1e-9);
  PassTimer t;
  t.begin_frame(0, 0);
  t.record("dof", 20);
  t.record("gi", 40);
  t.record("frame", 65);
  t.set_prefix("right.");
  t.record("dof", 20);
  t.record("gi", 4);  // the photon map was the left eye's
  t.record("frame", 27);
  t.set_prefix("");
  stereo.observe(t);
  EXPECT_NEAR(stereo.state().measured_ms, 92, 1e-9);
  EXPECT_NEAR(stereo.state().other_ms, 92 - 40 - 44, 1e-9);
  EXPECT_NEAR(stereo.state().choices.at(0).correction, 40.0 / 20.0, 1e-9);  // dof: 40 ms for a 2 x 10 ms front
}

TEST(Governor, SaysWhenNoCombinationMeetsTheBudget) {
  Governor g(12, parse_fronts(kFronts, "test"));
  Settings s;
  g.apply(plan_running({PassId::Dof, PassId::Gi}), "embree", "cpu", 100, 100, s);
  EXPECT_TRUE(g.state().cannot_meet);
  EXPECT_EQ(s.text("dof.method"), "lee-mipmap");
  EXPECT_EQ(s.text("gi.photons"), "5000");
  EXPECT_NE(g.state().summary().find("cannot meet"), std::string::npos);
  EXPECT_THROW(g.set_budget_ms(0), std::invalid_argument);
  EXPECT_THROW(g.set_budget_ms(std::nan("")), std::invalid_argument);
}

TEST(Governor, MalformedFrontsNameTheField) {
  const auto error = [](const std::string& json) {
    try {
      parse_fronts(json, "f.json");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error("{").find("f.json: not JSON"), std::string::npos);
  EXPECT_NE(error(R"({"fronts": [{"effect": "blur"}]})").find("f.json.fronts[0].effect"), std::string::npos);
  std::string bad_ms = kFronts;
  bad_ms.replace(bad_ms.find("\"ms\": 30"), 8, "\"ms\": -3");
  EXPECT_NE(error(bad_ms).find("f.json.fronts[0].options[1].ms"), std::string::npos) << error(bad_ms);
  std::string bad_setting = kFronts;
  bad_setting.replace(bad_setting.find("\"gi.photons\": \"5000\""), 20, "\"gi.photons\": \"many\"");
  EXPECT_NE(error(bad_setting).find("f.json.fronts[1].options[0].settings"), std::string::npos) << error(bad_setting);
}

TEST(Governor, TheBuiltInFrontsParseAndEachIsSortedByTime) {
  const auto& fronts = builtin_fronts();
  ASSERT_GE(fronts.size(), 4u);
  for (const Front& f : fronts) {
    ASSERT_FALSE(f.options.empty()) << f.effect;
    for (std::size_t k = 1; k < f.options.size(); ++k) EXPECT_LE(f.options[k - 1].ms, f.options[k].ms) << f.effect;
  }
}

}  // namespace
}  // namespace fovea::render
