// SPDX-License-Identifier: Apache-2.0
#pragma once
// What the GPU gather (backend/gpu_frame.h GpuGiGather) takes from the CPU's side of the GI pass:
// the photon maps packed for upload, the materials whose pixels the G-buffer answers, the eye rays,
// the area. The frame pipeline and the GL tests build it the same way.
#include <cstdint>
#include <vector>

#include "backend/gpu_frame.h"
#include "gi/gi_render.h"
#include "gi/photon_map.h"
#include "scene/scene.h"

namespace fovea::render {

// The map's photons as the GPU takes them, in the map's order; `index` gets each one's index in the
// map's photons (what the GPU's labels refer back to).
void pack_gpu_photons(const gi::PhotonMap& map, std::vector<GpuPhoton>& out, std::vector<std::uint32_t>& index);

// Everything but the maps and the traced pixels: the gathered materials (gi::gbuffer_materials), the
// eye rays of `camera` at now_s, the scene's background and ambient (taken out of the raster's colour
// unless `keep_ambient`), the area and Algorithm 8.4's fovea fraction.
GpuGiGather gi_gather_input(const Scene& scene, const Camera& camera, double now_s, const gi::GazeArea& area,
                            float fovea_fraction, bool keep_ambient = false);

}  // namespace fovea::render
