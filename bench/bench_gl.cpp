// SPDX-License-Identifier: Apache-2.0
// OpenGL raster G-buffer backend under Mesa llvmpipe: frame time with read-back (what the pipeline
// pays: render + glReadPixels of the five targets + row flip) and without (render + glFinish), at
// 640x480 and 1024x768, for the procedural Cornell-like and many-objects scenes and every bundled
// scene that loads. The Embree backend renders the same frames alongside as the reference cost.
// Needs a display: xvfb-run -a build/<dir>/bench/bench_gl
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "../tests/gl/test_scenes.h"  // the procedural scenes the GL tests use
#include "backend/backend.h"
#include "backend/gl/gl_backend.h"
#include "scene/scene_loader.h"

namespace {

using namespace fovea::render;

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
  register_scene("cornell-procedural", testing::cornell_box());
  register_scene("many-objects-120", testing::many_objects(120));
  const std::filesystem::path dir = std::filesystem::path(FOVEA_SOURCE_DIR) / "renderer" / "scenes";
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
