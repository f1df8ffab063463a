// SPDX-License-Identifier: Apache-2.0
// The GPU-resident frame on OpenGL (backend/gl/gl_frame.h) against the CPU passes it replaces, on
// the bundled scenes: the tone map (every operator; exact formula and table), the upload of a CPU
// pass's HDR colour, the overlay (gaze rings, focus outline, iso-depth line), the partial readback,
// and whole frames of the pipeline on both paths. Runs through EGL with DISPLAY unset.
//
// Tolerances. The tone map and the overlay's colours use the CPU's formulas, in float: 1/255 (one
// 8-bit level) everywhere, from pow() and the table differing at a rounding boundary. The rings
// test a pixel's distance to the gaze point against the ring's radii in float on the GPU and in
// double on the CPU, so a pixel centre within a float ulp of a radius may fall on either side: a
// few such pixels per ring are allowed (kRingEdgePixels), and no other difference.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "backend/backend.h"
#include "backend/gl/gl_backend.h"
#include "gaze/gaze_input.h"
#include "gi/gi_render.h"
#include "hdr_compare.h"
#include "passes/overlay.h"
#include "passes/tonemap.h"
#include "pipeline/frame_pipeline.h"
#include "scene/scene_loader.h"

namespace fovea::render {
namespace {

constexpr int kRingEdgePixels = 8;

Scene bundled(const char* name, std::uint32_t w = 200, std::uint32_t h = 150) {
  Scene s = load_scene(std::filesystem::path(FOVEA_SOURCE_DIR) / "renderer/scenes" / name);
  s.camera.width = w;
  s.camera.height = h;
  return s;
}

struct Difference {
  int max_level = 0;        // the largest difference of a channel, in 8-bit levels
  std::size_t pixels = 0;   // pixels differing by more than one level
};

Difference compare(const Image8& a, const Image8& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  Difference d;
  for (std::size_t p = 0; p < std::size_t{a.width} * a.height; ++p) {
    int worst = 0;
    for (std::size_t k = 0; k < 3; ++k) worst = std::max(worst, std::abs(int{a.rgb[3 * p + k]} - int{b.rgb[3 * p + k]}));
    d.max_level = std::max(d.max_level, worst);
    if (worst > 1) ++d.pixels;
  }
  return d;
}

Image8 gpu_image(GpuFrame& gpu) {
  Image8 out;
  gpu.read_display(out.rgb, out.width, out.height);
  return out;
}

GpuTonemap::Op gpu_op(const std::string& op) {
  return op == "reinhard" ? GpuTonemap::Op::Reinhard : op == "clamp" ? GpuTonemap::Op::Clamp : GpuTonemap::Op::Exponential;
}

class GlFrameTest : public ::testing::Test {
 protected:
  void SetUp() override {
    backend_ = std::make_unique<GlBackend>();
    gpu_ = backend_->gpu_frame();
    ASSERT_TRUE(gpu_->unavailable_reason().empty()) << gpu_->unavailable_reason();
  }
  // The scene's G-buffer on the CPU (every plane read back) and the same render left on the GPU.
  GBuffer render_both(const Scene& s) {
    backend_->set_scene(s);
    GBuffer cpu;
    backend_->render({}, {}, cpu);
    GBuffer on_gpu;
    gpu_->render_gbuffer({}, {}, GBufferPlanes::all(), on_gpu);
    EXPECT_EQ(on_gpu.width, cpu.width);
    return cpu;
  }
  std::unique_ptr<GlBackend> backend_;
  GpuFrame* gpu_ = nullptr;
};

TEST_F(GlFrameTest, ToneMapAgreesWithTheCpuPassOnTheBundledScenes) {
  for (const char* name : {"attention.json", "cornell.json", "occlusion.json"}) {
    const GBuffer g = render_both(bundled(name));
    for (const char* op : {"reinhard", "clamp", "exponential"}) {
      for (const float exposure : {1.0f, 4.0f}) {
        SCOPED_TRACE(std::string(name) + " " + op + " exposure " + std::to_string(exposure));
        gpu_->tonemap({gpu_op(op), exposure});
        gpu_->finish();
        const Image8 gpu = gpu_image(*gpu_);
        for (const bool exact : {true, false}) {
          Image8 cpu;
          tonemap(g.color, g.width, g.height, TonemapParams{exposure, op, exact}, cpu);
          const Difference d = compare(gpu, cpu);
          EXPECT_LE(d.max_level, 1) << (exact ? "pow()" : "table");
        }
      }
    }
  }
}

// The compute tone map (GL 4.3, taken on GPUs) writes the same bytes as the fragment pass: the
// G-buffer's colour, an uploaded HDR image (rows top first, NaN, Inf, negatives), and a GI inset.
TEST_F(GlFrameTest, TheComputeToneMapWritesTheFragmentPassesBytes) {
  if (!backend_->context().features().at_least(4, 3)) GTEST_SKIP() << "no compute shaders in this context";
  const auto both = [&](const GpuTonemap& base) {
    Image8 out[2];
    for (const GpuTonemap::Pass pass : {GpuTonemap::Pass::Fragment, GpuTonemap::Pass::Compute}) {
      GpuTonemap t = base;
      t.pass = pass;
      gpu_->tonemap(t);
      gpu_->finish();
      out[pass == GpuTonemap::Pass::Compute ? 1 : 0] = gpu_image(*gpu_);
    }
    EXPECT_EQ(out[0].rgb, out[1].rgb);
  };
  for (const char* name : {"attention.json", "cornell.json"}) {
    SCOPED_TRACE(name);
    const GBuffer g = render_both(bundled(name, 97, 61));  // odd sizes: partial 8x8 groups
    for (const char* op : {"reinhard", "clamp", "exponential"}) both({gpu_op(op), 2.0f, GpuTonemap::Pass::Auto});
    std::vector<glm::vec3> hdr(g.size());
    for (std::size_t i = 0; i < hdr.size(); ++i) hdr[i] = glm::vec3(0.01f * static_cast<float>(i % 300), 0.5f, 3.0f);
    hdr[3] = {std::numeric_limits<float>::quiet_NaN(), -1.0f, std::numeric_limits<float>::infinity()};
    gpu_->upload_hdr(hdr, g.width, g.height);
    both({GpuTonemap::Op::Reinhard, 1.0f, GpuTonemap::Pass::Auto});
    gpu_->upload_inset(std::vector<glm::vec3>(g.size(), glm::vec3(2.0f, 0.1f, 0.4f)), g.width, g.height, {40, 30}, 20,
                       0.5f);
    both({GpuTonemap::Op::Reinhard, 1.0f, GpuTonemap::Pass::Auto});
  }
}

TEST_F(GlFrameTest, AnUploadedHdrImageIsToneMappedWithItsTopRowFirst) {
  const Scene s = bundled("cornell.json", 64, 48);
  render_both(s);
  // Rows that differ from each other, and the values the CPU pass maps to 0: NaN, Inf, negative.
  std::vector<glm::vec3> hdr(64 * 48);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x)
      hdr[static_cast<std::size_t>(y * 64 + x)] =
          glm::vec3(0.02f * static_cast<float>(y), 0.1f * static_cast<float>(x), x == y ? 3.0f : 0.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  hdr[5] = {nan, -1.0f, inf};
  gpu_->upload_hdr(hdr, 64, 48);
  gpu_->tonemap({GpuTonemap::Op::Reinhard, 1.0f});
  gpu_->finish();
  Image8 cpu;
  tonemap(hdr, 64, 48, TonemapParams{1.0f, "reinhard", true}, cpu);
  const Image8 gpu = gpu_image(*gpu_);
  EXPECT_LE(compare(gpu, cpu).max_level, 1);
  EXPECT_EQ(gpu.rgb[15], 0);  // NaN -> 0
  EXPECT_EQ(gpu.rgb[16], 0);  // negative -> 0
}

TEST_F(GlFrameTest, TheGiInsetIsCompositedAsTheCpuCompositesIt) {
  const Scene s = bundled("cornell.json", 120, 90);
  const GBuffer g = render_both(s);
  std::vector<glm::vec3> gi(g.size(), glm::vec3(0.0f));
  for (std::size_t i = 0; i < gi.size(); ++i) gi[i] = glm::vec3(2.0f, 0.3f * static_cast<float>(i % 7), 0.5f);
  struct Case {
    glm::vec2 centre;
    float radius, fovea;
  };
  // Inside; cut by the image's corner; a fovea of 0 (a ramp from the centre) and of 1 (no ramp).
  for (const Case& c : {Case{{60, 45}, 30, 0.7f}, Case{{3, 88}, 25, 0.5f}, Case{{80, 20}, 15, 0.0f},
                        Case{{40, 50}, 12, 1.0f}}) {
    SCOPED_TRACE(std::to_string(c.centre.x) + "," + std::to_string(c.centre.y));
    gpu_->upload_inset(gi, g.width, g.height, c.centre, c.radius, c.fovea);
    gpu_->tonemap({GpuTonemap::Op::Reinhard, 1.0f});
    gpu_->finish();
    std::vector<glm::vec3> hybrid;
    gi::hybrid_composite(g.color, gi, g.width, g.height, gi::GazeArea{c.centre, c.radius}, c.fovea, hybrid);
    Image8 cpu, local;
    tonemap(hybrid, g.width, g.height, TonemapParams{1.0f, "reinhard", true}, cpu);
    tonemap(g.color, g.width, g.height, TonemapParams{1.0f, "reinhard", true}, local);
    const Image8 gpu = gpu_image(*gpu_);
    EXPECT_LE(compare(gpu, cpu).max_level, 1);
    EXPECT_GT(compare(cpu, local).pixels, 50u);  // the inset shows
  }
  // The next frame has no inset unless it uploads one.
  render_both(s);
  gpu_->tonemap({GpuTonemap::Op::Reinhard, 1.0f});
  gpu_->finish();
  Image8 local;
  tonemap(g.color, g.width, g.height, TonemapParams{1.0f, "reinhard", true}, local);
  EXPECT_LE(compare(gpu_image(*gpu_), local).max_level, 1);
}

TEST_F(GlFrameTest, TheOverlayAgreesWithTheCpuDrawing) {
  const Scene s = bundled("cornell.json");
  const GBuffer g = render_both(s);
  std::uint32_t some_object = 0;
  for (const std::uint32_t id : g.object_id) some_object = std::max(some_object, id);
  ASSERT_NE(some_object, 0u);
  struct Case {
    const char* name;
    GazeMark gaze;
    double area_deg;
    GpuOverlay::Focus focus;
    bool in_transition;
  };
  const Case cases[] = {
      {"valid gaze, gaze-area ring, focus outline", {0.3, 0.6, true}, 10.0, GpuOverlay::Focus::Outline, false},
      {"invalid gaze at the corner, outline in transition", {0.99, 0.02, false}, 0.0, GpuOverlay::Focus::Outline, true},
      {"gaze off the image, iso-depth line", {1.2, -0.1, true}, 5.0, GpuOverlay::Focus::IsoDepth, false},
      {"rings only", {0.5, 0.5, true}, 20.0, GpuOverlay::Focus::None, false},
  };
  const double focal_depth = [&] {
    double lo = 1e9, hi = 0;
    for (std::size_t i = 0; i < g.size(); ++i)
      if (g.object_id[i] != 0) lo = std::min<double>(lo, g.depth[i]), hi = std::max<double>(hi, g.depth[i]);
    return 0.5 * (lo + hi);
  }();
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    GpuOverlay o;
    o.gaze = true;
    o.gaze_x = c.gaze.x;
    o.gaze_y = c.gaze.y;
    o.gaze_valid = c.gaze.valid;
    o.ring_diameter_px = std::max(3.0, degrees_to_pixels(s.display, g.width, 1.0));
    o.area_diameter_px = c.area_deg > 0 ? degrees_to_pixels(s.display, g.width, c.area_deg) : 0.0;
    o.focus = c.focus;
    o.focus_object = c.focus == GpuOverlay::Focus::Outline ? some_object : 0;
    o.focal_depth_m = focal_depth;
    o.focus_in_transition = c.in_transition;
    gpu_->tonemap({GpuTonemap::Op::Reinhard, 1.0f});
    gpu_->overlay(o);
    gpu_->finish();

    Image8 cpu;
    tonemap(g.color, g.width, g.height, TonemapParams{1.0f, "reinhard", true}, cpu);
    const Image8 without_overlay = cpu;
    if (c.focus != GpuOverlay::Focus::None)
      draw_focus(cpu, g, o.focus_object, focal_depth, c.in_transition, "");
    draw_gaze(cpu, s.display, c.gaze, c.area_deg);
    const Image8 gpu = gpu_image(*gpu_);
    const Difference d = compare(gpu, cpu);
    EXPECT_LE(d.pixels, static_cast<std::size_t>(kRingEdgePixels * (c.area_deg > 0 ? 2 : 1)));
    // The case draws something (else agreement would say nothing), and so does the GPU.
    const std::size_t drawn = compare(cpu, without_overlay).pixels;
    EXPECT_GT(drawn, 20u);
    EXPECT_GT(compare(gpu, without_overlay).pixels, drawn - d.pixels - 1);
  }
}

TEST_F(GlFrameTest, ANonFiniteGazePointDrawsNoRing) {
  const GBuffer g = render_both(bundled("cornell.json", 64, 48));
  gpu_->tonemap({GpuTonemap::Op::Reinhard, 1.0f});
  gpu_->finish();
  const Image8 plain = gpu_image(*gpu_);
  for (const double bad : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(), 1e300}) {
    GpuOverlay o;
    o.gaze = true;
    o.gaze_x = bad;
    o.gaze_y = 0.5;
    o.ring_diameter_px = 10;
    o.area_diameter_px = 20;
    gpu_->tonemap({GpuTonemap::Op::Reinhard, 1.0f});
    gpu_->overlay(o);
    gpu_->finish();
    EXPECT_EQ(compare(gpu_image(*gpu_), plain).max_level, 0) << bad;
  }
}

TEST_F(GlFrameTest, ReadBackBringsOnlyThePlanesAskedFor) {
  const Scene s = bundled("occlusion.json", 96, 72);
  const GBuffer full = render_both(s);
  GBuffer partial;
  gpu_->render_gbuffer({}, {}, GBufferPlanes::all(), partial);
  ASSERT_EQ(partial.size(), full.size());
  std::fill(partial.color.begin(), partial.color.end(), glm::vec3(-7.0f));  // must stay as it is
  gpu_->read_back({.depth = true, .object_id = true}, partial);
  EXPECT_EQ(partial.depth, full.depth);
  EXPECT_EQ(partial.object_id, full.object_id);
  EXPECT_EQ(partial.color[0], glm::vec3(-7.0f));
}

TEST_F(GlFrameTest, PlanesNobodyReadsAreNeitherClearedNorWritten) {
  const GBuffer full = render_both(bundled("occlusion.json", 96, 72));
  // An empty scene, colour only: the colour becomes the background, the depth keeps the last frame's.
  Scene empty = bundled("occlusion.json", 96, 72);
  empty.objects.clear();
  backend_->set_scene(empty);
  GBuffer g;
  gpu_->render_gbuffer({}, {}, GBufferPlanes{.color = true}, g);
  gpu_->read_back(GBufferPlanes::all(), g);
  EXPECT_EQ(g.depth, full.depth);
  EXPECT_EQ(g.object_id, full.object_id);
  for (const glm::vec3& c : g.color) ASSERT_EQ(c, empty.background);
}

TEST_F(GlFrameTest, FinishWaitsForTheGpuAndTimesEachPass) {
  render_both(bundled("attention.json", 128, 96));
  gpu_->tonemap({});
  GpuOverlay o;
  o.gaze = true;
  o.ring_diameter_px = 10;
  gpu_->overlay(o);
  const double before =
      std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  const GpuCompletion done = gpu_->finish();
  EXPECT_GE(done.wall_s, before);
  std::vector<std::string> names;
  for (const auto& [pass, ms] : done.pass_ms) {
    names.push_back(pass);
    EXPECT_TRUE(std::isfinite(ms) && ms >= 0 && ms < 60'000) << pass << " " << ms;
  }
  // render_both's G-buffer, then the tone map and the overlay of this frame.
  EXPECT_EQ(names, (std::vector<std::string>{"gpu.gbuffer", "gpu.tonemap", "gpu.overlay"}));
  EXPECT_TRUE(gpu_->finish().pass_ms.empty());  // each pass is reported once
}

// Whole frames: the pipeline on the GPU-resident path (its G-buffer by either pass) and on the
// readback path with the forward G-buffer (the reference), same settings: within one 8-bit level
// but for the gaze ring's edge.
TEST(GlFramePipeline, BothPathsMakeTheSameFramesOnTheBundledScenes) {
  struct Row {
    const char* scene;
    std::vector<std::string> settings;
  };
  const Row rows[] = {
      {"attention.json", {"overlay.focus=true"}},  // attention, focus, LOD; lee-mipmap on the GPU
      {"cornell.json", {"gi.enabled=true", "gi.photons=4000", "gi.caustic_photons=0"}},  // the GI inset uploaded
      {"occlusion.json", {"tonemap.operator=exponential", "tonemap.exposure=2"}},
  };
  for (const Row& row : rows)
  for (const char* gbuffer_pass : {"forward", "visibility"}) {
    SCOPED_TRACE(std::string(row.scene) + ", GPU path with frame.gbuffer_pass=" + gbuffer_pass);
    Image8 images[2];
    for (const bool gpu : {true, false}) {
      Settings s;
      for (const std::string& a : row.settings) s.set_assignment(a);
      s.set("frame.gpu", gpu ? "true" : "false");
      s.set("frame.gbuffer_pass", gpu ? gbuffer_pass : "forward");
      s.set("tonemap.exact", "true");
      std::unique_ptr<GazeInput> gaze = make_gaze_input("mouse");
      gaze->set_cursor(0.4, 0.55);
      FramePipeline pipeline(bundled(row.scene, 160, 120), s, std::make_unique<GlBackend>(), *gaze);
      PassTimer timer;
      for (std::uint64_t i = 0; i < 2; ++i) {
        const double t = 0.1 * static_cast<double>(i);
        const FramePipeline::Frame f = pipeline.render(i, t, i == 0 ? 0.0 : t - 0.1, t, timer);
        ASSERT_EQ(f.on_gpu, gpu) << f.plan.explain();
        images[gpu ? 0 : 1] = gpu ? pipeline.read_display() : *f.image;
      }
      EXPECT_TRUE(timer.summary().count("gaze-age"));
      EXPECT_EQ(timer.summary().count("gpu.gbuffer"), gpu ? 1u : 0u);
    }
    const Difference d = compare(images[0], images[1]);
    EXPECT_LE(d.pixels, static_cast<std::size_t>(2 * kRingEdgePixels)) << "max " << d.max_level;
  }
}

// A stereo frame where the frame lies: each eye's display image is the readback path's image of that
// eye (the right eye reusing attention, levels and focus on both paths), and the eyes differ.
TEST(GlFramePipeline, BothPathsMakeTheSameStereoFrames) {
  Image8 images[2][2];  // [gpu][eye]
  for (const bool gpu : {true, false}) {
    SCOPED_TRACE(gpu ? "GPU path" : "readback path");
    Settings s;
    s.set("frame.gpu", gpu ? "true" : "false");
    s.set("tonemap.exact", "true");
    s.set("overlay.gaze", "false");
    std::unique_ptr<GazeInput> gaze = make_gaze_input("mouse");
    gaze->set_cursor(0.4, 0.55);
    Scene scene = bundled("attention.json", 160, 120);
    scene.camera.stereo = true;
    FramePipeline pipeline(std::move(scene), s, std::make_unique<GlBackend>(), *gaze);
    PassTimer timer;
    for (std::uint64_t i = 0; i < 2; ++i) {
      const double t = 0.1 * static_cast<double>(i);
      for (const FramePipeline::Eye eye : {FramePipeline::Eye::Left, FramePipeline::Eye::Right}) {
        const FramePipeline::Frame f = pipeline.render(i, t, i == 0 ? 0.0 : t - 0.1, t, timer, false, eye);
        ASSERT_EQ(f.on_gpu, gpu) << f.plan.explain();
        images[gpu ? 0 : 1][eye == FramePipeline::Eye::Left ? 0 : 1] = gpu ? pipeline.read_display() : *f.image;
      }
    }
    EXPECT_EQ(timer.summary().count("right.attention"), 0u);
    EXPECT_EQ(timer.summary().count("right.gbuffer"), 1u);
  }
  for (int eye = 0; eye < 2; ++eye) {
    const Difference d = compare(images[0][eye], images[1][eye]);
    EXPECT_LE(d.pixels, 4u) << (eye == 0 ? "left" : "right") << " eye: max " << d.max_level;
  }
  EXPECT_GT(compare(images[0][0], images[0][1]).pixels, 100u) << "the eyes see the same image";
}

// frame.effect_passes: the compute passes (tone map, attention, lee-mipmap or schedl-layered, ULOD's blend) make the frames the
// fragment passes make (the same GLSL per texel), and --explain's where line says which ran.
TEST(GlFramePipeline, TheComputeEffectPassesMakeTheFragmentPassesFrames) {
  for (const char* method : {"lee-mipmap", "schedl-layered"}) {
    Image8 images[2];
    for (const char* passes : {"compute", "fragment"}) {
      SCOPED_TRACE(std::string(method) + ", " + passes);
      Settings s;
      s.set("frame.effect_passes", passes);
      s.set("dof.method", method);
      s.set("lod.policy", "ulod");
      s.set("attention.device", "gpu");  // attention's pixel stage (on ULOD's proxy) on the GPU too
      s.set("tonemap.exact", "true");
      std::unique_ptr<GazeInput> gaze = make_gaze_input("mouse");
      gaze->set_cursor(0.4, 0.55);
      FramePipeline pipeline(bundled("attention.json", 160, 120), s, std::make_unique<GlBackend>(), *gaze);
      PassTimer timer;
      for (std::uint64_t i = 0; i < 3; ++i) {
        const double t = 0.1 * static_cast<double>(i);
        const FramePipeline::Frame f = pipeline.render(i, t, i == 0 ? 0.0 : t - 0.1, t, timer);
        ASSERT_TRUE(f.on_gpu) << f.plan.explain();
        EXPECT_NE(f.plan.placement.find("effect passes: " + std::string(passes)), std::string::npos) << f.plan.placement;
      }
      EXPECT_EQ(timer.summary().count("gpu.dof"), 1u);
      EXPECT_EQ(timer.summary().count("gpu.attention"), 1u);
      images[std::string(passes) == "compute" ? 0 : 1] = pipeline.read_display();
    }
    const Difference d = compare(images[0], images[1]);
    EXPECT_LE(d.max_level, 1) << method << ": " << d.pixels << " pixels differ";
  }
}

// ULOD's next levels drawn aside by the G-buffer pass the frame takes: with the visibility buffer
// (the compute resolve, on GPUs) the blended frames are the forward pass's.
TEST(GlFramePipeline, UlodsAsideDrawTakesTheFramesGBufferPass) {
  Image8 images[2];
  for (const char* gbuffer_pass : {"visibility", "forward"}) {
    SCOPED_TRACE(gbuffer_pass);
    Settings s;
    s.set("frame.gbuffer_pass", gbuffer_pass);
    s.set("lod.policy", "ulod");
    s.set("dof.enabled", "false");
    s.set("tonemap.exact", "true");
    std::unique_ptr<GazeInput> gaze = make_gaze_input("none");
    FramePipeline pipeline(bundled("attention.json", 160, 120), s, std::make_unique<GlBackend>(), *gaze);
    PassTimer timer;
    for (std::uint64_t i = 0; i < 3; ++i) {
      const double t = 0.1 * static_cast<double>(i);
      const FramePipeline::Frame f = pipeline.render(i, t, i == 0 ? 0.0 : t - 0.1, t, timer);
      ASSERT_TRUE(f.on_gpu) << f.plan.explain();
    }
    EXPECT_EQ(timer.summary().count("gpu.ulod"), 1u) << "no object between levels: nothing blended";
    images[std::string(gbuffer_pass) == "visibility" ? 0 : 1] = pipeline.read_display();
  }
  const Difference d = compare(images[0], images[1]);
  EXPECT_LE(d.pixels, 40u) << "max " << d.max_level;  // where two surfaces touch, either may win
}

// attention.device=gpu (backend/gl/gl_attention.h) against attention.device=cpu in the frame: the
// same objects, pixel counts and depths, the same attention within float sums, over frames of an
// animation (the Kalman filter and the temporal context see the same values), with the finite checks
// on; colour stays on the GPU when attention runs there.
TEST(GlFramePipeline, TheGpuAttentionIsTheCpuAttentionInTheFrame) {
  std::vector<attention::ObjectAttention> objects[2];
  for (const char* device : {"gpu", "cpu"}) {
    Settings s;
    s.set("attention.device", device);
    s.set("focus.mode", "attention");
    s.set("lod.enabled", "false");  // the pass alone
    s.set("debug.finite_checks", "true");
    std::unique_ptr<GazeInput> gaze = make_gaze_input("none");
    FramePipeline pipeline(bundled("attention.json", 192, 144), s, std::make_unique<GlBackend>(), *gaze);
    PassTimer timer;
    FramePipeline::Frame f;
    for (int k = 0; k < 4; ++k) f = pipeline.render(static_cast<std::uint64_t>(k), 0.1 * k, 0.1 * (k - 1), 0.1 * k, timer);
    ASSERT_TRUE(f.on_gpu) << f.plan.explain();
    ASSERT_NE(f.attention, nullptr);
    const bool gpu = std::string(device) == "gpu";
    EXPECT_EQ(f.plan.at(PassId::Attention).on_gpu, gpu) << f.plan.explain();
    EXPECT_EQ(timer.summary().count("gpu.attention"), gpu ? 1u : 0u);
    EXPECT_EQ(f.read_back.color, !gpu) << "only a CPU attention reads the colour back";
    objects[gpu ? 0 : 1] = f.attention->objects;
  }
  ASSERT_FALSE(objects[1].empty());
  ASSERT_EQ(objects[0].size(), objects[1].size());
  for (std::size_t i = 0; i < objects[0].size(); ++i) {
    const attention::ObjectAttention &g = objects[0][i], &c = objects[1][i];
    EXPECT_EQ(g.id, c.id) << "rank " << i;
    EXPECT_EQ(g.pixels, c.pixels) << "object " << c.id;
    EXPECT_EQ(g.depth_m, c.depth_m) << "object " << c.id;
    EXPECT_NEAR(g.attention, c.attention, 1e-4 * std::max(1e-3, c.attention)) << "object " << c.id;
  }
}

// With attention on the GPU the focus pass reads only the pixels it looks at (FocusPixels: rectangles
// around the gaze point and the screen centre) and, with lee-mipmap on the GPU and LOD by screen size,
// nothing of the G-buffer is read back whole; it focuses where the readback path's focus pass does,
// frame by frame, in each mode that uses attention.
TEST(GlFramePipeline, TheFocusPassReadsOnlyThePixelsItLooksAt) {
  for (const char* mode : {"gaze+attention", "attention"}) {
    SCOPED_TRACE(mode);
    std::vector<attention::FocusResult> focus[2];
    for (const bool gpu : {true, false}) {
      Settings s;
      s.set("frame.gpu", gpu ? "true" : "false");
      s.set("attention.device", gpu ? "gpu" : "cpu");
      s.set("focus.mode", mode);  // the scene's LOD (screen size) and lee-mipmap too: the whole frame
      std::unique_ptr<GazeInput> gaze = make_gaze_input("mouse");
      FramePipeline pipeline(bundled("attention.json", 192, 144), s, std::make_unique<GlBackend>(), *gaze);
      PassTimer timer;
      for (std::uint64_t i = 0; i < 12; ++i) {
        gaze->set_cursor(i < 6 ? 0.3 : 0.62, 0.55);  // a fixation, a saccade, another fixation
        const double t = 0.05 * static_cast<double>(i);
        const FramePipeline::Frame f = pipeline.render(i, t, i == 0 ? 0.0 : t - 0.05, t, timer);
        ASSERT_EQ(f.on_gpu, gpu) << f.plan.explain();
        ASSERT_NE(f.focus, nullptr);
        focus[gpu ? 0 : 1].push_back(*f.focus);
        if (gpu) {
          EXPECT_FALSE(f.read_back.any()) << f.plan.explain();
          EXPECT_LT(f.focus_pixels_read, f.gbuffer->size() / 100) << "frame " << i;
        }
      }
    }
    ASSERT_EQ(focus[0].size(), focus[1].size());
    for (std::size_t i = 0; i < focus[0].size(); ++i) {
      const attention::FocusResult &g = focus[0][i], &c = focus[1][i];
      EXPECT_EQ(g.object, c.object) << "frame " << i << ": " << g.why << " / " << c.why;
      EXPECT_EQ(g.object_visible, c.object_visible) << "frame " << i;
      EXPECT_NEAR(g.focal_depth_m, c.focal_depth_m, 1e-9 * c.focal_depth_m) << "frame " << i;
      EXPECT_EQ(g.in_transition, c.in_transition) << "frame " << i;
    }
    std::printf("%s: focus %s, then %s\n", mode, focus[0][5].why.c_str(), focus[0].back().why.c_str());
  }
}

// lod.policy=ulod in a GPU-resident frame: the next levels are drawn aside and blended where the
// frame lies (gpu.ulod); nothing is read back or uploaded for the blend, and the blended colour is
// the readback path's (lod::ulod_blend on the CPU) over frames of the scene's animation.
TEST(GlFramePipeline, TheUlodBlendRunsOnTheGpuAsOnTheCpu) {
  std::vector<glm::vec3> hdr[2];
  for (const bool gpu : {true, false}) {
    Settings s;
    s.set("frame.gpu", gpu ? "true" : "false");
    s.set("lod.policy", "ulod");
    s.set("dof.enabled", "false");  // the blend alone reaches the tone map
    std::unique_ptr<GazeInput> gaze = make_gaze_input("none");
    FramePipeline pipeline(bundled("attention.json", 192, 144), s, std::make_unique<GlBackend>(), *gaze);
    PassTimer timer;
    FramePipeline::Frame f;
    std::size_t blending = 0;
    for (std::uint64_t i = 0; i < 3; ++i) {
      const double t = 0.5 * static_cast<double>(i);
      f = pipeline.render(i, t, i == 0 ? 0.0 : t - 0.5, t, timer);
      ASSERT_EQ(f.on_gpu, gpu) << f.plan.explain();
      ASSERT_NE(f.lod, nullptr) << f.plan.explain();
      blending = 0;
      for (const lod::Selection& sel : f.lod->selection) blending += sel.blend > 0 && sel.blend_to != sel.drawn;
    }
    EXPECT_GT(blending, 0u) << "no object between two levels: the test would not blend";
    if (gpu) {
      EXPECT_EQ(timer.summary().count("gpu.ulod"), 1u);
      EXPECT_FALSE(f.read_back.color) << f.plan.explain();
      EXPECT_TRUE(f.written.object_id) << "the blend reads the ids where they lie";
      pipeline.gpu_frame()->read_hdr(hdr[0]);
    } else {
      hdr[1] = f.gbuffer->color;
    }
  }
  ASSERT_EQ(hdr[0].size(), hdr[1].size());
  double worst = 0;
  for (std::size_t i = 0; i < hdr[0].size(); ++i)
    for (int c = 0; c < 3; ++c) worst = std::max(worst, static_cast<double>(std::fabs(hdr[0][i][c] - hdr[1][i][c])));
  std::printf("ulod blend GPU vs CPU: largest difference %.2e\n", worst);
  EXPECT_LE(worst, 1e-5);
}

// With ULOD the attention pass runs first on a proxy (every object at its coarsest level); with
// attention.device=gpu the proxy is rendered and its pixel stage runs on the GPU, and the objects'
// attention and the levels chosen from it are the CPU's.
TEST(GlFramePipeline, TheUlodProxyAttentionRunsOnTheGpuAsOnTheCpu) {
  std::vector<attention::ObjectAttention> objects[2];
  std::vector<lod::Selection> selection[2];
  for (const char* device : {"gpu", "cpu"}) {
    Settings s;
    s.set("lod.policy", "ulod");
    s.set("attention.device", device);
    std::unique_ptr<GazeInput> gaze = make_gaze_input("none");
    FramePipeline pipeline(bundled("attention.json", 192, 144), s, std::make_unique<GlBackend>(), *gaze);
    PassTimer timer;
    FramePipeline::Frame f;
    for (std::uint64_t i = 0; i < 3; ++i) f = pipeline.render(i, 0.4 * static_cast<double>(i), 0.4 * (static_cast<double>(i) - 1), 0.4 * static_cast<double>(i), timer);
    const bool gpu = std::string(device) == "gpu";
    ASSERT_TRUE(f.on_gpu) << f.plan.explain();
    ASSERT_NE(f.attention, nullptr);
    ASSERT_NE(f.lod, nullptr);
    EXPECT_EQ(f.plan.at(PassId::Attention).on_gpu, gpu) << f.plan.explain();
    EXPECT_EQ(timer.summary().count("gpu.attention"), gpu ? 1u : 0u);
    EXPECT_EQ(timer.summary().count("attention.proxy"), gpu ? 0u : 1u);  // the CPU's proxy render and readback
    objects[gpu ? 0 : 1] = f.attention->objects;
    selection[gpu ? 0 : 1] = f.lod->selection;
  }
  ASSERT_FALSE(objects[1].empty());
  ASSERT_EQ(objects[0].size(), objects[1].size());
  for (std::size_t i = 0; i < objects[0].size(); ++i) {
    EXPECT_EQ(objects[0][i].id, objects[1][i].id);
    EXPECT_EQ(objects[0][i].pixels, objects[1][i].pixels);
    EXPECT_NEAR(objects[0][i].attention, objects[1][i].attention, 1e-4 * std::max(1e-3, objects[1][i].attention));
  }
  ASSERT_EQ(selection[0].size(), selection[1].size());
  for (std::size_t i = 0; i < selection[0].size(); ++i) {
    EXPECT_EQ(selection[0][i].id, selection[1][i].id);
    EXPECT_EQ(selection[0][i].drawn, selection[1][i].drawn);
    EXPECT_NEAR(selection[0][i].blend, selection[1][i].blend, 1e-3);
  }
}

// The accumulation reference renders the scene again mid-frame, once per lens sample: aside
// (BackendSettings::keep_frame), so the G-buffer the GPU-resident frame keeps (what the overlay's
// focus outline reads) is still the frame's, the readback path's planes exactly.
TEST(GlFramePipeline, TheDofReferencesLeaveTheFramesGBufferWhereItLies) {
  GBuffer planes[2];
  for (const bool gpu : {true, false}) {
    Settings s;
    s.set("frame.gpu", gpu ? "true" : "false");
    s.set("dof.method", "accum");
    s.set("dof.samples", "4");
    s.set("focus.mode", "fixed");
    s.set("debug.gbuffer_planes", "all");  // every plane written where the frame lies, to compare
    std::unique_ptr<GazeInput> gaze = make_gaze_input("none");
    FramePipeline pipeline(bundled("attention.json", 160, 120), s, std::make_unique<GlBackend>(), *gaze);
    PassTimer timer;
    const FramePipeline::Frame f = pipeline.render(0, 0.3, 0.25, 0.3, timer);
    ASSERT_EQ(f.on_gpu, gpu) << f.plan.explain();
    ASSERT_TRUE(f.plan.runs(PassId::Dof));
    if (gpu) {
      planes[0].resize(f.gbuffer->width, f.gbuffer->height);
      pipeline.gpu_frame()->read_back({.depth = true, .object_id = true}, planes[0]);
    } else {
      planes[1] = *f.gbuffer;
    }
  }
  ASSERT_EQ(planes[0].size(), planes[1].size());
  EXPECT_EQ(planes[0].object_id, planes[1].object_id);
  EXPECT_EQ(planes[0].depth, planes[1].depth);
}

// lee-mipmap, schedl-layered (M = 3, its layers peeled on the GPU) and lee-splat (its hidden image
// peeled there) in a GPU-resident frame run on the GPU (gpu.dof timed, nothing read back for them)
// and their colour is the CPU pass's within the GPU's tolerance (tests/gl/test_gl_lee_mipmap.cpp,
// test_gl_schedl_layered.cpp, test_gl_lee_splat.cpp): the HDR colour the tone map reads, with
// dof.device=gpu against dof.device=cpu in the same frame.
TEST(GlFramePipeline, TheGpuDofIsTheCpuDofInTheFrame) {
  for (const char* method : {"lee-mipmap", "schedl-layered", "lee-splat"}) {
  SCOPED_TRACE(method);
  std::vector<glm::vec3> hdr[2];
  for (const char* device : {"gpu", "cpu"}) {
    Settings s;
    s.set("dof.method", method);
    s.set("dof.device", device);
    s.set("focus.mode", "fixed");
    s.set("lod.enabled", "false");  // the pass alone
    std::unique_ptr<GazeInput> gaze = make_gaze_input("none");
    FramePipeline pipeline(bundled("attention.json", 192, 144), s, std::make_unique<GlBackend>(), *gaze);
    PassTimer timer;
    const FramePipeline::Frame f = pipeline.render(0, 0.0, 0.0, 0.0, timer);
    ASSERT_TRUE(f.on_gpu) << f.plan.explain();
    ASSERT_TRUE(f.plan.runs(PassId::Dof)) << f.plan.explain();
    const bool gpu = std::string(device) == "gpu";
    EXPECT_EQ(f.plan.at(PassId::Dof).on_gpu, gpu);
    EXPECT_EQ(timer.summary().count("gpu.dof"), gpu ? 1u : 0u);
    EXPECT_EQ(timer.summary().count("gpu.peel"), gpu && std::string(method) != "lee-mipmap" ? 1u : 0u);
    EXPECT_EQ(f.read_back.any(), !gpu) << "focus.mode=fixed: only a CPU dof reads the G-buffer back";
    pipeline.gpu_frame()->read_hdr(hdr[gpu ? 0 : 1]);
  }
  const double psnr = test::psnr_shown(hdr[0], hdr[1]);
  std::printf("%s in the frame: GPU vs CPU %.1f dB\n", method, psnr);
  EXPECT_GE(psnr, 40.0);
  }
}

// The layered DOF methods on the raster backend peel their layers (gl_peel.h) as the ray tracer does:
// occlusion.json's bars over the checkerboard (partial occlusion, what the peeled layers are for),
// the frame through the OpenGL backend against the same frame through Embree.
TEST(GlFramePipeline, TheLayeredDofMethodsPeelOnTheRasterBackendAsOnTheRayTracer) {
  for (const char* method : {"schedl-layered", "lee-splat"}) {
    SCOPED_TRACE(method);
    Image8 images[2];
    for (const BackendKind kind : {BackendKind::OpenGL, BackendKind::Embree}) {
      Settings s;
      s.set("dof.method", method);
      s.set("focus.mode", "fixed");
      s.set("tonemap.exact", "true");
      std::unique_ptr<GazeInput> gaze = make_gaze_input("none");
      FramePipeline pipeline(bundled("occlusion.json", 160, 120), s, make_backend(kind), *gaze);
      PassTimer timer;
      const FramePipeline::Frame f = pipeline.render(0, 0.0, 0.0, 0.0, timer);
      ASSERT_TRUE(f.plan.runs(PassId::Dof)) << f.plan.explain();
      images[kind == BackendKind::OpenGL ? 0 : 1] = f.on_gpu ? pipeline.read_display() : *f.image;
    }
    double se = 0;
    for (std::size_t i = 0; i < images[0].rgb.size(); ++i) {
      const double d = static_cast<double>(images[0].rgb[i]) - static_cast<double>(images[1].rgb[i]);
      se += d * d;
    }
    const double psnr = se == 0 ? 1e9 : 10.0 * std::log10(255.0 * 255.0 * static_cast<double>(images[0].rgb.size()) / se);
    std::printf("%s: raster backend vs ray tracer %.1f dB\n", method, psnr);
    EXPECT_GE(psnr, 40.0);
  }
}

}  // namespace
}  // namespace fovea::render
