// SPDX-License-Identifier: Apache-2.0
// The frame pipeline's GPU-resident path against a fake backend with a fake GpuFrame (no OpenGL):
// which path each setting takes and why (--explain's "where" line), which G-buffer planes come back
// for the CPU passes that run, when the CPU's HDR colour is uploaded, the GPU pass order, and the
// fallback when the device lacks a feature. Table-driven, as Filament tests its frame graph.
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "backend/gpu_frame.h"
#include "gaze/gaze_input.h"
#include "pipeline/frame_pipeline.h"
#include "scene/geometry.h"

namespace fovea::render {
namespace {

// A G-buffer of a simple scene: object 1 at 2 m over the middle half of the image, background (the
// far plane) around it.
void fill(const Scene& scene, const BackendSettings& s, GBuffer& out) {
  const std::uint32_t w = s.width > 0 ? s.width : scene.camera.width;
  const std::uint32_t h = s.height > 0 ? s.height : scene.camera.height;
  out.resize(w, h);
  for (std::uint32_t y = 0; y < h; ++y) {
    for (std::uint32_t x = 0; x < w; ++x) {
      const bool box = x >= w / 4 && x < 3 * w / 4 && y >= h / 4 && y < 3 * h / 4;
      const std::size_t i = out.index(x, y);
      out.color[i] = box ? glm::vec3(0.5f) : glm::vec3(0.1f);
      out.depth[i] = box ? 2.0f : scene.camera.far_m;
      out.object_id[i] = box ? 1u : 0u;
      out.normal[i] = box ? glm::vec3(0, 0, 1) : glm::vec3(0.0f);
    }
  }
}

// Records what the pipeline asked of the GPU.
class FakeGpuFrame final : public GpuFrame {
 public:
  explicit FakeGpuFrame(std::string unavailable) : unavailable_(std::move(unavailable)) {}
  const std::string& unavailable_reason() const override { return unavailable_; }
  std::string description() const override { return "fake GPU"; }
  void prepare(const Prepare& p) override { prepared = p; }
  void render_gbuffer(const FrameTime&, const BackendSettings& s, const GBufferPlanes& planes, GBuffer& out) override {
    calls.push_back("gbuffer");
    written = planes;
    visibility_buffer = s.visibility_buffer;
    fill(*scene, s, rendered_);
    if (out.width != rendered_.width || out.height != rendered_.height) out.resize(rendered_.width, rendered_.height);
  }
  void read_back(const GBufferPlanes& planes, GBuffer& out) override {
    calls.push_back("read_back");
    read_back_planes = planes;
    if (planes.color) out.color = rendered_.color;
    if (planes.depth) out.depth = rendered_.depth;
    if (planes.object_id) out.object_id = rendered_.object_id;
  }
  void upload_inset(const std::vector<glm::vec3>& gi, std::uint32_t w, std::uint32_t h, glm::vec2, float radius,
                    float) override {
    calls.push_back("inset");
    EXPECT_EQ(gi.size(), std::size_t{w} * h);
    EXPECT_GT(radius, 0.0f);
  }
  void gi_gather(const GpuGiGather& g) override {
    calls.push_back("gi_gather");
    EXPECT_GT(g.radius_px, 0.0f);
  }
  std::string gi_gather_unavailable(std::size_t) const override { return "the fake has no GI gather"; }
  void read_gi(std::vector<glm::vec3>& gi) override { gi.clear(); }
  void read_gi_labels(std::vector<std::uint8_t>& used, std::vector<double>& t, std::vector<double>& g) override {
    used.clear();
    t.clear();
    g.clear();
  }
  void upload_hdr(const std::vector<glm::vec3>& hdr, std::uint32_t w, std::uint32_t h) override {
    calls.push_back("upload");
    EXPECT_EQ(hdr.size(), std::size_t{w} * h);
  }
  void dof_lee_mipmap(const dof::CocModel& coc, const dof::LeeMipmapSettings&) override {
    calls.push_back("dof");
    EXPECT_FALSE(coc.pinhole());
  }
  dof::SchedlStats dof_schedl_layered(const FrameTime&, const BackendSettings&, const dof::CocModel& coc,
                                      std::uint32_t layers) override {
    calls.push_back("dof layered " + std::to_string(layers));
    EXPECT_FALSE(coc.pinhole());
    return {};
  }
  // The box's pixels, as one object with the map's every pixel salient.
  void attention_pixels(const attention::AttentionSettings& s, double, double far_m, const std::vector<std::uint32_t>& ids,
                        const std::vector<float>& motion, std::vector<attention::ObjectPixels>& out) override {
    calls.push_back("attention");
    EXPECT_EQ(ids.size(), motion.size());
    const auto n = static_cast<std::size_t>(s.map_size);
    out = {attention::ObjectPixels{1, n * n / 4, 0.5 * static_cast<double>(n * n / 4), 0.125 * static_cast<double>(n * n),
                                   0.125 * static_cast<double>(n * n), far_m / 2}};
    map_size = s.map_size;
  }
  void ulod_blend(const FrameTime&, const BackendSettings&, const std::vector<std::uint32_t>& ids,
                  const std::vector<float>& blend) override {
    calls.push_back("ulod");
    EXPECT_EQ(ids.size(), blend.size());
  }
  void read_rect(std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1, std::vector<float>& depth,
                 std::vector<std::uint32_t>& ids) override {
    calls.push_back("rect");
    attention::GBufferPixels(rendered_).read(x0, y0, x1, y1, depth, ids);
  }
  void attention_pixels_on(const FrameTime&, const BackendSettings&, const attention::AttentionSettings& s,
                           double near_m, double far_m, const std::vector<std::uint32_t>& ids,
                           const std::vector<float>& motion, std::vector<attention::ObjectPixels>& out) override {
    attention_pixels(s, near_m, far_m, ids, motion, out);
    calls.back() = "attention on proxy";
  }
  void read_saliency(std::vector<float>& saliency) override {
    saliency.assign(static_cast<std::size_t>(map_size) * static_cast<std::size_t>(map_size), 0.5f);
  }
  void dof_lee_splat(const FrameTime&, const BackendSettings&, const dof::CocModel& coc,
                     const dof::LeeSplatSettings& s) override {
    calls.push_back(std::string("dof splat") + (s.use_hidden ? " with hidden" : ""));
    EXPECT_FALSE(coc.pinhole());
  }
  void read_hdr(std::vector<glm::vec3>& hdr) override { hdr = rendered_.color; }
  void tonemap(const GpuTonemap&) override { calls.push_back("tonemap"); }
  void overlay(const GpuOverlay& o) override {
    calls.push_back("overlay");
    last_overlay = o;
  }
  GpuCompletion finish() override {
    calls.push_back("finish");
    return {0.0, {{"gpu.gbuffer", 1.0}, {"gpu.tonemap", 0.5}}};
  }
  void read_display(std::vector<std::uint8_t>& rgb, std::uint32_t& w, std::uint32_t& h) override {
    w = rendered_.width;
    h = rendered_.height;
    rgb.assign(std::size_t{w} * h * 3, 7);
  }
  Texture display_texture() const override { return {}; }

  const Scene* scene = nullptr;
  std::vector<std::string> calls;
  GBufferPlanes read_back_planes, written;
  bool visibility_buffer = false;  // what the last G-buffer was asked to be drawn with
  GpuOverlay last_overlay;
  int map_size = 0;
  Prepare prepared;  // what the last frame asked to be built ahead of its first use

 private:
  std::string unavailable_;
  GBuffer rendered_;
};

class FakeBackend final : public Backend {
 public:
  explicit FakeBackend(bool with_gpu, std::string unavailable = "") {
    if (with_gpu) gpu_ = std::make_unique<FakeGpuFrame>(std::move(unavailable));
  }
  std::string name() const override { return "fake"; }
  BackendCapabilities capabilities() const override { return capabilities_; }
  BackendCapabilities capabilities_;
  void set_scene(const Scene& scene) override {
    scene_ = scene;
    if (gpu_) gpu_->scene = &scene_;
  }
  void set_camera(const Camera& camera) override { scene_.camera = camera; }
  void render(const FrameTime&, const BackendSettings& s, GBuffer& out) override {
    ++cpu_renders;
    fill(scene_, s, out);
  }
  GpuFrame* gpu_frame() override { return gpu_.get(); }

  std::unique_ptr<FakeGpuFrame> gpu_;
  int cpu_renders = 0;

 private:
  Scene scene_;
};

// A box in front of a 64x48 camera; a thin lens when asked (so dof, focus and attention run).
Scene scene(bool thin_lens) {
  Scene s;
  s.camera.width = 64;
  s.camera.height = 48;
  s.materials.push_back(Material{});
  Object o;
  o.id = 1;
  o.mesh = std::make_shared<Mesh>(make_box({1, 1, 1}));
  o.task_importance = 1;  // a foreground object: the focus pass may focus on it
  s.objects.push_back(o);
  s.lights.push_back(Light{});
  if (thin_lens) {
    s.camera.lens.aperture_m = 0.01;
    s.camera.lens.focal_length_m = 0.05;
    s.camera.lens.focus_distance_m = 2;
  }
  return s;
}

struct Run {
  std::unique_ptr<GazeInput> gaze = make_gaze_input("mouse");
  FakeBackend* backend = nullptr;
  std::unique_ptr<FramePipeline> pipeline;
  FramePipeline::Frame frame;
  PassTimer timer;
};

// `coarser_level`: the box gets a level of detail (the same mesh), so lod-select runs.
std::unique_ptr<Run> render_one(bool thin_lens, const std::vector<std::string>& settings, bool with_gpu = true,
                                const std::string& unavailable = "", bool coarser_level = false) {
  auto run = std::make_unique<Run>();
  Settings s;
  for (const std::string& a : settings) s.set_assignment(a);
  run->gaze->set_cursor(0.5, 0.5);
  auto backend = std::make_unique<FakeBackend>(with_gpu, unavailable);
  run->backend = backend.get();
  Scene sc = scene(thin_lens);
  if (coarser_level) sc.objects[0].lods.push_back(LodLevel{sc.objects[0].mesh, 0.01f});
  run->pipeline = std::make_unique<FramePipeline>(std::move(sc), s, std::move(backend), *run->gaze);
  run->frame = run->pipeline->render(0, 0, 0, 0, run->timer);
  return run;
}

struct PathRow {
  const char* name;
  bool thin_lens;
  std::vector<std::string> settings;
  bool on_gpu;
  GBufferPlanes read_back;  // on_gpu only
  bool upload;              // the CPU's HDR colour goes up for the tone map
  const char* where;        // in --explain's "where" line
  GBufferPlanes gpu_reads = {};  // what the GPU's overlay reads besides colour (the focus outline: depth, ids)
};

const std::vector<PathRow> kPaths = {
    {"pinhole: nothing runs on the CPU, nothing comes back; only colour is written", false, {}, true, {}, false,
     "written: colour; read back: nothing"},
    {"thin lens: attention and lee-mipmap on the GPU, focus reads what it looks at; nothing comes back whole", true,
     {}, true, {}, false, "written: colour, depth, id; read back: nothing (focus: only the pixels it looks at)",
     {.depth = true, .object_id = true}},
    {"attention.device=cpu: attention reads colour, depth and ids back", true, {"attention.device=cpu"}, true,
     {.color = true, .depth = true, .object_id = true}, false, "read back: colour, depth, id"},
    {"fixed focus: lee-mipmap on the GPU, nothing comes back", true, {"focus.mode=fixed"}, true, {}, false,
     "written: colour, depth; read back: nothing", {.depth = true}},
    {"dof.device=cpu: DOF reads colour and depth back, its colour goes up", true, {"focus.mode=fixed", "dof.device=cpu"},
     true, {.color = true, .depth = true}, true, "read back: colour, depth"},
    {"lee-splat on the GPU: nothing comes back", true, {"focus.mode=fixed", "dof.method=lee-splat"}, true, {}, false,
     "written: colour, depth; read back: nothing", {.depth = true}},
    {"lee-splat with dof.device=cpu reads colour and depth back, its colour goes up", true,
     {"focus.mode=fixed", "dof.method=lee-splat", "dof.hidden=false", "dof.device=cpu"}, true,
     {.color = true, .depth = true}, true, "read back: colour, depth"},
    {"gaze focus without attention: focus reads depth and ids (an object's median depth), the outline its ids on "
     "the GPU", true, {"focus.mode=gaze", "dof.enabled=false", "overlay.focus=true"}, true,
     {.depth = true, .object_id = true}, false, "written: colour, depth, id; read back: depth, id",
     {.depth = true, .object_id = true}},
    {"the reference DOF renders again: nothing of the G-buffer comes back for it", true,
     {"focus.mode=fixed", "dof.method=accum", "dof.samples=2"}, true, {}, true, "read back: nothing"},
    {"gi: the inset is composited on the GPU, nothing comes back for it", false,
     {"gi.enabled=true", "gi.photons=200", "gi.caustic_photons=0"}, true, {}, false, "read back: nothing"},
    {"gi with the CSF periphery: the hybrid image is made on the CPU and goes up", false,
     {"gi.enabled=true", "gi.photons=200", "gi.caustic_photons=0", "gi.periphery=csf"}, true, {}, true,
     "read back: nothing"},
    {"frame.gpu=false: the readback path", true, {"frame.gpu=false"}, false, {}, false, "frame.gpu=false"},
    {"a G-buffer map is drawn on the CPU", false, {"overlay.map=depth"}, false, {}, false,
     "overlay.map=depth is drawn on the CPU"},
    {"output=gbuffer reads everything", false, {"output=gbuffer"}, false, {}, false, "output=gbuffer"},
};

TEST(GpuFramePath, EachSettingTakesItsPathAndReadsBackWhatItsCpuPassesRead) {
  for (const PathRow& row : kPaths) {
    SCOPED_TRACE(row.name);
    const auto run = render_one(row.thin_lens, row.settings);
    const FakeGpuFrame& gpu = *run->backend->gpu_;
    EXPECT_EQ(run->frame.on_gpu, row.on_gpu);
    EXPECT_NE(run->frame.plan.explain().find(row.where), std::string::npos) << run->frame.plan.explain();
    if (!row.on_gpu) {
      EXPECT_TRUE(gpu.calls.empty());
      EXPECT_GE(run->backend->cpu_renders, 1);
      continue;
    }
    EXPECT_EQ(gpu.read_back_planes, row.read_back);
    // The G-buffer pass writes what is read (colour always for the tone map); the rest is culled.
    EXPECT_EQ(gpu.written, row.read_back | GBufferPlanes{.color = true} | row.gpu_reads);
    EXPECT_EQ(run->frame.written, gpu.written);
    const bool uploaded = std::find(gpu.calls.begin(), gpu.calls.end(), "upload") != gpu.calls.end();
    EXPECT_EQ(uploaded, row.upload);
    EXPECT_EQ(run->frame.image, nullptr);  // the display image stays on the GPU
  }
}

// frame.gbuffer_pass: which G-buffer pass the backend is asked for, by what it can do and what is
// faster on it, and what the "where" line says.
TEST(GpuFramePath, TheGBufferPassFollowsTheSettingAndWhatTheDeviceCanDo) {
  struct Row {
    const char* name;
    BackendCapabilities can;
    const char* setting;
    bool visibility;  // asked of the backend
    const char* where;
  };
  const BackendCapabilities none{}, software{.visibility_buffer = true},
      gpu{.visibility_buffer = true, .visibility_buffer_faster = true};
  const Row rows[] = {
      {"auto on a GPU: the visibility buffer", gpu, "auto", true, "visibility buffer + compute shading"},
      {"auto on a software rasteriser: forward", software, "auto", false, "auto on a software rasteriser"},
      {"asked for where it runs but is slower: visibility", software, "visibility", true, "visibility buffer"},
      // The backend draws forward then, and logs why once (GlBackend::ensure_visibility).
      {"asked for without compute shaders: asked, and the where line says why", none, "visibility", true,
       "no compute shaders"},
      {"auto without compute shaders: forward, and why", none, "auto", false, "no compute shaders"},
      {"forward asked for", gpu, "forward", false, "(forward raster shading)"},
  };
  for (const Row& row : rows) {
    SCOPED_TRACE(row.name);
    auto run = std::make_unique<struct Run>();
    Settings s;
    s.set("frame.gbuffer_pass", row.setting);
    auto backend = std::make_unique<FakeBackend>(true);
    backend->capabilities_ = row.can;
    run->backend = backend.get();
    run->pipeline = std::make_unique<FramePipeline>(scene(false), s, std::move(backend), *run->gaze);
    run->frame = run->pipeline->render(0, 0, 0, 0, run->timer);
    EXPECT_EQ(run->backend->gpu_->visibility_buffer, row.visibility);
    EXPECT_NE(run->frame.plan.explain().find(row.where), std::string::npos) << run->frame.plan.explain();
  }
}

TEST(GpuFramePath, GpuPassesRunInPipelineOrderAndEndWithTheFence) {
  const auto run = render_one(true, {});
  // Focus reads rectangles of depth and ids (the screen centre's, the gaze points') as it looks.
  const std::vector<std::string> want = {"gbuffer", "read_back", "attention", "rect", "rect", "rect",
                                         "dof",     "tonemap",   "overlay",   "finish"};
  EXPECT_EQ(run->backend->gpu_->calls, want);
  EXPECT_EQ(run->backend->cpu_renders, 0);  // no second render of the G-buffer on the CPU path
}

// Each frame names the GPU passes its plan may run before the G-buffer (GpuFrame::prepare): their
// programs compile then, not in the frame a pass starts (ULOD's blend, once an object is between levels).
TEST(GpuFramePath, TheFramePreparesThePassesItsPlanMayRun) {
  struct Row {
    std::vector<std::string> settings;
    GpuFrame::Prepare want;
  };
  const Row rows[] = {
      {{}, {.attention = true, .lee_mipmap = true}},
      {{"focus.mode=fixed", "dof.method=lee-splat"}, {.lee_splat = true}},
      {{"focus.mode=fixed", "dof.method=schedl-layered"}, {.schedl_layered = true}},
      {{"focus.mode=fixed", "dof.device=cpu"}, {}},
      {{"lod.policy=ulod", "focus.mode=fixed", "dof.enabled=false"}, {.attention = true, .ulod_blend = true}},
  };
  for (const Row& row : rows) {
    std::string name;
    for (const std::string& kv : row.settings) name += kv + " ";
    SCOPED_TRACE(name);
    const auto run = render_one(true, row.settings, true, "", true);
    const GpuFrame::Prepare& got = run->backend->gpu_->prepared;
    EXPECT_EQ(got.attention, row.want.attention);
    EXPECT_EQ(got.ulod_blend, row.want.ulod_blend);
    EXPECT_EQ(got.lee_mipmap, row.want.lee_mipmap);
    EXPECT_EQ(got.schedl_layered, row.want.schedl_layered);
    EXPECT_EQ(got.lee_splat, row.want.lee_splat);
  }
}

TEST(GpuFramePath, SchedlLayeredRunsOnTheGpuWithItsLayers) {
  const auto run = render_one(true, {"focus.mode=fixed", "dof.method=schedl-layered", "dof.layers=3"});
  const std::vector<std::string>& calls = run->backend->gpu_->calls;
  // The fake backend does not peel: one layer, as DofPass takes it on the CPU.
  const bool peels = run->backend->capabilities().peeling;
  EXPECT_NE(std::find(calls.begin(), calls.end(), peels ? "dof layered 3" : "dof layered 1"), calls.end());
  EXPECT_FALSE(run->backend->gpu_->read_back_planes.any());
  EXPECT_EQ(run->backend->cpu_renders, 0);
}

TEST(GpuFramePath, TimingsCarryTheGpuPassesAndTheGazeAgeAtCompletion) {
  const auto run = render_one(false, {});
  EXPECT_DOUBLE_EQ(run->timer.frame_ms("gpu.gbuffer"), 1.0);
  EXPECT_DOUBLE_EQ(run->timer.frame_ms("gpu.tonemap"), 0.5);
  EXPECT_TRUE(run->timer.summary().count("gaze-age"));
  // The fake GPU finishes at steady-clock 0, before the gaze was latched: the age is then negative,
  // which says the number is the fence's time minus the latch, plus the sample's own age.
  EXPECT_LT(run->frame.gaze_age_at_completion_ms, 0.0);
}

TEST(GpuFramePath, TheOverlayDrawsTheGazeRingsAndTheFocusOutlineOnTheGpu) {
  const auto run = render_one(true, {"overlay.focus=true", "focus.mode=fixed"});
  const GpuOverlay& o = run->backend->gpu_->last_overlay;
  EXPECT_TRUE(o.gaze);
  EXPECT_GE(o.ring_diameter_px, 3.0);
  EXPECT_EQ(o.area_diameter_px, 0.0);  // gi off: no gaze-area ring
  // focus.mode=fixed: the focus pass does not run, so there is no outline to draw.
  EXPECT_EQ(o.focus, GpuOverlay::Focus::None);
  const auto with_focus = render_one(true, {"overlay.focus=true", "focus.mode=gaze"});
  const GpuOverlay& f = with_focus->backend->gpu_->last_overlay;
  EXPECT_EQ(f.focus, GpuOverlay::Focus::Outline) << with_focus->frame.focus->why;  // the gazed box is on screen
  EXPECT_EQ(f.focus_object, 1u);
}

TEST(GpuFramePath, ADeviceWithoutTheFeaturesFallsBackToTheReadbackPathAndSaysWhy) {
  testing::internal::CaptureStderr();
  const auto run = render_one(true, {}, true, "no fences (GL_ARB_sync)");
  const std::string log = testing::internal::GetCapturedStderr();
  EXPECT_FALSE(run->frame.on_gpu);
  EXPECT_NE(run->frame.image, nullptr);
  EXPECT_TRUE(run->backend->gpu_->calls.empty());
  EXPECT_NE(log.find("GPU passes off (no fences (GL_ARB_sync))"), std::string::npos) << log;
  EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1);  // one line
  EXPECT_NE(run->frame.plan.explain().find("GPU passes unavailable: no fences"), std::string::npos);
}

TEST(GpuFramePath, ABackendWithoutAGpuFrameTakesTheReadbackPath) {
  const auto run = render_one(false, {}, false);
  EXPECT_FALSE(run->frame.on_gpu);
  EXPECT_NE(run->frame.plan.explain().find("the fake backend renders on the CPU"), std::string::npos);
}

TEST(GpuFramePath, ReadDisplayReturnsTheGpuImage) {
  auto run = render_one(false, {});
  const Image8& image = run->pipeline->read_display();
  EXPECT_EQ(image.width, 64u);
  EXPECT_EQ(image.height, 48u);
  EXPECT_EQ(image.rgb.size(), 64u * 48u * 3u);
  EXPECT_EQ(image.rgb[0], 7);
}

}  // namespace
}  // namespace fovea::render
