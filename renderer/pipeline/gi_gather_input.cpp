// SPDX-License-Identifier: Apache-2.0
#include "pipeline/gi_gather_input.h"

#include "gi/eye_rays.h"

namespace fovea::render {

void pack_gpu_photons(const gi::PhotonMap& map, std::vector<GpuPhoton>& out, std::vector<std::uint32_t>& index) {
  out.clear();
  index = map.indexed();
  const std::span<const gi::Photon> photons = map.photons();
  out.reserve(index.size());
  for (const std::uint32_t i : index) {
    const gi::Photon& p = photons[i];
    out.push_back({p.position, p.power, p.incoming, p.light, p.kind == gi::EmissionKind::Traditional});
  }
}

GpuGiGather gi_gather_input(const Scene& scene, const Camera& camera, double now_s, const gi::GazeArea& area,
                            float fovea_fraction, bool keep_ambient) {
  GpuGiGather g;
  for (const auto& [id, m] : gi::gbuffer_materials(scene)) {
    if (m == nullptr) continue;  // traced on the CPU
    g.surfaces.push_back({id, m->kd, m->is_glossy() ? m->ks : glm::vec3(0.0f), m->shininess});
  }
  const gi::EyeRays eye(camera, now_s);
  g.eye = eye.eye;
  g.right = eye.right * eye.tan_x;
  g.up = eye.up * eye.tan_y;
  g.back = eye.back;
  g.background = scene.background;
  g.ambient = keep_ambient ? glm::vec3(0.0f) : scene.ambient;
  g.centre_px = area.center_px;
  g.radius_px = area.radius_px;
  g.fovea_fraction = fovea_fraction;
  g.lights = static_cast<std::uint32_t>(scene.lights.size());
  return g;
}

}  // namespace fovea::render
