// SPDX-License-Identifier: Apache-2.0
// Gaze-directed hybrid rendering with photon mapping (Jensen & Pedersen 2009): the thesis's tables
// on this machine, and accuracy against a converged reference.
//
//   stages    per-stage times like Tables 9.13-9.15 (traditional, gaze-directed, traditional with the
//             gaze-directed map's photon count in the area) per image size
//   density   photons in the gaze area at 5/10/20 deg like Tables 9.9-9.10, on a diffuse, a specular
//             (glass) and an indirectly lit scene, per strategy
//   area      full screen against a 20 deg gaze area like Table 9.16
//   accuracy  relative RMSE inside the gaze area against a many-photon traditional reference, against
//             ms per frame, per strategy, photon count and estimate (CSV; bench/plot_gi.py plots it)
//   radius    the gaze area's size against photons: the hybrid image against a full-screen reference,
//             errors weighted by the eye's resolution at each pixel's eccentricity
//
// The scene is cornell.json (the thesis's test room) with the gaze on its sphere. --scene FILE (a
// JSON or glTF scene) replaces it in stages, area, accuracy and radius, so that the tables can be
// had on a textured, many-object scene too; density compares cornell's variants and refuses one.
// --gaze X,Y moves the gaze (normalized screen coordinates, origin top left; default with --scene:
// the centre, as nothing tells where a viewer of an arbitrary scene looks).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "backend/embree/embree_backend.h"
#include "gi/csf_mask.h"
#include "gi/gi_pass.h"
#include "scene/scene_loader.h"

namespace fs = std::filesystem;
using namespace fovea::render;

namespace {

struct Size {
  std::uint32_t w, h;
};

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// The bench's scenes: cornell.json (the thesis's test room), its sphere in glass, and the room lit
// only indirectly (a spot light aimed at the ceiling).
Scene make_scene(const std::string& kind, Size size) {
  Scene s = load_scene(std::string(FOVEA_SOURCE_DIR) + "/renderer/scenes/cornell.json");
  s.camera.width = size.w;
  s.camera.height = size.h;
  if (kind == "specular") {
    for (std::size_t m = 0; m < s.materials.size(); ++m)
      if (s.materials[m].type == MaterialType::Glass) s.objects.back().material = static_cast<std::uint32_t>(m);
  } else if (kind == "indirect") {
    Light& l = s.lights.front();
    l.type = LightType::Spot;
    l.position = {0.0f, 1.2f, -1.0f};
    l.direction = {0, 1, 0};
    l.spot_cutoff_deg = 35;
    l.spot_falloff_deg = 5;
  }
  s.ambient = glm::vec3(0.0f);  // the GI replaces it inside the area; keep the local image comparable
  return s;
}

// Where a viewer looks: the sphere (cornell.json's last object) projected on the screen.
glm::vec2 gaze_on_sphere(const Scene& s) {
  const glm::vec3 c = s.objects.back().transform.translation;
  const glm::vec4 clip = s.camera.projection() * s.camera.view_at(0) * glm::vec4(c, 1.0f);
  return {0.5f * (clip.x / clip.w + 1.0f), 0.5f * (1.0f - clip.y / clip.w)};
}

// --gaze's "X,Y": two finite numbers in [0, 1]; nothing if the text is not that.
std::optional<glm::vec2> parse_gaze(const std::string& text) {
  const std::vector<std::string> xy = split(text);
  if (std::count(text.begin(), text.end(), ',') != 1 || xy.size() != 2) return std::nullopt;
  glm::vec2 g(0.0f);
  for (glm::length_t i = 0; i < 2; ++i) {
    const char* begin = xy[static_cast<std::size_t>(i)].c_str();
    char* end = nullptr;
    const double v = std::strtod(begin, &end);
    if (end == begin || *end != '\0' || !std::isfinite(v) || v < 0 || v > 1) return std::nullopt;
    g[i] = static_cast<float>(v);
  }
  return g;
}

struct Run {
  gi::GiPassResult last;
  double photons_ms = 0, index_ms = 0, precompute_ms = 0, render_ms = 0, composite_ms = 0, total_ms = 0;
  std::vector<glm::vec3> gi;         // the last frame's GI image
  std::vector<glm::vec3> composite;  // the last frame's output: GI in the gaze area blended into the local image
};

// `frames` frames with the gaze still; stage medians over the frames after `warmup`.
Run run_frames(gi::GiPass& pass, const Scene& scene, const gi::GazeArea& area, const gi::GiPassSettings& s,
               const std::vector<glm::vec3>& local, int frames, int warmup) {
  Run r;
  std::vector<double> ph, ix, pc, rd, cp, tot;
  std::vector<glm::vec3> out;
  for (int k = 0; k < frames; ++k) {
    const gi::GiPassResult& g = pass.run(scene.camera, 0, area, s, local, out);
    if (k < warmup) continue;
    ph.push_back(g.photons_ms);
    ix.push_back(g.index_ms);
    pc.push_back(g.precompute_ms);
    rd.push_back(g.render_ms);
    cp.push_back(g.composite_ms);
    tot.push_back(g.photons_ms + g.index_ms + g.precompute_ms + g.render_ms + g.composite_ms);
  }
  r.last = pass.last();
  r.gi = pass.gi_image();
  r.composite = out;
  r.photons_ms = median(ph);
  r.index_ms = median(ix);
  r.precompute_ms = median(pc);
  r.render_ms = median(rd);
  r.composite_ms = median(cp);
  r.total_ms = median(tot);
  return r;
}

double relative_rmse(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& ref, const gi::GazeArea& area,
                     std::uint32_t w) {
  double se = 0, sum = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    if (!area.contains(static_cast<float>(i % w) + 0.5f, static_cast<float>(i / w) + 0.5f)) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = static_cast<double>(a[i][c]) - static_cast<double>(ref[i][c]);
      se += d * d;
      sum += static_cast<double>(ref[i][c]);
      ++n;
    }
  }
  return n > 0 && sum > 0 ? std::sqrt(se / static_cast<double>(n)) / (sum / static_cast<double>(n)) : 0.0;
}

// Relative RMSE over the whole image with each pixel weighted by what the eye resolves at its
// eccentricity from the gaze: the Geisler-Perry cutoff frequency there over the fovea's (Murphy
// 2007 eq. 4.3). An error in the periphery counts as much less as the eye sees there.
double csf_weighted_relative_rmse(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& ref, std::uint32_t w,
                                  std::uint32_t h, const fovea::protocol::DisplayGeometry& display, glm::vec2 gaze) {
  const gi::CsfSettings csf;
  const double fovea_cpd = gi::cutoff_frequency_cpd(0.0, csf);
  const fovea::protocol::Degrees g = fovea::protocol::normalized_to_degrees(display, {gaze.x, gaze.y});
  double se = 0, sum = 0, weights = 0;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    const double x = (static_cast<double>(i % w) + 0.5) / w, y = (static_cast<double>(i / w) + 0.5) / h;
    const double ecc = fovea::protocol::angle_between_deg(g, fovea::protocol::normalized_to_degrees(display, {x, y}));
    const double wt = gi::cutoff_frequency_cpd(ecc, csf) / fovea_cpd;
    for (int c = 0; c < 3; ++c) {
      const double d = static_cast<double>(a[i][c]) - static_cast<double>(ref[i][c]);
      se += wt * d * d;
      sum += wt * static_cast<double>(ref[i][c]);
    }
    weights += 3 * wt;
  }
  return weights > 0 && sum > 0 ? std::sqrt(se / weights) / (sum / weights) : 0.0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Gaze-directed hybrid rendering with photon mapping: per-stage times, photons in the gaze area, "
               "full screen against the gaze area, accuracy against a converged reference, and the gaze area's size "
               "against photons; on cornell.json or a given scene"};
  std::string sections = "stages,density,area,accuracy,radius", sizes_text = "320x240,640x480,1024x768", csv_dir;
  std::string scene_file, gaze_text, radii_text = "0.3";
  std::uint32_t photons = 40000, reference_photons = 2000000;
  int frames = 6;
  CLI::Option* sections_option =
      app.add_option("--sections", sections,
                     "comma-separated: stages,density,area,accuracy,radius (with --scene the default leaves density "
                     "out)");
  app.add_option("--scene", scene_file,
                 "a scene file (.json, .gltf, .glb) instead of cornell.json's diffuse variant in stages, area, "
                 "accuracy and radius (density compares cornell's variants: not with --scene)");
  app.add_option("--gaze", gaze_text,
                 "the gaze point X,Y in normalized screen coordinates (0..1, origin top left); default: the centre "
                 "with --scene, else cornell's sphere");
  app.add_option("--sizes", sizes_text, "image sizes of the stages section, WxH comma-separated");
  app.add_option("--photons", photons, "stored photons per frame (maxPhotons)")->check(CLI::Range(100u, 10000000u));
  app.add_option("--reference-photons", reference_photons, "photons of the accuracy and radius sections' references")
      ->check(CLI::Range(1000u, 100000000u));
  app.add_option("--frames", frames, "frames per measurement (the first 2 warm the gaze-directed map up)")
      ->check(CLI::Range(3, 100));
  app.add_option("--nn-radii", radii_text,
                 "the accuracy section's radiance-estimate radii in metres (gi.nn_radius), comma-separated, or auto "
                 "(fovea-render's default: sqrt(nnn A / (pi photons)), per photon count): Table 8.3's "
                 "0.3 m suits a 2 m room, a larger scene's photons lie further apart; the reference uses the smallest");
  app.add_option("--csv-dir", csv_dir, "write one CSV per section into this directory");
  CLI11_PARSE(app, argc, argv);

  std::vector<float> radii;  // 0: auto
  for (const std::string& t : split(radii_text)) {
    if (t == "auto") {
      radii.push_back(0.0f);
      continue;
    }
    char* end = nullptr;
    const double r = std::strtod(t.c_str(), &end);
    if (end == t.c_str() || *end != '\0' || !(r >= 1e-4) || !(r <= 1000)) {
      std::fprintf(stderr, "--nn-radii: '%s' is not a radius in [0.0001, 1000] m\n", t.c_str());
      return 2;
    }
    radii.push_back(static_cast<float>(r));
  }
  if (radii.empty()) {
    std::fprintf(stderr, "--nn-radii: no radius given\n");
    return 2;
  }

  std::vector<Size> sizes;
  for (const std::string& t : split(sizes_text)) {
    unsigned w = 0, h = 0;
    if (std::sscanf(t.c_str(), "%ux%u", &w, &h) != 2 || w == 0 || h == 0 || w > 8192 || h > 8192) {
      std::fprintf(stderr, "--sizes: '%s' is not WxH (1..8192 each)\n", t.c_str());
      return 2;
    }
    sizes.push_back({w, h});
  }
  // density's three scenes are cornell's variants; a given scene has no such variants, so only the
  // sections that take one scene run on it.
  if (!scene_file.empty() && sections_option->count() == 0) sections = "stages,area,accuracy,radius";
  const std::vector<std::string> wanted = split(sections);
  for (const std::string& w : wanted) {
    if (w != "stages" && w != "density" && w != "area" && w != "accuracy" && w != "radius") {
      std::fprintf(stderr, "--sections: '%s' is not one of stages, density, area, accuracy, radius\n", w.c_str());
      return 2;
    }
    if (w == "density" && !scene_file.empty()) {
      std::fprintf(stderr, "--sections density compares cornell.json's diffuse, specular and indirect variants: it "
                           "does not run with --scene\n");
      return 2;
    }
  }
  std::optional<glm::vec2> gaze_point;
  if (!gaze_text.empty() && !(gaze_point = parse_gaze(gaze_text))) {
    std::fprintf(stderr, "--gaze: '%s' is not X,Y with X and Y finite numbers in [0, 1]\n", gaze_text.c_str());
    return 2;
  }
  // Loaded once: a glTF scene's parse and texture decoding cost far more than a section's setup.
  std::optional<Scene> user_scene;
  if (!scene_file.empty()) {
    try {
      user_scene = load_scene(scene_file);
    } catch (const SceneError& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return 2;
    }
  }
  const std::string scene_name = user_scene ? fs::path(scene_file).filename().string() : "cornell.json (diffuse)";
  // The scene of stages, area, accuracy and radius at `size`, with make_scene's changes to a given
  // one too, so that its numbers compare with cornell's.
  const auto bench_scene = [&](Size size) {
    if (!user_scene) return make_scene("diffuse", size);
    Scene s = *user_scene;
    s.camera.width = size.w;
    s.camera.height = size.h;
    s.ambient = glm::vec3(0.0f);
    return s;
  };
  // Nothing says where a viewer of a given scene looks: the centre, unless --gaze says.
  const auto gaze_in = [&](const Scene& s) {
    return gaze_point ? *gaze_point : user_scene ? glm::vec2(0.5f) : gaze_on_sphere(s);
  };
  // A section header's ", gaze (X, Y)". The sphere's place on the screen follows the image's
  // aspect: without `s` (sizes of several aspects), its coordinates are left out.
  const auto gaze_note = [&](const Scene* s) {
    char xy[64] = "";
    if (s != nullptr || gaze_point || user_scene) {
      const glm::vec2 g = s != nullptr ? gaze_in(*s) : gaze_point ? *gaze_point : glm::vec2(0.5f);
      std::snprintf(xy, sizeof xy, " (%.2f, %.2f)", static_cast<double>(g.x), static_cast<double>(g.y));
    }
    return std::string(", gaze") + (!gaze_point && !user_scene ? " on the sphere" : "") + xy;
  };
  const auto on_scene = [&](const Scene* s) { return " on " + scene_name + gaze_note(s); };
  const auto section = [&](const char* name) { return std::find(wanted.begin(), wanted.end(), name) != wanted.end(); };
  if (!csv_dir.empty()) fs::create_directories(csv_dir);
  const auto csv = [&](const std::string& name) {
    return csv_dir.empty() ? std::ofstream() : std::ofstream(fs::path(csv_dir) / name);
  };
  const int warmup = 2;

  const auto base_settings = [&](gi::Strategy strategy, gi::IndirectEstimate estimate) {
    gi::GiPassSettings s;
    s.strategy = strategy;
    s.photons = photons;
    s.render.indirect_estimate = estimate;
    s.render.shadows = true;
    return s;
  };
  const auto local_image = [](const Scene& scene, double* ms) {
    EmbreeBackend b;
    b.set_scene(scene);
    GBuffer g;
    BackendSettings bs;
    bs.shadows = true;
    const auto t0 = std::chrono::steady_clock::now();
    b.render({}, bs, g);
    if (ms) *ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return g.color;
  };

  if (section("stages")) {
    const bool one_aspect = std::all_of(sizes.begin(), sizes.end(), [&](Size z) {
      return std::uint64_t{z.w} * sizes.front().h == std::uint64_t{z.h} * sizes.front().w;
    });
    const Scene first = bench_scene(sizes.front());
    std::printf("== per-stage ms (Tables 9.13-9.15), 20 deg gaze area, %u photons%s\n", photons,
                on_scene(one_aspect ? &first : nullptr).c_str());
    std::printf("%-10s %-26s %-11s %8s %8s %8s %8s %8s %8s %8s %8s\n", "size", "strategy", "estimate", "stored",
                "in_area", "photons", "index", "precomp", "render", "compose", "total");
    std::ofstream out = csv("gi_stages.csv");
    if (out) out << "size,strategy,estimate,photons_stored,area_photons,photons_ms,index_ms,precompute_ms,render_ms,composite_ms,total_ms,gbuffer_ms,area_pixels\n";
    for (Size size : sizes) {
      const Scene scene = bench_scene(size);
      double gbuffer_ms = 0;
      const std::vector<glm::vec3> local = local_image(scene, &gbuffer_ms);
      const gi::GazeArea area = gi::gaze_area(scene.display, size.w, size.h, gaze_in(scene), 20.0);
      std::size_t trad_area = 0, gaze_area_photons = 0;
      const auto row = [&](const std::string& name, gi::GiPassSettings s) {
        s.count_area_photons = true;
        gi::GiPass pass;
        pass.set_scene(scene);
        const Run r = run_frames(pass, scene, area, s, local, frames, warmup);
        const char* est = s.render.indirect_estimate == gi::IndirectEstimate::Nearest ? "nearest" : "precomputed";
        std::printf("%4ux%-5u %-26s %-11s %8zu %8zu %8.1f %8.1f %8.1f %8.1f %8.1f %8.1f\n", size.w, size.h, name.c_str(), est,
                    r.last.photons, r.last.area_photons, r.photons_ms, r.index_ms, r.precompute_ms, r.render_ms,
                    r.composite_ms, r.total_ms);
        std::fflush(stdout);
        if (out)
          out << size.w << "x" << size.h << "," << name << "," << est << "," << r.last.photons << "," << r.last.area_photons
              << "," << r.photons_ms << "," << r.index_ms << "," << r.precompute_ms << "," << r.render_ms << ","
              << r.composite_ms << "," << r.total_ms << "," << gbuffer_ms << "," << r.last.render.pixels << "\n";
        return r;
      };
      for (gi::IndirectEstimate est : {gi::IndirectEstimate::Nearest, gi::IndirectEstimate::Precomputed}) {
        trad_area = row("traditional", base_settings(gi::Strategy::Traditional, est)).last.area_photons;
        gaze_area_photons = row("gaze-directed", base_settings(gi::Strategy::GazeDirected, est)).last.area_photons;
        // Traditional photon mapping with as many photons in the area as the gaze-directed map had.
        gi::GiPassSettings eq = base_settings(gi::Strategy::Traditional, est);
        eq.photons = trad_area > 0 ? static_cast<std::uint32_t>(std::min<double>(
                                         2e7, static_cast<double>(photons) * static_cast<double>(gaze_area_photons) /
                                                  static_cast<double>(trad_area)))
                                   : photons;
        row("traditional, equal in area", eq);
      }
      std::printf("%4ux%-5u G-buffer (local illumination, Embree, shadows): %.1f ms\n", size.w, size.h, gbuffer_ms);
    }
  }

  if (section("density")) {
    const Scene diffuse = make_scene("diffuse", {640, 480});  // the variants share its camera and sphere
    std::printf("\n== photons in the gaze area (Tables 9.9-9.10), 640x480, %u photons stored, after %d frames, on "
                "cornell.json's variants%s\n", photons, frames, gaze_note(&diffuse).c_str());
    std::printf("%-9s %5s %-14s %10s %10s %9s\n", "scene", "deg", "strategy", "in_area", "used", "gain_%");
    std::ofstream out = csv("gi_density.csv");
    if (out) out << "scene,area_deg,strategy,area_photons,photons_used,gain_percent\n";
    for (const std::string kind : {"diffuse", "specular", "indirect"}) {
      const Scene scene = make_scene(kind, {640, 480});
      const std::vector<glm::vec3> local = local_image(scene, nullptr);
      for (double deg : {5.0, 10.0, 20.0}) {
        const gi::GazeArea area = gi::gaze_area(scene.display, 640, 480, gaze_in(scene), deg);
        double trad = 0;
        for (gi::Strategy st : {gi::Strategy::Traditional, gi::Strategy::GazeDirected, gi::Strategy::Importon}) {
          gi::GiPassSettings s = base_settings(st, gi::IndirectEstimate::Nearest);
          s.count_area_photons = true;
          s.label_gaze_photons = true;
          gi::GiPass pass;
          pass.set_scene(scene);
          const Run r = run_frames(pass, scene, area, s, local, frames, frames - 1);
          const auto in_area = static_cast<double>(r.last.area_photons);
          if (st == gi::Strategy::Traditional) trad = in_area;
          const double gain = trad > 0 ? 100.0 * (in_area / trad - 1.0) : 0.0;
          std::printf("%-9s %5.0f %-14s %10zu %10llu %9.0f\n", kind.c_str(), deg, gi::to_string(st), r.last.area_photons,
                      static_cast<unsigned long long>(r.last.render.photons_used), gain);
          std::fflush(stdout);
          if (out)
            out << kind << "," << deg << "," << gi::to_string(st) << "," << r.last.area_photons << ","
                << r.last.render.photons_used << "," << gain << "\n";
        }
      }
    }
  }

  if (section("area")) {
    const Scene scene = bench_scene({640, 480});
    std::printf("\n== full screen against a 20 deg gaze area (Table 9.16), 640x480, %u photons%s\n", photons,
                on_scene(&scene).c_str());
    std::printf("%-14s %-11s %-12s %10s %10s %10s\n", "strategy", "estimate", "area", "pixels", "render_ms", "total_ms");
    std::ofstream out = csv("gi_area.csv");
    if (out) out << "strategy,estimate,area,pixels,render_ms,total_ms\n";
    const std::vector<glm::vec3> local = local_image(scene, nullptr);
    const gi::GazeArea gaze = gi::gaze_area(scene.display, 640, 480, gaze_in(scene), 20.0);
    const gi::GazeArea full{{320.0f, 240.0f}, 401.0f};
    for (gi::Strategy st : {gi::Strategy::Traditional, gi::Strategy::GazeDirected})
      for (gi::IndirectEstimate est : {gi::IndirectEstimate::Nearest, gi::IndirectEstimate::Precomputed})
        for (const auto& [name, area] : {std::pair<const char*, gi::GazeArea>{"full screen", full}, {"20 deg", gaze}}) {
          gi::GiPassSettings s = base_settings(st, est);
          if (std::string(name) == "full screen") s.fovea = 1.0f;
          gi::GiPass pass;
          pass.set_scene(scene);
          const Run r = run_frames(pass, scene, area, s, local, frames, warmup);
          const char* e = est == gi::IndirectEstimate::Nearest ? "nearest" : "precomputed";
          std::printf("%-14s %-11s %-12s %10llu %10.1f %10.1f\n", gi::to_string(st), e, name,
                      static_cast<unsigned long long>(r.last.render.pixels), r.render_ms, r.total_ms);
          std::fflush(stdout);
          if (out)
            out << gi::to_string(st) << "," << e << "," << name << "," << r.last.render.pixels << "," << r.render_ms << ","
                << r.total_ms << "\n";
        }
  }

  if (section("accuracy")) {
    const Scene scene = bench_scene({640, 480});
    const std::vector<glm::vec3> local = local_image(scene, nullptr);
    const gi::GazeArea area = gi::gaze_area(scene.display, 640, 480, gaze_in(scene), 20.0);
    std::printf("\n== relative RMSE in the 20 deg gaze area against traditional photon mapping with %u photons, 640x480%s\n",
                reference_photons, on_scene(&scene).c_str());
    gi::GiPassSettings ref = base_settings(gi::Strategy::Traditional, gi::IndirectEstimate::Nearest);
    ref.photons = reference_photons;
    // The many-photon reference finds its nearest photons close by: the smallest radius biases it least.
    std::vector<float> given;
    std::copy_if(radii.begin(), radii.end(), std::back_inserter(given), [](float r) { return r > 0; });
    const double surfaces_m2 = gi::surface_area_m2(scene);
    ref.render.estimate.max_radius = given.empty() ? gi::auto_nn_radius(surfaces_m2, ref.render.estimate.nearest, reference_photons)
                                                   : *std::min_element(given.begin(), given.end());
    gi::GiPass ref_pass;
    ref_pass.set_scene(scene);
    const auto t0 = std::chrono::steady_clock::now();
    const Run reference = run_frames(ref_pass, scene, area, ref, local, 1, 0);
    std::printf("reference: %zu photons, radius %.3g m, %.1f s\n", reference.last.photons, static_cast<double>(ref.render.estimate.max_radius),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    // A scene whose lights store few or no photons gives errors against a black reference: say so.
    if (!reference.last.note.empty()) std::printf("reference: %s\n", reference.last.note.c_str());
    std::printf("%-14s %-11s %8s %8s %10s %10s\n", "strategy", "estimate", "photons", "radius_m", "ms/frame", "rel_rmse");
    std::ofstream out = csv("gi_accuracy.csv");
    if (out) out << "strategy,estimate,photons,ms_per_frame,relative_rmse,reference_photons,nn_radius_m\n";
    for (const float radius : radii)
      for (gi::Strategy st : {gi::Strategy::Traditional, gi::Strategy::GazeDirected, gi::Strategy::Importon})
        // radius: every photon within the radius, the GPU gather's estimate (gi.estimate=radius; not with
        // the gaze-directed strategy, whose labels the GPU does not make).
        for (const std::string en : {"nearest", "radius", "precomputed"})
          for (std::uint32_t n : {5000u, 10000u, 20000u, 40000u, 80000u}) {
            if (en == "radius" && st == gi::Strategy::GazeDirected) continue;
            gi::GiPassSettings s = base_settings(st, en == "precomputed" ? gi::IndirectEstimate::Precomputed
                                                                       : gi::IndirectEstimate::Nearest);
            s.render.estimate.fixed_radius = s.render.caustic_estimate.fixed_radius = en == "radius";
            s.photons = n;
            s.render.estimate.max_radius = radius > 0 ? radius : gi::auto_nn_radius(surfaces_m2, s.render.estimate.nearest, n);
            gi::GiPass pass;
            pass.set_scene(scene);
            const Run r = run_frames(pass, scene, area, s, local, frames, warmup);
            const double e = relative_rmse(r.gi, reference.gi, area, 640);
            char shown[16] = "auto";
            if (radius > 0) std::snprintf(shown, sizeof shown, "%.3g", static_cast<double>(radius));
            std::printf("%-14s %-11s %8u %8s %10.1f %10.4f\n", gi::to_string(st), en.c_str(), n, shown, r.total_ms, e);
            std::fflush(stdout);
            if (out)
              out << gi::to_string(st) << "," << en << "," << n << "," << r.total_ms << "," << e << "," << reference_photons
                  << ",";
            if (out) (radius > 0 ? out << radius : out << "auto") << "\n";
          }
  }
  if (section("radius")) {
    // The gaze area's size against photons: the hybrid image (GI in the area, local illumination
    // outside) against a full-screen reference, errors weighted by the eye's resolution at each
    // pixel's eccentricity (the governor trades gi.gaze_area_deg against gi.photons on this). The
    // raster side keeps the scene's ambient term outside the area, as fovea-render's does.
    Scene scene = bench_scene({640, 480});
    scene.ambient =
        user_scene ? user_scene->ambient : load_scene(std::string(FOVEA_SOURCE_DIR) + "/renderer/scenes/cornell.json").ambient;
    const std::vector<glm::vec3> local = local_image(scene, nullptr);
    const glm::vec2 gaze = gaze_in(scene);
    const gi::GazeArea full{{320.0f, 240.0f}, 401.0f};
    std::printf("\n== gaze-area size against photons: CSF-weighted relative RMSE over the image against a full-screen "
                "traditional map with %u photons, 640x480%s\n", reference_photons, on_scene(&scene).c_str());
    // Every map's radiance estimate at the radius fovea-render's default (gi.nn_radius=auto) gives its
    // photon count: the governor's front applies these options without a radius of their own.
    const double area_m2 = gi::surface_area_m2(scene);
    gi::GiPassSettings ref = base_settings(gi::Strategy::Traditional, gi::IndirectEstimate::Nearest);
    ref.photons = reference_photons;
    ref.fovea = 1.0f;
    ref.render.estimate.max_radius = gi::auto_nn_radius(area_m2, ref.render.estimate.nearest, reference_photons);
    gi::GiPass ref_pass;
    ref_pass.set_scene(scene);
    const Run reference = run_frames(ref_pass, scene, full, ref, local, 1, 0);
    if (!reference.last.note.empty()) std::printf("reference: %s\n", reference.last.note.c_str());
    std::printf("%-14s %-11s %8s %8s %10s %10s %10s\n", "strategy", "estimate", "photons", "area", "ms/frame", "csf_rmse",
                "area_rmse");
    std::ofstream out = csv("gi_radius.csv");
    if (out) out << "strategy,estimate,photons,area_deg,ms_per_frame,csf_weighted_rmse,area_rmse,reference_photons,nn_radius_m\n";
    for (gi::Strategy st : {gi::Strategy::Traditional, gi::Strategy::GazeDirected})
      for (std::uint32_t n : {10000u, 40000u, 80000u})
        for (double deg : {10.0, 20.0, 40.0, 0.0}) {  // 0: the full screen
          gi::GiPassSettings s = base_settings(st, gi::IndirectEstimate::Precomputed);
          s.photons = n;
          s.render.estimate.max_radius = gi::auto_nn_radius(area_m2, s.render.estimate.nearest, n);
          const gi::GazeArea area = deg > 0 ? gi::gaze_area(scene.display, 640, 480, gaze, deg) : full;
          if (deg == 0) s.fovea = 1.0f;
          gi::GiPass pass;
          pass.set_scene(scene);
          const Run r = run_frames(pass, scene, area, s, local, frames, warmup);
          const double e = csf_weighted_relative_rmse(r.composite, reference.composite, 640, 480, scene.display, gaze);
          const double ea = relative_rmse(r.composite, reference.composite, area, 640);
          std::printf("%-14s %-11s %8u %8s %10.1f %10.4f %10.4f\n", gi::to_string(st), "precomputed", n,
                      deg > 0 ? (std::to_string(static_cast<int>(deg)) + " deg").c_str() : "full", r.total_ms, e, ea);
          std::fflush(stdout);
          if (out)
            out << gi::to_string(st) << ",precomputed," << n << "," << deg << "," << r.total_ms << "," << e << "," << ea << ","
                << reference_photons << "," << s.render.estimate.max_radius << "\n";
        }
  }
  return 0;
}
