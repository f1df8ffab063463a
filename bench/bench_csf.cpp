// SPDX-License-Identifier: Apache-2.0
// CSF-driven peripheral ray casting (renderer/gi/csf_mask.h, Murphy 2007 ch. 4-5): rays cast versus
// full resolution, and the time to build the ring mesh and ray mask and to refine and reconstruct an
// analytic scene of a few discs, per image size, with the gaze at the centre and at a corner.
//
// Each size is shown on a display with the same pixel pitch (--pitch-mm, a 19" 1280x1024 monitor's
// by default) at --distance-mm, so larger images are larger screens reaching further into the
// periphery. Plain table on stdout; --csv writes the same rows.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "gi/csf_mask.h"

namespace {

using Clock = std::chrono::steady_clock;
using fovea::render::gi::CsfSettings;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Size {
  std::uint32_t width, height;
};

std::vector<Size> parse_sizes(const std::string& text) {
  std::vector<Size> sizes;
  std::stringstream list(text);
  std::string item;
  while (std::getline(list, item, ',')) {
    unsigned w = 0, h = 0;
    char x = 0;
    std::stringstream parse(item);
    if (!(parse >> w >> x >> h) || x != 'x' || w == 0 || h == 0 || w > 16384 || h > 16384 || !parse.eof())
      throw std::invalid_argument("--sizes: \"" + item + "\" is not WxH (1..16384 each)");
    sizes.push_back({w, h});
  }
  if (sizes.empty()) throw std::invalid_argument("--sizes: no sizes given");
  return sizes;
}

// A few discs placed relative to the image size (some in the fovea, some across it, some peripheral),
// with a cheap Lambert-like shade; the scene is the "ray caster".
struct DiscScene {
  struct Disc {
    glm::vec2 centre;
    float radius;
    std::uint32_t id;
  };
  std::vector<Disc> discs;

  DiscScene(std::uint32_t width, std::uint32_t height) {
    const float w = static_cast<float>(width), h = static_cast<float>(height), s = std::min(w, h);
    discs = {{{0.50f * w, 0.50f * h}, 0.06f * s, 1},  {{0.56f * w, 0.47f * h}, 0.10f * s, 2},
             {{0.20f * w, 0.25f * h}, 0.12f * s, 3},  {{0.80f * w, 0.70f * h}, 0.15f * s, 4},
             {{0.30f * w, 0.80f * h}, 0.08f * s, 5},  {{0.90f * w, 0.15f * h}, 0.05f * s, 6},
             {{0.05f * w, 0.95f * h}, 0.10f * s, 7}};
  }
  std::uint32_t object_at(glm::vec2 p) const {
    std::uint32_t hit = 0;
    for (const Disc& d : discs)
      if (glm::length(p - d.centre) <= d.radius) hit = d.id;
    return hit;
  }
  glm::vec3 colour_at(glm::vec2 p, std::uint32_t id) const {
    if (id == 0) return {0.1f, 0.1f, 0.15f};
    const Disc& d = discs[id - 1];
    const glm::vec2 q = (p - d.centre) / d.radius;
    const float nz = std::sqrt(std::max(0.0f, 1.0f - glm::dot(q, q)));  // a sphere's normal, lit from the viewer
    return glm::vec3(0.2f + 0.1f * static_cast<float>(id % 3), 0.5f, 0.8f) * nz;
  }
};

struct Row {
  Size size;
  std::string gaze;
  std::uint64_t pixels, mask_rays, rays_cast, mismatched;
  std::uint64_t rings, quads, refined_quads;
  double mesh_ms, mask_ms, reconstruct_ms, full_ms;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"CSF ray mask (Murphy 2007): rays cast versus full resolution and build/reconstruct times"};
  std::string sizes_text = "640x480,1024x768,1280x1024", csv_path;
  double pitch_mm = 0.294, distance_mm = 600, quality = 1.0;
  std::uint32_t repeats = 5;
  app.add_option("--sizes", sizes_text, "image sizes WxH, comma-separated");
  app.add_option("--csv", csv_path, "also write the table as CSV to this file");
  app.add_option("--pitch-mm", pitch_mm, "display pixel pitch in millimetres")->check(CLI::Range(0.01, 10.0));
  app.add_option("--distance-mm", distance_mm, "viewing distance in millimetres")->check(CLI::Range(50.0, 10000.0));
  app.add_option("--quality", quality, "CsfSettings::quality")->check(CLI::Range(0.0, 100.0));
  app.add_option("--repeats", repeats, "timed runs per case (median)")->check(CLI::Range(1u, 100u));
  CLI11_PARSE(app, argc, argv);

  std::vector<Size> sizes;
  try {
    sizes = parse_sizes(sizes_text);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
  CsfSettings settings;
  settings.quality = quality;

  std::vector<Row> rows;
  for (const Size size : sizes) {
    const fovea::protocol::DisplayGeometry display{size.width, size.height, size.width * pitch_mm / 1000.0,
                                                   size.height * pitch_mm / 1000.0, distance_mm / 1000.0};
    const DiscScene scene(size.width, size.height);
    const fovea::render::gi::ObjectAt object_at = [&](glm::vec2 p) { return scene.object_at(p); };
    const fovea::render::gi::ColourAt colour_at = [&](glm::vec2 p, std::uint32_t id) { return scene.colour_at(p, id); };
    const float w = static_cast<float>(size.width), h = static_cast<float>(size.height);
    for (const auto& [gaze_name, gaze] : {std::pair{std::string("centre"), glm::vec2(w / 2, h / 2)},
                                          std::pair{std::string("corner"), glm::vec2(0.5f, 0.5f)}}) {
      Row row{size, gaze_name, std::uint64_t{size.width} * size.height, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
      std::vector<double> mesh_ms, mask_ms, reconstruct_ms, full_ms;
      fovea::render::gi::CsfReconstruction image;
      for (std::uint32_t r = 0; r < repeats; ++r) {
        auto start = Clock::now();
        const auto mesh = fovea::render::gi::ring_mesh(display, size.width, size.height, gaze, settings);
        mesh_ms.push_back(ms_since(start));
        start = Clock::now();
        const auto mask = fovea::render::gi::ray_mask(mesh);
        mask_ms.push_back(ms_since(start));
        start = Clock::now();
        const auto refinement = fovea::render::gi::refine_silhouettes(mesh, object_at, settings);
        image = fovea::render::gi::reconstruct(mesh, refinement, object_at, colour_at);
        reconstruct_ms.push_back(ms_since(start));
        row.mask_rays = mask.rays();
        // The baseline: one ray (object and colour) through every pixel with the same callbacks.
        start = Clock::now();
        std::vector<glm::vec3> full(row.pixels);
        for (std::uint32_t y = 0; y < size.height; ++y)
          for (std::uint32_t x = 0; x < size.width; ++x) {
            const glm::vec2 p{static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f};
            full[std::size_t{y} * size.width + x] = colour_at(p, object_at(p));
          }
        full_ms.push_back(ms_since(start));
      }
      for (std::uint32_t y = 0; y < size.height; ++y)
        for (std::uint32_t x = 0; x < size.width; ++x)
          if (image.object_ids[std::size_t{y} * size.width + x] !=
              scene.object_at({static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f}))
            ++row.mismatched;
      row.rays_cast = image.stats.rays_cast;
      row.rings = image.stats.rings;
      row.quads = image.stats.quads;
      row.refined_quads = image.stats.refined_quads;
      row.mesh_ms = median(mesh_ms);
      row.mask_ms = median(mask_ms);
      row.reconstruct_ms = median(reconstruct_ms);
      row.full_ms = median(full_ms);
      rows.push_back(row);
    }
  }

  std::printf("display: %.3f mm pixel pitch at %.0f mm, quality %.2f, median of %u runs\n", pitch_mm, distance_mm,
              quality, repeats);
  std::printf("%-10s %-6s %9s %9s %9s %7s %6s %7s %8s %8s %8s %8s %11s %8s\n", "size", "gaze", "pixels", "mask",
              "rays", "rays%", "rings", "quads", "refined", "wrong_id", "mesh_ms", "mask_ms", "refine+rec", "full_ms");
  for (const Row& r : rows) {
    char size_text[32];
    std::snprintf(size_text, sizeof size_text, "%ux%u", r.size.width, r.size.height);
    std::printf("%-10s %-6s %9llu %9llu %9llu %6.1f%% %6llu %7llu %8llu %8llu %8.2f %8.2f %11.2f %8.2f\n", size_text,
                r.gaze.c_str(), static_cast<unsigned long long>(r.pixels), static_cast<unsigned long long>(r.mask_rays),
                static_cast<unsigned long long>(r.rays_cast),
                100.0 * static_cast<double>(r.rays_cast) / static_cast<double>(r.pixels),
                static_cast<unsigned long long>(r.rings), static_cast<unsigned long long>(r.quads),
                static_cast<unsigned long long>(r.refined_quads), static_cast<unsigned long long>(r.mismatched),
                r.mesh_ms, r.mask_ms, r.reconstruct_ms, r.full_ms);
  }
  if (!csv_path.empty()) {
    std::ofstream csv(csv_path);
    if (!csv) {
      std::fprintf(stderr, "cannot write %s\n", csv_path.c_str());
      return 1;
    }
    csv << "width,height,gaze,pixels,mask_rays,rays_cast,rays_percent,rings,quads,refined_quads,wrong_ids,mesh_ms,"
           "mask_ms,refine_reconstruct_ms,full_resolution_ms\n";
    for (const Row& r : rows) {
      csv << r.size.width << ',' << r.size.height << ',' << r.gaze << ',' << r.pixels << ',' << r.mask_rays << ','
          << r.rays_cast << ',' << 100.0 * static_cast<double>(r.rays_cast) / static_cast<double>(r.pixels) << ','
          << r.rings << ',' << r.quads << ',' << r.refined_quads << ',' << r.mismatched << ',' << r.mesh_ms << ','
          << r.mask_ms << ',' << r.reconstruct_ms << ',' << r.full_ms << '\n';
    }
  }
  return 0;
}
