// SPDX-License-Identifier: Apache-2.0
// Embree G-buffer throughput at 1024x768: primary rays per second for each traversal mode (single
// rays, packets of 4/8/16, rtcIntersect1M streams) and geometry mode (flattened world-space
// meshes vs instances), with and without shading (shading always with shadow rays).
//
// Scenes: a Cornell-box-like room and a field of 64 objects (4 animated) built here, plus the
// bundled renderer/scenes/cornell.json and attention.json through load_scene when they load.
// Every frame advances scene time by 1/60 s, so animated objects are re-committed each iteration
// (the per-frame BVH update is part of the cost being compared).
//
// items_per_second = primary rays/s; counters: Mrays/s (primary), shadow_Mrays/s, shadow/px.
// Wall-clock time (UseRealTime): the work runs on TBB's threads, not the benchmark thread.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "backend/embree/embree_backend.h"
#include "scene/geometry.h"
#include "scene/scene_loader.h"

using namespace fovea::render;

namespace {

BackendSettings shadow_settings(bool shadows) {
  BackendSettings s;
  s.shadows = shadows;
  return s;
}

constexpr std::uint32_t kWidth = 1024, kHeight = 768;

Object make_object(std::uint32_t id, Mesh mesh, glm::vec3 at, std::uint32_t material, glm::vec3 rotation_deg = {}) {
  Object o;
  o.name = "object" + std::to_string(id);
  o.id = id;
  o.mesh = std::make_shared<Mesh>(std::move(mesh));
  o.transform.translation = at;
  o.transform.rotation_deg = rotation_deg;
  o.material = material;
  return o;
}

Material lambert(const char* name, glm::vec3 kd) {
  Material m;
  m.name = name;
  m.kd = kd;
  return m;
}

// A 2 m Cornell-like room: five walls, a tall and a short box, a glossy sphere, an emissive ceiling
// panel with a 2x2-sample area light just beneath it.
Scene cornell_scene() {
  Scene s;
  s.name = "cornell-procedural";
  s.camera.position = {0, 1, 3.4f};
  s.camera.target = {0, 1, 0};
  s.camera.vertical_fov_deg = 40;
  s.camera.width = kWidth;
  s.camera.height = kHeight;
  s.materials = {lambert("white", glm::vec3(0.7f)), lambert("red", {0.6f, 0.05f, 0.05f}),
                 lambert("green", {0.05f, 0.6f, 0.05f})};
  Material glossy = lambert("glossy", glm::vec3(0.5f));
  glossy.type = MaterialType::BlinnPhong;
  glossy.ks = glm::vec3(0.4f);
  glossy.shininess = 40;
  s.materials.push_back(glossy);
  Material lamp;
  lamp.name = "lamp";
  lamp.type = MaterialType::Emissive;
  lamp.emission = glm::vec3(10);
  s.materials.push_back(lamp);
  std::uint32_t id = 1;
  s.objects.push_back(make_object(id++, make_plane({2, 2}), {0, 0, 0}, 0));                 // floor
  s.objects.push_back(make_object(id++, make_plane({2, 2}), {0, 2, 0}, 0, {180, 0, 0}));    // ceiling
  s.objects.push_back(make_object(id++, make_plane({2, 2}), {0, 1, -1}, 0, {90, 0, 0}));    // back
  s.objects.push_back(make_object(id++, make_plane({2, 2}), {-1, 1, 0}, 1, {0, 0, -90}));   // left
  s.objects.push_back(make_object(id++, make_plane({2, 2}), {1, 1, 0}, 2, {0, 0, 90}));     // right
  s.objects.push_back(make_object(id++, make_box({0.6f, 1.2f, 0.6f}), {-0.35f, 0.6f, -0.3f}, 0, {0, 20, 0}));
  s.objects.push_back(make_object(id++, make_box({0.6f, 0.6f, 0.6f}), {0.4f, 0.3f, 0.3f}, 0, {0, -18, 0}));
  s.objects.push_back(make_object(id++, make_sphere(0.25f, 32, 64), {0.4f, 0.85f, 0.3f}, 3));
  s.objects.push_back(make_object(id++, make_plane({0.5f, 0.5f}), {0, 1.999f, 0}, 4, {180, 0, 0}));  // lamp panel
  Light l;
  l.type = LightType::Area;
  l.position = {0, 1.99f, 0};
  l.direction = {0, -1, 0};
  l.area_size = glm::vec2(0.5f);
  l.area_samples = 2;
  l.power = glm::vec3(60);
  s.lights.push_back(l);
  return s;
}

// Tens of objects, few animated: an 8x8 grid of spheres, boxes and cylinders on a ground plane,
// 4 of them moving; one point light and one spot light.
Scene many_objects_scene() {
  Scene s;
  s.name = "many-objects";
  s.camera.position = {0, 6, 14};
  s.camera.target = {0, 0, 0};
  s.camera.vertical_fov_deg = 50;
  s.camera.width = kWidth;
  s.camera.height = kHeight;
  s.materials = {lambert("ground", glm::vec3(0.5f)), lambert("a", {0.7f, 0.3f, 0.2f}), lambert("b", {0.2f, 0.5f, 0.7f})};
  Material glossy = lambert("glossy", glm::vec3(0.4f));
  glossy.type = MaterialType::BlinnPhong;
  glossy.ks = glm::vec3(0.5f);
  glossy.shininess = 60;
  s.materials.push_back(glossy);
  std::uint32_t id = 1;
  s.objects.push_back(make_object(id++, make_plane({40, 40}), {0, 0, 0}, 0));
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j < 8; ++j) {
      const glm::vec3 at{1.5f * (static_cast<float>(i) - 3.5f), 0.5f, 1.5f * (static_cast<float>(j) - 3.5f)};
      const auto material = static_cast<std::uint32_t>(1 + (i + j) % 3);
      const glm::vec3 rot{0, 13.0f * static_cast<float>(i + 2 * j), 0};
      Mesh mesh = (i + j) % 3 == 0   ? make_sphere(0.5f, 24, 48)
                  : (i + j) % 3 == 1 ? make_box({0.8f, 1.0f, 0.8f})
                                     : make_cylinder(0.4f, 1.0f, 48);
      Object o = make_object(id++, std::move(mesh), at, material, rot);
      if (i == j && i % 2 == 0) {
        Animation a;
        a.keys = {{0.0, {0, 0, 0}, {0, 0, 0}}, {1.0, {0.5f, 0.3f, 0}, {0, 180, 0}}, {2.0, {0, 0, 0}, {0, 360, 0}}};
        o.animation = a;
      }
      s.objects.push_back(std::move(o));
    }
  }
  Light p;
  p.position = {3, 8, 6};
  p.power = glm::vec3(2000);
  s.lights.push_back(p);
  Light spot;
  spot.type = LightType::Spot;
  spot.position = {-4, 6, 2};
  spot.direction = glm::normalize(glm::vec3(0.5f, -1, -0.3f));
  spot.spot_cutoff_deg = 40;
  spot.power = glm::vec3(1500);
  s.lights.push_back(spot);
  return s;
}

std::filesystem::path scenes_dir() {
  if (const char* env = std::getenv("FOVEA_SCENES_DIR")) return env;
  return std::filesystem::path(__FILE__).parent_path().parent_path() / "renderer" / "scenes";
}

// nullptr (and a note on stderr) if the bundled scene does not load.
std::shared_ptr<const Scene> bundled(const std::string& file) {
  try {
    Scene s = load_scene(scenes_dir() / file);
    s.camera.width = kWidth;
    s.camera.height = kHeight;
    return std::make_shared<const Scene>(std::move(s));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_embree: skipping %s: %s\n", file.c_str(), e.what());
    return nullptr;
  }
}

void frame(benchmark::State& state, std::shared_ptr<const Scene> scene, EmbreeOptions options, bool shadows) {
  EmbreeBackend backend(options);
  backend.set_scene(*scene);
  GBuffer g;
  double t = 0;
  std::uint64_t primary = 0, shadow = 0;
  backend.render({t, t}, shadow_settings(shadows), g);  // warm-up
  for (auto _ : state) {
    t += 1.0 / 60;
    backend.render({t, t - 1.0 / 60}, shadow_settings(shadows), g);
    benchmark::DoNotOptimize(g.color.data());
    primary += backend.last_frame_stats().primary_rays;
    shadow += backend.last_frame_stats().shadow_rays;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(primary));
  state.counters["Mrays/s"] = benchmark::Counter(static_cast<double>(primary) / 1e6, benchmark::Counter::kIsRate);
  state.counters["shadow_Mrays/s"] = benchmark::Counter(static_cast<double>(shadow) / 1e6, benchmark::Counter::kIsRate);
  state.counters["shadow/px"] = primary > 0 ? static_cast<double>(shadow) / static_cast<double>(primary) : 0.0;
}

// Side-by-side comparison that survives a shared, noisy machine: every configuration (geometry x
// traversal) renders the same frame in turn within each iteration (starting position rotated per
// iteration), so load changes hit all of them alike. Counters and the table printed at the end
// give each configuration's primary Mrays/s and its ratio to the flattened single-ray baseline.
struct CompareRow {
  std::string scene, config;
  bool shading = false;
  double mrays = 0, ratio = 0;
};
std::vector<CompareRow>& compare_rows() {
  static std::vector<CompareRow> rows;
  return rows;
}

void compare(benchmark::State& state, const std::string& scene_name, std::shared_ptr<const Scene> scene, bool shading) {
  struct Config {
    std::string name;
    std::unique_ptr<EmbreeBackend> backend;
    double seconds = 0;
    std::uint64_t rays = 0;
  };
  std::vector<Config> configs;
  for (const EmbreeGeometry geometry : {EmbreeGeometry::Flattened, EmbreeGeometry::Instanced}) {
    for (const EmbreeTraversal traversal : {EmbreeTraversal::Single, EmbreeTraversal::Packet4, EmbreeTraversal::Packet8,
                                            EmbreeTraversal::Packet16, EmbreeTraversal::Stream}) {
      Config c;
      c.name = std::string(to_string(geometry)) + "/" + to_string(traversal);
      c.backend = std::make_unique<EmbreeBackend>(EmbreeOptions{traversal, geometry, shading});
      c.backend->set_scene(*scene);
      configs.push_back(std::move(c));
    }
  }
  GBuffer g;
  double t = 0;
  for (Config& c : configs) c.backend->render({t, t}, shadow_settings(shading), g);  // warm-up
  std::size_t rotation = 0;
  for (auto _ : state) {
    t += 1.0 / 60;
    for (std::size_t k = 0; k < configs.size(); ++k) {
      Config& c = configs[(k + rotation) % configs.size()];
      const auto start = std::chrono::steady_clock::now();
      c.backend->render({t, t - 1.0 / 60}, shadow_settings(shading), g);
      c.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      c.rays += c.backend->last_frame_stats().primary_rays;
      benchmark::DoNotOptimize(g.color.data());
    }
    ++rotation;
  }
  const double base = static_cast<double>(configs.front().rays) / configs.front().seconds;
  for (const Config& c : configs) {
    const double rate = static_cast<double>(c.rays) / c.seconds;
    state.counters[c.name] = rate / 1e6;
    compare_rows().push_back({scene_name, c.name, shading, rate / 1e6, rate / base});
  }
}

void build(benchmark::State& state, std::shared_ptr<const Scene> scene, EmbreeGeometry geometry) {
  EmbreeBackend backend({EmbreeTraversal::Single, geometry, true});
  for (auto _ : state) backend.set_scene(*scene);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::pair<std::string, std::shared_ptr<const Scene>>> scenes = {
      {"cornell-procedural", std::make_shared<const Scene>(cornell_scene())},
      {"many-objects", std::make_shared<const Scene>(many_objects_scene())},
  };
  for (const char* file : {"cornell.json", "attention.json"}) {
    if (auto s = bundled(file)) scenes.emplace_back(file, s);
  }
  const EmbreeTraversal traversals[] = {EmbreeTraversal::Single, EmbreeTraversal::Packet4, EmbreeTraversal::Packet8,
                                        EmbreeTraversal::Packet16, EmbreeTraversal::Stream};
  for (const auto& [name, scene] : scenes) {
    for (const bool shading : {false, true}) {
      benchmark::RegisterBenchmark(("compare/" + name + (shading ? "/shaded+shadows" : "/geometry-only")).c_str(), compare,
                                   name, scene, shading)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime()
          ->Iterations(shading ? 4 : 8);
    }
  }
  for (const auto& [name, scene] : scenes) {
    for (const EmbreeGeometry geometry : {EmbreeGeometry::Flattened, EmbreeGeometry::Instanced}) {
      benchmark::RegisterBenchmark(("set_scene/" + name + "/" + to_string(geometry)).c_str(), build, scene, geometry)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
      for (const bool shading : {false, true}) {
        for (const EmbreeTraversal traversal : traversals) {
          const std::string label = "frame/" + name + "/" + to_string(geometry) + "/" + to_string(traversal) +
                                    (shading ? "/shaded+shadows" : "/geometry-only");
          benchmark::RegisterBenchmark(label.c_str(), frame, scene, EmbreeOptions{traversal, geometry, shading}, shading)
              ->Unit(benchmark::kMillisecond)
              ->UseRealTime()
              ->MinTime(0.3);
        }
      }
    }
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  if (!compare_rows().empty()) {
    std::printf("\nSide-by-side comparison (primary Mrays/s at %ux%u, ratio to flattened/single):\n", kWidth, kHeight);
    std::printf("%-20s %-16s %-22s %10s %8s\n", "scene", "shading", "geometry/traversal", "Mrays/s", "ratio");
    for (const CompareRow& r : compare_rows()) {
      std::printf("%-20s %-16s %-22s %10.2f %8.2f\n", r.scene.c_str(), r.shading ? "shaded+shadows" : "geometry-only",
                  r.config.c_str(), r.mrays, r.ratio);
    }
  }
  benchmark::Shutdown();
  return 0;
}
