// SPDX-License-Identifier: Apache-2.0
// OpenGL raster G-buffer backend under Mesa llvmpipe: frame time with read-back (what the pipeline
// pays: render + glReadPixels of the five targets + row flip) and without (render + glFinish), at
// 640x480 and 1024x768, for the procedural Cornell-like and many-objects scenes and every bundled
// scene that loads. The Embree backend renders the same frames alongside as the reference cost.
// ulod_blend/{fragment,compute}: ULOD's blend pass alone, both implementations side by side.
// lee_mipmap/{fragment,compute}/f{11.2,2.8,0.7}: Lee 2009 ch. 4's DOF alone on attention.json's
// G-buffer at 1920x1080, focused at 4 m, at f/11.2, f/2.8 (the scene's) and f/0.7: both
// implementations at three CoCs in one run (issue 42: cost independent of the CoC).
// schedl_layered/{fragment,compute}/f{2.8,0.7}: Schedl & Wimmer's layered DOF, M = 3 (the visible
// layer and two peeled ones), on the same G-buffer: the fragment box blur against the compute
// pass's running sums.
// attention/{fragment,compute}/map{64,128}: Lee 2009 ch. 3's pixel stage alone (GlAttention: resample,
// pyramids, contrast, S_p, per-object sums and median depths, the per-object values read back) on
// the same G-buffer at two saliency-map sizes.
// Needs a display: xvfb-run -a build/<dir>/bench/bench_gl
#include <benchmark/benchmark.h>
#include <epoxy/gl.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "../tests/gl/test_scenes.h"  // the procedural scenes the GL tests use
#include "backend/backend.h"
#include "backend/gl/gl_attention.h"
#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_program.h"
#include "backend/gl/gl_lee_mipmap.h"
#include "backend/gl/gl_schedl_layered.h"
#include "backend/gl/gl_ulod_blend.h"
#include "dof/lens.h"
#include "scene/scene_loader.h"

namespace {

using namespace fovea::render;

// The repository's root: FOVEA_SOURCE_DIR from the environment (the GPU machine runs this binary in
// a copy of the tree elsewhere, bench/device/gpu-effects.sh), else where it was built from.
std::filesystem::path source_dir() {
  const char* dir = std::getenv("FOVEA_SOURCE_DIR");
  return dir != nullptr && *dir != '\0' ? std::filesystem::path(dir) : std::filesystem::path(FOVEA_SOURCE_DIR);
}

GlBackend& gl_backend() {
  static GlBackend backend;
  return backend;
}

Backend& embree_backend() {
  static std::unique_ptr<Backend> backend = make_backend(BackendKind::Embree);
  return *backend;
}

// Animated scenes advance 1/60 s per frame, so animated objects and the camera really move.
FrameTime frame_time(std::int64_t frame) {
  const double now = static_cast<double>(frame) / 60.0;
  return {now, frame == 0 ? now : now - 1.0 / 60.0};
}

void set_counters(benchmark::State& state, const Scene& s) {
  const auto pixels = static_cast<double>(s.camera.width) * s.camera.height;
  state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["Mpix/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * pixels / 1e6, benchmark::Counter::kIsRate);
  state.counters["objects"] = static_cast<double>(s.objects.size());
}

void gl_render_readback(benchmark::State& state, Scene s) {
  GlBackend& backend = gl_backend();
  backend.set_scene(s);
  GBuffer g;
  std::int64_t frame = 0;
  for (auto _ : state) {
    backend.render(frame_time(frame++), BackendSettings{}, g);
    benchmark::DoNotOptimize(g.color.data());
  }
  set_counters(state, s);
}

void gl_render_only(benchmark::State& state, Scene s) {
  GlBackend& backend = gl_backend();
  backend.set_scene(s);
  std::int64_t frame = 0;
  for (auto _ : state) backend.render_without_readback(frame_time(frame++));  // ends with glFinish
  set_counters(state, s);
}

void embree_render(benchmark::State& state, Scene s) {
  Backend& backend = embree_backend();
  backend.set_scene(s);
  GBuffer g;
  std::int64_t frame = 0;
  for (auto _ : state) {
    backend.render(frame_time(frame++), BackendSettings{}, g);
    benchmark::DoNotOptimize(g.color.data());
  }
  set_counters(state, s);
}

// ULOD's blend pass alone (issue 42), fragment against compute, side by side: a 1920x1080 frame where
// a third of the pixels belong to one of 100 blending objects, ending with glFinish.
void ulod_blend(benchmark::State& state, GlUlodBlend::Pass pass) {
  GlBackend& backend = gl_backend();
  backend.context().make_current();
  constexpr std::uint32_t w = 1920, h = 1080;
  std::vector<float> colour(std::size_t{4} * w * h, 0.5f);
  std::vector<std::uint32_t> ids(std::size_t{w} * h);
  for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<std::uint32_t>(i % 300);  // 1..99 blend
  const auto upload = [&](GLenum internal, GLenum format, GLenum type, const void* data) {
    const unsigned t = gl::make_texture(internal, format, type, w, h);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, format, type, data);
    return t;
  };
  const unsigned drawn = upload(GL_RGBA32F, GL_RGBA, GL_FLOAT, colour.data());
  const unsigned next = upload(GL_RGBA32F, GL_RGBA, GL_FLOAT, colour.data());
  const unsigned id_tex = upload(GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, ids.data());
  std::vector<std::uint32_t> blending;
  std::vector<float> factors;
  for (std::uint32_t id = 1; id < 100; ++id) {
    blending.push_back(id);
    factors.push_back(0.5f);
  }
  GlUlodBlend blend(backend.context().features().at_least(4, 3));
  if (pass == GlUlodBlend::Pass::Compute && !blend.has_compute()) {
    state.SkipWithError("no OpenGL 4.3 compute");
    return;
  }
  for (auto _ : state) {
    blend.run({drawn, id_tex, w, h}, {next, id_tex, w, h}, blending, factors, pass);
    glFinish();
  }
  for (unsigned t : {drawn, next, id_tex}) glDeleteTextures(1, &t);
}

// attention.json's G-buffer at 1920x1080, uploaded once as the DOF's input textures.
struct DofFrame {
  Scene scene;
  unsigned color = 0, depth = 0, ids = 0;
  unsigned peeled_color[2] = {0, 0}, peeled_depth[2] = {0, 0};  // the first two layers behind it
};
const DofFrame& dof_frame() {
  static const DofFrame frame = [] {
    DofFrame f;
    f.scene = load_scene(source_dir() / "renderer/scenes/attention.json");
    f.scene.camera.width = 1920;
    f.scene.camera.height = 1080;
    GlBackend& backend = gl_backend();
    backend.set_scene(f.scene);
    GBuffer g;
    backend.render({}, {}, g);
    backend.context().make_current();
    std::vector<float> staging;
    gl::upload_top_first(f.color, GL_RGB32F, GL_RGB, &g.color[0].x, g.width, g.height, 3, staging);
    gl::upload_top_first(f.depth, GL_R32F, GL_RED, g.depth.data(), g.width, g.height, 1, staging);
    std::vector<std::uint32_t> ids(g.object_id.size());  // rows bottom-up, as OpenGL keeps them
    for (std::uint32_t y = 0; y < g.height; ++y)
      std::copy_n(g.object_id.begin() + std::ptrdiff_t{y} * g.width, g.width,
                  ids.begin() + std::ptrdiff_t{g.height - 1 - y} * g.width);
    f.ids = gl::make_texture(GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, g.width, g.height);
    glBindTexture(GL_TEXTURE_2D, f.ids);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, static_cast<GLsizei>(g.width), static_cast<GLsizei>(g.height),
                    GL_RED_INTEGER, GL_UNSIGNED_INT, ids.data());
    for (std::uint32_t k = 0; k < 2; ++k) {
      BackendSettings peel;
      peel.peel = k + 1;
      GBuffer layer;
      backend.render({}, peel, layer);
      backend.context().make_current();
      gl::upload_top_first(f.peeled_color[k], GL_RGB32F, GL_RGB, &layer.color[0].x, layer.width, layer.height, 3, staging);
      gl::upload_top_first(f.peeled_depth[k], GL_R32F, GL_RED, layer.depth.data(), layer.width, layer.height, 1, staging);
    }
    return f;
  }();
  return frame;
}

// The scene's lens at f-number `f_number`, focused at 4 m.
dof::CocModel lens_at(const Scene& scene, double f_number) {
  Camera camera = scene.camera;
  camera.lens.aperture_m = camera.lens.focal_length_m / f_number;
  return dof::coc_model(camera, {}, 4.0, dof::CocProjection::Sensor);
}

void lee_mipmap(benchmark::State& state, GlLeeMipmap::Pass pass, double f_number) {
  const DofFrame& f = dof_frame();
  gl_backend().context().make_current();
  const dof::CocModel coc = lens_at(f.scene, f_number);
  GlLeeMipmap mipmap(gl_backend().context().features().at_least(4, 3));
  if (pass == GlLeeMipmap::Pass::Compute && !mipmap.has_compute()) {
    state.SkipWithError("no OpenGL 4.3 compute");
    return;
  }
  const GlDofInput in{f.color, f.depth, f.scene.camera.width, f.scene.camera.height};
  mipmap.run(in, coc, {}, pass);  // the targets made outside the timing
  glFinish();
  for (auto _ : state) {
    mipmap.run(in, coc, {}, pass);
    glFinish();
  }
  state.counters["K_px"] = coc.terms().k;
}

void schedl_layered(benchmark::State& state, GlSchedlLayered::Pass pass, double f_number) {
  const DofFrame& f = dof_frame();
  gl_backend().context().make_current();
  const dof::CocModel coc = lens_at(f.scene, f_number);
  GlSchedlLayered schedl(gl_backend().context().features().at_least(4, 3));
  if (pass == GlSchedlLayered::Pass::Compute && !schedl.has_compute()) {
    state.SkipWithError("no OpenGL 4.3 compute");
    return;
  }
  const std::uint32_t w = f.scene.camera.width, h = f.scene.camera.height;
  const GlDofInput in{f.color, f.depth, w, h};
  const std::vector<GlDofInput> peeled{{f.peeled_color[0], f.peeled_depth[0], w, h}, {f.peeled_color[1], f.peeled_depth[1], w, h}};
  dof::SchedlStats stats = schedl.run(in, peeled, coc, {}, pass);
  glFinish();
  for (auto _ : state) {
    stats = schedl.run(in, peeled, coc, {}, pass);
    glFinish();
  }
  state.counters["K_px"] = coc.terms().k;
  state.counters["layers"] = stats.layers;
}

void attention_pass(benchmark::State& state, GlAttention::Pass pass, int map_size) {
  const DofFrame& f = dof_frame();
  gl_backend().context().make_current();
  GlAttention attention(gl_backend().context().features().at_least(4, 3));
  if (pass == GlAttention::Pass::Compute && !attention.has_compute()) {
    state.SkipWithError("no OpenGL 4.3 compute");
    return;
  }
  attention::AttentionSettings s;
  s.map_size = map_size;
  GlAttentionObjects objects;
  for (const Object& o : f.scene.objects) {
    objects.ids.push_back(o.id);
    objects.motion.push_back(0.0f);
  }
  const GlAttentionInput in{f.color, f.depth, f.ids, f.scene.camera.width, f.scene.camera.height};
  std::vector<attention::ObjectPixels> out;
  attention.run(in, f.scene.camera.near_m, f.scene.camera.far_m, s, objects, out, pass);  // targets made outside
  for (auto _ : state) attention.run(in, f.scene.camera.near_m, f.scene.camera.far_m, s, objects, out, pass);
  state.counters["objects"] = static_cast<double>(out.size());
}

void register_scene(const std::string& name, Scene s) {
  for (const auto& [w, h] : {std::pair{640u, 480u}, std::pair{1024u, 768u}}) {
    s.camera.width = w;
    s.camera.height = h;
    const std::string suffix = name + "/" + std::to_string(w) + "x" + std::to_string(h);
    benchmark::RegisterBenchmark(("gl_render_readback/" + suffix).c_str(), gl_render_readback, s)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("gl_render_only/" + suffix).c_str(), gl_render_only, s)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("embree_render/" + suffix).c_str(), embree_render, s)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  }
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  std::printf("GL renderer: %s\n", gl_backend().context().renderer().c_str());
  for (const auto& [name, pass] : {std::pair{"fragment", GlUlodBlend::Pass::Fragment}, std::pair{"compute", GlUlodBlend::Pass::Compute}})
    benchmark::RegisterBenchmark((std::string("ulod_blend/") + name + "/1920x1080").c_str(), ulod_blend, pass)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  for (const auto& [name, pass] : {std::pair{"fragment", GlLeeMipmap::Pass::Fragment}, std::pair{"compute", GlLeeMipmap::Pass::Compute}})
    for (const auto& [f_name, f_number] : {std::pair{"f11.2", 11.2}, std::pair{"f2.8", 2.8}, std::pair{"f0.7", 0.7}})
      benchmark::RegisterBenchmark((std::string("lee_mipmap/") + name + "/" + f_name + "/1920x1080").c_str(), lee_mipmap,
                                   pass, f_number)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
  for (const auto& [name, pass] : {std::pair{"fragment", GlSchedlLayered::Pass::Fragment}, std::pair{"compute", GlSchedlLayered::Pass::Compute}})
    for (const auto& [f_name, f_number] : {std::pair{"f2.8", 2.8}, std::pair{"f0.7", 0.7}})
      benchmark::RegisterBenchmark((std::string("schedl_layered/") + name + "/" + f_name + "/1920x1080").c_str(),
                                   schedl_layered, pass, f_number)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
  for (const auto& [name, pass] : {std::pair{"fragment", GlAttention::Pass::Fragment}, std::pair{"compute", GlAttention::Pass::Compute}})
    for (const int n : {64, 128})
      benchmark::RegisterBenchmark((std::string("attention/") + name + "/map" + std::to_string(n) + "/1920x1080").c_str(),
                                   attention_pass, pass, n)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
  register_scene("cornell-procedural", testing::cornell_box());
  register_scene("many-objects-120", testing::many_objects(120));
  const std::filesystem::path dir = source_dir() / "renderer" / "scenes";
  std::vector<std::filesystem::path> files;
  if (std::filesystem::is_directory(dir)) {
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
      if (entry.path().extension() == ".json") files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  for (const auto& file : files) {
    try {
      register_scene(file.stem().string(), load_scene(file));
    } catch (const std::exception& e) {
      std::printf("skipping %s: %s\n", file.string().c_str(), e.what());
    }
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
