// SPDX-License-Identifier: Apache-2.0
// The effect planner's decisions, table-driven: each row is a scene feature set plus settings, and
// the passes that must (not) be planned.
#include <gtest/gtest.h>

#include <algorithm>

#include "attention/attention.h"
#include "backend/gpu_frame.h"
#include "pipeline/planner.h"
#include "scene/geometry.h"

using namespace fovea::render;

namespace {

struct SceneFeatures {
  bool thin_lens = false;
  bool mirror = false;
  bool lights = true;
  bool lods = false;
};

Scene make_scene(const SceneFeatures& f) {
  Scene s;
  s.materials.push_back(Material{});
  Material mirror;
  mirror.type = MaterialType::Mirror;
  s.materials.push_back(mirror);
  Object o;
  o.id = 1;
  o.mesh = std::make_shared<Mesh>(make_box({1, 1, 1}));
  o.material = f.mirror ? 1 : 0;
  if (f.lods) o.lods.push_back(LodLevel{o.mesh, 0.01f});
  s.objects.push_back(o);
  if (f.lights) s.lights.push_back(Light{});
  if (f.thin_lens) {
    s.camera.lens.aperture_m = 0.01;
    s.camera.lens.focal_length_m = 0.05;
  }
  return s;
}

struct Row {
  const char* name;
  SceneFeatures scene;
  std::vector<std::string> settings;
  bool gaze;
  std::vector<PassId> needed;
  std::vector<PassId> not_needed;
  const char* reason_contains;  // in the reason of the first not_needed pass (or first needed)
};

const std::vector<Row> kRows = {
    {"pinhole: no dof, hence no focus, hence no attention", {}, {}, true,
     {PassId::GBuffer, PassId::Tonemap, PassId::Overlay}, {PassId::Dof, PassId::Focus, PassId::Attention}, "pinhole"},
    {"thin lens: dof needs focus, focus (gaze+attention) needs attention", {.thin_lens = true}, {}, true,
     {PassId::Dof, PassId::Focus, PassId::Attention}, {PassId::Gi, PassId::LodSelect}, "gi.enabled=false"},
    {"fixed focus: dof without focus or attention", {.thin_lens = true}, {"focus.mode=fixed"}, true, {PassId::Dof},
     {PassId::Focus, PassId::Attention}, "focus.mode=fixed"},
    {"gaze-only focus: no attention needed", {.thin_lens = true}, {"focus.mode=gaze"}, true,
     {PassId::Dof, PassId::Focus}, {PassId::Attention}, "nothing consumes attention"},
    {"dof switched off", {.thin_lens = true}, {"dof.enabled=false"}, true, {}, {PassId::Dof, PassId::Focus},
     "dof.enabled=false"},
    {"gi on, diffuse scene: gi without caustics", {}, {"gi.enabled=true"}, true, {PassId::Gi}, {}, "caustic map: no"},
    {"gi on, mirror: caustic map", {.mirror = true}, {"gi.enabled=true"}, true, {PassId::Gi}, {}, "caustic map: yes"},
    {"gi on but no lights", {.lights = false}, {"gi.enabled=true"}, true, {}, {PassId::Gi}, "no lights"},
    {"LOD chains, ULOD: lod-select, which consumes attention", {.lods = true}, {"lod.policy=ulod"}, true,
     {PassId::LodSelect, PassId::Attention}, {PassId::Dof}, "pinhole"},
    {"LOD chains, screen size: lod-select without attention", {.lods = true}, {}, true, {PassId::LodSelect},
     {PassId::Attention}, "nothing consumes attention"},
    {"LOD chains but lod off", {.lods = true}, {"lod.enabled=false"}, true, {}, {PassId::LodSelect, PassId::Attention},
     "lod.enabled=false"},
    {"no LOD chains", {}, {}, true, {}, {PassId::LodSelect}, "no object has an LOD chain"},
    {"no gaze source: no gaze overlay", {}, {}, false, {PassId::Tonemap}, {PassId::Overlay}, "no gaze source"},
    {"attention overlay requested", {}, {"overlay.map=attention"}, false, {PassId::Overlay, PassId::Attention}, {},
     "overlay.map=attention"},
    {"attention switched off", {.thin_lens = true}, {"attention.enabled=false"}, true, {PassId::Focus},
     {PassId::Attention}, "attention.enabled=false"},
    {"output=gbuffer: only the G-buffer", {.thin_lens = true, .mirror = true}, {"output=gbuffer", "gi.enabled=true"},
     true, {PassId::GBuffer}, {PassId::Tonemap, PassId::Overlay, PassId::Dof, PassId::Gi, PassId::Focus}, "output=gbuffer"},
};

}  // namespace

TEST(Planner, DecisionTable) {
  for (const Row& row : kRows) {
    SCOPED_TRACE(row.name);
    const Scene scene = make_scene(row.scene);
    Settings settings;
    for (const auto& a : row.settings) settings.set_assignment(a);
    const FramePlan plan = plan_frame(PlanContext{scene, settings, row.gaze});
    for (PassId id : row.needed) EXPECT_TRUE(plan.needed(id)) << declaration(id).name << ": " << plan.at(id).reason;
    for (PassId id : row.not_needed) EXPECT_FALSE(plan.needed(id)) << declaration(id).name << ": " << plan.at(id).reason;
    const PassId probe = !row.not_needed.empty() ? row.not_needed.front() : row.needed.front();
    EXPECT_NE(plan.at(probe).reason.find(row.reason_contains), std::string::npos)
        << declaration(probe).name << " reason was: " << plan.at(probe).reason;
    EXPECT_TRUE(plan.runs(PassId::GBuffer));
  }
}

TEST(Planner, DofRunsWithAThinLensAndSaysWhenAMethodCannotRun) {
  const Scene scene = make_scene({.thin_lens = true});
  Settings settings;
  FramePlan plan = plan_frame(PlanContext{scene, settings, true});
  EXPECT_TRUE(plan.runs(PassId::Dof)) << plan.explain();
  EXPECT_NE(plan.explain().find("method lee-mipmap"), std::string::npos) << plan.explain();
  settings.set_assignment("dof.method=schedl-layered");
  EXPECT_TRUE(plan_frame(PlanContext{scene, settings, true}).runs(PassId::Dof));
  // The ray-traced reference needs per-pixel lens rays: not on the raster backend.
  settings.set_assignment("dof.method=reference");
  EXPECT_TRUE(plan_frame(PlanContext{scene, settings, true, true}).runs(PassId::Dof));
  plan = plan_frame(PlanContext{scene, settings, true, false});
  EXPECT_FALSE(plan.runs(PassId::Dof));
  const std::string text = plan.explain();
  EXPECT_NE(text.find("later dof"), std::string::npos) << text;
  EXPECT_NE(text.find("run   gbuffer"), std::string::npos) << text;
  EXPECT_NE(text.find("--backend embree"), std::string::npos) << text;
  settings.set_assignment("dof.method=accum");
  EXPECT_TRUE(plan_frame(PlanContext{scene, settings, true, false}).runs(PassId::Dof));
}

// The gi line names the radius the pass will use, and whether gi.nn_radius=auto chose it.
TEST(Planner, TheGiReasonNamesTheRadianceEstimatesRadius) {
  const Scene scene = make_scene({});
  Settings settings;
  settings.set("gi.enabled", "true");
  PlanContext c{scene, settings, true};
  c.gi_nn_radius_m = 2.5f;
  const std::string why = plan_frame(c).explain();
  EXPECT_NE(why.find("radiance estimate radius 2.5 m (gi.nn_radius=auto"), std::string::npos) << why;
  settings.set("gi.nn_radius", "0.3");
  c.gi_nn_radius_m = 0.3f;
  const std::string set = plan_frame(c).explain();
  EXPECT_NE(set.find("radiance estimate radius 0.3 m"), std::string::npos) << set;
  EXPECT_EQ(set.find("gi.nn_radius=auto"), std::string::npos) << set;
}

TEST(Planner, EveryPassHasADeclaration) {
  ASSERT_EQ(pass_declarations().size(), static_cast<std::size_t>(kPassCount));
  for (std::size_t i = 0; i < pass_declarations().size(); ++i) {
    const PassDecl& d = pass_declarations()[i];
    EXPECT_EQ(static_cast<std::size_t>(d.id), i) << d.name << " out of pipeline order";
    EXPECT_FALSE(d.writes.empty()) << d.name << " writes nothing: the graph would always cull it";
    EXPECT_NE(d.rule, nullptr) << d.name;
  }
}

// The typed declarations of what each pass reads of the G-buffer, and what the GPU-resident frame
// derives from them: the planes read back for the passes without a GPU implementation, and the
// planes the G-buffer pass must write (the others are culled).
TEST(Planner, GBufferPlanesReadFollowFromThePassesThatRun) {
  struct Row {
    const char* name;
    SceneFeatures scene;
    std::vector<std::string> settings;
    GBufferPlanes on_cpu, all;
  };
  const GBufferPlanes cdi{.color = true, .depth = true, .object_id = true};
  const Row rows[] = {
      {"pinhole: only the tone map reads (colour), on the GPU", {}, {}, {}, {.color = true}},
      {"thin lens: attention (colour, depth, ids) and lee-mipmap on the GPU, focus reads what it looks at",
       {.thin_lens = true}, {}, {}, cdi},
      {"attention.device=cpu: attention reads colour, depth and ids back", {.thin_lens = true},
       {"attention.device=cpu"}, cdi, cdi},
      {"the accumulation reference renders again: DOF reads nothing", {.thin_lens = true},
       {"dof.method=accum", "focus.mode=fixed"}, {}, {.color = true}},
      {"LOD by screen size: nothing of the G-buffer", {.lods = true}, {}, {}, {.color = true}},
      {"LOD by Brown's policy: the last frame's colour and ids", {.lods = true}, {"lod.policy=brown"},
       {.color = true, .object_id = true}, {.color = true, .object_id = true}},
      {"ULOD: attention reads its proxy; LOD's blend reads colour and ids where they lie", {.lods = true},
       {"lod.policy=ulod"}, {}, {.color = true, .object_id = true}},
      {"the focus outline reads depth and ids on the GPU; focus without attention reads them back", {.thin_lens = true},
       {"dof.enabled=false", "focus.mode=gaze", "overlay.focus=true"}, {.depth = true, .object_id = true},
       {.color = true, .depth = true, .object_id = true}},
      {"gi on the CPU reads nothing", {}, {"gi.enabled=true", "gi.device=cpu"}, {}, {.color = true}},
      {"gi gathering on the GPU reads depth, ids and normals where they lie", {}, {"gi.enabled=true"}, {},
       {.color = true, .depth = true, .object_id = true, .normal = true}},
  };
  for (const Row& row : rows) {
    SCOPED_TRACE(row.name);
    const Scene scene = make_scene(row.scene);
    Settings settings;
    for (const std::string& a : row.settings) settings.set_assignment(a);
    PlanContext c{scene, settings, true};
    c.gpu_resident = true;
    const FramePlan plan = plan_frame(c);
    EXPECT_EQ(planes_read_on_cpu(plan), row.on_cpu) << plan.explain();
    EXPECT_EQ(planes_read(plan), row.all) << plan.explain();
  }
  // The passes with a GPU implementation: the G-buffer, attention, the tone map, the overlay, dof for
  // some methods, and gi's gather.
  for (const PassDecl& d : pass_declarations()) {
    EXPECT_EQ(d.on_gpu != nullptr, d.id == PassId::GBuffer || d.id == PassId::Attention || d.id == PassId::Tonemap ||
                                       d.id == PassId::Overlay || d.id == PassId::Dof || d.id == PassId::Gi)
        << d.name;
  }
}

// dof.device and the methods with a GPU implementation: where dof runs in a GPU-resident frame, what
// comes back for it, and what the plan says.
TEST(Planner, AttentionRunsOnTheGpuWhereTheFrameLiesAndSaysWhyNot) {
  struct Row {
    const char* name;
    std::vector<std::string> settings;
    bool resident;
    bool runs, on_gpu;
    const char* says;
  };
  const Row rows[] = {
      {"a GPU-resident frame", {}, true, true, true, "on the GPU"},
      {"the readback path: on the CPU, nothing said", {}, false, true, false, ""},
      {"attention.device=cpu", {"attention.device=cpu"}, true, true, false, "on the CPU: attention.device=cpu"},
      {"attention.device=gpu without a GPU-resident frame: later", {"attention.device=gpu"}, false, false, false,
       "attention.device=gpu: the frame is not on the GPU"},
      {"attention.device=gpu where it can", {"attention.device=gpu"}, true, true, true, "on the GPU"},
  };
  const Scene scene = make_scene({.thin_lens = true});
  for (const Row& row : rows) {
    SCOPED_TRACE(row.name);
    Settings settings;
    settings.set("focus.mode", "attention");
    for (const std::string& a : row.settings) settings.set_assignment(a);
    PlanContext c{scene, settings, true};
    c.gpu_resident = row.resident;
    const FramePlan plan = plan_frame(c);
    EXPECT_EQ(plan.runs(PassId::Attention), row.runs) << plan.explain();
    EXPECT_EQ(plan.at(PassId::Attention).on_gpu, row.on_gpu) << plan.explain();
    const PlannedPass& p = plan.at(PassId::Attention);
    EXPECT_NE(p.reason.find(row.says), std::string::npos) << p.reason;
    // In a GPU-resident frame colour comes back for attention only when it runs on the CPU (focus
    // reads depth and ids; dof runs on the GPU).
    if (row.resident) {
      EXPECT_EQ(planes_read_on_cpu(plan).color, row.runs && !row.on_gpu) << plan.explain();
    }
  }
  // On a software rasteriser auto keeps it on the CPU; gpu still puts it there.
  for (const char* device : {"auto", "gpu"}) {
    Settings settings;
    settings.set("attention.device", device);
    PlanContext c{scene, settings, true};
    c.gpu_resident = true;
    c.gpu_is_software = true;
    const FramePlan plan = plan_frame(c);
    const bool gpu = std::string(device) == "gpu";
    EXPECT_EQ(plan.at(PassId::Attention).on_gpu, gpu) << device;
    if (!gpu) {
      EXPECT_NE(plan.at(PassId::Attention).reason.find("on the CPU: attention.device=auto on a software rasteriser"),
                std::string::npos)
          << plan.at(PassId::Attention).reason;
    }
  }
  // ULOD runs attention first, on its own proxy render: on the GPU too (the proxy is rendered there).
  const Scene with_lods = make_scene({.thin_lens = true, .lods = true});
  Settings settings;
  settings.set("lod.policy", "ulod");
  PlanContext c{with_lods, settings, true};
  c.gpu_resident = true;
  const FramePlan plan = plan_frame(c);
  ASSERT_TRUE(plan.runs(PassId::Attention)) << plan.explain();
  EXPECT_TRUE(plan.at(PassId::Attention).on_gpu) << plan.at(PassId::Attention).reason;
  EXPECT_FALSE(planes_read_on_cpu(plan).any()) << plan.explain();
}

// gi.device: the gather on the GPU where the frame lies, unless something needs the CPU's; why not.
TEST(Planner, GiGathersOnTheGpuWhereTheFrameLiesAndSaysWhyNot) {
  struct Row {
    const char* name;
    std::vector<std::string> settings;
    bool resident, software;
    const char* device_says;  // "" : the frame can gather
    bool runs, on_gpu;
    const char* says;
  };
  const Row rows[] = {
      {"a GPU-resident frame on a GPU", {}, true, false, "", true, true, "on the GPU"},
      {"the readback path: on the CPU", {}, false, false, "", true, false, "follows the gaze"},
      {"gi.device=cpu", {"gi.device=cpu"}, true, false, "", true, false, "on the CPU: gi.device=cpu"},
      {"the k nearest are the CPU's", {"gi.estimate=nearest"}, true, false, "", true, false,
       "gi.estimate=nearest is the CPU's"},
      {"precomputed irradiance is the CPU's", {"gi.estimate=precomputed"}, true, false, "", true, false,
       "gi.estimate=precomputed is the CPU's"},
      {"gaze-directed: the GPU labels the photons used", {"gi.strategy=gaze-directed"}, true, false, "", true, true,
       "on the GPU"},
      {"shadow rays", {"shadows=true"}, true, false, "", true, false, "no shadow rays"},
      {"the CSF periphery", {"gi.periphery=csf"}, true, false, "", true, false, "gi.periphery=csf"},
      {"a software rasteriser with auto", {}, true, true, "", true, false, "software rasteriser"},
      {"a software rasteriser with gi.device=gpu", {"gi.device=gpu"}, true, true, "", true, true, "on the GPU"},
      {"no compute shaders", {}, true, false, "the GPU gather needs compute shaders", true, false, "needs compute"},
      {"gi.device=gpu without compute shaders: later", {"gi.device=gpu"}, true, false,
       "the GPU gather needs compute shaders", false, false, "gi.device=gpu: the GPU gather needs compute shaders"},
  };
  Scene many_lights = make_scene({});
  many_lights.lights.resize(GpuGiGather::kMaxLabelLights + 1, many_lights.lights.front());
  Settings gaze_directed;
  gaze_directed.set("gi.enabled", "true");
  gaze_directed.set("gi.strategy", "gaze-directed");
  PlanContext labels{many_lights, gaze_directed, true};
  labels.gpu_resident = true;
  const FramePlan too_many = plan_frame(labels);
  EXPECT_FALSE(too_many.at(PassId::Gi).on_gpu);
  EXPECT_NE(too_many.at(PassId::Gi).reason.find("17 lights: the GPU labels photons of 16 at most"), std::string::npos)
      << too_many.at(PassId::Gi).reason;
  const Scene scene = make_scene({});
  for (const Row& row : rows) {
    SCOPED_TRACE(row.name);
    Settings settings;
    settings.set("gi.enabled", "true");
    for (const std::string& a : row.settings) settings.set_assignment(a);
    PlanContext c{scene, settings, true};
    c.gpu_resident = row.resident;
    c.gpu_is_software = row.software;
    c.gpu_gi_unavailable = row.device_says;
    const FramePlan plan = plan_frame(c);
    EXPECT_EQ(plan.runs(PassId::Gi), row.runs) << plan.explain();
    EXPECT_EQ(plan.at(PassId::Gi).on_gpu, row.on_gpu) << plan.explain();
    EXPECT_NE(plan.at(PassId::Gi).reason.find(row.says), std::string::npos) << plan.at(PassId::Gi).reason;
  }
}

TEST(Planner, DofRunsOnTheGpuWhereItsMethodCanAndSaysWhyNot) {
  struct Row {
    const char* name;
    std::vector<std::string> settings;
    bool resident;
    bool runs, on_gpu;
    const char* says;
  };
  const Row rows[] = {
      {"lee-mipmap in a GPU-resident frame", {}, true, true, true, "lee-mipmap, on the GPU"},
      {"the readback path: on the CPU, nothing said", {}, false, true, false, "method lee-mipmap"},
      {"dof.device=cpu", {"dof.device=cpu"}, true, true, false, "on the CPU: dof.device=cpu"},
      {"lee-splat in a GPU-resident frame", {"dof.method=lee-splat"}, true, true, true, "lee-splat, on the GPU"},
      {"the CSF periphery composites GI on the CPU", {"gi.enabled=true", "gi.periphery=csf"}, true, true, false,
       "gi.periphery=csf composites GI over the DOF colour on the CPU"},
      {"dof.device=gpu without a GPU-resident frame: later", {"dof.device=gpu"}, false, false, false,
       "dof.device=gpu: the frame is not on the GPU"},
      {"dof.device=gpu with a method that renders again: later", {"dof.device=gpu", "dof.method=accum"}, true, false,
       false, "dof.device=gpu: dof.method=accum has no GPU implementation yet"},
      {"schedl-layered in a GPU-resident frame", {"dof.method=schedl-layered"}, true, true, true,
       "schedl-layered, on the GPU"},
  };
  const Scene scene = make_scene({.thin_lens = true});
  for (const Row& row : rows) {
    SCOPED_TRACE(row.name);
    Settings settings;
    settings.set("focus.mode", "fixed");
    for (const std::string& a : row.settings) settings.set_assignment(a);
    PlanContext c{scene, settings, true};
    c.gpu_resident = row.resident;
    const FramePlan plan = plan_frame(c);
    EXPECT_EQ(plan.runs(PassId::Dof), row.runs) << plan.explain();
    EXPECT_TRUE(plan.needed(PassId::Dof));
    EXPECT_EQ(plan.at(PassId::Dof).on_gpu, row.on_gpu) << plan.explain();
    EXPECT_NE(plan.at(PassId::Dof).reason.find(row.says), std::string::npos) << plan.at(PassId::Dof).reason;
    // In a GPU-resident frame what dof reads comes back only when it runs on the CPU.
    if (row.resident) {
      EXPECT_EQ(planes_read_on_cpu(plan).color, row.runs && !row.on_gpu) << plan.explain();
    }
  }
}

// The graph's declarations are closed: every resource a pass reads is written by some pass, and
// every resource written is read by some pass or is a frame output (else the writer is always culled).
TEST(PlannerGraph, EveryEdgeHasAProducerAndEveryProductAConsumer) {
  for (int i = 0; i < kResourceCount; ++i) {
    const auto r = static_cast<Resource>(i);
    bool written = false, read = false;
    for (const PassDecl& d : pass_declarations()) {
      written = written || std::find(d.writes.begin(), d.writes.end(), r) != d.writes.end();
      for (const ReadDecl& e : d.reads) read = read || e.resource == r;
    }
    EXPECT_TRUE(written) << to_string(r) << " is read but no pass writes it";
    EXPECT_TRUE(read || r == Resource::Display || r == Resource::GBuffer) << to_string(r) << " is written, never read";
  }
}

// The culling, checked on every combination of a grid of scenes and settings against what the
// graph promises: the G-buffer always runs; a pass runs only when needed; every pass that runs
// writes the output or something a running pass reads this frame; and a pass that wants to run and
// can is culled only when no running pass reads what it writes.
TEST(PlannerGraph, CullingKeepsExactlyThePassesTheOutputDependsOn) {
  int plans = 0;
  for (const bool thin : {false, true})
    for (const bool lods : {false, true})
      for (const bool gaze : {false, true})
        for (const bool rays : {false, true})
          for (const char* output : {"final", "gbuffer"})
            for (const char* mode : {"fixed", "gaze", "gaze+attention"})
              for (const char* method : {"lee-mipmap", "reference"})
                for (const char* policy : {"screen-size", "ulod"})
                  for (const char* map : {"none", "attention", "depth"})
                    for (const char* focus_overlay : {"false", "true"})
                      for (const char* gi : {"false", "true"}) {
                        const Scene scene = make_scene({.thin_lens = thin, .lods = lods});
                        Settings s;
                        for (const std::string& a :
                             {std::string("output=") + output, std::string("focus.mode=") + mode,
                              std::string("dof.method=") + method, std::string("lod.policy=") + policy,
                              std::string("overlay.map=") + map, std::string("overlay.focus=") + focus_overlay,
                              std::string("gi.enabled=") + gi})
                          s.set_assignment(a);
                        const PlanSettings typed = plan_settings(s);
                        const PlanContext c{scene, s, gaze, rays, &typed};
                        const FramePlan plan = plan_frame(c);
                        ++plans;
                        SCOPED_TRACE(plan.explain());
                        ASSERT_TRUE(plan.runs(PassId::GBuffer));
                        for (const PassDecl& p : pass_declarations()) {
                          const bool writes_output =
                              std::find(p.writes.begin(), p.writes.end(), c.output()) != p.writes.end();
                          bool read_by_a_running_pass = false;
                          for (const PassDecl& q : pass_declarations()) {
                            if (q.id == p.id || !plan.runs(q.id)) continue;
                            for (const ReadDecl& r : q.reads)
                              read_by_a_running_pass =
                                  read_by_a_running_pass ||
                                  (r.reads(c) &&
                                   std::find(p.writes.begin(), p.writes.end(), r.resource) != p.writes.end());
                          }
                          const PassRule rule = p.rule(c);
                          if (plan.runs(p.id)) {
                            EXPECT_TRUE(plan.needed(p.id)) << p.name;
                            EXPECT_TRUE(rule.wanted && rule.able) << p.name;
                            EXPECT_TRUE(writes_output || read_by_a_running_pass) << p.name << " runs for nobody";
                          } else if (rule.wanted && rule.able) {
                            EXPECT_FALSE(writes_output || read_by_a_running_pass) << p.name << " culled but read";
                          }
                        }
                      }
  EXPECT_EQ(plans, 2 * 2 * 2 * 2 * 2 * 3 * 2 * 2 * 3 * 2 * 2);
}

// The edges follow the settings (table-driven), and a culled pass says which reader does not read it.
TEST(PlannerGraph, EdgesFollowTheSettingsAndCulledPassesNameTheirReaders) {
  struct Row {
    const char* name;
    SceneFeatures scene;
    std::vector<std::string> settings;
    bool gaze;
    PassId pass;
    Resource resource;
    bool reads;
  };
  const Row rows[] = {
      {"focus reads attention with gaze+attention", {.thin_lens = true}, {}, true, PassId::Focus, Resource::Attention, true},
      {"not with gaze alone", {.thin_lens = true}, {"focus.mode=gaze"}, true, PassId::Focus, Resource::Attention, false},
      {"lod-select reads attention with ULOD", {.lods = true}, {"lod.policy=ulod"}, true, PassId::LodSelect,
       Resource::Attention, true},
      {"and then attention reads its proxy, not the G-buffer", {.lods = true}, {"lod.policy=ulod"}, true,
       PassId::Attention, Resource::GBuffer, false},
      {"gi's gaze area follows attention without a gaze source", {}, {"gi.enabled=true"}, false, PassId::Gi,
       Resource::Attention, true},
      {"not with one", {}, {"gi.enabled=true"}, true, PassId::Gi, Resource::Attention, false},
      {"nor with gi.area=full", {}, {"gi.enabled=true", "gi.area=full"}, false, PassId::Gi, Resource::Attention, false},
      {"the overlay reads the focal depth it draws", {}, {"overlay.focus=true"}, true, PassId::Overlay,
       Resource::FocalDepth, true},
      {"the accumulation reference reads nothing of the G-buffer", {.thin_lens = true}, {"dof.method=accum"}, true,
       PassId::Dof, Resource::GBuffer, false},
  };
  for (const Row& row : rows) {
    SCOPED_TRACE(row.name);
    const Scene scene = make_scene(row.scene);
    Settings settings;
    for (const std::string& a : row.settings) settings.set_assignment(a);
    const FramePlan plan = plan_frame(PlanContext{scene, settings, row.gaze});
    const std::vector<Resource>& reads = plan.at(row.pass).reads;
    EXPECT_EQ(std::find(reads.begin(), reads.end(), row.resource) != reads.end(), row.reads) << plan.explain();
  }
  const Scene scene = make_scene({});
  const FramePlan plan = plan_frame(PlanContext{scene, Settings{}, true});
  const std::string& why = plan.at(PassId::Attention).reason;
  EXPECT_NE(why.find("nothing consumes attention"), std::string::npos) << why;
  EXPECT_NE(why.find("lod-select reads it only with lod.policy=ulod"), std::string::npos) << why;
  EXPECT_NE(why.find("focus is not needed"), std::string::npos) << why;
  EXPECT_NE(why.find("overlay reads it only with overlay.map=saliency|spatial|temporal|attention"), std::string::npos)
      << why;
  // The graph printed lists only the edges that exist this frame: no GI inset without gi.
  EXPECT_EQ(plan.explain().find("GI inset"), std::string::npos) << plan.explain();
}

// The attention maps (one list, attention::kMaps) are overlay.map values and make the planner run
// the attention pass.
TEST(Planner, EveryAttentionMapIsAnOverlayValueAndNeedsAttention) {
  const Scene scene = make_scene({});
  for (const std::string_view map : attention::kMaps) {
    Settings settings;
    ASSERT_NO_THROW(settings.set("overlay.map", std::string(map))) << map;
    const FramePlan plan = plan_frame(PlanContext{scene, settings, true});
    EXPECT_TRUE(plan.runs(PassId::Attention)) << map << "\n" << plan.explain();
  }
  EXPECT_FALSE(attention::is_map("depth"));
}

// The passes parse their typed settings again only when the version moved: every change moves it,
// setting a value a key already holds does not, and a refused value leaves it (and the value) alone.
TEST(Settings, VersionMovesWithEveryChangeAndOnlyThen) {
  Settings s;
  const std::uint64_t v0 = s.version();
  s.set("dof.method", "lee-splat");
  EXPECT_EQ(s.version(), v0 + 1);
  s.set("dof.method", "lee-splat");
  EXPECT_EQ(s.version(), v0 + 1);
  EXPECT_THROW(s.set("dof.method", "nonsense"), std::invalid_argument);
  EXPECT_EQ(s.version(), v0 + 1);
  EXPECT_EQ(s.text("dof.method"), "lee-splat");
  s.set_assignment("dof.method=lee-mipmap");
  EXPECT_EQ(s.version(), v0 + 2);
}

TEST(Settings, RejectUnknownKeysAndBadValuesNamingWhatIsAllowed) {
  Settings s;
  EXPECT_FALSE(s.flag("gi.enabled"));
  s.set_assignment("gi.enabled=true");
  EXPECT_TRUE(s.flag("gi.enabled"));
  s.set("tonemap.exposure", "2.5");
  EXPECT_DOUBLE_EQ(s.number("tonemap.exposure"), 2.5);
  EXPECT_EQ(s.changed().size(), 2u);
  const auto message = [&](const std::string& a) {
    try {
      s.set_assignment(a);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message("gi.enable=true").find("known: output"), std::string::npos);
  EXPECT_NE(message("gi.enabled=yes").find("allowed bool"), std::string::npos);
  EXPECT_NE(message("tonemap.exposure=nan").find("number in"), std::string::npos);
  EXPECT_NE(message("tonemap.exposure=-1").find("number in"), std::string::npos);
  EXPECT_NE(message("dof.method=magic").find("reference|accum|lee-mipmap"), std::string::npos);
  EXPECT_NE(message("novalue").find("expected key=value"), std::string::npos);
  // "auto|number in [lo, hi]": the word or a number in range, nothing else.
  EXPECT_EQ(s.text("gi.nn_radius"), "auto");
  EXPECT_EQ(message("gi.nn_radius=1.5"), "accepted");
  EXPECT_EQ(message("gi.nn_radius=auto"), "accepted");
  EXPECT_NE(message("gi.nn_radius=0").find("allowed auto|number in [0.0001, 1000]"), std::string::npos);
  EXPECT_NE(message("gi.nn_radius=autox").find("allowed auto|number in"), std::string::npos);
  EXPECT_NE(message("gi.nn_radius=nan").find("allowed auto|number in"), std::string::npos);
  EXPECT_TRUE(s.flag("gi.enabled")) << "a refused assignment changes nothing";
}
