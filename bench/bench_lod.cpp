// SPDX-License-Identifier: Apache-2.0
// Level of detail (Lee 2009 Fig. 7.4/7.5): frame time against the number of visible objects for
// NOLOD, ULOD2..ULOD5 and each selection policy, with the triangles drawn and the image error against
// full detail inside the gazed region and in the periphery.
//
// Scene: N of 256 objects (a bunny-like bumpy ellipsoid of 69,384 triangles, or a dragon-like bumpy
// torus knot of 435,200, generated here: Lee's counts) with random colour, size and pose on a floor in
// front of the camera; chains of 5 levels, base 4 (eq. 7.4). ULODm is timed as fovea's lod-select
// pass runs it: the proxy G-buffer (every object at level m-1, Lee §7.2), the attention pass on it,
// eq. 7.3, the G-buffer at the chosen levels and the unpopping blend pass; each part is reported
// next to eq. 7.2's prediction from T_n (a frame without objects) and t (NOLOD's cost per object).
// The viewer is taken to look at the object the full-detail attention pass ranks first.
// The raster backend (OpenGL; run under deploy/with-xvfb.sh) is the renderer Lee's costs are about;
// Embree's ray casting is timed alongside (its cost grows with the log of the triangles).
//
// --scene FILE measures the same conditions on a scene file instead (JSON, glTF or GLB; issue 41:
// a textured scene whose objects differ in size, material and chain): every object with a chain
// (a glTF object gets one by default) is a model, T_n is the frame with no objects, and eq. 7.2's
// per-object cost t becomes a per-triangle cost, (T_NOLOD - T_n) / triangles, which is the same
// model when every object is one mesh.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <numbers>
#include <random>
#include <sstream>

#include "attention/attention.h"
#include "backend/backend.h"
#include "backend/embree/embree_backend.h"
#include "lod/lod_chain.h"
#include "lod/lod_frame.h"
#include "lod/lod_policy.h"
#include "scene/scene_loader.h"

using namespace fovea::render;
using Clock = std::chrono::steady_clock;

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// Two triangles per cell of a (rows + 1) x (cols + 1) vertex grid.
void grid_indices(Mesh& m, int rows, int cols) {
  const auto row = static_cast<std::uint32_t>(cols + 1);
  for (std::uint32_t r = 0; r < static_cast<std::uint32_t>(rows); ++r)
    for (std::uint32_t c = 0; c < static_cast<std::uint32_t>(cols); ++c) {
      const std::uint32_t a = r * row + c, b = a + row;
      m.indices.insert(m.indices.end(), {a, b, a + 1, a + 1, b, b + 1});
    }
}

// A bumpy ellipsoid: rings x segments quads, radially displaced by a few sines.
Mesh bunny_like(int rings, int segments) {
  Mesh m;
  for (int r = 0; r <= rings; ++r) {
    const float v = static_cast<float>(r) / static_cast<float>(rings), theta = v * kPi;
    for (int s = 0; s <= segments; ++s) {
      const float u = static_cast<float>(s) / static_cast<float>(segments), phi = u * 2 * kPi;
      const glm::vec3 d{std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)};
      const float bump = 1.0f + 0.08f * std::sin(7 * theta) * std::cos(5 * phi) + 0.03f * std::sin(23 * theta + 11 * phi);
      m.positions.push_back(d * glm::vec3(0.45f, 0.5f, 0.35f) * bump);
      m.normals.push_back(d);
    }
  }
  grid_indices(m, rings, segments);
  return m;
}

// A bumpy (2,3) torus knot tube: along x around quads.
Mesh dragon_like(int along, int around) {
  Mesh m;
  const auto knot = [](float t) {
    const float r = 0.3f + 0.12f * std::cos(3 * t);
    return glm::vec3(r * std::cos(2 * t), 0.12f * std::sin(3 * t), r * std::sin(2 * t));
  };
  for (int i = 0; i <= along; ++i) {
    const float t = 2 * kPi * static_cast<float>(i) / static_cast<float>(along);
    const glm::vec3 c = knot(t), tangent = glm::normalize(knot(t + 1e-3f) - knot(t - 1e-3f));
    const glm::vec3 n0 = glm::normalize(glm::cross(tangent, glm::vec3(0, 1, 0)));
    const glm::vec3 b0 = glm::cross(tangent, n0);
    for (int j = 0; j <= around; ++j) {
      const float a = 2 * kPi * static_cast<float>(j) / static_cast<float>(around);
      const glm::vec3 d = n0 * std::cos(a) + b0 * std::sin(a);
      const float bump = 1.0f + 0.15f * std::sin(40 * t) * std::sin(6 * a);
      m.positions.push_back(c + d * 0.06f * bump);
      m.normals.push_back(d);
    }
  }
  grid_indices(m, along, around);
  return m;
}

Scene make_scene(const lod::Chain& chain, int count, std::uint32_t seed, std::uint32_t w, std::uint32_t h) {
  Scene s;
  s.name = "lod-bench";
  s.camera.position = {0, 2.2f, 6};
  s.camera.target = {0, 0.4f, -4};
  s.camera.width = w;
  s.camera.height = h;
  s.camera.far_m = 60;
  Material floor;
  floor.kd = glm::vec3(0.4f);
  s.materials.push_back(floor);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  for (int k = 0; k < 16; ++k) {  // random hue and luminance
    Material m;
    m.type = MaterialType::BlinnPhong;
    const float hue = u(rng) * 6, lum = 0.2f + 0.7f * u(rng);
    const glm::vec3 c = glm::clamp(glm::abs(glm::mod(glm::vec3(hue, hue + 4, hue + 2), 6.0f) - 3.0f) - 1.0f, 0.0f, 1.0f);
    m.kd = c * lum;
    m.ks = glm::vec3(0.2f);
    m.shininess = 30;
    s.materials.push_back(m);
  }
  Object ground;
  ground.name = "floor";
  ground.id = 1;
  Mesh plane;
  plane.positions = {{-20, 0, 8}, {20, 0, 8}, {20, 0, -30}, {-20, 0, -30}};
  plane.normals.assign(4, glm::vec3(0, 1, 0));
  plane.indices = {0, 1, 2, 0, 2, 3};
  ground.mesh = std::make_shared<Mesh>(plane);
  s.objects.push_back(ground);
  auto full = std::make_shared<const Mesh>(chain.levels[0].mesh);
  std::vector<LodLevel> lods;
  for (std::size_t l = 1; l < chain.levels.size(); ++l)
    lods.push_back({std::make_shared<const Mesh>(chain.levels[l].mesh), chain.levels[l].error_m});
  const int side = 16;
  for (int k = 0; k < count; ++k) {
    Object o;
    o.name = "model" + std::to_string(k);
    o.id = static_cast<std::uint32_t>(k + 2);
    o.mesh = full;
    o.lods = lods;
    o.material = 1 + static_cast<std::uint32_t>(rng() % 16);
    const float scale = 0.5f + 0.9f * u(rng);
    // A 16 x 16 grid of slots from 1 m to 28 m ahead, jittered: the first N slots in a random order.
    const int slot = k;
    const float x = (static_cast<float>(slot % side) - 7.5f) * 1.1f * (1.0f + static_cast<float>(slot / side) * 0.12f);
    const float z = -1.0f - static_cast<float>(slot / side) * 1.7f;
    o.transform.translation = {x + 0.3f * (u(rng) - 0.5f), 0.5f * scale, z + 0.3f * (u(rng) - 0.5f)};
    o.transform.rotation_deg = {0, 360 * u(rng), 0};
    o.transform.scale = glm::vec3(scale);
    o.task_importance = u(rng);
    s.objects.push_back(o);
  }
  Light l;
  l.position = {0, 8, 4};
  l.power = glm::vec3(3000);
  s.lights.push_back(l);
  s.ambient = glm::vec3(0.05f);
  return s;
}

// PSNR of the tone-mapped (x / (1 + x)) colours over the pixels whose region is `which`.
double psnr(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b, const std::vector<std::uint8_t>& region,
            std::uint8_t which) {
  double se = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (region[i] != which) continue;
    for (int c = 0; c < 3; ++c) {
      const auto tone = [](float v) { return std::min(1.0, static_cast<double>(v) / (1.0 + static_cast<double>(v))); };
      const double d = tone(a[i][c]) - tone(b[i][c]);
      se += d * d;
      ++n;
    }
  }
  if (n == 0) return std::nan("");
  const double mse = se / static_cast<double>(n);
  return mse > 0 ? 10 * std::log10(1.0 / mse) : 99.0;
}

template <typename F>
double median_ms(int frames, F&& body) {
  std::vector<double> ms;
  for (int f = 0; f < frames; ++f) {
    const auto s0 = Clock::now();
    body();
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - s0).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

double attention_of(const attention::AttentionFrame& att, std::uint32_t id) {
  for (const auto& a : att.objects)
    if (a.id == id) return a.attention;
  return 0.0;
}

// Triangles of each object at each of its levels (level 0 its mesh), clamped as the backends clamp.
struct TriangleTable {
  std::vector<std::vector<std::uint64_t>> per_object;
  explicit TriangleTable(const Scene& scene) {
    for (const Object& o : scene.objects) {
      std::vector<std::uint64_t> levels{o.mesh ? o.mesh->triangle_count() : 0};
      for (const LodLevel& l : o.lods) levels.push_back(l.mesh ? l.mesh->triangle_count() : 0);
      per_object.push_back(std::move(levels));
    }
  }
  std::uint64_t at(std::size_t object, int level) const {
    const auto& l = per_object[object];
    return l[static_cast<std::size_t>(std::clamp(level, 0, static_cast<int>(l.size()) - 1))];
  }
  // Over the models: the objects with a chain (the generated floor has none).
  std::uint64_t models_at(int level) const {
    std::uint64_t sum = 0;
    for (std::size_t k = 0; k < per_object.size(); ++k)
      if (per_object[k].size() > 1) sum += at(k, level);
    return sum;
  }
};

// One measured scene: what the rows call it, the scene, its T_n frame (no models) and the highest
// object id that is ground rather than model (the generated floor; none in a scene file).
struct BenchScene {
  std::string model;
  int count = 0;
  Scene scene, empty;
  std::uint32_t ground_ids = 0;
};

Scene load_bench_scene(const std::string& file, std::uint32_t w, std::uint32_t h) {
  Scene s = load_scene(file);
  s.camera.width = w;
  s.camera.height = h;
  lod::attach_chains(s);
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"LOD: frame time against visible objects for NOLOD, ULOD2..5 and each policy (Lee 2009 Fig. 7.4/7.5)"};
  std::string models_text = "bunny,dragon", counts_text = "16,64,128,256", backends_text = "gl,embree", csv_path;
  std::string size_text = "1024x768";
  int frames = 5, map_size = 64;
  double region_deg = 5;
  bool quick = false;
  std::string proxy_resolution = "map";
  std::string scene_file;
  auto* models_option = app.add_option("--models", models_text, "bunny, dragon");
  auto* counts_option = app.add_option("--counts", counts_text, "numbers of visible objects");
  app.add_option("--scene", scene_file,
                 "measure on this scene file (JSON, .gltf, .glb) instead of the generated models: its objects with "
                 "LOD chains are the models (glTF objects get one by default)")
      ->excludes(models_option)
      ->excludes(counts_option);
  app.add_option("--backends", backends_text, "gl (needs a display: deploy/with-xvfb.sh), embree");
  app.add_option("--size", size_text, "WxH");
  app.add_option("--frames", frames, "timed frames per condition (median)")->check(CLI::Range(1, 100));
  app.add_option("--map-size", map_size, "the attention pass's saliency map (Lee 7.4 used 64x64)")->check(CLI::Range(64, 512));
  app.add_option("--region-deg", region_deg, "the gazed region: object pixels within this visual angle of the gaze point")
      ->check(CLI::Range(0.5, 60.0));
  app.add_option("--proxy-resolution", proxy_resolution, "the attention proxy at twice the map's side (map) or full size")
      ->check(CLI::IsMember({"map", "full"}));
  app.add_option("--csv", csv_path, "write the table as CSV");
  app.add_flag("--quick", quick, "meshes 16x smaller (a smoke run)");
  CLI11_PARSE(app, argc, argv);
  unsigned w = 0, h = 0;
  if (std::sscanf(size_text.c_str(), "%ux%u", &w, &h) != 2 || w == 0 || h == 0) {
    std::fprintf(stderr, "--size %s: expected WxH\n", size_text.c_str());
    return 2;
  }
  const auto split = [](const std::string& t) {
    std::vector<std::string> out;
    std::stringstream ss(t);
    std::string item;
    while (std::getline(ss, item, ',')) out.push_back(item);
    return out;
  };
  std::ofstream csv;
  if (!csv_path.empty()) {
    csv.open(csv_path);
    csv << "model,backend,objects,condition,ms_per_frame,ms_render,ms_proxy,ms_attention,ms_blend,ms_model,triangles,"
           "psnr_attended_db,psnr_gazed_db,psnr_periphery_db,proxy_mean_abs_dso,proxy_top1_same,proxy_top10_same\n";
  }
  std::printf("%-7s %-7s %5s %-10s %9s %9s %8s %8s %8s %9s %11s %7s %7s %7s %6s\n", "model", "backend", "objs", "condition",
              "ms/frame", "render", "proxy", "attn", "blend", "eq7.2", "triangles", "dB_att", "dB_gaze", "dB_per", "|dSo|");
  attention::AttentionSettings as;
  as.map_size = map_size;
  // One second of frames at 30 Hz: eq. 3.10's temporal context (lambda = 30 frames) and the Kalman
  // filter need a history. T_a: the median of the last five updates.
  const auto track = [&](const GBuffer& g, const Scene& scene, attention::AttentionTracker& tracker) {
    std::vector<double> ms;
    for (int k = 0; k < 30; ++k) {
      const auto s0 = Clock::now();
      tracker.update(g, scene, k / 30.0, k > 0 ? (k - 1) / 30.0 : 0.0);
      if (k >= 25) ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - s0).count());
    }
    std::sort(ms.begin(), ms.end());
    return ms[ms.size() / 2];
  };
  // The scenes to measure, one at a time (a 256-dragon scene holds a few GiB).
  std::vector<std::function<BenchScene()>> scenes;
  if (!scene_file.empty()) {
    scenes.push_back([&] {
      BenchScene b;
      b.model = std::filesystem::path(scene_file).stem().string();
      const auto t0 = Clock::now();
      b.scene = load_bench_scene(scene_file, w, h);
      b.empty = b.scene;
      b.empty.objects.clear();
      std::uint64_t full = 0, coarsest = 0;
      for (const Object& o : b.scene.objects) {
        if (o.lods.empty()) continue;
        ++b.count;
        full += o.mesh->triangle_count();
        coarsest += o.lods.back().mesh->triangle_count();
      }
      std::printf("# %s: %zu objects, %d with chains: %llu triangles at full detail, %llu at their coarsest (loaded "
                  "in %.1f s)\n", scene_file.c_str(), b.scene.objects.size(), b.count,
                  static_cast<unsigned long long>(full), static_cast<unsigned long long>(coarsest),
                  std::chrono::duration<double>(Clock::now() - t0).count());
      return b;
    });
  }
  for (const std::string& model : scene_file.empty() ? split(models_text) : std::vector<std::string>{}) {
    auto chain = std::make_shared<lod::Chain>();
    for (const std::string& count_text : split(counts_text)) {
      scenes.push_back([&, model, chain, count_text] {
        if (chain->levels.empty()) {
          const int q = quick ? 4 : 1;
          const Mesh mesh = model == "dragon" ? dragon_like(1700 / q, 128 / q) : bunny_like(147 / q, 236 / q);
          const auto t0 = Clock::now();
          *chain = lod::build_chain(mesh, lod::ChainSettings{}, model);
          std::printf("# %s: %zu triangles, chain", model.c_str(), mesh.triangle_count());
          for (const auto& l : chain->levels) std::printf(" %zu", l.mesh.triangle_count());
          std::printf(" (built in %.1f s)\n", std::chrono::duration<double>(Clock::now() - t0).count());
        }
        BenchScene b;
        b.model = model;
        b.count = std::stoi(count_text);
        b.scene = make_scene(*chain, b.count, 7, w, h);
        b.empty = make_scene(*chain, 0, 7, w, h);
        b.ground_ids = 1;
        return b;
      });
    }
  }
  for (const auto& next_scene : scenes) {
    {
      BenchScene bench;
      try {
        bench = next_scene();
      } catch (const std::exception& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return 2;
      }
      const std::string& model = bench.model;
      const int count = bench.count;
      const Scene& scene = bench.scene;
      const Scene& floor_only = bench.empty;
      const TriangleTable triangles(scene);
      // Attention on the full-detail frame (Embree): where the viewer is taken to look (the most
      // attended object) and what the proxies' attention is compared against (Lee Fig. 7.1).
      EmbreeOptions eo;
      eo.geometry = EmbreeGeometry::Instanced;  // 256 x 435k triangles only fit shared
      attention::AttentionFrame full_attention;
      {
        EmbreeBackend reference_backend(eo);
        reference_backend.set_scene(scene);
        GBuffer ref;
        reference_backend.render({}, BackendSettings{}, ref);
        attention::AttentionTracker tracker(as);
        track(ref, scene, tracker);
        full_attention = tracker.last();
      }
      const auto& fa = full_attention.objects;
      if (!fa.empty())
        std::printf("# %d objects: S_o of the most attended %.3f, of the 10th %.3f\n", count, fa.front().attention,
                    fa[std::min<std::size_t>(9, fa.size() - 1)].attention);
      glm::dvec2 gaze(0.5);
      if (!fa.empty()) gaze = {fa.front().screen_x, fa.front().screen_y};
      const fovea::protocol::Degrees gaze_deg = fovea::protocol::normalized_to_degrees(scene.display, {gaze.x, gaze.y});
      lod::BoundsCache bounds;
      std::vector<std::size_t> object_index;
      const auto views_for = [&](const attention::AttentionFrame& att) {
        lod::ViewInputs in;
        in.gaze_x = gaze.x;
        in.gaze_y = gaze.y;
        in.attention = [&att](std::uint32_t id) { return attention_of(att, id); };
        return lod::object_views(scene, in, bounds, object_index);
      };
      for (const std::string& backend_name : split(backends_text)) {
        std::unique_ptr<Backend> backend;
        try {
          if (backend_name == "gl") backend = make_backend(BackendKind::OpenGL);
          else backend = std::make_unique<EmbreeBackend>(eo);
          backend->set_scene(floor_only);
        } catch (const std::exception& e) {
          std::printf("# %s backend unavailable: %s\n", backend_name.c_str(), e.what());
          continue;
        }
        GBuffer g, next, proxy;
        // T_n of eqs. 7.1-7.2: the frame without any object (clear, set-up, the G-buffer's read-back).
        backend->render({}, BackendSettings{}, g);
        const double t_n = median_ms(frames, [&] { backend->render({}, BackendSettings{}, g); });
        backend->set_scene(scene);
        struct Row {
          std::string condition;
          double total = 0, render = 0, proxy = 0, attention = 0, blend = 0, model = std::nan("");
          std::uint64_t triangles = 0;
          double dso = std::nan("");
          int top_same = -1;  // the ten most attended objects in the same order (1), or not (0)
          int top1_same = -1; // the most attended object the same
        };
        GBuffer full_image;
        std::vector<std::uint8_t> region;    // 0 gazed, 1 periphery, 2 floor and background
        std::vector<std::uint8_t> attended;  // 0: an object the full-detail pass attends (S_o >= half the top's)
        double per_triangle_ms = 0;        // t of eq. 7.1 per object at full detail, over its triangles
        const auto emit = [&](const Row& r, const GBuffer& image) {
          const double pa = psnr(image.color, full_image.color, attended, 0);
          const double pg = psnr(image.color, full_image.color, region, 0), pp = psnr(image.color, full_image.color, region, 1);
          std::printf("%-7s %-7s %5d %-10s %9.1f %9.1f %8.1f %8.1f %8.1f %9.1f %11llu %7.1f %7.1f %7.1f %6.3f\n", model.c_str(),
                      backend_name.c_str(), count, r.condition.c_str(), r.total, r.render, r.proxy, r.attention, r.blend, r.model,
                      static_cast<unsigned long long>(r.triangles), pa, pg, pp, r.dso);
          std::fflush(stdout);
          if (csv)
            csv << model << "," << backend_name << "," << count << "," << r.condition << "," << r.total << "," << r.render << ","
                << r.proxy << "," << r.attention << "," << r.blend << "," << r.model << "," << r.triangles << "," << pa << "," << pg << ","
                << pp << "," << r.dso << "," << r.top1_same << "," << r.top_same << "\n";
        };
        const auto render_with = [&](const BackendSettings& bs, GBuffer& out) {
          backend->render({}, bs, out);  // warm-up (level switch)
          return median_ms(frames, [&] { backend->render({}, bs, out); });
        };
        const auto render_levels = [&](const std::vector<std::uint8_t>& levels, GBuffer& out) {
          BackendSettings bs;
          bs.lod_levels = levels;
          return render_with(bs, out);
        };
        {
          Row r{"NOLOD"};
          r.render = r.total = render_levels(std::vector<std::uint8_t>(scene.objects.size(), 0), full_image);
          r.triangles = triangles.models_at(0);
          per_triangle_ms = r.triangles > 0 ? std::max(0.0, r.total - t_n) / static_cast<double>(r.triangles) : 0;
          r.model = t_n + per_triangle_ms * static_cast<double>(r.triangles);
          region.assign(full_image.size(), 2);
          for (std::uint32_t y = 0; y < full_image.height; ++y)
            for (std::uint32_t x = 0; x < full_image.width; ++x) {
              const std::size_t i = full_image.index(x, y);
              if (full_image.object_id[i] <= bench.ground_ids) continue;
              const fovea::protocol::Degrees at = fovea::protocol::normalized_to_degrees(
                  scene.display, {(x + 0.5) / full_image.width, (y + 0.5) / full_image.height});
              region[i] = fovea::protocol::angle_between_deg(gaze_deg, at) <= region_deg ? 0 : 1;
            }
          attended.assign(full_image.size(), 1);
          const double top = fa.empty() ? 0.0 : fa.front().attention;
          for (std::size_t i = 0; i < full_image.size(); ++i)
            if (full_image.object_id[i] > bench.ground_ids && top > 0 && attention_of(full_attention, full_image.object_id[i]) >= 0.5 * top)
              attended[i] = 0;
          Row floor{"floor-only"};
          floor.total = floor.render = floor.model = t_n;
          emit(floor, full_image);
          emit(r, full_image);
        }
        // ULODm (Lee §7.4): levels 0..m-1; the attention pass runs on every object's level m-1 (its
        // proxy, §7.2), eq. 7.3 on S_o relative to the most attended object, and the two adjacent
        // levels are blended in image space (a second G-buffer when any object is between levels).
        for (int m = 2; m <= 5; ++m) {
          Row r{"ULOD" + std::to_string(m)};
          BackendSettings proxy_settings;
          proxy_settings.lod_levels.assign(scene.objects.size(), static_cast<std::uint8_t>(m - 1));
          if (proxy_resolution == "map") lod::proxy_size(w, h, map_size, proxy_settings.width, proxy_settings.height);
          r.proxy = render_with(proxy_settings, proxy);
          attention::AttentionTracker tracker(as);
          r.attention = track(proxy, scene, tracker);
          const attention::AttentionFrame& att = tracker.last();
          // Lee Fig. 7.1: the proxy's attention against the full-detail frame's.
          double sum = 0;
          int n = 0;
          for (const auto& a : fa)
            if (a.attention > 0 || attention_of(att, a.id) > 0) {
              sum += std::abs(a.attention - attention_of(att, a.id));
              ++n;
            }
          r.dso = n > 0 ? sum / n : 0;
          r.top_same = 1;
          r.top1_same = !fa.empty() && !att.objects.empty() && fa.front().id == att.objects.front().id ? 1 : 0;
          for (std::size_t k = 0; k < std::min<std::size_t>(10, std::min(fa.size(), att.objects.size())); ++k)
            if (fa[k].id != att.objects[k].id) r.top_same = 0;
          const auto s0 = Clock::now();
          std::vector<lod::ObjectView> views = views_for(att);
          for (lod::ObjectView& v : views) {  // the chain cut to m levels
            v.levels = std::min(v.levels, m);
            v.level_error_m.resize(static_cast<std::size_t>(v.levels));
            v.level_triangles.resize(static_cast<std::size_t>(v.levels));
          }
          lod::PolicySettings ps;
          ps.policy = lod::Policy::Ulod;
          lod::LodSelector selector(ps);
          const double top = att.objects.empty() ? std::nan("") : att.objects.front().attention;
          const std::vector<lod::Selection> chosen = selector.select(views, 0, top);
          std::vector<std::uint8_t> levels(scene.objects.size(), 0), next_levels;
          for (std::size_t k = 0; k < chosen.size(); ++k) levels[object_index[k]] = static_cast<std::uint8_t>(chosen[k].drawn);
          const bool blends = lod::ulod_next_levels(scene, chosen, next_levels);
          const double select_ms = std::chrono::duration<double, std::milli>(Clock::now() - s0).count();
          r.render = render_levels(levels, g) + select_ms;
          // Eq. 7.2's t . (a + r) over the objects, plus the blend pass: triangles drawn at t per triangle.
          for (std::size_t k = 0; k < chosen.size(); ++k) {
            const std::size_t o = object_index[k];
            r.triangles += triangles.at(o, m - 1) + triangles.at(o, chosen[k].drawn);
            if (blends) r.triangles += triangles.at(o, chosen[k].blend_to);
          }
          if (blends) {
            BackendSettings next_settings;
            next_settings.lod_levels = next_levels;
            lod::ulod_pixel_mask(g, chosen, next_settings.pixel_mask);
            next_settings.readback = {.color = true, .object_id = true};
            r.blend = render_with(next_settings, next);
            const auto b0 = Clock::now();
            lod::ulod_blend(g, next, chosen);
            r.blend += std::chrono::duration<double, std::milli>(Clock::now() - b0).count();
          }
          r.total = r.proxy + r.attention + r.render + r.blend;
          // T_n per pass in proportion to the pixels it renders (the proxy's are fewer; Embree traces only
          // the blend pass's masked pixels, the raster backend draws them all).
          const double proxy_share = proxy_settings.width > 0 ? static_cast<double>(proxy_settings.width) * proxy_settings.height / (static_cast<double>(w) * h) : 1.0;
          double blend_share = 0;
          if (blends) {
            std::vector<std::uint8_t> mask;
            lod::ulod_pixel_mask(g, chosen, mask);
            blend_share = backend_name == "gl" ? 1.0
                                               : static_cast<double>(std::count(mask.begin(), mask.end(), 1)) / static_cast<double>(mask.size());
          }
          r.model = t_n * (1 + proxy_share + blend_share) + r.attention + per_triangle_ms * static_cast<double>(r.triangles);
          emit(r, g);
        }
        for (lod::Policy p : {lod::Policy::Distance, lod::Policy::ScreenSize, lod::Policy::Brown, lod::Policy::Gaze}) {
          Row r{lod::to_string(p)};
          const auto s0 = Clock::now();
          const std::vector<lod::ObjectView> views = views_for(full_attention);
          lod::PolicySettings ps;
          ps.policy = p;
          lod::LodSelector selector(ps);
          const auto& chosen = selector.select(views, 0);
          const double select_ms = std::chrono::duration<double, std::milli>(Clock::now() - s0).count();
          std::vector<std::uint8_t> levels(scene.objects.size(), 0);
          for (std::size_t k = 0; k < chosen.size(); ++k) {
            levels[object_index[k]] = static_cast<std::uint8_t>(chosen[k].drawn);
            r.triangles += triangles.at(object_index[k], chosen[k].drawn);
          }
          r.render = r.total = render_levels(levels, g) + select_ms;
          r.model = t_n + per_triangle_ms * static_cast<double>(r.triangles);
          emit(r, g);
        }
      }
    }
  }
  return 0;
}
