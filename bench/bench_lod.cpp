// Level of detail (Lee 2009 Fig. 7.4/7.5): frame time against the number of visible objects for
// NOLOD, ULOD2..ULOD5 and each selection policy, with the triangles drawn and the image error against
// full detail inside the attended (or gazed) region and in the periphery.
//
// Scene: N of 256 objects (a bunny-like bumpy ellipsoid of 69,432 triangles, or a dragon-like bumpy
// torus knot of 435,200, generated here: Lee's counts) with random colour, size and pose on a floor in
// front of the camera; chains of 5 levels, base 4 (eq. 7.4). Attention S_o from the attention pass
// (Lee ch. 3) on the full-detail frame; the gaze at the most attended object for the gaze policy.
// The raster backend (OpenGL; run under deploy/with-xvfb.sh) is the renderer Lee's costs are about;
// Embree's ray casting is timed alongside (its cost grows with the log of the triangles).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <numbers>
#include <random>
#include <sstream>

#include "attention/attention.h"
#include "backend/backend.h"
#include "backend/embree/embree_backend.h"
#include "lod/lod_chain.h"
#include "lod/lod_policy.h"

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

double psnr(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b, const std::vector<std::uint8_t>& mask,
            std::uint8_t which) {
  double se = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (mask[i] != which) continue;
    for (int c = 0; c < 3; ++c) {
      const auto to8 = [](float v) { return std::min(1.0, static_cast<double>(v) / (1.0 + static_cast<double>(v))); };
      const double d = to8(a[i][c]) - to8(b[i][c]);
      se += d * d;
      ++n;
    }
  }
  if (n == 0) return std::nan("");
  const double mse = se / static_cast<double>(n);
  return mse > 0 ? 10 * std::log10(1.0 / mse) : 99.0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"LOD: frame time against visible objects for NOLOD, ULOD2..5 and each policy (Lee 2009 Fig. 7.4/7.5)"};
  std::string models_text = "bunny,dragon", counts_text = "16,64,128,256", backends_text = "gl,embree", csv_path;
  std::string size_text = "1024x768";
  int frames = 5;
  bool quick = false;
  app.add_option("--models", models_text, "bunny, dragon");
  app.add_option("--counts", counts_text, "numbers of visible objects");
  app.add_option("--backends", backends_text, "gl (needs a display: deploy/with-xvfb.sh), embree");
  app.add_option("--size", size_text, "WxH");
  app.add_option("--frames", frames, "timed frames per condition (median)")->check(CLI::Range(1, 100));
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
    csv << "model,backend,objects,condition,ms_per_frame,triangles,psnr_attended_db,psnr_periphery_db\n";
  }
  std::printf("%-7s %-7s %5s %-12s %10s %12s %10s %10s\n", "model", "backend", "objs", "condition", "ms/frame", "triangles",
              "psnr_att", "psnr_per");
  for (const std::string& model : split(models_text)) {
    const int q = quick ? 4 : 1;
    const Mesh mesh = model == "dragon" ? dragon_like(1700 / q, 128 / q) : bunny_like(147 / q, 236 / q);
    const auto t0 = Clock::now();
    lod::ChainSettings cs;
    const lod::Chain chain = lod::build_chain(mesh, cs, model);
    std::printf("# %s: %zu triangles, chain", model.c_str(), mesh.triangle_count());
    for (const auto& l : chain.levels) std::printf(" %zu", l.mesh.triangle_count());
    std::printf(" (built in %.1f s)\n", std::chrono::duration<double>(Clock::now() - t0).count());
    for (const std::string& count_text : split(counts_text)) {
      const int count = std::stoi(count_text);
      const Scene scene = make_scene(chain, count, 7, w, h);
      // Attention on the full-detail frame (Embree), and the attended region: its top 10 % objects.
      EmbreeOptions eo;
      eo.geometry = EmbreeGeometry::Instanced;  // 256 x 435k triangles only fit shared
      EmbreeBackend reference_backend(eo);
      reference_backend.set_scene(scene);
      GBuffer ref;
      reference_backend.render({}, BackendSettings{}, ref);
      // One second of frames at 30 Hz: eq. 3.10's temporal context (lambda = 30 frames) and the Kalman
      // filter need a history; a single update gives every object a low S_o.
      attention::AttentionTracker tracker;
      for (int k = 0; k < 30; ++k) tracker.update(ref, scene, k / 30.0, k > 0 ? (k - 1) / 30.0 : 0.0);
      const attention::AttentionFrame& att = tracker.last();
      if (!att.objects.empty())
        std::printf("# %d objects: S_o of the most attended %.3f, of the 10th %.3f\n", count, att.objects.front().attention,
                    att.objects[std::min<std::size_t>(9, att.objects.size() - 1)].attention);
      std::vector<std::uint32_t> attended;
      for (std::size_t k = 0; k < att.objects.size() && k < std::max<std::size_t>(1, att.objects.size() / 10); ++k)
        attended.push_back(att.objects[k].id);
      std::vector<std::uint8_t> mask(ref.size(), 1);  // 0 attended, 1 periphery, 2 background
      for (std::size_t i = 0; i < ref.size(); ++i) {
        if (ref.object_id[i] <= 1) mask[i] = 2;
        else if (std::find(attended.begin(), attended.end(), ref.object_id[i]) != attended.end()) mask[i] = 0;
      }
      glm::dvec2 gaze(0.5);
      if (!att.objects.empty()) gaze = {att.objects.front().screen_x, att.objects.front().screen_y};
      // Conditions: level per object index.
      struct Condition {
        std::string name;
        std::vector<std::uint8_t> levels;
      };
      std::vector<Condition> conditions;
      conditions.push_back({"NOLOD", std::vector<std::uint8_t>(scene.objects.size(), 0)});
      const auto attention_of = [&](std::uint32_t id) {
        for (const auto& a : att.objects)
          if (a.id == id) return a.attention;
        return 0.0;
      };
      const double top_attention = att.objects.empty() || !(att.objects.front().attention > 0) ? 1.0 : att.objects.front().attention;
      for (int m = 2; m <= 5; ++m) {  // ULODm: levels 0..m-1, L = (m - 1)(1 - S_o / max S_o) (eq. 7.3), rounded
        Condition c{"ULOD" + std::to_string(m), std::vector<std::uint8_t>(scene.objects.size(), 0)};
        for (std::size_t i = 1; i < scene.objects.size(); ++i)
          c.levels[i] = static_cast<std::uint8_t>(
              std::lround((m - 1) * (1.0 - std::min(1.0, attention_of(scene.objects[i].id) / top_attention))));
        conditions.push_back(c);
      }
      for (lod::Policy p : {lod::Policy::Distance, lod::Policy::ScreenSize, lod::Policy::Brown, lod::Policy::Gaze}) {
        lod::PolicySettings ps;
        ps.policy = p;
        lod::LodSelector sel(ps);
        std::vector<lod::ObjectView> views;
        const glm::mat4 vp = scene.camera.projection() * scene.camera.view_at(0);
        const double px_per_rad = h / (2.0 * std::tan(glm::radians(static_cast<double>(scene.camera.vertical_fov_deg)) / 2));
        const fovea::protocol::Degrees gaze_deg = fovea::protocol::normalized_to_degrees(scene.display, {gaze.x, gaze.y});
        for (std::size_t i = 1; i < scene.objects.size(); ++i) {
          const Object& o = scene.objects[i];
          lod::ObjectView v;
          v.id = o.id;
          v.levels = 5;
          for (const auto& l : chain.levels) {
            v.level_error_m.push_back(l.error_m * o.transform.scale.x);
            v.level_triangles.push_back(l.mesh.triangle_count());
          }
          const glm::vec3 c = o.transform.translation;
          v.distance_m = static_cast<double>(glm::length(c - scene.camera.position));
          v.radius_m = 0.5 * static_cast<double>(o.transform.scale.x);
          v.px_per_radian = px_per_rad;
          v.projected_radius_px = v.radius_m / v.distance_m * px_per_rad;
          v.screen_area_px = static_cast<double>(w) * h;
          const glm::vec4 clip = vp * glm::vec4(c, 1);
          v.screen_x = 0.5 * (static_cast<double>(clip.x / clip.w) + 1);
          v.screen_y = 0.5 * (1 - static_cast<double>(clip.y / clip.w));
          v.eccentricity_deg = fovea::protocol::angle_between_deg(gaze_deg, fovea::protocol::normalized_to_degrees(scene.display, {v.screen_x, v.screen_y}));
          v.attention = attention_of(o.id);
          v.luminance_contrast = 0.1;
          views.push_back(v);
        }
        const auto& chosen = sel.select(views, 0);
        Condition c{lod::to_string(p), std::vector<std::uint8_t>(scene.objects.size(), 0)};
        for (std::size_t k = 0; k < chosen.size(); ++k) c.levels[k + 1] = static_cast<std::uint8_t>(chosen[k].drawn);
        conditions.push_back(c);
      }
      for (const std::string& backend_name : split(backends_text)) {
        std::unique_ptr<Backend> backend;
        try {
          if (backend_name == "gl") backend = make_backend(BackendKind::OpenGL);
          else backend = std::make_unique<EmbreeBackend>(eo);
          backend->set_scene(scene);
        } catch (const std::exception& e) {
          std::printf("# %s backend unavailable: %s\n", backend_name.c_str(), e.what());
          continue;
        }
        GBuffer full_image;
        for (const Condition& c : conditions) {
          BackendSettings bs;
          bs.lod_levels = c.levels;
          GBuffer g;
          backend->render({}, bs, g);  // warm-up (level switch)
          std::vector<double> ms;
          for (int f = 0; f < frames; ++f) {
            const auto s0 = Clock::now();
            backend->render({}, bs, g);
            ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - s0).count());
          }
          std::sort(ms.begin(), ms.end());
          if (c.name == "NOLOD") full_image = g;
          std::uint64_t tris = 0;
          for (std::size_t i = 1; i < scene.objects.size(); ++i) tris += chain.levels[std::min<std::size_t>(c.levels[i], 4)].mesh.triangle_count();
          const double pa = psnr(g.color, full_image.color, mask, 0), pp = psnr(g.color, full_image.color, mask, 1);
          std::printf("%-7s %-7s %5d %-12s %10.1f %12llu %10.1f %10.1f\n", model.c_str(), backend_name.c_str(), count,
                      c.name.c_str(), ms[ms.size() / 2], static_cast<unsigned long long>(tris), pa, pp);
          std::fflush(stdout);
          if (csv)
            csv << model << "," << backend_name << "," << count << "," << c.name << "," << ms[ms.size() / 2] << "," << tris
                << "," << pa << "," << pp << "\n";
        }
      }
    }
  }
  return 0;
}
