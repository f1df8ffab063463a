// SPDX-License-Identifier: Apache-2.0
#pragma once
// Shared by the gaze-directed photon mapping tests: cornell.json at 160x120 and one frame of the loop
// the pipeline runs (trace, index, render with labels, hand the labelled map back).
#include <string>
#include <vector>

#include "backend/embree/embree_backend.h"
#include "gi/gaze_photons.h"
#include "scene/scene_loader.h"

namespace fovea::render::gi::test {

inline Scene cornell() {
  Scene s = load_scene(std::string(FOVEA_SOURCE_DIR) + "/renderer/scenes/cornell.json");
  s.camera.width = 160;
  s.camera.height = 120;
  return s;
}

inline double mean_in(const std::vector<glm::vec3>& img, const GazeArea& a, std::uint32_t w) {
  double sum = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < img.size(); ++i) {
    if (!a.contains(static_cast<float>(i % w) + 0.5f, static_cast<float>(i / w) + 0.5f)) continue;
    sum += static_cast<double>(img[i].x + img[i].y + img[i].z) / 3.0;
    ++n;
  }
  return n ? sum / static_cast<double>(n) : 0.0;
}

// One frame of the loop the pipeline runs: trace, index, render with labels, hand back.
struct Frame {
  double mean = 0;
  GiStats render;
  GazeFrameStats gaze;
  std::vector<Photon> photons;  // a copy of the frame's map
};
inline Frame gaze_frame(const EmbreeBackend& backend, const Scene& scene, GazePhotonMapper& mapper, const GazeDirectedSettings& gs,
                 const GazeArea& area, const GiRenderSettings& rs) {
  Frame f;
  PhotonMaps maps;
  maps.global = mapper.trace(backend, gs, &f.gaze);
  maps.index();
  std::vector<glm::vec3> hdr;
  render_gaze_area(backend, scene.camera, 0, maps, area, rs, hdr, &f.render, true);
  f.mean = mean_in(hdr, area, scene.camera.width);
  f.photons = maps.global.photons;
  mapper.finish_frame(std::move(maps.global), f.render);
  return f;
}

inline GiRenderSettings indirect_only() {
  GiRenderSettings rs;
  rs.shadows = true;
  return rs;
}

}  // namespace fovea::render::gi::test
