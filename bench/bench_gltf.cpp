// SPDX-License-Identifier: Apache-2.0
// A glTF scene's cost and the backends' agreement on it (issue 41): load phases (parse, textures,
// LOD chains; the backend's BVH build or upload), resident memory, the G-buffer's time per backend
// at one resolution, and Embree against OpenGL as PSNR of the displayed images (x / (1 + x), sRGB
// encoded, peak 1): over all pixels and over the pixels where both see the same object (silhouettes
// and alpha-mask edges may differ by a pixel by design).
// --culling adds what back-face culling of single-sided materials costs or saves: per backend, the
// scene as authored against every material double-sided, frames interleaved in one process.
// Usage: bench_gltf --scene FILE [--width 1280] [--height 720] [--frames 5] [--camera NODE] [--culling]
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "backend/backend.h"
#include "lod/lod_chain.h"
#include "scene/scene_loader.h"
#include "scene/texture.h"

using namespace fovea::render;

namespace {

double ms_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

// VmRSS and VmHWM (peak) of this process, MiB.
std::pair<double, double> resident_mib() {
  std::ifstream in("/proc/self/status");
  std::string line;
  double rss = 0, hwm = 0;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) rss = std::stod(line.substr(6)) / 1024.0;
    if (line.rfind("VmHWM:", 0) == 0) hwm = std::stod(line.substr(6)) / 1024.0;
  }
  return {rss, hwm};
}

float display(float x) { return linear_to_srgb(std::isfinite(x) && x > 0 ? x / (1.0f + x) : 0.0f); }

struct Psnr {
  double all = 0, same_object = 0;
  double same_fraction = 0;
};

Psnr psnr(const GBuffer& a, const GBuffer& b) {
  double se_all = 0, se_same = 0;
  std::size_t same = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    double se = 0;
    for (int c = 0; c < 3; ++c) {
      const double d = display(a.color[i][c]) - display(b.color[i][c]);
      se += d * d;
    }
    se_all += se;
    if (a.object_id[i] == b.object_id[i]) {
      se_same += se;
      ++same;
    }
  }
  const auto to_db = [](double se, std::size_t n) {
    const double mse = se / static_cast<double>(3 * std::max<std::size_t>(n, 1));
    return mse > 0 ? 10 * std::log10(1.0 / mse) : 99.0;
  };
  return {to_db(se_all, a.size()), to_db(se_same, same), static_cast<double>(same) / static_cast<double>(a.size())};
}

// Per backend: the scene as authored (single-sided materials back-face culled) and the same scene
// with every material double-sided, rendered alternately so that both see the same machine load.
void compare_culling(const Scene& scene, std::uint32_t width, std::uint32_t height, int frames) {
  Scene both_sides = scene;
  std::size_t single = 0;
  for (Material& m : both_sides.materials) {
    if (m.type == MaterialType::MetallicRoughness && !m.pbr.double_sided) ++single;
    m.pbr.double_sided = true;
  }
  std::printf("\nback-face culling (%zu of %zu materials single-sided), G-buffer p50 ms over %d interleaved frames each:\n",
              single, scene.materials.size(), frames - 1);
  for (const BackendKind kind : {BackendKind::Embree, BackendKind::OpenGL}) {
    const auto culled = make_backend(kind), drawn = make_backend(kind);
    culled->set_scene(scene);
    drawn->set_scene(both_sides);
    BackendSettings settings;
    settings.width = width;
    settings.height = height;
    GBuffer g;
    std::vector<double> ms_culled, ms_drawn;
    for (int i = 0; i < frames; ++i) {
      auto t = std::chrono::steady_clock::now();
      culled->render(FrameTime{}, settings, g);
      if (i > 0) ms_culled.push_back(ms_since(t));
      t = std::chrono::steady_clock::now();
      drawn->render(FrameTime{}, settings, g);
      if (i > 0) ms_drawn.push_back(ms_since(t));
    }
    std::sort(ms_culled.begin(), ms_culled.end());
    std::sort(ms_drawn.begin(), ms_drawn.end());
    const double c = ms_culled[ms_culled.size() / 2], d = ms_drawn[ms_drawn.size() / 2];
    std::printf("%-8s culled %8.1f  all double-sided %8.1f  ratio %.3f\n", kind == BackendKind::Embree ? "embree" : "gl",
                c, d, c / d);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_gltf: a glTF scene's load cost, memory, G-buffer time per backend and Embree-vs-OpenGL PSNR"};
  std::string scene_path, camera;
  std::uint32_t width = 1280, height = 720;
  int frames = 5;
  app.add_option("--scene", scene_path, "a .gltf/.glb asset or a JSON scene")->required();
  app.add_option("--camera", camera, "a glTF camera node");
  app.add_option("--width", width, "image width")->check(CLI::Range(16u, 7680u));
  app.add_option("--height", height, "image height")->check(CLI::Range(16u, 4320u));
  app.add_option("--frames", frames, "G-buffer renders per backend (the first is dropped as warm-up)")->check(CLI::Range(2, 1000));
  bool culling = false;
  app.add_flag("--culling", culling,
               "also time each backend with the single-sided materials culled against all drawn double-sided "
               "(interleaved frames)");
  CLI11_PARSE(app, argc, argv);

  LoadReport load;
  Scene scene = load_scene(scene_path, {{"camera.width", std::to_string(width)}, {"camera.height", std::to_string(height)}},
                           camera, &load);
  auto t = std::chrono::steady_clock::now();
  lod::attach_chains(scene);
  load.add("lod", ms_since(t));
  std::size_t triangles = 0, textures = 0, texture_bytes = 0;
  for (const Object& o : scene.objects) triangles += o.mesh ? o.mesh->triangle_count() : 0;
  for (const auto& tex : scene.textures) {
    ++textures;
    texture_bytes += tex->bytes();
  }
  const auto [rss_loaded, hwm_loaded] = resident_mib();
  std::printf("scene %s: %zu objects, %zu triangles, %zu materials, %zu textures (%.0f MiB with mip chains)\n",
              scene_path.c_str(), scene.objects.size(), triangles, scene.materials.size(), textures,
              static_cast<double>(texture_bytes) / (1 << 20));
  std::printf("%s\n", load.summary().c_str());
  std::printf("resident after loading: %.0f MiB (peak %.0f MiB)\n", rss_loaded, hwm_loaded);

  std::vector<GBuffer> images;
  std::printf("\n%-8s %12s %14s %14s %14s\n", "backend", "set_scene ms", "gbuffer p50 ms", "gbuffer min ms", "resident MiB");
  for (const BackendKind kind : {BackendKind::Embree, BackendKind::OpenGL}) {
    t = std::chrono::steady_clock::now();
    const auto backend = make_backend(kind);
    backend->set_scene(scene);
    const double set_ms = ms_since(t);
    BackendSettings settings;
    settings.width = width;
    settings.height = height;
    GBuffer g;
    std::vector<double> ms;
    for (int i = 0; i < frames; ++i) {
      t = std::chrono::steady_clock::now();
      backend->render(FrameTime{}, settings, g);
      if (i > 0) ms.push_back(ms_since(t));
    }
    std::sort(ms.begin(), ms.end());
    std::printf("%-8s %12.0f %14.1f %14.1f %14.0f\n", kind == BackendKind::Embree ? "embree" : "gl", set_ms,
                ms[ms.size() / 2], ms.front(), resident_mib().first);
    images.push_back(std::move(g));
  }
  const Psnr p = psnr(images[0], images[1]);
  std::printf("\nEmbree vs OpenGL (display values x/(1+x), sRGB, peak 1): PSNR %.1f dB over all pixels, %.1f dB over the "
              "%.1f %% where both see the same object\n",
              p.all, p.same_object, 100 * p.same_fraction);
  if (culling) compare_culling(scene, width, height, frames);
  std::printf("peak resident: %.0f MiB\n", resident_mib().second);
  return 0;
}
