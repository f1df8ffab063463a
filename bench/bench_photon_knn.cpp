// SPDX-License-Identifier: Apache-2.0
// Side by side: fovea's photon kd-tree (renderer/gi/photon_map.h, Jensen's left-balanced tree) against
// nanoflann (Debian's libnanoflann-dev), on real photon maps of cornell.json and the queries the GI
// render makes (the surface points seen inside a 20 deg gaze area at 640x480): build time, k-nearest
// time (k = nNN), and that both find the same neighbours. DESIGN.md: nanoflann replaces ours only if
// this shows it faster.
#include <CLI/CLI.hpp>
#include <nanoflann.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include "backend/embree/embree_backend.h"
#include "gi/gaze_photons.h"
#include "gi/gi_render.h"
#include "scene/scene_loader.h"

using namespace fovea::render;
using Clock = std::chrono::steady_clock;

namespace {

struct Cloud {
  std::vector<glm::vec3> points;
  std::size_t kdtree_get_point_count() const { return points.size(); }
  float kdtree_get_pt(std::size_t i, std::size_t dim) const { return points[i][static_cast<glm::length_t>(dim)]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};
using NanoTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Cloud>, Cloud, 3, std::uint32_t>;

// nanoflann's KNNResultSet (sorted insertion) with the search radius as its initial worst distance:
// the radius-capped k-nearest query the estimate makes (NNRadius), which 1.4.3 does not offer.
class CappedKnn {
 public:
  using DistanceType = float;
  using IndexType = std::uint32_t;
  using CountType = std::size_t;
  CappedKnn(std::size_t capacity, float radius2) : capacity_(capacity), radius2_(radius2) {}
  void init(std::uint32_t* indices, float* dists) {
    indices_ = indices;
    dists_ = dists;
    count_ = 0;
    if (capacity_) dists_[capacity_ - 1] = radius2_;
  }
  std::size_t size() const { return count_; }
  bool full() const { return count_ == capacity_; }
  bool addPoint(float dist, std::uint32_t index) {
    std::size_t i;
    for (i = count_; i > 0; --i) {
      if (dists_[i - 1] > dist) {
        if (i < capacity_) {
          dists_[i] = dists_[i - 1];
          indices_[i] = indices_[i - 1];
        }
      } else {
        break;
      }
    }
    if (i < capacity_) {
      dists_[i] = dist;
      indices_[i] = index;
    }
    if (count_ < capacity_) count_++;
    return true;
  }
  float worstDist() const { return dists_[capacity_ - 1]; }

 private:
  std::uint32_t* indices_ = nullptr;
  float* dists_ = nullptr;
  std::size_t capacity_, count_ = 0;
  float radius2_;
};

double ms(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Photon k-nearest search: fovea's left-balanced kd-tree against nanoflann on cornell.json's photon maps"};
  std::uint32_t k = 240;
  float radius = 0.3f;
  std::vector<std::uint32_t> sizes = {40000, 200000};
  std::vector<std::size_t> leaves = {1, 4, 10, 20};
  app.add_option("--k", k, "neighbours per query (nNN)")->check(CLI::Range(1u, 10000u));
  app.add_option("--radius", radius, "search radius, metres (NNRadius; 0: unbounded)")->check(CLI::Range(0.0f, 1000.0f));
  app.add_option("--photons", sizes, "stored photons of the maps to compare");
  app.add_option("--leaves", leaves, "nanoflann leaf sizes to try");
  CLI11_PARSE(app, argc, argv);

  Scene scene = load_scene(std::string(FOVEA_SOURCE_DIR) + "/renderer/scenes/cornell.json");
  scene.camera.width = 640;
  scene.camera.height = 480;
  EmbreeBackend backend;
  backend.set_scene(scene);
  GBuffer g;
  backend.render({}, BackendSettings{}, g);
  const gi::GazeArea area = gi::gaze_area(scene.display, 640, 480, {0.55f, 0.6f}, 20.0);
  // The render's queries: the visible surface points inside the area (the eye, not a random cloud).
  std::vector<glm::vec3> queries;
  const glm::mat4 to_world = glm::inverse(scene.camera.view_at(0));
  const float tan_y = std::tan(glm::radians(scene.camera.vertical_fov_deg) * 0.5f), tan_x = tan_y * 640.0f / 480.0f;
  for (std::uint32_t y = 0; y < 480; ++y)
    for (std::uint32_t x = 0; x < 640; ++x) {
      const std::size_t i = g.index(x, y);
      if (g.object_id[i] == 0 || !area.contains(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f)) continue;
      const float ndc_x = 2.0f * (static_cast<float>(x) + 0.5f) / 640.0f - 1.0f;
      const float ndc_y = 1.0f - 2.0f * (static_cast<float>(y) + 0.5f) / 480.0f;
      const glm::vec3 dir = glm::vec3(to_world[0]) * (ndc_x * tan_x) + glm::vec3(to_world[1]) * (ndc_y * tan_y) - glm::vec3(to_world[2]);
      queries.push_back(glm::vec3(to_world[3]) + dir * g.depth[i]);
    }
  std::printf("%zu queries (visible points in a 20 deg gaze area, 640x480), k = %u within %.2f m, one thread\n",
              queries.size(), k, static_cast<double>(radius));
  std::printf("%-9s %-22s %10s %12s %12s %8s\n", "photons", "tree", "build_ms", "knn_us/query", "vs_fovea", "same");

  for (std::uint32_t n : sizes) {
    gi::TraceSettings ts;
    ts.stored_photons = n;
    const gi::PhotonTraceResult traced = gi::trace_photons(backend, ts);
    const std::vector<gi::Photon>& photons = traced.photons;

    auto t0 = Clock::now();
    gi::PhotonMap ours;
    ours.build_all(photons);
    const double ours_build = ms(t0);
    gi::Neighbours nb;
    std::vector<float> ours_kth(queries.size());
    t0 = Clock::now();
    for (std::size_t q = 0; q < queries.size(); ++q) {
      ours.nearest(queries[q], k, radius > 0 ? radius : std::numeric_limits<float>::infinity(), nb);
      ours_kth[q] = nb.distance2.empty() ? 0.0f : nb.distance2.back();
    }
    const double ours_us = ms(t0) * 1000.0 / static_cast<double>(queries.size());
    std::printf("%-9zu %-22s %10.1f %12.2f %12s %8s\n", photons.size(), "fovea (left-balanced)", ours_build, ours_us, "1.00x", "-");

    Cloud cloud;
    for (const gi::Photon& p : photons) cloud.points.push_back(p.position);
    for (std::size_t leaf : leaves) {
      t0 = Clock::now();
      NanoTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(leaf));
      tree.buildIndex();
      const double build = ms(t0);
      std::vector<std::uint32_t> idx(k);
      std::vector<float> d2(k);
      std::size_t same = 0;
      t0 = Clock::now();
      for (std::size_t q = 0; q < queries.size(); ++q) {
        const float pt[3] = {queries[q].x, queries[q].y, queries[q].z};
        CappedKnn result(k, radius > 0 ? radius * radius : std::numeric_limits<float>::max());
        result.init(idx.data(), d2.data());
        tree.findNeighbors(result, pt, nanoflann::SearchParams());
        const std::size_t found = result.size();
        same += (found == 0 && ours_kth[q] == 0.0f) || (found > 0 && d2[found - 1] == ours_kth[q]) ? 1u : 0u;
      }
      const double us = ms(t0) * 1000.0 / static_cast<double>(queries.size());
      char name[32], ratio[32], agree[32];
      std::snprintf(name, sizeof name, "nanoflann leaf %zu", leaf);
      std::snprintf(ratio, sizeof ratio, "%.2fx", ours_us / us);
      std::snprintf(agree, sizeof agree, "%.1f%%", 100.0 * static_cast<double>(same) / static_cast<double>(queries.size()));
      std::printf("%-9zu %-22s %10.1f %12.2f %12s %8s\n", photons.size(), name, build, us, ratio, agree);
    }
  }
  return 0;
}
